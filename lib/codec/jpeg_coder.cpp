// JPEG wrapper over the TurboJPEG 2.x API.
//
// Handles are created once per thread and reused: tjInitCompress and
// tjInitDecompress allocate the whole libjpeg state, which would otherwise be
// paid again for every chunk. A handle that saw a failure is replaced (see
// TjHandle::discard).

#include <turbojpeg.h>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "codec/coder_checks.h"
#include "codec/coders.h"

namespace relief::codec {
namespace {

constexpr const char* kCoder = "jpeg";

// DCT choice, measured on a smooth 1024x1024 grey map (libjpeg-turbo 2.1):
//   encode: TurboJPEG's default is the fast forward DCT. The accurate one ran
//     at the same speed (~470 Mpixel/s at q 85) and gave +0.5 dB at q 85 and
//     +2.7 dB at q 95 (where it also made the stream 3 % smaller), so it is
//     always used.
//   decode: the fast IDCT was only ~4 % faster (830 vs 800 Mpixel/s at q 85)
//     but lost 2.1 dB at q 85 and 4.5 dB at q 95: accuracy is clearly worse,
//     so the accurate IDCT (TurboJPEG's decode default) is requested
//     explicitly.
// TJFLAG_NOREALLOC: the output buffer is sized by tjBufSize.
constexpr int kEncodeFlags = TJFLAG_ACCURATEDCT | TJFLAG_NOREALLOC;
// TJFLAG_STOPONWARNING turns libjpeg's "premature end of data" and similar
// warnings into a failure, so a truncated stream is reported instead of
// silently padded with grey. TJFLAG_LIMITSCANS bounds the work a hostile
// progressive stream can cause.
constexpr int kDecodeFlags = TJFLAG_ACCURATEDCT | TJFLAG_STOPONWARNING | TJFLAG_LIMITSCANS;

// One TurboJPEG handle owned by the current thread, created on first use.
class TjHandle {
 public:
  explicit TjHandle(bool compress) : compress_(compress) {}
  ~TjHandle() { discard(); }
  TjHandle(const TjHandle&) = delete;
  TjHandle& operator=(const TjHandle&) = delete;

  // nullptr if TurboJPEG cannot allocate a handle.
  tjhandle get() {
    if (handle_ == nullptr) handle_ = compress_ ? tjInitCompress() : tjInitDecompress();
    return handle_;
  }

  // Drops the handle after a failure. libjpeg-turbo 2.1 can leave a handle
  // unusable after a fatal error: once tjDecompressHeader3 fails mid-header
  // (e.g. "Unsupported JPEG data precision"), every later call on that handle
  // fails with "two SOI markers". Failures are rare, so a fresh handle is
  // cheap insurance against one bad chunk poisoning the thread.
  void discard() {
    if (handle_ != nullptr) tjDestroy(handle_);
    handle_ = nullptr;
  }

