// Coordinate reference systems (lib/crs, relief/crs.h) and their way through
// LAS files and archives: GeoTIFF key directories built here (EPSG code,
// user-defined Lambert with double parameters, compound with a vertical CRS),
// WKT round trips, hostile directories, CRS mismatches refused by compress
// and append, `info --json`; and the GeoTIFF CRSs of shared/data/las-crs
// against what PDAL reports for them (skipped when the data is absent).

#include <catch2/catch.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "relief/crs.h"
#include "relief/io.h"
#include "support/run_cli.h"
#include "support/shared_data.h"
#include "support/temp_dir.h"

namespace relief {
namespace {

using test::TempDir;

// ---- Building GeoTIFF records

struct Key {
  std::uint16_t id, location, count, value;
};

std::vector<std::uint8_t> words_le(const std::vector<std::uint16_t>& words) {
  std::vector<std::uint8_t> out;
  for (std::uint16_t w : words) {
    out.push_back(static_cast<std::uint8_t>(w));
    out.push_back(static_cast<std::uint8_t>(w >> 8));
  }
  return out;
}

std::vector<std::uint8_t> directory(const std::vector<Key>& keys, int declared = -1) {
  std::vector<std::uint16_t> w = {1, 1, 0,
                                  static_cast<std::uint16_t>(declared < 0 ? keys.size() : static_cast<std::size_t>(declared))};
  for (const Key& k : keys) w.insert(w.end(), {k.id, k.location, k.count, k.value});
  return words_le(w);
}

std::vector<std::uint8_t> doubles_le(const std::vector<double>& values) {
  std::vector<std::uint8_t> out(8 * values.size());
  for (std::size_t i = 0; i < values.size(); ++i) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &values[i], 8);
    for (int b = 0; b < 8; ++b) out[8 * i + static_cast<std::size_t>(b)] = static_cast<std::uint8_t>(bits >> (8 * b));
  }
  return out;
}

std::vector<std::uint8_t> ascii(const std::string& s) { return {s.begin(), s.end()}; }

// The user-defined Lambert conformal conic of PDAL's autzen-thin-srs.las, in
// international feet, on NAD83(HARN) given by its datum code only.
GeoTiffRecords user_defined_lcc() {
  GeoTiffRecords r;
  r.keys = directory({{1024, 0, 1, 1},     {1025, 0, 1, 1},     {2048, 0, 1, 32767}, {2050, 0, 1, 6152},
                      {2054, 0, 1, 9102},  {2057, 34736, 1, 6}, {2059, 34736, 1, 7}, {3072, 0, 1, 32767},
                      {3074, 0, 1, 32767}, {3075, 0, 1, 8},     {3076, 0, 1, 9002},  {3078, 34736, 1, 2},
                      {3079, 34736, 1, 3}, {3084, 34736, 1, 1}, {3085, 34736, 1, 0}, {3086, 34736, 1, 4},
                      {3087, 34736, 1, 5}, {3073, 34737, 10, 0}});
  r.doubles = doubles_le({41.75, -120.5, 43.0, 45.5, 400000.0, 0.0, 6378137.0, 298.257222101});
  r.ascii = ascii("Test LCC||");
  return r;
}

const char* kExpectedLcc =
    "PROJCS[\"x\",GEOGCS[\"NAD83(HARN)\",DATUM[\"NAD83_High_Accuracy_Reference_Network\",SPHEROID[\"GRS 1980\","
    "6378137,298.257222101,AUTHORITY[\"EPSG\",\"7019\"]],AUTHORITY[\"EPSG\",\"6152\"]],PRIMEM[\"Greenwich\",0],"
    "UNIT[\"degree\",0.0174532925199433]],PROJECTION[\"Lambert_Conformal_Conic_2SP\"],"
    "PARAMETER[\"latitude_of_origin\",41.75],PARAMETER[\"central_meridian\",-120.5],"
    "PARAMETER[\"standard_parallel_1\",43],PARAMETER[\"standard_parallel_2\",45.5],"
    "PARAMETER[\"false_easting\",400000],PARAMETER[\"false_northing\",0],UNIT[\"foot\",0.3048],"
    "AXIS[\"Easting\",EAST],AXIS[\"Northing\",NORTH]]";

bool equivalent(const std::string& a, const std::string& b) {
  Result<bool> r = crs_equivalent(a, b);
  INFO((r.is_ok() ? std::string() : r.status().message()));
  REQUIRE(r.is_ok());
  return *r;
}

// ---- LAS files through Relief's own writer (it writes GeoTIFF records verbatim)

void write_las(const std::string& path, const std::string& crs, const std::string& source, double x0 = 1000) {
  WriterOptions o;
  o.crs = crs;
  o.crs_source = source;
  auto w = open_point_writer(path, o);
  REQUIRE(w.is_ok());
  PointCloud c;
  for (int i = 0; i < 400; ++i) {
    c.positions.push_back({x0 + (i % 20) * 0.5, 5000 + (i / 20) * 0.5, 10 + 0.01 * (i % 7)});
  }
  REQUIRE((*w)->write(c).is_ok());
  REQUIRE((*w)->finish().is_ok());
}

PointStreamInfo read_info(const std::string& path) {
  auto r = open_point_reader(path);
  INFO((r.is_ok() ? std::string() : r.status().message()));
  REQUIRE(r.is_ok());
  return (*r)->info();
}

