#include "codec/color_window.h"

#include <algorithm>
#include <bit>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

namespace relief::codec {

namespace {

constexpr std::size_t kWindow = 32;

}  // namespace

// Built twice, for AVX2 and for the baseline, the loader picking one (the
// same integers either way).
__attribute__((target_clones("avx2", "default"))) WindowSums window_sums_plain(const ColorWindowView& v,
                                                                               std::size_t first, std::size_t i,
                                                                               const std::uint32_t* table) {
  const std::size_t window = i - first;
  const std::uint32_t* xs = v.x + first;
  const std::uint32_t* ys = v.y + first;
  const std::uint32_t* zs = v.z + first;
  const std::uint32_t cx = v.x[i], cy = v.y[i], cz = v.z[i];
  std::uint64_t q[kWindow];
  std::uint64_t q_min = ~std::uint64_t{0};
  for (std::size_t u = 0; u < window; ++u) {
    const auto dx = static_cast<std::int32_t>(xs[u] - cx);
    const auto dy = static_cast<std::int32_t>(ys[u] - cy);
    const auto dz = static_cast<std::int32_t>(zs[u] - cz);
    const auto ax = static_cast<std::uint32_t>((dx ^ (dx >> 31)) - (dx >> 31));
    const auto ay = static_cast<std::uint32_t>((dy ^ (dy >> 31)) - (dy >> 31));
    const auto az = static_cast<std::uint32_t>((dz ^ (dz >> 31)) - (dz >> 31));
    const std::uint64_t d = std::uint64_t{ax} * ax + std::uint64_t{ay} * ay + std::uint64_t{az} * az;
    q[u] = std::max<std::uint64_t>(4 * d, 1);  // d < 3 * 2^42
    q_min = std::min(q_min, q[u]);
  }
  const int shift = std::max(0, static_cast<int>(std::bit_width(q_min)) - 5);
  // The table lookups first, then sums the compiler can vectorise (a loop
  // with both does not).
  std::uint32_t weight[kWindow];
  for (std::size_t u = 0; u < window; ++u) weight[u] = table[std::min<std::uint64_t>(q[u] >> shift, kFarRatio)];
  // Weights below 2^31 and values below 2^8: 32 products sum below 2^44.
  WindowSums s;
  const std::uint8_t* rs = v.r + first;
  const std::uint8_t* gs = v.g + first;
  const std::uint8_t* bs = v.b + first;
  const std::uint8_t* as = v.activity + first;
  for (std::size_t u = 0; u < window; ++u) {
    const std::uint64_t w = weight[u];
    s.w += w;
    s.r += w * rs[u];
    s.g += w * gs[u];
    s.b += w * bs[u];
    s.act += w * as[u];
  }
  return s;
}

#if defined(__x86_64__)

namespace {

#define RELIEF_AVX2 __attribute__((target("avx2")))

RELIEF_AVX2 inline __m256i load8(const std::uint32_t* p) {
  return _mm256_loadu_si256(reinterpret_cast<const __m256i*>(p));
}

// Weights below 2^31 times values below 2^8 in 64-bit lanes: the even
// 32-bit lanes' products, then the odd ones'.
RELIEF_AVX2 inline __m256i accumulate(__m256i sum, __m256i w, const std::uint8_t* p) {
  const __m256i value = _mm256_cvtepu8_epi32(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p)));
  const __m256i even = _mm256_mul_epu32(w, value);
  const __m256i odd = _mm256_mul_epu32(_mm256_srli_epi64(w, 32), _mm256_srli_epi64(value, 32));
  return _mm256_add_epi64(sum, _mm256_add_epi64(even, odd));
}

RELIEF_AVX2 inline std::uint64_t total(__m256i s) {
  const __m128i h = _mm_add_epi64(_mm256_castsi256_si128(s), _mm256_extracti128_si256(s, 1));
  return static_cast<std::uint64_t>(_mm_cvtsi128_si64(h)) + static_cast<std::uint64_t>(_mm_extract_epi64(h, 1));
}

