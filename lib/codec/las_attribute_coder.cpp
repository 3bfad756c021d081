// Mirror pair in one file: each LAS attribute's encoder and decoder run the
// same routine (code_attribute), parameterised by the bit coder, as
// geometry_coder.cpp does, so they cannot drift apart. format-spec/chunk.md
// §11.7 is the normative description.
//
// Points arrive in cell order, so the previous point is a spatial neighbour:
// categorical values (classification, returns, flags, user data) are coded
// with adaptive models whose context is the previous point's value; numeric
// ones (scan angle, GPS time, NIR) as differences from the previous point
// with models chosen by the size of the previous difference. Format 6 codes
// GPS times in time order instead (code_gps_time_order), and with them the
// attributes that follow acquisition order (code_time_ordered).
#include "codec/las_attribute_coder.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <memory>
#include <numeric>
#include <string>
#include <type_traits>

#include "codec/attribute_coder.h"
#include "codec/bit_coders.h"
#include "codec/octree.h"
#include "codec/range_coder.h"

namespace relief::codec {

namespace {

// A byte as 8 binary decisions down a tree (node 1 is the root, node k's
// children are 2k and 2k + 1), most significant bit first. From format 11
// (`hits`, §11.7.3) one decision first says whether the byte is the one this
// model has coded most, and the tree follows only when it is not: a
// context's value mostly repeats (a run of one class, a pulse's count of
// returns), and one decision then does the work of eight.
struct ByteModel {
  BitModel node[256];
  // Format 11: the byte the hit flag asks about, the one this model has
  // coded most (a majority vote: a hit adds a vote, up to 255; a miss takes
  // one away, and a miss with no votes left makes the missed byte the guess).
  BitModel hit;
  std::uint8_t guess = 0;
  std::uint8_t votes = 0;
};

template <typename C>
void code_byte(C& c, ByteModel& m, std::uint8_t& v, bool hits) {
  if (hits && c.bit(m.hit, v == m.guess ? 1 : 0) != 0) {
    v = m.guess;
    if (m.votes < 255) ++m.votes;
    return;
  }
  unsigned node = 1;
  for (int i = 7; i >= 0; --i) node = 2 * node + static_cast<unsigned>(c.bit(m.node[node], (v >> i) & 1));
  v = static_cast<std::uint8_t>(node - 256);
  if (m.votes == 0) {
    m.guess = v;
  } else {
    --m.votes;
  }
}

// Byte models per context, made when a context is first used (1.5 KB each).
using ByteContexts = LazyModels<ByteModel>;

constexpr std::size_t kByteContexts = 256;

// A u8 attribute with the previous point's value as context.
template <typename C>
bool code_bytes_prev(C& c, std::vector<std::uint8_t>& v, bool hits) {
  ByteContexts models(kByteContexts);
  std::uint8_t prev = 0;
  for (std::uint8_t& x : v) {
    code_byte(c, models[prev], x, hits);
    prev = x;
    if (!c.ok()) return false;
  }
  return true;
}

// Size classes of a difference: how often |r| can be shifted right by 2
// before it reaches 0, at most 11 (as the intensity section, §11.5).
constexpr int kDeltaClasses = 12;
int delta_class(std::int64_t r) {
  const std::uint64_t m = r < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(r) : static_cast<std::uint64_t>(r);
  int c = 0;
  for (std::uint64_t v = m; v != 0 && c < kDeltaClasses - 1; v >>= 2) ++c;
  return c;
}

// Integers coded as differences from the previous point (modulo 2^64), with
// the class of the previous difference as context. `get(i)` gives the value
// (encoder), `put(i, v)` stores a decoded one and returns false when it is out
// of the attribute's range.
template <typename C, typename Get, typename Put>
bool code_deltas(C& c, std::size_t n, Get&& get, Put&& put) {
  auto models = std::make_unique<SIntModel[]>(kDeltaClasses);
  std::uint64_t prev = 0;
  int cls = 0;
  for (std::size_t i = 0; i < n; ++i) {
    auto r = static_cast<std::int64_t>(get(i) - prev);
    if (!c.sint(models[static_cast<std::size_t>(cls)], r) || !c.ok()) return false;
    prev += static_cast<std::uint64_t>(r);
    if (!put(i, prev)) return false;
    cls = delta_class(r);
  }
  return true;
}

// Format 15 (§11.7): NIR differences with the model set of the green
// level's change between the same two points (clamped to ±12) and of the
// class of the previous difference. The NIR band moves with the visible ones
// (shadows, roofs, vegetation edges), green most closely: on the aerial tile
// of the shared files NIR costs 4.12 bits a point with code_deltas, 3.35 so
// (bench/attributes).
constexpr std::int64_t kGreenReach = 12;

template <typename C, typename Get, typename Put>
bool code_deltas_by_green(C& c, std::size_t n, std::span<const Rgb8> colors, Get&& get, Put&& put) {
  auto models = std::make_unique<SIntModel[]>((2 * kGreenReach + 1) * kDeltaClasses);
  std::uint64_t prev = 0;
  int cls = 0;
  std::int64_t green = 0;  // the previous point's green level (0 before the first)
  for (std::size_t i = 0; i < n; ++i) {
    const std::int64_t change = std::clamp<std::int64_t>(colors[i].g - green, -kGreenReach, kGreenReach);
    green = colors[i].g;
    const auto ctx = static_cast<std::size_t>(change + kGreenReach) * kDeltaClasses + static_cast<std::size_t>(cls);
    auto r = static_cast<std::int64_t>(get(i) - prev);
    if (!c.sint(models[ctx], r) || !c.ok()) return false;
    prev += static_cast<std::uint64_t>(r);
    if (!put(i, prev)) return false;
    cls = delta_class(r);
  }
  return true;
}

// Greatest common divisor of the magnitudes of v (1 when all are 0): a
// section of such values codes it first and the values divided by it. Scan
// angles are whole degrees (x 1000) or steps of 0.006 degrees (x 6) in
// LasAttributes' units, and 8-bit NIR is often stored x 256.
template <typename T>
std::uint64_t common_unit(const std::vector<T>& v) {
  std::uint64_t g = 0;
  for (const T x : v) {
    const auto m = static_cast<std::uint64_t>(x < 0 ? -static_cast<std::int64_t>(x) : static_cast<std::int64_t>(x));
    g = std::gcd(g, m);
    if (g == 1) break;
  }
  return g == 0 ? 1 : g;
}

// Codes the unit (as unit - 1); false for a unit the attribute cannot have.
template <typename C>
bool code_unit(C& c, std::uint64_t& unit, std::uint64_t max_unit) {
  auto model = std::make_unique<UIntModel>();
  std::uint64_t u = unit - 1;
  if (!c.uint(*model, u) || u >= max_unit) return false;
  unit = u + 1;
  return c.ok();
}

// GPS times: in cell order consecutive points are spatial neighbours, but
// the previous point often lies on an adjacent scan line, far away in time,
// while one of the few points before it lies on the same line. Each point
// names one of the last kGpsWindow points as its reference (the encoder takes
// the nearest in time, the lowest index on ties; context: the previous
// point's choice) and codes its bit-pattern difference from that reference,
// modelled by how far back the reference is (0, 1, 2, 3+) and by the class of
// the reference's own difference (its scan line's regime).
constexpr int kGpsWindowBits = 5;
constexpr std::size_t kGpsWindow = std::size_t{1} << kGpsWindowBits;
constexpr std::size_t kGpsReach = 4;
template <typename C>
bool code_gps(C& c, std::vector<double>& v) {
  struct Models {
    BitModel ref[kGpsWindow][kGpsWindow];
    SIntModel delta[kGpsReach][kDeltaClasses];
  };
  auto m = std::make_unique<Models>();
  // window[(i - 1 - j) mod kGpsWindow] is the bit pattern of point i - 1 - j
  // (0 before the first point).
  std::array<std::uint64_t, kGpsWindow> window{};
  std::array<int, kGpsWindow> window_cls{};
  std::size_t prev_ref = 0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    const std::uint64_t bits = std::bit_cast<std::uint64_t>(v[i]);
    const auto slot = [&](std::size_t j) { return (i + 2 * kGpsWindow - 1 - j) % kGpsWindow; };
    std::size_t best = 0;
    std::uint64_t best_dist = ~std::uint64_t{0};
    for (std::size_t j = 0; j < kGpsWindow; ++j) {
      const std::uint64_t d = bits - window[slot(j)];
      const std::uint64_t dist = std::min(d, std::uint64_t{0} - d);
      if (dist < best_dist) {
        best_dist = dist;
        best = j;
      }
    }
    unsigned node = 1;
    for (int b = kGpsWindowBits - 1; b >= 0; --b) {
      node = 2 * node + static_cast<unsigned>(c.bit(m->ref[prev_ref][node], static_cast<int>(best >> b) & 1));
    }
    const std::size_t j = node - kGpsWindow;
    const std::uint64_t ref = window[slot(j)];
    auto r = static_cast<std::int64_t>(bits - ref);
    if (!c.sint(m->delta[std::min(j, kGpsReach - 1)][window_cls[slot(j)]], r) || !c.ok()) return false;
    const std::uint64_t got = ref + static_cast<std::uint64_t>(r);
    v[i] = std::bit_cast<double>(got);
    if (!std::isfinite(v[i])) return false;
    window[i % kGpsWindow] = got;
    window_cls[i % kGpsWindow] = delta_class(r);
    prev_ref = j;
  }
  return true;
}

// GPS times in time order (format 6, format-spec/chunk.md §11.7.1). The
// points are visited in increasing order of their times' bit patterns (ties
// by cell index): for each, the time as a difference from the previous one
// (a pulse's returns share a time, a scanner's pulse spacing repeats), then
// which point it is, as its rank among the unused points near a position
// predicted from the previous ones (the next pulse lies one step further
// along the scan line; a pulse's next return lies below its last).
constexpr int kRankBits = 5;
constexpr std::uint32_t kRankEscape = (1u << kRankBits) - 1;
constexpr std::size_t kMaxCandidates = 64;
constexpr std::size_t kBucketsPerPoint = 4;
constexpr std::uint32_t kNoPoint = ~std::uint32_t{0};
// A time's step is 0 (another return of the pulse), one of the last kSteps
// distinct steps (a move-to-front list: scanners alternate between a few
// spacings, one unit of the last place apart), or another.
constexpr std::size_t kSteps = 6;
constexpr int kTimeSymbolBits = 3;
constexpr int kTimeSymbols = static_cast<int>(kSteps) + 2;
constexpr int kRankContexts = 9;

// The bucket shift the encoder picks: the smallest with at most 4 n buckets
// over the points' x-y bounding box. Smaller buckets leave fewer candidates
// (fewer escapes where vegetation stacks points, faster). bench/attributes,
// bits a point, 4 n buckets against n / 4 and n: the aerial tile 2.40
// against 6.26 and 2.84, the Autzen tile 5.10 against 5.19 and 4.87.
int pick_bucket_shift(std::span<const CellXyz> cells) {
  std::uint32_t mx = 0, my = 0;
  for (const CellXyz& p : cells) {
    mx = std::max(mx, p[0]);
    my = std::max(my, p[1]);
  }
  for (int b = 0; b < kMaxBucketShift; ++b) {
    const std::uint64_t buckets = (std::uint64_t{mx >> b} + 1) * (std::uint64_t{my >> b} + 1);
    if (buckets <= kBucketsPerPoint * cells.size()) return b;
  }
  return kMaxBucketShift;
}

// `order[k]` is the cell index of the k-th point in time order (encoder:
// given; decoder: filled); `bits` the times' bit patterns by cell index.
// Without `ranks` (format 8, geometry in time order, §11.3.3) the section
// holds the times alone: the geometry has fixed the order, `cells` is unused
// and the decoder fills bits[k] with the k-th time (order[k] = k).
template <typename C>
bool code_gps_time_order(C& c, std::vector<std::uint64_t>& bits, std::vector<std::uint32_t>& order,
                         std::span<const CellXyz> cells, int shift_in, bool ranks = true, bool any_order = false) {
  const std::size_t n = bits.size();
  if ((ranks && cells.size() != n) || order.size() != n) return false;
  struct Models {
    UIntModel shift, first_index;
    BitModel symbol[kTimeSymbols][std::size_t{1} << kTimeSymbolBits];
    SIntModel step[kDeltaClasses];
    BitModel rank[kRankContexts][std::size_t{1} << kRankBits];
    SIntModel jump[2];
  };
  auto m = std::make_unique<Models>();
  std::uint64_t shift = static_cast<std::uint64_t>(shift_in);
  if (ranks && (!c.uint(m->shift, shift) || shift > kMaxBucketShift)) return false;
  if (!ranks) shift = kMaxBucketShift;
  const int b = static_cast<int>(shift);
  std::uint32_t mx = 0, my = 0;
  for (const CellXyz& p : cells) {
    mx = std::max(mx, p[0]);
    my = std::max(my, p[1]);
  }
  const std::uint64_t gx = std::uint64_t{mx >> b} + 1, gy = std::uint64_t{my >> b} + 1;
  if (gx * gy > kBucketsPerPoint * std::uint64_t{n} + 16) return false;
  // Each bucket's unused points, in cell order, as a doubly linked list
  // (built from the back, each point pushed at the front).
  std::vector<std::uint32_t> head(ranks ? gx * gy : 0, kNoPoint), next(ranks ? n : 0, kNoPoint),
      prev(ranks ? n : 0, kNoPoint);
  const auto bucket = [&](std::size_t i) { return std::size_t{cells[i][1] >> b} * gx + (cells[i][0] >> b); };
  for (std::size_t i = ranks ? n : 0; i-- > 0;) {
    const std::size_t k = bucket(i);
    const auto u = static_cast<std::uint32_t>(i);
    if (head[k] != kNoPoint) prev[head[k]] = u;
    next[u] = head[k];
    head[k] = u;
  }
  std::vector<std::uint8_t> used(ranks ? n : 0, 0);
  struct Candidate {
    std::uint64_t dist;
    std::uint32_t index;
    bool operator<(const Candidate& o) const { return dist != o.dist ? dist < o.dist : index < o.index; }
  };
  std::array<Candidate, kMaxCandidates> cand{};
  std::uint64_t last = 0;
  std::array<std::uint64_t, kSteps> steps{};
  int prev_symbol = 0, step_cls = 0, prev_rank = 0;
  std::array<std::int64_t, 3> pulse{}, pulse_before{};  // first points of the last two pulses
  for (std::size_t k = 0; k < n; ++k) {
    // ---- The time.
    std::uint64_t d = C::kEncoding ? bits[order[k]] - last : 0;
    int symbol = kTimeSymbols - 1;
    if (d == 0) {
      symbol = 0;
    } else {
      for (std::size_t j = 0; j < kSteps; ++j) {
        if (steps[j] == d) {
          symbol = static_cast<int>(j) + 1;
          break;
        }
      }
    }
    unsigned node = 1;
    for (int i = kTimeSymbolBits - 1; i >= 0; --i) {
      node = 2 * node + static_cast<unsigned>(c.bit(m->symbol[prev_symbol][node], (symbol >> i) & 1));
    }
    symbol = static_cast<int>(node - (1u << kTimeSymbolBits));
    if (symbol >= kTimeSymbols) return false;
    std::size_t slot = kSteps - 1;  // where the step was: it moves to the front
    if (symbol == 0) {
      d = 0;
    } else if (symbol < kTimeSymbols - 1) {
      slot = static_cast<std::size_t>(symbol - 1);
      d = steps[slot];
    } else {
      auto r = static_cast<std::int64_t>(d - steps[0]);
      if (!c.sint(m->step[step_cls], r)) return false;
      d = steps[0] + static_cast<std::uint64_t>(r);
      step_cls = delta_class(r);
    }
    const std::uint64_t time = last + d;
    // In time order the bit patterns never decrease; a layer in the
    // encoder's own order (format 14, any_order) may step back (the step
    // then wraps modulo 2^64).
    if ((time < last && !any_order) || !std::isfinite(std::bit_cast<double>(time))) return false;
    if (d != 0) {
      for (std::size_t j = slot; j > 0; --j) steps[j] = steps[j - 1];
      steps[0] = d;
    }
    prev_symbol = symbol;
    // ---- The point.
    std::uint64_t index = C::kEncoding || ranks ? order[k] : k;
    if (!ranks) {
      if (!c.ok()) return false;
      bits[index] = time;
      order[k] = static_cast<std::uint32_t>(index);
      last = time;
      continue;
    }
    if (k == 0) {
      if (!c.uint(m->first_index, index) || index >= n) return false;
    } else {
      const bool same = d == 0;
      const CellXyz& at = cells[order[k - 1]];
      std::int64_t pr[3];
      for (int a = 0; a < 3; ++a) {
        const auto i = static_cast<std::size_t>(a);
        pr[a] = same ? std::int64_t{at[i]} : 2 * pulse[i] - pulse_before[i];
      }
      // The buckets within one bucket edge of the prediction (2 or 3 a side).
      const std::int64_t reach = std::int64_t{1} << b;
      const auto span_of = [&](std::int64_t v, std::uint32_t hi) {
        return std::pair<std::size_t, std::size_t>{static_cast<std::size_t>(std::clamp<std::int64_t>(v - reach, 0, hi) >> b),
                                                   static_cast<std::size_t>(std::clamp<std::int64_t>(v + reach, 0, hi) >> b)};
      };
      const auto [x0, x1] = span_of(pr[0], mx);
      const auto [y0, y1] = span_of(pr[1], my);
      const auto dist_to = [&](std::uint32_t q) {
        std::uint64_t dist = 0;
        for (int a = 0; a < 3; ++a) {
          const std::int64_t e = std::int64_t{cells[q][static_cast<std::size_t>(a)]} - pr[a];
          dist += static_cast<std::uint64_t>(e * e);
        }
        return dist;
      };
      // The encoder counts the candidates before the point (its rank) as it
      // visits them; the decoder keeps them to pick the rank it reads.
      const Candidate point{C::kEncoding ? dist_to(static_cast<std::uint32_t>(index)) : 0,
                            static_cast<std::uint32_t>(index)};
      std::uint32_t before = 0;
      bool found = false;
      std::size_t count = 0;
      for (std::size_t y = y0; y <= y1 && count < kMaxCandidates; ++y) {
        for (std::size_t x = x0; x <= x1 && count < kMaxCandidates; ++x) {
          for (std::uint32_t q = head[y * gx + x];
               q != kNoPoint && count < kMaxCandidates; q = next[q]) {
            const Candidate here{dist_to(q), q};
            if constexpr (C::kEncoding) {
              found = found || q == index;
              before += here < point ? 1 : 0;
            } else {
              cand[count] = here;
            }
            ++count;
          }
        }
      }
      std::uint32_t rank = found ? std::min(before, kRankEscape) : kRankEscape;
      const int ctx = (same ? 3 : symbol == kTimeSymbols - 1 ? 6 : 0) + std::min(prev_rank, 2);
      node = 1;
      for (int i = kRankBits - 1; i >= 0; --i) {
        node = 2 * node + static_cast<unsigned>(c.bit(m->rank[ctx][node], static_cast<int>(rank >> i) & 1));
      }
      rank = node - (1u << kRankBits);
      prev_rank = static_cast<int>(rank);
      if (rank == kRankEscape) {
        auto r = static_cast<std::int64_t>(index - order[k - 1]);
        if (!c.sint(m->jump[same ? 1 : 0], r)) return false;
        index = order[k - 1] + static_cast<std::uint64_t>(r);
        if (index >= n || used[index]) return false;
      } else {
        if (rank >= count) return false;
        if (!C::kEncoding) {
          const auto end = cand.begin() + static_cast<std::ptrdiff_t>(count);
          if (rank == 0) {
            index = std::min_element(cand.begin(), end)->index;
          } else {
            std::nth_element(cand.begin(), cand.begin() + rank, end);
            index = cand[rank].index;
          }
        }
      }
    }
    if (!c.ok()) return false;
    const auto u = static_cast<std::uint32_t>(index);
    used[u] = 1;
    const std::size_t bk = bucket(u);
    (prev[u] == kNoPoint ? head[bk] : next[prev[u]]) = next[u];
    if (next[u] != kNoPoint) prev[next[u]] = prev[u];
    order[k] = u;
    bits[u] = time;
    last = time;
    if (k == 0 || d != 0) {
      for (int a = 0; a < 3; ++a) {
        const auto i = static_cast<std::size_t>(a);
        pulse_before[i] = k == 0 ? std::int64_t{cells[u][i]} : pulse[i];
        pulse[i] = cells[u][i];
      }
    }
  }
  return true;
}

// Point source IDs: a move-to-front list of the last kSourceSlots distinct
// IDs (flight lines overlap, so cell order alternates between a few); the
// symbol is the slot of the ID (0..3) or kSourceSlots for a new one, coded
// with the previous symbol as context, a new ID then as two bytes.
constexpr int kSourceSlots = 4;
constexpr int kSourceSymbolBits = 3;
// In time order (format 6, `kind` non-null: las_pulse_kinds) the trees are also
// chosen by whether the point is another return of the previous point's pulse.
template <typename C>
bool code_point_source(C& c, std::vector<std::uint16_t>& v, const std::vector<std::uint8_t>* kind = nullptr) {
  struct Models {
    BitModel symbol[2][kSourceSlots + 1][1 << kSourceSymbolBits];
    ByteModel high, low;
  };
  auto m = std::make_unique<Models>();
  std::array<std::uint16_t, kSourceSlots> slots{};
  int prev_sym = 0;
  for (std::size_t k = 0; k < v.size(); ++k) {
    std::uint16_t& x = v[k];
    const std::size_t pulse = kind != nullptr && (*kind)[k] == 1 ? 1 : 0;  // kPulseSame
    int sym = kSourceSlots;
    for (int s = 0; s < kSourceSlots; ++s) {
      if (slots[static_cast<std::size_t>(s)] == x) {
        sym = s;
        break;
      }
    }
    unsigned node = 1;
    for (int i = kSourceSymbolBits - 1; i >= 0; --i) {
      node = 2 * node + static_cast<unsigned>(c.bit(m->symbol[pulse][prev_sym][node], (sym >> i) & 1));
    }
    sym = static_cast<int>(node - (1u << kSourceSymbolBits));
    if (sym > kSourceSlots) return false;
    std::uint16_t id = 0;
    if (sym == kSourceSlots) {
      std::uint8_t hi = static_cast<std::uint8_t>(x >> 8), lo = static_cast<std::uint8_t>(x);
      code_byte(c, m->high, hi, false);
      code_byte(c, m->low, lo, false);
      id = static_cast<std::uint16_t>(hi << 8 | lo);
      sym = kSourceSlots - 1;  // a new ID enters at the front, the last slot drops out
    } else {
      id = slots[static_cast<std::size_t>(sym)];
    }
    for (int s = sym; s > 0; --s) slots[static_cast<std::size_t>(s)] = slots[static_cast<std::size_t>(s - 1)];
    slots[0] = id;
    x = id;
    prev_sym = static_cast<int>(node - (1u << kSourceSymbolBits));
    if (!c.ok()) return false;
  }
  return true;
}

// Extra bytes: per byte column j, the difference from the previous point's
// byte in that column (modulo 256), with the column (columns from
// kExtraColumns - 1 on share one) and the class of that column's previous
// difference as context.
constexpr std::size_t kExtraColumns = 64;
constexpr std::size_t kExtraClasses = 4;
std::size_t byte_delta_class(std::uint8_t d) {
  if (d == 0) return 0;
  if (d == 1 || d == 255) return 1;
  if (d < 16 || d > 240) return 2;
  return 3;
}
template <typename C>
bool code_extra_bytes(C& c, std::vector<std::uint8_t>& v, std::size_t width, bool hits) {
  ByteContexts models(kExtraColumns * kExtraClasses);
  std::vector<std::uint8_t> prev(width, 0), cls(width, 0);
  const std::size_t n = width == 0 ? 0 : v.size() / width;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* row = v.data() + i * width;
    for (std::size_t j = 0; j < width; ++j) {
      std::uint8_t d = static_cast<std::uint8_t>(row[j] - prev[j]);
      code_byte(c, models[std::min(j, kExtraColumns - 1) * kExtraClasses + cls[j]], d, hits);
      row[j] = static_cast<std::uint8_t>(prev[j] + d);
      prev[j] = row[j];
      cls[j] = static_cast<std::uint8_t>(byte_delta_class(d));
    }
    if (!c.ok()) return false;
  }
  return true;
}