TEST_CASE("GeoTIFF keys naming an EPSG code", "[crs]") {
  GeoTiffRecords r;
  r.keys = directory({{1024, 0, 1, 1}, {1025, 0, 1, 1}, {3072, 0, 1, 26910}, {3076, 0, 1, 9001}});
  auto d = crs_from_geotiff(r, "t.las");
  REQUIRE(d.is_ok());
  auto s = describe_crs(d->wkt, "t");
  REQUIRE(s.is_ok());
  CHECK(s->name == "NAD83 / UTM zone 10N");
  CHECK(s->epsg == 26910);
  CHECK_FALSE(s->geographic);
  CHECK(equivalent(d->wkt, "EPSG:26910"));
  CHECK_FALSE(equivalent(d->wkt, "EPSG:2154"));
  // The source form gives the records back.
  GeoTiffRecords back;
  REQUIRE(parse_geotiff_source_text(d->source, back));
  CHECK(back.keys == r.keys);

  GeoTiffRecords geographic;
  geographic.keys = directory({{1024, 0, 1, 2}, {2048, 0, 1, 4326}});
  auto g = crs_from_geotiff(geographic, "g.las");
  REQUIRE(g.is_ok());
  auto gs = describe_crs(g->wkt, "g");
  REQUIRE(gs.is_ok());
  CHECK(gs->epsg == 4326);
  CHECK(gs->geographic);
}

TEST_CASE("GeoTIFF keys: a projected code in another linear unit keeps that unit", "[crs]") {
  // EPSG:26995 is in metres; ProjLinearUnitsGeoKey says US survey feet (the
  // state plane of PDAL's mvk-thin.las).
  GeoTiffRecords r;
  r.keys = directory({{1024, 0, 1, 1}, {3072, 0, 1, 26995}, {3076, 0, 1, 9003}});
  auto d = crs_from_geotiff(r, "ft.las");
  REQUIRE(d.is_ok());
  CHECK(d->wkt.find("US survey foot") != std::string::npos);
  CHECK_FALSE(equivalent(d->wkt, "EPSG:26995"));
  auto s = describe_crs(d->wkt, "ft");
  REQUIRE(s.is_ok());
  CHECK(s->epsg != 26995);  // the code named the metre version
}

TEST_CASE("GeoTIFF keys: user-defined Lambert conformal conic with double parameters", "[crs]") {
  auto d = crs_from_geotiff(user_defined_lcc(), "lcc.las");
  REQUIRE(d.is_ok());
  CHECK(equivalent(d->wkt, kExpectedLcc));
  // A different standard parallel is a different CRS.
  GeoTiffRecords other = user_defined_lcc();
  other.doubles = doubles_le({41.75, -120.5, 43.5, 45.5, 400000.0, 0.0, 6378137.0, 298.257222101});
  auto o = crs_from_geotiff(other, "lcc2.las");
  REQUIRE(o.is_ok());
  CHECK_FALSE(equivalent(o->wkt, kExpectedLcc));
  auto s = describe_crs(d->wkt, "lcc");
  REQUIRE(s.is_ok());
  CHECK(s->name == "Test LCC");
}

TEST_CASE("GeoTIFF keys: compound CRS with a vertical CRS", "[crs]") {
  GeoTiffRecords r;
  r.keys = directory({{1024, 0, 1, 1}, {3072, 0, 1, 26910}, {4096, 0, 1, 5703}, {4099, 0, 1, 9001}});
  auto d = crs_from_geotiff(r, "c.las");
  REQUIRE(d.is_ok());
  CHECK(d->wkt.rfind("COMPOUNDCRS[", 0) == 0);
  CHECK(equivalent(d->wkt, "EPSG:26910+5703"));
  CHECK_FALSE(equivalent(d->wkt, "EPSG:26910"));
  // A vertical datum code without a vertical CRS code, in feet.
  GeoTiffRecords datum;
  datum.keys = directory({{1024, 0, 1, 1}, {3072, 0, 1, 26910}, {4098, 0, 1, 5103}, {4099, 0, 1, 9002}});
  auto v = crs_from_geotiff(datum, "v.las");
  REQUIRE(v.is_ok());
  CHECK(v->wkt.find("VERTCRS[") != std::string::npos);
  CHECK(v->wkt.find("North American Vertical Datum 1988") != std::string::npos);
  CHECK(v->wkt.find("LENGTHUNIT[\"foot\"") != std::string::npos);
}

TEST_CASE("GeoTIFF keys that name no CRS give none, without error", "[crs]") {
  GeoTiffRecords r;
  r.keys = directory({{1025, 0, 1, 1}});
  auto d = crs_from_geotiff(r, "raster.las");
  REQUIRE(d.is_ok());
  CHECK(d->wkt.empty());
}

