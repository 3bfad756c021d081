// Areas of interest for queries: a polygon (with holes) or several, read
// from OGC Well-Known Text, an ESRI shapefile or GeoJSON, in the archive's
// x-y coordinates or in a CRS of their own that a query converts them from.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "relief/status.h"
#include "relief/types.h"

namespace relief {

class Polygon2D {
 public:
  // `POLYGON ((x y, x y, ...), (hole ...))` or `MULTIPOLYGON (((...)), ...)`,
  // keywords in any case, with optional Z, M or ZM (only x and y are used).
  // A ring needs 3 distinct vertices; an unclosed ring is closed; every
  // coordinate must lie within 2^50 (archives' limit). Errors name `source`
  // (a file name, or "the polygon") and what is wrong.
  static Result<Polygon2D> from_wkt(std::string_view wkt, const std::string& source);
  // An ESRI shapefile's main file (.shp) of polygons (shape types 5, 15 or 25;
  // null shapes skipped, Z and M ignored): every part of every record is a
  // ring, all of them one area by the even-odd rule (so ring orientation does
  // not matter). Any other shape type is refused, naming it.
  static Result<Polygon2D> from_shapefile(std::span<const std::uint8_t> bytes, const std::string& source);
  static bool is_shapefile(std::span<const std::uint8_t> bytes);
  // GeoJSON (RFC 7946): a Polygon, MultiPolygon, GeometryCollection of them,
  // Feature or FeatureCollection, all its rings one area by the even-odd
  // rule; other geometry types are refused. Its CRS is longitude/latitude on
  // WGS 84 ("OGC:CRS84"), or the one a 2008-style "crs" member names.
  static Result<Polygon2D> from_geojson(std::string_view text, const std::string& source);
  // A file of at most 256 MiB: a shapefile (by its file code; the CRS from
  // the .prj beside it, when there is one), GeoJSON (text starting with '{')
  // or WKT text.
  static Result<Polygon2D> from_file(const std::string& path);
  // What --polygon and Python's polygon= take: "@PATH" for from_file, else
  // GeoJSON or WKT text.
  static Result<Polygon2D> from_arg(const std::string& text);

  // The CRS the vertices are in, as their source named it (any form
  // relief/crs.h reads); empty: the archive's own, whatever it is.
  const std::string& crs() const { return crs_; }
  // Declares the vertices to be in `crs` (empty: the archive's), replacing
  // what the source said. kFormatError naming `where` when it is not a CRS.
  Status set_crs(const std::string& crs, const std::string& where);
  // The area in CRS `target`: every vertex converted (relief/crs.h
  // CrsTransform, x = easting or longitude), and every edge split where the
  // straight edge of the source CRS bends in the target's by more than 10^-7
  // of the converted area's extent (up to 1,024 pieces an edge, and 16 times
  // the edges or 2^20 in all). The result has `target` as its CRS.
  // kInvalidArgument naming `where` when a vertex cannot be converted.
  Result<Polygon2D> converted_to(const std::string& target, const std::string& where) const;

  // Whether (x, y) is inside by the even-odd rule over every ring (holes are
  // rings inside rings). A point exactly on an edge is inside on one side of
  // it and outside on the other (the crossing rule, half-open in y), so
  // polygons that share an edge split the points on it between them, each to
  // exactly one.
  bool contains(double x, double y) const;

  enum class Overlap { kOutside, kPartial, kInside };
  // How the x-y rectangle of `box` lies against the area: kInside or
  // kOutside when no edge comes near it (then contains() gives that for
  // every point of it), else kPartial.
  Overlap classify(const Box3d& box) const;

  // The x-y bounds, z from -inf to +inf.
  const Box3d& bounds() const { return bounds_; }
  std::size_t ring_count() const { return ring_count_; }
  std::size_t edge_count() const { return edges_.size(); }

  // Every ring's edges, each with its lower end first (y0 < y1, or y0 == y1
  // and x0 <= x1): contains() is the crossing test over these.
  struct Edge {
    double x0, y0, x1, y1;
  };
  const std::vector<Edge>& edges() const { return edges_; }

 private:
  static Result<Polygon2D> from_rings(const std::vector<std::vector<std::array<double, 2>>>& rings,
                                      const std::string& source);
  // From edges in any direction: bounds, limits and the index.
  static Result<Polygon2D> from_edges(std::vector<Edge> edges, std::size_t rings, const std::string& source);
  void build_index();

  std::vector<Edge> edges_;
  std::size_t ring_count_ = 0;
  std::string crs_;
  Box3d bounds_;
  // Edges by horizontal strip of the bounds: strip s holds every edge whose
  // y range meets it, so a point tests only its strip's edges.
  double strip_height_ = 1;
  std::vector<std::uint32_t> strip_start_;  // strips + 1 offsets into strip_edges_
  std::vector<std::uint32_t> strip_edges_;
  std::size_t strip_of(double y) const;
};

}  // namespace relief
