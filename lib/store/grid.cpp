// The voxel key of the archive grid (format-spec/archive.md, section 4).
#include <cmath>
#include <cstdint>
#include <limits>

#include "relief/archive.h"

namespace relief {
namespace {

// floor((p - origin) / edge) as an int64. The formula is the format's
// definition, evaluated in IEEE double exactly as written, so every writer
// puts a point on the same side of a chunk face.
//
// Choice for out-of-range values: saturate. key_of has no error channel and a
// finite coordinate only leaves the int64 range with an absurd edge (|p| /
// edge >= 2^63, e.g. 1e6 m with an edge below 1e-13 m); ingest validates the
// edge and the points (finite) before it asks for keys, so saturation is a
// last line of defence that keeps the conversion defined, not a feature.
// NaN, which validated clouds never contain, maps to 0.
std::int64_t axis_key(double p, double origin, double edge) {
  const double k = std::floor((p - origin) / edge);
  // 2^63 is exact in double; every double below it converts without overflow.
  constexpr double kLimit = 9223372036854775808.0;
  if (std::isnan(k)) return 0;
  if (k >= kLimit) return std::numeric_limits<std::int64_t>::max();
  if (k < -kLimit) return std::numeric_limits<std::int64_t>::min();
  return static_cast<std::int64_t>(k);
}

}  // namespace

ChunkKey ArchiveGrid::key_of(const Vec3d& p) const {
  return {axis_key(p.x, origin.x, chunk_edge), axis_key(p.y, origin.y, chunk_edge),
          axis_key(p.z, origin.z, chunk_edge)};
}

void ArchiveGrid::keys_of(const Vec3d* points, std::size_t n, ChunkKey* out) const {
  // floor without a libm call: truncate, then step down when truncation
  // rounded up (negative non-integers). Exact for |q| < 2^62, where the int64
  // conversion is exact and cannot overflow; anything else goes through the
  // saturating axis_key.
  constexpr double kFast = 4611686018427387904.0;  // 2^62
  const double e = chunk_edge;
  const auto fast_floor = [](double q) {
    const auto t = static_cast<std::int64_t>(q);
    return t - (static_cast<double>(t) > q ? 1 : 0);
  };
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3d& p = points[i];
    const double qx = (p.x - origin.x) / e;
    const double qy = (p.y - origin.y) / e;
    const double qz = (p.z - origin.z) / e;
    if (std::abs(qx) < kFast && std::abs(qy) < kFast && std::abs(qz) < kFast) {
      out[i] = {fast_floor(qx), fast_floor(qy), fast_floor(qz)};
    } else {
      out[i] = key_of(p);
    }
  }
}

Box3d ArchiveGrid::chunk_box(const ChunkKey& key) const {
  // The nominal cube of the key. key_of rounds twice (subtraction, division),
  // so a point within an ulp or so of a face may be keyed to the cube beside
  // the one this box describes; queries therefore use the stored bounds of
  // the decoded points, never this box.
  const double ix = static_cast<double>(key.ix);
  const double iy = static_cast<double>(key.iy);
  const double iz = static_cast<double>(key.iz);
  Box3d box;
  box.min = {origin.x + ix * chunk_edge, origin.y + iy * chunk_edge, origin.z + iz * chunk_edge};
  // i + 1 in double: an int64 key + 1 could overflow.
  box.max = {origin.x + (ix + 1) * chunk_edge, origin.y + (iy + 1) * chunk_edge,
             origin.z + (iz + 1) * chunk_edge};
  return box;
}

}  // namespace relief