TEST_CASE("hostile GeoTIFF key directories are rejected naming the file", "[crs]") {
  std::vector<std::pair<std::string, GeoTiffRecords>> cases;
  auto add = [&](const std::string& what, GeoTiffRecords r) { cases.emplace_back(what, std::move(r)); };
  GeoTiffRecords r;
  r.keys = {1, 0, 1};  // 3 bytes: not even the header
  add("truncated header", r);
  r.keys = directory({{1024, 0, 1, 1}}, 5000);
  add("lying key count", r);
  r.keys = directory({{1024, 0, 1, 1}, {3072, 0, 1, 26910}});
  r.keys.resize(r.keys.size() - 3);  // the last key cut short
  add("truncated key", r);
  r = user_defined_lcc();
  r.doubles.resize(8 * 5);  // parameters 5..7 missing
  add("double offset out of range", r);
  r = user_defined_lcc();
  r.ascii.clear();
  add("ASCII offset out of range", r);
  r = GeoTiffRecords{};
  r.keys = directory({{1024, 0, 1, 1}, {3073, 34737, 65535, 65535}});
  r.ascii = ascii("x|");
  add("offset + count overflow", r);
  r.keys = directory({{1024, 0, 1, 1}, {3072, 0, 7, 26910}});
  add("inline key with a count", r);
  r.keys = directory({{1024, 0, 1, 1}, {3072, 33550, 1, 0}});
  add("unknown tag location", r);
  r.keys = words_le({2, 1, 0, 0});
  add("directory version", r);
  r = user_defined_lcc();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  r.doubles = doubles_le({41.75, -120.5, 43.0, 45.5, nan, 0.0, 6378137.0, 298.257222101});
  add("NaN parameter", r);
  r = user_defined_lcc();
  // libgeotiff prints parameters into fixed buffers: 1e300 used to abort the
  // process (glibc's fortify check) inside GTIFGetProj4Defn.
  r.doubles = doubles_le({41.75, -120.5, 43.0, 45.5, 1e300, 0.0, 6378137.0, 298.257222101});
  add("huge parameter", r);
  for (const auto& [what, records] : cases) {
    INFO(what);
    auto d = crs_from_geotiff(records, "hostile.las");
    REQUIRE_FALSE(d.is_ok());
    CHECK(d.status().code() == StatusCode::kFormatError);
    CHECK(d.status().message().find("hostile.las") != std::string::npos);
  }
  // The same through a LAS file: the reader refuses it naming the file.
  TempDir dir;
  const std::string path = dir.file("hostile.las");
  GeoTiffRecords lying;
  lying.keys = directory({{1024, 0, 1, 1}, {3072, 34736, 4, 100}});
  write_las(path, "EPSG:26910", geotiff_source_text(lying));
  auto reader = open_point_reader(path);
  REQUIRE_FALSE(reader.is_ok());
  CHECK(reader.status().code() == StatusCode::kFormatError);
  CHECK(reader.status().message().find(path) != std::string::npos);
}

TEST_CASE("older stored forms are still understood", "[crs]") {
  auto s = describe_crs("EPSG:2154", "old");
  REQUIRE(s.is_ok());
  CHECK(s->epsg == 2154);
  auto k = describe_crs("GeoTIFF keys: 1024=1, 3072=2154", "old");
  REQUIRE(k.is_ok());
  CHECK(k->epsg == 2154);
  CHECK(equivalent("EPSG:2154", "GeoTIFF keys: 1024=1, 3072=2154"));
  CHECK_FALSE(describe_crs("not a CRS", "bad").is_ok());
  CHECK(crs_label("EPSG:26910") == "\"NAD83 / UTM zone 10N\" (EPSG:26910)");
}

const char* kWkt1Lambert93 =
    "PROJCS[\"RGF93 / Lambert-93\",GEOGCS[\"RGF93\",DATUM[\"Reseau_Geodesique_Francais_1993\",SPHEROID[\"GRS "
    "1980\",6378137,298.257222101,AUTHORITY[\"EPSG\",\"7019\"]],AUTHORITY[\"EPSG\",\"6171\"]],PRIMEM[\"Greenwich\",0],"
    "UNIT[\"degree\",0.0174532925199433],AUTHORITY[\"EPSG\",\"4171\"]],PROJECTION[\"Lambert_Conformal_Conic_2SP\"],"
    "PARAMETER[\"standard_parallel_1\",49],PARAMETER[\"standard_parallel_2\",44],PARAMETER[\"latitude_of_origin\",46.5],"
    "PARAMETER[\"central_meridian\",3],PARAMETER[\"false_easting\",700000],PARAMETER[\"false_northing\",6600000],"
    "UNIT[\"metre\",1],AUTHORITY[\"EPSG\",\"2154\"]]";

TEST_CASE("WKT 1 and 2 through LAS: read as WKT2, written back as given", "[crs]") {
  TempDir dir;
  auto wkt2 = crs_to_wkt2("EPSG:32632", "t");
  REQUIRE(wkt2.is_ok());
  for (const std::string& given : {std::string(kWkt1Lambert93), *wkt2}) {
    const std::string path = dir.file("w.las");
    std::filesystem::remove(path);
    auto normalised = crs_to_wkt2(given, "given");
    REQUIRE(normalised.is_ok());
    write_las(path, *normalised, given);
    const PointStreamInfo info = read_info(path);
    CHECK(info.crs_source == given);  // the WKT VLR holds the text as the source had it
    CHECK(info.crs.rfind("PROJCRS[", 0) == 0);
    CHECK(equivalent(info.crs, given));
  }
}

