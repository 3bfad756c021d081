// Octree occupancy coding for the error-bounded layer. Mirror pair in one file:
// encoder and decoder share the traversal (code_octree) and differ only in the
// bit coder they pass, so they cannot drift apart.
//
// Nodes of one level are visited in Morton order. Decreasing one coordinate
// decreases the Morton key, so when a node is visited its -x, -y and -z
// neighbours (and all their children) are already known to the decoder; its
// +x, +y, +z neighbours are known to exist or not (the whole level is known
// before its children are coded) but not their children.
//
// Codec 8 (chunk format 7) makes codec 7's decisions with probabilities
// mixed from two context models (mix_code below). Codec 11 (chunk format 10)
// is codec 8 with chains: an isolated node's one-cell subtree coded with the
// plain index models, no flag and no mixing (format-spec/chunk.md §11.3.4).
// Codec 12 (chunk format 13) is codec 11 with a third model in every mix and
// an adaptive probability map after it (mix_code_faces, §11.3.5). Codec 13
// (chunk format 16) is codec 12 with each single child's index bits (and a
// chain's) predicted by a plane fitted to the nearby cells the decoder knows
// (PlaneSums, §11.3.6). Codec 14 (chunk format 17) is codec 13 with those
// index bits also told which of the two halves lies nearer the known points
// around the node (near_class, §11.3.7).
#include "codec/geometry_coder.h"

#include <algorithm>
#include <array>
#include <bit>
#include <memory>
#include <string>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif
#if defined(__x86_64__)
#include <immintrin.h>
#endif

#include "codec/octree.h"
#include "codec/range_coder.h"

namespace relief::codec {

namespace {

// Context of one child bit: 14 bits (see format-spec/chunk.md).
constexpr int kOccupancyContexts = 1 << 14;
constexpr int kCountContexts = 2;

// Single-child coding (codec 7): the "exactly one child" flag's contexts
// (occupied face neighbours 0..3, parent had one child, levels to the leaves
// 0..3) and the index bits' (tree position 1..7, the axis's plane prediction,
// the node's -a/+a face neighbours, the -a neighbour has children, levels to
// the leaves).
constexpr int kSingleFlagContexts = 4 * 2 * 4;
constexpr int kSingleIndexContexts = 8 * 3 * 4 * 2 * 4;

// ---- Mixing (codec 8). Each bit of codec 7's three kinds (single-child
// flag, single-child index, child bit of a multi-child node) is coded with a
// probability mixed in the logistic domain from codec 7's model for it (its
// fast and slow estimates) and a second model with a different context,
// weighted by a small online-trained mixer. Integer arithmetic only, so
// encoder and decoder agree on every platform (format-spec/chunk.md §11.3.2).
//
// Logit domain: st = 256 ln(p / (1 - p)), within +-2047.
// squash(x) = 2^16 / (1 + e^(-x/256)), by linear interpolation between 33
// knots at x = 128 (i - 16), the formula rounded to integers.
constexpr std::int32_t kSquashKnots[33] = {22,    36,    60,    98,    162,   267,   439,   720,   1179,
                                           1921,  3108,  4971,  7812,  11955, 17625, 24743, 32768, 40793,
                                           47911, 53581, 57724, 60565, 62428, 63615, 64357, 64816, 65097,
                                           65269, 65374, 65438, 65476, 65500, 65514};
constexpr std::int32_t squash(std::int32_t x) {
  if (x > 2047) x = 2047;
  if (x < -2047) x = -2047;
  const std::int32_t w = x & 127;  // two's complement: x = 128 (i - 16) + w
  const std::int32_t i = (x >> 7) + 16;
  return (kSquashKnots[i] * (128 - w) + kSquashKnots[i + 1] * w + 64) >> 7;
}
// stretch of a probability by its top 12 bits j = p >> 4: the smallest x in
// [-2047, 2047] with squash(x) >> 4 >= j, 2047 when there is none (so
// stretch inverts squash).
constexpr auto kStretch = [] {
  std::array<std::int16_t, 4096> t{};
  std::int32_t j = 0;
  for (std::int32_t x = -2047; x <= 2047; ++x) {
    for (const std::int32_t v = squash(x) >> 4; j <= v; ++j) t[static_cast<std::size_t>(j)] = static_cast<std::int16_t>(x);
  }
  for (; j < 4096; ++j) t[static_cast<std::size_t>(j)] = 2047;
  return t;
}();
// The same functions as tables for the coding loop (byte-for-byte the values
// above): squash over its whole clamped domain by x + 2047, and stretch of a
// model's clamped mean p0() by (fast + slow) >> 5 (kProbMax >> 4 = 4094).
// Each squash entry holds p = squash(x) in its low 16 bits and p clamped to
// [kProbMin, kProbMax] (what is coded with) in its high 16.
constexpr auto kSquashTable = [] {
  std::array<std::uint32_t, 4095> t{};
  for (std::int32_t x = -2047; x <= 2047; ++x) {
    const auto p = static_cast<std::uint32_t>(squash(x));
    t[static_cast<std::size_t>(x + 2047)] = p | (std::clamp(p, kProbMin, kProbMax) << 16);
  }
  return t;
}();
static_assert(kProbMax >> 4 == 4094 && (kProbMax & 15) == 0);
constexpr auto kStretchMean = [] {
  std::array<std::int16_t, 4096> t{};
  for (std::size_t j = 0; j < 4096; ++j) t[j] = kStretch[std::min<std::size_t>(j, kProbMax >> 4)];
  return t;
}();

// Second models' contexts: child bits by the node's six face neighbours and
// the child byte so far (1 then the k bits below child k: 1..255); single-child
// flags by the face neighbours, the minus neighbours' child counts (3^3) and
// the levels to the leaves; index bits by the tree position, the minus
// neighbours' halves along the axis (5^3) and the levels to the leaves.
constexpr int kChildBContexts = 64 * 256;
constexpr int kFlagBContexts = 64 * 27 * 4;
constexpr int kIndexBContexts = 8 * 125 * 4;
// Inputs: the first model's fast and slow estimates, the second's mean, a bias.
constexpr int kMixInputs = 4;
constexpr std::int32_t kMixBias = 256;
constexpr std::int32_t kMixInitWeight = 1 << 15;  // 0.5 in 16.16 fixed point
constexpr int kMixShift = 16;
// |weight| <= 64.0: a hostile stream cannot overflow the arithmetic.
constexpr std::int32_t kMixMaxWeight = 1 << 22;

template <int Sets>
struct Mixer {
  std::int32_t w[Sets][kMixInputs];
  Mixer() {
    for (auto& set : w) set[0] = set[1] = set[2] = kMixInitWeight, set[3] = 0;
  }
};

// Codes one bit with the mix of models `a` and `b` under weight set `w`, then
// updates the weights and both models.
// (Inlined: a call per decision costs a fifth of the decoder's time.)
template <typename CodeProb>
[[gnu::always_inline]] inline int mix_code(BitModel& a, BitModel& b, std::int32_t* w, CodeProb& code_prob, int truth_bit) {
  // stretch(a.fast), stretch(a.slow), stretch(b.p0()); the bias input is kMixBias.
  const std::int32_t s0 = kStretch[a.fast >> 4];
  const std::int32_t s1 = kStretch[a.slow >> 4];
  const std::int32_t s2 = kStretchMean[(static_cast<std::uint32_t>(b.fast) + b.slow) >> 5];
  const std::int64_t dot = static_cast<std::int64_t>(w[0]) * s0 + static_cast<std::int64_t>(w[1]) * s1 +
                           static_cast<std::int64_t>(w[2]) * s2 + static_cast<std::int64_t>(w[3]) * kMixBias;
  // |dot| < 4 * 2^22 * 2^11, so dot >> 16 fits an int32; squash clamps it.
  const std::int32_t x = std::clamp(static_cast<std::int32_t>(dot >> 16), -2047, 2047);
  const std::uint32_t sq = kSquashTable.data()[2047 + x];
  const auto p = static_cast<std::int32_t>(sq & 0xFFFF);
  const int bit = code_prob(sq >> 16, truth_bit);
  // The models first (fewer values live across the weights' update).
  a.update(bit);
  b.update(bit);
  const std::int32_t err = (bit ? 0 : 65536) - p;
  // |st * err| < 2^11 * 2^16: the products fit an int32 (and >> floors as
  // the int64 of the specification does).
  const std::int32_t v0 = w[0] + ((s0 * err) >> kMixShift);
  const std::int32_t v1 = w[1] + ((s1 * err) >> kMixShift);
  const std::int32_t v2 = w[2] + ((s2 * err) >> kMixShift);
  const std::int32_t v3 = w[3] + ((kMixBias * err) >> kMixShift);
  // All within [-kMixMaxWeight, kMixMaxWeight) in one test (v + max < 2^23);
  // otherwise clamp each.
  static_assert(kMixMaxWeight == 1 << 22);
  const auto off = [](std::int32_t v) { return static_cast<std::uint32_t>(v + kMixMaxWeight); };
  if (((off(v0) | off(v1) | off(v2) | off(v3)) >> 23) == 0) {
    w[0] = v0, w[1] = v1, w[2] = v2, w[3] = v3;
  } else {
    w[0] = std::clamp(v0, -kMixMaxWeight, kMixMaxWeight);
    w[1] = std::clamp(v1, -kMixMaxWeight, kMixMaxWeight);
    w[2] = std::clamp(v2, -kMixMaxWeight, kMixMaxWeight);
    w[3] = std::clamp(v3, -kMixMaxWeight, kMixMaxWeight);
  }
  return bit;
}

// ---- Codec 12: a third model in the mix, then an adaptive probability map
// (APM: a secondary estimate of the mixed probability by its own context,
// interpolated between 33 knots of the logistic domain; format-spec/chunk.md
// §11.3.5).
constexpr int kFaceMixInputs = 5;
// Each model input starts at ~0.34 (4 inputs: ~1.34 in all, codec 8's 3
// start at 1.5).
constexpr std::int32_t kFaceMixInitWeight = 22000;

template <int Sets>
struct FaceMixer {
  std::int32_t w[Sets][kFaceMixInputs];
  FaceMixer() {
    for (auto& set : w) set[0] = set[1] = set[2] = set[3] = kFaceMixInitWeight, set[4] = 0;
  }
};

// Knot i (0..32) stands for x = 128 (i - 16) and starts at squash(x).
struct Apm {
  std::uint16_t knot[33];
  Apm() {
    for (int i = 0; i < 33; ++i) knot[i] = static_cast<std::uint16_t>(squash(128 * (i - 16)));
  }
};
constexpr int kApmShift = 6;

// As mix_code with a third model `c`, the mixed probability then refined by
// `apm`: the coder uses (p + 3 p_apm) / 4; the mixer learns from p, the map
// from the bit at the knot nearest to p's stretch.
template <typename CodeProb>
[[gnu::always_inline]] inline int mix_code_faces(BitModel& a, BitModel& b, BitModel& c, std::int32_t* w, Apm& apm,
                                                 CodeProb& code_prob, int truth_bit) {
  const std::int32_t s0 = kStretch[a.fast >> 4];
  const std::int32_t s1 = kStretch[a.slow >> 4];
  const std::int32_t s2 = kStretchMean[(static_cast<std::uint32_t>(b.fast) + b.slow) >> 5];
  const std::int32_t s3 = kStretchMean[(static_cast<std::uint32_t>(c.fast) + c.slow) >> 5];
  const std::int64_t dot = static_cast<std::int64_t>(w[0]) * s0 + static_cast<std::int64_t>(w[1]) * s1 +
                           static_cast<std::int64_t>(w[2]) * s2 + static_cast<std::int64_t>(w[3]) * s3 +
                           static_cast<std::int64_t>(w[4]) * kMixBias;
  // |dot| < 5 * 2^22 * 2^11 < 2^36: dot >> 16 fits an int32.
  const std::int32_t x = std::clamp(static_cast<std::int32_t>(dot >> 16), -2047, 2047);
  const auto p = static_cast<std::int32_t>(kSquashTable.data()[2047 + x] & 0xFFFF);
  const int j = (x + 2048) >> 7, f = (x + 2048) & 127;  // j 0..31
  const std::int32_t pa = (apm.knot[j] * (128 - f) + apm.knot[j + 1] * f) >> 7;
  const auto coded = std::clamp(static_cast<std::uint32_t>(p + 3 * pa) >> 2, kProbMin, kProbMax);
  const int bit = code_prob(coded, truth_bit);
  a.update(bit);
  b.update(bit);
  c.update(bit);
  std::uint16_t& k = apm.knot[f < 64 ? j : j + 1];
  k = static_cast<std::uint16_t>(k + (((bit ? 0 : 65535) - static_cast<std::int32_t>(k)) >> kApmShift));
  const std::int32_t err = (bit ? 0 : 65536) - p;
  const std::int32_t st[kFaceMixInputs] = {s0, s1, s2, s3, kMixBias};
  for (int i = 0; i < kFaceMixInputs; ++i) {
    w[i] = std::clamp(w[i] + ((st[i] * err) >> kMixShift), -kMixMaxWeight, kMixMaxWeight);
  }
  return bit;
}

// Codec 12's third models' context: for each axis a, the children of N's -a
// face neighbour on the face it shares with N (those with bit a set), in
// increasing k as 4 bits; by axis and the neighbour's child byte.
constexpr auto kFacePattern = [] {
  std::array<std::array<std::uint8_t, 256>, 3> t{};
  for (int a = 0; a < 3; ++a) {
    for (int occ = 0; occ < 256; ++occ) {
      int pattern = 0, j = 0;
      for (int k = 0; k < 8; ++k) {
        if (((k >> a) & 1) == 0) continue;
        pattern |= ((occ >> k) & 1) << j++;
      }
      t[static_cast<std::size_t>(a)][static_cast<std::size_t>(occ)] = static_cast<std::uint8_t>(pattern);
    }
  }
  return t;
}();

// Codec 12's third models (by the face patterns P, 12 bits, and: the child
// position k for child bits, lone and whether any face neighbour is occupied
// for flags, the tree position t for index bits), mixers and APMs (by codec
// 11's child context's low 6 bits and k; by the flag context; by t, the
// axis's plane prediction and whether its minus neighbour is occupied).
struct FaceModels {
  BitModel child_c[8 << 12];
  BitModel flag_c[4 << 12];
  BitModel index_c[8 << 12];
  FaceMixer<32> child_mixer;
  FaceMixer<8> flag_mixer;
  FaceMixer<12> index_mixer;
  Apm child_apm[512];
  Apm flag_apm[32];
  Apm index_apm[64];
};

// ---- Codec 13: plane prediction of a single child's index bits (§11.3.6).
// The points: the children of the (up to) kPlaneWindow nodes before the node
// in the level's order and the centres of the kPlaneWindow after it, those
// within kPlaneReach cells (each axis) of it; coordinates relative to the node
// in quarter-node units (the node spans 0..4, its children's centres are at 1
// and 3). Every value below is an exact integer: with at most 8 kPlaneWindow +
// kPlaneWindow points of coordinates |p| <= 4 kPlaneReach + 3 = 19 the sums
// stay below 2^17 and the determinants below 2^50; the residual is formed in
// 128 bits.
constexpr std::size_t kPlaneWindow = 32;
constexpr std::int64_t kPlaneReach = 4;
constexpr int kPlaneClasses = 17;      // plane_class
constexpr int kChildPlaneClasses = 9;  // child_plane_class
static_assert(kPlaneWindow <= 32, "the scan keeps one bit per node in a 64-bit mask");

// By child byte: the count of children and, over them, the sums of e_a =
// 2 c_a + 1 (c_a: the child's bit along axis a) and of e_a e_b (a <= b, in
// the order xx, xy, xz, yy, yz, zz).
struct ChildMoments {
  std::int32_t n;
  std::int32_t e[3];
  std::int32_t ee[6];
};
constexpr auto kChildMoments = [] {
  std::array<ChildMoments, 256> t{};
  for (int byte = 0; byte < 256; ++byte) {
    ChildMoments m{};
    for (int k = 0; k < 8; ++k) {
      if (((byte >> k) & 1) == 0) continue;
      const std::int32_t e[3] = {2 * (k & 1) + 1, 2 * ((k >> 1) & 1) + 1, 2 * (k >> 2) + 1};
      ++m.n;
      for (int a = 0, q = 0; a < 3; ++a) {
        m.e[a] += e[a];
        for (int b = a; b < 3; ++b, ++q) m.ee[q] += e[a] * e[b];
      }
    }
    t[static_cast<std::size_t>(byte)] = m;
  }
  return t;
}();
// Index of (a, b) in ChildMoments::ee.
constexpr int kPairIndex[3][3] = {{0, 1, 2}, {1, 3, 4}, {2, 4, 5}};

// Sums over points of 1, p_a and p_a p_b (a <= b, in ChildMoments' order).
// The scan adds up each neighbour's sums in the level's absolute quarter-cell
// coordinates (4 x + e: below 2^23 at depth 21, so a product below 2^46 and a
// sum of at most 288 of them below 2^55), then moves the origin to the node
// once (to_node). The result is the same integers as summing the relative
// coordinates point by point, with 10 additions a neighbour.
struct PlaneSums {
  std::int64_t n = 0;
  std::int64_t s[3] = {0, 0, 0};
  std::int64_t ss[6] = {0, 0, 0, 0, 0, 0};

