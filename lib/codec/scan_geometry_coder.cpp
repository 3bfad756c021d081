// Mirror pair in one file: the encoder and the decoder run code_scan (a
// template over the bit coder, bit_coders.h). format-spec/chunk.md §11.3.3 is
// the normative description.
//
// An airborne or mobile scanner records pulse after pulse along a scan line:
// in time order consecutive points are a pulse spacing apart in x and y, and
// the step repeats (LAZ predicts it by the median of the last five); a
// pulse's later returns lie below its first; a point's height is close to
// that of the previous point of the same return level. The octree of §11.3
// sees none of this: at the LAS scale it spends most of its decisions on
// single-child levels whose bits look random in cell order.
#include "codec/scan_geometry_coder.h"

#include <algorithm>
#include <array>
#include <bit>
#include <memory>
#include <string>

#include "codec/bit_coders.h"
#include "codec/range_coder.h"

namespace relief::codec {

namespace {

// Return structure: min(number of returns, 3) x 4 + min(return number, 3),
// then x 3 pulse kinds.
constexpr std::size_t kReturnClasses = 16;
constexpr std::size_t kPulseKinds = 3;
constexpr std::size_t kContexts = kReturnClasses * kPulseKinds;
// Magnitude classes of a residual: its bit length, at most 15.
constexpr std::size_t kMagnitudes = 16;
// Levels of the last heights: number of returns - return number, at most 7.
constexpr std::size_t kLevels = 8;
constexpr std::size_t kMedianSpan = 5;

int magnitude(std::int64_t r) {
  const std::uint64_t m = r < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(r) : static_cast<std::uint64_t>(r);
  return std::min(static_cast<int>(std::bit_width(m)), static_cast<int>(kMagnitudes) - 1);
}

// Signed-integer model sets made when first used: a chunk touches few of the
// 1,600 contexts, and each costs 1.6 KB.
using LazySInts = LazyModels<SIntModel>;

// The last kMedianSpan steps of one return class, oldest first; the median
// predicts the next.
struct StepHistory {
  std::array<std::int64_t, kMedianSpan> steps{};
  std::int64_t median() const {
    static_assert(kMedianSpan == 5);
    return median_of_five(steps);
  }
  void push(std::int64_t d) {
    std::copy(steps.begin() + 1, steps.end(), steps.begin());
    steps.back() = d;
  }
};

std::uint8_t at(std::span<const std::uint8_t> v, std::size_t k, std::uint8_t otherwise = 0) {
  return v.empty() ? otherwise : v[k];
}

// floor(a / b) for b > 0.
std::int64_t floor_div(std::int64_t a, std::int64_t b) { return a / b - ((a % b) < 0 ? 1 : 0); }

constexpr std::uint64_t kMaxMultiple = 64;

template <typename C>
bool code_scan(C& c, std::vector<CellXyz>& cells, int depth, const ScanContext& ctx) {
  const std::size_t n = cells.size();
  if (n == 0) return true;
  const std::uint64_t limit = std::uint64_t{1} << depth;
  struct Fixed {
    UIntModel first[3];
    std::array<StepHistory, kReturnClasses> x, y;
    std::array<std::int64_t, kLevels> height{};
  };
  auto f = std::make_unique<Fixed>();
  // The last step between two returns of one pulse with a height change:
  // the beam's direction, along which a pulse's next return lies.
  std::int64_t beam[3] = {0, 0, 1};
  LazySInts rx(kContexts), ry(kContexts * kMagnitudes), rz(kContexts * kMagnitudes);
  for (int a = 0; a < 3; ++a) {
    std::uint64_t v = cells[0][static_cast<std::size_t>(a)];
    if (!c.uint(f->first[a], v) || v >= limit) return false;
    cells[0][static_cast<std::size_t>(a)] = static_cast<std::uint32_t>(v);
  }
  const bool returns = !ctx.return_number.empty() || !ctx.number_of_returns.empty();
  const auto level_of = [&](std::size_t k) -> std::size_t {
    const std::uint8_t rn = at(ctx.return_number, k), nr = at(ctx.number_of_returns, k);
    return returns ? std::min<std::size_t>(nr > rn ? nr - rn : 0, kLevels - 1) : 0;
  };
  f->height[level_of(0)] = cells[0][2];
  for (std::size_t k = 1; k < n; ++k) {
    const std::uint8_t rn = at(ctx.return_number, k), nr = at(ctx.number_of_returns, k);
    const std::size_t level = level_of(k);
    const std::size_t cls = std::size_t{std::min<std::uint8_t>(nr, 3)} * 4 + std::min<std::uint8_t>(rn, 3);
    const std::size_t m = cls * kPulseKinds + std::min<std::uint8_t>(at(ctx.pulse_kind, k), kPulseKinds - 1);
    const CellXyz& prev = cells[k - 1];
    CellXyz& cur = cells[k];
    const bool same_pulse = at(ctx.pulse_kind, k) == 1;
    std::int64_t r[2];
    std::uint64_t v[2], z;
    if (same_pulse) {
      // Another return of the previous point's pulse: its height first,
      // then x and y along the beam from the previous return.
      const std::int64_t base = f->height[level];
      auto rzv = static_cast<std::int64_t>(std::uint64_t{cur[2]} - static_cast<std::uint64_t>(base));
      if (!c.sint(rz[m * kMagnitudes], rzv)) return false;
      z = static_cast<std::uint64_t>(base) + static_cast<std::uint64_t>(rzv);
      if (z >= limit) return false;
      const std::int64_t dz = static_cast<std::int64_t>(z) - static_cast<std::int64_t>(prev[2]);
      for (int a = 0; a < 2; ++a) {
        const auto i = static_cast<std::size_t>(a);
        const std::int64_t predicted = floor_div(dz * beam[a], beam[2]);
        r[a] = static_cast<std::int64_t>(std::uint64_t{cur[i]} - prev[i] - static_cast<std::uint64_t>(predicted));
        SIntModel& model = a == 0 ? rx[m] : ry[m * kMagnitudes + static_cast<std::size_t>(magnitude(r[0]))];
        if (!c.sint(model, r[a])) return false;
        v[a] = std::uint64_t{prev[i]} + static_cast<std::uint64_t>(predicted) + static_cast<std::uint64_t>(r[a]);
        if (v[a] >= limit) return false;
      }
      if (dz != 0) {
        beam[0] = static_cast<std::int64_t>(v[0]) - static_cast<std::int64_t>(prev[0]);
        beam[1] = static_cast<std::int64_t>(v[1]) - static_cast<std::int64_t>(prev[1]);
        beam[2] = dz < 0 ? -dz : dz;
        if (dz < 0) {
          beam[0] = -beam[0];
          beam[1] = -beam[1];
        }
      }
    } else {
      // A new pulse: the step from the previous point is the median of the
      // class's last steps per pulse spacing, times the spacings elapsed.
      const auto mult = static_cast<std::int64_t>(std::clamp<std::uint64_t>(at(ctx.pulse_multiple, k, 1), 1, kMaxMultiple));
      for (int a = 0; a < 2; ++a) {
        const auto i = static_cast<std::size_t>(a);
        StepHistory& hist = a == 0 ? f->x[cls] : f->y[cls];
        const std::int64_t predicted = hist.median() * mult;
        r[a] = static_cast<std::int64_t>(std::uint64_t{cur[i]} - prev[i] - static_cast<std::uint64_t>(predicted));
        SIntModel& model = a == 0 ? rx[m] : ry[m * kMagnitudes + static_cast<std::size_t>(magnitude(r[0]))];
        if (!c.sint(model, r[a])) return false;
        v[a] = std::uint64_t{prev[i]} + static_cast<std::uint64_t>(predicted) + static_cast<std::uint64_t>(r[a]);
        if (v[a] >= limit) return false;
        hist.push(floor_div(static_cast<std::int64_t>(v[a]) - static_cast<std::int64_t>(prev[i]), mult));
      }
      // z: from the last height of the point's return level.
      const std::int64_t base = f->height[level];
      auto rzv = static_cast<std::int64_t>(std::uint64_t{cur[2]} - static_cast<std::uint64_t>(base));
      const std::size_t mz = static_cast<std::size_t>((magnitude(r[0]) + magnitude(r[1]) + 1) / 2);
      if (!c.sint(rz[m * kMagnitudes + mz], rzv)) return false;
      z = static_cast<std::uint64_t>(base) + static_cast<std::uint64_t>(rzv);
      if (z >= limit) return false;
    }
    if (!c.ok()) return false;
    cur = {static_cast<std::uint32_t>(v[0]), static_cast<std::uint32_t>(v[1]), static_cast<std::uint32_t>(z)};
    f->height[level] = static_cast<std::int64_t>(z);
  }
  return c.ok();
}

bool context_fits(const ScanContext& ctx, std::size_t n) {
  const auto fits = [&](std::span<const std::uint8_t> v) { return v.empty() || v.size() == n; };
  return fits(ctx.pulse_kind) && fits(ctx.pulse_multiple) && fits(ctx.return_number) && fits(ctx.number_of_returns);
}

}  // namespace

int order_slot(std::uint32_t bit) {
  switch (bit) {
    case kLasClassification: return 2;
    case kLasClassFlags: return 3;
    case kLasNir: return 4;
    case kLasColorLow: return 5;
    case kLasExtraBytes: return 6;
    default: return -1;
  }
}

std::vector<std::uint8_t> scan_pulse_multiples(std::span<const double> times) {
  std::vector<std::uint8_t> out(times.size(), 1);
  std::uint64_t last_step = 0;
  for (std::size_t k = 1; k < times.size(); ++k) {
    const std::uint64_t d = std::bit_cast<std::uint64_t>(times[k]) - std::bit_cast<std::uint64_t>(times[k - 1]);
    if (d == 0) continue;
    if (last_step != 0 && d / kMaxMultiple <= last_step) {
      const std::uint64_t rounded = d / last_step + ((d % last_step) >= last_step - last_step / 2 ? 1 : 0);
      out[k] = static_cast<std::uint8_t>(std::clamp<std::uint64_t>(rounded, 1, kMaxMultiple));
    }
    last_step = d;
  }
  return out;
}

std::vector<std::uint8_t> encode_scan_geometry(std::span<const CellXyz> cells, int depth, const ScanContext& context) {
  RangeEncoder enc;
  EncCoder c(enc);
  std::vector<CellXyz> work(cells.begin(), cells.end());
  // Empty: the input broke a precondition (a cell of 2^depth or more, a
  // context of another size), which the chunk encoder reports.
  if (!context_fits(context, work.size()) || !code_scan(c, work, depth, context)) return {};
  return enc.finish();
}

Result<std::vector<CellXyz>> decode_scan_geometry(std::span<const std::uint8_t> data, int depth, std::size_t n,
                                                  const ScanContext& context) {
  if (depth < 0 || depth > 21) return corrupt_data("scan-order geometry: depth " + std::to_string(depth) + " > 21");
  if (!context_fits(context, n)) return corrupt_data("scan-order geometry: context does not cover the points");
  // Every point after the first takes at least three decisions (three zero
  // flags), the first at least three prefix decisions.
  if (n > max_decisions(data.size()) / 3) {
    return corrupt_data("scan-order geometry: " + std::to_string(data.size()) + " bytes cannot hold " +
                        std::to_string(n) + " points");
  }
  std::vector<CellXyz> cells(n);
  RangeDecoder dec(data);
  DecCoder c(dec);
  if (!code_scan(c, cells, depth, context) || dec.overrun() > 0) {
    return corrupt_data("scan-order geometry: invalid or truncated stream");
  }
  return cells;
}

}  // namespace relief::codec
