// Polygon areas of interest (relief/polygon.h): WKT accepted and refused,
// the strip-indexed point test against a plain test over every edge, edges
// shared by neighbours, and the rectangle test against the points in it.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "relief/polygon.h"
#include "support/temp_dir.h"

using namespace relief;

namespace {

using Ring = std::vector<std::array<double, 2>>;

// The even-odd crossing test over every edge, each taken lower end first:
// what Polygon2D::contains promises, without its index.
bool plain_contains(const std::vector<Ring>& rings, double x, double y) {
  bool in = false;
  for (const Ring& r : rings) {
    for (std::size_t i = 0; i < r.size(); ++i) {
      auto a = r[i], b = r[(i + 1) % r.size()];
      if (a[1] > b[1] || (a[1] == b[1] && a[0] > b[0])) std::swap(a, b);
      if (a[1] <= y && y < b[1]) {
        const double xi = a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1]);
        if (x < xi) in = !in;
      }
    }
  }
  return in;
}

std::string wkt_ring(const Ring& r) {
  std::ostringstream s;
  s.precision(17);
  s << "(";
  for (std::size_t i = 0; i <= r.size(); ++i) s << (i ? ", " : "") << r[i % r.size()][0] << " " << r[i % r.size()][1];
  s << ")";
  return s.str();
}

// A star-shaped ring of `n` vertices around (cx, cy): a jagged outline with
// long and short edges.
Ring star(std::mt19937& rng, double cx, double cy, double radius, int n) {
  std::uniform_real_distribution<double> jitter(0.3, 1.0);
  Ring r;
  for (int i = 0; i < n; ++i) {
    const double a = 2 * M_PI * i / n;
    const double d = radius * jitter(rng);
    r.push_back({cx + d * std::cos(a), cy + d * std::sin(a)});
  }
  return r;
}

Polygon2D parse(const std::string& wkt) {
  auto p = Polygon2D::from_wkt(wkt, "test");
  INFO(wkt);
  REQUIRE(p.is_ok());
  return std::move(p).value();
}

}  // namespace

TEST_CASE("WKT polygons are read in their usual forms", "[polygon]") {
  const Polygon2D square = parse("POLYGON ((0 0, 10 0, 10 10, 0 10, 0 0))");
  CHECK(square.ring_count() == 1);
  CHECK(square.edge_count() == 4);
  CHECK(square.bounds().min.x == 0);
  CHECK(square.bounds().max.y == 10);
  CHECK(std::isinf(square.bounds().min.z));
  CHECK(square.contains(5, 5));
  CHECK_FALSE(square.contains(15, 5));
  CHECK_FALSE(square.contains(NAN, 5));
  // Case, spacing, signs, exponents, Z / M / ZM values, an unclosed ring.
  for (const char* text : {"polygon((0 0,10 0,10 10,0 10,0 0))", "  Polygon Z ((0 0 1, 10 0 2, 10 10 3, 0 10 4, 0 0 1))  ",
                           "POLYGON M ((0 0 7,1e1 0 7,10 +10 7,0 10 7,0 0 7))", "POLYGON ZM ((0 0 1 2, 10 0 1 2, 10 10 1 2, 0 10 1 2))",
                           "POLYGON ((0 0, 10 0, 10 10, 0 10))", "POLYGON ((0 0, 10 0, 10 0, 10 10, 0 10, 0 0, 0 0))",
                           "POLYGON((-0 -0,10.0 0,10 10,0 10,0 0))\n"}) {
    const Polygon2D p = parse(text);
    INFO(text);
    CHECK(p.edge_count() == 4);
    CHECK(p.contains(5, 5));
    CHECK_FALSE(p.contains(10.5, 5));
  }
  const Polygon2D holed = parse("POLYGON ((0 0, 10 0, 10 10, 0 10, 0 0), (4 4, 6 4, 6 6, 4 6, 4 4))");
  CHECK(holed.ring_count() == 2);
  CHECK(holed.contains(2, 2));
  CHECK_FALSE(holed.contains(5, 5));
  const Polygon2D multi = parse("MULTIPOLYGON (((0 0, 1 0, 1 1, 0 0)), ((5 5, 9 5, 9 9, 5 9, 5 5), (6 6, 7 6, 7 7, 6 6)))");
  CHECK(multi.ring_count() == 3);
  CHECK(multi.contains(0.9, 0.5));
  CHECK(multi.contains(8, 8));
  CHECK_FALSE(multi.contains(3, 3));
  CHECK_FALSE(multi.contains(6.8, 6.5));
  CHECK(multi.bounds().max.x == 9);
}

