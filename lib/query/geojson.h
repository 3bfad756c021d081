// GeoJSON areas (RFC 7946) for relief/polygon.h: the rings of every Polygon
// and MultiPolygon in a geometry, a Feature or a FeatureCollection, and the
// CRS the coordinates are in. Internal to lib/query.
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "relief/status.h"

namespace relief::geojson {

struct Ring {
  std::vector<std::array<double, 2>> vertices;  // as the file gave them (x, y of each position)
  std::string label;                            // "feature 3, polygon 1, ring 2", for messages
};

struct Area {
  std::vector<Ring> rings;
  // "OGC:CRS84" (longitude, latitude on WGS 84: RFC 7946), or the name a
  // 2008-style "crs" member gives.
  std::string crs;
};

// Whether `text` is JSON rather than WKT: its first character other than
// white space (and a UTF-8 byte order mark) is '{'.
bool looks_like(std::string_view text);

// Reads `text`: a Polygon, MultiPolygon, GeometryCollection of those, Feature
// (a null geometry adds nothing) or FeatureCollection. Other geometry types,
// malformed JSON, nesting deeper than 256 levels and positions of fewer than
// two numbers are refused, naming `source` and where.
Status read(std::string_view text, const std::string& source, Area& out);

}  // namespace relief::geojson