std::uint64_t double_bits(double v) { return std::bit_cast<std::uint64_t>(v); }

constexpr int kMaxReturnContext = 15;

// Format 11 codes bytes with a hit flag first (code_byte).
bool byte_hits(int version) { return version >= 11; }
// Format 15: the scan angle in time order by what followed the same values (§11.7.2).
bool scan_angle_successors(int version) { return version >= 15; }
// Format 15: NIR against the points' colours, where the blob has them (§11.7).
bool nir_by_green(int version) { return version >= 15; }

// Codes attribute `bit` of las (every vector already sized to n points).
// `unit` is the common unit of scan angles or NIR (encoder: computed by
// common_unit; decoder: read here). `hits`: bytes as format 11 codes them.
template <typename C>
bool code_attribute(C& c, std::uint32_t bit, LasAttributes& las, std::size_t n, std::uint64_t unit, bool hits,
                    std::span<const Rgb8> green_from = {}) {
  switch (bit) {
    case kLasClassification: return code_bytes_prev(c, las.classification, hits);
    case kLasClassFlags: return code_bytes_prev(c, las.class_flags, hits);
    case kLasReturnNumber: return code_bytes_prev(c, las.return_number, hits);
    case kLasNumberOfReturns: {
      // The point's own return number (coded before) and the previous
      // point's number of returns: a pulse's returns share their count.
      ByteContexts models(static_cast<std::size_t>(kMaxReturnContext + 1) * (kMaxReturnContext + 1));
      const bool has_rn = !las.return_number.empty();
      std::uint8_t prev = 0;
      for (std::size_t i = 0; i < n; ++i) {
        const int rn = has_rn ? std::min<int>(las.return_number[i], kMaxReturnContext) : 0;
        const std::size_t ctx = static_cast<std::size_t>(rn) * (kMaxReturnContext + 1) +
                                static_cast<std::size_t>(std::min<int>(prev, kMaxReturnContext));
        code_byte(c, models[ctx], las.number_of_returns[i], hits);
        prev = las.number_of_returns[i];
        if (!c.ok()) return false;
      }
      return true;
    }
    case kLasScanFlags: return code_bytes_prev(c, las.scan_flags, hits);
    case kLasScanAngle: {
      constexpr std::uint64_t kMaxUnit = std::uint64_t{1} << 31;
      if (!code_unit(c, unit, kMaxUnit)) return false;
      const auto u = static_cast<std::int64_t>(unit);
      return code_deltas(
          c, n,
          [&](std::size_t i) { return static_cast<std::uint64_t>(static_cast<std::int64_t>(las.scan_angle[i]) / u); },
          [&](std::size_t i, std::uint64_t v) {
            const auto q = static_cast<std::int64_t>(v);
            if (q < INT32_MIN / u || q > INT32_MAX / u) return false;
            las.scan_angle[i] = static_cast<std::int32_t>(q * u);
            return true;
          });
    }
    case kLasUserData: return code_bytes_prev(c, las.user_data, hits);
    case kLasPointSourceId: return code_point_source(c, las.point_source_id);
    case kLasGpsTime:
      // The IEEE bit pattern: for times of one sign and binade its
      // differences are the time differences in units of the last place.
      // (A move-to-front list of 8 "tracks" measured no better than the
      // previous point; the window of the last 32 points gains 2.7-3.6
      // bits per point on the shared aerial files.)
      return code_gps(c, las.gps_time);
    case kLasNir: {
      constexpr std::uint64_t kMaxUnit = 0xFFFF;
      if (!code_unit(c, unit, kMaxUnit)) return false;
      const auto get = [&](std::size_t i) { return std::uint64_t{las.nir[i]} / unit; };
      const auto put = [&](std::size_t i, std::uint64_t v) {
        if (v > 0xFFFF / unit) return false;
        las.nir[i] = static_cast<std::uint16_t>(v * unit);
        return true;
      };
      if (!green_from.empty()) return green_from.size() == n && code_deltas_by_green(c, n, green_from, get, put);
      return code_deltas(c, n, get, put);
    }
    case kLasExtraBytes: return code_extra_bytes(c, las.extra_bytes, las.extra_bytes_size, hits);
    default: return false;
  }
}

