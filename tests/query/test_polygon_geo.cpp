// Areas of interest from GIS files (relief/polygon.h): GeoJSON read in its
// usual forms and refused when malformed, a shapefile's .prj, and areas
// converted between CRSs (vertices and the bends of long edges).
#include <catch2/catch.hpp>

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "relief/crs.h"
#include "relief/polygon.h"
#include "support/temp_dir.h"

using namespace relief;

namespace {

Polygon2D geo(const std::string& text) {
  auto p = Polygon2D::from_geojson(text, "test.geojson");
  INFO(text);
  REQUIRE(p.is_ok());
  return std::move(p).value();
}

// Whether two areas hold the same points of a seeded sample over `box`.
int disagreements(const Polygon2D& a, const Polygon2D& b, double x0, double y0, double x1, double y1) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(x0, x1), uy(y0, y1);
  int bad = 0;
  for (int i = 0; i < 20000; ++i) {
    const double x = ux(rng), y = uy(rng);
    bad += a.contains(x, y) != b.contains(x, y) ? 1 : 0;
  }
  return bad;
}

constexpr const char* kSquareWithHole =
    "[[[0, 0], [10, 0], [10, 10], [0, 10], [0, 0]], [[4, 4], [6, 4], [6, 6], [4, 6], [4, 4]]]";

}  // namespace

TEST_CASE("GeoJSON areas are read in their usual forms", "[polygon][geojson]") {
  const Polygon2D wkt = Polygon2D::from_wkt("POLYGON ((0 0, 10 0, 10 10, 0 10), (4 4, 6 4, 6 6, 4 6))", "w").value();
  const std::string polygon = std::string(R"({"type": "Polygon", "coordinates": )") + kSquareWithHole + "}";
  for (const std::string& text :
       {polygon,
        // Members in another order, positions with z, white space, a BOM.
        std::string("\xEF\xBB\xBF\n {\"coordinates\":[[[0,0,5],[10,0,5],[10,10,5],[0,10,5]],[[4,4],[6,4],[6,6],[4,6]]],"
                    "\r\n\t\"type\":\"Polygon\", \"bbox\": [0, 0, 10, 10]}"),
        std::string(R"({"type": "Feature", "id": 7, "properties": {"name": "lot \u00e9", "tags": [1, "a", null, true, [2, 3]]},)"
                    R"( "geometry": )") + polygon + "}",
        std::string(R"({"type": "FeatureCollection", "features": [{"type": "Feature", "properties": null, "geometry": null},)"
                    R"( {"type": "Feature", "properties": {}, "geometry": )") + polygon + "}]}",
        std::string(R"({"type": "MultiPolygon", "coordinates": [)") + kSquareWithHole + "]}",
        std::string(R"({"type": "GeometryCollection", "geometries": [)") + polygon + "]}"}) {
    const Polygon2D p = geo(text);
    INFO(text);
    CHECK(p.ring_count() == 2);
    CHECK(p.edge_count() == 8);
    CHECK(p.crs() == "OGC:CRS84");
    CHECK(p.contains(2, 2));
    CHECK_FALSE(p.contains(5, 5));
    CHECK(disagreements(p, wkt, -1, -1, 11, 11) == 0);
  }
  // Two polygons of a MultiPolygon, and a named CRS (2008 GeoJSON, as QGIS
  // and GDAL write one that is not longitude/latitude).
  const Polygon2D two = geo(R"({"type": "MultiPolygon", "crs": {"type": "name", "properties": {"name": )"
                            R"("urn:ogc:def:crs:EPSG::32610"}}, "coordinates": [[[[0,0],[1,0],[1,1]]], [[[5,5],[9,5],[9,9]]]]})");
  CHECK(two.ring_count() == 2);
  CHECK(two.crs() == "urn:ogc:def:crs:EPSG::32610");
  CHECK(two.contains(0.9, 0.5));
  CHECK(two.contains(8.5, 6));
  CHECK_FALSE(two.contains(3, 3));
  // Inline text is GeoJSON by its '{', as --polygon and Python take it.
  const auto arg = Polygon2D::from_arg(std::string(" {\"type\": \"Polygon\", \"coordinates\": ") + kSquareWithHole + "}");
  REQUIRE(arg.is_ok());
  CHECK(arg->contains(2, 2));
}