 private:
  bool compress_;
  tjhandle handle_ = nullptr;
};

TjHandle& thread_compressor() {
  thread_local TjHandle handle(true);
  return handle;
}

TjHandle& thread_decompressor() {
  thread_local TjHandle handle(false);
  return handle;
}

// The error text of `holder`'s handle, after which the handle is discarded.
std::string take_error(TjHandle& holder) {
  const char* message = tjGetErrorStr2(holder.get());
  std::string text = message != nullptr ? std::string(message) : "unknown TurboJPEG error";
  holder.discard();
  return text;
}

struct TjFree {
  void operator()(unsigned char* buffer) const { tjFree(buffer); }
};

}  // namespace

Result<std::vector<std::uint8_t>> jpeg_encode(const Image8& image, int quality,
                                              bool subsample_chroma) {
  RELIEF_RETURN_IF_ERROR(detail::check_image8(kCoder, image));
  if (quality < 1 || quality > 100) {
    return invalid_argument("jpeg: quality " + std::to_string(quality) + " outside 1..100");
  }
  TjHandle& holder = thread_compressor();
  tjhandle handle = holder.get();
  if (handle == nullptr) return internal_error("jpeg: cannot create a TurboJPEG compressor");

  const int width = static_cast<int>(image.width);
  const int height = static_cast<int>(image.height);
  const bool gray = image.channels == 1;
  const int subsamp = gray ? TJSAMP_GRAY : (subsample_chroma ? TJSAMP_420 : TJSAMP_444);
  const int pixel_format = gray ? TJPF_GRAY : TJPF_RGB;

  // Worst-case buffer up front: allocated lazily by the OS, so only the pages
  // the compressed data touches cost anything, and TurboJPEG never reallocates.
  const unsigned long capacity = tjBufSize(width, height, subsamp);
  if (capacity == static_cast<unsigned long>(-1) || capacity > 0x7fffffffUL) {
    return invalid_argument("jpeg: image too large for TurboJPEG");
  }
  std::unique_ptr<unsigned char, TjFree> buffer(tjAlloc(static_cast<int>(capacity)));
  if (!buffer) return internal_error("jpeg: cannot allocate the output buffer");

  unsigned char* out = buffer.get();
  unsigned long out_size = capacity;
  if (tjCompress2(handle, image.pixels.data(), width, 0, height, pixel_format, &out, &out_size,
                  subsamp, quality, kEncodeFlags) != 0) {
    return internal_error("jpeg: " + take_error(holder));
  }
  // NOREALLOC guarantees TurboJPEG wrote into our buffer.
  return std::vector<std::uint8_t>(out, out + out_size);
}

Result<Image8> jpeg_decode(std::span<const std::uint8_t> data, std::uint32_t width,
                           std::uint32_t height, std::uint32_t channels) {
  RELIEF_RETURN_IF_ERROR(detail::check_image_side(kCoder, width, height));
  RELIEF_RETURN_IF_ERROR(detail::check_channels(kCoder, channels));
  if (data.empty()) return corrupt_data("jpeg: empty stream");
  TjHandle& holder = thread_decompressor();
  tjhandle handle = holder.get();
  if (handle == nullptr) return internal_error("jpeg: cannot create a TurboJPEG decompressor");

  const auto size = static_cast<unsigned long>(data.size());
  int jpeg_width = 0;
  int jpeg_height = 0;
  int subsamp = -1;
  int colorspace = -1;
  if (tjDecompressHeader3(handle, data.data(), size, &jpeg_width, &jpeg_height, &subsamp,
                          &colorspace) != 0) {
    return corrupt_data("jpeg: bad header: " + take_error(holder));
  }
  if (jpeg_width != static_cast<int>(width) || jpeg_height != static_cast<int>(height)) {
    return corrupt_data("jpeg: stream is " + std::to_string(jpeg_width) + "x" +
                        std::to_string(jpeg_height) + ", expected " + std::to_string(width) +
                        "x" + std::to_string(height));
  }
  // Only what jpeg_encode produces is accepted, so a stream cannot smuggle in
  // CMYK, Adobe RGB or an exotic subsampling the rest of the codec never tested.
  const bool layout_ok = channels == 1
                             ? (colorspace == TJCS_GRAY && subsamp == TJSAMP_GRAY)
                             : (colorspace == TJCS_YCbCr &&
                                (subsamp == TJSAMP_420 || subsamp == TJSAMP_444));
  if (!layout_ok) {
    return corrupt_data("jpeg: colourspace " + std::to_string(colorspace) + " / subsampling " +
                        std::to_string(subsamp) + " does not match " + std::to_string(channels) +
                        " channel(s)");
  }

  Image8 image;
  image.width = width;
  image.height = height;
  image.channels = channels;
  image.pixels.resize(detail::sample_count(width, height, channels));
  const int pixel_format = channels == 1 ? TJPF_GRAY : TJPF_RGB;
  // Width and height come from the caller (and agree with the header), so the
  // output buffer is exactly what TurboJPEG will write: no scaling happens.
  if (tjDecompress2(handle, data.data(), size, image.pixels.data(), static_cast<int>(width), 0,
                    static_cast<int>(height), pixel_format, kDecodeFlags) != 0) {
    return corrupt_data("jpeg: " + take_error(holder));
  }
  return image;
}

}  // namespace relief::codec