// Format 6, a chunk with GPS times (format-spec/chunk.md §11.7.2): where a
// point stands in the sequence of pulses, from its time and the previous
// point's in time order. A pulse's returns share a time; a step in time much
// longer than the last (kPulseGap) means pulses outside the chunk in between,
// often the next scan line re-entering it.
constexpr std::uint8_t kPulseNext = 0;  // the next pulse
constexpr std::uint8_t kPulseSame = 1;  // another return of the previous point's pulse
constexpr std::uint8_t kPulseGap = 2;   // a later pulse: floor(step / 2) > the last non-zero step
constexpr std::size_t kPulseKinds = 3;

}  // namespace

// The kinds of the points in time order: `order` lists indices into `gps`.
std::vector<std::uint8_t> las_pulse_kinds(const std::vector<double>& gps, std::span<const std::uint32_t> order) {
  std::vector<std::uint8_t> kind(order.size(), kPulseNext);
  std::uint64_t last_step = 0;
  for (std::size_t k = 1; k < order.size(); ++k) {
    const std::uint64_t d = double_bits(gps[order[k]]) - double_bits(gps[order[k - 1]]);
    kind[k] = d == 0 ? kPulseSame : (last_step != 0 && d / 2 > last_step) ? kPulseGap : kPulseNext;
    if (d != 0) last_step = d;
  }
  return kind;
}

