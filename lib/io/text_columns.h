// The columns of XYZ/CSV text and the properties of PLY: what a name means
// when read, the names the writers give the LAS dimensions (which the readers
// map back), and the checks and stores of LAS dimension values. Shared by the
// text and PLY readers and writers. Internal to lib/io.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "relief/status.h"
#include "relief/types.h"

namespace relief {

enum class TextColumn : std::uint8_t {
  kSkip,
  kX,
  kY,
  kZ,
  kRed,
  kGreen,
  kBlue,
  kIntensity,
  // The LAS dimensions (las_text_columns()).
  kClass,
  kGpsTime,
  kReturnNumber,
  kNumberOfReturns,
  kScanDirection,
  kEdgeOfFlightLine,
  kScannerChannel,
  kSynthetic,
  kKeyPoint,
  kWithheld,
  kOverlap,
  kScanAngle,
  kUserData,
  kPointSourceId,
  kNir,
  // A column kept as a float64 field of extra bytes; any number of them.
  kExtra,
};
// Columns held by at most one column each (every one before kExtra).
inline constexpr std::size_t kTextColumnKinds = static_cast<std::size_t>(TextColumn::kExtra);

// A LAS dimension's column: the LasAttributeBits it fills; the largest whole
// number it takes (0: not a whole number: GPS time is any finite value, the
// scan angle degrees within +-kMaxTextScanAngle); its name in messages; the
// header name the text writer gives it (PDAL's); the PLY writer's name (LAS's).
struct LasTextColumn {
  TextColumn column;
  std::uint32_t bit;
  double max;
  const char* what;
  const char* header;
  const char* snake;
};
// Every LAS dimension, in the order the writer puts them.
std::span<const LasTextColumn> las_text_columns();
// LAS 1.4 scan angles run from -180 to 180 degrees.
inline constexpr double kMaxTextScanAngle = 180;

// A header name without quotes and a leading '#' or "//".
std::string text_display_name(std::string_view name);
// The column a header name means, if any: names match in any case, without
// quotes, a leading '#' or "//", a "scalar_" prefix (CloudCompare's scalar
// fields), '_' or '-': x y z; red green blue (r g b, diffuse_red ...);
// intensity (i, reflectance); the LAS dimensions by their LAS and PDAL names
// (classification or class, gps_time, return_number, number_of_returns,
// scan_direction_flag, edge_of_flight_line, scanner_channel, synthetic,
// key_point, withheld, overlap, scan_angle_rank or scan_angle, user_data,
// point_source_id, infrared or nir).
std::optional<TextColumn> text_column_of_name(std::string_view name);

// A name for a column or property of extra bytes that the readers keep under
// that name: `base` with blanks, non-ASCII characters and those in
// `replace` made '_', `empty` when it is empty, "_extra" added when the
// readers would take it for a coordinate, colour, intensity or LAS
// dimension, and "_2", "_3" ... when `taken` has it; then added to `taken`.
std::string unique_field_name(std::string base, std::string_view replace, const char* empty,
                              std::vector<std::string>& taken);

// Empty when `value` is one the LAS dimension `c` can hold, else a message
// such as "return number 16 is not a whole number from 0 to 15".
std::string las_column_error(const LasTextColumn& c, double value);
// Appends one point's LAS dimensions to `las`: v[k] is the value of
// TextColumn k (0 for columns absent), checked by las_column_error; `bits`
// the LasAttributeBits carried (class and scan flags assembled from their
// columns, the scan angle from degrees to thousandths).
void push_las_columns(const double* v, std::uint32_t bits, LasAttributes& las);
// The inverse of push_las_columns for one column: point i's value (the scan
// angle in degrees; a whole number for the others but GPS time). `las` must
// carry the column's vector.
double las_column_value(const LasAttributes& las, TextColumn column, std::size_t i);
// Values `las` holds of the LAS dimension whose LasAttributeBits is `bit`
// (one of those push_las_columns fills).
std::size_t las_column_count(const LasAttributes& las, std::uint32_t bit);
// Whether a writer's batch of n points carries what it was opened with: one
// value per point of each LAS dimension whose LasAttributeBits `bits` has,
// and `extra_size` extra bytes per point (0: none asked). An error naming
// `path` when not (a caller's bug, which would otherwise read past the
// vectors); every batch of 0 points passes.
Status check_batch_columns(const LasAttributes& las, std::uint32_t bits, std::size_t extra_size, std::size_t n,
                           const std::string& path);
// Sizes the vectors push_las_columns fills for `bits` to n points and clears
// the others of them (colour low bytes and extra bytes are left alone).
void size_las_columns(LasAttributes& las, std::uint32_t bits, std::size_t n);

}  // namespace relief
