// Bit-exact comparison of two point clouds for round-trip tests; on the first
// differing point it reports the index and both positions.
#pragma once

#include <catch2/catch.hpp>

#include <bit>
#include <cstdint>
#include <cstring>

#include "relief/types.h"

namespace relief::test {

inline void require_same(const PointCloud& got, const PointCloud& want) {
  REQUIRE(got.size() == want.size());
  REQUIRE(got.colors.size() == want.colors.size());
  REQUIRE(got.intensities.size() == want.intensities.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    const bool same_pos = std::memcmp(&got.positions[i], &want.positions[i], sizeof(Vec3d)) == 0;
    const bool same_color = !want.has_colors() || got.colors[i] == want.colors[i];
    const bool same_intensity =
        !want.has_intensity() ||
        std::bit_cast<std::uint32_t>(got.intensities[i]) == std::bit_cast<std::uint32_t>(want.intensities[i]);
    if (same_pos && same_color && same_intensity) continue;
    INFO("point " << i << ": got (" << got.positions[i].x << ", " << got.positions[i].y << ", "
                  << got.positions[i].z << ") want (" << want.positions[i].x << ", " << want.positions[i].y
                  << ", " << want.positions[i].z << ")");
    CHECK(same_pos);
    CHECK(same_color);
    REQUIRE(same_intensity);
    FAIL("point mismatch");
  }
}

// The per-point LAS attributes but colour low bytes and extra bytes, vector
// by vector (GPS times as doubles).
inline void check_same_las(const LasAttributes& got, const LasAttributes& want) {
  CHECK(got.classification == want.classification);
  CHECK(got.class_flags == want.class_flags);
  CHECK(got.return_number == want.return_number);
  CHECK(got.number_of_returns == want.number_of_returns);
  CHECK(got.scan_flags == want.scan_flags);
  CHECK(got.scan_angle == want.scan_angle);
  CHECK(got.user_data == want.user_data);
  CHECK(got.point_source_id == want.point_source_id);
  CHECK(got.gps_time == want.gps_time);
  CHECK(got.nir == want.nir);
}

}  // namespace relief::test
