// The weighted sums behind the colour prediction of chunk format 9 and later
// (format-spec/chunk.md §11.4.1, section codec 10): over a window of earlier
// points, each point's weight from its squared cell distance relative to the
// nearest one's. Internal to the codec; split out of attribute_coder.cpp so
// its vector forms can be tested against the plain one.
#pragma once

#include <cstddef>
#include <cstdint>

namespace relief::codec {

// Relative distances clamp at kFarRatio (§11.4.1).
inline constexpr std::uint32_t kFarRatio = 4095;

struct WindowSums {
  std::uint64_t w = 0, r = 0, g = 0, b = 0, act = 0;
  bool operator==(const WindowSums&) const = default;
};

// The window's points, one array per axis and per value (struct of arrays,
// so the sums vectorise).
struct ColorWindowView {
  const std::uint32_t* x;
  const std::uint32_t* y;
  const std::uint32_t* z;
  const std::uint8_t* r;
  const std::uint8_t* g;
  const std::uint8_t* b;
  const std::uint8_t* activity;
};

// The sums of §11.4.1 over points first..i-1 for point i (i - first at most
// 32): squared distances (cell coordinates are below 2^21, so each
// |difference| fits 32 bits and the square 64), then each relative to the
// nearest: q = max(4 d, 1) shifted right by s, where s brings the nearest's q
// below 32, weighted by table[min(q >> s, kFarRatio)]. Picks the fastest form
// this CPU runs; every form gives the same integers.
WindowSums window_sums(const ColorWindowView& v, std::size_t first, std::size_t i, const std::uint32_t* table);

// The plain form, for tests.
WindowSums window_sums_plain(const ColorWindowView& v, std::size_t first, std::size_t i, const std::uint32_t* table);

}  // namespace relief::codec
