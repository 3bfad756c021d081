// JPEG 2000 wrapper over OpenJPEG 2.5: raw J2K codestreams (no JP2 boxes, the
// chunk header already says what the image is), coded entirely in memory.

#include <openjpeg.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <exception>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "codec/coder_checks.h"
#include "codec/coders.h"

namespace relief::codec {
namespace {

constexpr const char* kCoder = "j2k";
constexpr int kLosslessQuality = 100;
// Five wavelet levels (six resolutions) is OpenJPEG's default and where the
// gains flatten for map-sized images; small images get fewer (see below).
constexpr int kMaxResolutions = 6;
// The largest code block J2K allows is 64x64; it codes best on large images.
constexpr std::uint32_t kMaxCodeBlock = 64;
// J2K's smallest code block side.
constexpr std::uint32_t kMinCodeBlock = 4;
// OpenJPEG's internal stream buffer: large enough that the callbacks are
// called rarely, small enough not to dwarf a map-sized codestream.
constexpr std::size_t kMaxStreamChunk = std::size_t{1} << 20;
constexpr std::size_t kMinStreamChunk = 4096;

// ---- RAII for OpenJPEG objects.
struct CodecDeleter {
  void operator()(opj_codec_t* codec) const { opj_destroy_codec(codec); }
};
struct StreamDeleter {
  void operator()(opj_stream_t* stream) const { opj_stream_destroy(stream); }
};
struct ImageDeleter {
  void operator()(opj_image_t* image) const { opj_image_destroy(image); }
};
using CodecPtr = std::unique_ptr<opj_codec_t, CodecDeleter>;
using StreamPtr = std::unique_ptr<opj_stream_t, StreamDeleter>;
using ImagePtr = std::unique_ptr<opj_image_t, ImageDeleter>;

class CstrInfo {
 public:
  explicit CstrInfo(opj_codestream_info_v2_t* info) : info_(info) {}
  ~CstrInfo() {
    if (info_ != nullptr) opj_destroy_cstr_info(&info_);
  }
  CstrInfo(const CstrInfo&) = delete;
  CstrInfo& operator=(const CstrInfo&) = delete;
  const opj_codestream_info_v2_t* get() const { return info_; }