TEST_CASE("malformed WKT is refused naming the source and the problem", "[polygon]") {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"", "expected POLYGON or MULTIPOLYGON"},
      {"POINT (1 2)", "'POINT' is not POLYGON or MULTIPOLYGON"},
      {"POLYGON EMPTY", "EMPTY"},
      {"POLYGON ((0 0, 1 0, 1 1, 0 0)) x", "unexpected text after the polygon"},
      {"POLYGON ((0 0, 1 0, 1 1, 0 0)", "expected ')'"},
      {"POLYGON (0 0, 1 0, 1 1, 0 0)", "expected '('"},
      {"POLYGON ((0 0, 1 0, 1 nan, 0 0))", "a vertex needs x and y"},
      {"POLYGON ((0 0, 1 0, 1 -inf, 0 0))", "expected a finite number"},
      {"POLYGON ((0 0, 1 0, 1 1e999, 0 0))", "expected a finite number"},
      {"POLYGON ((0 0, 1, 1 1, 0 0))", "a vertex needs x and y"},
      {"POLYGON ((0 0 0 0 0, 1 0, 1 1, 0 0))", "more than 4 numbers"},
      {"POLYGON ((0 0, 1 1, 0 0))", "ring 1 of the polygon has 2 distinct vertices"},
      {"POLYGON ((0 0, 1 0, 1 1, 0 0), (5 5, 5 5, 5 5))", "ring 2 of the polygon has 1 distinct vertices"},
      {"POLYGON Q ((0 0, 1 0, 1 1, 0 0))", "unexpected 'Q'"},
      {"POLYGON ((0 0, 1 0, 1 2e15, 0 0))", "the polygon has the vertex (1, 2000000000000000), beyond the coordinate limit"},
      {"MULTIPOLYGON ((0 0, 1 0, 1 1, 0 0))", "expected '('"},
  };
  for (const auto& [text, message] : cases) {
    INFO("'" << text << "'");
    const auto p = Polygon2D::from_wkt(text, "aoi.wkt");
    REQUIRE_FALSE(p.is_ok());
    CHECK(p.status().code() == StatusCode::kInvalidArgument);
    CHECK(p.status().message().rfind("aoi.wkt: ", 0) == 0);
    CHECK(p.status().message().find(message) != std::string::npos);
  }
}

TEST_CASE("the indexed point test equals the plain test over every edge", "[polygon]") {
  std::mt19937 rng(5);
  for (const int vertices : {3, 12, 200, 5000}) {
    // An outer star, a hole star inside it and a second part beside it.
    const std::vector<Ring> rings = {star(rng, 0, 0, 100, vertices), star(rng, 0, 0, 25, vertices / 3 + 3),
                                     star(rng, 300, 50, 60, vertices)};
    const std::string wkt = "MULTIPOLYGON ((" + wkt_ring(rings[0]) + ", " + wkt_ring(rings[1]) + "), (" +
                            wkt_ring(rings[2]) + "))";
    const Polygon2D p = parse(wkt);
    std::uniform_real_distribution<double> x(-120, 380), y(-120, 130);
    std::size_t in = 0, mismatches = 0;
    for (int i = 0; i < 100000; ++i) {
      const double px = x(rng), py = y(rng);
      const bool want = plain_contains(rings, px, py);
      in += want ? 1 : 0;
      mismatches += p.contains(px, py) != want ? 1 : 0;
    }
    // Vertices themselves, where rounding and the half-open rule bite.
    for (const Ring& r : rings) {
      for (const auto& v : r) mismatches += p.contains(v[0], v[1]) != plain_contains(rings, v[0], v[1]) ? 1 : 0;
    }
    INFO(vertices << " vertices a ring");
    CHECK(mismatches == 0);
    CHECK(in > 2000);  // the test is not vacuous
  }
}