namespace {

// A map from 64-bit keys to the last residual stored under them: open
// addressing, linear probing, doubled at half load. Only lookups and stores
// are used, so its behaviour is that of any map (format-spec/chunk.md
// §11.7.2, version 15); at most one entry per point is added.
class SuccessorMap {
 public:
  SuccessorMap() : keys_(kFirstCapacity), values_(kFirstCapacity), used_(kFirstCapacity, 0) {}

  const std::int64_t* find(std::uint64_t key) const {
    for (std::size_t i = slot(key);; i = (i + 1) & (keys_.size() - 1)) {
      if (!used_[i]) return nullptr;
      if (keys_[i] == key) return &values_[i];
    }
  }
  void store(std::uint64_t key, std::int64_t value) {
    std::size_t i = slot(key);
    while (used_[i] && keys_[i] != key) i = (i + 1) & (keys_.size() - 1);
    if (used_[i]) {
      values_[i] = value;
      return;
    }
    keys_[i] = key;
    values_[i] = value;
    used_[i] = 1;
    if (2 * ++size_ > keys_.size()) grow();
  }

 private:
  static constexpr std::size_t kFirstCapacity = 1024;
  std::size_t slot(std::uint64_t key) const {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ull) >> (64 - std::countr_zero(keys_.size())));
  }
  void grow() {
    std::vector<std::uint64_t> keys(2 * keys_.size());
    std::vector<std::int64_t> values(keys.size());
    std::vector<std::uint8_t> used(keys.size(), 0);
    keys.swap(keys_);
    values.swap(values_);
    used.swap(used_);
    size_ = 0;
    for (std::size_t i = 0; i < keys.size(); ++i) {
      if (used[i]) store(keys[i], values[i]);
    }
  }

  std::vector<std::uint64_t> keys_;
  std::vector<std::int64_t> values_;
  std::vector<std::uint8_t> used_;
  std::size_t size_ = 0;
};

