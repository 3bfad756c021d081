// The summary printed after the CSV: Relief's rate-distortion Pareto front per
// file and, for each of its points, the bits per point Draco and G-PCC need
// for the same RMSE_SNN (log-log interpolation on their measured rows).
#pragma once

#include <cstddef>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "bench_common.h"
#include "relief/status.h"

// One rate-distortion point of some codec.
struct CurvePoint {
  double bpp = 0;
  double rmse = 0;
  std::size_t points_out = 0;
  double rmse_rgb = std::numeric_limits<double>::quiet_NaN();
  int color_tolerance = 0;  // Relief's rows only
  std::string label;
};

// The points no other point beats on both bpp and rmse, by increasing bpp
// (so rmse strictly decreasing). Points with a non-finite or negative value
// are dropped; ties keep the first.
std::vector<CurvePoint> pareto_front(std::vector<CurvePoint> points);

// The bpp a codec whose Pareto front is `front` needs for `rmse`, by linear
// interpolation of log(bpp) over log(rmse) between the two front points that
// bracket it. nullopt when `rmse` lies outside the front's measured range (no
// extrapolation) or the front has no usable points.
std::optional<double> bpp_at_rmse(const std::vector<CurvePoint>& front, double rmse);

// Rows of `codec` (e.g. "tmc13") from an anchors results CSV; the header names
// the columns, so their order does not matter. Setting goes into the label.
relief::Result<std::vector<CurvePoint>> read_anchor_curve(const std::string& csv_path, const std::string& codec);

// Splits one CSV line; understands double-quoted fields with "" escapes.
std::vector<std::string> split_csv_line(const std::string& line);

struct FileSummaryInput {
  std::string stem;
  std::size_t points = 0;
  bool has_colour = false;
  std::vector<BenchRow> rows;  // every row of this file, Relief and Draco
  bool draco_measured = false; // false: compare with the anchors' Draco rows instead
  std::string anchors_dir;     // "" = no anchors
};

// Prints the `#` summary block of one file.
void print_file_summary(Output& out, const FileSummaryInput& in);
