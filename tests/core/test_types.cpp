// relief/types.h: the one list of LasAttributes' per-point vectors, and the
// PointCloud operations built on it.
#include <catch2/catch.hpp>

#include <cstdint>
#include <cstdlib>
#include <vector>

#include "relief/types.h"

namespace relief {

TEST_CASE("LasAttributes::for_each_vector visits every per-point vector once, in bit order", "[core]") {
  LasAttributes a;
  std::vector<std::uint32_t> bits;
  a.for_each_vector([&](auto& v, std::uint32_t bit) {
    bits.push_back(bit);
    v.resize(bits.size());  // vector k gets k + 1 values
  });
  const std::vector<std::uint32_t> expect = {kLasClassification, kLasClassFlags, kLasReturnNumber,
                                             kLasNumberOfReturns, kLasScanFlags,  kLasScanAngle,
                                             kLasUserData,        kLasPointSourceId, kLasGpsTime,
                                             kLasNir,             kLasColorLow};
  CHECK(bits == expect);
  // Each member by name: a vector left out of the list would stay empty.
  CHECK(a.classification.size() == 1);
  CHECK(a.class_flags.size() == 2);
  CHECK(a.return_number.size() == 3);
  CHECK(a.number_of_returns.size() == 4);
  CHECK(a.scan_flags.size() == 5);
  CHECK(a.scan_angle.size() == 6);
  CHECK(a.user_data.size() == 7);
  CHECK(a.point_source_id.size() == 8);
  CHECK(a.gps_time.size() == 9);
  CHECK(a.nir.size() == 10);
  CHECK(a.color_low.size() == 11);
  CHECK(a.extra_bytes.empty());
  CHECK(a.carried() == 0x7FFu);
  CHECK_FALSE(a.empty());
  a.extra_bytes = {1};
  CHECK(a.carried() == 0xFFFu);
  CHECK(LasAttributes{}.empty());
  CHECK(LasAttributes{}.carried() == 0);
}

TEST_CASE("PointCloud gathers, appends and copies a point with every LAS attribute", "[core]") {
  PointCloud c;
  for (int i = 0; i < 4; ++i) {
    c.positions.push_back({static_cast<double>(i), 0, 0});
    c.las.classification.push_back(static_cast<std::uint8_t>(i));
    c.las.gps_time.push_back(i + 0.5);
    c.las.color_low.push_back({static_cast<std::uint8_t>(i), 1, 2});
    c.las.extra_bytes.push_back(static_cast<std::uint8_t>(10 + i));
    c.las.extra_bytes.push_back(static_cast<std::uint8_t>(20 + i));
  }
  c.las.extra_bytes_size = 2;
  const PointCloud g = c.gathered({3, 1});
  CHECK(g.las.classification == std::vector<std::uint8_t>{3, 1});
  CHECK(g.las.gps_time == std::vector<double>{3.5, 1.5});
  REQUIRE(g.las.color_low.size() == 2);
  CHECK(g.las.color_low[0].r == 3);
  CHECK(g.las.extra_bytes == std::vector<std::uint8_t>{13, 23, 11, 21});
  CHECK(g.las.carried() == c.las.carried());
  PointCloud a = g;
  a.append_points(c);
  CHECK(a.size() == 6);
  CHECK(a.las.gps_time.size() == 6);
  CHECK(a.las.gps_time[5] == 3.5);
  PointCloud one;
  one.push_back_from(c, 2);
  CHECK(one.las.classification == std::vector<std::uint8_t>{2});
  CHECK(one.las.color_low.size() == 1);
  CHECK(one.las.extra_bytes == std::vector<std::uint8_t>{12, 22});
  CHECK(one.las.scan_angle.empty());
}

}  // namespace relief

TEST_CASE("las_color_level inverts split_8bit_level for every level, and keeps the 16-bit rule", "[core]") {
  std::uint32_t above_255_with_equal_bytes = 0;
  for (std::uint32_t v = 0; v <= 65535; ++v) {
    std::uint8_t colour = 0, low = 0;
    relief::split_8bit_level(static_cast<std::uint16_t>(v), colour, low);
    if (relief::las_color_level(colour, low, true) != v) FAIL("level " << v << " split as " << int{colour} << "/" << int{low});
    // Levels up to 255 are the colour twice (what archives of 8-bit levels
    // always held); levels above never are, and their colour is about v / 256.
    if ((v <= 255) != (colour == low)) ++above_255_with_equal_bytes;
    if (v <= 255 && colour != v) FAIL("level " << v << " has colour " << int{colour});
    if (v > 255 && std::abs(static_cast<int>(colour) - static_cast<int>(v / 256)) > 1) FAIL("level " << v << " has colour " << int{colour});
  }
  CHECK(above_255_with_equal_bytes == 0);
  // 16-bit levels: the high byte and the low byte.
  CHECK(relief::las_color_level(0x12, 0x34, false) == 0x1234);
  CHECK(relief::las_color_level(200, 200, false) == 200 * 257);
  CHECK(relief::las_color_level(200, 200, true) == 200);
}
