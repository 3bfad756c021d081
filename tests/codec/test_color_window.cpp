// The colour window's sums (format-spec/chunk.md §11.4.1): the form this CPU
// runs (AVX2 for a full window of near points) gives the plain form's
// integers, on both weight tables, at the edges of the vector form's range
// (differences of 2^14 - 1 and 2^14 cells, far points, duplicates) and on
// short windows.
#include <catch2/catch.hpp>

#include <array>
#include <cstdint>
#include <random>
#include <vector>

#include "codec/color_window.h"

namespace {

using namespace relief::codec;

struct Window {
  std::vector<std::uint32_t> x, y, z;
  std::vector<std::uint8_t> r, g, b, act;
  ColorWindowView view() const { return {x.data(), y.data(), z.data(), r.data(), g.data(), b.data(), act.data()}; }
};

// `n` points around (2^20, 2^20, 2^20), each axis offset drawn from
// [-spread, spread], with random values.
Window random_window(std::mt19937& rng, std::size_t n, std::uint32_t spread) {
  Window w;
  std::uniform_int_distribution<std::int64_t> offset(-static_cast<std::int64_t>(spread), spread);
  std::uniform_int_distribution<int> byte(0, 255);
  for (std::size_t i = 0; i < n; ++i) {
    w.x.push_back(static_cast<std::uint32_t>((1 << 20) + offset(rng)));
    w.y.push_back(static_cast<std::uint32_t>((1 << 20) + offset(rng)));
    w.z.push_back(static_cast<std::uint32_t>((1 << 20) + offset(rng)));
    w.r.push_back(static_cast<std::uint8_t>(byte(rng)));
    w.g.push_back(static_cast<std::uint8_t>(byte(rng)));
    w.b.push_back(static_cast<std::uint8_t>(byte(rng)));
    w.act.push_back(static_cast<std::uint8_t>(byte(rng)));
  }
  return w;
}

// The two weight tables of §11.4.1: floor(2^30 / max(r, 1)^E), E = 1, 2.
std::vector<std::uint32_t> weight_table(int e) {
  std::vector<std::uint32_t> t(kFarRatio + 1);
  for (std::uint32_t r = 0; r <= kFarRatio; ++r) {
    const std::uint64_t v = r == 0 ? 1 : r;
    t[r] = static_cast<std::uint32_t>((std::uint64_t{1} << 30) / (e == 1 ? v : v * v));
  }
  return t;
}

void check_all(const Window& w, const std::vector<std::uint32_t>& table) {
  const std::size_t n = w.x.size();
  for (std::size_t i = 1; i < n; ++i) {
    const std::size_t first = i > 32 ? i - 32 : 0;
    const WindowSums fast = window_sums(w.view(), first, i, table.data());
    const WindowSums plain = window_sums_plain(w.view(), first, i, table.data());
    INFO("point " << i);
    REQUIRE(fast == plain);
  }
}

}  // namespace

TEST_CASE("the colour window's sums are the plain form's integers", "[color]") {
  std::mt19937 rng(20261128);
  const auto table1 = weight_table(1);
  const auto table2 = weight_table(2);
  // Spreads inside the vector form's range, at its edge and beyond it.
  for (const std::uint32_t spread : {0u, 1u, 3u, 40u, 1000u, (1u << 14) - 1, 1u << 14, 1u << 16, (1u << 20) - 1}) {
    INFO("spread " << spread);
    const Window w = random_window(rng, 200, spread);
    check_all(w, table1);
    check_all(w, table2);
  }
}

TEST_CASE("the colour window's sums at the edge of 2^14 cells", "[color]") {
  const auto table = weight_table(2);
  // 32 points at the largest offsets the vector form takes on every axis at
  // once, then one point 2^14 cells away on one axis, on each axis in turn.
  for (int axis = -1; axis < 3; ++axis) {
    Window w;
    for (int i = 0; i < 33; ++i) {
      const std::uint32_t base = 1u << 20;
      const std::uint32_t o = (i % 2 == 0) ? (1u << 14) - 1 : 0;
      std::array<std::uint32_t, 3> p{base + o, base - o, base + (i == 32 ? 0 : o)};
      if (i == 7 && axis >= 0) p[static_cast<std::size_t>(axis)] = base + (1u << 14);
      if (i == 32) p = {base, base, base};
      w.x.push_back(p[0]);
      w.y.push_back(p[1]);
      w.z.push_back(p[2]);
      w.r.push_back(static_cast<std::uint8_t>(255 - i));
      w.g.push_back(static_cast<std::uint8_t>(i * 7));
      w.b.push_back(255);
      w.act.push_back(255);
    }
    INFO("axis " << axis);
    REQUIRE(window_sums(w.view(), 0, 32, table.data()) == window_sums_plain(w.view(), 0, 32, table.data()));
  }
}

TEST_CASE("the colour window's sums with duplicates of the point", "[color]") {
  // Every neighbour in the point's own cell: q = 1 everywhere, the largest
  // weights (2^30) and values, the sums' largest magnitudes.
  Window w;
  for (int i = 0; i < 33; ++i) {
    w.x.push_back(5);
    w.y.push_back(6);
    w.z.push_back(7);
    w.r.push_back(255);
    w.g.push_back(255);
    w.b.push_back(255);
    w.act.push_back(255);
  }
  const auto table = weight_table(1);
  const WindowSums s = window_sums(w.view(), 0, 32, table.data());
  CHECK(s.w == 32ull << 30);
  CHECK(s.r == 255ull * (32ull << 30));
  CHECK(s == window_sums_plain(w.view(), 0, 32, table.data()));
}