 private:
  opj_codestream_info_v2_t* info_;
};

// ---- Messages: OpenJPEG reports through callbacks. Errors are kept for the
// Status; info and warnings are dropped so nothing reaches stderr.
struct MessageSink {
  std::string first_error;
};

void ignore_message(const char* /*msg*/, void* /*client_data*/) {}

void capture_error(const char* msg, void* client_data) {
  auto* sink = static_cast<MessageSink*>(client_data);
  if (sink == nullptr || msg == nullptr || !sink->first_error.empty()) return;
  try {
    // The first error is the specific one; later ones are "failed to decode".
    sink->first_error = msg;
    while (!sink->first_error.empty() &&
           (sink->first_error.back() == '\n' || sink->first_error.back() == ' ')) {
      sink->first_error.pop_back();
    }
  } catch (...) {
    // Out of memory while keeping a message: the failure is reported anyway.
  }
}

void install_handlers(opj_codec_t* codec, MessageSink* sink) {
  opj_set_info_handler(codec, ignore_message, nullptr);
  opj_set_warning_handler(codec, ignore_message, nullptr);
  opj_set_error_handler(codec, capture_error, sink);
}

std::string describe(const MessageSink& sink, const char* what) {
  std::string message = std::string("j2k: ") + what;
  if (!sink.first_error.empty()) message += ": " + sink.first_error;
  return message;
}

// ---- In-memory streams.
constexpr OPJ_SIZE_T kStreamEnd = static_cast<OPJ_SIZE_T>(-1);

struct MemReader {
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
  std::size_t pos = 0;
};

OPJ_SIZE_T reader_read(void* buffer, OPJ_SIZE_T count, void* user) {
  auto* reader = static_cast<MemReader*>(user);
  if (reader->pos >= reader->size) return kStreamEnd;
  const std::size_t n = std::min<std::size_t>(count, reader->size - reader->pos);
  std::memcpy(buffer, reader->data + reader->pos, n);
  reader->pos += n;
  return n;
}

OPJ_OFF_T reader_skip(OPJ_OFF_T count, void* user) {
  auto* reader = static_cast<MemReader*>(user);
  // Clamp to the buffer and report how far we actually moved, as a file
  // stream at EOF would.
  if (count >= 0) {
    const std::size_t n =
        std::min<std::size_t>(static_cast<std::size_t>(count), reader->size - reader->pos);
    reader->pos += n;
    return static_cast<OPJ_OFF_T>(n);
  }
  const std::size_t back = std::min<std::size_t>(static_cast<std::size_t>(-count), reader->pos);
  reader->pos -= back;
  return -static_cast<OPJ_OFF_T>(back);
}

OPJ_BOOL reader_seek(OPJ_OFF_T offset, void* user) {
  auto* reader = static_cast<MemReader*>(user);
  if (offset < 0 || static_cast<std::uint64_t>(offset) > reader->size) return OPJ_FALSE;
  reader->pos = static_cast<std::size_t>(offset);
  return OPJ_TRUE;
}

struct MemWriter {
  std::vector<std::uint8_t> bytes;
  std::size_t pos = 0;
};

// Grows the writer so that [0, end) exists; false when memory runs out (the
// callbacks are called from C and must not let an exception through).
bool writer_reserve(MemWriter* writer, std::size_t end) {
  if (end <= writer->bytes.size()) return true;
  try {
    writer->bytes.resize(end);
  } catch (const std::exception&) {
    return false;
  }
  return true;
}

OPJ_SIZE_T writer_write(void* buffer, OPJ_SIZE_T count, void* user) {
  auto* writer = static_cast<MemWriter*>(user);
  if (!writer_reserve(writer, writer->pos + count)) return kStreamEnd;
  std::memcpy(writer->bytes.data() + writer->pos, buffer, count);
  writer->pos += count;
  return count;
}

OPJ_OFF_T writer_skip(OPJ_OFF_T count, void* user) {
  auto* writer = static_cast<MemWriter*>(user);
  if (count < 0) {
    if (static_cast<std::size_t>(-count) > writer->pos) return -1;
    writer->pos -= static_cast<std::size_t>(-count);
    return count;
  }
  if (!writer_reserve(writer, writer->pos + static_cast<std::size_t>(count))) return -1;
  writer->pos += static_cast<std::size_t>(count);
  return count;
}

OPJ_BOOL writer_seek(OPJ_OFF_T offset, void* user) {
  auto* writer = static_cast<MemWriter*>(user);
  if (offset < 0 || !writer_reserve(writer, static_cast<std::size_t>(offset))) return OPJ_FALSE;
  writer->pos = static_cast<std::size_t>(offset);
  return OPJ_TRUE;
}

std::size_t stream_chunk(std::size_t hint) {
  return std::clamp(hint, kMinStreamChunk, kMaxStreamChunk);
}

// ---- Encoder parameters.

// 1 + floor(log2(side)): a resolution level needs at least one sample per
// side, so 1x1 images get a single resolution (no transform at all).
int resolutions_for(std::uint32_t width, std::uint32_t height) {
  std::uint32_t side = std::min(width, height);
  int levels = 1;
  while (side > 1 && levels < kMaxResolutions) {
    side >>= 1;
    ++levels;
  }
  return levels;
}

// Smallest power of two >= side, within J2K's code-block limits: a block
// larger than the image only wastes coder state.
int code_block_for(std::uint32_t side) {
  std::uint32_t block = kMinCodeBlock;
  while (block < side && block < kMaxCodeBlock) block <<= 1;
  return static_cast<int>(block);
}

Result<std::vector<std::uint8_t>> encode_planes(std::uint32_t width, std::uint32_t height,
                                                std::uint32_t channels, std::uint32_t precision,
                                                int quality,
                                                const auto& sample /* (index) -> int */) {
  if (quality < 1 || quality > kLosslessQuality) {
    return invalid_argument("j2k: quality " + std::to_string(quality) + " outside 1..100");
  }
  opj_image_cmptparm_t params[3];
  std::memset(params, 0, sizeof(params));
  for (std::uint32_t c = 0; c < channels; ++c) {
    params[c].dx = 1;
    params[c].dy = 1;
    params[c].w = width;
    params[c].h = height;
    params[c].x0 = 0;
    params[c].y0 = 0;
    params[c].prec = precision;
    params[c].sgnd = 0;
  }
  ImagePtr image(
      opj_image_create(channels, params, channels == 3 ? OPJ_CLRSPC_SRGB : OPJ_CLRSPC_GRAY));
  if (!image) return internal_error("j2k: cannot allocate the image");
  image->x0 = 0;
  image->y0 = 0;
  image->x1 = width;
  image->y1 = height;
  const std::size_t pixels = detail::sample_count(width, height, 1);
  for (std::uint32_t c = 0; c < channels; ++c) {
    OPJ_INT32* plane = image->comps[c].data;
    for (std::size_t i = 0; i < pixels; ++i) plane[i] = sample(i * channels + c);
  }

  opj_cparameters_t cp;
  opj_set_default_encoder_parameters(&cp);
  cp.tcp_numlayers = 1;
  if (quality == kLosslessQuality) {
    cp.irreversible = 0;  // reversible 5/3 wavelet and RCT
    cp.cp_disto_alloc = 1;
    cp.tcp_rates[0] = 0.0f;  // 0 = keep every coding pass
  } else {
    cp.irreversible = 1;  // 9/7 wavelet and ICT
    cp.cp_fixed_quality = 1;
    cp.tcp_distoratio[0] = static_cast<float>(j2k_quality_to_psnr(quality));
  }
  cp.tcp_mct = channels == 3 ? 1 : 0;
  cp.numresolution = resolutions_for(width, height);
  cp.cblockw_init = code_block_for(width);
  cp.cblockh_init = code_block_for(height);

  MessageSink sink;
  CodecPtr codec(opj_create_compress(OPJ_CODEC_J2K));
  if (!codec) return internal_error("j2k: cannot create the encoder");
  install_handlers(codec.get(), &sink);
  if (!opj_setup_encoder(codec.get(), &cp, image.get())) {
    return internal_error(describe(sink, "encoder setup failed"));
  }

  MemWriter writer;
  const std::size_t raw_bytes = pixels * channels * (precision > 8 ? 2 : 1);
  StreamPtr stream(opj_stream_create(stream_chunk(raw_bytes / 4), OPJ_STREAM_WRITE));
  if (!stream) return internal_error("j2k: cannot create the output stream");
  opj_stream_set_write_function(stream.get(), writer_write);
  opj_stream_set_skip_function(stream.get(), writer_skip);
  opj_stream_set_seek_function(stream.get(), writer_seek);
  opj_stream_set_user_data(stream.get(), &writer, nullptr);

  if (!opj_start_compress(codec.get(), image.get(), stream.get()) ||
      !opj_encode(codec.get(), stream.get()) || !opj_end_compress(codec.get(), stream.get())) {
    return internal_error(describe(sink, "encoding failed"));
  }
  // opj_end_compress writes EOC and flushes; release the stream before
  // handing out the bytes it wrote into.
  stream.reset();
  writer.bytes.resize(writer.pos);
  return std::move(writer.bytes);
}

// ---- Codestream main header, checked before OpenJPEG sees the stream.
// opj_read_header already does work proportional to the image area the SIZ
// marker announces (a mutated 48x40 stream claiming 48x2.6M took 0.4 s), so
// the few fields that size everything are compared with the caller first.
// ISO/IEC 15444-1 A.5.1: SOC, then SIZ = Lsiz Rsiz Xsiz Ysiz XOsiz YOsiz
// XTsiz YTsiz XTOsiz YTOsiz Csiz, then Ssiz XRsiz YRsiz per component.
constexpr std::uint16_t kMarkerSoc = 0xff4f;
constexpr std::uint16_t kMarkerSiz = 0xff51;
constexpr std::size_t kSizFixedSize = 38;      // Lsiz .. Csiz
constexpr std::size_t kSizComponentSize = 3;   // Ssiz XRsiz YRsiz
constexpr std::size_t kSizStart = 4;           // after SOC and the SIZ marker

std::uint32_t read_be(const std::uint8_t* p, int bytes) {
  std::uint32_t value = 0;
  for (int i = 0; i < bytes; ++i) value = (value << 8) | p[i];
  return value;
}

Status check_main_header(std::span<const std::uint8_t> data, std::uint32_t width,
                         std::uint32_t height, std::uint32_t channels, std::uint32_t precision) {
  const std::size_t siz_size = kSizFixedSize + kSizComponentSize * channels;
  if (data.size() < kSizStart + siz_size) return corrupt_data("j2k: stream ends inside the header");
  const std::uint8_t* p = data.data();
  if (read_be(p, 2) != kMarkerSoc || read_be(p + 2, 2) != kMarkerSiz) {
    return corrupt_data("j2k: not a J2K codestream (no SOC/SIZ)");
  }
  const std::uint8_t* siz = p + kSizStart;
  const std::uint32_t length = read_be(siz, 2);
  const std::uint32_t x1 = read_be(siz + 4, 4);
  const std::uint32_t y1 = read_be(siz + 8, 4);
  const std::uint32_t x0 = read_be(siz + 12, 4);
  const std::uint32_t y0 = read_be(siz + 16, 4);
  const std::uint32_t tile_w = read_be(siz + 20, 4);
  const std::uint32_t tile_h = read_be(siz + 24, 4);
  const std::uint32_t tile_x0 = read_be(siz + 28, 4);
  const std::uint32_t tile_y0 = read_be(siz + 32, 4);
  const std::uint32_t components = read_be(siz + 36, 2);
  if (x1 != width || y1 != height || x0 != 0 || y0 != 0) {
    return corrupt_data("j2k: stream covers [" + std::to_string(x0) + "," + std::to_string(x1) +
                        ")x[" + std::to_string(y0) + "," + std::to_string(y1) + "), expected " +
                        std::to_string(width) + "x" + std::to_string(height));
  }
  if (components != channels || length != siz_size) {
    return corrupt_data("j2k: stream has " + std::to_string(components) +
                        " components, expected " + std::to_string(channels));
  }
  // One tile covering the image: a hostile header could otherwise ask for
  // millions of 1x1 tiles, each with its own allocations.
  if (tile_x0 != 0 || tile_y0 != 0 || tile_w < width || tile_h < height) {
    return corrupt_data("j2k: stream is tiled; expected a single tile");
  }
  for (std::uint32_t c = 0; c < channels; ++c) {
    const std::uint8_t* comp = siz + kSizFixedSize + kSizComponentSize * c;
    // Ssiz: bit 7 = signed, low bits = precision - 1.
    if (comp[0] != precision - 1 || comp[1] != 1 || comp[2] != 1) {
      return corrupt_data("j2k: component " + std::to_string(c) + " is not " +
                          std::to_string(precision) + "-bit unsigned and unsubsampled");
    }
  }
  return Status::ok();
}

// Decodes a codestream after checking that its header describes exactly a
// width x height image of `channels` unsigned components of `precision` bits
// in one tile, which is all the encoder above ever writes.
Result<ImagePtr> decode_planes(std::span<const std::uint8_t> data, std::uint32_t width,
                               std::uint32_t height, std::uint32_t channels,
                               std::uint32_t precision) {
  if (data.empty()) return corrupt_data("j2k: empty stream");
  RELIEF_RETURN_IF_ERROR(check_main_header(data, width, height, channels, precision));
  MessageSink sink;
  CodecPtr codec(opj_create_decompress(OPJ_CODEC_J2K));
  if (!codec) return internal_error("j2k: cannot create the decoder");
  install_handlers(codec.get(), &sink);
  opj_dparameters_t dp;
  opj_set_default_decoder_parameters(&dp);
  if (!opj_setup_decoder(codec.get(), &dp)) {
    return internal_error(describe(sink, "decoder setup failed"));
  }
  // Strict mode: a truncated codestream is an error, not a blurrier image.
  if (!opj_decoder_set_strict_mode(codec.get(), OPJ_TRUE)) {
    return internal_error(describe(sink, "cannot enable strict decoding"));
  }

  MemReader reader{data.data(), data.size(), 0};
  StreamPtr stream(opj_stream_create(stream_chunk(data.size()), OPJ_STREAM_READ));
  if (!stream) return internal_error("j2k: cannot create the input stream");
  opj_stream_set_read_function(stream.get(), reader_read);
  opj_stream_set_skip_function(stream.get(), reader_skip);
  opj_stream_set_seek_function(stream.get(), reader_seek);
  opj_stream_set_user_data(stream.get(), &reader, nullptr);
  opj_stream_set_user_data_length(stream.get(), data.size());

  opj_image_t* raw_image = nullptr;
  const bool header_ok = opj_read_header(stream.get(), codec.get(), &raw_image) != 0;
  ImagePtr image(raw_image);
  if (!header_ok || !image) return corrupt_data(describe(sink, "bad header"));

  // check_main_header read the same SIZ bytes; this re-checks OpenJPEG's own
  // parse of them, which is what sizes the decode allocations.
  if (image->x0 != 0 || image->y0 != 0 || image->x1 != width || image->y1 != height) {
    return corrupt_data("j2k: stream covers [" + std::to_string(image->x0) + "," +
                        std::to_string(image->x1) + ")x[" + std::to_string(image->y0) + "," +
                        std::to_string(image->y1) + "), expected " + std::to_string(width) +
                        "x" + std::to_string(height));
  }
  if (image->numcomps != channels) {
    return corrupt_data("j2k: stream has " + std::to_string(image->numcomps) +
                        " components, expected " + std::to_string(channels));
  }
  for (std::uint32_t c = 0; c < channels; ++c) {
    const opj_image_comp_t& comp = image->comps[c];
    if (comp.dx != 1 || comp.dy != 1 || comp.prec != precision || comp.sgnd != 0) {
      return corrupt_data("j2k: component " + std::to_string(c) + " is " +
                          std::to_string(comp.prec) + "-bit" + (comp.sgnd ? " signed" : "") +
                          " with subsampling " + std::to_string(comp.dx) + "x" +
                          std::to_string(comp.dy) + ", expected " + std::to_string(precision) +
                          "-bit unsigned, not subsampled");
    }
  }
  {
    // The work OpenJPEG does per packet scales with tiles x layers x
    // resolutions; the encoder writes one tile, one layer and at most
    // kMaxResolutions, so anything more is damage (a flipped layer count of
    // 65281 made a 48x40 decode take 23 ms instead of 0.1 ms).
    CstrInfo info(opj_get_cstr_info(codec.get()));
    const opj_codestream_info_v2_t* cs = info.get();
    if (cs == nullptr) return internal_error("j2k: cannot read the codestream info");
    if (cs->tw != 1 || cs->th != 1) {
      return corrupt_data("j2k: stream has " + std::to_string(cs->tw) + "x" +
                          std::to_string(cs->th) + " tiles, expected one");
    }
    if (cs->m_default_tile_info.numlayers != 1) {
      return corrupt_data("j2k: stream has " + std::to_string(cs->m_default_tile_info.numlayers) +
                          " quality layers, expected one");
    }
    const opj_tccp_info_t* tccp = cs->m_default_tile_info.tccp_info;
    for (std::uint32_t c = 0; tccp != nullptr && c < cs->nbcomps; ++c) {
      if (tccp[c].numresolutions > static_cast<OPJ_UINT32>(kMaxResolutions)) {
        return corrupt_data("j2k: component " + std::to_string(c) + " has " +
                            std::to_string(tccp[c].numresolutions) + " resolutions, at most " +
                            std::to_string(kMaxResolutions) + " expected");
      }
    }
  }

  if (!opj_decode(codec.get(), stream.get(), image.get())) {
    return corrupt_data(describe(sink, "decoding failed"));
  }
  if (!opj_end_decompress(codec.get(), stream.get())) {
    return corrupt_data(describe(sink, "decoding did not finish"));
  }
  for (std::uint32_t c = 0; c < channels; ++c) {
    const opj_image_comp_t& comp = image->comps[c];
    if (comp.data == nullptr || comp.w != width || comp.h != height || comp.factor != 0) {
      return corrupt_data("j2k: component " + std::to_string(c) + " was not fully decoded");
    }
  }
  return image;
}

template <typename T>
T clamp_sample(OPJ_INT32 value) {
  constexpr OPJ_INT32 kMax = std::numeric_limits<T>::max();
  return static_cast<T>(std::clamp<OPJ_INT32>(value, 0, kMax));
}

}  // namespace

// Linear in quality, psnr = 15 + 0.5 q: q = 50 -> 40 dB (a visually clean
// 8-bit map), q = 99 -> 64.5 dB (RMSE 0.15 of an 8-bit level, ~39 of a
// 16-bit one), q = 1 -> 15.5 dB. PSNR is measured by OpenJPEG against each component's peak
// (255 or 65535), so the same quality means the same relative error at 8 and
// 16 bits. Measured: 16-bit maps land within ~1.5 dB of the target up to
// q 99, but 8-bit output saturates near 55 dB (the rounding to integers alone
// costs ~59 dB), so on 8-bit maps qualities above ~90 buy little and 100
// (exact) is the next real step. Quality 100 (and above) returns 0,
// OpenJPEG's "lossless" marker; below 1 is treated as 1.
double j2k_quality_to_psnr(int quality) {
  if (quality >= kLosslessQuality) return 0.0;
  const int q = std::max(quality, 1);
  return 15.0 + 0.5 * q;
}

Result<std::vector<std::uint8_t>> j2k_encode8(const Image8& image, int quality) {
  RELIEF_RETURN_IF_ERROR(detail::check_image8(kCoder, image));
  const std::uint8_t* pixels = image.pixels.data();
  return encode_planes(image.width, image.height, image.channels, 8, quality,
                       [pixels](std::size_t i) { return static_cast<OPJ_INT32>(pixels[i]); });
}

Result<std::vector<std::uint8_t>> j2k_encode16(const Image16& image, int quality) {
  RELIEF_RETURN_IF_ERROR(detail::check_image16(kCoder, image));
  const std::uint16_t* pixels = image.pixels.data();
  return encode_planes(image.width, image.height, 1, 16, quality,
                       [pixels](std::size_t i) { return static_cast<OPJ_INT32>(pixels[i]); });
}

Result<Image8> j2k_decode8(std::span<const std::uint8_t> data, std::uint32_t width,
                           std::uint32_t height, std::uint32_t channels) {
  RELIEF_RETURN_IF_ERROR(detail::check_image_side(kCoder, width, height));
  RELIEF_RETURN_IF_ERROR(detail::check_channels(kCoder, channels));
  RELIEF_ASSIGN_OR_RETURN(ImagePtr decoded, decode_planes(data, width, height, channels, 8));
  Image8 out;
  out.width = width;
  out.height = height;
  out.channels = channels;
  const std::size_t pixels = detail::sample_count(width, height, 1);
  out.pixels.resize(pixels * channels);
  for (std::uint32_t c = 0; c < channels; ++c) {
    const OPJ_INT32* plane = decoded->comps[c].data;
    for (std::size_t i = 0; i < pixels; ++i) {
      out.pixels[i * channels + c] = clamp_sample<std::uint8_t>(plane[i]);
    }
  }
  return out;
}

Result<Image16> j2k_decode16(std::span<const std::uint8_t> data, std::uint32_t width,
                             std::uint32_t height) {
  RELIEF_RETURN_IF_ERROR(detail::check_image_side(kCoder, width, height));
  RELIEF_ASSIGN_OR_RETURN(ImagePtr decoded, decode_planes(data, width, height, 1, 16));
  Image16 out;
  out.width = width;
  out.height = height;
  const std::size_t pixels = detail::sample_count(width, height, 1);
  out.pixels.resize(pixels);
  const OPJ_INT32* plane = decoded->comps[0].data;
  for (std::size_t i = 0; i < pixels; ++i) out.pixels[i] = clamp_sample<std::uint16_t>(plane[i]);
  return out;
}

}  // namespace relief::codec