// A full window whose points all lie within 2^14 - 1 cells of point i on
// every axis (nearly always: the window is the previous 32 points of a
// spatially or temporally ordered layer). Then 4 d < 12 * 2^28 < 2^32, so
// the distances, their minimum, the shift and the table lookups fit 32-bit
// lanes, eight at a time, and only the weighted sums need 64 bits. Returns
// false, with nothing computed, for any other window.
RELIEF_AVX2 bool window_sums_avx2(const ColorWindowView& v, std::size_t first, std::size_t i,
                                                      const std::uint32_t* table, WindowSums& out) {
  constexpr int kVectors = static_cast<int>(kWindow / 8);
  const __m256i cx = _mm256_set1_epi32(static_cast<int>(v.x[i]));
  const __m256i cy = _mm256_set1_epi32(static_cast<int>(v.y[i]));
  const __m256i cz = _mm256_set1_epi32(static_cast<int>(v.z[i]));
  __m256i q[kVectors];
  __m256i any = _mm256_setzero_si256();
  __m256i q_min = _mm256_set1_epi32(-1);
  const __m256i one = _mm256_set1_epi32(1);
  for (int k = 0; k < kVectors; ++k) {
    const std::size_t at = first + 8 * static_cast<std::size_t>(k);
    // |difference| as the plain form takes it: the difference's 32 bits as
    // a signed value (a point 2^31 cells away gives 0x80000000, refused below).
    const __m256i ax = _mm256_abs_epi32(_mm256_sub_epi32(load8(v.x + at), cx));
    const __m256i ay = _mm256_abs_epi32(_mm256_sub_epi32(load8(v.y + at), cy));
    const __m256i az = _mm256_abs_epi32(_mm256_sub_epi32(load8(v.z + at), cz));
    any = _mm256_or_si256(any, _mm256_or_si256(ax, _mm256_or_si256(ay, az)));
    const __m256i d = _mm256_add_epi32(_mm256_mullo_epi32(ax, ax),
                                       _mm256_add_epi32(_mm256_mullo_epi32(ay, ay), _mm256_mullo_epi32(az, az)));
    q[k] = _mm256_max_epu32(_mm256_slli_epi32(d, 2), one);
    q_min = _mm256_min_epu32(q_min, q[k]);
  }
  if (!_mm256_testz_si256(any, _mm256_set1_epi32(~((1 << 14) - 1)))) return false;
  // The minimum of the eight lanes.
  __m128i m = _mm_min_epu32(_mm256_castsi256_si128(q_min), _mm256_extracti128_si256(q_min, 1));
  m = _mm_min_epu32(m, _mm_shuffle_epi32(m, 0x4E));
  m = _mm_min_epu32(m, _mm_shuffle_epi32(m, 0xB1));
  const auto nearest = static_cast<std::uint32_t>(_mm_cvtsi128_si32(m));
  const int shift = std::max(0, static_cast<int>(std::bit_width(nearest)) - 5);
  const __m128i count = _mm_cvtsi32_si128(shift);
  const __m256i far = _mm256_set1_epi32(static_cast<int>(kFarRatio));
  const __m256i low = _mm256_set1_epi64x(0xFFFFFFFF);
  __m256i sw = _mm256_setzero_si256(), sr = sw, sg = sw, sb = sw, sa = sw;
  for (int k = 0; k < kVectors; ++k) {
    const std::size_t at = first + 8 * static_cast<std::size_t>(k);
    const __m256i index = _mm256_min_epu32(_mm256_srl_epi32(q[k], count), far);
    const __m256i w = _mm256_i32gather_epi32(reinterpret_cast<const int*>(table), index, 4);
    sw = _mm256_add_epi64(sw, _mm256_add_epi64(_mm256_and_si256(w, low), _mm256_srli_epi64(w, 32)));
    sr = accumulate(sr, w, v.r + at);
    sg = accumulate(sg, w, v.g + at);
    sb = accumulate(sb, w, v.b + at);
    sa = accumulate(sa, w, v.activity + at);
  }
  out = {total(sw), total(sr), total(sg), total(sb), total(sa)};
  return true;
}

#undef RELIEF_AVX2

bool cpu_has_avx2() {
  static const bool has = __builtin_cpu_supports("avx2") != 0;
  return has;
}

}  // namespace

#endif

WindowSums window_sums(const ColorWindowView& v, std::size_t first, std::size_t i, const std::uint32_t* table) {
#if defined(__x86_64__)
  WindowSums s;
  if (i - first == kWindow && cpu_has_avx2() && window_sums_avx2(v, first, i, table, s)) return s;
#endif
  return window_sums_plain(v, first, i, table);
}

}  // namespace relief::codec
