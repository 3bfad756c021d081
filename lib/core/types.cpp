#include "relief/types.h"

#include <algorithm>
#include <cmath>
#include <type_traits>

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
  c.las.for_each_vector([&f](auto& v, std::uint32_t) { f(v); });
}

}  // namespace

bool LasAttributes::empty() const { return carried() == 0; }

std::uint32_t LasAttributes::carried() const {
  std::uint32_t bits = extra_bytes.empty() ? 0u : std::uint32_t{kLasExtraBytes};
  for_each_vector([&bits](const auto& v, std::uint32_t bit) { bits |= v.empty() ? 0u : bit; });
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
  LasAttributes::for_each_vector_pair(las, a, [i](auto& to, const auto& from, std::uint32_t) {
    if (!from.empty()) to.push_back(from[i]);
  });
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
  LasAttributes::for_each_vector_pair(las, a, [&](auto& to, const auto& from, std::uint32_t) { append_column(to, from); });
  if (!a.extra_bytes.empty()) las.extra_bytes_size = a.extra_bytes_size;
  append_column(las.extra_bytes, a.extra_bytes);
}

void PointCloud::assign_range(const PointCloud& src, std::size_t first, std::size_t n) {
  // Each column of this cloud becomes the same range of src's column (empty
  // when src does not carry it); capacity is kept for the next range.
  const auto assign = [first, n](auto& dst, const auto& from, std::size_t width) {
    if (from.empty()) {
      dst.clear();
      return;
    }
    const auto begin = from.begin() + static_cast<std::ptrdiff_t>(first * width);
    dst.assign(begin, begin + static_cast<std::ptrdiff_t>(n * width));
  };
  assign(positions, src.positions, 1);
  assign(colors, src.colors, 1);
  assign(intensities, src.intensities, 1);
  LasAttributes::for_each_vector_pair(las, src.las, [&](auto& to, const auto& from, std::uint32_t) { assign(to, from, 1); });
  las.extra_bytes_size = src.las.extra_bytes_size;
  assign(las.extra_bytes, src.las.extra_bytes, src.las.extra_bytes_size);
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
  LasAttributes::for_each_vector_pair(las, out.las, [&](const auto& from, auto& to, std::uint32_t) { gather(from, to); });
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

Result<AttributeSet> parse_attribute_set(const std::string& list) {
  AttributeSet set = AttributeSet::none();
  std::size_t start = 0;
  while (start <= list.size()) {
    std::size_t end = list.find(',', start);
    if (end == std::string::npos) end = list.size();
    const std::string name = list.substr(start, end - start);
    start = end + 1;
    if (name == "all") {
      set = AttributeSet::all();
      continue;
    }
    if (name == "none" && list == "none") continue;
    if (name == "rgb") {
      set.colors = true;
      continue;
    }
    if (name == "intensity") {
      set.intensity = true;
      continue;
    }
    std::uint32_t bit = 0;
    for (std::uint32_t i = 0; i < kLasAttributeCount; ++i) {
      if (name == kLasAttributeNames[i]) bit = 1u << i;
    }
    if (bit == 0) {
      return invalid_argument("attribute " + (name.empty() ? std::string("list '" + list + "' has an empty name")
                                                           : "'" + name + "' is unknown") +
                              " (rgb, intensity, " + las_attribute_list(~std::uint32_t{0}) +
                              "; all; or none for x y z alone)");
    }
    set.las |= bit;
  }
  return set;
}

std::string attribute_set_list(const AttributeSet& set) {
  std::string out = set.colors ? "rgb" : "";
  if (set.intensity) out += out.empty() ? "intensity" : ",intensity";
  const std::string las = las_attribute_list(set.las & ((1u << kLasAttributeCount) - 1));
  if (!las.empty()) out += (out.empty() ? "" : ",") + las;
  return out;
}

void keep_attributes(PointCloud& cloud, const AttributeSet& set) {
  if (set.everything()) return;
  if (!set.colors) std::vector<Rgb8>().swap(cloud.colors);
  if (!set.intensity) std::vector<float>().swap(cloud.intensities);
  const std::uint32_t keep = set.las_kept();
  cloud.las.for_each_vector([&](auto& v, std::uint32_t bit) {
    if ((keep & bit) == 0) std::remove_reference_t<decltype(v)>().swap(v);
  });
  if ((keep & kLasExtraBytes) == 0) {
    std::vector<std::uint8_t>().swap(cloud.las.extra_bytes);
    cloud.las.extra_bytes_size = 0;
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

std::string las_metadata_problem(const LasSourceMetadata& m) {
  const std::size_t h = m.header.size();
  if (h == 0 && m.records.empty()) return "";
  if ((h != 227 && h != 235 && h != 375) || m.header[0] != 'L' || m.header[1] != 'A' || m.header[2] != 'S' ||
      m.header[3] != 'F') {
    return "a LAS header block must be 227, 235 or 375 bytes starting 'LASF' (it is " + std::to_string(h) +
           " bytes)";
  }
  for (const LasVlr& r : m.records) {
    const std::size_t limit = r.extended ? kMaxKeptLasRecord : 65535;
    if (r.data.size() > limit) {
      return "a LAS record " + std::string(r.extended ? "(extended VLR)" : "(VLR)") + " of " +
             std::to_string(r.data.size()) + " bytes is over the " + std::to_string(limit) + " bytes kept";
    }
  }
  return "";
}

}  // namespace relief