// Version 15 (§11.7.2): each scan angle step between pulses with the model
// set of what followed the same two values (else the same value) the last
// time, which a scanner's fixed angular sampling repeats line after line.
// Values are coded as q = angle / u; returns false on a stream or value the
// section cannot hold.
constexpr std::int64_t kSuccessorReach = 64;  // predicted steps -64..64 have sets of their own
constexpr std::size_t kSuccessorClasses = 2 * kSuccessorReach + 2;  // + "nothing stored"

template <typename C>
bool code_scan_angle_successors(C& c, LasAttributes& las, std::size_t n, std::int64_t u,
                                const std::vector<std::uint8_t>& kind) {
  // Set 0: points of the same pulse; then by (gap?, order) × predicted class.
  auto models = std::make_unique<SIntModel[]>(1 + 2 * 2 * kSuccessorClasses);
  SuccessorMap pairs, singles;
  std::uint64_t prev = 0, before = 0;  // q_{k-1}, and q_{k-1} as it was at the last step between pulses
  for (std::size_t k = 0; k < n; ++k) {
    std::int64_t r = static_cast<std::int64_t>(static_cast<std::uint64_t>(static_cast<std::int64_t>(las.scan_angle[k]) / u) - prev);
    std::size_t ctx = 0;
    const bool step = kind[k] != kPulseSame;
    // Every q fits 32 bits (checked below), so the pair packs into one key.
    const std::uint64_t pair_key = ((before & 0xFFFFFFFFu) << 32) | (prev & 0xFFFFFFFFu);
    if (step) {
      const std::int64_t* s = pairs.find(pair_key);
      const std::size_t order = s != nullptr ? 1 : 0;
      if (s == nullptr) s = singles.find(prev);
      const std::size_t cls =
          s == nullptr ? 0 : static_cast<std::size_t>(std::clamp(*s, -kSuccessorReach, kSuccessorReach) + kSuccessorReach + 1);
      ctx = 1 + ((kind[k] == kPulseGap ? 2 : 0) + order) * kSuccessorClasses + cls;
    }
    if (!c.sint(models[ctx], r) || !c.ok()) return false;
    if (step) {
      pairs.store(pair_key, r);
      singles.store(prev, r);
      before = prev;
    }
    prev += static_cast<std::uint64_t>(r);
    const auto q = static_cast<std::int64_t>(prev);
    if (q < INT32_MIN / u || q > INT32_MAX / u) return false;
    las.scan_angle[k] = static_cast<std::int32_t>(q * u);
  }
  return true;
}

// An attribute of kLasTimeOrdered with its points in time order (las's
// vectors hold them so), where consecutive points are consecutive returns
// and pulses as LAZ codes them; `kind` from las_pulse_kinds. A pulse's returns
// share their scan angle, flags and source and count their return numbers
// up; the scan angle moves slowly along a line.
template <typename C>
bool code_time_ordered(C& c, std::uint32_t bit, LasAttributes& las, std::size_t n, std::uint64_t unit,
                       const std::vector<std::uint8_t>& kind, bool hits, bool successors) {
  if (kind.size() < n) return false;
  switch (bit) {
    case kLasReturnNumber:
    case kLasScanFlags:
    case kLasUserData: {
      std::vector<std::uint8_t>& v =
          bit == kLasReturnNumber ? las.return_number : bit == kLasScanFlags ? las.scan_flags : las.user_data;
      ByteContexts models(kPulseKinds * kByteContexts);
      std::uint8_t prev = 0;
      for (std::size_t k = 0; k < n; ++k) {
        code_byte(c, models[kind[k] * kByteContexts + prev], v[k], hits);
        prev = v[k];
        if (!c.ok()) return false;
      }
      return true;
    }
    case kLasNumberOfReturns: {
      // (Three kinds measured 2-5 % dearer than two here.)
      constexpr std::size_t kSide = kMaxReturnContext + 1;
      ByteContexts models(2 * kSide * kSide);
      const bool has_rn = !las.return_number.empty();
      std::uint8_t prev = 0;
      for (std::size_t k = 0; k < n; ++k) {
        const int rn = has_rn ? std::min<int>(las.return_number[k], kMaxReturnContext) : 0;
        const std::size_t ctx = ((kind[k] == kPulseSame ? kSide : 0) + static_cast<std::size_t>(rn)) * kSide +
                                static_cast<std::size_t>(std::min<int>(prev, kMaxReturnContext));
        code_byte(c, models[ctx], las.number_of_returns[k], hits);
        prev = las.number_of_returns[k];
        if (!c.ok()) return false;
      }
      return true;
    }
    case kLasScanAngle: {
      // Differences from the previous point, with model sets by the kind
      // and, from the differences of the last two points that began a pulse,
      // their classes (the sweep's speed) and the sign of the last non-zero
      // one (its direction). A second-order prediction (the last pulse's
      // difference again) measured 50 % dearer on the aerial tile.
      constexpr std::uint64_t kMaxUnit = std::uint64_t{1} << 31;
      if (!code_unit(c, unit, kMaxUnit)) return false;
      const auto u = static_cast<std::int64_t>(unit);
      if (successors) return code_scan_angle_successors(c, las, n, u, kind);
      constexpr std::size_t kBefore = 3;
      auto models = std::make_unique<SIntModel[]>(kPulseKinds * kDeltaClasses * kBefore * 2);
      std::uint64_t prev = 0;
      std::size_t cls = 0, cls_before = 0, down = 0;
      for (std::size_t k = 0; k < n; ++k) {
        auto r = static_cast<std::int64_t>(
            static_cast<std::uint64_t>(static_cast<std::int64_t>(las.scan_angle[k]) / u) - prev);
        const std::size_t ctx =
            ((kind[k] * kDeltaClasses + cls) * kBefore + std::min(cls_before, kBefore - 1)) * 2 + down;
        if (!c.sint(models[ctx], r) || !c.ok()) return false;
        prev += static_cast<std::uint64_t>(r);
        const auto q = static_cast<std::int64_t>(prev);
        if (q < INT32_MIN / u || q > INT32_MAX / u) return false;
        las.scan_angle[k] = static_cast<std::int32_t>(q * u);
        if (kind[k] != kPulseSame) {
          cls_before = cls;
          cls = static_cast<std::size_t>(delta_class(r));
          if (r != 0) down = r < 0 ? 1 : 0;
        }
      }
      return true;
    }
    case kLasPointSourceId: return code_point_source(c, las.point_source_id, &kind);
    default: return false;
  }
}