TEST_CASE("malformed or non-polygon GeoJSON is refused naming the source and the problem", "[polygon][geojson]") {
  const std::string deep = std::string(300, '[') + std::string(300, ']');
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "not GeoJSON: the text ends where a value should be at character 1"},
      {"{", "expected a member name in quotes"},
      {"{\"type\": \"Polygon\",}", "expected a member name in quotes"},
      {"{\"type\": \"Polygon\" \"coordinates\": []}", "expected '}' at character 20"},
      {"{\"type\": \"Polygon\", \"coordinates\": [[[0,0],[1,0],[1,1]]]} x", "unexpected text after the JSON value"},
      {"{\"type\": \"Polygon\", \"coordinates\": [[[0,0],[1,0],[1,01]]]}", "a malformed number"},
      {"{\"type\": \"Polygon\", \"coordinates\": [[[0,0],[1,0],[1,1.]]]}", "a malformed number"},
      {"{\"type\": \"Polygon\", \"coordinates\": [[[0,0],[1,0],[1,NaN]]]}", "unexpected character 'N'"},
      {"{\"type\": \"Polygon\", \"coordinates\": [[[0,0],[1,0],[1,1e999]]]}", "a number out of range"},
      {"{\"type\": \"Poly\ngon\"}", "a control character inside a string"},
      {"{\"type\": \"\\ud800\"}", "a lone UTF-16 surrogate"},
      {"{\"type\": \"\\q\"}", "the escape '\\q'"},
      {"{\"type\": \"Polygon\", \"coordinates\": " + deep + "}", "nested deeper than 256 levels"},
      {"[1, 2]", "the GeoJSON is an array, not an object"},
      {"{\"coordinates\": []}", "the GeoJSON has no \"type\" string"},
      {"{\"type\": \"LineString\", \"coordinates\": [[0,0],[1,1]]}", "the GeoJSON is a LineString, not a Polygon or MultiPolygon"},
      {"{\"type\": \"Circle\"}", "has the type \"Circle\", which GeoJSON does not define"},
      {"{\"type\": \"Polygon\"}", "is a Polygon without a \"coordinates\" array"},
      {"{\"type\": \"Polygon\", \"coordinates\": [[0,0],[1,0],[1,1]]}", "one more [ ] is needed"},
      {"{\"type\": \"Polygon\", \"coordinates\": [[[0,0],[1,0],[1]]]}", "polygon, ring 1 holds something other than positions"},
      {"{\"type\": \"Polygon\", \"coordinates\": [[[0,0],[1,1],[0,0]]]}", "polygon, ring 1 has 2 distinct vertices"},
      {"{\"type\": \"Polygon\", \"coordinates\": [[[0,0],[1,0],[1,2e15]]]}", "beyond the coordinate limit of 2^50"},
      {"{\"type\": \"Polygon\", \"coordinates\": []}", "the GeoJSON holds no polygon"},
      {"{\"type\": \"FeatureCollection\", \"features\": [{\"type\": \"Feature\", \"geometry\": null}, {\"type\": \"Feature\", "
       "\"geometry\": {\"type\": \"Point\", \"coordinates\": [1, 2]}}]}",
       "feature 2 is a Point, not a Polygon or MultiPolygon"},
      {"{\"type\": \"FeatureCollection\"}", "has no \"features\" array"},
      {"{\"type\": \"Feature\"}", "has no \"geometry\""},
      {"{\"type\": \"Polygon\", \"crs\": {\"type\": \"link\", \"properties\": {\"href\": \"x\"}}, \"coordinates\": [[[0,0],[1,0],[1,1]]]}",
       "the \"crs\" member names no CRS"},
      {"{\"type\": \"Polygon\", \"crs\": {\"type\": \"name\", \"properties\": {\"name\": \"EPSG:999999\"}}, "
       "\"coordinates\": [[[0,0],[1,0],[1,1]]]}",
       "not a coordinate reference system PROJ understands"},
  };
  for (const auto& [text, message] : cases) {
    INFO("'" << text << "'");
    const auto p = Polygon2D::from_geojson(text, "aoi.geojson");
    REQUIRE_FALSE(p.is_ok());
    CHECK(p.status().message().rfind("aoi.geojson: ", 0) == 0);
    CHECK(p.status().message().find(message) != std::string::npos);
  }
}