  // The children of a node at cell (x, y, z) whose child byte's moments are m.
  static PlaneSums children(std::int64_t x, std::int64_t y, std::int64_t z, const ChildMoments& m) {
    PlaneSums out;
    const std::int64_t o[3] = {4 * x, 4 * y, 4 * z};
    out.n = m.n;
    for (int a = 0, q = 0; a < 3; ++a) {
      out.s[a] = o[a] * m.n + m.e[a];
      for (int b = a; b < 3; ++b, ++q) {
        out.ss[q] = o[a] * o[b] * m.n + o[a] * m.e[b] + o[b] * m.e[a] + m.ee[q];
      }
    }
    return out;
  }
  void add(const PlaneSums& m) {
    n += m.n;
    for (int a = 0; a < 3; ++a) s[a] += m.s[a];
    for (int q = 0; q < 6; ++q) ss[q] += m.ss[q];
  }
  void subtract(const PlaneSums& m) {
    n -= m.n;
    for (int a = 0; a < 3; ++a) s[a] -= m.s[a];
    for (int q = 0; q < 6; ++q) ss[q] -= m.ss[q];
  }
  // One point at p.
  static PlaneSums point(std::int64_t px, std::int64_t py, std::int64_t pz) {
    PlaneSums out;
    out.n = 1;
    out.s[0] = px, out.s[1] = py, out.s[2] = pz;
    out.ss[0] = px * px, out.ss[1] = px * py, out.ss[2] = px * pz;
    out.ss[3] = py * py, out.ss[4] = py * pz, out.ss[5] = pz * pz;
    return out;
  }
  // The same points relative to the origin o: sum (p_a - o_a)(p_b - o_b) =
  // sum p_a p_b - o_a sum p_b - o_b sum p_a + n o_a o_b (each term below 2^55).
  void to_node(const std::int64_t* o) {
    for (int a = 0, q = 0; a < 3; ++a) {
      for (int b = a; b < 3; ++b, ++q) ss[q] += n * o[a] * o[b] - o[a] * s[b] - o[b] * s[a];
    }
    for (int a = 0; a < 3; ++a) s[a] -= n * o[a];
  }
  std::int64_t sum2(int a, int b) const { return ss[kPairIndex[a][b]]; }
};

constexpr std::int64_t det3(std::int64_t a, std::int64_t b, std::int64_t c, std::int64_t d, std::int64_t e,
                            std::int64_t f, std::int64_t g, std::int64_t h, std::int64_t i) {
  return a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
}

// Bit j - begin for each node j in [begin, i) and bit 32 + j - i - 1 for each
// in (i, end) whose cell is within kPlaneReach of (x, y, z) on every axis
// (i - begin <= 32, end - i - 1 <= 32). The level's coordinates are below
// 2^21, so the differences fit an int32.
inline bool within_reach(std::int32_t d) {
  return static_cast<std::uint32_t>(d + static_cast<std::int32_t>(kPlaneReach)) <= 2 * kPlaneReach;
}
#if defined(__x86_64__)
// The same bits eight nodes at a time, where the CPU has AVX2 (the window's
// 32 nodes a side in four steps instead of eight).
__attribute__((target("avx2"))) inline __m256i in_reach8(const std::int32_t* l, __m256i v, __m256i lo,
                                                         __m256i hi) {
  const __m256i d = _mm256_sub_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(l)), v);
  return _mm256_and_si256(_mm256_cmpgt_epi32(d, lo), _mm256_cmpgt_epi32(hi, d));
}
__attribute__((target("avx2"))) std::uint32_t near_run_avx2(const std::int32_t* lx, const std::int32_t* ly,
                                                            const std::int32_t* lz, std::size_t from,
                                                            std::size_t to, std::int32_t x, std::int32_t y,
                                                            std::int32_t z) {
  std::uint32_t bits = 0;
  std::size_t j = from;
  const __m256i vx = _mm256_set1_epi32(x), vy = _mm256_set1_epi32(y), vz = _mm256_set1_epi32(z);
  const __m256i lo = _mm256_set1_epi32(-static_cast<std::int32_t>(kPlaneReach) - 1);
  const __m256i hi = _mm256_set1_epi32(static_cast<std::int32_t>(kPlaneReach) + 1);
  for (; j + 8 <= to; j += 8) {
    const __m256i ok =
        _mm256_and_si256(_mm256_and_si256(in_reach8(lx + j, vx, lo, hi), in_reach8(ly + j, vy, lo, hi)),
                         in_reach8(lz + j, vz, lo, hi));
    bits |= static_cast<std::uint32_t>(_mm256_movemask_ps(_mm256_castsi256_ps(ok))) << (j - from);
  }
  for (; j < to; ++j) {
    const bool ok = within_reach(lx[j] - x) && within_reach(ly[j] - y) && within_reach(lz[j] - z);
    bits |= static_cast<std::uint32_t>(ok) << (j - from);
  }
  return bits;
}
bool cpu_has_avx2() {
  static const bool has = __builtin_cpu_supports("avx2") != 0;
  return has;
}
#endif

