// Coordinate reference systems, through the libraries made for them: GeoTIFF
// keys (the LAS GeoKeyDirectory, GeoDoubleParams and GeoAsciiParams records)
// are decoded by libgeotiff, WKT 1 and 2 parsed and written by PROJ.
//
// Relief keeps a CRS as WKT2 (WKT2:2019 as PROJ writes it; horizontal and
// vertical with their units, a COMPOUNDCRS for both) and, beside it, the CRS
// as its source gave it (its "source form"), so a LAS writer can give it
// back the same way:
//   - a WKT string: the WKT text as the file had it (WKT1 or WKT2);
//   - GeoTIFF keys: "GeoTIFF VLRs: 34735=<hex>; 34736=<hex>; 34737=<hex>",
//     the three LAS records verbatim, lower-case hexadecimal (the last two
//     only when present).
// Older archives hold "EPSG:<code>" or "GeoTIFF keys: <key>=<value>, ...";
// every function here accepts those too.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "relief/status.h"

namespace relief {

inline constexpr char kGeoTiffSourcePrefix[] = "GeoTIFF VLRs:";

// The three GeoTIFF records of a LAS file, as bytes.
struct GeoTiffRecords {
  std::vector<std::uint8_t> keys;     // GeoKeyDirectoryTag (record 34735)
  std::vector<std::uint8_t> doubles;  // GeoDoubleParamsTag (34736), may be empty
  std::vector<std::uint8_t> ascii;    // GeoAsciiParamsTag (34737), may be empty
};

// A CRS read from a source.
struct CrsDefinition {
  std::string wkt;     // WKT2; empty when the source names no CRS the libraries understand
  std::string source;  // the source form (see above)
};

// Decodes GeoTIFF records into WKT2. The directory is checked before
// libgeotiff sees it: every count and offset against the bytes present. A
// malformed directory is kFormatError naming `where` and the problem. Keys
// that are well formed but name no CRS (e.g. only GTRasterTypeGeoKey) give
// an empty wkt.
Result<CrsDefinition> crs_from_geotiff(const GeoTiffRecords& records, const std::string& where);

// Parses a CRS in any form Relief has stored or read (WKT1, WKT2, PROJJSON,
// "EPSG:<code>", the two GeoTIFF forms above) into WKT2. kFormatError naming
// `where` when it is not a CRS.
Result<std::string> crs_to_wkt2(const std::string& text, const std::string& where);
// The same for text that is meant to be WKT (a LAS WKT VLR, which the LAS
// specification defines as OGC WKT): PROJ's WKT parser alone, never a search
// of PROJ's database for the text as a name (~0.5-1 s for a few hundred bytes
// of damage, and it can match an unrelated CRS). So "EPSG:4326" is refused here.
Result<std::string> wkt_to_wkt2(const std::string& wkt, const std::string& where);

// The GeoTIFF source form of `records`, and back (false when `text` is not
// that form or its hexadecimal is broken).
std::string geotiff_source_text(const GeoTiffRecords& records);
bool parse_geotiff_source_text(const std::string& text, GeoTiffRecords& out);

struct CrsSummary {
  std::string name;
  std::optional<int> epsg;  // the CRS's EPSG code, or one PROJ identifies it with
  std::string wkt;          // WKT2
  bool geographic = false;  // horizontal axes are longitude/latitude
};

// Name, EPSG code and WKT2 of a CRS in any of the accepted forms.
Result<CrsSummary> describe_crs(const std::string& text, const std::string& where);

// Whether two CRSs (any accepted forms) are the same CRS (PROJ's
// PJ_COMP_EQUIVALENT: same definition, names and ids aside).
Result<bool> crs_equivalent(const std::string& a, const std::string& b);

// "NAD83 / UTM zone 10N (EPSG:26910)" for messages; the text's first
// 60 characters when it is not a CRS.
std::string crs_label(const std::string& text);

// Converts x-y positions between the horizontal parts of two CRSs (any of the
// accepted forms; a compound CRS's vertical part is left out), with PROJ's
// best operation for each position. Axes are in GIS order at both ends:
// easting or longitude first, whatever order the CRS's definition gives
// (PROJ's proj_normalize_for_visualization), as LAS files, shapefiles and
// GeoJSON hold them. One object is for one thread at a time.
class CrsTransform {
 public:
  // kFormatError naming `where` when either CRS is not understood or PROJ
  // finds no operation between them.
  static Result<CrsTransform> create(const std::string& from, const std::string& to, const std::string& where);
  CrsTransform(CrsTransform&&) noexcept;
  CrsTransform& operator=(CrsTransform&&) noexcept;
  ~CrsTransform();

  // (x, y) converted in place; false, leaving them alone, when the position
  // lies outside what the operation can take (a latitude beyond 90 degrees,
  // a point a projection cannot reach) or the result is not finite.
  bool apply(double& x, double& y) const;

 private:
  struct Impl;
  explicit CrsTransform(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace relief