// Copies the vector(s) attribute `bit` is coded from, src's point order[k]
// to dst's point k (number of returns: return numbers too, its context).
void gather_time_ordered(std::uint32_t bit, const LasAttributes& src, LasAttributes& dst,
                         std::span<const std::uint32_t> order) {
  const auto gather = [&](const auto& from, auto& to) {
    to.resize(order.size());
    for (std::size_t k = 0; k < order.size(); ++k) to[k] = from[order[k]];
  };
  switch (bit) {
    case kLasReturnNumber: gather(src.return_number, dst.return_number); break;
    case kLasNumberOfReturns:
      gather(src.number_of_returns, dst.number_of_returns);
      if (!src.return_number.empty()) gather(src.return_number, dst.return_number);
      break;
    case kLasScanFlags: gather(src.scan_flags, dst.scan_flags); break;
    case kLasScanAngle: gather(src.scan_angle, dst.scan_angle); break;
    case kLasUserData: gather(src.user_data, dst.user_data); break;
    case kLasPointSourceId: gather(src.point_source_id, dst.point_source_id); break;
    default: break;
  }
}

// The fewest binary decisions one point of attribute `bit` can take: a
// stream must be long enough for n points before anything is allocated.
std::uint64_t min_decisions_per_point(std::uint32_t bit, std::uint32_t extra_bytes_size, int version) {
  if (bit == kLasGpsTime && version >= 6) return 3;  // a time symbol and a rank or an index
  const std::uint64_t byte = byte_hits(version) ? 1 : 8;  // a hit, or a byte's tree
  switch (bit) {
    case kLasScanAngle:
    case kLasNir: return 1;  // a zero difference
    case kLasGpsTime: return kGpsWindowBits + 1;  // a reference and a zero difference
    case kLasPointSourceId: return kSourceSymbolBits;
    case kLasColorLow: return 3;  // three zero differences
    case kLasExtraBytes: return byte * extra_bytes_size;
    default: return byte;  // one byte
  }
}

// Resizes the vector of attribute `bit` to n points.
void size_attribute(std::uint32_t bit, LasAttributes& las, std::size_t n) {
  if (bit == kLasExtraBytes) {
    las.extra_bytes.assign(n * std::size_t{las.extra_bytes_size}, 0);
    return;
  }
  las.for_each_vector([&](auto& v, std::uint32_t b) {
    if (b == bit) v.assign(n, {});
  });
}

// Calls f(vector) with the vector of attribute `bit` (not extra bytes or
// colour low bytes, which have their own handling below).
template <typename L, typename F>  // L: LasAttributes, const or not
void with_column(std::uint32_t bit, L& las, F&& f) {
  switch (bit) {
    case kLasClassification: f(las.classification); break;
    case kLasClassFlags: f(las.class_flags); break;
    case kLasReturnNumber: f(las.return_number); break;
    case kLasNumberOfReturns: f(las.number_of_returns); break;
    case kLasScanFlags: f(las.scan_flags); break;
    case kLasScanAngle: f(las.scan_angle); break;
    case kLasUserData: f(las.user_data); break;
    case kLasPointSourceId: f(las.point_source_id); break;
    case kLasNir: f(las.nir); break;
    default: break;
  }
}

// True when every point has the same value (GPS times: the same bit pattern).
bool all_equal(std::uint32_t bit, LasAttributes& las) {
  if (bit == kLasGpsTime) {
    const std::vector<double>& v = las.gps_time;
    return std::all_of(v.begin(), v.end(), [&](double t) { return double_bits(t) == double_bits(v.front()); });
  }
  if (bit == kLasExtraBytes) {
    const std::size_t w = las.extra_bytes_size;
    const std::vector<std::uint8_t>& v = las.extra_bytes;
    for (std::size_t at = w; at < v.size(); at += w) {
      if (!std::equal(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(w), v.begin() + static_cast<std::ptrdiff_t>(at))) {
        return false;
      }
    }
    return true;
  }
  bool equal = true;
  with_column(bit, las, [&](const auto& v) {
    equal = std::adjacent_find(v.begin(), v.end(), [](const auto& a, const auto& b) { return !(a == b); }) == v.end();
  });
  return equal;
}

// Resizes attribute `bit` to n points, each a copy of point 0.
void spread_first(std::uint32_t bit, LasAttributes& las, std::size_t n) {
  if (bit == kLasGpsTime) {
    las.gps_time.resize(n, las.gps_time.front());
  } else if (bit == kLasExtraBytes) {
    const std::size_t w = las.extra_bytes_size;
    las.extra_bytes.resize(n * w);
    for (std::size_t i = 1; i < n; ++i) {
      std::copy_n(las.extra_bytes.begin(), w, las.extra_bytes.begin() + static_cast<std::ptrdiff_t>(i * w));
    }
  } else {
    with_column(bit, las, [&](auto& v) { v.resize(n, v.front()); });
  }
}

template <typename T>
int cmp(const T& a, const T& b) {
  return a < b ? -1 : (b < a ? 1 : 0);
}

}  // namespace

const char* las_attribute_name(std::uint32_t bit) {
  static constexpr const char* kNames[kLasAttributeCount] = {
      "classification", "classification flags", "return number", "number of returns",
      "scan flags",     "scan angle",           "user data",     "point source ID",
      "GPS time",       "NIR",                  "colour low byte", "extra bytes"};
  const int b = std::countr_zero(bit);
  return b < kLasAttributeCount ? kNames[b] : "unknown LAS attribute";
}

std::vector<std::uint32_t> las_time_order(const std::vector<double>& gps_time) {
  const std::size_t n = gps_time.size();
  std::vector<KeyedIndex> keyed(n);
  std::uint64_t lowest = ~std::uint64_t{0};
  for (const double t : gps_time) lowest = std::min(lowest, double_bits(t));
  // Keys above the lowest: a chunk's times share their high bytes, whose
  // passes the sort then skips.
  for (std::size_t i = 0; i < n; ++i) keyed[i] = {double_bits(gps_time[i]) - lowest, static_cast<std::uint32_t>(i)};
  radix_sort(keyed, 64);  // stable: equal times stay in index order
  std::vector<std::uint32_t> order(n);
  for (std::size_t k = 0; k < n; ++k) order[k] = keyed[k].index;
  return order;
}