std::uint64_t near_mask(const std::int32_t* lx, const std::int32_t* ly, const std::int32_t* lz,
                        std::size_t begin, std::size_t i, std::size_t end, std::int32_t x, std::int32_t y,
                        std::int32_t z) {
#if defined(__x86_64__)
  if (cpu_has_avx2()) {
    return std::uint64_t{near_run_avx2(lx, ly, lz, begin, i, x, y, z)} |
           std::uint64_t{near_run_avx2(lx, ly, lz, i + 1, end, x, y, z)} << 32;
  }
#endif
  const auto run = [&](std::size_t from, std::size_t to) {
    std::uint32_t bits = 0;
    std::size_t j = from;
#if defined(__SSE2__)
    // Four nodes at a time: |d| <= reach as -reach - 1 < d < reach + 1.
    const __m128i vx = _mm_set1_epi32(x), vy = _mm_set1_epi32(y), vz = _mm_set1_epi32(z);
    const __m128i lo = _mm_set1_epi32(-static_cast<std::int32_t>(kPlaneReach) - 1);
    const __m128i hi = _mm_set1_epi32(static_cast<std::int32_t>(kPlaneReach) + 1);
    const auto in = [&](const std::int32_t* l, __m128i v) {
      const __m128i d = _mm_sub_epi32(_mm_loadu_si128(reinterpret_cast<const __m128i*>(l)), v);
      return _mm_and_si128(_mm_cmpgt_epi32(d, lo), _mm_cmplt_epi32(d, hi));
    };
    for (; j + 4 <= to; j += 4) {
      const __m128i ok = _mm_and_si128(_mm_and_si128(in(lx + j, vx), in(ly + j, vy)), in(lz + j, vz));
      bits |= static_cast<std::uint32_t>(_mm_movemask_ps(_mm_castsi128_ps(ok))) << (j - from);
    }
#endif
    for (; j < to; ++j) {
      const bool ok = within_reach(lx[j] - x) && within_reach(ly[j] - y) && within_reach(lz[j] - z);
      bits |= static_cast<std::uint32_t>(ok) << (j - from);
    }
    return bits;
  };
  return std::uint64_t{run(begin, i)} | std::uint64_t{run(i + 1, end)} << 32;
}

// A 128-bit integer (GCC and Clang; __extension__ keeps -Wpedantic quiet).
__extension__ typedef __int128 Int128;

// The least-squares plane p_a = alpha + beta p_u + gamma p_v through the
// points of `ps` along axis a (u, v the other two axes in increasing order),
// by Cramer's rule: det is the determinant of the normal equations' matrix
// and da, db, dg are det times alpha, beta and gamma; rss is det times the
// residual sum of squares. Exact: with n <= 288 points of coordinates |p| <=
// 19 the sums stay below 2^17, det and the other determinants below 2^50;
// the products of two of them are formed in 128 bits. `ok` is false when
// there are fewer than 3 points, they lie on a line in (u, v) (det <= 0), or
// the plane is steeper than 2 along u or v (it then says little about a).
struct AxisFit {
  bool ok = false;
  std::int64_t det = 0, da = 0, db = 0, dg = 0;
  Int128 rss = 0;
  // det times the plane's offset, at (u0, v0), from the coordinate c along a.
  std::int64_t offset(std::int64_t u0, std::int64_t v0, std::int64_t c) const {
    return da + db * u0 + dg * v0 - c * det;
  }
};
AxisFit fit_axis(const PlaneSums& ps, int a) {
  AxisFit f;
  if (ps.n < 3) return f;
  const int u = a == 0 ? 1 : 0, v = a == 2 ? 1 : 2;
  const std::int64_t n = ps.n, su = ps.s[u], sv = ps.s[v], sa = ps.s[a];
  const std::int64_t suu = ps.sum2(u, u), svv = ps.sum2(v, v), suv = ps.sum2(u, v);
  const std::int64_t sua = ps.sum2(u, a), sva = ps.sum2(v, a), saa = ps.sum2(a, a);
  f.det = det3(n, su, sv, su, suu, suv, sv, suv, svv);
  if (f.det <= 0) return f;
  f.da = det3(sa, su, sv, sua, suu, suv, sva, suv, svv);
  f.db = det3(n, sa, sv, su, sua, suv, sv, sva, svv);
  f.dg = det3(n, su, sa, su, suu, sua, sv, suv, sva);
  if (f.db > 2 * f.det || f.db < -2 * f.det || f.dg > 2 * f.det || f.dg < -2 * f.det) return f;
  f.rss = Int128{saa} * f.det - (Int128{f.da} * sa + Int128{f.db} * sua + Int128{f.dg} * sva);
  f.ok = true;
  return f;
}

// The plane class of a single child's coordinate along axis a (§11.3.6):
// the fit along a evaluated at the child's (u0, v0) (2 c + 1 for an axis whose
// bit c is decoded, else 2), its offset from the node's mid-plane 2 and that
// offset against the fit's residual. 0: no fit; else 1 + 4 conf + 2 sure +
// (offset > 0), conf 3 for |offset| >= 2, 2 for >= 1, 1 for >= 1/2, else 0,
// sure when offset^2 >= rss / n (the offset is at least the residual's RMS).
int plane_class(const PlaneSums& ps, int a, std::int64_t u0, std::int64_t v0) {
  const AxisFit f = fit_axis(ps, a);
  if (!f.ok) return 0;
  const std::int64_t off = f.offset(u0, v0, 2);
  const std::int64_t mag = off < 0 ? -off : off;
  const int conf = mag >= 2 * f.det ? 3 : (mag >= f.det ? 2 : (2 * mag >= f.det ? 1 : 0));
  // offset^2 >= (rss / det) / n  <=>  mag^2 n >= rss det (mag, rss: det times
  // their values), both below 2^112.
  const bool sure = Int128{mag} * mag * ps.n >= f.rss * f.det;
  return 1 + 4 * conf + (sure ? 2 : 0) + (off > 0 ? 1 : 0);
}

// The plane of a node with several children (§11.3.6): the axis whose fit has
// the least mean squared residual (rss / det; the first of z, y, x on a tie),
// and whether that residual exceeds 2 per point.
struct NodePlane {
  int axis = -1;  // none
  AxisFit fit;
  bool thick = false;
};
NodePlane node_plane(const PlaneSums& ps) {
  NodePlane best;
  for (int a = 2; a >= 0; --a) {
    const AxisFit f = fit_axis(ps, a);
    if (!f.ok) continue;
    // rss / det < best.rss / best.det, both below 2^102.
    if (best.axis < 0 || f.rss * best.fit.det < best.fit.rss * f.det) best.axis = a, best.fit = f;
  }
  if (best.axis >= 0) best.thick = best.fit.rss > Int128{2 * ps.n} * best.fit.det;
  return best;
}

