// The error-bounded grid's one formula, shared by the ingest (which snaps
// points before they are bucketed) and the codec (which codes the indices):
// index k on an axis decodes to origin + k * step, computed in double.
// Internal to Relief.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>

namespace relief::core {

// The coordinate of grid index k (format-spec/chunk.md: origin + k x step).
inline double grid_value(double origin, std::int64_t k, double step) {
  return origin + static_cast<double>(k) * step;
}

// Indices beyond this are refused: a double then no longer tells them apart,
// and base + local in a blob's header could overflow.
inline constexpr double kMaxGridIndex = 4.0e18;

// Whether v lies within kMaxGridIndex steps of the origin: asked only when
// grid_index_within found no index, to tell that case from a step too fine.
inline bool grid_index_in_range(double v, double origin, double step) {
  return std::fabs((v - origin) / step) < kMaxGridIndex;
}

// The spacing of doubles at |v| (one unit in the last place).
inline double double_spacing(double v) { return std::nextafter(std::fabs(v), HUGE_VAL) - std::fabs(v); }

// Doubles must resolve the grid: at least kMinStepsPerSpacing of their
// spacing to a step, else several indices decode to one value and a
// decoded value may miss the tolerance by many times it (a 1e-5 tolerance
// around 1e12, where doubles are 1.2e-4 apart, gave errors of 1.2e-4).
inline constexpr double kMinStepsPerSpacing = 64;

// The index whose decoded coordinate lies within step / 2 of v: the nearest
// index (halves away from zero), or its neighbour when the nearest's decoded
// value, rounded to a double, lands beyond step / 2 (at a tie such as 1.2345
// on a 0.001 step). At a tie both decoded values may round beyond step / 2
// by a unit in the last place or two (-0.4375: -0.438 and -0.437 both lie
// 4e-19 beyond 0.0005); the nearer is taken, within step / 2 plus a few units
// in the last place, where doubles near v resolve the step
// (kMinStepsPerSpacing). Empty when |v - origin| is beyond kMaxGridIndex
// steps or no index qualifies. (A point already on the grid, such as a LAS
// file's at its own scale and offset, decodes to itself and always does.)
inline std::optional<std::int64_t> grid_index_within(double v, double origin, double step) {
  const double t = (v - origin) / step;
  if (!(std::fabs(t) < kMaxGridIndex)) return std::nullopt;  // grid_index_in_range's test
  const auto i = static_cast<std::int64_t>(t);
  const double frac = t - static_cast<double>(i);  // exact
  const std::int64_t k = i + (frac >= 0.5 ? 1 : 0) - (frac <= -0.5 ? 1 : 0);
  const double half = step / 2;
  const double d = grid_value(origin, k, step);
  const double e = std::fabs(d - v);
  if (e <= half) return k;
  const std::int64_t other = d > v ? k - 1 : k + 1;
  const double f = std::fabs(grid_value(origin, other, step) - v);
  if (f <= half) return other;
  if (double_spacing(v) * kMinStepsPerSpacing > step) return std::nullopt;
  const double slack = 2 * double_spacing(std::max(std::fabs(v), std::fabs(d)) * 2);
  if (std::min(e, f) <= half + slack) return e <= f ? k : other;
  return std::nullopt;
}

// Why grid_index_within found no index for v: the step is finer than doubles
// near v resolve (a tolerance of 1e-5 around 1e12, where they are 1.2e-4
// apart). "coordinate V cannot come back within the tolerance T: ...".
inline std::string grid_too_fine_text(double v, double step) {
  const double spacing = double_spacing(v);
  char text[360];
  std::snprintf(
      text, sizeof text,
      "coordinate %.17g cannot come back within the tolerance %.9g: doubles near it are %.9g apart, "
      "and a tolerance of %.0f times that (%.9g) or more is always kept there",
      v, step / 2, spacing, kMinStepsPerSpacing / 2, spacing * kMinStepsPerSpacing / 2);
  return text;
}

}  // namespace relief::core
