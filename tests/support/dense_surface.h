// A dense wavy surface for the ingest's memory and split tests: n points over
// [0, 2] x [0, 2] m, z = 0.3 + 0.2 sin 3x + 0.1 cos 2y plus 2 mm of noise.
#pragma once

#include <cmath>
#include <cstdint>
#include <random>

#include "relief/types.h"

namespace relief::test {

// `skewed`: x denser towards 0 (octants of different sizes).
inline PointCloud dense_surface(std::size_t n, std::uint64_t seed, bool skewed = false) {
  PointCloud dense;
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 2.0);
  std::normal_distribution<double> noise(0.0, 0.002);
  dense.positions.resize(n);
  for (Vec3d& p : dense.positions) {
    p.x = skewed ? u(rng) * u(rng) / 2 + 0.5 * u(rng) : u(rng);
    p.y = u(rng);
    p.z = 0.3 + 0.2 * std::sin(3 * p.x) + 0.1 * std::cos(2 * p.y) + noise(rng);
  }
  return dense;
}

}  // namespace relief::test
