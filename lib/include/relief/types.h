// Basic value types shared by every Relief module.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "relief/status.h"

namespace relief {

struct Vec3d {
  double x = 0, y = 0, z = 0;
  friend bool operator==(const Vec3d&, const Vec3d&) = default;
};

struct Rgb8 {
  std::uint8_t r = 0, g = 0, b = 0;
  friend bool operator==(const Rgb8&, const Rgb8&) = default;
};

// Axis-aligned box; empty() until the first point is added.
struct Box3d {
  Vec3d min{+1e308, +1e308, +1e308};
  Vec3d max{-1e308, -1e308, -1e308};

  bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
  void add(const Vec3d& p) {
    // Inline: ingest and the codec call this once per point.
    min.x = p.x < min.x ? p.x : min.x;
    min.y = p.y < min.y ? p.y : min.y;
    min.z = p.z < min.z ? p.z : min.z;
    max.x = p.x > max.x ? p.x : max.x;
    max.y = p.y > max.y ? p.y : max.y;
    max.z = p.z > max.z ? p.z : max.z;
  }
  // Length of the diagonal; 0 for an empty box.
  double diagonal() const;
  Vec3d extent() const;
};

// A point cloud with optional per-point attributes. Coordinates are double
// end to end so georeferenced data keeps sub-millimetre precision.
struct PointCloud {
  std::vector<Vec3d> positions;
  std::vector<Rgb8> colors;         // empty, or one per position
  std::vector<float> intensities;   // empty, or one per position

  std::size_t size() const { return positions.size(); }
  bool empty() const { return positions.empty(); }
  bool has_colors() const { return !colors.empty(); }
  bool has_intensity() const { return !intensities.empty(); }

  // Attribute arrays match the positions and every coordinate and intensity
  // is finite. `what` names the cloud in the error (a file name, "chunk").
  Status validate(const std::string& what) const;
  Box3d bounds() const;
  void reserve(std::size_t n, bool with_colors, bool with_intensity);
};

}  // namespace relief