std::vector<std::uint8_t> encode_las_attribute(std::uint32_t bit, const LasAttributes& las, std::size_t n,
                                               int version, std::span<const CellXyz> cells,
                                               std::span<const std::uint32_t> time_order,
                                               std::span<const Rgb8> colors) {
  // The shared routine writes back what it codes (the decoder's side of the
  // interface); the encoder's values come back unchanged, but it needs a
  // mutable copy of the one vector it codes.
  LasAttributes work;
  work.extra_bytes_size = las.extra_bytes_size;
  switch (bit) {
    case kLasClassification: work.classification = las.classification; break;
    case kLasClassFlags: work.class_flags = las.class_flags; break;
    case kLasReturnNumber: work.return_number = las.return_number; break;
    case kLasNumberOfReturns:
      work.number_of_returns = las.number_of_returns;
      work.return_number = las.return_number;
      break;
    case kLasScanFlags: work.scan_flags = las.scan_flags; break;
    case kLasScanAngle: work.scan_angle = las.scan_angle; break;
    case kLasUserData: work.user_data = las.user_data; break;
    case kLasPointSourceId: work.point_source_id = las.point_source_id; break;
    case kLasGpsTime: work.gps_time = las.gps_time; break;
    case kLasNir: work.nir = las.nir; break;
    case kLasExtraBytes: work.extra_bytes = las.extra_bytes; break;
    default: break;
  }
  if (bit == kLasColorLow) {
    // Format 7 first codes one decision, 1 = every low triplet equals the
    // point's decoded colour (8-bit levels, or v * 257: the low bytes carry
    // nothing); else, and before format 7, the triplets follow.
    RangeEncoder enc;
    bool equal = false;
    if (version >= 7 && n > 0) {
      equal = colors.size() == n && las.color_low.size() == n &&
              std::equal(colors.begin(), colors.end(), las.color_low.begin(),
                         [](const Rgb8& a, const Rgb8& b) { return a.r == b.r && a.g == b.g && a.b == b.b; });
      BitModel equal_flag;
      enc.encode(equal_flag, equal ? 1 : 0);
    }
    if (!equal) encode_colors_into(enc, las.color_low, 0);
    return enc.finish();
  }
  // A constant attribute (user data 0, one flight line, no flags) is one
  // value: a flag, then the attribute coded for point 0 alone.
  RangeEncoder enc;
  EncCoder c(enc);
  BitModel constant_flag;
  const bool constant = n > 0 && all_equal(bit, work);
  if (n > 0) c.bit(constant_flag, constant ? 1 : 0);
  if (bit == kLasGpsTime && version >= 6 && n > 0 && !constant) {
    std::vector<std::uint64_t> bits(n);
    for (std::size_t i = 0; i < n; ++i) bits[i] = double_bits(work.gps_time[i]);
    std::vector<std::uint32_t> order = time_order.size() == n ? std::vector<std::uint32_t>(time_order.begin(), time_order.end())
                                                              : las_time_order(work.gps_time);
    // An empty result: the coder refused its input (a broken precondition),
    // which the chunk encoder reports rather than store a cut stream.
    if (!code_gps_time_order(c, bits, order, cells, pick_bucket_shift(cells))) return {};
    return enc.finish();
  }
  if ((bit & kLasTimeOrdered) != 0 && version >= 6 && n > 0 && !constant && time_order.size() == n &&
      las.gps_time.size() == n) {
    LasAttributes ordered;
    gather_time_ordered(bit, las, ordered, time_order);
    std::uint64_t unit = bit == kLasScanAngle ? common_unit(ordered.scan_angle) : 1;
    if (!code_time_ordered(c, bit, ordered, n, unit, las_pulse_kinds(las.gps_time, time_order), byte_hits(version),
                           scan_angle_successors(version))) {
      return {};
    }
    return enc.finish();
  }
  std::size_t coded = n;
  if (constant) {
    coded = 1;
    if (bit == kLasGpsTime) work.gps_time.resize(1);
    if (bit == kLasExtraBytes) work.extra_bytes.resize(work.extra_bytes_size);
    with_column(bit, work, [](auto& v) { v.resize(1); });
  }
  std::uint64_t unit = 1;
  if (bit == kLasScanAngle) unit = common_unit(work.scan_angle);
  if (bit == kLasNir) unit = common_unit(work.nir);
  // Format 15: a NIR section that is not constant codes against the colours.
  const std::span<const Rgb8> green_from =
      bit == kLasNir && nir_by_green(version) && !constant ? colors : std::span<const Rgb8>{};
  if (!code_attribute(c, bit, work, coded, unit, byte_hits(version), green_from)) return {};
  return enc.finish();
}

namespace {

// Colour low bytes (section 20): the triplets as point colours with t = 0;
// in format 7 after one decision, 1 = every triplet is the point's decoded
// colour (`colors`, n of them).
Status decode_color_low(std::span<const std::uint8_t> data, std::size_t n, LasAttributes& las, int version,
                        std::span<const Rgb8> colors) {
  RangeDecoder dec(data);
  if (version >= 7 && n > 0) {
    BitModel equal_flag;
    if (dec.decode(equal_flag) == 1) {
      if (dec.overrun() > 0) return corrupt_data("colour low byte section: truncated stream");
      if (colors.size() != n) return corrupt_data("colour low byte section: equal to colours the blob does not hold");
      las.color_low.assign(colors.begin(), colors.end());
      return Status::ok();
    }
  }
  if (n > max_decisions(data.size()) / min_decisions_per_point(kLasColorLow, 0, version)) {
    return corrupt_data("colour low byte section: " + std::to_string(data.size()) + " bytes cannot hold " +
                        std::to_string(n) + " points");
  }
  if (!decode_colors_from(dec, n, 0, las.color_low) || dec.overrun() > 0) {
    return corrupt_data("colour low byte section: invalid or truncated stream");
  }
  return Status::ok();
}

}  // namespace

