#include "io/text_columns.h"

#include <algorithm>
#include <array>
#include <cctype>

#include "relief/types.h"

namespace relief {

namespace {

constexpr LasTextColumn kLasColumns[] = {
    {TextColumn::kClass, kLasClassification, 255, "classification", "Classification"},
    {TextColumn::kSynthetic, kLasClassFlags, 1, "synthetic flag", "Synthetic"},
    {TextColumn::kKeyPoint, kLasClassFlags, 1, "key-point flag", "KeyPoint"},
    {TextColumn::kWithheld, kLasClassFlags, 1, "withheld flag", "Withheld"},
    {TextColumn::kOverlap, kLasClassFlags, 1, "overlap flag", "Overlap"},
    {TextColumn::kReturnNumber, kLasReturnNumber, 15, "return number", "ReturnNumber"},
    {TextColumn::kNumberOfReturns, kLasNumberOfReturns, 15, "number of returns", "NumberOfReturns"},
    {TextColumn::kScanDirection, kLasScanFlags, 1, "scan direction flag", "ScanDirectionFlag"},
    {TextColumn::kEdgeOfFlightLine, kLasScanFlags, 1, "edge of flight line flag", "EdgeOfFlightLine"},
    {TextColumn::kScannerChannel, kLasScanFlags, 3, "scanner channel", "ScannerChannel"},
    {TextColumn::kScanAngle, kLasScanAngle, 0, "scan angle", "ScanAngleRank"},
    {TextColumn::kUserData, kLasUserData, 255, "user data", "UserData"},
    {TextColumn::kPointSourceId, kLasPointSourceId, 65535, "point source ID", "PointSourceId"},
    {TextColumn::kGpsTime, kLasGpsTime, 0, "GPS time", "GpsTime"},
    {TextColumn::kNir, kLasNir, 65535, "NIR", "Infrared"},
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

}  // namespace relief
