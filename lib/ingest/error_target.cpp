// --error-target: pick the cell size for a wanted RMSE_SNN by trial encodes.
#include <cmath>
#include <limits>

#include "relief/ingest.h"
#include "relief/metrics.h"

namespace relief {

namespace {

// The sample is the first points of the input (storage order is usually scan
// order, so they form a spatially coherent piece at the input's density).
constexpr std::size_t kSamplePoints = 200000;
constexpr int kBisections = 7;

Result<double> sample_rmse(const PointCloud& sample, EncodeParams p, double cell) {
  p.cell_size = cell;
  p.grid_origin.reset();
  RELIEF_ASSIGN_OR_RETURN(std::vector<std::uint8_t> blob, encode_chunk(sample, p));
  RELIEF_ASSIGN_OR_RETURN(PointCloud back, decode_chunk(blob));
  if (back.empty()) return std::numeric_limits<double>::infinity();
  RELIEF_ASSIGN_OR_RETURN(ErrorMetrics m, compare_clouds(sample, back));
  return m.rmse_snn;
}

}  // namespace

Result<double> choose_cell_for_error(const PointCloud& full_sample, const EncodeParams& base, double target,
                                     double* achieved) {
  if (!(target > 0) || !std::isfinite(target)) return invalid_argument("error target must be a positive number");
  if (full_sample.size() < 3) return invalid_argument("too few points to calibrate an error target");
  PointCloud sample;
  const std::size_t n = std::min(full_sample.size(), kSamplePoints);
  sample.positions.assign(full_sample.positions.begin(), full_sample.positions.begin() + static_cast<std::ptrdiff_t>(n));
  if (full_sample.has_colors()) {
    sample.colors.assign(full_sample.colors.begin(), full_sample.colors.begin() + static_cast<std::ptrdiff_t>(n));
  }
  // Intensity does not affect geometry error; leave it out for speed.
  // Bracket: rmse(lo) <= target < rmse(hi), starting from the density cell.
  double lo = suggest_cell_size(sample, base.map_resolution);
  double hi = lo;
  RELIEF_ASSIGN_OR_RETURN(double e, sample_rmse(sample, base, lo));
  double e_lo = e;
  if (e <= target) {
    for (int i = 0; i < 12; ++i) {
      hi = lo * 2;
      RELIEF_ASSIGN_OR_RETURN(double eh, sample_rmse(sample, base, hi));
      if (eh > target) break;
      lo = hi;
      e_lo = eh;
    }
  } else {
    for (int i = 0; i < 12 && e > target; ++i) {
      hi = lo;
      lo /= 2;
      RELIEF_ASSIGN_OR_RETURN(e, sample_rmse(sample, base, lo));
    }
    if (e > target) {
      return invalid_argument("error target " + std::to_string(target) +
                              " is below what the method reaches on this data (" + std::to_string(e) +
                              " at the finest tried cell)");
    }
    e_lo = e;
  }
  for (int i = 0; i < kBisections && hi > lo; ++i) {
    const double mid = std::sqrt(lo * hi);
    RELIEF_ASSIGN_OR_RETURN(double em, sample_rmse(sample, base, mid));
    if (em <= target) {
      lo = mid;
      e_lo = em;
    } else {
      hi = mid;
    }
  }
  if (achieved) *achieved = e_lo;
  return lo;
}

}  // namespace relief
