// The LAS attributes of an ingest (PointCloud::las) as one set for every
// batch: zero-filled for inputs that lack one, packed into bucket records.
// Internal to the ingest module.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "relief/types.h"

namespace relief::ingest {

// Calls f(vector, bit) for each per-point LasAttributes vector except
// extra_bytes (which holds extra_bytes_size values per point).
template <typename Las, typename F>
void for_each_las_column(Las& a, F&& f) {
  f(a.classification, kLasClassification);
  f(a.class_flags, kLasClassFlags);
  f(a.return_number, kLasReturnNumber);
  f(a.number_of_returns, kLasNumberOfReturns);
  f(a.scan_flags, kLasScanFlags);
  f(a.scan_angle, kLasScanAngle);
  f(a.user_data, kLasUserData);
  f(a.point_source_id, kLasPointSourceId);
  f(a.gps_time, kLasGpsTime);
  f(a.nir, kLasNir);
  f(a.color_low, kLasColorLow);
}

// Gives `batch` exactly the LAS attributes `bits` (relief/types.h).
inline void conform_las(PointCloud& batch, std::uint32_t bits, std::uint32_t extra_size) {
  conform_las_attributes(batch, bits, extra_size);
}

// Sizes every vector of `bits` to n points (others cleared).
inline void resize_las(LasAttributes& a, std::size_t n, std::uint32_t bits, std::uint32_t extra_size) {
  for_each_las_column(a, [&](auto& v, std::uint32_t bit) { v.resize((bits & bit) != 0 ? n : 0); });
  const bool extra = (bits & kLasExtraBytes) != 0;
  a.extra_bytes_size = extra ? extra_size : 0;
  a.extra_bytes.resize(extra ? n * std::size_t{extra_size} : 0);
}

// Reserves room for n points in every vector of `bits`.
inline void reserve_las(LasAttributes& a, std::size_t n, std::uint32_t bits, std::uint32_t extra_size) {
  for_each_las_column(a, [&](auto& v, std::uint32_t bit) {
    if ((bits & bit) != 0) v.reserve(n);
  });
  if ((bits & kLasExtraBytes) != 0) a.extra_bytes.reserve(n * std::size_t{extra_size});
}

// Copies the carried vectors of `src` into `dst` from point `at` on (dst sized).
inline void copy_las(const LasAttributes& src, LasAttributes& dst, std::size_t at) {
  const auto copy = [at](const auto& from, auto& to) {
    if (!from.empty()) std::copy(from.begin(), from.end(), to.begin() + static_cast<std::ptrdiff_t>(at));
  };
  copy(src.classification, dst.classification);
  copy(src.class_flags, dst.class_flags);
  copy(src.return_number, dst.return_number);
  copy(src.number_of_returns, dst.number_of_returns);
  copy(src.scan_flags, dst.scan_flags);
  copy(src.scan_angle, dst.scan_angle);
  copy(src.user_data, dst.user_data);
  copy(src.point_source_id, dst.point_source_id);
  copy(src.gps_time, dst.gps_time);
  copy(src.nir, dst.nir);
  copy(src.color_low, dst.color_low);
  if (!src.extra_bytes.empty()) {
    std::copy(src.extra_bytes.begin(), src.extra_bytes.end(),
              dst.extra_bytes.begin() + static_cast<std::ptrdiff_t>(at * src.extra_bytes_size));
  }
}

// Bytes of the LAS attributes in one bucket record: each carried value in its
// own width, in LasAttributeBits order, then the extra bytes.
inline std::size_t las_record_bytes(std::uint32_t bits, std::uint32_t extra_size) {
  std::size_t n = 0;
  LasAttributes probe;
  for_each_las_column(probe, [&](auto& v, std::uint32_t bit) {
    if ((bits & bit) != 0) n += sizeof(typename std::decay_t<decltype(v)>::value_type);
  });
  if ((bits & kLasExtraBytes) != 0) n += extra_size;
  return n;
}

// Native byte order: the bucket files never leave the process that wrote
// them, so the values are copied as they are.
inline std::uint8_t* put_las_record(std::uint8_t* r, const LasAttributes& a, std::size_t i, std::uint32_t bits) {
  for_each_las_column(a, [&](const auto& v, std::uint32_t bit) {
    if ((bits & bit) == 0) return;
    std::memcpy(r, &v[i], sizeof v[i]);
    r += sizeof v[i];
  });
  if ((bits & kLasExtraBytes) != 0) {
    const std::size_t w = a.extra_bytes_size;
    std::memcpy(r, a.extra_bytes.data() + i * w, w);
    r += w;
  }
  return r;
}

inline const std::uint8_t* get_las_record(const std::uint8_t* r, LasAttributes& a, std::size_t k,
                                          std::uint32_t bits) {
  for_each_las_column(a, [&](auto& v, std::uint32_t bit) {
    if ((bits & bit) == 0) return;
    std::memcpy(&v[k], r, sizeof v[k]);
    r += sizeof v[k];
  });
  if ((bits & kLasExtraBytes) != 0) {
    const std::size_t w = a.extra_bytes_size;
    std::memcpy(a.extra_bytes.data() + k * w, r, w);
    r += w;
  }
  return r;
}

}  // namespace relief::ingest