// The class of child k of a node with several children: 0 without a plane;
// else 1 + 2 dist + thick, dist 0..3 as the plane passes the child's centre
// along the plane's axis closer than 1/2, 1, 2 quarter-node units, or not.
int child_plane_class(const NodePlane& np, int k) {
  if (np.axis < 0) return 0;
  const int a = np.axis, u = a == 0 ? 1 : 0, v = a == 2 ? 1 : 2;
  const auto e = [k](int axis) { return std::int64_t{2 * ((k >> axis) & 1) + 1}; };
  const std::int64_t off = np.fit.offset(e(u), e(v), e(a));
  const std::int64_t mag = off < 0 ? -off : off;
  const std::int64_t det = np.fit.det;
  const int dist = 2 * mag < det ? 0 : (mag < det ? 1 : (mag < 2 * det ? 2 : 3));
  return 1 + 2 * dist + (np.thick ? 1 : 0);
}

// Codec 8's second models and mixers (weight sets: child bits by k and the
// levels to the leaves, flags by lone and the levels to the leaves, index
// bits by axis and the levels to the leaves), allocated for codecs 8, 11 and 12.
struct MixedModels {
  BitModel child_b[kChildBContexts];
  BitModel flag_b[kFlagBContexts];
  BitModel index_b[kIndexBContexts];
  Mixer<32> child_mixer;
  Mixer<8> flag_mixer;
  Mixer<12> index_mixer;
};

// Codecs 13 and 14: index models for chains (plain) and APMs for single
// children (in place of codec 12's), by tree position t, the index bit's
// class (kClasses of them: codec 13's plane classes, codec 14's index
// classes), the axis's plane memory prediction and the levels to the leaves
// (chains) or whether the axis's minus neighbour is occupied (single
// children).
template <int kClasses>
struct IndexModels {
  BitModel chain_index[8 * kClasses * 3 * 4];
  Apm index_apm[8 * kClasses * 3 * 2];
};
// Codec 13's and 14's child bits' mixer weight sets (in place of codec
// 12's), by k, the levels to the leaves and the child's plane class.
struct PlaneModels {
  FaceMixer<32 * kChildPlaneClasses> child_mixer;
};

// ---- Codec 14: near classes (§11.3.7). A single child's or a chain's index
// bit along axis a, with the points the plane sums count listed: which of
// the two halves of the node along a (the child's coordinates on the other
// axes as far as known) lies nearer the nearest of them, by how much, and
// whether either lies near one. 0 without any point, else 1..16.
constexpr int kNearClasses = 17;
// Codec 14's index classes: codec 13's plane class when there is a plane
// and the bit is along z; the near class (17..32) when there is no plane;
// for an x or y bit with a plane, the plane class by a coarse near class
// (33..80).
constexpr int kIndexClasses = kPlaneClasses + (kNearClasses - 1) + 3 * (kPlaneClasses - 1);

// Codec 14's index models are codec 13's by its index classes in place of
// the plane classes (the child bits' weight sets are codec 13's, in
// PlaneModels); each codec allocates only its own.
using PlaneIndexModels = IndexModels<kPlaneClasses>;
using NearModels = IndexModels<kIndexClasses>;

// Points in quarter-node units relative to the node, as the plane sums count
// them: at most 8 per node before it and one per node after. By axis, so that
// the distances below are computed several points at a time.
constexpr std::size_t kMaxNearPoints = 8 * kPlaneWindow + kPlaneWindow;
struct NearPoints {
  std::size_t n = 0;
  std::int32_t c[3][kMaxNearPoints];
  void add(std::int32_t x, std::int32_t y, std::int32_t z) {
    c[0][n] = x, c[1][n] = y, c[2][n] = z;
    ++n;
  }
};

// The near class of an index bit along axis a, the child's coordinates so far
// `at` (2 c + 1 for a decoded axis, else 2): with d_h the least squared
// distance from the centre of half h (2 h + 1 along a, `at` on the others) to
// a point, m = |d_1 - d_0| and r = min(d_0, d_1): 1 + (d_1 > d_0) + 2 q +
// 8 (r < 24), q = 0 for m = 0, 1 for m < 8, 2 for m < 32, else 3. `strong`
// is set when q >= 2. (Coordinates lie within -15..19, so squared distances
// are at most 3 * 18^2.)
int near_class(const NearPoints& np, int a, const std::int64_t* at, bool& strong) {
  strong = false;
  if (np.n == 0) return 0;
  const int u = a == 0 ? 1 : 0, v = a == 2 ? 1 : 2;
  const auto cu = static_cast<std::int32_t>(at[u]), cv = static_cast<std::int32_t>(at[v]);
  const std::int32_t* const pu = np.c[u];
  const std::int32_t* const pv = np.c[v];
  const std::int32_t* const pa = np.c[a];
  std::int32_t d0 = INT32_MAX, d1 = INT32_MAX;
  for (std::size_t j = 0; j < np.n; ++j) {
    const std::int32_t eu = pu[j] - cu, ev = pv[j] - cv;
    const std::int32_t side = eu * eu + ev * ev;
    const std::int32_t e0 = pa[j] - 1, e1 = pa[j] - 3;
    d0 = std::min(d0, side + e0 * e0);
    d1 = std::min(d1, side + e1 * e1);
  }
  const std::int32_t m = d1 > d0 ? d1 - d0 : d0 - d1;
  const int q = m == 0 ? 0 : (m < 8 ? 1 : (m < 32 ? 2 : 3));
  strong = q >= 2;
  return 1 + (d1 > d0 ? 1 : 0) + 2 * q + (std::min(d0, d1) < 24 ? 8 : 0);
}

// Codec 14's class of an index bit along axis a, from codec 13's plane class
// (0 without a plane) and the near class (§11.3.7).
int index_class(int plane_cls, int a, const NearPoints& np, const std::int64_t* at) {
  if (plane_cls != 0 && a == 2) return plane_cls;
  bool strong = false;
  const int near = near_class(np, a, at, strong);
  if (plane_cls == 0) return near == 0 ? 0 : kPlaneClasses + near - 1;
  const int coarse = strong ? 1 + ((near - 1) & 1) : 0;
  return kPlaneClasses + kNearClasses - 1 + (plane_cls - 1) + (kPlaneClasses - 1) * coarse;
}

// Codec 11's chain flag: one model per number of levels left below the
// node (capped).
constexpr int kChainFlagContexts = 16;

struct GeometryModels {
  BitModel occupancy[kOccupancyContexts];
  BitModel single_flag[kSingleFlagContexts];
  BitModel single_index[kSingleIndexContexts];
  BitModel chain_flag[kChainFlagContexts];
  BitModel duplicate[kCountContexts];
  UIntModel extra;
  std::unique_ptr<MixedModels> mixed;   // codecs 8 and 11 to 14
  std::unique_ptr<FaceModels> faces;    // codecs 12 to 14
  std::unique_ptr<PlaneModels> planes;  // codecs 13 and 14
  std::unique_ptr<PlaneIndexModels> plane_index;  // codec 13
  std::unique_ptr<NearModels> near;               // codec 14
};

// Visits every node of levels 0..depth-1 and codes its 8 child bits through
// `code(model, bit)` (the encoder passes the true bit and ignores the result;
// the decoder ignores the bit and returns what it decoded). `true_byte`
// returns the known child occupancy byte of node i of level d on the encoder
// side. `grow(n)` is told the size of the next level after every node and
// returns false to stop (decoder bounds); so does a node without children.
// On return `nodes` holds the keys of the occupied cells at `depth`.
constexpr std::uint32_t kMissing = 0xFFFFFFFFu;

// Index of child k of a node whose child byte is `byte` and whose first
// child has index `first`, or kMissing.
// (A table, not std::popcount: baseline x86-64 has no popcnt instruction.)
constexpr auto kBitCount = [] {
  std::array<std::uint8_t, 256> t{};
  for (int v = 0; v < 256; ++v) t[static_cast<std::size_t>(v)] = static_cast<std::uint8_t>((v & 1) + t[static_cast<std::size_t>(v >> 1)]);
  return t;
}();
// The set bits of a 64-bit word with at most 32 low bits set (codec 13's
// window masks).
inline std::size_t bit_count32(std::uint64_t v) {
  return std::size_t{kBitCount[v & 0xFF]} + kBitCount[(v >> 8) & 0xFF] + kBitCount[(v >> 16) & 0xFF] +
         kBitCount[(v >> 24) & 0xFF];
}
inline std::uint32_t child_index(std::uint8_t byte, std::uint32_t first, int k) {
  if (((byte >> k) & 1) == 0) return kMissing;
  return first + kBitCount[byte & ((1u << k) - 1)];
}

// A child byte's count class for codec 8's flag contexts: 0 (none), 1 (one
// child), 2 (more).
constexpr auto kCountClass = [] {
  std::array<std::uint8_t, 256> t{};
  for (std::size_t v = 0; v < 256; ++v) t[v] = static_cast<std::uint8_t>(std::min<int>(kBitCount[v], 2));
  return t;
}();

// Plane memory (after G-PCC's planar mode): for each axis, per plane
// coordinate along it (hashed into a small table), the last node visited in
// that plane, where it lay in the other two axes, and which halves of it along
// the axis held children. Surfaces at constant x, y or z (facades, ground,
// the depth levels of an RGB-D camera) repeat their half across gaps that
// face neighbours cannot see.
class PlaneMemory {
 public:
  static constexpr int kBits = 12;
  static constexpr std::uint32_t kSize = 1u << kBits;
  // Closer than this (Manhattan, in node units) a remembered node predicts.
  static constexpr std::uint32_t kReach = 32;

