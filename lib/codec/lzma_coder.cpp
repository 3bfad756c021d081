// LZMA wrapper over liblzma: raw LZMA2 streams (no .xz container; the chunk
// format stores the sizes and its own checksum) plus liblzma's CRC-32.

#include <lzma.h>

#include <algorithm>
#include <cstdint>
#include <exception>
#include <string>
#include <vector>

#include "codec/coders.h"

namespace relief::codec {
namespace {

// Largest dictionary the encoder ever uses, and therefore the dictionary the
// decoder allocates: inputs are patch-parameter tables of at most a few
// hundred KiB, so anything larger would only cost memory.
constexpr std::uint32_t kLzmaMaxDict = std::uint32_t{1} << 20;
// liblzma's smallest dictionary (LZMA_DICT_SIZE_MIN).
constexpr std::uint32_t kLzmaMinDict = 4096;
// Encoder preset. Measured on 10-100 KB synthetic patch tables with the
// dictionary capped as below: presets 6..9 differ only in dictionary size, so
// once it is overridden they produce identical bytes; LZMA_PRESET_EXTREME
// changed the size by -5 %..+0.3 % (no consistent gain) and cost 5-20 % more
// encode time (100 KB: 34.7 ms vs 37-42 ms). Plain 6 it is.
constexpr std::uint32_t kLzmaPreset = 6;
// Bound on what a decoder may use: the fixed 1 MiB dictionary plus liblzma's
// ~30 KiB of state. Checked so a future change of the constants above cannot
// silently raise the per-thread decode footprint.
constexpr std::uint64_t kLzmaDecoderMemLimit = std::uint64_t{2} << 20;
// LZMA2 chunk limits (liblzma lzma2_decoder.c): a compressed chunk has a
// control byte, a 16-bit unpacked size (plus 5 bits in the control byte, so at
// most 2 MiB), a 16-bit packed size and at least one packed byte.
constexpr std::size_t kLzma2MinChunkSize = 6;
constexpr std::uint64_t kLzma2MaxChunkOutput = std::uint64_t{1} << 21;

// Smallest power of two >= size within [kLzmaMinDict, kLzmaMaxDict]: a small
// input does not pay for hashing and allocating a large dictionary.
std::uint32_t dict_size_for(std::size_t size) {
  std::uint32_t dict = kLzmaMinDict;
  while (dict < size && dict < kLzmaMaxDict) dict <<= 1;
  return dict;
}

class LzmaStream {
 public:
  LzmaStream() = default;
  ~LzmaStream() { lzma_end(&stream_); }
  LzmaStream(const LzmaStream&) = delete;
  LzmaStream& operator=(const LzmaStream&) = delete;
  lzma_stream* get() { return &stream_; }

