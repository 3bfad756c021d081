#include "codec/patch.h"

#include <algorithm>

namespace relief::codec {

namespace {

double sign_nonzero(double v) { return v < 0 ? -1.0 : 1.0; }

std::uint8_t to_u8(double unit) {  // [-1, 1] -> 0..255
  const double q = std::round((std::clamp(unit, -1.0, 1.0) + 1.0) * 0.5 * 255.0);
  return static_cast<std::uint8_t>(q);
}

double from_u8(std::uint8_t q) { return static_cast<double>(q) / 255.0 * 2.0 - 1.0; }

Vec3d normalized_or(Vec3d v, Vec3d fallback) {
  const double l = norm(v);
  if (!(l > 1e-300) || !std::isfinite(l)) return fallback;
  return (1.0 / l) * v;
}

}  // namespace

void octahedral_encode(Vec3d n, std::uint8_t& u, std::uint8_t& v) {
  const double l1 = std::abs(n.x) + std::abs(n.y) + std::abs(n.z);
  double px = n.x / l1, py = n.y / l1;
  if (n.z < 0) {
    const double ox = px;
    px = (1.0 - std::abs(py)) * sign_nonzero(ox);
    py = (1.0 - std::abs(ox)) * sign_nonzero(py);
  }
  u = to_u8(px);
  v = to_u8(py);
}

Vec3d octahedral_decode(std::uint8_t u, std::uint8_t v) {
  double x = from_u8(u), y = from_u8(v);
  const double z = 1.0 - std::abs(x) - std::abs(y);
  if (z < 0) {
    const double ox = x;
    x = (1.0 - std::abs(y)) * sign_nonzero(ox);
    y = (1.0 - std::abs(ox)) * sign_nonzero(y);
  }
  return normalized_or({x, y, z}, {0, 0, 1});
}

void axis_aligned_frame(Vec3d n, Vec3d& e1, Vec3d& e2) {
  const Vec3d by_x = cross(n, {1, 0, 0});
  if (norm(by_x) >= kAxisFallbackThreshold) {
    e1 = normalized_or(by_x, {0, 1, 0});
  } else {
    e1 = normalized_or(cross(n, {0, 1, 0}), {0, 0, 1});
  }
  e2 = cross(n, e1);  // unit: n and e1 are orthonormal
}

std::uint8_t quantize_param(double value, double range, int rounding) {
  double t = (value + range) / (2.0 * range) * 255.0;
  if (rounding < 0) {
    t = std::floor(t);
  } else if (rounding > 0) {
    t = std::ceil(t);
  } else {
    t = std::round(t);
  }
  return static_cast<std::uint8_t>(std::clamp(t, 0.0, 255.0));
}

double dequantize_param(std::uint8_t q, double range) {
  return -range + static_cast<double>(q) * (2.0 * range / 255.0);
}

PatchFrame make_frame(const QuantizedPatch& q, Vec3d cell_center, double cell_edge,
                      int map_resolution) {
  PatchFrame f;
  f.cell_edge = cell_edge;
  f.n = octahedral_decode(q.oct_u, q.oct_v);
  axis_aligned_frame(f.n, f.e1, f.e2);
  const double range = kHalfDiagonal * cell_edge;
  f.origin = cell_center + dequantize_param(q.offset, range) * f.n;
  f.umin = dequantize_param(q.umin, range);
  f.vmin = dequantize_param(q.vmin, range);
  const double r = static_cast<double>(map_resolution);
  f.pixel_u = (dequantize_param(q.umax, range) - f.umin) / r;
  f.pixel_v = (dequantize_param(q.vmax, range) - f.vmin) / r;
  return f;
}

}  // namespace relief::codec