TEST_CASE("neighbouring polygons split the points on their shared edges", "[polygon]") {
  // Two quadrilaterals sharing a slanted edge, run in opposite directions.
  const Polygon2D left = parse("POLYGON ((0 0, 3 0, 5 10, 0 10, 0 0))");
  const Polygon2D right = parse("POLYGON ((5 10, 3 0, 10 0, 10 10, 5 10))");
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> t(0, 1);
  for (int i = 0; i < 20000; ++i) {
    const double s = t(rng);
    const double x = 3 + 2 * s, y = 10 * s;  // on the shared edge (up to rounding)
    CHECK(left.contains(x, y) + right.contains(x, y) == 1);
    const double gx = 10 * t(rng), gy = 10 * t(rng);  // anywhere in the pair's square
    CHECK(left.contains(gx, gy) + right.contains(gx, gy) == 1);
  }
}

TEST_CASE("rectangles inside or outside a polygon hold only such points", "[polygon]") {
  std::mt19937 rng(11);
  const std::vector<Ring> rings = {star(rng, 0, 0, 100, 300), star(rng, 0, 0, 30, 40)};
  const Polygon2D p = parse("POLYGON (" + wkt_ring(rings[0]) + ", " + wkt_ring(rings[1]) + ")");
  std::uniform_real_distribution<double> c(-130, 130), e(0.01, 20);
  std::uniform_real_distribution<double> t(0, 1);
  int counts[3] = {0, 0, 0};
  for (int i = 0; i < 6000; ++i) {
    const double x0 = c(rng), y0 = c(rng), w = e(rng), h = e(rng);
    const Box3d box{{x0, y0, 0}, {x0 + w, y0 + h, 1}};
    const Polygon2D::Overlap o = p.classify(box);
    ++counts[static_cast<int>(o)];
    if (o == Polygon2D::Overlap::kPartial) continue;
    const bool want = o == Polygon2D::Overlap::kInside;
    bool all = true;
    for (int k = 0; k < 200 && all; ++k) {
      // Corners and edges of the rectangle too.
      const double u = k < 4 ? (k & 1) : t(rng), v = k < 4 ? (k >> 1) : t(rng);
      all = p.contains(x0 + u * w, y0 + v * h) == want;
    }
    INFO("box " << x0 << "," << y0 << " " << w << "x" << h);
    CHECK(all);
  }
  // Every kind occurs, so the checks above mean something.
  CHECK(counts[0] > 100);
  CHECK(counts[1] > 100);
  CHECK(counts[2] > 50);
  // Not finite, or degenerate: partial, or outside.
  CHECK(p.classify(Box3d{{-INFINITY, 0, 0}, {1, 1, 1}}) == Polygon2D::Overlap::kPartial);
  CHECK(p.classify(Box3d{{1000, 1000, 0}, {1001, 1001, 1}}) == Polygon2D::Overlap::kOutside);
}

TEST_CASE("a comb of long edges is tested right", "[polygon]") {
  // A comb: 2,000 teeth whose long sides run the polygon's whole height.
  Ring r;
  for (int i = 0; i < 2000; ++i) {
    r.push_back({2.0 * i, 0});
    r.push_back({2.0 * i, 1000});
    r.push_back({2.0 * i + 1, 1000});
    r.push_back({2.0 * i + 1, 0.5});
  }
  r.push_back({4000, -1});
  r.push_back({0, -1});
  const Polygon2D p = parse("POLYGON (" + wkt_ring(r) + ")");
  CHECK(p.contains(0.5, 500));
  CHECK_FALSE(p.contains(1.5, 500));
  CHECK(p.contains(1.5, 0.1));
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> x(-1, 4001), y(-2, 1001);
  std::size_t mismatches = 0;
  for (int i = 0; i < 20000; ++i) {
    const double px = x(rng), py = y(rng);
    mismatches += p.contains(px, py) != plain_contains({r}, px, py) ? 1 : 0;
  }
  CHECK(mismatches == 0);
}

