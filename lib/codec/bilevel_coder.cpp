// Bilevel (occupancy mask) wrapper over JBIG-KIT's T.85 coder (jbig85.c).
//
// Encoder options, measured on synthetic occupancy masks made of 16x16 tiles
// (discs, unions of discs and ragged full tiles; 10-90 % of tiles occupied;
// 1024x1024, 256x256 and 512x128):
//   - three-line template (LRLTWO off): 3.8 % smaller than the two-line one;
//   - TPBON on: within 0.1 % of off in size, and it lets whole empty rows
//     (common in sparse masks) cost a single decision;
//   - one stripe for the whole image (l0 = height): 0.1 % smaller than the
//     T.85 BASIC l0 = 128; the marker overhead buys nothing here;
//   - mx = 0: the adaptive-template pixel never moved on these masks, so the
//     bytes are identical and the streams stay simpler.
// Through this wrapper a 1024x1024 mask at 51 % occupancy (disc blobs in
// 16x16 tiles) codes to 0.15 bit/pixel; encode ~140-165 Mpixel/s, decode
// ~190 Mpixel/s on one core.

extern "C" {
// jbig85.h has no C++ guard of its own.
#include <jbig85.h>
}

#include <array>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include "codec/coder_checks.h"
#include "codec/coders.h"

