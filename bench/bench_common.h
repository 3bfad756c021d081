// Shared pieces of bench/codec: one result row, the CSV format, the output
// sink (stdout plus an optional copy in a file) and timing helpers.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

// One configuration measured on one file: one CSV row. Fields that do not
// apply hold NaN (numbers) or "" (text) and are printed as empty fields.
struct BenchRow {
  std::string file;           // file stem, e.g. "stanford_bunny"
  std::string codec;          // "relief" or "draco"
  std::string decomposition;  // relief: "voxel" | "octree"
  std::string image;          // relief: "jpeg" | "jpeg2000"
  std::string fill;           // relief: "pushpull" | "box" (empty-pixel fill)
  double cell = std::numeric_limits<double>::quiet_NaN();  // relief: cell / smallest leaf edge
  int quality = -1;           // relief: height quality; draco: qp
  int height_bits = 0;        // relief: 8 | 16; 0 = not applicable
  std::size_t points_in = 0;
  std::size_t points_out = 0;
  std::size_t bytes = 0;
  double bpp = 0;
  double rmse_snn = 0;
  double psnr = 0;
  double rmse_rgb_snn = std::numeric_limits<double>::quiet_NaN();  // NaN: no colour
  double hausdorff = 0;
  double enc_mpts_s = 0;
  double dec_mpts_s = 0;      // decoded (output) points / decode seconds
  double dec_in_mpts_s = std::numeric_limits<double>::quiet_NaN();  // input points / decode seconds (the anchors' convention)
  double dec_lod4_mpts_s = std::numeric_limits<double>::quiet_NaN();
  std::string section_bytes;

  // Not printed in the CSV; used for labels in the summary and progress notes.
  double cell_multiplier = std::numeric_limits<double>::quiet_NaN();
  int color_quality = -1;
  double lod4_seconds = std::numeric_limits<double>::quiet_NaN();
  double dec_seconds = 0;
};

const char* csv_header();
std::string csv_line(const BenchRow& row);
// A short human label: "voxel/jpeg 0.7xc0 q75" or "draco qp=11".
std::string row_label(const BenchRow& row);

// "%.6g", "inf"/"-inf", or "" for NaN: the CSV's empty field.
std::string format_number(double v);

// Writes every line to stdout and, when open, to a copy file; flushes after
// each line so a long run shows progress and a killed run keeps its rows.
class Output {
 public:
  Output() = default;
  ~Output();
  Output(const Output&) = delete;
  Output& operator=(const Output&) = delete;

  // Opens the copy file; returns false (errno-style message in `error`) on failure.
  bool open_copy(const std::string& path, std::string& error);
  void line(const std::string& text);
  // printf-style convenience for summary lines.
  void linef(const char* format, ...) __attribute__((format(printf, 2, 3)));

 private:
  std::FILE* copy_ = nullptr;
};

// Progress and errors: stderr, so the CSV on stdout stays clean.
void note(const char* format, ...) __attribute__((format(printf, 1, 2)));

using BenchClock = std::chrono::steady_clock;
inline double seconds_between(BenchClock::time_point a, BenchClock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// Median of a non-empty sample (mean of the two middle values for even sizes).
double median(std::vector<double> values);

// Millions of points per second; NaN when the time is not positive.
double mpts_per_s(std::size_t points, double seconds);
