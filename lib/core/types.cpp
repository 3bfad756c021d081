#include "relief/types.h"

#include <algorithm>
#include <cmath>

namespace relief {

Vec3d Box3d::extent() const {
  if (empty()) return {};
  return {max.x - min.x, max.y - min.y, max.z - min.z};
}

double Box3d::diagonal() const {
  const Vec3d e = extent();
  return std::sqrt(e.x * e.x + e.y * e.y + e.z * e.z);
}

Status PointCloud::validate(const std::string& what) const {
  if (!colors.empty() && colors.size() != positions.size()) {
    return invalid_argument(what + ": " + std::to_string(colors.size()) + " colours for " +
                            std::to_string(positions.size()) + " points");
  }
  if (!intensities.empty() && intensities.size() != positions.size()) {
    return invalid_argument(what + ": " + std::to_string(intensities.size()) +
                            " intensities for " + std::to_string(positions.size()) + " points");
  }
  for (std::size_t i = 0; i < positions.size(); ++i) {
    const Vec3d& p = positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      return invalid_argument(what + ": point " + std::to_string(i) +
                              " has a non-finite coordinate (NaN or Inf)");
    }
  }
  for (std::size_t i = 0; i < intensities.size(); ++i) {
    if (!std::isfinite(intensities[i])) {
      return invalid_argument(what + ": point " + std::to_string(i) +
                              " has a non-finite intensity (NaN or Inf)");
    }
  }
  return Status::ok();
}

Box3d PointCloud::bounds() const {
  Box3d b;
  for (const Vec3d& p : positions) b.add(p);
  return b;
}

void PointCloud::reserve(std::size_t n, bool with_colors, bool with_intensity) {
  positions.reserve(n);
  if (with_colors) colors.reserve(n);
  if (with_intensity) intensities.reserve(n);
}

}  // namespace relief
