// Shared by `relief query` and `relief decompress`: stream a query into a
// point writer and report.
#pragma once

#include <string>

#include "cli_common.h"
#include "relief/query.h"

namespace relief::cli {

// Query options from --lod, --threads, --skip-corrupt and the LAS filters
// --class, --first-returns, --last-returns (kQueryFilterFlags,
// kQueryFilterOptions; malformed values are recorded in `args`); warnings go
// to stderr prefixed "relief COMMAND: ".
QueryOptions query_options_from(Args& args, const std::string& command);

// Help lines for the LAS filters, shared by query and decompress.
inline constexpr const char* kQueryFilterHelp =
    "  --class C,...     only points whose LAS classification is one of these (0..255)\n"
    "  --first-returns   only first returns (return number 1)\n"
    "  --last-returns    only last returns (return number = number of returns)\n"
    "                    Filters combine; they need an archive that carries the LAS attributes\n"
    "  --attributes LIST only these attributes beside x y z, as 'relief info' lists them: rgb,\n"
    "                    intensity, classification, return_number, gps_time, extra_bytes ...;\n"
    "                    'none' for x y z alone (default all). The others are not decoded: faster\n"
    "  --polygon AREA    only points inside this x-y area: POLYGON or MULTIPOLYGON Well-Known Text\n"
    "                    or GeoJSON (holes by the even-odd rule; Z/M values ignored), or @FILE: a\n"
    "                    file of WKT or GeoJSON, or an ESRI shapefile (.shp) of polygons. WKT is in\n"
    "                    the archive's coordinates; GeoJSON in longitude/latitude (or the CRS its\n"
    "                    \"crs\" member names) and a shapefile in its .prj's CRS are converted to\n"
    "                    the archive's CRS. Chunks outside the area are not read\n"
    "  --polygon-crs CRS the CRS the area's coordinates are in (EPSG:4326, WKT, ...; easting or\n"
    "                    longitude first), converted to the archive's; overrides the file's\n";

// Runs `box` (or everything when `all`) against the archive at `archive_path`
// into `out_path`. Returns the process exit code; prints errors and, unless
// quiet, a summary.
int run_query_to_file(const std::string& command, const std::string& archive_path, const Box3d* box,
                      const std::string& out_path, const QueryOptions& options, bool quiet);

}  // namespace relief::cli