TEST_CASE("damaged WKT goes to PROJ's WKT parser, names and codes to its lookup", "[crs]") {
  // A WKT VLR that lost bytes in its first keyword (as fuzzing made one):
  // refused by the WKT parser with its complaint, not searched for by name
  // in PROJ's database (which took ~1 s for such a text and can match an
  // unrelated CRS).
  const std::string damaged = "PRO\xf9\xff\xff\xff" + std::string(kWkt1Lambert93).substr(3);
  auto bad = crs_to_wkt2(damaged, "x.las: WKT VLR");
  REQUIRE_FALSE(bad.is_ok());
  CHECK(bad.status().code() == StatusCode::kFormatError);
  CHECK_THAT(bad.status().message(),
             Catch::Contains("x.las: WKT VLR: not a WKT coordinate reference system PROJ understands: "));
  // Whole WKT with a damaged value inside, and WKT 1 with parentheses.
  std::string inner(kWkt1Lambert93);
  inner.replace(inner.find("GEOGCS["), 7, "GEOGCS[[");
  CHECK_FALSE(crs_to_wkt2(inner, "inner").is_ok());
  std::string parens(kWkt1Lambert93);
  for (char& c : parens) c = c == '[' ? '(' : c == ']' ? ')' : c;
  auto p = describe_crs(parens, "parentheses");
  REQUIRE(p.is_ok());
  CHECK(p->epsg == 2154);
  // Names (parentheses inside), codes and PROJJSON still reach proj_create.
  auto csrs = describe_crs("NAD83(CSRS) / UTM zone 10N", "name");
  REQUIRE(csrs.is_ok());
  CHECK(csrs->epsg == 3157);
  auto wgs = describe_crs("WGS 84", "name");
  REQUIRE(wgs.is_ok());
  CHECK(wgs->epsg == 4326);
  auto harn = describe_crs("NAD83(HARN)", "name");
  REQUIRE(harn.is_ok());
  CHECK(harn->name == "NAD83(HARN)");
  CHECK(describe_crs("urn:ogc:def:crs:EPSG::2154", "urn")->epsg == 2154);
  // A LAS WKT VLR is WKT by definition: wkt_to_wkt2 never looks a text up by
  // name (fuzzing made one of GeoTIFF citation text, which took 0.5 s).
  CHECK(crs_to_wkt2("EPSG:2154", "any").is_ok());
  auto code = wkt_to_wkt2("EPSG:2154", "x.las: WKT VLR");
  REQUIRE_FALSE(code.is_ok());
  CHECK_THAT(code.status().message(), Catch::StartsWith("x.las: WKT VLR: not a WKT coordinate reference system"));
  CHECK_FALSE(wkt_to_wkt2("proCS_North_American_1983|Datum = D_North_American_1983|", "x.las: WKT VLR").is_ok());
  auto good = wkt_to_wkt2(kWkt1Lambert93, "x.las: WKT VLR");
  REQUIRE(good.is_ok());
  CHECK(equivalent(*good, "EPSG:2154"));
}

TEST_CASE("answers kept for a CRS asked about again are the same, errors name each caller", "[crs]") {
  // lib/crs keeps PROJ's last answers (a reader of many tiles asks the same
  // question per file); what comes back must not depend on that.
  const Result<std::string> first = wkt_to_wkt2(kWkt1Lambert93, "a.las: WKT VLR");
  const Result<std::string> again = wkt_to_wkt2(kWkt1Lambert93, "b.las: WKT VLR");
  REQUIRE(first.is_ok());
  REQUIRE(again.is_ok());
  CHECK(*first == *again);
  const GeoTiffRecords lcc = user_defined_lcc();
  const Result<CrsDefinition> d1 = crs_from_geotiff(lcc, "a.las");
  const Result<CrsDefinition> d2 = crs_from_geotiff(lcc, "b.las");
  REQUIRE(d1.is_ok());
  REQUIRE(d2.is_ok());
  CHECK(d1->wkt == d2->wkt);
  CHECK(d1->source == d2->source);
  CHECK(describe_crs("EPSG:2154", "x")->name == describe_crs("EPSG:2154", "y")->name);
  CHECK(*crs_equivalent(*first, "EPSG:2154"));
  CHECK(*crs_equivalent(*first, "EPSG:2154"));
  CHECK_FALSE(*crs_equivalent(*first, "EPSG:4326"));
  // Failures are not kept: each names its own caller.
  for (const char* file : {"a.las", "b.las"}) {
    const Result<std::string> bad = wkt_to_wkt2("PROJCS[\"broken\"", std::string(file) + ": WKT VLR");
    REQUIRE_FALSE(bad.is_ok());
    CHECK_THAT(bad.status().message(), Catch::StartsWith(std::string(file) + ": WKT VLR"));
  }
  // More CRSs than are kept, then the first again: still the same answer.
  for (const int code : {2154, 4326, 25832, 25833, 32631, 32632, 32633, 3857, 27572, 2056, 31467, 28992, 3035,
                         3034, 4258, 4269, 26910, 26911}) {
    REQUIRE(describe_crs("EPSG:" + std::to_string(code), "code")->epsg == code);
  }
  CHECK(wkt_to_wkt2(kWkt1Lambert93, "c.las: WKT VLR").value() == *first);
}