  // Forgets everything. Entries are stamped with the generation that wrote
  // them, so a reset is a new generation rather than a pass over the tables
  // (which start zeroed, generation 0, before the first reset).
  void reset() {
    if (++generation_ == 0) {
      for (auto& t : table_) t.fill(Entry{});
      generation_ = 1;
    }
  }
  // -1: the remembered node had children only in the lower half along `axis`,
  // +1 only in the upper half, 0 no (near) memory or both halves.
  int predict(int axis, std::uint32_t plane, std::uint32_t u, std::uint32_t v) const {
    const Entry& e = table_[static_cast<std::size_t>(axis)][plane & (kSize - 1)];
    if (e.generation != generation_ || e.plane != plane) return 0;
    const std::uint32_t du = e.u > u ? e.u - u : u - e.u;
    const std::uint32_t dv = e.v > v ? e.v - v : v - e.v;
    return du + dv > kReach ? 0 : e.prediction;
  }
  // `byte`: the node's child byte (never 0).
  void remember(int axis, std::uint32_t plane, std::uint32_t u, std::uint32_t v, std::uint8_t byte);

 private:
  struct Entry {
    std::uint32_t plane = 0, u = 0, v = 0;
    // What the node predicts along the axis (-1, 0, +1, as predict()).
    std::int8_t prediction = 0;
    std::uint8_t generation = 0;
  };
  std::array<std::array<Entry, kSize>, 3> table_{};
  std::uint8_t generation_ = 0;
};

// Child bits with c along `axis` set, for the halves test.
constexpr std::uint8_t kUpperHalf[3] = {0xAA, 0xCC, 0xF0};

// Codec 8's index bits: by tree position t (1..7; it fixes the axis a and
// the bits decoded above it) and a minus neighbour's child byte, the
// neighbour's halves along a among its children that agree with those bits:
// 0 no neighbour, 1 none, 2 lower only, 3 upper only, 4 both.
constexpr auto kIndexHalves = [] {
  std::array<std::array<std::uint8_t, 256>, 8> table{};
  for (int t = 1; t < 8; ++t) {
    const int a = t == 1 ? 2 : (t < 4 ? 1 : 0);
    std::uint8_t keep = 0xFF;
    for (int b = 2; b > a; --b) {
      keep &= ((t >> (b - a - 1)) & 1) ? kUpperHalf[b] : static_cast<std::uint8_t>(~kUpperHalf[b]);
    }
    for (int occ = 1; occ < 256; ++occ) {
      const int sub = occ & keep;
      table[static_cast<std::size_t>(t)][static_cast<std::size_t>(occ)] =
          static_cast<std::uint8_t>(1 + ((sub & ~kUpperHalf[a] & 0xFF) ? 1 : 0) + ((sub & kUpperHalf[a]) ? 2 : 0));
    }
  }
  return table;
}();

// A child byte's plane prediction along each axis: -1 with children only in
// the lower half, +1 only in the upper half, 0 in both (or none).
constexpr auto kHalvesPrediction = [] {
  std::array<std::array<std::int8_t, 256>, 3> t{};
  for (int a = 0; a < 3; ++a) {
    for (int byte = 0; byte < 256; ++byte) {
      const bool lower = (byte & ~kUpperHalf[a] & 0xFF) != 0, upper = (byte & kUpperHalf[a]) != 0;
      t[static_cast<std::size_t>(a)][static_cast<std::size_t>(byte)] =
          static_cast<std::int8_t>(lower && !upper ? -1 : (upper && !lower ? 1 : 0));
    }
  }
  return t;
}();

void PlaneMemory::remember(int axis, std::uint32_t plane, std::uint32_t u, std::uint32_t v, std::uint8_t byte) {
  table_[static_cast<std::size_t>(axis)][plane & (kSize - 1)] = {
      plane, u, v, kHalvesPrediction[static_cast<std::size_t>(axis)][byte], generation_};
}

// The pieces of a child bit's context (format-spec/chunk.md), as tables so a
// node computes them once for its 8 children. Each "spread" word holds one
// byte per child k (byte k).
//
// Bits 0-2 (near): axis a's bit is set when the face neighbour on child k's
// side along a exists; by the node's neighbour mask (bit q: n6[q] present).
constexpr auto kNearSpread = [] {
  std::array<std::uint64_t, 64> t{};
  for (unsigned mask = 0; mask < 64; ++mask) {
    for (unsigned k = 0; k < 8; ++k) {
      unsigned near = 0;
      for (unsigned a = 0; a < 3; ++a) near |= ((mask >> (2 * a + ((k >> a) & 1))) & 1) << a;
      t[mask] |= std::uint64_t{near} << (8 * k);
    }
  }
  return t;
}();
// Bits 3-5 (child_nb), axes where child k is in the lower half: the -a
// neighbour's child across the face is occupied; by axis and that
// neighbour's child byte, already in place (<< 3).
constexpr auto kMinusSpread = [] {
  std::array<std::array<std::uint64_t, 256>, 3> t{};
  for (unsigned a = 0; a < 3; ++a) {
    for (unsigned occ = 0; occ < 256; ++occ) {
      for (unsigned k = 0; k < 8; ++k) {
        if ((k >> a) & 1) continue;
        const unsigned below = (occ >> (k | (1u << a))) & 1;
        t[a][occ] |= std::uint64_t{below << (3 + a)} << (8 * k);
      }
    }
  }
  return t;
}();
// Bits 3-5, axes where child k is in the upper half: its sibling below is
// occupied; by k and the bits of the node's byte coded so far (<< 3).
constexpr auto kPlusNb = [] {
  std::array<std::array<std::uint8_t, 256>, 8> t{};
  for (unsigned k = 0; k < 8; ++k) {
    for (unsigned byte = 0; byte < 256; ++byte) {
      unsigned nb = 0;
      for (unsigned a = 0; a < 3; ++a) {
        if ((k >> a) & 1) nb |= ((byte >> (k ^ (1u << a))) & 1) << a;
      }
      t[k][byte] = static_cast<std::uint8_t>(nb << 3);
    }
  }
  return t;
}();
// Bits 11-13: score + 3, where score counts +1 per axis whose plane memory
// puts child k's half occupied and -1 per axis that puts it empty; by the
// three predictions (each -1, 0, 1) as 9 (p2 + 1) + 3 (p1 + 1) + (p0 + 1).
constexpr auto kScoreSpread = [] {
  std::array<std::uint64_t, 27> t{};
  for (int i = 0; i < 27; ++i) {
    const int pred[3] = {i % 3 - 1, i / 3 % 3 - 1, i / 9 - 1};
    for (int k = 0; k < 8; ++k) {
      int score = 0;
      for (int a = 0; a < 3; ++a) {
        if (pred[a] != 0) score += (pred[a] > 0) == (((k >> a) & 1) != 0) ? 1 : -1;
      }
      t[static_cast<std::size_t>(i)] |= static_cast<std::uint64_t>(score + 3) << (8 * k);
    }
  }
  return t;
}();

