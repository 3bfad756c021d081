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

// Gives `batch` exactly the LAS attributes `bits` (relief/types.h).
inline void conform_las(PointCloud& batch, std::uint32_t bits, std::uint32_t extra_size) {
  conform_las_attributes(batch, bits, extra_size);
}

// Sizes every vector of `bits` to n points (others cleared).
inline void resize_las(LasAttributes& a, std::size_t n, std::uint32_t bits, std::uint32_t extra_size) {
  a.for_each_vector([&](auto& v, std::uint32_t bit) { v.resize((bits & bit) != 0 ? n : 0); });
  const bool extra = (bits & kLasExtraBytes) != 0;
  a.extra_bytes_size = extra ? extra_size : 0;
  a.extra_bytes.resize(extra ? n * std::size_t{extra_size} : 0);
}

// Reserves room for n points in every vector of `bits`.
inline void reserve_las(LasAttributes& a, std::size_t n, std::uint32_t bits, std::uint32_t extra_size) {
  a.for_each_vector([&](auto& v, std::uint32_t bit) {
    if ((bits & bit) != 0) v.reserve(n);
  });
  if ((bits & kLasExtraBytes) != 0) a.extra_bytes.reserve(n * std::size_t{extra_size});
}

// Copies the carried vectors of `src` into `dst` from point `at` on (dst sized).
inline void copy_las(const LasAttributes& src, LasAttributes& dst, std::size_t at) {
  const auto copy = [at](const auto& from, auto& to) {
    if (!from.empty()) std::copy(from.begin(), from.end(), to.begin() + static_cast<std::ptrdiff_t>(at));
  };
  LasAttributes::for_each_vector_pair(src, dst, [&](const auto& from, auto& to, std::uint32_t) { copy(from, to); });
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
  probe.for_each_vector([&](auto& v, std::uint32_t bit) {
    if ((bits & bit) != 0) n += sizeof(typename std::decay_t<decltype(v)>::value_type);
  });
  if ((bits & kLasExtraBytes) != 0) n += extra_size;
  return n;
}

// Native byte order: the bucket files never leave the process that wrote
// them, so the values are copied as they are.
inline std::uint8_t* put_las_record(std::uint8_t* r, const LasAttributes& a, std::size_t i, std::uint32_t bits) {
  a.for_each_vector([&](const auto& v, std::uint32_t bit) {
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
  a.for_each_vector([&](auto& v, std::uint32_t bit) {
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