TEST_CASE("GeoTIFF records through LAS come back verbatim", "[crs]") {
  TempDir dir;
  const GeoTiffRecords lcc = user_defined_lcc();
  auto d = crs_from_geotiff(lcc, "lcc");
  REQUIRE(d.is_ok());
  const std::string path = dir.file("lcc.las");
  write_las(path, d->wkt, d->source);
  const PointStreamInfo info = read_info(path);
  CHECK(info.crs_source == d->source);
  CHECK(equivalent(info.crs, kExpectedLcc));
}

// ---- CLI: mismatches, --assume-crs, info --json

test::CliRun cli(const std::string& args) { return test::run_cli(RELIEF_CLI, args); }

bool valid_utf8(const std::string& s) {
  for (std::size_t i = 0; i < s.size();) {
    const auto c = static_cast<unsigned char>(s[i]);
    std::size_t n = c < 0x80 ? 1 : (c >> 5) == 6 ? 2 : (c >> 4) == 14 ? 3 : (c >> 3) == 30 ? 4 : 0;
    if (n == 0 || s.size() - i < n) return false;
    for (std::size_t k = 1; k < n; ++k) {
      if ((static_cast<unsigned char>(s[i + k]) >> 6) != 2) return false;
    }
    i += n;
  }
  return true;
}

TEST_CASE("CrsTransform: longitude and latitude to UTM, axes in GIS order", "[crs]") {
  // On the central meridian of WGS 84 / UTM 10N (123 W) the easting is the
  // false easting and the northing 0.9996 times the meridian arc, here
  // integrated numerically for 44 N on the WGS 84 ellipsoid: 4,871,872.8408 m.
  for (const char* from : {"OGC:CRS84", "EPSG:4326", "urn:ogc:def:crs:OGC:1.3:CRS84"}) {
    CAPTURE(from);
    auto t = CrsTransform::create(from, "EPSG:32610", "test");
    REQUIRE(t.is_ok());
    double x = -123.0, y = 44.0;  // longitude first, even for EPSG:4326's latitude-first definition
    REQUIRE(t->apply(x, y));
    CHECK(x == Approx(500000.0).margin(1e-6));
    CHECK(y == Approx(4871872.8408).margin(2e-3));
  }
  // A compound target converts through its horizontal part.
  auto compound = CrsTransform::create("OGC:CRS84", "EPSG:32610+5703", "test");
  REQUIRE(compound.is_ok());
  double x = -123.0, y = 44.0;
  REQUIRE(compound->apply(x, y));
  CHECK(y == Approx(4871872.8408).margin(2e-3));
  // Back again.
  auto back = CrsTransform::create("EPSG:32610", "OGC:CRS84", "test");
  REQUIRE(back.is_ok());
  REQUIRE(back->apply(x, y));
  CHECK(x == Approx(-123.0).margin(1e-9));
  CHECK(y == Approx(44.0).margin(1e-9));
}

TEST_CASE("CrsTransform: positions it cannot take, and CRSs it does not know", "[crs]") {
  auto t = CrsTransform::create("OGC:CRS84", "EPSG:32610", "area.geojson");
  REQUIRE(t.is_ok());
  double x = 10.0, y = 95.0;  // beyond the pole
  CHECK_FALSE(t->apply(x, y));
  CHECK(x == 10.0);
  CHECK(y == 95.0);
  double nx = std::nan(""), ny = 0;
  CHECK_FALSE(t->apply(nx, ny));
  auto bad = CrsTransform::create("EPSG:999999", "EPSG:32610", "area.geojson");
  REQUIRE_FALSE(bad.is_ok());
  CHECK(bad.status().code() == StatusCode::kFormatError);
  CHECK(bad.status().message().find("area.geojson") != std::string::npos);
}

TEST_CASE("compress and append refuse inputs with different CRSs unless --assume-crs", "[crs][cli]") {
  TempDir dir;
  const std::string utm = dir.file("utm.las");
  const std::string lambert = dir.file("lambert.las");
  const std::string none = dir.file("none.las");
  write_las(utm, "EPSG:26910", "", 500000);
  write_las(lambert, "EPSG:2154", "", 700000);
  write_las(none, "", "", 500100);

  SECTION("compress") {
    const auto r = cli("compress " + utm + " " + lambert + " -o " + dir.file("a.relief") + " --quiet");
    CHECK(r.code == 11);
    CHECK(r.output.find("NAD83 / UTM zone 10N") != std::string::npos);
    CHECK(r.output.find("EPSG:26910") != std::string::npos);
    CHECK(r.output.find("Lambert-93") != std::string::npos);
    CHECK(r.output.find("EPSG:2154") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir.file("a.relief")));

    const auto ok = cli("compress " + utm + " " + lambert + " -o " + dir.file("b.relief") + " --quiet --assume-crs");
    CHECK(ok.code == 0);
    CHECK(ok.output.find("warning") != std::string::npos);
    const auto info = cli("info " + dir.file("b.relief") + " --json");
    CHECK(info.output.find("\"epsg\": 26910") != std::string::npos);
  }
  SECTION("append") {
    REQUIRE(cli("compress " + lambert + " -o " + dir.file("l.relief") + " --quiet").code == 0);
    const auto r = cli("append " + dir.file("l.relief") + " " + utm + " --quiet");
    CHECK(r.code == 11);
    CHECK(r.output.find("EPSG:26910") != std::string::npos);
    CHECK(r.output.find("EPSG:2154") != std::string::npos);
    const auto ok = cli("append " + dir.file("l.relief") + " " + utm + " --quiet --assume-crs");
    CHECK(ok.code == 0);
    CHECK(ok.output.find("warning") != std::string::npos);
    const auto info = cli("info " + dir.file("l.relief") + " --json");
    CHECK(info.output.find("\"epsg\": 2154") != std::string::npos);
  }
  SECTION("an input without a CRS takes the other's, with a warning") {
    const auto r = cli("compress " + none + " " + utm + " -o " + dir.file("n.relief") + " --quiet");
    CHECK(r.code == 0);
    CHECK(r.output.find("has no CRS") != std::string::npos);
    const auto info = cli("info " + dir.file("n.relief"));
    CHECK(info.output.find("NAD83 / UTM zone 10N (EPSG:26910)") != std::string::npos);
  }
  SECTION("the same CRS in another form is accepted") {
    const std::string keys = dir.file("keys.las");
    GeoTiffRecords r;
    r.keys = directory({{1024, 0, 1, 1}, {3072, 0, 1, 26910}});
    auto d = crs_from_geotiff(r, "k");
    REQUIRE(d.is_ok());
    write_las(keys, d->wkt, d->source, 500200);
    const auto ok = cli("compress " + utm + " " + keys + " -o " + dir.file("s.relief") + " --quiet");
    CHECK(ok.code == 0);
    CHECK(ok.output.find("warning") == std::string::npos);
  }
}