namespace relief::codec {
namespace {

constexpr const char* kCoder = "jbig";
constexpr int kEncodeOptions = JBG_TPBON;
constexpr int kAtMaxOffset = 0;
// Size of the bi-level image header (BIH) that starts every T.85 stream.
constexpr std::size_t kBihSize = 20;
// BIH layout: DL D P fill, XD YD L0 (big-endian 32-bit), MX MY order options.
constexpr std::size_t kBihWidthAt = 4;
constexpr std::size_t kBihHeightAt = 8;
constexpr std::size_t kBihOptionsAt = 19;
// The decoder keeps up to three lines (two with LRLTWO) in the caller's buffer.
constexpr std::size_t kDecoderLines = 3;

std::size_t bytes_per_line(std::uint32_t width) { return (static_cast<std::size_t>(width) + 7) / 8; }

std::uint32_t read_be32(const std::uint8_t* p) {
  return (static_cast<std::uint32_t>(p[0]) << 24) | (static_cast<std::uint32_t>(p[1]) << 16) |
         (static_cast<std::uint32_t>(p[2]) << 8) | static_cast<std::uint32_t>(p[3]);
}

// byte -> its eight bits as 0/1 bytes, most significant bit first.
constexpr std::array<std::array<std::uint8_t, 8>, 256> make_unpack_table() {
  std::array<std::array<std::uint8_t, 8>, 256> table{};
  for (unsigned value = 0; value < 256; ++value) {
    for (unsigned bit = 0; bit < 8; ++bit) {
      table[value][bit] = static_cast<std::uint8_t>((value >> (7 - bit)) & 1u);
    }
  }
  return table;
}
constexpr auto kUnpackTable = make_unpack_table();

struct EncodeSink {
  std::vector<std::uint8_t> bytes;
  bool failed = false;
};

// Called from C: must not throw.
void encoder_out(unsigned char* start, std::size_t len, void* file) {
  auto* sink = static_cast<EncodeSink*>(file);
  if (sink->failed) return;
  try {
    sink->bytes.insert(sink->bytes.end(), start, start + len);
  } catch (const std::exception&) {
    sink->failed = true;
  }
}

struct DecodeSink {
  std::uint8_t* out = nullptr;
  std::uint32_t width = 0;
  std::uint32_t height = 0;
  std::uint32_t next_line = 0;
  bool rejected = false;
};

// Called by the decoder for each finished line; returns non-zero to stop it.
// The output is caller-sized, so any line past the expected height (possible
// when a VLENGTH stream never lowers its height) stops the decoder instead.
int decoder_line(const jbg85_dec_state* /*state*/, unsigned char* start, std::size_t len,
                 unsigned long y, void* file) {
  auto* sink = static_cast<DecodeSink*>(file);
  if (y != sink->next_line || y >= sink->height || len != bytes_per_line(sink->width)) {
    sink->rejected = true;
    return 1;
  }
  std::uint8_t* row = sink->out + static_cast<std::size_t>(y) * sink->width;
  const std::size_t full_bytes = sink->width / 8;
  for (std::size_t i = 0; i < full_bytes; ++i) {
    std::memcpy(row + i * 8, kUnpackTable[start[i]].data(), 8);
  }
  const std::size_t tail = sink->width % 8;
  if (tail != 0) std::memcpy(row + full_bytes * 8, kUnpackTable[start[full_bytes]].data(), tail);
  ++sink->next_line;
  return 0;
}

std::string jbig_error(int code) {
  const char* text = jbg85_strerror(code);
  // The low four bits name the exact check that failed; keep them.
  char hex[16];
  std::snprintf(hex, sizeof(hex), "0x%02x", static_cast<unsigned>(code));
  return std::string("jbig: ") + (text != nullptr ? text : "unknown error") + " (" + hex + ")";
}

// Packs 8 pixels (bytes 0/1) into one MSB-first byte. With pixel i as byte i
// of a 64-bit word, multiplying by 0x8040201008040201 moves its bit from 8i
// to 63 - i; every other partial product lands on a distinct bit below 56 or
// overflows, so nothing carries into the top byte.
std::uint8_t pack8(const std::uint8_t* pixels) {
  std::uint64_t word = 0;
  // Compilers merge this into one load on little-endian targets.
  for (unsigned i = 0; i < 8; ++i) word |= static_cast<std::uint64_t>(pixels[i]) << (8 * i);
  word &= 0x0101010101010101ULL;
  return static_cast<std::uint8_t>((word * 0x8040201008040201ULL) >> 56);
}

}  // namespace

Result<std::vector<std::uint8_t>> bilevel_encode(std::span<const std::uint8_t> bits,
                                                 std::uint32_t width, std::uint32_t height) {
  RELIEF_RETURN_IF_ERROR(detail::check_image_side(kCoder, width, height));
  const std::size_t pixels = detail::sample_count(width, height, 1);
  if (bits.size() != pixels) {
    return invalid_argument("jbig: " + std::to_string(bits.size()) + " pixels, expected " +
                            std::to_string(pixels));
  }

  // Pack to MSB-first rows with zero padding, as jbig85 requires.
  const std::size_t bpl = bytes_per_line(width);
  std::vector<std::uint8_t> packed(bpl * height, 0);
  std::uint8_t seen = 0;
  for (std::uint8_t value : bits) seen |= value;
  if (seen > 1) return invalid_argument("jbig: pixel values must be 0 or 1");
  const std::size_t full_bytes = width / 8;
  for (std::uint32_t y = 0; y < height; ++y) {
    const std::uint8_t* src = bits.data() + static_cast<std::size_t>(y) * width;
    std::uint8_t* dst = packed.data() + static_cast<std::size_t>(y) * bpl;
    for (std::size_t i = 0; i < full_bytes; ++i) dst[i] = pack8(src + i * 8);
    for (std::uint32_t x = static_cast<std::uint32_t>(full_bytes * 8); x < width; ++x) {
      dst[x >> 3] |= static_cast<std::uint8_t>(src[x] << (7 - (x & 7)));
    }
  }

  EncodeSink sink;
  jbg85_enc_state state;
  jbg85_enc_init(&state, width, height, encoder_out, &sink);
  jbg85_enc_options(&state, kEncodeOptions, height, kAtMaxOffset);
  for (std::uint32_t y = 0; y < height; ++y) {
    // The previous-line pointers are ignored for the first lines; they only
    // have to be valid pointers.
    unsigned char* line = packed.data() + static_cast<std::size_t>(y) * bpl;
    unsigned char* prev = y >= 1 ? line - bpl : line;
    unsigned char* prev_prev = y >= 2 ? line - 2 * bpl : prev;
    jbg85_enc_lineout(&state, line, prev, prev_prev);
  }
  if (sink.failed) return internal_error("jbig: out of memory while encoding");
  return std::move(sink.bytes);
}

Result<std::vector<std::uint8_t>> bilevel_decode(std::span<const std::uint8_t> data,
                                                 std::uint32_t width, std::uint32_t height) {
  RELIEF_RETURN_IF_ERROR(detail::check_image_side(kCoder, width, height));
  if (data.size() < kBihSize) return corrupt_data("jbig: stream ends inside the header");

  // Check the header against the caller before the decoder sees a byte.
  const std::uint32_t bih_width = read_be32(data.data() + kBihWidthAt);
  const std::uint32_t bih_height = read_be32(data.data() + kBihHeightAt);
  const bool variable_length = (data[kBihOptionsAt] & JBG_VLENGTH) != 0;
  // With VLENGTH the header height is an upper bound that a NEWLEN marker may
  // lower later; the final height is checked once decoding ends.
  const bool height_ok = variable_length ? bih_height >= height : bih_height == height;
  if (bih_width != width || !height_ok) {
    return corrupt_data("jbig: stream is " + std::to_string(bih_width) + "x" +
                        std::to_string(bih_height) + (variable_length ? " (variable)" : "") +
                        ", expected " + std::to_string(width) + "x" + std::to_string(height));
  }

  const std::size_t bpl = bytes_per_line(width);
  std::vector<std::uint8_t> line_buffer(kDecoderLines * bpl);
  std::vector<std::uint8_t> out(detail::sample_count(width, height, 1));
  DecodeSink sink{out.data(), width, height, 0, false};

  jbg85_dec_state state;
  jbg85_dec_init(&state, line_buffer.data(), line_buffer.size(), decoder_line, &sink);
  std::size_t consumed = 0;
  // jbg85_dec_in only reads the input; its parameter is non-const for
  // historical reasons.
  int rc = jbg85_dec_in(&state, const_cast<unsigned char*>(data.data()), data.size(), &consumed);
  if (rc == JBG_EAGAIN) {
    // Everything was consumed without the image completing. A VLENGTH stream
    // is not self-terminating, so tell the decoder this is the end.
    rc = jbg85_dec_end(&state);
    if (rc == JBG_EAGAIN) return corrupt_data("jbig: stream ends early");
  } else if (rc == JBG_EOK && consumed != data.size()) {
    return corrupt_data("jbig: " + std::to_string(data.size() - consumed) +
                        " trailing bytes after the image");
  }
  if (rc == JBG_EOK_INTR || sink.rejected) {
    return corrupt_data("jbig: stream has more lines than the expected " +
                        std::to_string(height));
  }
  if (rc != JBG_EOK) return corrupt_data(jbig_error(rc));
  if (jbg85_dec_getwidth(&state) != width || jbg85_dec_getheight(&state) != height ||
      sink.next_line != height) {
    return corrupt_data("jbig: stream decoded to " + std::to_string(sink.next_line) +
                        " lines, expected " + std::to_string(height));
  }
  return out;
}

}  // namespace relief::codec
