// Patch parameters: quantization and the local frame both sides derive from the
// quantized values (the encoder builds its maps in the dequantized frame, so
// parameter quantization moves the parameterisation, never the points).
// Internal to the codec.
#pragma once

#include <cmath>
#include <cstdint>

#include "relief/types.h"

namespace relief {

// Vector helpers, in namespace relief so argument-dependent lookup finds them.
inline Vec3d operator+(Vec3d a, Vec3d b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline Vec3d operator-(Vec3d a, Vec3d b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline Vec3d operator*(double s, Vec3d a) { return {s * a.x, s * a.y, s * a.z}; }
inline double dot(Vec3d a, Vec3d b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline Vec3d cross(Vec3d a, Vec3d b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm(Vec3d a) { return std::sqrt(dot(a, a)); }

}  // namespace relief

namespace relief::codec {

// Half the space diagonal of a unit cube: every point of a cell lies within
// this many cell edges of the cell centre, along any direction.
inline constexpr double kHalfDiagonal = 0.8660254037844386;
// Below this |n x X| the paper's e1 = n x X degenerates; e1 = n x Y is used.
inline constexpr double kAxisFallbackThreshold = 0.5;

struct QuantizedPatch {
  std::uint8_t oct_u = 0, oct_v = 0;  // octahedral normal
  std::uint8_t offset = 0;            // plane offset from the cell centre along n
  std::uint8_t umin = 0, umax = 0, vmin = 0, vmax = 0;  // extent in the plane
};

struct PatchFrame {
  Vec3d origin;      // cell centre + offset * n
  Vec3d e1, e2, n;   // right-handed orthonormal frame, n = patch normal
  double umin = 0, vmin = 0;        // extent start in the plane
  double pixel_u = 0, pixel_v = 0;  // pixel pitch along e1, e2
  double cell_edge = 0;
};

// Octahedral mapping of a unit vector to two 8-bit values and back.
void octahedral_encode(Vec3d n, std::uint8_t& u, std::uint8_t& v);
Vec3d octahedral_decode(std::uint8_t u, std::uint8_t v);

// The paper's axis-aligned frame: e1 = n x (1,0,0), e2 = n x e1, with the
// fallback e1 = n x (0,1,0) when n is (nearly) parallel to the x axis.
void axis_aligned_frame(Vec3d n, Vec3d& e1, Vec3d& e2);

// A signed value in [-range, range] on 8 bits; floor/ceil round outward.
std::uint8_t quantize_param(double value, double range, int rounding);  // -1 floor, 0 nearest, +1 ceil
double dequantize_param(std::uint8_t q, double range);

PatchFrame make_frame(const QuantizedPatch& q, Vec3d cell_center, double cell_edge,
                      int map_resolution);

}  // namespace relief::codec
