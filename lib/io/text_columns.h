// The columns of XYZ/CSV text: what a header name means when read, and the
// names the text writer gives the LAS dimensions (PDAL's, which the reader
// maps back). Shared by xyz_reader.cpp and xyz_writer.cpp. Internal to lib/io.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>

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
// header name the writer gives it (PDAL's).
struct LasTextColumn {
  TextColumn column;
  std::uint32_t bit;
  double max;
  const char* what;
  const char* header;
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

}  // namespace relief
