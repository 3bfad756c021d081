// Seeded synthetic scenes for tests and benchmarks. The same seed gives the
// same cloud on every platform (own PRNG, no std::distribution).
#pragma once

#include <cstdint>
#include <vector>

#include "relief/types.h"

namespace relief::test {

// SplitMix64: small, fast and fully specified.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next();
  double uniform();                    // [0, 1)
  double uniform(double a, double b);  // [a, b)
  double normal();                     // standard normal (Box-Muller)
  // A uniformly random permutation of 0..n-1 (Fisher-Yates).
  std::vector<std::uint32_t> permutation(std::size_t n);

 private:
  std::uint64_t state_;
};

struct SceneOptions {
  std::uint64_t seed = 1;
  std::size_t points = 10000;
  double noise = 0;        // Gaussian noise sigma along the surface normal
  bool colors = false;     // smooth colour gradient plus texture
  bool intensity = false;  // smooth intensity field
  Vec3d offset{0, 0, 0};   // added to every point (georeferenced-style coordinates)
};

// Points on a size x size square through the origin with unit normal `normal`.
PointCloud make_plane(const SceneOptions& o, Vec3d normal, double size);
// Points on a sphere of the given radius centred at the origin.
PointCloud make_sphere(const SceneOptions& o, double radius);
// A wavy terrain z = a sin(x) cos(y) over size x size.
PointCloud make_terrain(const SceneOptions& o, double size, double amplitude);
// A room-like scene: floor, walls and a box, size metres across.
PointCloud make_room(const SceneOptions& o, double size);
// An airborne scan of a wavy terrain with trees, size metres square: scan
// lines across x, flown back and forth, one pulse every 25 cm along a line
// and 50 cm between lines, in the order a scanner records them. A pulse that
// hits a tree (about one in five) has 2 or 3 returns with the same time,
// canopy first. Fills positions (o.points in all, o.noise ignored), the
// colours and intensities o asks for, and las.return_number,
// number_of_returns and gps_time.
PointCloud make_airborne_scan(const SceneOptions& o, double size);

}  // namespace relief::test