// `true_chain(d, i)` (encoder side) is 1 when the subtree of node i of
// level d holds one cell, for codec 11's chains.
// kMixing: 0 for codecs 6 and 7, 1 for codecs 8 and 11 (two models mixed),
// 2 for codec 12 (three models mixed, then the APM), 3 for codec 13 (codec
// 12 with the plane classes of §11.3.6), 4 for codec 14 (codec 13 with the
// near classes of §11.3.7).
template <int kMixing, typename Code, typename CodeProb, typename TrueByte, typename TrueChain, typename Grow>
bool code_octree_impl(int depth, OctreeCoding coding, GeometryModels& models, std::vector<std::uint64_t>& nodes,
                      Code& code, CodeProb& code_prob, TrueByte& true_byte, TrueChain& true_chain, Grow& grow) {
  constexpr bool mixed = kMixing >= 1;
  constexpr bool three = kMixing >= 2;
  constexpr bool plane = kMixing >= 3;
  constexpr bool nearest = kMixing == 4;
  MixedModels* const mm = models.mixed.get();   // codec 8's and 11's to 14's, else null
  FaceModels* const fm = models.faces.get();    // codec 12's to 14's, else null
  PlaneModels* const pm = models.planes.get();  // codec 13's and 14's, else null
  PlaneIndexModels* const pim = models.plane_index.get();  // codec 13's, else null
  NearModels* const nm = models.near.get();                // codec 14's, else null
  const bool single_mode = coding == OctreeCoding::kSingleChild || mixed;
  const bool chains = coding == OctreeCoding::kChains || coding == OctreeCoding::kFacePatterns ||
                      coding == OctreeCoding::kPlanes || coding == OctreeCoding::kNearest;
  // Per node of the current level (codec 11): whether its subtree is known
  // to hold one cell (a chain), known to hold more, or not known.
  enum : std::uint8_t { kUnknown, kChain, kNotChain };
  std::vector<std::uint8_t> chain(1, kUnknown), next_chain;
  nodes.assign(1, 0);  // the root
  // Per node of the current level: its six face neighbours' indices in the
  // level (-x, +x, -y, +y, -z, +z; kMissing when empty), its child byte and
  // the index of its first child in the next level. A level's neighbour
  // indices come from the level above (a child's neighbour is a sibling or a
  // child of its parent's neighbour), so no lookup structure is needed.
  std::vector<std::uint32_t> nb(6, kMissing), next_nb;
  std::vector<std::uint8_t> occ;
  // Per node of the current level: its parent had exactly one child.
  std::vector<std::uint8_t> lone, next_lone;
  std::vector<std::uint32_t> first;
  std::vector<std::uint64_t> next;
  // Per axis, per node of the current level: its cell coordinate at the
  // level (a child's is its parent's doubled plus its bit along the axis;
  // below 2^21). By axis, so that codec 13's plane sums scan them four
  // nodes at a time.
  std::array<std::vector<std::int32_t>, 3> cell = {{{0}, {0}, {0}}}, next_cell;
  auto planes = std::make_unique<PlaneMemory>();
  // Codec 13's sliding sums over whole windows (§11.3.6): `before` over the
  // children of the up to kPlaneWindow nodes before the current one (each
  // node's own in `ring`, by index mod kPlaneWindow), `after` over the
  // centres of the up to kPlaneWindow after it. A node's sums are then a
  // window's less the nodes out of reach, or the nodes within reach added up,
  // whichever are fewer: the same integers either way.
  PlaneSums before, after;
  std::array<PlaneSums, kPlaneWindow> ring{};
  const auto centre = [&cell](std::size_t j) {
    return PlaneSums::point(4 * std::int64_t{cell[0][j]} + 2, 4 * std::int64_t{cell[1][j]} + 2,
                            4 * std::int64_t{cell[2][j]} + 2);
  };
  lone.assign(1, 0);
  for (int d = 0; d < depth; ++d) {
    planes->reset();
    if constexpr (plane) {
      before = PlaneSums{};
      after = PlaneSums{};
      for (std::size_t j = 1; j < std::min(nodes.size(), kPlaneWindow + 1); ++j) after.add(centre(j));
    }
    const int to_leaves = std::min(depth - 1 - d, 3);
    next_lone.clear();
    next_chain.clear();
    const std::size_t count = nodes.size();
    occ.assign(count, 0);
    first.assign(count, 0);
    // The next level's keys: next[0, next_count), with room for 8 more
    // kept before each node (a child key is stored before it is known to be
    // occupied).
    std::size_t next_count = 0;
    for (std::size_t i = 0; i < count; ++i) {
      const std::uint32_t* n6 = &nb[6 * i];
      // Child bytes of the minus-side neighbours (visited already: lowering
      // one coordinate lowers the Morton key).
      std::uint8_t minus_occ[3];
      for (int a = 0; a < 3; ++a) minus_occ[a] = n6[2 * a] != kMissing ? occ[n6[2 * a]] : 0;
      // Bit q: face neighbour q exists.
      unsigned faces_mask = 0;
      for (int q = 0; q < 6; ++q) faces_mask |= (n6[q] != kMissing ? 1u : 0u) << q;
      // Codec 12: the face patterns P.
      unsigned patterns = 0;
      if constexpr (three) {
        patterns = static_cast<unsigned>(kFacePattern[0][minus_occ[0]]) |
                   static_cast<unsigned>(kFacePattern[1][minus_occ[1]]) << 4 |
                   static_cast<unsigned>(kFacePattern[2][minus_occ[2]]) << 8;
      }
      const std::array<std::uint32_t, 3> xyz = {static_cast<std::uint32_t>(cell[0][i]),
                                                static_cast<std::uint32_t>(cell[1][i]),
                                                static_cast<std::uint32_t>(cell[2][i])};
      int plane_pred[3];
      for (int a = 0; a < 3; ++a) plane_pred[a] = planes->predict(a, xyz[a], xyz[(a + 1) % 3], xyz[(a + 2) % 3]);
      const std::uint8_t truth = true_byte(d, i);
      std::uint8_t byte = 0;
      int siblings = 0;
      if (next.size() < next_count + 8) next.resize(std::max(2 * next.size(), next_count + 8));
      std::uint64_t* const next_keys = next.data();
      first[i] = static_cast<std::uint32_t>(next_count);
      bool single = false;
      // Codec 11: an isolated node (its parent's only child, no face
      // neighbour) with at least two levels below it says with one flag
      // whether its subtree holds one cell (a chain); a chain node's child
      // is then its only one, its index coded with codec 7's index models
      // alone (no flag S, no mixing; an isolated node's neighbour contexts
      // are all empty anyway), and so are its descendants'.
      bool on_chain = chains && chain[i] == kChain;
      bool not_chain = chains && chain[i] == kNotChain;
      if (chains && chain[i] == kUnknown && lone[i] != 0 && faces_mask == 0 && depth - d >= 2) {
        on_chain = code(models.chain_flag[std::min(depth - 1 - d, kChainFlagContexts - 1)], true_chain(d, i)) != 0;
        not_chain = !on_chain;
      }
      // Codec 13: the node's plane sums (§11.3.6), made once its flags have
      // said what it codes (index bits, or child bits): the children of the
      // up to kPlaneWindow nodes before it and the centres of those after it
      // that lie within kPlaneReach cells.
      PlaneSums sums;
      NearPoints near;  // codec 14: the points the sums count, one by one
      if constexpr (plane) {
        // The windows move on by one node: node i - 1 (its child byte now
        // known) joins `before` and node i - 1 - kPlaneWindow leaves it; node
        // i leaves `after` and node i + kPlaneWindow joins it.
        if (i > 0) {
          PlaneSums& slot = ring[(i - 1) % kPlaneWindow];
          if (i - 1 >= kPlaneWindow) before.subtract(slot);
          slot =
              PlaneSums::children(cell[0][i - 1], cell[1][i - 1], cell[2][i - 1], kChildMoments[occ[i - 1]]);
          before.add(slot);
          after.subtract(centre(i));
          if (i + kPlaneWindow < count) after.add(centre(i + kPlaneWindow));
        }
      }
      const auto gather = [&](bool with_points) {
        // Which nodes lie within reach, in loops without branches (bit
        // j - begin for a node before, 32 + j - i - 1 for one after), then
        // the sums over those.
        const std::size_t begin = i > kPlaneWindow ? i - kPlaneWindow : 0;
        const std::size_t end = std::min(count, i + 1 + kPlaneWindow);
        const std::int32_t x = cell[0][i], y = cell[1][i], z = cell[2][i];
        const std::uint64_t mask = near_mask(cell[0].data(), cell[1].data(), cell[2].data(), begin, i, end, x, y, z);
        const std::uint64_t in_before = (std::uint64_t{1} << (i - begin)) - 1;
        const std::uint64_t in_after = (std::uint64_t{1} << (end - i - 1)) - 1;
        const std::uint64_t near_before = mask & in_before, far_before = ~mask & in_before;
        const std::uint64_t near_after = (mask >> 32) & in_after, far_after = ~(mask >> 32) & in_after;
        PlaneSums part;
        // Fewer out of reach than within: take those away from the window.
        if (2 * bit_count32(near_before) > i - begin) {
          part = before;
          for (std::uint64_t b = far_before; b != 0; b &= b - 1) {
            part.subtract(ring[(begin + static_cast<std::size_t>(std::countr_zero(b))) % kPlaneWindow]);
          }
        } else {
          for (std::uint64_t b = near_before; b != 0; b &= b - 1) {
            part.add(ring[(begin + static_cast<std::size_t>(std::countr_zero(b))) % kPlaneWindow]);
          }
        }
        sums = part;
        // A node after N: its centre, 4 x + 2.
        if (2 * bit_count32(near_after) > end - i - 1) {
          part = after;
          for (std::uint64_t b = far_after; b != 0; b &= b - 1) {
            part.subtract(centre(i + 1 + static_cast<std::size_t>(std::countr_zero(b))));
          }
        } else {
          part = PlaneSums{};
          for (std::uint64_t b = near_after; b != 0; b &= b - 1) {
            part.add(centre(i + 1 + static_cast<std::size_t>(std::countr_zero(b))));
          }
        }
        sums.add(part);
        const std::int64_t origin[3] = {4 * std::int64_t{x}, 4 * std::int64_t{y}, 4 * std::int64_t{z}};
        sums.to_node(origin);
        if (nearest && with_points) {
          // The same points, relative to N: a node before's children, a
          // node after's centre.
          near.n = 0;
          for (std::uint64_t b = near_before; b != 0; b &= b - 1) {
            const std::size_t j = begin + static_cast<std::size_t>(std::countr_zero(b));
            const std::int32_t o[3] = {4 * (cell[0][j] - x) + 1, 4 * (cell[1][j] - y) + 1,
                                       4 * (cell[2][j] - z) + 1};
            for (unsigned bits = occ[j]; bits != 0; bits &= bits - 1) {
              const int k = std::countr_zero(bits);
              near.add(o[0] + 2 * (k & 1), o[1] + (k & 2), o[2] + ((k >> 1) & 2));
            }
          }
          for (std::uint64_t b = near_after; b != 0; b &= b - 1) {
            const std::size_t j = i + 1 + static_cast<std::size_t>(std::countr_zero(b));
            near.add(4 * (cell[0][j] - x) + 2, 4 * (cell[1][j] - y) + 2, 4 * (cell[2][j] - z) + 2);
          }
        }
      };
      if (on_chain) {
        const int truth_k = kBitCount[truth] == 1 ? kBitCount[static_cast<std::uint8_t>(truth - 1)] : 0;
        int t = 1;
        if constexpr (plane) {
          gather(true);
          std::int64_t at[3] = {2, 2, 2};  // the child's coordinates known so far
          for (int a = 2; a >= 0; --a) {
            const int cls = plane_class(sums, a, at[a == 0 ? 1 : 0], at[a == 2 ? 1 : 2]);
            BitModel* m;
            if constexpr (nearest) {
              const int index_cls = index_class(cls, a, near, at);
              m = &nm->chain_index[((t * kIndexClasses + index_cls) * 3 + plane_pred[a] + 1) * 4 + to_leaves];
            } else {
              m = &pim->chain_index[((t * kPlaneClasses + cls) * 3 + plane_pred[a] + 1) * 4 + to_leaves];
            }
            const int bit = code(*m, (truth_k >> a) & 1);
            at[a] = 2 * bit + 1;
            t = 2 * t + bit;
          }
        } else {
          for (int a = 2; a >= 0; --a) {
            const int axis_part = ((plane_pred[a] + 1) * 4 * 2) << 2;  // faces_a = 0, minus = 0
            t = 2 * t +
                code(models.single_index[((t * 24) << 2) + axis_part + to_leaves], (truth_k >> a) & 1);
          }
        }
        const int k = t - 8;
        byte = static_cast<std::uint8_t>(1u << k);
        siblings = 1;
        next_keys[next_count++] = (nodes[i] << 3) | static_cast<std::uint64_t>(k);
        if (d + 1 < depth) next_chain.push_back(kChain);
      } else if (single_mode) {
        const int faces = kBitCount[faces_mask];
        const int flag_ctx = (std::min(faces, 3) << 3) | (lone[i] << 2) | to_leaves;
        const int truth_single = kBitCount[truth] == 1 ? 1 : 0;
        if constexpr (!mixed) {
          single = code(models.single_flag[flag_ctx], truth_single) != 0;
        } else {
          // The minus neighbours' child counts (0 missing, 1 one child, 2 more).
          const int nbc = 9 * kCountClass[minus_occ[0]] + 3 * kCountClass[minus_occ[1]] + kCountClass[minus_occ[2]];
          BitModel& mb = mm->flag_b[((faces_mask * 27 + static_cast<unsigned>(nbc)) << 2) | static_cast<unsigned>(to_leaves)];
          if constexpr (three) {
            BitModel& mc = fm->flag_c[patterns | static_cast<unsigned>(lone[i]) << 12 | (faces_mask != 0 ? 1u : 0u) << 13];
            single = mix_code_faces(models.single_flag[flag_ctx], mb, mc, fm->flag_mixer.w[(lone[i] << 2) | to_leaves],
                                    fm->flag_apm[flag_ctx], code_prob, truth_single) != 0;
          } else {
            single = mix_code(models.single_flag[flag_ctx], mb, mm->flag_mixer.w[(lone[i] << 2) | to_leaves], code_prob,
                              truth_single) != 0;
          }
        }
      }
      if (single) {
        // The child's index, z bit first: node t of the binary tree (1, then 2t + bit).
        const int truth_k = kBitCount[truth] == 1 ? kBitCount[static_cast<std::uint8_t>(truth - 1)] : 0;
        // ctx = ((((t * 3 + pred + 1) * 4 + faces) * 2 + minus) << 2) | to_leaves,
        // of which all but t is the axis's.
        int t = 1;
        std::int64_t at[3] = {2, 2, 2};  // codec 13: the child's coordinates known so far
        if constexpr (plane) gather(true);
        for (int a = 2; a >= 0; --a) {
          const int faces_a = static_cast<int>((faces_mask >> (2 * a)) & 3);
          const int axis_part = (((plane_pred[a] + 1) * 4 + faces_a) * 2 + (minus_occ[a] != 0 ? 1 : 0)) << 2;
          const int ctx = ((t * 24) << 2) + axis_part + to_leaves;
          if constexpr (!mixed) {
            t = 2 * t + code(models.single_index[ctx], (truth_k >> a) & 1);
          } else {
            // The minus neighbours' halves along a among their children that
            // agree with the bits decoded so far (kIndexHalves).
            const std::uint8_t* const halves = kIndexHalves[static_cast<std::size_t>(t)].data();
            const int hv = 25 * halves[minus_occ[0]] + 5 * halves[minus_occ[1]] + halves[minus_occ[2]];
            BitModel& mb = mm->index_b[((t * 125 + hv) << 2) | to_leaves];
            if constexpr (three) {
              BitModel& mc = fm->index_c[patterns | static_cast<unsigned>(t) << 12];
              const int minus = minus_occ[a] != 0 ? 1 : 0;
              Apm* apm;
              if constexpr (plane) {
                const int cls = plane_class(sums, a, at[a == 0 ? 1 : 0], at[a == 2 ? 1 : 2]);
                if constexpr (nearest) {
                  const int index_cls = index_class(cls, a, near, at);
                  apm = &nm->index_apm[((t * kIndexClasses + index_cls) * 3 + plane_pred[a] + 1) * 2 + minus];
                } else {
                  apm = &pim->index_apm[((t * kPlaneClasses + cls) * 3 + plane_pred[a] + 1) * 2 + minus];
                }
              } else {
                apm = &fm->index_apm[t << 3 | (plane_pred[a] + 1) << 1 | minus];
              }
              const int bit =
                  mix_code_faces(models.single_index[ctx], mb, mc, fm->index_mixer.w[a * 4 + to_leaves], *apm,
                                 code_prob, (truth_k >> a) & 1);
              at[a] = 2 * bit + 1;
              t = 2 * t + bit;
            } else {
              t = 2 * t + mix_code(models.single_index[ctx], mb, mm->index_mixer.w[a * 4 + to_leaves], code_prob,
                                   (truth_k >> a) & 1);
            }
          }
        }
        const int k = t - 8;
        byte = static_cast<std::uint8_t>(1u << k);
        siblings = 1;
        next_keys[next_count++] = (nodes[i] << 3) | static_cast<std::uint64_t>(k);
      }
      if (!single && !on_chain) {
        const std::uint64_t low = kNearSpread[faces_mask] | kMinusSpread[0][minus_occ[0]] | kMinusSpread[1][minus_occ[1]] |
                                  kMinusSpread[2][minus_occ[2]];
        const std::uint64_t score =
            kScoreSpread[static_cast<std::size_t>(9 * (plane_pred[2] + 1) + 3 * (plane_pred[1] + 1) + (plane_pred[0] + 1))];
        // Codec 8's second model by the child byte so far: the contexts of
        // the specification ((1 << k) | the k bits below child k), numbered
        // as the node of a binary tree instead (1, then 2 tree + bit), one
        // slot per (k, bits below) all the same.
        BitModel* const child_b = mixed ? &mm->child_b[faces_mask << 8] : nullptr;
        unsigned tree = 1;
        // Codec 13: the node's plane, for the child bits' mixer weight sets.
        NodePlane np;
        if constexpr (plane) {
          gather(false);
          np = node_plane(sums);
        }
        for (int k = 0; k < 8; ++k) {
          const int sh = 8 * k;
          const int ctx = static_cast<int>((low >> sh) & 0xFF) | kPlusNb[static_cast<std::size_t>(k)][byte] | (k << 6) |
                          (std::min(siblings, 3) << 9) | (static_cast<int>((score >> sh) & 0xFF) << 11);
          // With single-child coding a coded byte has at least two bits set:
          // when the bits left are exactly the ones still needed they are 1.
          const bool forced = single_mode && 8 - k <= 2 - siblings;
          int bit;
          if (forced) {
            bit = 1;
          } else if constexpr (!mixed) {
            bit = code(models.occupancy[ctx], (truth >> k) & 1);
          } else {
            BitModel& mb = child_b[tree];
            if constexpr (three) {
              BitModel& mc = fm->child_c[patterns | static_cast<unsigned>(k) << 12];
              std::int32_t* w = fm->child_mixer.w[(k << 2) | to_leaves];
              if constexpr (plane) {
                w = pm->child_mixer.w[((k << 2) | to_leaves) * kChildPlaneClasses + child_plane_class(np, k)];
              }
              bit = mix_code_faces(models.occupancy[ctx], mb, mc, w, fm->child_apm[(ctx & 63) | k << 6],
                                   code_prob, (truth >> k) & 1);
            } else {
              bit = mix_code(models.occupancy[ctx], mb, mm->child_mixer.w[(k << 2) | to_leaves], code_prob,
                             (truth >> k) & 1);
            }
          }
          // Written in any case, kept when the bit is set (the branch would
          // be as unpredictable as the bit).
          next_keys[next_count] = (nodes[i] << 3) | static_cast<std::uint64_t>(k);
          next_count += static_cast<std::size_t>(bit);
          byte = static_cast<std::uint8_t>(byte | (bit << k));
          siblings += bit;
          if constexpr (mixed) tree = 2 * tree + static_cast<unsigned>(bit);
        }
      }
      // An occupied node has at least one occupied child.
      if (byte == 0) return false;
      if (chains && !on_chain && d + 1 < depth) {
        // The only child of a node known to hold two cells or more holds them too.
        next_chain.resize(next_count, not_chain && kBitCount[byte] == 1 ? kNotChain : kUnknown);
      }
      occ[i] = byte;
      if (single_mode) next_lone.insert(next_lone.end(), kBitCount[byte], kBitCount[byte] == 1 ? 1 : 0);
      for (int a = 0; a < 3; ++a) planes->remember(a, xyz[a], xyz[(a + 1) % 3], xyz[(a + 2) % 3], byte);
      if (!grow(next_count)) return false;
    }
    next.resize(next_count);
    // Neighbours and coordinates of the next level (none after the last).
    if (d + 1 < depth) {
      next_nb.assign(6 * next_count, kMissing);
      for (std::vector<std::int32_t>& c : next_cell) c.resize(next_count);
      for (std::size_t i = 0; i < count; ++i) {
        const std::uint8_t byte = occ[i];
        const std::uint32_t* n6 = &nb[6 * i];
        std::uint32_t ci = first[i];  // the children, in k order
        for (unsigned bits = byte; bits != 0; bits &= bits - 1, ++ci) {
          const int k = std::countr_zero(bits);
          std::uint32_t* out = &next_nb[6 * static_cast<std::size_t>(ci)];
          for (int a = 0; a < 3; ++a) {
            const int c = (k >> a) & 1;
            const int sibling = k ^ (1 << a);
            // Towards the sibling's side: inside this node.
            out[2 * a + (1 - c)] = child_index(byte, first[i], sibling);
            // Away from it: a child of the neighbour on that side.
            const std::uint32_t m = n6[2 * a + c];
            out[2 * a + c] = m != kMissing ? child_index(occ[m], first[m], sibling) : kMissing;
          }
          for (int a = 0; a < 3; ++a) next_cell[a][ci] = 2 * cell[a][i] + ((k >> a) & 1);
        }
      }
    }
    nb.swap(next_nb);
    cell.swap(next_cell);
    nodes.swap(next);
    lone.swap(next_lone);
    chain.swap(next_chain);
  }
  return true;
}