TEST_CASE("query and stats convert an area in another CRS to the archive's", "[crs][cli][polygon]") {
  TempDir dir;
  // A 40 x 40 grid of points 0.5 m apart in WGS 84 / UTM 10N; the area's
  // corners lie between grid lines, so no point is near its edges.
  const auto grid = [&](const std::string& path, const std::string& crs) {
    WriterOptions o;
    o.crs = crs;
    auto w = open_point_writer(path, o);
    REQUIRE(w.is_ok());
    PointCloud c;
    for (int i = 0; i < 1600; ++i) c.positions.push_back({500000 + (i % 40) * 0.5, 4871800 + (i / 40) * 0.5, 10.0});
    REQUIRE((*w)->write(c).is_ok());
    REQUIRE((*w)->finish().is_ok());
  };
  grid(dir.file("utm.las"), "EPSG:32610");
  grid(dir.file("plain.las"), "");
  const std::string archive = dir.file("utm.relief");
  const std::string plain = dir.file("plain.relief");
  REQUIRE(cli("compress " + dir.file("utm.las") + " -o " + archive + " --quiet").code == 0);
  REQUIRE(cli("compress " + dir.file("plain.las") + " -o " + plain + " --quiet").code == 0);
  // A triangle (186 grid points inside by the crossing rule, counted below).
  const double corners[3][2] = {{500002.25, 4871802.25}, {500012.25, 4871803.25}, {500004.25, 4871811.75}};
  std::size_t want = 0;
  for (int i = 0; i < 1600; ++i) {
    const double x = 500000 + (i % 40) * 0.5, y = 4871800 + (i / 40) * 0.5;
    bool in = false;
    for (int k = 0; k < 3; ++k) {
      const double* a = corners[k];
      const double* b = corners[(k + 1) % 3];
      if ((a[1] <= y) != (b[1] <= y) && x < a[0] + (y - a[1]) * (b[0] - a[0]) / (b[1] - a[1])) in = !in;
    }
    want += in ? 1 : 0;
  }
  REQUIRE(want > 40);
  auto to_lonlat = CrsTransform::create("EPSG:32610", "OGC:CRS84", "test");
  REQUIRE(to_lonlat.is_ok());
  std::string utm_wkt = "POLYGON ((", ll_wkt = "POLYGON ((", geojson = "{\"type\": \"Polygon\", \"coordinates\": [[";
  for (int k = 0; k < 3; ++k) {
    double x = corners[k][0], y = corners[k][1];
    char t[120];
    std::snprintf(t, sizeof t, "%s%.17g %.17g", k ? ", " : "", x, y);
    utm_wkt += t;
    REQUIRE(to_lonlat->apply(x, y));
    std::snprintf(t, sizeof t, "%s%.17g %.17g", k ? ", " : "", x, y);
    ll_wkt += t;
    std::snprintf(t, sizeof t, "%s[%.17g, %.17g]", k ? ", " : "", x, y);
    geojson += t;
  }
  utm_wkt += "))";
  ll_wkt += "))";
  geojson += "]]}";
  std::ofstream(dir.file("lot.geojson")) << geojson;
  const auto count = [](const test::CliRun& r) {
    const std::size_t at = r.output.find("points ");
    REQUIRE(at != std::string::npos);
    std::string digits;
    for (std::size_t i = at + 7; i < r.output.size() && r.output[i] != '\n'; ++i) {
      if (std::isdigit(static_cast<unsigned char>(r.output[i])) != 0) digits += r.output[i];
    }
    return std::stoull(digits);
  };
  const auto utm = cli("stats " + archive + " --polygon '" + utm_wkt + "'");
  REQUIRE(utm.code == 0);
  CHECK(count(utm) == want);
  const auto geo = cli("stats " + archive + " --polygon @" + dir.file("lot.geojson"));
  REQUIRE(geo.code == 0);
  CHECK(count(geo) == want);
  CHECK(geo.output.find("warning") == std::string::npos);
  const auto ll = cli("stats " + archive + " --polygon '" + ll_wkt + "' --polygon-crs EPSG:4326");
  REQUIRE(ll.code == 0);
  CHECK(count(ll) == want);
  const auto q = cli("query " + archive + " --polygon @" + dir.file("lot.geojson") + " -o " + dir.file("lot.xyz") + " --quiet");
  REQUIRE(q.code == 0);
  std::ifstream xyz(dir.file("lot.xyz"));
  const auto lines = static_cast<std::size_t>(std::count(std::istreambuf_iterator<char>(xyz), {}, '\n'));
  CHECK(lines >= want);  // a header line or none, then one line a point
  CHECK(lines <= want + 1);
  // Longitude/latitude taken as the archive's coordinates: nothing, and why.
  const auto raw = cli("stats " + archive + " --polygon '" + ll_wkt + "'");
  REQUIRE(raw.code == 0);
  CHECK(count(raw) == 0);
  CHECK(raw.output.find("are its coordinates in the archive's CRS?") != std::string::npos);
  // An archive without a CRS takes the coordinates as they are, and says so.
  const auto none = cli("stats " + plain + " --polygon @" + dir.file("lot.geojson"));
  REQUIRE(none.code == 0);
  CHECK(count(none) == 0);
  CHECK(none.output.find("the archive names no CRS, so the polygon's coordinates (in \"WGS 84 (CRS84)\"") !=
        std::string::npos);
  // Usage errors.
  const auto alone = cli("stats " + archive + " --polygon-crs EPSG:4326");
  CHECK(alone.code == 2);
  CHECK(alone.output.find("--polygon-crs needs --polygon") != std::string::npos);
  const auto bad = cli("query " + archive + " --polygon '" + ll_wkt + "' --polygon-crs EPSG:999999 -o " + dir.file("x.xyz"));
  CHECK(bad.code == 2);
  CHECK(bad.output.find("--polygon-crs") != std::string::npos);
  CHECK(bad.output.find("not a coordinate reference system PROJ understands") != std::string::npos);
}

