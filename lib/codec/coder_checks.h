// Argument checks shared by the image/bilevel coder wrappers. Private to
// lib/codec: no third-party header here either.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

#include "codec/coders.h"
#include "relief/status.h"

namespace relief::codec::detail {

// Checks that a width x height image is within the sides every coder accepts.
// `coder` is the message prefix ("jpeg", "j2k", ...).
inline Status check_image_side(const char* coder, std::uint32_t width, std::uint32_t height) {
  if (width == 0 || height == 0 || width > kMaxImageSide || height > kMaxImageSide) {
    return invalid_argument(std::string(coder) + ": image size " + std::to_string(width) + "x" +
                            std::to_string(height) + " outside 1.." +
                            std::to_string(kMaxImageSide));
  }
  return Status::ok();
}

inline Status check_channels(const char* coder, std::uint32_t channels) {
  if (channels != 1 && channels != 3) {
    return invalid_argument(std::string(coder) + ": " + std::to_string(channels) +
                            " channels, expected 1 or 3");
  }
  return Status::ok();
}

// Sample count of a checked image; cannot overflow because both sides are at
// most kMaxImageSide and channels at most 3.
inline std::size_t sample_count(std::uint32_t width, std::uint32_t height, std::uint32_t channels) {
  return static_cast<std::size_t>(width) * height * channels;
}

// Full validation of an image handed to an encoder.
inline Status check_image8(const char* coder, const Image8& image) {
  RELIEF_RETURN_IF_ERROR(check_image_side(coder, image.width, image.height));
  RELIEF_RETURN_IF_ERROR(check_channels(coder, image.channels));
  const std::size_t expected = sample_count(image.width, image.height, image.channels);
  if (image.pixels.size() != expected) {
    return invalid_argument(std::string(coder) + ": pixel vector holds " +
                            std::to_string(image.pixels.size()) + " samples, expected " +
                            std::to_string(expected));
  }
  return Status::ok();
}

inline Status check_image16(const char* coder, const Image16& image) {
  RELIEF_RETURN_IF_ERROR(check_image_side(coder, image.width, image.height));
  const std::size_t expected = sample_count(image.width, image.height, 1);
  if (image.pixels.size() != expected) {
    return invalid_argument(std::string(coder) + ": pixel vector holds " +
                            std::to_string(image.pixels.size()) + " samples, expected " +
                            std::to_string(expected));
  }
  return Status::ok();
}

}  // namespace relief::codec::detail