// The traversal, instantiated apart for codecs 8 and 11 and for codec 12
// (their extra work stays out of the older codecs' loop).
template <typename Code, typename CodeProb, typename TrueByte, typename TrueChain, typename Grow>
bool code_octree(int depth, OctreeCoding coding, GeometryModels& models, std::vector<std::uint64_t>& nodes,
                 Code&& code, CodeProb&& code_prob, TrueByte&& true_byte, TrueChain&& true_chain, Grow&& grow) {
  if (coding == OctreeCoding::kNearest) {
    models.mixed = std::make_unique<MixedModels>();
    models.faces = std::make_unique<FaceModels>();
    models.planes = std::make_unique<PlaneModels>();
    models.near = std::make_unique<NearModels>();
    return code_octree_impl<4>(depth, coding, models, nodes, code, code_prob, true_byte, true_chain, grow);
  }
  if (coding == OctreeCoding::kPlanes) {
    models.mixed = std::make_unique<MixedModels>();
    models.faces = std::make_unique<FaceModels>();
    models.planes = std::make_unique<PlaneModels>();
    models.plane_index = std::make_unique<PlaneIndexModels>();
    return code_octree_impl<3>(depth, coding, models, nodes, code, code_prob, true_byte, true_chain, grow);
  }
  if (coding == OctreeCoding::kFacePatterns) {
    models.mixed = std::make_unique<MixedModels>();
    models.faces = std::make_unique<FaceModels>();
    return code_octree_impl<2>(depth, coding, models, nodes, code, code_prob, true_byte, true_chain, grow);
  }
  if (coding == OctreeCoding::kMixed || coding == OctreeCoding::kChains) {
    models.mixed = std::make_unique<MixedModels>();
    return code_octree_impl<1>(depth, coding, models, nodes, code, code_prob, true_byte, true_chain, grow);
  }
  return code_octree_impl<0>(depth, coding, models, nodes, code, code_prob, true_byte, true_chain, grow);
}

}  // namespace

