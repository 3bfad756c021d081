// encode_jpeg_rgb: whole pictures (previews) as ordinary JFIF files. Unlike
// the map coder in jpeg_coder.cpp it keeps the standard tables in the stream,
// so any viewer opens the file.
#include <turbojpeg.h>

#include <cstdint>
#include <string>
#include <vector>

#include "relief/image.h"

namespace relief {

namespace {

constexpr int kBytesPerPixel = 3;

}  // namespace

Result<std::vector<std::uint8_t>> encode_jpeg_rgb(std::span<const std::uint8_t> rgb, int width, int height,
                                                  int quality) {
  if (width < 1 || height < 1 || width > kMaxJpegSide || height > kMaxJpegSide) {
    return invalid_argument("JPEG image size " + std::to_string(width) + " x " + std::to_string(height) +
                            " is outside 1.." + std::to_string(kMaxJpegSide));
  }
  if (rgb.size() != static_cast<std::size_t>(width) * static_cast<std::size_t>(height) * kBytesPerPixel) {
    return invalid_argument("JPEG image: " + std::to_string(rgb.size()) + " bytes for " + std::to_string(width) +
                            " x " + std::to_string(height) + " RGB pixels");
  }
  if (quality < 1 || quality > 100) return invalid_argument("JPEG quality must be 1..100");
  tjhandle handle = tjInitCompress();
  if (handle == nullptr) return internal_error(std::string("TurboJPEG: cannot create a compressor: ") + tjGetErrorStr());
  unsigned char* out = nullptr;  // allocated by TurboJPEG (no TJFLAG_NOREALLOC)
  unsigned long out_size = 0;
  const int rc = tjCompress2(handle, rgb.data(), width, 0, height, TJPF_RGB, &out, &out_size, TJSAMP_420, quality,
                             TJFLAG_ACCURATEDCT);
  Result<std::vector<std::uint8_t>> result =
      rc == 0 ? Result<std::vector<std::uint8_t>>(std::vector<std::uint8_t>(out, out + out_size))
              : Result<std::vector<std::uint8_t>>(internal_error(std::string("TurboJPEG: ") + tjGetErrorStr2(handle)));
  tjFree(out);
  tjDestroy(handle);
  return result;
}

}  // namespace relief