TEST_CASE("compress and stream --crs name the inputs' CRS, append checks it against the archive's", "[crs][cli]") {
  TempDir dir;
  const std::string xyz = dir.file("scan.xyz");
  {
    std::ofstream out(xyz);
    out << "x y z\n";
    for (int i = 0; i < 400; ++i) out << 500000 + (i % 20) * 0.5 << " " << 4871800 + (i / 20) * 0.5 << " 10\n";
  }
  const std::string nad = dir.file("nad.las");
  write_las(nad, "EPSG:26910", "", 500000);
  const auto json_crs = [&](const std::string& archive) {
    const auto r = cli("info " + archive + " --json");
    REQUIRE(r.code == 0);
    return r.output;
  };

  // An XYZ file names no CRS: --crs gives the archive one.
  const std::string a = dir.file("a.relief");
  const auto made = cli("compress " + xyz + " -o " + a + " --crs EPSG:32610 --quiet");
  REQUIRE(made.code == 0);
  CHECK(made.output.find("warning") == std::string::npos);
  CHECK(json_crs(a).find("\"epsg\": 32610") != std::string::npos);
  // A LAS file naming another: replaced, with a warning that says the
  // coordinates stay as they are.
  const std::string b = dir.file("b.relief");
  const auto replaced = cli("compress " + nad + " -o " + b + " --crs EPSG:32610 --quiet");
  REQUIRE(replaced.code == 0);
  CHECK(replaced.output.find("has the CRS \"NAD83 / UTM zone 10N\" (EPSG:26910); --crs gives the archive \"WGS 84 / "
                             "UTM zone 10N\" (EPSG:32610) (the coordinates are not converted)") != std::string::npos);
  CHECK(json_crs(b).find("\"epsg\": 32610") != std::string::npos);
  // The same CRS said twice: no warning.
  const std::string c = dir.file("c.relief");
  const auto same = cli("compress " + nad + " -o " + c + " --crs EPSG:26910 --quiet");
  REQUIRE(same.code == 0);
  CHECK(same.output.find("warning") == std::string::npos);
  // Without --crs the XYZ archive has none.
  const std::string d = dir.file("d.relief");
  REQUIRE(cli("compress " + xyz + " -o " + d + " --quiet").code == 0);
  CHECK(json_crs(d).find("\"crs\": null") != std::string::npos);

  // Append: --crs is the new inputs' CRS, checked against the archive's.
  const auto clash = cli("append " + a + " " + xyz + " --crs EPSG:2154 --quiet");
  CHECK(clash.code == 11);
  CHECK(clash.output.find("has the CRS \"WGS 84 / UTM zone 10N\" (EPSG:32610) but --crs has \"RGF93 v1 / Lambert-93\"") !=
        std::string::npos);
  CHECK(cli("append " + a + " " + xyz + " --crs EPSG:32610 --quiet").code == 0);
  const auto given = cli("append " + d + " " + xyz + " --crs EPSG:32610 --quiet");
  REQUIRE(given.code == 0);
  CHECK(json_crs(d).find("\"epsg\": 32610") != std::string::npos);

  // Not a CRS: a usage error before anything is made.
  const auto bad = cli("compress " + xyz + " -o " + dir.file("e.relief") + " --crs EPSG:999999");
  CHECK(bad.code == 2);
  CHECK(bad.output.find("--crs: not a coordinate reference system PROJ understands") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(dir.file("e.relief")));

  // A stream names its CRS the same way; one appended to must agree.
  const std::string s = dir.file("s.relief");
  const std::string body = dir.file("body.xyz");
  std::ofstream(body) << "500000 4871800 10\n500001 4871800 10\n500000 4871801 10\n";
  REQUIRE(cli("stream " + s + " --cell 1 --crs EPSG:32610 --quiet < " + body).code == 0);
  CHECK(json_crs(s).find("\"epsg\": 32610") != std::string::npos);
  const auto other = cli("stream " + s + " --crs EPSG:2154 --quiet < " + body);
  CHECK(other.code == 11);
  CHECK(other.output.find("but --crs has \"RGF93 v1 / Lambert-93\" (EPSG:2154); one archive holds one CRS") !=
        std::string::npos);
  CHECK(cli("stream " + s + " --crs EPSG:32610 --quiet < " + body).code == 0);

  // What a CRS is for: an area in longitude/latitude finds the points.
  const auto area = cli("stats " + a + " --polygon \"POLYGON ((-123.0001 43.99, -122.99 43.99, -122.99 44.1, -123.0001 44.1))\" "
                        "--polygon-crs EPSG:4326");
  REQUIRE(area.code == 0);
  CHECK(area.output.find("points               800") != std::string::npos);
}