namespace {

// An ESRI shapefile main file, written field by field as the ESRI whitepaper
// (July 1998) lays it out: a 100-byte header (file code 9994 and the length
// in 16-bit words big-endian, version 1000 and the shape type little-endian,
// the bounding box), then records of a big-endian header (number, content
// length in words) and a little-endian content.
struct Shp {
  std::vector<std::uint8_t> bytes = std::vector<std::uint8_t>(100, 0);
  int type;
  int records = 0;
  explicit Shp(int t) : type(t) {}
  static void be(std::vector<std::uint8_t>& b, std::size_t at, std::int32_t v) {
    for (int i = 0; i < 4; ++i) b[at + i] = static_cast<std::uint8_t>(static_cast<std::uint32_t>(v) >> (24 - 8 * i));
  }
  static void le(std::vector<std::uint8_t>& b, std::int32_t v) {
    for (int i = 0; i < 4; ++i) b.push_back(static_cast<std::uint8_t>(static_cast<std::uint32_t>(v) >> (8 * i)));
  }
  static void le(std::vector<std::uint8_t>& b, double d) {
    std::uint64_t v;
    std::memcpy(&v, &d, 8);
    for (int i = 0; i < 8; ++i) b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  void null_record() {
    std::vector<std::uint8_t> c;
    le(c, std::int32_t{0});
    add(c);
  }
  // Rings as parts; type 15 appends the Z range and values, 25 the M ones.
  void polygon(const std::vector<Ring>& rings, int shape = -1) {
    std::vector<std::uint8_t> c;
    std::int32_t points = 0;
    for (const Ring& r : rings) points += static_cast<std::int32_t>(r.size());
    le(c, std::int32_t{shape < 0 ? type : shape});
    for (int i = 0; i < 4; ++i) le(c, 0.0);  // the record's box (not read)
    le(c, static_cast<std::int32_t>(rings.size()));
    le(c, points);
    std::int32_t first = 0;
    for (const Ring& r : rings) {
      le(c, first);
      first += static_cast<std::int32_t>(r.size());
    }
    for (const Ring& r : rings) {
      for (const auto& v : r) {
        le(c, v[0]);
        le(c, v[1]);
      }
    }
    if (type == 15 || type == 25) {
      for (int i = 0; i < 2 + points; ++i) le(c, 7.5);  // range, then one per point
    }
    add(c);
  }
  void add(const std::vector<std::uint8_t>& content) {
    const std::size_t at = bytes.size();
    bytes.resize(at + 8);
    be(bytes, at, ++records);
    be(bytes, at + 4, static_cast<std::int32_t>(content.size() / 2));
    bytes.insert(bytes.end(), content.begin(), content.end());
  }
  std::vector<std::uint8_t> finish() const {
    std::vector<std::uint8_t> b = bytes;
    be(b, 0, 9994);
    be(b, 24, static_cast<std::int32_t>(b.size() / 2));
    std::vector<std::uint8_t> v;
    le(v, std::int32_t{1000});
    le(v, std::int32_t{type});
    std::memcpy(b.data() + 28, v.data(), 8);
    return b;
  }
};

// A closed ring, as shapefiles store them (first point repeated last).
Ring closed(Ring r) {
  r.push_back(r.front());
  return r;
}

}  // namespace

TEST_CASE("polygon shapefiles read as the same area as their WKT", "[polygon][shapefile]") {
  std::mt19937 rng(21);
  // Outer ring clockwise, hole counter-clockwise, as ESRI writes them; the
  // even-odd rule does not care.
  const Ring outer = {{0, 0}, {0, 50}, {60, 50}, {60, 0}};
  const Ring hole = {{10, 10}, {20, 10}, {20, 20}, {10, 20}};
  const Ring other = star(rng, 100, 25, 20, 50);
  const std::string wkt = "MULTIPOLYGON ((" + wkt_ring(outer) + ", " + wkt_ring(hole) + "), (" + wkt_ring(other) + "))";
  const Polygon2D want = parse(wkt);
  for (const int type : {5, 15, 25}) {
    Shp shp(type);
    shp.polygon({closed(outer), closed(hole)});
    shp.null_record();
    shp.polygon({closed(other)});
    auto got = Polygon2D::from_shapefile(shp.finish(), "aoi.shp");
    INFO("shape type " << type);
    REQUIRE(got.is_ok());
    CHECK(got->ring_count() == 3);
    CHECK(got->edge_count() == want.edge_count());
    std::uniform_real_distribution<double> x(-5, 125), y(-5, 55);
    std::size_t mismatches = 0, in = 0;
    for (int i = 0; i < 20000; ++i) {
      const double px = x(rng), py = y(rng);
      mismatches += got->contains(px, py) != want.contains(px, py) ? 1 : 0;
      in += want.contains(px, py) ? 1 : 0;
    }
    CHECK(mismatches == 0);
    CHECK(in > 5000);
    CHECK_FALSE(got->contains(15, 15));  // the hole
  }
}

TEST_CASE("damaged or non-polygon shapefiles are refused naming the file and the record", "[polygon][shapefile]") {
  Shp good(5);
  good.polygon({closed({{0, 0}, {1, 0}, {1, 1}})});
  good.polygon({closed({{5, 5}, {6, 5}, {6, 6}})});
  const std::vector<std::uint8_t> ok = good.finish();
  REQUIRE(Polygon2D::from_shapefile(ok, "a.shp").is_ok());
  struct Case {
    std::string what;
    std::vector<std::uint8_t> bytes;
    std::string message;
  };
  std::vector<Case> cases;
  {
    Shp lines(3);
    lines.polygon({closed({{0, 0}, {1, 0}, {1, 1}})}, 3);
    cases.push_back({"polylines", lines.finish(), "its shapes are a polyline (type 3), not polygons"});
  }
  {
    auto b = ok;
    b.resize(b.size() - 10);
    cases.push_back({"cut short", b, "truncated: the header declares"});
    auto c = ok;
    c[28] = 0xE9;  // version 1001
    cases.push_back({"version", c, "version 1001, not 1000"});
    auto d = ok;
    Shp::be(d, 100 + 4, 1 << 28);  // the first record's length
    cases.push_back({"record length", d, "record 1 at byte 100: its 536870912 bytes run past the end"});
    auto e = ok;
    e[100 + 8 + 36] = 0xFF;  // parts = 255 (+ high bytes 0)
    cases.push_back({"parts", e, "record 1 at byte 100: 255 parts and 4 points do not fit"});
    auto f = ok;
    f[100 + 8 + 40] = 0x7F;
    f[100 + 8 + 43] = 0x7F;  // points = 2,130,706,559
    cases.push_back({"points", f, "parts and 2130706559 points do not fit"});
    auto g = ok;
    g[100 + 8 + 44] = 2;  // part 1 starts at point 2
    cases.push_back({"part start", g, "part 1 starts at point 2"});
    auto h = ok;
    std::memset(h.data() + 100 + 8 + 48 + 16, 0xFF, 8);  // point 1's x: a NaN
    cases.push_back({"NaN", h, "record 1 at byte 100: point 1 is not finite"});
    auto k = ok;
    k[100 + 8] = 1;  // record 1 says it is a point in a polygon file
    cases.push_back({"mixed types", k, "shape type 1 in a file of type 5"});
    cases.push_back({"header only", std::vector<std::uint8_t>(ok.begin(), ok.begin() + 60), "no shapefile header"});
  }
  {
    Shp degenerate(5);
    degenerate.polygon({closed({{0, 0}, {1, 1}})});
    cases.push_back({"two vertices", degenerate.finish(), "part 1 has 2 distinct vertices"});
    Shp empty(5);
    empty.null_record();
    cases.push_back({"only null shapes", empty.finish(), "holds no polygon"});
  }
  for (const Case& c : cases) {
    INFO(c.what);
    const auto p = Polygon2D::from_shapefile(c.bytes, "a.shp");
    REQUIRE_FALSE(p.is_ok());
    CHECK(p.status().message().rfind("a.shp: ", 0) == 0);
    CHECK(p.status().message().find(c.message) != std::string::npos);
  }
}

TEST_CASE("polygon files: a shapefile or WKT by content, @ in an argument", "[polygon][shapefile]") {
  relief::test::TempDir tmp;
  Shp shp(5);
  shp.polygon({closed({{0, 0}, {0, 10}, {10, 10}, {10, 0}})});
  const auto bytes = shp.finish();
  std::ofstream(tmp.file("aoi.shp"), std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                                              static_cast<std::streamsize>(bytes.size()));
  std::ofstream(tmp.file("aoi.wkt")) << "POLYGON ((0 0, 10 0, 10 10, 0 10, 0 0))\n";
  for (const std::string name : {"aoi.shp", "aoi.wkt"}) {
    auto p = Polygon2D::from_arg("@" + tmp.file(name));
    INFO(name);
    REQUIRE(p.is_ok());
    CHECK(p->contains(5, 5));
    CHECK_FALSE(p->contains(11, 5));
  }
  CHECK(Polygon2D::from_arg("POLYGON ((0 0, 1 0, 1 1, 0 0))").is_ok());
  const auto missing = Polygon2D::from_arg("@" + tmp.file("none.shp"));
  REQUIRE_FALSE(missing.is_ok());
  CHECK(missing.status().code() == StatusCode::kIoError);
  CHECK(missing.status().message().find("none.shp: cannot read") != std::string::npos);
  const auto dir = Polygon2D::from_arg("@" + tmp.path().string());
  REQUIRE_FALSE(dir.is_ok());
  CHECK(dir.status().message().find("is a directory") != std::string::npos);
}

TEST_CASE("a shapefile's .prj beside it names the area's CRS", "[polygon][shapefile][crs]") {
  relief::test::TempDir tmp;
  Shp shp(5);
  shp.polygon({closed({{0, 0}, {0, 10}, {10, 10}, {10, 0}})});
  const auto bytes = shp.finish();
  for (const char* name : {"a.shp", "b.shp", "c.shp", "d.shp"}) {
    std::ofstream(tmp.file(name), std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                                          static_cast<std::streamsize>(bytes.size()));
  }
  // As ArcGIS and QGIS write them: ESRI WKT 1 on one line.
  const std::string esri =
      "PROJCS[\"WGS_1984_UTM_Zone_10N\",GEOGCS[\"GCS_WGS_1984\",DATUM[\"D_WGS_1984\",SPHEROID[\"WGS_1984\",6378137.0,"
      "298.257223563]],PRIMEM[\"Greenwich\",0.0],UNIT[\"Degree\",0.0174532925199433]],PROJECTION[\"Transverse_Mercator\"],"
      "PARAMETER[\"False_Easting\",500000.0],PARAMETER[\"False_Northing\",0.0],PARAMETER[\"Central_Meridian\",-123.0],"
      "PARAMETER[\"Scale_Factor\",0.9996],PARAMETER[\"Latitude_Of_Origin\",0.0],UNIT[\"Meter\",1.0]]";
  std::ofstream(tmp.file("a.prj")) << esri << "\r\n";
  std::ofstream(tmp.file("b.PRJ")) << esri;
  std::ofstream(tmp.file("c.prj")) << "no CRS at all";
  const auto a = Polygon2D::from_arg("@" + tmp.file("a.shp"));
  REQUIRE(a.is_ok());
  CHECK(a->crs() == esri);
  const auto b = Polygon2D::from_arg("@" + tmp.file("b.shp"));
  REQUIRE(b.is_ok());
  CHECK(b->crs() == esri);
  const auto c = Polygon2D::from_arg("@" + tmp.file("c.shp"));
  REQUIRE_FALSE(c.is_ok());
  CHECK(c.status().message().find("c.prj: ") != std::string::npos);
  CHECK(c.status().message().find("not a coordinate reference system") != std::string::npos);
  const auto d = Polygon2D::from_arg("@" + tmp.file("d.shp"));  // no .prj: the archive's CRS
  REQUIRE(d.is_ok());
  CHECK(d->crs().empty());
}