std::vector<std::uint8_t> encode_geometry(const OccupiedCells& cells, int depth, OctreeCoding coding) {
  // Without a budget, only a refused input makes no stream.
  std::optional<std::vector<std::uint8_t>> out = encode_geometry_within(cells, depth, coding, SIZE_MAX);
  return out ? std::move(*out) : std::vector<std::uint8_t>{};
}

namespace {

// encode_geometry's preconditions: depth 0..kMaxGeometryDepth, keys strictly
// increasing and below 8^depth, one count >= 1 per key, at least one cell.
bool valid_cells(const OccupiedCells& cells, int depth) {
  if (depth < 0 || depth > kMaxGeometryDepth || cells.keys.empty() || cells.counts.size() != cells.keys.size()) {
    return false;
  }
  if ((cells.keys.back() >> (3 * depth)) != 0) return false;
  for (std::size_t j = 0; j < cells.keys.size(); ++j) {
    if (cells.counts[j] == 0 || (j > 0 && cells.keys[j] <= cells.keys[j - 1])) return false;
  }
  return true;
}

}  // namespace

std::optional<std::vector<std::uint8_t>> encode_geometry_within(const OccupiedCells& cells, int depth,
                                                                OctreeCoding coding, std::size_t max_bytes) {
  // A broken precondition would code another octree (or none): an empty
  // stream says so, which no valid input gives (callers report it).
  if (!valid_cells(cells, depth)) return std::vector<std::uint8_t>{};
  // The finished stream is longer than any enc.bytes() on the way.
  RangeEncoder enc;
  auto models = std::make_unique<GeometryModels>();
  // Child occupancy bytes of every level, from the leaves up.
  std::vector<std::vector<std::uint8_t>> bytes(static_cast<std::size_t>(depth));
  // Codec 11: per level, the index of each node's first cell, and the cell
  // count after the last node (a node holds one cell when the next node's
  // first cell follows its own).
  const bool chains = coding == OctreeCoding::kChains || coding == OctreeCoding::kFacePatterns ||
                      coding == OctreeCoding::kPlanes || coding == OctreeCoding::kNearest;
  std::vector<std::vector<std::uint32_t>> first_cell(chains ? static_cast<std::size_t>(depth) : 0);
  {
    std::vector<std::uint64_t> level = cells.keys;
    std::vector<std::uint32_t> level_first;
    if (chains) {
      level_first.resize(level.size());
      for (std::size_t j = 0; j < level.size(); ++j) level_first[j] = static_cast<std::uint32_t>(j);
    }
    for (int d = depth - 1; d >= 0; --d) {
      std::vector<std::uint64_t> parents;
      std::vector<std::uint32_t> parents_first;
      std::vector<std::uint8_t>& b = bytes[static_cast<std::size_t>(d)];
      for (std::size_t j = 0; j < level.size(); ++j) {
        const std::uint64_t key = level[j];
        const std::uint64_t parent = key >> 3;
        if (parents.empty() || parents.back() != parent) {
          parents.push_back(parent);
          b.push_back(0);
          if (chains) parents_first.push_back(level_first[j]);
        }
        b.back() = static_cast<std::uint8_t>(b.back() | (1u << (key & 7)));
      }
      level.swap(parents);
      if (chains) {
        level_first.swap(parents_first);
        first_cell[static_cast<std::size_t>(d)] = level_first;
        first_cell[static_cast<std::size_t>(d)].push_back(static_cast<std::uint32_t>(cells.keys.size()));
      }
    }
  }
  std::vector<std::uint64_t> nodes;
  const bool whole = code_octree(
      depth, coding, *models, nodes,
      [&](BitModel& m, int bit) {
        enc.encode(m, bit);
        return bit;
      },
      [&](std::uint32_t p0, int bit) {
        enc.encode_prob(p0, bit);
        return bit;
      },
      [&](int d, std::size_t i) { return bytes[static_cast<std::size_t>(d)][i]; },
      [&](int d, std::size_t i) {
        const std::vector<std::uint32_t>& f = first_cell[static_cast<std::size_t>(d)];
        return f[i + 1] - f[i] == 1 ? 1 : 0;
      },
      [&](std::size_t) { return enc.bytes() <= max_bytes; });
  if (!whole) return std::nullopt;
  int prev_dup = 0;
  for (const std::uint32_t c : cells.counts) {
    const int dup = c > 1 ? 1 : 0;
    enc.encode(models->duplicate[prev_dup], dup);
    if (dup) encode_uint(enc, models->extra, c - 2);
    prev_dup = dup;
  }
  std::vector<std::uint8_t> out = enc.finish();
  if (out.size() > max_bytes) return std::nullopt;
  return out;
}

Result<OccupiedCells> decode_geometry(std::span<const std::uint8_t> data, int depth, std::uint64_t point_count,
                                      OctreeCoding coding, std::uint64_t* decisions) {
  if (depth < 0 || depth > kMaxGeometryDepth) return corrupt_data("geometry: depth out of range");
  if (point_count == 0) return corrupt_data("geometry: no points");
  RangeDecoder dec(data);
  auto models = std::make_unique<GeometryModels>();
  OccupiedCells cells;
  bool over = false;
  const bool ok = code_octree(
      depth, coding, *models, cells.keys, [&](BitModel& m, int) { return dec.decode(m); },
      [&](std::uint32_t p0, int) { return dec.decode_prob(p0); }, [](int, std::size_t) { return std::uint8_t{0}; },
      [](int, std::size_t) { return 0; },
      [&](std::size_t n) {
        // Every node holds a point; a stream read past its end stops here.
        over = n > point_count || dec.exhausted();
        return !over;
      });
  if (!ok) {
    return corrupt_data(over ? "geometry: the octree holds more cells than the chunk has points, or is truncated"
                             : "geometry: an occupied octree node without children");
  }
  cells.counts.resize(cells.keys.size());
  std::uint64_t total = 0;
  int prev_dup = 0;
  for (std::uint32_t& c : cells.counts) {
    const int dup = dec.decode(models->duplicate[prev_dup]);
    std::uint64_t extra = 0;
    if (dup && !decode_uint(dec, models->extra, extra)) return corrupt_data("geometry: bad duplicate count");
    if (dec.exhausted()) return corrupt_data("geometry: stream truncated in the point counts");
    const std::uint64_t n = dup ? extra + 2 : 1;
    total += n;
    if (n > point_count || total > point_count) {
      return corrupt_data("geometry: cells hold more points than the chunk declares");
    }
    c = static_cast<std::uint32_t>(n);
    prev_dup = dup;
  }
  if (total != point_count) {
    return corrupt_data("geometry: cells hold " + std::to_string(total) + " points, the chunk declares " +
                        std::to_string(point_count));
  }
  if (decisions != nullptr) *decisions = dec.decisions();
  return cells;
}

}  // namespace relief::codec