TEST_CASE("info --json: attributes array, codec parameters object, CRS object, valid UTF-8", "[crs][cli]") {
  TempDir dir;
  // A file name that is not UTF-8: the JSON must still be.
  const std::string odd = dir.file(std::string("bad\xff\xfe name \"q\".las"));
  write_las(odd, "EPSG:26910", "", 500000);
  const std::string archive = dir.file("j.relief");
  REQUIRE(cli("compress '" + odd + "' -o " + archive + " --quiet").code == 0);
  const auto r = cli("info " + archive + " --json");
  REQUIRE(r.code == 0);
  CHECK(valid_utf8(r.output));
  CHECK(r.output.find("\xEF\xBF\xBD") != std::string::npos);  // the replacement character
  CHECK(r.output.find("\\\"q\\\"") != std::string::npos);
  // A LAS source: intensity, then its LAS attributes.
  CHECK(r.output.find("\"attributes\": [\"intensity\", \"classification\", ") != std::string::npos);
  CHECK(r.output.find("\"codec_params\": {\"decomposition\": ") != std::string::npos);
  CHECK(r.output.find("\"step\": [") != std::string::npos);
  CHECK(r.output.find("\"crs\": {\"name\": \"NAD83 / UTM zone 10N\", \"epsg\": 26910, \"wkt\": \"PROJCRS[") !=
        std::string::npos);

  const std::string plain = dir.file("plain.las");
  write_las(plain, "", "", 0);
  REQUIRE(cli("compress " + plain + " -o " + dir.file("p.relief") + " --quiet").code == 0);
  const auto p = cli("info " + dir.file("p.relief") + " --json");
  CHECK(p.output.find("\"crs\": null") != std::string::npos);
}

// ---- shared data: PDAL's LAS files with GeoTIFF CRSs

// The value of string field `key` of a small JSON object (the X.crs.json files).
std::string json_string_field(const std::string& json, const std::string& key) {
  const std::string tag = "\"" + key + "\": \"";
  std::size_t p = json.find(tag);
  if (p == std::string::npos) return "";
  std::string out;
  for (p += tag.size(); p < json.size() && json[p] != '"'; ++p) {
    if (json[p] == '\\' && p + 1 < json.size()) ++p;
    out += json[p];
  }
  return out;
}

TEST_CASE("shared data: GeoTIFF CRSs survive LAS -> archive -> LAS", "[crs][cli][shared-data]") {
  TempDir dir;
  for (const char* name : {"autzen-thin-srs", "interesting", "lots_of_vlr", "mvk-thin"}) {
    const auto las = test::shared_file(std::string("las-crs/") + name + ".las");
    const auto expected_json = test::shared_file(std::string("las-crs/") + name + ".crs.json");
    if (!las || !expected_json) continue;
    INFO(name);
    std::ifstream f(*expected_json);
    const std::string json((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    const std::string expected = json_string_field(json, "compoundwkt");
    REQUIRE_FALSE(expected.empty());

    CHECK(equivalent(read_info(*las).crs, expected));
    const std::string archive = dir.file(std::string(name) + ".relief");
    const std::string out = dir.file(std::string(name) + ".out.las");
    REQUIRE(cli("compress " + *las + " -o " + archive + " --quiet").code == 0);
    REQUIRE(cli("decompress " + archive + " -o " + out + " --quiet").code == 0);
    const PointStreamInfo back = read_info(out);
    CHECK(equivalent(back.crs, expected));
    CHECK(back.crs_source.rfind(kGeoTiffSourcePrefix, 0) == 0);  // written back as GeoTIFF keys
    // PDAL names some of them by the EPSG CRS they match, Relief by the
    // file's citation: the CRS is the same, the name need not be.
    const auto info = cli("info " + archive + " --json");
    CHECK(info.output.find("\"crs\": {\"name\": \"") != std::string::npos);
  }
}

}  // namespace
}  // namespace relief
