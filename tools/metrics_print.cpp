#include "metrics_print.h"

#include <cmath>
#include <cstdio>

namespace relief::cli {

namespace {

// JSON has no infinity: an exact reconstruction prints null.
void json_number(const char* key, double v, bool last = false) {
  if (std::isfinite(v)) {
    std::printf("  \"%s\": %.10g%s\n", key, v, last ? "" : ",");
  } else {
    std::printf("  \"%s\": null%s\n", key, last ? "" : ",");
  }
}

}  // namespace

void print_metrics(const ErrorMetrics& m, bool json) {
  if (json) {
    std::printf("{\n  \"points_original\": %zu,\n  \"points_reconstructed\": %zu,\n", m.points_original,
                m.points_reconstructed);
    json_number("rmse_nn_original_to_reconstructed", m.rmse_nn_pq);
    json_number("rmse_nn_reconstructed_to_original", m.rmse_nn_qp);
    json_number("rmse_snn", m.rmse_snn);
    json_number("hausdorff", m.hausdorff);
    json_number("peak", m.peak);
    if (m.has_rgb) {
      json_number("rmse_rgb_nn_original_to_reconstructed", m.rmse_rgb_nn_pq);
      json_number("rmse_rgb_nn_reconstructed_to_original", m.rmse_rgb_nn_qp);
      json_number("rmse_rgb_snn", m.rmse_rgb_snn);
      json_number("psnr_rgb", m.psnr_rgb);
    }
    json_number("psnr", m.psnr, true);
    std::printf("}\n");
    return;
  }
  std::printf("points in (original)        %zu\n", m.points_original);
  std::printf("points out (reconstructed)  %zu\n", m.points_reconstructed);
  std::printf("RMSE_NN(P,Q)                %.6g\n", m.rmse_nn_pq);
  std::printf("RMSE_NN(Q,P)                %.6g\n", m.rmse_nn_qp);
  std::printf("RMSE_SNN                    %.6g\n", m.rmse_snn);
  std::printf("Hausdorff                   %.6g\n", m.hausdorff);
  std::printf("PSNR (peak %.6g)            %.3f dB\n", m.peak, m.psnr);
  if (m.has_rgb) {
    std::printf("RMSE_RGB_NN(P,Q)            %.4f\n", m.rmse_rgb_nn_pq);
    std::printf("RMSE_RGB_NN(Q,P)            %.4f\n", m.rmse_rgb_nn_qp);
    std::printf("RMSE_RGB_SNN                %.4f\n", m.rmse_rgb_snn);
    std::printf("PSNR_RGB                    %.3f dB\n", m.psnr_rgb);
  }
}

}  // namespace relief::cli