 private:
  lzma_stream stream_ = LZMA_STREAM_INIT;
};

std::string ret_name(lzma_ret ret) {
  switch (ret) {
    case LZMA_MEM_ERROR: return "out of memory";
    case LZMA_MEMLIMIT_ERROR: return "memory limit reached";
    case LZMA_FORMAT_ERROR: return "not an LZMA2 stream";
    case LZMA_OPTIONS_ERROR: return "unsupported options";
    case LZMA_DATA_ERROR: return "data is corrupt";
    case LZMA_BUF_ERROR: return "no progress possible";
    case LZMA_PROG_ERROR: return "programming error";
    default: return "error " + std::to_string(static_cast<int>(ret));
  }
}

}  // namespace

Result<std::vector<std::uint8_t>> lzma_compress(std::span<const std::uint8_t> data) {
  lzma_options_lzma options;
  if (lzma_lzma_preset(&options, kLzmaPreset)) return internal_error("lzma: bad preset");
  options.dict_size = dict_size_for(data.size());
  const lzma_filter filters[2] = {{LZMA_FILTER_LZMA2, &options},
                                  {LZMA_VLI_UNKNOWN, nullptr}};
  LzmaStream stream;
  const lzma_ret init = lzma_raw_encoder(stream.get(), filters);
  if (init != LZMA_OK) return internal_error("lzma: encoder init: " + ret_name(init));

  std::vector<std::uint8_t> out;
  try {
    // Incompressible data grows by ~0.01 %; start near the input size and
    // grow only if that happens.
    out.resize(data.size() + data.size() / 64 + 64);
  } catch (const std::exception&) {
    return limit_exceeded("lzma: cannot allocate the output buffer");
  }
  lzma_stream* s = stream.get();
  s->next_in = data.data();
  s->avail_in = data.size();
  s->next_out = out.data();
  s->avail_out = out.size();
  for (;;) {
    const lzma_ret ret = lzma_code(s, LZMA_FINISH);
    if (ret == LZMA_STREAM_END) break;
    if (ret != LZMA_OK) return internal_error("lzma: encoding: " + ret_name(ret));
    if (s->avail_out == 0) {
      const std::size_t used = out.size();
      try {
        out.resize(used * 2);
      } catch (const std::exception&) {
        return limit_exceeded("lzma: cannot grow the output buffer");
      }
      s->next_out = out.data() + used;
      s->avail_out = out.size() - used;
    }
  }
  out.resize(static_cast<std::size_t>(s->total_out));
  return out;
}

Result<std::vector<std::uint8_t>> lzma_decompress(std::span<const std::uint8_t> data,
                                                  std::size_t expected_size) {
  lzma_options_lzma options;
  if (lzma_lzma_preset(&options, kLzmaPreset)) return internal_error("lzma: bad preset");
  // The encoder never uses more than kLzmaMaxDict, and an LZMA2 chunk cannot
  // refer back further than the dictionary, so this is always enough.
  options.dict_size = kLzmaMaxDict;
  const lzma_filter filters[2] = {{LZMA_FILTER_LZMA2, &options},
                                  {LZMA_VLI_UNKNOWN, nullptr}};
  if (lzma_raw_decoder_memusage(filters) > kLzmaDecoderMemLimit) {
    return internal_error("lzma: decoder would exceed its memory limit");
  }
  if (data.empty()) return corrupt_data("lzma: empty stream");

  std::vector<std::uint8_t> out;
  try {
    out.resize(expected_size);
  } catch (const std::exception&) {
    return limit_exceeded("lzma: cannot allocate " + std::to_string(expected_size) + " bytes");
  }
  LzmaStream stream;
  const lzma_ret init = lzma_raw_decoder(stream.get(), filters);
  if (init != LZMA_OK) return internal_error("lzma: decoder init: " + ret_name(init));

  lzma_stream* s = stream.get();
  s->next_in = data.data();
  s->avail_in = data.size();
  s->next_out = out.data();
  s->avail_out = out.size();
  // Once the expected bytes are out, the decoder gets a one-byte scratch
  // buffer: a correct stream ends there without writing to it.
  std::uint8_t overflow_probe = 0;
  bool probing = false;
  for (;;) {
    if (s->avail_out == 0 && !probing) {
      probing = true;
      s->next_out = &overflow_probe;
      s->avail_out = 1;
    }
    const lzma_ret ret = lzma_code(s, LZMA_FINISH);
    if (probing && s->avail_out == 0) {
      return corrupt_data("lzma: stream holds more than the expected " +
                          std::to_string(expected_size) + " bytes");
    }
    if (ret == LZMA_STREAM_END) break;
    if (ret == LZMA_OK) continue;  // progress was made; go on
    if (ret == LZMA_BUF_ERROR) {
      return corrupt_data("lzma: stream ends early (" + std::to_string(s->total_out) + " of " +
                          std::to_string(expected_size) + " bytes)");
    }
    if (ret == LZMA_MEM_ERROR) return internal_error("lzma: out of memory");
    return corrupt_data("lzma: " + ret_name(ret));
  }
  if (s->total_out != expected_size) {
    return corrupt_data("lzma: stream ends early (" + std::to_string(s->total_out) + " of " +
                        std::to_string(expected_size) + " bytes)");
  }
  if (s->avail_in != 0) {
    return corrupt_data("lzma: " + std::to_string(s->avail_in) +
                        " trailing bytes after the stream");
  }
  return out;
}

std::uint64_t lzma_max_decoded_size(std::size_t coded_size) {
  return static_cast<std::uint64_t>(coded_size / kLzma2MinChunkSize) * kLzma2MaxChunkOutput;
}

std::uint32_t crc32(std::span<const std::uint8_t> data) {
  return lzma_crc32(data.data(), data.size(), 0);
}

}  // namespace relief::codec
