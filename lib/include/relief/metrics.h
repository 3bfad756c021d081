// Error measures of Golla & Klein 2015, section IV-A.
#pragma once

#include <cstddef>

#include "relief/status.h"
#include "relief/types.h"

namespace relief {

struct ErrorMetrics {
  std::size_t points_original = 0;       // |P|
  std::size_t points_reconstructed = 0;  // |Q|
  double rmse_nn_pq = 0;    // RMSE_NN(P, Q): original -> nearest reconstructed
  double rmse_nn_qp = 0;    // RMSE_NN(Q, P): reconstructed -> nearest original
  double rmse_snn = 0;      // sqrt(0.5 MSE_NN(P,Q) + 0.5 MSE_NN(Q,P))
  double hausdorff = 0;     // max over both directions of the nearest-neighbour distance
  double peak = 0;          // bounding-box diagonal of the original
  double psnr = 0;          // 20 log10(peak / max(RMSE_NN(P,Q), RMSE_NN(Q,P))); +inf if exact
  bool has_rgb = false;     // both clouds carry colour
  double rmse_rgb_nn_pq = 0;  // colour RMSE over R,G,B (0..255) using spatial nearest neighbours
  double rmse_rgb_nn_qp = 0;
  double rmse_rgb_snn = 0;
  double psnr_rgb = 0;      // 20 log10(255 / rmse_rgb_snn); +inf if exact
};

struct MetricsOptions {
  unsigned threads = 0;  // 0 = all cores
};

// Compares an original cloud P with its reconstruction Q using kd-trees.
// Both must be non-empty and finite.
Result<ErrorMetrics> compare_clouds(const PointCloud& original, const PointCloud& reconstructed,
                                    const MetricsOptions& options = {});

}  // namespace relief
