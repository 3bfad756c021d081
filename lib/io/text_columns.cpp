#include "io/text_columns.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>

#include "io/text_scan.h"

namespace relief {

namespace {

constexpr LasTextColumn kLasColumns[] = {
    {TextColumn::kClass, kLasClassification, 255, "classification", "Classification", "classification"},
    {TextColumn::kSynthetic, kLasClassFlags, 1, "synthetic flag", "Synthetic", "synthetic"},
    {TextColumn::kKeyPoint, kLasClassFlags, 1, "key-point flag", "KeyPoint", "key_point"},
    {TextColumn::kWithheld, kLasClassFlags, 1, "withheld flag", "Withheld", "withheld"},
    {TextColumn::kOverlap, kLasClassFlags, 1, "overlap flag", "Overlap", "overlap"},
    {TextColumn::kReturnNumber, kLasReturnNumber, 15, "return number", "ReturnNumber", "return_number"},
    {TextColumn::kNumberOfReturns, kLasNumberOfReturns, 15, "number of returns", "NumberOfReturns",
     "number_of_returns"},
    {TextColumn::kScanDirection, kLasScanFlags, 1, "scan direction flag", "ScanDirectionFlag", "scan_direction_flag"},
    {TextColumn::kEdgeOfFlightLine, kLasScanFlags, 1, "edge of flight line flag", "EdgeOfFlightLine",
     "edge_of_flight_line"},
    {TextColumn::kScannerChannel, kLasScanFlags, 3, "scanner channel", "ScannerChannel", "scanner_channel"},
    {TextColumn::kScanAngle, kLasScanAngle, 0, "scan angle", "ScanAngleRank", "scan_angle"},
    {TextColumn::kUserData, kLasUserData, 255, "user data", "UserData", "user_data"},
    {TextColumn::kPointSourceId, kLasPointSourceId, 65535, "point source ID", "PointSourceId", "point_source_id"},
    {TextColumn::kGpsTime, kLasGpsTime, 0, "GPS time", "GpsTime", "gps_time"},
    {TextColumn::kNir, kLasNir, 65535, "NIR", "Infrared", "nir"},
};

struct ColumnName {
  std::string_view name;
  TextColumn column;
};
// Names after normalise().
constexpr ColumnName kColumnNames[] = {
    {"x", TextColumn::kX},
    {"y", TextColumn::kY},
    {"z", TextColumn::kZ},
    {"red", TextColumn::kRed},
    {"r", TextColumn::kRed},
    {"diffusered", TextColumn::kRed},
    {"green", TextColumn::kGreen},
    {"g", TextColumn::kGreen},
    {"diffusegreen", TextColumn::kGreen},
    {"blue", TextColumn::kBlue},
    {"b", TextColumn::kBlue},
    {"diffuseblue", TextColumn::kBlue},
    {"intensity", TextColumn::kIntensity},
    {"i", TextColumn::kIntensity},
    {"reflectance", TextColumn::kIntensity},
    {"classification", TextColumn::kClass},
    {"class", TextColumn::kClass},
    {"gpstime", TextColumn::kGpsTime},
    {"returnnumber", TextColumn::kReturnNumber},
    {"numberofreturns", TextColumn::kNumberOfReturns},
    {"scandirectionflag", TextColumn::kScanDirection},
    {"scandirection", TextColumn::kScanDirection},
    {"edgeofflightline", TextColumn::kEdgeOfFlightLine},
    {"scannerchannel", TextColumn::kScannerChannel},
    {"synthetic", TextColumn::kSynthetic},
    {"keypoint", TextColumn::kKeyPoint},
    {"withheld", TextColumn::kWithheld},
    {"overlap", TextColumn::kOverlap},
    {"scananglerank", TextColumn::kScanAngle},
    {"scanangle", TextColumn::kScanAngle},
    {"userdata", TextColumn::kUserData},
    {"pointsourceid", TextColumn::kPointSourceId},
    {"infrared", TextColumn::kNir},
    {"nir", TextColumn::kNir},
};

std::string normalise(std::string_view name) {
  std::string n = text_display_name(name);
  for (char& c : n) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (n.starts_with("scalar_")) n.erase(0, 7);
  std::erase_if(n, [](char c) { return c == '_' || c == '-'; });
  return n;
}

}  // namespace

std::span<const LasTextColumn> las_text_columns() { return kLasColumns; }

std::string text_display_name(std::string_view name) {
  std::string n;
  for (const char c : name) {
    if (c != '"' && c != '\'') n.push_back(c);
  }
  while (n.starts_with('#') || n.starts_with("//")) n.erase(0, n.starts_with('#') ? 1 : 2);
  return n;
}

std::optional<TextColumn> text_column_of_name(std::string_view name) {
  const std::string n = normalise(name);
  for (const ColumnName& c : kColumnNames) {
    if (c.name == n) return c.column;
  }
  return std::nullopt;
}

std::string unique_field_name(std::string base, std::string_view replace, const char* empty,
                              std::vector<std::string>& taken) {
  for (char& c : base) {
    if (c <= ' ' || c > '~' || replace.find(c) != std::string_view::npos) c = '_';
  }
  if (base.empty()) base = empty;
  if (text_column_of_name(base)) base += "_extra";
  std::string name = base;
  for (int k = 2; std::find(taken.begin(), taken.end(), name) != taken.end(); ++k) {
    name = base + "_" + std::to_string(k);
  }
  taken.push_back(name);
  return name;
}

std::string las_column_error(const LasTextColumn& c, double value) {
  if (c.column == TextColumn::kGpsTime) {
    return std::isfinite(value) ? std::string() : "GPS time " + format_double(value) + " is not finite";
  }
  if (c.column == TextColumn::kScanAngle) {
    return std::abs(value) <= kMaxTextScanAngle
               ? std::string()
               : "scan angle " + format_double(value) + " is not from -180 to 180 degrees";
  }
  if (value >= 0 && value <= c.max && value == std::floor(value)) return {};
  return std::string(c.what) + " " + format_double(value) + " is not a whole number from 0 to " + format_double(c.max);
}

void push_las_columns(const double* v, std::uint32_t bits, LasAttributes& las) {
  const auto u8 = [v](TextColumn c) { return static_cast<std::uint8_t>(v[static_cast<std::size_t>(c)]); };
  const auto at = [v](TextColumn c) { return v[static_cast<std::size_t>(c)]; };
  if ((bits & kLasClassification) != 0) las.classification.push_back(u8(TextColumn::kClass));
  if ((bits & kLasClassFlags) != 0) {
    las.class_flags.push_back(static_cast<std::uint8_t>(u8(TextColumn::kSynthetic) | u8(TextColumn::kKeyPoint) << 1 |
                                                        u8(TextColumn::kWithheld) << 2 | u8(TextColumn::kOverlap) << 3));
  }
  if ((bits & kLasReturnNumber) != 0) las.return_number.push_back(u8(TextColumn::kReturnNumber));
  if ((bits & kLasNumberOfReturns) != 0) las.number_of_returns.push_back(u8(TextColumn::kNumberOfReturns));
  if ((bits & kLasScanFlags) != 0) {
    las.scan_flags.push_back(static_cast<std::uint8_t>(u8(TextColumn::kScanDirection) |
                                                       u8(TextColumn::kEdgeOfFlightLine) << 1 |
                                                       u8(TextColumn::kScannerChannel) << 2));
  }
  // LasAttributes keeps thousandths of a degree.
  if ((bits & kLasScanAngle) != 0) {
    las.scan_angle.push_back(static_cast<std::int32_t>(std::lround(at(TextColumn::kScanAngle) * 1000)));
  }
  if ((bits & kLasUserData) != 0) las.user_data.push_back(u8(TextColumn::kUserData));
  if ((bits & kLasPointSourceId) != 0) {
    las.point_source_id.push_back(static_cast<std::uint16_t>(at(TextColumn::kPointSourceId)));
  }
  if ((bits & kLasGpsTime) != 0) las.gps_time.push_back(at(TextColumn::kGpsTime));
  if ((bits & kLasNir) != 0) las.nir.push_back(static_cast<std::uint16_t>(at(TextColumn::kNir)));
}

double las_column_value(const LasAttributes& a, TextColumn column, std::size_t i) {
  switch (column) {
    case TextColumn::kClass: return a.classification[i];
    case TextColumn::kSynthetic: return a.class_flags[i] & 1;
    case TextColumn::kKeyPoint: return (a.class_flags[i] >> 1) & 1;
    case TextColumn::kWithheld: return (a.class_flags[i] >> 2) & 1;
    case TextColumn::kOverlap: return (a.class_flags[i] >> 3) & 1;
    case TextColumn::kReturnNumber: return a.return_number[i];
    case TextColumn::kNumberOfReturns: return a.number_of_returns[i];
    case TextColumn::kScanDirection: return a.scan_flags[i] & 1;
    case TextColumn::kEdgeOfFlightLine: return (a.scan_flags[i] >> 1) & 1;
    case TextColumn::kScannerChannel: return (a.scan_flags[i] >> 2) & 3;
    // Thousandths of a degree as degrees: the nearest double, which
    // push_las_columns rounds back to the same thousandths.
    case TextColumn::kScanAngle: return a.scan_angle[i] / 1000.0;
    case TextColumn::kUserData: return a.user_data[i];
    case TextColumn::kPointSourceId: return a.point_source_id[i];
    case TextColumn::kGpsTime: return a.gps_time[i];
    case TextColumn::kNir: return a.nir[i];
    default: return 0;
  }
}

std::size_t las_column_count(const LasAttributes& a, std::uint32_t bit) {
  std::size_t count = 0;
  a.for_each_vector([&](const auto& v, std::uint32_t b) { count = b == bit ? v.size() : count; });
  return count;
}

Status check_batch_columns(const LasAttributes& las, std::uint32_t bits, std::size_t extra_size, std::size_t n,
                           const std::string& path) {
  if (n == 0) return Status::ok();
  bool complete = extra_size == 0 || (las.extra_bytes_size == extra_size && las.extra_bytes.size() == n * extra_size);
  for (const LasTextColumn& c : kLasColumns) {
    if ((bits & c.bit) != 0) complete = complete && las_column_count(las, c.bit) == n;
  }
  if (complete) return Status::ok();
  return invalid_argument(path + ": a batch of " + std::to_string(n) +
                          " points lacks a LAS attribute or extra bytes the writer was opened with");
}

void size_las_columns(LasAttributes& las, std::uint32_t bits, std::size_t n) {
  las.for_each_vector([&](auto& v, std::uint32_t bit) {
    if (bit != kLasColorLow) v.resize((bits & bit) != 0 ? n : 0);
  });
}

}  // namespace relief
