#include "relief/types.h"

#include <algorithm>
#include <cmath>

namespace relief {

const char* gps_time_type_name(GpsTimeType t) {
  switch (t) {
    case GpsTimeType::kWeek:
      return "week";
    case GpsTimeType::kStandard:
      return "standard";
    case GpsTimeType::kUnknown:
      break;
  }
  return "";
}

GpsTimeType parse_gps_time_type(const std::string& text) {
  if (text == "week") return GpsTimeType::kWeek;
  if (text == "standard") return GpsTimeType::kStandard;
  return GpsTimeType::kUnknown;
}

std::string las_attribute_list(std::uint32_t bits) {
  std::string out;
  for (std::uint32_t i = 0; i < kLasAttributeCount; ++i) {
    if ((bits & (1u << i)) == 0) continue;
    if (!out.empty()) out += ",";
    out += kLasAttributeNames[i];
  }
  return out;
}

std::uint32_t las_attributes_from_list(const std::string& list) {
  std::uint32_t bits = 0;
  std::size_t start = 0;
  while (start <= list.size()) {
    std::size_t end = list.find(',', start);
    if (end == std::string::npos) end = list.size();
    const std::string name = list.substr(start, end - start);
    for (std::uint32_t i = 0; i < kLasAttributeCount; ++i) {
      if (name == kLasAttributeNames[i]) bits |= 1u << i;
    }
    start = end + 1;
  }
  return bits;
}

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
  const std::size_t n = positions.size();
  const auto check = [&](std::size_t have, const char* name) -> Status {
    if (have == 0 || have == n) return Status::ok();
    return invalid_argument(what + ": " + std::to_string(have) + " " + name + " values for " + std::to_string(n) +
                            " points");
  };
  RELIEF_RETURN_IF_ERROR(check(las.classification.size(), "classification"));
  RELIEF_RETURN_IF_ERROR(check(las.class_flags.size(), "classification flag"));
  RELIEF_RETURN_IF_ERROR(check(las.return_number.size(), "return number"));
  RELIEF_RETURN_IF_ERROR(check(las.number_of_returns.size(), "number of returns"));
  RELIEF_RETURN_IF_ERROR(check(las.scan_flags.size(), "scan flag"));
  RELIEF_RETURN_IF_ERROR(check(las.scan_angle.size(), "scan angle"));
  RELIEF_RETURN_IF_ERROR(check(las.user_data.size(), "user data"));
  RELIEF_RETURN_IF_ERROR(check(las.point_source_id.size(), "point source ID"));
  RELIEF_RETURN_IF_ERROR(check(las.gps_time.size(), "GPS time"));
  RELIEF_RETURN_IF_ERROR(check(las.nir.size(), "NIR"));
  RELIEF_RETURN_IF_ERROR(check(las.color_low.size(), "colour low byte"));
  if (!las.color_low.empty() && colors.empty()) {
    return invalid_argument(what + ": colour low bytes without colours");
  }
  if (las.extra_bytes_size == 0 ? !las.extra_bytes.empty()
                                : las.extra_bytes.size() != n * std::size_t{las.extra_bytes_size} &&
                                      !las.extra_bytes.empty()) {
    return invalid_argument(what + ": " + std::to_string(las.extra_bytes.size()) + " extra bytes for " +
                            std::to_string(n) + " points of " + std::to_string(las.extra_bytes_size) +
                            " bytes each");
  }
  for (std::size_t i = 0; i < las.gps_time.size(); ++i) {
    if (!std::isfinite(las.gps_time[i])) {
      return invalid_argument(what + ": point " + std::to_string(i) + " has a non-finite GPS time (NaN or Inf)");
    }
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

namespace {

// Calls f(vector) for every per-point vector of the cloud except extra_bytes
// (which holds extra_bytes_size values per point).
template <typename Cloud, typename F>
void for_each_column(Cloud& c, F&& f) {
  f(c.positions);
  f(c.colors);
  f(c.intensities);
  f(c.las.classification);
  f(c.las.class_flags);
  f(c.las.return_number);
  f(c.las.number_of_returns);
  f(c.las.scan_flags);
  f(c.las.scan_angle);
  f(c.las.user_data);
  f(c.las.point_source_id);
  f(c.las.gps_time);
  f(c.las.nir);
  f(c.las.color_low);
}

}  // namespace

bool LasAttributes::empty() const {
  return classification.empty() && class_flags.empty() && return_number.empty() && number_of_returns.empty() &&
         scan_flags.empty() && scan_angle.empty() && user_data.empty() && point_source_id.empty() &&
         gps_time.empty() && nir.empty() && color_low.empty() && extra_bytes.empty();
}

std::uint32_t LasAttributes::carried() const {
  std::uint32_t bits = 0;
  const auto set = [&bits](bool has, std::uint32_t bit) { bits |= has ? bit : 0u; };
  set(!classification.empty(), kLasClassification);
  set(!class_flags.empty(), kLasClassFlags);
  set(!return_number.empty(), kLasReturnNumber);
  set(!number_of_returns.empty(), kLasNumberOfReturns);
  set(!scan_flags.empty(), kLasScanFlags);
  set(!scan_angle.empty(), kLasScanAngle);
  set(!user_data.empty(), kLasUserData);
  set(!point_source_id.empty(), kLasPointSourceId);
  set(!gps_time.empty(), kLasGpsTime);
  set(!nir.empty(), kLasNir);
  set(!color_low.empty(), kLasColorLow);
  set(!extra_bytes.empty(), kLasExtraBytes);
  return bits;
}

void PointCloud::clear_points() {
  for_each_column(*this, [](auto& v) { v.clear(); });
  las.extra_bytes.clear();
}

void PointCloud::push_back_from(const PointCloud& src, std::size_t i) {
  positions.push_back(src.positions[i]);
  if (!src.colors.empty()) colors.push_back(src.colors[i]);
  if (!src.intensities.empty()) intensities.push_back(src.intensities[i]);
  const LasAttributes& a = src.las;
  if (!a.classification.empty()) las.classification.push_back(a.classification[i]);
  if (!a.class_flags.empty()) las.class_flags.push_back(a.class_flags[i]);
  if (!a.return_number.empty()) las.return_number.push_back(a.return_number[i]);
  if (!a.number_of_returns.empty()) las.number_of_returns.push_back(a.number_of_returns[i]);
  if (!a.scan_flags.empty()) las.scan_flags.push_back(a.scan_flags[i]);
  if (!a.scan_angle.empty()) las.scan_angle.push_back(a.scan_angle[i]);
  if (!a.user_data.empty()) las.user_data.push_back(a.user_data[i]);
  if (!a.point_source_id.empty()) las.point_source_id.push_back(a.point_source_id[i]);
  if (!a.gps_time.empty()) las.gps_time.push_back(a.gps_time[i]);
  if (!a.nir.empty()) las.nir.push_back(a.nir[i]);
  if (!a.color_low.empty()) las.color_low.push_back(a.color_low[i]);
  if (!a.extra_bytes.empty()) {
    las.extra_bytes_size = a.extra_bytes_size;
    const std::size_t w = a.extra_bytes_size;
    las.extra_bytes.insert(las.extra_bytes.end(), a.extra_bytes.begin() + static_cast<std::ptrdiff_t>(i * w),
                           a.extra_bytes.begin() + static_cast<std::ptrdiff_t>((i + 1) * w));
  }
}

void PointCloud::append_points(const PointCloud& src) {
  // Pairs each column of this cloud with the same column of `src`.
  auto append_column = [](auto& dst, const auto& from) { dst.insert(dst.end(), from.begin(), from.end()); };
  append_column(positions, src.positions);
  append_column(colors, src.colors);
  append_column(intensities, src.intensities);
  const LasAttributes& a = src.las;
  append_column(las.classification, a.classification);
  append_column(las.class_flags, a.class_flags);
  append_column(las.return_number, a.return_number);
  append_column(las.number_of_returns, a.number_of_returns);
  append_column(las.scan_flags, a.scan_flags);
  append_column(las.scan_angle, a.scan_angle);
  append_column(las.user_data, a.user_data);
  append_column(las.point_source_id, a.point_source_id);
  append_column(las.gps_time, a.gps_time);
  append_column(las.nir, a.nir);
  append_column(las.color_low, a.color_low);
  if (!a.extra_bytes.empty()) las.extra_bytes_size = a.extra_bytes_size;
  append_column(las.extra_bytes, a.extra_bytes);
}

PointCloud PointCloud::gathered(const std::vector<std::uint32_t>& order) const {
  PointCloud out;
  out.las.extra_bytes_size = las.extra_bytes_size;
  const auto gather = [&order](const auto& src, auto& dst) {
    if (src.empty()) return;
    dst.resize(order.size());
    for (std::size_t k = 0; k < order.size(); ++k) dst[k] = src[order[k]];
  };
  gather(positions, out.positions);
  gather(colors, out.colors);
  gather(intensities, out.intensities);
  gather(las.classification, out.las.classification);
  gather(las.class_flags, out.las.class_flags);
  gather(las.return_number, out.las.return_number);
  gather(las.number_of_returns, out.las.number_of_returns);
  gather(las.scan_flags, out.las.scan_flags);
  gather(las.scan_angle, out.las.scan_angle);
  gather(las.user_data, out.las.user_data);
  gather(las.point_source_id, out.las.point_source_id);
  gather(las.gps_time, out.las.gps_time);
  gather(las.nir, out.las.nir);
  gather(las.color_low, out.las.color_low);
  if (!las.extra_bytes.empty()) {
    const std::size_t w = las.extra_bytes_size;
    out.las.extra_bytes.resize(order.size() * w);
    for (std::size_t k = 0; k < order.size(); ++k) {
      std::copy_n(las.extra_bytes.begin() + static_cast<std::ptrdiff_t>(order[k] * w), w,
                  out.las.extra_bytes.begin() + static_cast<std::ptrdiff_t>(k * w));
    }
  }
  return out;
}

void PointCloud::resize_points(std::size_t n) {
  for_each_column(*this, [n](auto& v) {
    if (!v.empty()) v.resize(n);
  });
  positions.resize(n);
  if (!las.extra_bytes.empty()) las.extra_bytes.resize(n * std::size_t{las.extra_bytes_size});
}

void conform_las_attributes(PointCloud& cloud, std::uint32_t bits, std::uint32_t extra_bytes_size) {
  const std::size_t n = cloud.size();
  LasAttributes& a = cloud.las;
  if (cloud.colors.size() != n) bits &= ~std::uint32_t{kLasColorLow};
  const bool low_missing = (bits & kLasColorLow) != 0 && a.color_low.size() != n;
  // for_each_column visits positions, colours and intensities, then the LAS
  // vectors in LasAttributeBits order.
  constexpr int kBaseColumns = 3;
  int column = 0;
  std::uint32_t bit = 1;
  for_each_column(cloud, [&](auto& v) {
    if (column++ < kBaseColumns) return;
    if ((bits & bit) == 0) {
      v.clear();
    } else if (v.size() != n) {
      v.assign(n, {});
    }
    bit <<= 1;
  });
  if (low_missing) std::copy(cloud.colors.begin(), cloud.colors.end(), a.color_low.begin());
  if ((bits & kLasExtraBytes) == 0) {
    a.extra_bytes.clear();
    a.extra_bytes_size = 0;
  } else if (a.extra_bytes_size != extra_bytes_size || a.extra_bytes.size() != n * std::size_t{extra_bytes_size}) {
    a.extra_bytes.assign(n * std::size_t{extra_bytes_size}, 0);
    a.extra_bytes_size = extra_bytes_size;
  }
}

bool PointCloud::same_attributes(const PointCloud& other) const {
  const auto flags = [](const PointCloud& c) {
    std::vector<bool> f;
    for_each_column(c, [&f](const auto& v) { f.push_back(!v.empty()); });
    f.push_back(!c.las.extra_bytes.empty());
    return f;
  };
  return flags(*this) == flags(other) && las.extra_bytes_size == other.las.extra_bytes_size;
}

}  // namespace relief