TEST_CASE("an area converted between CRSs: vertices exact, long edges follow their bend", "[polygon][crs]") {
  // A parcel in longitude/latitude, converted to WGS 84 / UTM 10N: every
  // point converted on its own lands on the same side of the converted area
  // (those within a millimetre of an edge aside).
  const std::string lonlat = "POLYGON ((-123.01 44.0, -122.99 44.0, -122.99 44.02, -123.0 44.01, -123.01 44.02))";
  Polygon2D area = Polygon2D::from_wkt(lonlat, "lot").value();
  REQUIRE(area.set_crs("EPSG:4326", "test").is_ok());
  const auto utm = area.converted_to("EPSG:32610", "test");
  REQUIRE(utm.is_ok());
  CHECK(utm->crs() == "EPSG:32610");
  CHECK(utm->ring_count() == 1);
  CHECK(utm->edge_count() >= 5);
  auto to_utm = CrsTransform::create("OGC:CRS84", "EPSG:32610", "test");
  REQUIRE(to_utm.is_ok());
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> ux(-123.012, -122.988), uy(43.998, 44.022);
  int checked = 0;
  for (int i = 0; i < 20000; ++i) {
    double x = ux(rng), y = uy(rng);
    const bool inside = area.contains(x, y);
    REQUIRE(to_utm->apply(x, y));
    // Skip points within 1 mm of the converted edges.
    bool near = false;
    for (const auto& e : utm->edges()) {
      const double dx = e.x1 - e.x0, dy = e.y1 - e.y0;
      const double t = std::clamp(((x - e.x0) * dx + (y - e.y0) * dy) / (dx * dx + dy * dy), 0.0, 1.0);
      near = near || std::hypot(e.x0 + t * dx - x, e.y0 + t * dy - y) < 1e-3;
    }
    if (near) continue;
    ++checked;
    CHECK(utm->contains(x, y) == inside);
  }
  CHECK(checked > 19000);

  // Long edges (10 degrees of latitude along meridians 2 and 3 degrees off
  // the zone's centre, 1 degree along parallels) bend in UTM: they are split,
  // and every piece's middle lies on the converted edge to within 10^-7 of
  // the area's extent (~1,100 km: 0.11 m), with some rounding to spare.
  Polygon2D big = Polygon2D::from_wkt("POLYGON ((-126 30, -125 30, -125 40, -126 40))", "big").value();
  REQUIRE(big.set_crs("OGC:CRS84", "test").is_ok());
  const auto bent = big.converted_to("EPSG:32610", "test");
  REQUIRE(bent.is_ok());
  CHECK(bent->edge_count() > 8);
  auto back = CrsTransform::create("EPSG:32610", "OGC:CRS84", "test");
  REQUIRE(back.is_ok());
  const double extent = std::hypot(bent->bounds().max.x - bent->bounds().min.x, bent->bounds().max.y - bent->bounds().min.y);
  double worst = 0;
  for (const auto& e : bent->edges()) {
    double mx = 0.5 * (e.x0 + e.x1), my = 0.5 * (e.y0 + e.y1);
    REQUIRE(back->apply(mx, my));
    // Back in longitude/latitude the middle lies on one of the four
    // straight edges: its distance to the nearest, in metres (a degree of
    // longitude is at least 85 km here, of latitude 111 km).
    const double d = std::min({std::abs(mx + 126) * 85000, std::abs(mx + 125) * 85000, std::abs(my - 30) * 111000,
                               std::abs(my - 40) * 111000});
    worst = std::max(worst, d);
  }
  CHECK(worst < 1.5e-7 * extent);
  // Unconverted, the meridian edges' middles would be ~100 m off.
  const auto plain = Polygon2D::from_wkt("POLYGON ((-126 30, -125 30, -125 40, -126 40))", "p").value();
  CHECK(plain.edge_count() == 4);

  // No CRS of its own: taken as in the target's.
  const auto same = Polygon2D::from_wkt(lonlat, "lot")->converted_to("EPSG:32610", "test");
  REQUIRE(same.is_ok());
  CHECK(same->bounds().min.x == -123.01);

  // A vertex the conversion cannot take.
  Polygon2D polar = Polygon2D::from_wkt("POLYGON ((0 80, 10 80, 10 95, 0 95))", "polar").value();
  REQUIRE(polar.set_crs("OGC:CRS84", "test").is_ok());
  const auto refused = polar.converted_to("EPSG:32610", "the polygon");
  REQUIRE_FALSE(refused.is_ok());
  CHECK(refused.status().code() == StatusCode::kInvalidArgument);
  CHECK(refused.status().message().find("the polygon: the polygon's vertex (") != std::string::npos);
  CHECK(refused.status().message().find("cannot be converted from") != std::string::npos);

  // A CRS that is not one.
  Polygon2D p = Polygon2D::from_wkt(lonlat, "lot").value();
  const Status s = p.set_crs("not a crs", "--polygon-crs");
  REQUIRE_FALSE(s);
  CHECK(s.message().rfind("--polygon-crs", 0) == 0);
  CHECK(p.crs().empty());
}

TEST_CASE("a GeoJSON file and a shapefile's .prj give the area its CRS", "[polygon][geojson][shapefile]") {
  relief::test::TempDir tmp;
  std::ofstream(tmp.file("lot.geojson")) << "{\"type\": \"Polygon\", \"coordinates\": " << kSquareWithHole << "}\n";
  const auto g = Polygon2D::from_arg("@" + tmp.file("lot.geojson"));
  REQUIRE(g.is_ok());
  CHECK(g->crs() == "OGC:CRS84");
  CHECK(g->contains(2, 2));
  std::ofstream(tmp.file("bad.geojson")) << "{\"type\": \"Polygon\", \"coordinates\": [}";
  const auto bad = Polygon2D::from_arg("@" + tmp.file("bad.geojson"));
  REQUIRE_FALSE(bad.is_ok());
  CHECK(bad.status().message().find("bad.geojson: not GeoJSON: ") != std::string::npos);
}