Status decode_las_attribute(std::uint32_t bit, std::span<const std::uint8_t> data, std::size_t n, LasAttributes& las,
                            int version, std::span<const CellXyz> cells, std::span<const std::uint32_t> time_order,
                            std::span<const Rgb8> colors) {
  if (bit == kLasColorLow) return decode_color_low(data, n, las, version, colors);
  if (n > 0) {
    RangeDecoder dec(data);
    DecCoder c(dec);
    BitModel constant_flag;
    if (c.bit(constant_flag, 0) == 1) {
      // One value for every point: n is the layer's count, which the
      // geometry section has already been decoded against.
      size_attribute(bit, las, 1);
      if (!code_attribute(c, bit, las, 1, 1, byte_hits(version)) || dec.overrun() > 0) {
        return corrupt_data(std::string(las_attribute_name(bit)) + " section: invalid or truncated stream");
      }
      spread_first(bit, las, n);
      return Status::ok();
    }
  }
  const std::uint64_t need = min_decisions_per_point(bit, las.extra_bytes_size, version);
  if (n > 0 && need > 0 && n > max_decisions(data.size()) / need) {
    return corrupt_data(std::string(las_attribute_name(bit)) + " section: " +
                        std::to_string(data.size()) + " bytes cannot hold " + std::to_string(n) + " points");
  }
  if (bit == kLasGpsTime && version >= 6 && n > 0) {
    RangeDecoder dec(data);
    DecCoder c(dec);
    BitModel constant_flag;
    if (n > 0) c.bit(constant_flag, 0);  // 0: read above
    std::vector<std::uint64_t> bits(n);
    std::vector<std::uint32_t> order(n);
    if (!code_gps_time_order(c, bits, order, cells, 0) || dec.overrun() > 0) {
      return corrupt_data("GPS time section: invalid or truncated stream");
    }
    las.gps_time.resize(n);
    for (std::size_t i = 0; i < n; ++i) las.gps_time[i] = std::bit_cast<double>(bits[i]);
    return Status::ok();
  }
  if ((bit & kLasTimeOrdered) != 0 && version >= 6 && n > 0 && !time_order.empty()) {
    if (time_order.size() != n || las.gps_time.size() != n) {
      return corrupt_data(std::string(las_attribute_name(bit)) + " section: time order does not cover the points");
    }
    LasAttributes ordered;
    if (bit == kLasNumberOfReturns && las.return_number.size() == n) {
      gather_time_ordered(kLasReturnNumber, las, ordered, time_order);
    }
    size_attribute(bit, ordered, n);
    RangeDecoder dec(data);
    DecCoder c(dec);
    BitModel constant_flag;
    c.bit(constant_flag, 0);  // 0: read above
    if (!code_time_ordered(c, bit, ordered, n, 1, las_pulse_kinds(las.gps_time, time_order), byte_hits(version),
                           scan_angle_successors(version)) ||
        dec.overrun() > 0) {
      return corrupt_data(std::string(las_attribute_name(bit)) + " section: invalid or truncated stream");
    }
    size_attribute(bit, las, n);
    const auto scatter = [&](const auto& from, auto& to) {
      for (std::size_t k = 0; k < n; ++k) to[time_order[k]] = from[k];
    };
    with_column(bit, las, [&](auto& to) {
      with_column(bit, ordered, [&](const auto& from) {
        if constexpr (std::is_same_v<std::decay_t<decltype(from)>, std::decay_t<decltype(to)>>) scatter(from, to);
      });
    });
    return Status::ok();
  }
  size_attribute(bit, las, n);
  RangeDecoder dec(data);
  DecCoder c(dec);
  BitModel constant_flag;
  if (n > 0) c.bit(constant_flag, 0);  // 0: read above
  const std::span<const Rgb8> green_from = bit == kLasNir && nir_by_green(version) ? colors : std::span<const Rgb8>{};
  if (!green_from.empty() && green_from.size() != n) {
    return corrupt_data("NIR section: " + std::to_string(green_from.size()) + " colours for " + std::to_string(n) +
                        " points");
  }
  if (!code_attribute(c, bit, las, n, 1, byte_hits(version), green_from) || dec.overrun() > 0) {
    return corrupt_data(std::string(las_attribute_name(bit)) + " section: invalid or truncated stream");
  }
  return Status::ok();
}

std::vector<std::uint8_t> encode_gps_in_order(std::span<const double> times, bool any_order) {
  const std::size_t n = times.size();
  LasAttributes las;
  las.gps_time.assign(times.begin(), times.end());
  // A constant section is the same in every format 6+ blob.
  if (n == 0 || all_equal(kLasGpsTime, las)) return encode_las_attribute(kLasGpsTime, las, n, 8);
  RangeEncoder enc;
  EncCoder c(enc);
  BitModel constant_flag;
  c.bit(constant_flag, 0);
  std::vector<std::uint64_t> bits(n);
  std::vector<std::uint32_t> order(n);
  for (std::size_t k = 0; k < n; ++k) {
    bits[k] = double_bits(times[k]);
    order[k] = static_cast<std::uint32_t>(k);
  }
  if (!code_gps_time_order(c, bits, order, {}, 0, false, any_order)) return {};
  return enc.finish();
}

Status decode_gps_in_order(std::span<const std::uint8_t> data, std::size_t n, LasAttributes& las, bool any_order) {
  if (n == 0) return decode_las_attribute(kLasGpsTime, data, n, las, 8);
  {
    RangeDecoder peek(data);
    BitModel constant_flag;
    if (peek.decode(constant_flag) == 1) return decode_las_attribute(kLasGpsTime, data, n, las, 8);
  }
  if (n > max_decisions(data.size()) / kTimeSymbolBits) {
    return corrupt_data("GPS time section: " + std::to_string(data.size()) + " bytes cannot hold " +
                        std::to_string(n) + " points");
  }
  RangeDecoder dec(data);
  DecCoder c(dec);
  BitModel constant_flag;
  c.bit(constant_flag, 0);  // 0: read above
  std::vector<std::uint64_t> bits(n);
  std::vector<std::uint32_t> order(n);
  if (!code_gps_time_order(c, bits, order, {}, 0, false, any_order) || dec.overrun() > 0) {
    return corrupt_data("GPS time section: invalid or truncated stream");
  }
  las.gps_time.resize(n);
  for (std::size_t k = 0; k < n; ++k) las.gps_time[k] = std::bit_cast<double>(bits[k]);
  return Status::ok();
}

void permute_las_attribute(std::uint32_t bit, const LasAttributes& from, LasAttributes& to,
                           std::span<const std::uint32_t> positions, Permute how) {
  const std::size_t n = positions.size();
  // Point `j` of the permutation: (index in `from`, index in `to`).
  const auto ends = [&](std::size_t j) {
    return how == Permute::kGather ? std::pair<std::size_t, std::size_t>{positions[j], j}
                                   : std::pair<std::size_t, std::size_t>{j, positions[j]};
  };
  if (bit == kLasExtraBytes) {
    const std::size_t w = from.extra_bytes_size;
    to.extra_bytes_size = from.extra_bytes_size;
    to.extra_bytes.assign(n * w, 0);
    for (std::size_t j = 0; j < n; ++j) {
      const auto [src, dst] = ends(j);
      std::copy_n(from.extra_bytes.begin() + static_cast<std::ptrdiff_t>(src * w), w,
                  to.extra_bytes.begin() + static_cast<std::ptrdiff_t>(dst * w));
    }
    return;
  }
  const auto scatter = [&](const auto& src, auto& dst) {
    dst.resize(n);
    for (std::size_t j = 0; j < n; ++j) {
      const auto [s, d] = ends(j);
      dst[d] = src[s];
    }
  };
  if (bit == kLasGpsTime) return scatter(from.gps_time, to.gps_time);
  if (bit == kLasColorLow) return scatter(from.color_low, to.color_low);
  with_column(bit, from, [&](const auto& src) {
    with_column(bit, to, [&](auto& dst) {
      if constexpr (std::is_same_v<std::decay_t<decltype(src)>, std::decay_t<decltype(dst)>>) scatter(src, dst);
    });
  });
}

int compare_las_points(const LasAttributes& las, std::size_t a, std::size_t b) {
  const auto col = [&](const auto& v) { return v.empty() ? 0 : cmp(v[a], v[b]); };
  int r = 0;
  if ((r = col(las.classification)) != 0) return r;
  if ((r = col(las.class_flags)) != 0) return r;
  if ((r = col(las.return_number)) != 0) return r;
  if ((r = col(las.number_of_returns)) != 0) return r;
  if ((r = col(las.scan_flags)) != 0) return r;
  if ((r = col(las.scan_angle)) != 0) return r;
  if ((r = col(las.user_data)) != 0) return r;
  if ((r = col(las.point_source_id)) != 0) return r;
  if (!las.gps_time.empty() && (r = cmp(double_bits(las.gps_time[a]), double_bits(las.gps_time[b]))) != 0) return r;
  if ((r = col(las.nir)) != 0) return r;
  if (!las.color_low.empty()) {
    const Rgb8 x = las.color_low[a], y = las.color_low[b];
    if ((r = cmp(std::array{x.r, x.g, x.b}, std::array{y.r, y.g, y.b})) != 0) return r;
  }
  if (!las.extra_bytes.empty() && las.extra_bytes_size > 0) {
    const std::size_t w = las.extra_bytes_size;
    r = std::memcmp(las.extra_bytes.data() + a * w, las.extra_bytes.data() + b * w, w);
    if (r != 0) return r < 0 ? -1 : 1;
  }
  return 0;
}

}  // namespace relief::codec
