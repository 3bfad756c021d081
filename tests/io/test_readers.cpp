// Streaming readers: LAS files built here for every version and point format
// (with scale/offset, CRS records and extra bytes), XYZ/CSV column specs and
// delimiters, PCD ascii and binary, PLY in small batches against read_ply,
// the real shared LAS samples, and inputs that must be rejected cleanly.

#include <sys/stat.h>
#include <unistd.h>
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "relief/crs.h"
#include "relief/io.h"
#include "support/same_cloud.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"
#include "support/shared_data.h"

namespace fs = std::filesystem;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace relief {
using relief::test::TempDir;

namespace {

// ---------------------------------------------------------------- helpers


using test::write_file;

// Reads a whole stream in batches of `batch_size`, checking the batch
// contract on the way. Returns the status of the first failure.
Result<PointCloud> read_stream(PointReader& reader, std::size_t batch_size) {
  PointCloud all;
  PointCloud batch;
  for (;;) {
    Result<std::size_t> n = reader.read(batch, batch_size);
    if (!n.is_ok()) return n.status();
    REQUIRE(*n <= batch_size);
    REQUIRE(batch.size() == *n);
    REQUIRE(batch.colors.size() == (reader.info().has_colors ? *n : 0));
    REQUIRE(batch.intensities.size() == (reader.info().has_intensity ? *n : 0));
    if (*n == 0) break;
    all.positions.insert(all.positions.end(), batch.positions.begin(), batch.positions.end());
    all.colors.insert(all.colors.end(), batch.colors.begin(), batch.colors.end());
    all.intensities.insert(all.intensities.end(), batch.intensities.begin(), batch.intensities.end());
    all.las.extra_bytes_size = batch.las.extra_bytes_size;
    all.las.extra_bytes.insert(all.las.extra_bytes.end(), batch.las.extra_bytes.begin(), batch.las.extra_bytes.end());
  }
  return all;
}

Result<PointCloud> read_path(const std::string& path, std::size_t batch_size,
                             const ReaderOptions& options = {}) {
  Result<std::unique_ptr<PointReader>> r = open_point_reader(path, options);
  if (!r.is_ok()) return r.status();
  return read_stream(**r, batch_size);
}

// Exact comparison (bitwise for coordinates and intensities); reports the
// first mismatch only.
using relief::test::require_same;

void require_error(const Status& s, StatusCode code, const std::string& path,
                   const std::string& fragment = "") {
  INFO(s.to_string());
  REQUIRE_FALSE(s.is_ok());
  CHECK(s.code() == code);
  CHECK_THAT(s.message(), StartsWith(path + ": "));
  if (!fragment.empty()) CHECK_THAT(s.message(), Contains(fragment));
}

// Little-endian byte building for hand-made binary files.
class Bytes {
 public:
  template <typename T>
  Bytes& put(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (std::endian::native == std::endian::big) std::reverse(b, b + sizeof(T));
    out_.append(b, sizeof(T));
    return *this;
  }
  // A fixed-size, NUL-padded text field.
  Bytes& text(const std::string& s, std::size_t width) {
    std::string f = s.substr(0, width);
    f.resize(width, '\0');
    out_ += f;
    return *this;
  }
  Bytes& raw(const std::string& s) {
    out_ += s;
    return *this;
  }
  Bytes& zeros(std::size_t n) {
    out_.append(n, '\0');
    return *this;
  }
  std::size_t size() const { return out_.size(); }
  const std::string& str() const { return out_; }

 private:
  std::string out_;
};

// ---------------------------------------------------------------- LAS writer

struct LasPoint {
  std::int32_t x = 0, y = 0, z = 0;
  std::uint16_t intensity = 0;
  std::uint16_t r = 0, g = 0, b = 0;
};

struct LasRecord {
  std::string user_id;
  std::uint16_t record_id = 0;
  std::string payload;
};

struct LasSpec {
  int minor = 2;
  int format = 3;
  std::uint16_t extra_bytes = 0;
  Vec3d scale{0.01, 0.001, 0.25};
  Vec3d offset{484000.0, 6632000.0, -12.5};
  std::vector<LasPoint> points;
  std::vector<LasRecord> vlrs;
  std::vector<LasRecord> evlrs;  // 1.4 only
  std::size_t padding = 0;       // user bytes between the VLRs and the points
  std::optional<std::uint64_t> declared_count;
  std::uint8_t format_flags = 0;  // 0x80: the LAZ compression bit
};

constexpr std::array<std::size_t, 11> kLasMinLength = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
constexpr std::array<std::size_t, 11> kLasRgbOffset = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

std::string geokeys(const std::vector<std::array<std::uint16_t, 4>>& keys) {
  Bytes b;
  b.put<std::uint16_t>(1).put<std::uint16_t>(1).put<std::uint16_t>(0);
  b.put(static_cast<std::uint16_t>(keys.size()));
  for (const auto& k : keys) {
    for (const std::uint16_t w : k) b.put(w);
  }
  return b.str();
}

LasRecord wkt_record(const std::string& wkt) { return {"LASF_Projection", 2112, wkt + std::string(1, '\0')}; }
LasRecord geokey_record(const std::vector<std::array<std::uint16_t, 4>>& keys) {
  return {"LASF_Projection", 34735, geokeys(keys)};
}

std::string make_las(const LasSpec& s) {
  const std::size_t header_size = s.minor <= 2 ? 227 : s.minor == 3 ? 235 : 375;
  const std::size_t record_length = kLasMinLength[static_cast<std::size_t>(s.format)] + s.extra_bytes;
  std::size_t vlr_bytes = 0;
  for (const LasRecord& v : s.vlrs) vlr_bytes += 54 + v.payload.size();
  const std::size_t point_offset = header_size + vlr_bytes + s.padding;
  const std::uint64_t count = s.declared_count.value_or(s.points.size());
  const std::size_t evlr_start = point_offset + s.points.size() * record_length;

  Vec3d lo{1e300, 1e300, 1e300}, hi{-1e300, -1e300, -1e300};
  for (const LasPoint& p : s.points) {
    const Vec3d v{p.x * s.scale.x + s.offset.x, p.y * s.scale.y + s.offset.y, p.z * s.scale.z + s.offset.z};
    lo = {std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z)};
    hi = {std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z)};
  }

  Bytes b;
  b.raw("LASF").put<std::uint16_t>(7).put<std::uint16_t>(s.minor >= 4 ? 16 : 0);  // source id, WKT bit
  b.zeros(16);                                                                    // GUID
  b.put<std::uint8_t>(1).put(static_cast<std::uint8_t>(s.minor));
  b.text("relief test", 32).text("test_readers.cpp", 32);
  b.put<std::uint16_t>(42).put<std::uint16_t>(2024);
  b.put(static_cast<std::uint16_t>(header_size)).put(static_cast<std::uint32_t>(point_offset));
  b.put(static_cast<std::uint32_t>(s.vlrs.size()));
  b.put(static_cast<std::uint8_t>(s.format | s.format_flags)).put(static_cast<std::uint16_t>(record_length));
  const bool legacy = s.format < 6 && count <= 0xFFFFFFFFu;
  b.put(static_cast<std::uint32_t>(legacy ? count : 0));
  for (int i = 0; i < 5; ++i) b.put<std::uint32_t>(0);
  b.put(s.scale.x).put(s.scale.y).put(s.scale.z).put(s.offset.x).put(s.offset.y).put(s.offset.z);
  b.put(hi.x).put(lo.x).put(hi.y).put(lo.y).put(hi.z).put(lo.z);
  if (s.minor >= 3) b.put<std::uint64_t>(0);  // waveform data packets
  if (s.minor >= 4) {
    b.put(static_cast<std::uint64_t>(s.evlrs.empty() ? 0 : evlr_start));
    b.put(static_cast<std::uint32_t>(s.evlrs.size()));
    b.put(count);
    for (int i = 0; i < 15; ++i) b.put<std::uint64_t>(0);
  }
  REQUIRE(b.size() == header_size);
  for (const LasRecord& v : s.vlrs) {
    b.put<std::uint16_t>(0).text(v.user_id, 16).put(v.record_id);
    b.put(static_cast<std::uint16_t>(v.payload.size())).text("test record", 32).raw(v.payload);
  }
  b.zeros(s.padding);
  REQUIRE(b.size() == point_offset);
  const std::size_t rgb = kLasRgbOffset[static_cast<std::size_t>(s.format)];
  for (const LasPoint& p : s.points) {
    Bytes rec;
    rec.put(p.x).put(p.y).put(p.z).put(p.intensity);
    // Fill the fields that are not decoded with a pattern, so a wrong offset shows.
    while (rec.size() < record_length) rec.put<std::uint8_t>(static_cast<std::uint8_t>(0xA5 ^ rec.size()));
    std::string r = rec.str();
    if (rgb != 0) {
      for (int c = 0; c < 3; ++c) {
        const std::uint16_t level = c == 0 ? p.r : c == 1 ? p.g : p.b;
        r[rgb + 2 * c] = static_cast<char>(level & 0xFF);
        r[rgb + 2 * c + 1] = static_cast<char>(level >> 8);
      }
    }
    b.raw(r);
  }
  for (const LasRecord& v : s.evlrs) {
    b.put<std::uint16_t>(0).text(v.user_id, 16).put(v.record_id);
    b.put(static_cast<std::uint64_t>(v.payload.size())).text("test extended record", 32).raw(v.payload);
  }
  return b.str();
}

std::vector<LasPoint> las_points(std::size_t n, bool wide_colors) {
  std::vector<LasPoint> pts;
  test::Rng rng(n * 31 + 7);
  for (std::size_t i = 0; i < n; ++i) {
    LasPoint p;
    p.x = static_cast<std::int32_t>(rng.next() % 2000000) - 1000000;
    p.y = static_cast<std::int32_t>(rng.next());  // any 32-bit value
    p.z = static_cast<std::int32_t>(rng.next() % 4000) - 100;
    p.intensity = static_cast<std::uint16_t>(rng.next());
    const std::uint16_t range = wide_colors ? 65535 : 255;
    p.r = static_cast<std::uint16_t>(rng.next() % (range + 1u));
    p.g = static_cast<std::uint16_t>(rng.next() % (range + 1u));
    p.b = static_cast<std::uint16_t>(rng.next() % (range + 1u));
    pts.push_back(p);
  }
  if (wide_colors && n > 0) pts[0].r = 65535;  // at least one level above 255
  return pts;
}

PointCloud las_expected(const LasSpec& s, bool colors) {
  int shift = 0;
  for (const LasPoint& p : s.points) {
    if (std::max({p.r, p.g, p.b}) > 255) shift = 8;
  }
  PointCloud c;
  for (const LasPoint& p : s.points) {
    c.positions.push_back({static_cast<double>(p.x) * s.scale.x + s.offset.x,
                           static_cast<double>(p.y) * s.scale.y + s.offset.y,
                           static_cast<double>(p.z) * s.scale.z + s.offset.z});
    c.intensities.push_back(static_cast<float>(p.intensity));
    if (colors) {
      c.colors.push_back({static_cast<std::uint8_t>(p.r >> shift), static_cast<std::uint8_t>(p.g >> shift),
                          static_cast<std::uint8_t>(p.b >> shift)});
    }
  }
  return c;
}

// ---------------------------------------------------------------- LAS

TEST_CASE("LAS every version and point format reads back", "[io]") {
  const auto [minor, format] = GENERATE(table<int, int>({
      {0, 0},
      {0, 1},
      {0, 2},
      {0, 3},
      {2, 0},
      {2, 1},
      {2, 2},
      {2, 3},
      {3, 3},
      {4, 0},
      {4, 1},
      {4, 2},
      {4, 3},
      {4, 6},
      {4, 7},
      {4, 8},
      {4, 10},
  }));
  const std::uint16_t extra = GENERATE(std::uint16_t{0}, std::uint16_t{5});
  const bool wide = GENERATE(false, true);
  CAPTURE(minor, format, extra, wide);
  const bool colors = kLasRgbOffset[static_cast<std::size_t>(format)] != 0;

  LasSpec s;
  s.minor = minor;
  s.format = format;
  s.extra_bytes = extra;
  s.points = las_points(300, wide);
  // An Extra Bytes VLR (checked against the record length since the reader
  // keeps the extra bytes: `extra` undocumented bytes) or an unknown record.
  std::string descriptor(192, 'e');
  descriptor[2] = 0;
  descriptor[3] = static_cast<char>(extra);
  s.vlrs = {{"LASF_Spec", static_cast<std::uint16_t>(extra > 0 ? 4 : 7), descriptor},
            wkt_record("PROJCS[\"test\"]")};
  s.padding = 3;
  TempDir dir;
  const std::string path = dir.file("points.las");
  write_file(path, make_las(s));

  Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
  INFO(r.status().to_string());
  REQUIRE(r.is_ok());
  const PointStreamInfo& info = (*r)->info();
  CHECK(info.path == path);
  CHECK(info.format == "las");
  CHECK(info.point_count == std::optional<std::uint64_t>(300));
  CHECK(info.has_colors == colors);
  CHECK(info.has_intensity);
  CHECK(info.crs == "PROJCS[\"test\"]");
  CHECK(info.scale == s.scale);
  const PointCloud expected = las_expected(s, colors);
  REQUIRE(info.header_bounds.has_value());
  CHECK(info.header_bounds->min == expected.bounds().min);
  CHECK(info.header_bounds->max == expected.bounds().max);

  const std::size_t batch = GENERATE(std::size_t{1} << 20, std::size_t{7});
  CAPTURE(batch);
  const Result<PointCloud> got = read_stream(**r, batch);
  INFO(got.status().to_string());
  REQUIRE(got.is_ok());
  require_same(*got, expected);
}

TEST_CASE("LAS 16-bit colours are shifted only when the sample needs it", "[io]") {
  TempDir dir;
  LasSpec s;
  s.format = 2;
  s.points = las_points(100, false);
  SECTION("8-bit levels in 16-bit fields are kept") {
    write_file(dir.file("a.las"), make_las(s));
    for (const std::size_t batch : {std::size_t{1000}, std::size_t{3}}) {
      const Result<PointCloud> got = read_path(dir.file("a.las"), batch);
      REQUIRE(got.is_ok());
      require_same(*got, las_expected(s, true));
      CHECK(got->colors[5] == Rgb8{static_cast<std::uint8_t>(s.points[5].r),
                                   static_cast<std::uint8_t>(s.points[5].g),
                                   static_cast<std::uint8_t>(s.points[5].b)});
    }
  }
  SECTION("one level above 255 shifts every point, even before the first batch sees it") {
    s.points[97].b = 256;
    write_file(dir.file("b.las"), make_las(s));
    for (const std::size_t batch : {std::size_t{1000}, std::size_t{3}}) {
      const Result<PointCloud> got = read_path(dir.file("b.las"), batch);
      REQUIRE(got.is_ok());
      require_same(*got, las_expected(s, true));
      CHECK(got->colors[97].b == 1);
    }
  }
}

TEST_CASE("LAS coordinate reference systems", "[io]") {
  TempDir dir;
  const std::string path = dir.file("crs.las");
  auto open_las = [&](const LasSpec& s) {
    write_file(path, make_las(s));
    return open_point_reader(path);
  };
  auto info_of = [&](const LasSpec& s) {
    Result<std::unique_ptr<PointReader>> r = open_las(s);
    INFO(r.status().to_string());
    REQUIRE(r.is_ok());
    return (*r)->info();
  };
  auto crs_of = [&](const LasSpec& s) { return info_of(s).crs; };
  // The EPSG code of the WKT2 the reader made (0 when none).
  auto epsg_of = [&](const LasSpec& s) {
    const std::string crs = crs_of(s);
    Result<CrsSummary> d = describe_crs(crs, "test");
    INFO(crs);
    REQUIRE(d.is_ok());
    return d->epsg.value_or(0);
  };
  LasSpec s;
  s.format = 1;
  s.points = las_points(4, false);
  SECTION("none") { CHECK(crs_of(s).empty()); }
  SECTION("projected GeoTIFF code") {
    s.vlrs = {geokey_record({{1024, 0, 1, 1}, {1025, 0, 1, 1}, {3072, 0, 1, 32612}, {2048, 0, 1, 4326}})};
    CHECK(epsg_of(s) == 32612);
    CHECK_THAT(crs_of(s), StartsWith("PROJCRS[\"WGS 84 / UTM zone 12N\""));
    CHECK_THAT(info_of(s).crs_source, StartsWith("GeoTIFF VLRs: 34735="));
  }
  SECTION("geographic GeoTIFF code") {
    s.vlrs = {geokey_record({{1024, 0, 1, 2}, {2048, 0, 1, 4326}})};
    CHECK(epsg_of(s) == 4326);
  }
  SECTION("keys under a model type that names no CRS give none, with a warning") {
    s.vlrs = {geokey_record({{1025, 0, 1, 2}, {1024, 0, 1, 3}, {2048, 0, 1, 4326}})};
    const PointStreamInfo info = info_of(s);
    CHECK(info.crs.empty());
    REQUIRE(info.warnings.size() == 1);
    CHECK_THAT(info.warnings[0], Contains("name no coordinate reference system"));
  }
  SECTION("a key pointing at a GeoDoubleParams record the file lacks is refused") {
    s.vlrs = {geokey_record({{1024, 0, 1, 1}, {3072, 0, 1, 32767}, {3076, 34736, 1, 0}})};
    Result<std::unique_ptr<PointReader>> r = open_las(s);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kFormatError);
    CHECK_THAT(r.status().message(), Contains(path));
  }
  SECTION("a key count beyond the record is refused") {
    std::string keys = geokeys({{1024, 0, 1, 2}, {2048, 0, 1, 4267}});
    keys[6] = 99;  // NumberOfKeys
    s.vlrs = {{"LASF_Projection", 34735, keys}};
    Result<std::unique_ptr<PointReader>> r = open_las(s);
    REQUIRE_FALSE(r.is_ok());
    CHECK_THAT(r.status().message(), Contains(path) && Contains("declares 99 keys"));
  }
  SECTION("LAS 1.0-1.3: GeoTIFF keys win over a WKT VLR, in either order; WKT alone is used") {
    s.vlrs = {geokey_record({{1024, 0, 1, 1}, {3072, 0, 1, 2154}}), wkt_record("PROJCRS[\"RGF93 / Lambert-93\"]")};
    CHECK(epsg_of(s) == 2154);
    std::swap(s.vlrs[0], s.vlrs[1]);
    CHECK(epsg_of(s) == 2154);
    s.vlrs = {wkt_record("PROJCRS[\"not complete\"]")};
    const PointStreamInfo info = info_of(s);
    CHECK(info.crs == "PROJCRS[\"not complete\"]");  // PROJ cannot read it: kept as given
    REQUIRE(info.warnings.size() == 1);
    CHECK_THAT(info.warnings[0], Contains("kept as given"));
  }
  SECTION("LAS 1.4 extended VLRs after the points") {
    s.minor = 4;
    s.format = 6;
    s.vlrs = {geokey_record({{3072, 0, 1, 2154}})};
    s.evlrs = {{"other", 1, std::string(70000, 'x')}, wkt_record("GEOGCRS[\"from an EVLR\"]")};
    CHECK(crs_of(s) == "GEOGCRS[\"from an EVLR\"]");
    const Result<PointCloud> got = read_path(path, 2);
    REQUIRE(got.is_ok());
    require_same(*got, las_expected(s, false));
  }
  SECTION("records of other users are not read as a CRS") {
    s.vlrs = {{"LASF_Projectionx", 2112, "nope"}, {"Someone", 34735, geokeys({{3072, 0, 1, 1}})}};
    CHECK(crs_of(s).empty());
  }
}

TEST_CASE("LAS rejects a file truncated at any length", "[io]") {
  LasSpec s;
  s.minor = 4;
  s.format = 7;
  s.points = las_points(3, true);
  s.vlrs = {wkt_record("PROJCS[\"x\"]")};
  s.evlrs = {geokey_record({{3072, 0, 1, 2154}})};
  const std::string file = make_las(s);
  TempDir dir;
  const std::string path = dir.file("cut.las");
  write_file(path, file);
  REQUIRE(read_path(path, 100).is_ok());
  for (std::size_t len = 0; len < file.size(); ++len) {
    write_file(path, file.substr(0, len));
    const Result<PointCloud> r = read_path(path, 100);
    INFO("prefix length " << len);
    require_error(r.status(), StatusCode::kFormatError, path);
  }
}

TEST_CASE("LAS rejects lying and broken headers", "[io]") {
  TempDir dir;
  const std::string path = dir.file("bad.las");
  LasSpec s;
  s.format = 3;
  s.points = las_points(10, true);
  auto status_of = [&](const std::string& bytes) {
    write_file(path, bytes);
    return read_path(path, 1000).status();
  };
  SECTION("a count larger than the data") {
    s.declared_count = 11;
    require_error(status_of(make_las(s)), StatusCode::kFormatError, path,
                  "truncated: header declares 11 points but the file holds 10");
  }
  SECTION("a huge count is refused before anything is allocated") {
    s.minor = 4;
    s.declared_count = std::uint64_t{1} << 50;
    require_error(status_of(make_las(s)), StatusCode::kFormatError, path,
                  "header declares 1125899906842624 points but the file holds 10");
  }
  SECTION("a count larger than the data before the extended VLRs") {
    s.minor = 4;
    s.declared_count = 12;
    s.evlrs = {{"filler", 7, std::string(500, 'f')}};
    require_error(status_of(make_las(s)), StatusCode::kFormatError, path,
                  "truncated: header declares 12 points but the file holds 10");
  }
  SECTION("not a LAS file") {
    std::string bytes = make_las(s);
    bytes[0] = 'X';
    require_error(status_of(bytes), StatusCode::kFormatError, path, "LASF");
    require_error(status_of(""), StatusCode::kFormatError, path, "empty");
    require_error(status_of("LASF"), StatusCode::kFormatError, path, "truncated");
  }
  SECTION("LAZ compression bit without a LASzip VLR") {
    s.format_flags = 0x80;
    require_error(status_of(make_las(s)), StatusCode::kFormatError, path, "no LASzip VLR");
    s.format_flags = 0x40;
    require_error(status_of(make_las(s)), StatusCode::kFormatError, path, "no LASzip VLR");
  }
  SECTION("unsupported version and point format") {
    std::string bytes = make_las(s);
    bytes[24] = 2;
    require_error(status_of(bytes), StatusCode::kUnsupported, path, "version 2.2");
    bytes = make_las(s);
    bytes[104] = 11;
    require_error(status_of(bytes), StatusCode::kUnsupported, path, "point data format 11");
  }
  SECTION("record length shorter than the format") {
    std::string bytes = make_las(s);
    bytes[105] = 33;  // format 3 needs 34
    require_error(status_of(bytes), StatusCode::kFormatError, path, "record length 33");
  }
  SECTION("header size and point offset") {
    std::string bytes = make_las(s);
    bytes[94] = static_cast<char>(200);  // header size below 227
    require_error(status_of(bytes), StatusCode::kFormatError, path, "header size 200");
    bytes = make_las(s);
    bytes[96] = 100;  // offset to point data inside the header
    bytes[97] = 0;
    require_error(status_of(bytes), StatusCode::kFormatError, path, "offset to point data 100");
    bytes = make_las(s);
    bytes[99] = 0x7F;  // offset far beyond the end
    require_error(status_of(bytes), StatusCode::kFormatError, path, "truncated");
  }
  SECTION("a VLR running into the points") {
    s.vlrs = {wkt_record("PROJCS[\"x\"]")};
    std::string bytes = make_las(s);
    bytes[227 + 20] = static_cast<char>(0xFF);  // record length low byte
    require_error(status_of(bytes), StatusCode::kFormatError, path, "VLR 1 of 1");
    bytes = make_las(s);
    bytes[100] = 2;  // two VLRs declared, one present
    require_error(status_of(bytes), StatusCode::kFormatError, path, "VLR 2 of 2");
  }
  SECTION("scale zero or not finite") {
    std::string bytes = make_las(s);
    std::memset(bytes.data() + 131, 0, 8);
    require_error(status_of(bytes), StatusCode::kFormatError, path, "scale");
    bytes = make_las(s);
    const double inf = std::numeric_limits<double>::infinity();
    std::memcpy(bytes.data() + 163, &inf, 8);  // y offset
    require_error(status_of(bytes), StatusCode::kFormatError, path, "offset");
  }
}

TEST_CASE("LAS read from a pipe, where the size is unknown", "[io]") {
  LasSpec s;
  s.minor = 4;
  s.format = 8;
  s.points = las_points(60000, true);
  s.evlrs = {wkt_record("PROJCS[\"after the points\"]")};
  const std::string file = make_las(s);
  TempDir dir;
  const std::string fifo = dir.file("pipe.las");
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  std::signal(SIGPIPE, SIG_IGN);  // if the reader stops early the writer fails instead
  std::thread writer([&] { write_file(fifo, file); });
  Result<std::unique_ptr<PointReader>> r = open_point_reader(fifo);
  Result<PointCloud> got = r.is_ok() ? read_stream(**r, 25000) : Result<PointCloud>(r.status());
  r = Status(StatusCode::kInternal, "closed");  // closes the pipe before joining
  writer.join();
  INFO(got.status().to_string());
  REQUIRE(got.is_ok());
  require_same(*got, las_expected(s, true));  // the first batch holds levels > 255
}

TEST_CASE("LAS colour rule: a held sample reads as a second read does, and gives a pipe the whole sample", "[io]") {
  // 8-bit levels but one of 1000 at point 3000: past a batch of 1000 points,
  // within the rule's sample (the whole file), so the file is read as 16-bit
  // levels (shifted by 8).
  LasSpec s;
  s.format = 3;
  s.points = las_points(5000, false);
  s.points[3000].g = 1000;
  const std::string file = make_las(s);
  const PointCloud want = las_expected(s, true);
  REQUIRE(want.colors[3000].g == 3);
  TempDir dir;
  const std::string path = dir.file("late.las");
  write_file(path, file);
  ReaderOptions hold;
  hold.color_sample_memory = std::uint64_t{1} << 30;
  SECTION("a file: the sample held (decoded once), or not (decoded again to decide), the same points") {
    // 5000 * 64 - 1 bytes: one byte short of holding the sample.
    for (const std::uint64_t memory : {std::uint64_t{0}, hold.color_sample_memory, std::uint64_t{5000 * 64 - 1}}) {
      CAPTURE(memory);
      ReaderOptions o;
      o.color_sample_memory = memory;
      for (const std::size_t batch : {std::size_t{1}, std::size_t{999}, std::size_t{1000}, std::size_t{7000}}) {
        CAPTURE(batch);
        const Result<PointCloud> got = read_path(path, batch, o);
        REQUIRE(got.is_ok());
        require_same(*got, want);
      }
    }
  }
  SECTION("a pipe, which cannot be read twice: held, the whole sample decides; else the first batch") {
    for (const bool held : {true, false}) {
      CAPTURE(held);
      const std::string fifo = dir.file(held ? "held.las" : "first-batch.las");
      REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
      std::signal(SIGPIPE, SIG_IGN);
      std::thread writer([&] { write_file(fifo, file); });
      Result<std::unique_ptr<PointReader>> r = open_point_reader(fifo, held ? hold : ReaderOptions{});
      Result<PointCloud> got = r.is_ok() ? read_stream(**r, 1000) : Result<PointCloud>(r.status());
      std::vector<std::string> warnings;
      if (r.is_ok()) warnings = (*r)->info().warnings;
      r = Status(StatusCode::kInternal, "closed");  // closes the pipe before joining
      writer.join();
      INFO(got.status().to_string());
      REQUIRE(got.is_ok());
      if (held) {
        require_same(*got, want);
        CHECK(warnings.empty());
      } else {
        // The first 1000 points decided 8-bit levels: the late level is
        // kept beside its colour, with a warning naming it.
        CHECK(got->colors[0].r == s.points[0].r);
        std::uint8_t colour = 0, low = 0;
        relief::split_8bit_level(1000, colour, low);
        CHECK(got->colors[3000].g == colour);
        REQUIRE(warnings.size() == 1);
        CHECK_THAT(warnings[0], Catch::Matchers::Contains("point 3000 has the colour level 1000"));
      }
    }
  }
}

TEST_CASE("LAZ files go to the LAS reader", "[io]") {
  TempDir dir;
  const std::string path = dir.file("missing.LAZ");  // does not exist
  require_error(open_point_reader(path).status(), StatusCode::kIoError, path, "No such file");
  // An uncompressed LAS file named .laz reads as what it is.
  LasSpec s;
  s.format = 2;
  s.points = las_points(20, true);
  write_file(dir.file("plain.laz"), make_las(s));
  const Result<PointCloud> got = read_point_file(dir.file("plain.laz"));
  REQUIRE(got.is_ok());
  require_same(*got, las_expected(s, true));
}

// ---------------------------------------------------------------- real data

using relief::test::shared_file;

TEST_CASE("LAS reads the shared aerial tile exactly as its PLY conversion", "[io][shared-data]") {
  const auto las = shared_file("medium/orig/fr_aerial_rgb_698k.las");
  const auto ply = shared_file("medium/fr_aerial_rgb_698k.ply");
  if (!las || !ply) return;
  Result<std::unique_ptr<PointReader>> r = open_point_reader(*las);
  REQUIRE(r.is_ok());
  const PointStreamInfo& info = (*r)->info();
  CHECK(info.point_count == std::optional<std::uint64_t>(697721));
  CHECK(info.has_colors);
  CHECK(info.has_intensity);
  CHECK_THAT(info.crs, StartsWith("PROJCRS[\"RGF93 / Lambert-93\""));
  CHECK(info.scale == Vec3d{0.01, 0.01, 0.01});
  REQUIRE(info.header_bounds.has_value());
  CHECK(info.header_bounds->min.x == 484649.36);
  CHECK(info.header_bounds->max.y == 6632999.99);
  const Result<PointCloud> got = read_stream(**r, std::size_t{1} << 20);
  REQUIRE(got.is_ok());
  const Result<PointCloud> want = read_ply(*ply);
  REQUIRE(want.is_ok());
  require_same(*got, *want);  // coordinates, 16-bit colours >> 8 and intensity
  const auto [lo, hi] = std::minmax_element(got->intensities.begin(), got->intensities.end());
  CHECK(*lo == 311.0f);
  CHECK(*hi == 3004.0f);
}

TEST_CASE("LAS reads the shared terrestrial scan exactly as its PLY conversion", "[io][shared-data]") {
  const auto las = shared_file("medium/orig/lone_star_tls_519k.las");
  const auto ply = shared_file("medium/lone_star_tls_519k.ply");
  if (!las || !ply) return;
  Result<std::unique_ptr<PointReader>> r = open_point_reader(*las);
  REQUIRE(r.is_ok());
  const PointStreamInfo& info = (*r)->info();
  CHECK(info.point_count == std::optional<std::uint64_t>(518862));
  CHECK_FALSE(info.has_colors);
  // Its keys are 1025=2, 1024=3 (geocentric model), 2048=4326: no CRS that
  // libgeotiff and PROJ make of them (PROVENANCE: UTM zone 12N), so none.
  CHECK(info.crs.empty());
  CHECK(info.scale == Vec3d{0.00025, 0.00025, 0.00025});
  const Result<PointCloud> got = read_stream(**r, 100000);
  REQUIRE(got.is_ok());
  const Result<PointCloud> want = read_ply(*ply);
  REQUIRE(want.is_ok());
  require_same(*got, *want);
  const auto [lo, hi] = std::minmax_element(got->intensities.begin(), got->intensities.end());
  CHECK(*lo == 17.0f);
  CHECK(*hi == 2744.0f);
}

// ---------------------------------------------------------------- XYZ

PointCloud xyz_cloud(std::initializer_list<std::array<double, 3>> pts) {
  PointCloud c;
  for (const auto& p : pts) c.positions.push_back({p[0], p[1], p[2]});
  return c;
}

TEST_CASE("XYZ default columns, comments, blank lines and a header", "[io]") {
  TempDir dir;
  const std::string path = dir.file("plain.xyz");
  write_file(path,
             "# exported by hand\n"
             "X Y Z\n"
             "\n"
             "1.5 2.25 -3\n"
             "  // another comment\n"
             "484649.36\t6632629.73\t99.65   \r\n"
             "+7 8e2 -0.0 and more columns\n"
             "6.1 6.2 6.3");  // no final newline
  Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
  REQUIRE(r.is_ok());
  CHECK((*r)->info().format == "xyz");
  CHECK_FALSE((*r)->info().point_count.has_value());
  CHECK_FALSE((*r)->info().has_colors);
  CHECK_FALSE((*r)->info().has_intensity);
  const Result<PointCloud> got = read_stream(**r, 2);
  REQUIRE(got.is_ok());
  require_same(*got,
               xyz_cloud({{1.5, 2.25, -3}, {484649.36, 6632629.73, 99.65}, {7, 800, -0.0}, {6.1, 6.2, 6.3}}));
}

TEST_CASE("XYZ intensities a 32-bit float cannot give back are named once, when read", "[io]") {
  TempDir dir;
  ReaderOptions options;
  options.xyz_columns = "x,y,z,i";
  // Whole numbers, short decimals and values beyond float precision.
  const std::string exact = dir.file("exact.xyz");
  write_file(exact, "1 2 3 153\n2 3 4 0.1\n3 4 5 0.12345\n4 5 6 65535\n5 6 7 16777216\n");
  auto fine = open_point_reader(exact, options);
  REQUIRE(fine.is_ok());
  REQUIRE(read_stream(**fine, 2).is_ok());
  CHECK((*fine)->info().warnings.empty());
  const std::string rounded = dir.file("rounded.xyz");
  write_file(rounded, "1 2 3 153\n2 3 4 1234.5678901\n3 4 5 16777217\n");
  auto r = open_point_reader(rounded, options);
  REQUIRE(r.is_ok());
  CHECK((*r)->info().warnings.empty());  // known only once the line is read
  const Result<PointCloud> got = read_stream(**r, 2);
  REQUIRE(got.is_ok());
  CHECK(got->intensities[1] == 1234.5679f);
  REQUIRE((*r)->info().warnings.size() == 1);
  CHECK((*r)->info().warnings[0] == rounded + ": line 2: intensity 1234.5678901 is kept as the 32-bit float 1234.5679 "
                                              "(intensities are 32-bit floats: about 7 significant digits, integers "
                                              "exact up to 2^24); later ones are not listed");
}

TEST_CASE("XYZ column specs and delimiters", "[io]") {
  TempDir dir;
  PointCloud want = xyz_cloud({{1, 2, 3}, {4.5, -5.5, 6e-3}});
  want.colors = {{10, 20, 30}, {255, 0, 128}};
  want.intensities = {0.5f, 1200.0f};
  ReaderOptions o;
  o.xyz_columns = "x,y,z,r,g,b,i";
  SECTION("comma separated with a header, UTF-8 BOM and CRLF") {
    const std::string path = dir.file("a.csv");
    write_file(path,
               "\xEF\xBB\xBFx,y,z,red,green,blue,intensity\r\n1,2,3,10,20,30,0.5\r\n"
               "4.5, -5.5, 6e-3, 255, 0, 128, 1200\r\n");
    const Result<PointCloud> got = read_path(path, 100, o);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    require_same(*got, want);
  }
  SECTION("semicolons, reordered and skipped columns") {
    o.xyz_columns = "i;_,z, y ,x,b,g,r";  // the spec itself is comma separated
    const Result<std::unique_ptr<PointReader>> bad = open_point_reader(dir.file("b.txt"), o);
    REQUIRE_FALSE(bad.is_ok());
    CHECK(bad.status().code() == StatusCode::kInvalidArgument);
    o.xyz_columns = "i,_,z, y ,x,b,g,r";
    const std::string path = dir.file("b.txt");
    write_file(path, "0.5;99;3;2;1;30;20;10\n1200 ; x ; 6e-3;-5.5;4.5;128;0;255;extra\n");
    const Result<PointCloud> got = read_path(path, 1, o);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    require_same(*got, want);
  }
  SECTION("tabs and runs of spaces") {
    const std::string path = dir.file("c.xyz");
    write_file(path, "1\t2\t3\t10\t20\t30\t0.5\n   4.5    -5.5 \t 6e-3  255 0 128  1200  \n");
    const Result<PointCloud> got = read_path(path, 100, o);
    REQUIRE(got.is_ok());
    require_same(*got, want);
  }
  SECTION("a PTS file starts with its point count") {
    o.xyz_columns = "x,y,z,i,r,g,b";
    const std::string path = dir.file("d.PTS");
    write_file(path, "2\n1 2 3 0.5 10 20 30\n4.5 -5.5 6e-3 1200 255 0 128\n");
    const Result<PointCloud> got = read_path(path, 100, o);
    REQUIRE(got.is_ok());
    require_same(*got, want);
  }
  SECTION("invalid specs") {
    for (const char* spec : {"x,y", "x,y,z,r,g", "x,y,z,q", "x,x,y,z", "x,,y,z", ""}) {
      o.xyz_columns = spec;
      const Result<std::unique_ptr<PointReader>> r = open_point_reader(dir.file("e.xyz"), o);
      INFO(spec);
      require_error(r.status(), StatusCode::kInvalidArgument, dir.file("e.xyz"));
    }
  }
}

// The float64 extra field `field` (of `fields`, each 8 bytes) of point i.
double extra_double(const PointCloud& c, std::size_t i, std::size_t field, std::size_t fields) {
  double v = 0;
  REQUIRE(c.las.extra_bytes.size() >= 8 * fields * (i + 1));
  std::memcpy(&v, c.las.extra_bytes.data() + 8 * (fields * i + field), 8);
  return v;
}

TEST_CASE("Text without a header keeps the columns after x, y and z as extra bytes and says so", "[io]") {
  TempDir dir;
  const std::string path = dir.file("five.xyz");
  write_file(path, "1 2 3 0.5 -7\n4 5 6 1e3 8\n");
  for (const std::size_t batch : {std::size_t{1}, std::size_t{100}}) {
    Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
    REQUIRE(r.is_ok());
    const PointStreamInfo& info = (*r)->info();
    CHECK((info.las_attributes & kLasExtraBytes) != 0);
    CHECK(info.extra_bytes_size == 16);
    CHECK_FALSE(info.has_intensity);
    REQUIRE(info.warnings.size() == 1);
    CHECK(info.warnings[0] == path + ": no header line names its 5 columns, so after x, y and z columns 4 and 5 are "
                                     "kept as extra bytes (column_4 ...); --columns names them (x,y,z,i,r,g,b reads "
                                     "intensity and colour)");
    const Result<PointCloud> got = read_stream(**r, batch);
    REQUIRE(got.is_ok());
    REQUIRE(got->size() == 2);
    CHECK(extra_double(*got, 0, 0, 2) == 0.5);
    CHECK(extra_double(*got, 0, 1, 2) == -7.0);
    CHECK(extra_double(*got, 1, 0, 2) == 1000.0);
    CHECK(extra_double(*got, 1, 1, 2) == 8.0);
  }
  SECTION("a delimiter closing each line adds no column") {
    const std::string csv = dir.file("closed.csv");
    write_file(csv, "1,2,3,\n4,5,6,\n");
    Result<std::unique_ptr<PointReader>> r = open_point_reader(csv);
    REQUIRE(r.is_ok());
    CHECK((*r)->info().las_attributes == 0);
    CHECK((*r)->info().warnings.empty());
    REQUIRE(read_stream(**r, 10).is_ok());
  }
  SECTION("words are not kept, and the warning says so") {
    const std::string words = dir.file("words.txt");
    write_file(words, "1 2 3 wall 9\n4 5 6 roof 10\n");
    Result<std::unique_ptr<PointReader>> r = open_point_reader(words);
    REQUIRE(r.is_ok());
    CHECK((*r)->info().extra_bytes_size == 8);
    REQUIRE((*r)->info().warnings.size() == 1);
    CHECK_THAT((*r)->info().warnings[0], Contains("column 5 is kept as extra bytes (column_5) and the others are not kept"));
    const Result<PointCloud> got = read_stream(**r, 10);
    REQUIRE(got.is_ok());
    CHECK(extra_double(*got, 1, 0, 1) == 10.0);
  }
  SECTION("--no-extra-bytes keeps x, y and z, and says what it dropped") {
    ReaderOptions o;
    o.extra_bytes = false;
    Result<std::unique_ptr<PointReader>> r = open_point_reader(path, o);
    REQUIRE(r.is_ok());
    CHECK((*r)->info().las_attributes == 0);
    REQUIRE((*r)->info().warnings.size() == 1);
    CHECK_THAT((*r)->info().warnings[0], Contains("only x, y and z are kept (--no-extra-bytes)"));
    const Result<PointCloud> got = read_stream(**r, 10);
    REQUIRE(got.is_ok());
    require_same(*got, xyz_cloud({{1, 2, 3}, {4, 5, 6}}));
  }
}

TEST_CASE("PTS files: Leica's columns, a count before each block, counts checked", "[io]") {
  TempDir dir;
  SECTION("x y z intensity r g b, intensities signed as Leica's, in two blocks") {
    const std::string path = dir.file("scans.pts");
    write_file(path, "2\n1 2 3 -1200 10 20 30\n4.5 -5.5 6e-3 2047 255 0 128\n\n1\r\n7 8 9 -2048 1 2 3\n");
    PointCloud want = xyz_cloud({{1, 2, 3}, {4.5, -5.5, 6e-3}, {7, 8, 9}});
    want.colors = {{10, 20, 30}, {255, 0, 128}, {1, 2, 3}};
    want.intensities = {-1200.0f, 2047.0f, -2048.0f};
    for (const std::size_t batch : {std::size_t{1}, std::size_t{2}, std::size_t{100}}) {
      Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
      REQUIRE(r.is_ok());
      CHECK((*r)->info().has_colors);
      CHECK((*r)->info().has_intensity);
      CHECK((*r)->info().warnings.empty());
      const Result<PointCloud> got = read_stream(**r, batch);
      INFO(got.status().to_string());
      REQUIRE(got.is_ok());
      require_same(*got, want);
    }
  }
  SECTION("x y z intensity") {
    const std::string path = dir.file("four.pts");
    write_file(path, "2\n1 2 3 -5\n4 5 6 7\n");
    const Result<PointCloud> got = read_path(path, 100);
    REQUIRE(got.is_ok());
    PointCloud want = xyz_cloud({{1, 2, 3}, {4, 5, 6}});
    want.intensities = {-5.0f, 7.0f};
    require_same(*got, want);
  }
  SECTION("other column counts are kept as extra bytes, with a warning") {
    const std::string path = dir.file("five.pts");
    write_file(path, "1\n1 2 3 4 5\n");
    Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
    REQUIRE(r.is_ok());
    CHECK((*r)->info().extra_bytes_size == 16);
    REQUIRE((*r)->info().warnings.size() == 1);
    CHECK_THAT((*r)->info().warnings[0], Contains("as in a PTS file of 7 columns"));
  }
  SECTION("a count that does not match its block is an error naming both") {
    const std::string path = dir.file("bad.pts");
    write_file(path, "5\n1 2 3 4\n1 2 3 4\n");
    require_error(read_path(path, 100).status(), StatusCode::kFormatError, path,
                  "the PTS block whose count is on line 1 announces 5 points but the file ends after 2 of them "
                  "(a truncated file)");
    write_file(path, "1\n1 2 3 4\n1 2 3 4\n1\n1 2 3 4\n");
    require_error(read_path(path, 1).status(), StatusCode::kFormatError, path,
                  "line 4: the PTS block whose count is on line 1 announces 1 points but holds 2");
    write_file(path, "1\n1 2 3 4\n");
    ReaderOptions o;
    o.xyz_columns = "x,y,z,i";
    REQUIRE(read_path(path, 100, o).is_ok());
    write_file(path, "3\n1 2 3 4\n");
    require_error(read_path(path, 100, o).status(), StatusCode::kFormatError, path, "ends after 1 of them");
    write_file(path, "99999999999999999999999\n1 2 3\n");
    require_error(read_path(path, 100).status(), StatusCode::kFormatError, path,
                  "line 1: the PTS point count '99999999999999999999999' is out of range");
  }
}

// A PTX scan header: its grid and the 4 x 4 matrix by rows (the scanner's
// position and axes lines as a registered scanner's would be).
std::string ptx_header(int columns, int rows, const std::array<std::array<double, 4>, 4>& m) {
  std::string h = std::to_string(columns) + "\n" + std::to_string(rows) + "\n";
  h += "100 200 10\n0 1 0\n-1 0 0\n0 0 1\n";
  for (const auto& row : m) {
    for (int c = 0; c < 4; ++c) {
      char text[32];
      std::snprintf(text, sizeof text, "%.17g", row[c]);
      h += std::string(text) + (c < 3 ? " " : "\n");
    }
  }
  return h;
}

TEST_CASE("PTX scans: each scan's matrix applied, points without a return skipped", "[io]") {
  TempDir dir;
  // Scan 1: a quarter turn about z, then (100, 200, 10): (x, y, z) -> (100 - y, 200 + x, 10 + z).
  const std::array<std::array<double, 4>, 4> turn = {{{0, 1, 0, 0}, {-1, 0, 0, 0}, {0, 0, 1, 0}, {100, 200, 10, 1}}};
  const std::array<std::array<double, 4>, 4> identity = {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}, {0, 0, 0, 1}}};
  const std::string path = dir.file("site.PTX");
  write_file(path, ptx_header(2, 2, turn) +
                       "1.5 -2.25 0.5 0.5 10 20 30\n"
                       "0 0 0 0.5 0 0 0\n"
                       "\n"
                       "3 4 -1 0.125 255 0 128\r\n"
                       "0.25 0.5 2 1 1 2 3\n" +
                       ptx_header(0, 7, identity) +  // a scan without points
                       ptx_header(1, 1, identity) + "7 8 9 0.75 4 5 6\n");
  PointCloud want = xyz_cloud({{102.25, 201.5, 10.5}, {96, 203, 9}, {99.5, 200.25, 12}, {7, 8, 9}});
  want.colors = {{10, 20, 30}, {255, 0, 128}, {1, 2, 3}, {4, 5, 6}};
  want.intensities = {0.5f, 0.125f, 1.0f, 0.75f};
  for (const std::size_t batch : {std::size_t{1}, std::size_t{3}, std::size_t{100}}) {
    Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
    INFO(r.status().to_string());
    REQUIRE(r.is_ok());
    CHECK((*r)->info().format == "ptx");
    CHECK((*r)->info().has_colors);
    CHECK((*r)->info().has_intensity);
    CHECK_FALSE((*r)->info().point_count.has_value());
    const Result<PointCloud> got = read_stream(**r, batch);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    require_same(*got, want);
    CHECK((*r)->info().skipped_points == 1);
    CHECK((*r)->info().warnings.empty());
  }
  SECTION("without colour, and an empty file") {
    write_file(path, ptx_header(1, 2, identity) + "1 2 3 0.5\n4 5 6 0.25\n");
    const Result<PointCloud> got = read_path(path, 100);
    REQUIRE(got.is_ok());
    PointCloud plain = xyz_cloud({{1, 2, 3}, {4, 5, 6}});
    plain.intensities = {0.5f, 0.25f};
    require_same(*got, plain);
    write_file(path, "");
    const Result<PointCloud> none = read_path(path, 100);
    REQUIRE(none.is_ok());
    CHECK(none->size() == 0);
  }
  SECTION("malformed files are errors naming the line") {
    const auto status_of = [&](const std::string& text) {
      write_file(path, text);
      return read_path(path, 100).status();
    };
    const std::string head = ptx_header(1, 2, identity);
    require_error(status_of(head + "1 2 3 0.5\n"), StatusCode::kFormatError, path,
                  "the scan whose header is on line 1 has 2 points (1 x 2) but the file ends after 1 of them");
    require_error(status_of("3\n2\n0 0 0\n"), StatusCode::kFormatError, path,
                  "the scan header on line 1 ends before its the scanner's X axis");
    require_error(status_of("3.5\n2\n"), StatusCode::kFormatError, path,
                  "line 1: the scan's number of columns 3.5 is not a whole number");
    require_error(status_of("columns\n"), StatusCode::kFormatError, path, "line 1: expected number of columns");
    require_error(status_of(ptx_header(1, 1, {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0.5}, {0, 0, 0, 1}}}) +
                            "1 2 3 0.5\n"),
                  StatusCode::kFormatError, path, "line 9: the transformation matrix's fourth column must be 0 0 0 1");
    require_error(status_of(head + "1 2 3 0.5 1\n1 2 3 0.5\n"), StatusCode::kFormatError, path,
                  "line 11: a PTX point has 4 columns (x y z intensity) or 7 (with red green blue), not 5");
    require_error(status_of(head + "1 2 3 0.5\n1 2 3 0.5 1 2 3\n"), StatusCode::kFormatError, path,
                  "line 12: a point of this file has 4 columns, this line more");
    require_error(status_of(head + "1 2 3 0.5 1 2 3\n1 2 3 0.5 1 2 256\n"), StatusCode::kFormatError, path,
                  "line 12: colour level 256 is not a whole number 0..255");
    require_error(status_of(head + "1 2 3 0.5 1 2 3\n1 2 3 0.5 1 2.5 3\n"), StatusCode::kFormatError, path,
                  "line 12: colour level 2.5 is not a whole number 0..255");
    require_error(status_of(head + "1 2 3 0.5\n1 nan 3 0.5\n"), StatusCode::kFormatError, path,
                  "line 12: column 2 is not finite");
    require_error(status_of(head + "1 2 3 0.5\n1 two 3 0.5\n"), StatusCode::kFormatError, path,
                  "line 12: column 2 'two' is not a number");
    require_error(status_of(head + "1 2 3 0.5\n" + std::string(70000, '1') + "\n"), StatusCode::kFormatError, path,
                  "line 12: longer than 65536 bytes");
  }
}

TEST_CASE("XYZ rejects bad lines naming the line", "[io]") {
  TempDir dir;
  const std::string path = dir.file("bad.xyz");
  auto status_of = [&](const std::string& text, const std::string& columns = "x,y,z") {
    write_file(path, text);
    ReaderOptions o;
    o.xyz_columns = columns;
    return read_path(path, 100, o).status();
  };
  require_error(status_of("1 2 3\n\n4 5\n"), StatusCode::kFormatError, path,
                "line 3: expected at least 3 columns but found 2");
  require_error(status_of("1 2 3\n4 abc 6\n"), StatusCode::kFormatError, path,
                "line 2: column 2 'abc' is not a number");
  require_error(status_of("1,2,3\n4,,6\n"), StatusCode::kFormatError, path, "line 2: column 2 is empty");
  require_error(status_of("1 2 3\nnan 2 3\n"), StatusCode::kFormatError, path, "line 2: non-finite");
  require_error(status_of("1 2 3\n1 inf 3\n"), StatusCode::kFormatError, path, "line 2: non-finite");
  require_error(status_of("1 2 3\n1 2 1e999\n"), StatusCode::kFormatError, path, "line 2");
  require_error(status_of("1 2 3 0 0 65536\n", "x,y,z,r,g,b"), StatusCode::kFormatError, path,
                "line 1: colour level 65536 is outside 0..65535");
  require_error(status_of("1 2 3 0 -1 0\n", "x,y,z,r,g,b"), StatusCode::kFormatError, path,
                "line 1: colour level -1 is outside 0..65535");
  require_error(status_of("1 2 3 1e300\n", "x,y,z,i"), StatusCode::kFormatError, path, "line 1: intensity");
  // Only the first line may be a header.
  require_error(status_of("x y z\nalpha beta gamma\n"), StatusCode::kFormatError, path, "line 2");
  // European decimal commas with ';' separators are not silently split.
  require_error(status_of("1,5;2,5;3,5\n"), StatusCode::kFormatError, path, "line 1");
  const std::string missing = dir.file("missing.csv");
  require_error(read_path(missing, 10).status(), StatusCode::kIoError, missing, "No such file");
}

// ---------------------------------------------------------------- PCD

std::string pcd_header(const std::string& fields, const std::string& size, const std::string& type,
                       const std::string& count, std::size_t width, std::size_t height,
                       const std::string& data) {
  return "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS " + fields + "\nSIZE " + size +
         "\nTYPE " + type + "\nCOUNT " + count + "\nWIDTH " + std::to_string(width) + "\nHEIGHT " +
         std::to_string(height) + "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(width * height) +
         "\nDATA " + data + "\n";
}

std::uint32_t packed(std::uint8_t r, std::uint8_t g, std::uint8_t b) {
  return (std::uint32_t{r} << 16) | (std::uint32_t{g} << 8) | b;
}

TEST_CASE("PCD ascii with packed colour, intensity and a NaN point", "[io]") {
  TempDir dir;
  const std::string path = dir.file("scan.pcd");
  const float old_style = std::bit_cast<float>(packed(1, 2, 3));  // float printed by old writers
  char old_text[64];
  std::snprintf(old_text, sizeof old_text, "%.9g", static_cast<double>(old_style));
  write_file(path, pcd_header("x y z normal rgb intensity", "4 4 8 4 4 2", "F F F F F U", "1 1 1 3 1 1", 2, 2,
                              "ascii") +
                       "1.5 2.5 3.25 0 0 1 " + std::to_string(packed(10, 20, 30)) +
                       " 7\n"
                       "nan nan nan 0 0 0 0 0\n"
                       "\n"
                       "-1 -2 -3 0.1 0.2 0.3 " +
                       old_text +
                       " 65535\n"
                       "4 5 6 nan nan nan 4294967295 0\n");
  Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
  INFO(r.status().to_string());
  REQUIRE(r.is_ok());
  CHECK((*r)->info().format == "pcd");
  CHECK((*r)->info().point_count == std::optional<std::uint64_t>(4));
  CHECK((*r)->info().has_colors);
  CHECK((*r)->info().has_intensity);
  const Result<PointCloud> got = read_stream(**r, 2);
  INFO(got.status().to_string());
  REQUIRE(got.is_ok());
  PointCloud want = xyz_cloud({{1.5, 2.5, 3.25}, {-1, -2, -3}, {4, 5, 6}});
  want.colors = {{10, 20, 30}, {1, 2, 3}, {255, 255, 255}};
  want.intensities = {7, 65535, 0};
  require_same(*got, want);
  CHECK((*r)->info().skipped_points == 1);
}

std::string pcd_binary_body(const std::vector<std::array<float, 3>>& pts, bool with_rgb) {
  Bytes b;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    b.put(pts[i][0]).put(pts[i][1]).put(pts[i][2]);
    b.put<std::uint16_t>(0xBEEF).put<std::uint16_t>(0xCAFE);  // "label" with COUNT 2
    if (with_rgb) b.put(std::bit_cast<float>(packed(static_cast<std::uint8_t>(i), 100, 200)));
    b.put(static_cast<double>(i) * 0.25);  // intensity as F 8
  }
  return b.str();
}

TEST_CASE("PCD binary, organised with NaN pixels", "[io]") {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<std::array<float, 3>> pts = {{0.5f, 1.5f, -2.0f}, {nan, nan, nan}, {3, 4, 5},
                                                 {nan, 0, 0},         {nan, nan, nan}, {-1e6f, 2e-3f, 7}};
  const std::string file =
      pcd_header("x y z label rgb intensity", "4 4 4 2 4 8", "F F F U F F", "1 1 1 2 1 1", 3, 2, "binary") +
      pcd_binary_body(pts, true);
  TempDir dir;
  const std::string path = dir.file("organised.pcd");
  write_file(path, file);
  for (const std::size_t batch : {std::size_t{1}, std::size_t{2}, std::size_t{100}}) {
    Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
    REQUIRE(r.is_ok());
    const Result<PointCloud> got = read_stream(**r, batch);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    PointCloud want;
    want.positions = {{0.5f, 1.5f, -2.0f}, {3, 4, 5}, {-1e6f, 2e-3f, 7}};
    want.colors = {{0, 100, 200}, {2, 100, 200}, {5, 100, 200}};
    want.intensities = {0.0f, 0.5f, 1.25f};
    require_same(*got, want);
    CHECK((*r)->info().skipped_points == 3);
  }

  SECTION("truncated at any length") {
    const std::size_t header_end = file.find("DATA binary\n") + 12;
    for (std::size_t len = 0; len < file.size(); ++len) {
      write_file(path, file.substr(0, len));
      const Result<PointCloud> got = read_path(path, 100);
      INFO("prefix length " << len);
      require_error(got.status(), StatusCode::kFormatError, path);
      if (len >= header_end)
        CHECK_THAT(got.status().message(), Contains("truncated: header declares 6 points"));
    }
  }
}

TEST_CASE("PCD double coordinates, no colour, 0.6 header without COUNT", "[io]") {
  Bytes b;
  b.put(484649.36).put(6632629.73).put(99.65);
  b.put(-1.0).put(0.0).put(1e-300);
  const std::string file =
      "VERSION .6\nFIELDS x y z\nSIZE 8 8 8\nTYPE F F F\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n" +
      b.str();
  TempDir dir;
  const std::string path = dir.file("f8.pcd");
  write_file(path, file);
  const Result<PointCloud> got = read_path(path, 10);
  INFO(got.status().to_string());
  REQUIRE(got.is_ok());
  require_same(*got, xyz_cloud({{484649.36, 6632629.73, 99.65}, {-1.0, 0.0, 1e-300}}));
}

TEST_CASE("PCD rejects what it cannot read", "[io]") {
  TempDir dir;
  const std::string path = dir.file("bad.pcd");
  auto status_of = [&](const std::string& text) {
    write_file(path, text);
    return read_path(path, 100).status();
  };
  const std::string xyz_ascii = pcd_header("x y z", "4 4 4", "F F F", "1 1 1", 2, 1, "ascii");
  SECTION("binary_compressed") {
    require_error(status_of(pcd_header("x y z", "4 4 4", "F F F", "1 1 1", 2, 1, "binary_compressed") +
                            std::string(16, '\0')),
                  StatusCode::kFormatError, path,
                  "binary_compressed: uncompressed size 0 is not POINTS x point size = 2 x 12");
  }
  SECTION("truncated ascii body") {
    require_error(status_of(xyz_ascii + "1 2 3\n"), StatusCode::kFormatError, path,
                  "truncated: header declares 2 points but the data ends after 1");
  }
  SECTION("bad ascii values") {
    require_error(status_of(xyz_ascii + "1 2 3\n1 2\n"), StatusCode::kFormatError, path,
                  "point 1: expected 3 values but the line has 2");
    require_error(status_of(xyz_ascii + "1 2 3\n1 x 3\n"), StatusCode::kFormatError, path, "point 1: 'x'");
    require_error(status_of(xyz_ascii + "1 2 3\n1 inf 3\n"), StatusCode::kFormatError, path,
                  "point 1: non-finite coordinate");
  }
  SECTION("huge binary count is refused before reading") {
    require_error(
        status_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1000000000000\nHEIGHT 1\n"
                  "POINTS 1000000000000\nDATA binary\n" +
                  std::string(24, '\0')),
        StatusCode::kFormatError, path, "header declares 1000000000000 points but the data ends after 2");
  }
  SECTION("broken headers") {
    require_error(status_of(""), StatusCode::kFormatError, path, "empty");
    require_error(status_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\n"), StatusCode::kFormatError,
                  path, "DATA");
    require_error(status_of("FIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 1\nDATA ascii\n1 2\n"),
                  StatusCode::kFormatError, path, "'z'");
    require_error(status_of("FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nDATA ascii\n1 2 3\n"),
                  StatusCode::kFormatError, path, "SIZE");
    require_error(status_of("FIELDS x y z\nSIZE 2 4 4\nTYPE I F F\nWIDTH 1\nDATA ascii\n1 2 3\n"),
                  StatusCode::kFormatError, path, "'x'");
    require_error(
        status_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 3\nHEIGHT 2\nPOINTS 5\nDATA ascii\n"),
        StatusCode::kFormatError, path, "POINTS 5 differs");
    require_error(status_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 1\nFROB 1\nDATA ascii\n"),
                  StatusCode::kFormatError, path, "header line 5: unknown header keyword 'FROB'");
    require_error(status_of("FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 0 1\nWIDTH 1\nDATA ascii\n"),
                  StatusCode::kFormatError, path, "COUNT");
  }
}

// ---------------------------------------------------------------- PLY streaming

TEST_CASE("PLY streaming in small batches equals read_ply", "[io]") {
  test::SceneOptions o;
  o.points = 5000;
  o.colors = true;
  o.intensity = true;
  const PointCloud cloud = test::make_room(o, 8.0);
  const PlyEncoding enc =
      GENERATE(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian);
  CAPTURE(static_cast<int>(enc));
  TempDir dir;
  const std::string path = dir.file("stream.ply");
  REQUIRE(write_ply(path, cloud, {enc, PlyCoordinateType::kFloat64}).is_ok());
  const Result<PointCloud> whole = read_ply(path);
  REQUIRE(whole.is_ok());
  for (const std::size_t batch : {std::size_t{1}, std::size_t{7}, std::size_t{4096}, std::size_t{1} << 20}) {
    Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
    REQUIRE(r.is_ok());
    CHECK((*r)->info().format == "ply");
    CHECK((*r)->info().point_count == std::optional<std::uint64_t>(5000));
    CHECK((*r)->info().has_colors);
    CHECK((*r)->info().has_intensity);
    const Result<PointCloud> got = read_stream(**r, batch);
    REQUIRE(got.is_ok());
    require_same(*got, *whole);
  }
  const Result<PointCloud> via_dispatch = read_point_file(path);
  REQUIRE(via_dispatch.is_ok());
  require_same(*via_dispatch, *whole);
}

TEST_CASE("PLY streaming skips leading elements and stops after the vertices", "[io]") {
  const std::string file =
      "ply\nformat ascii 1.0\nelement camera 2\nproperty float a\nproperty list uchar int ids\n"
      "element vertex 3\nproperty double x\nproperty double y\nproperty double z\n"
      "property ushort red\nproperty ushort green\nproperty ushort blue\n"
      "element face 9\nproperty list uchar int vertex_indices\nend_header\n"
      "1 2 5 6\n2 0\n"
      "1 2 3 100 200 300\n4 5 6 65535 0 255\n7 8 9 0 0 0\n"
      "3 0 1 2\n";  // eight faces are missing
  TempDir dir;
  const std::string path = dir.file("mesh.ply");
  write_file(path, file);
  for (const std::size_t batch : {std::size_t{1}, std::size_t{100}}) {
    const Result<PointCloud> got = read_path(path, batch);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    PointCloud want = xyz_cloud({{1, 2, 3}, {4, 5, 6}, {7, 8, 9}});
    want.colors = {{0, 0, 1}, {255, 0, 0}, {0, 0, 0}};
    require_same(*got, want);
  }
  // The stream says the faces are cut short (a vertex count below the
  // records present shows so); the whole-file reader refuses the file.
  {
    auto reader = open_point_reader(path);
    REQUIRE(reader.is_ok());
    PointCloud batch;
    while (true) {
      auto n = (*reader)->read(batch, 100);
      REQUIRE(n.is_ok());
      if (*n == 0) break;
    }
    REQUIRE((*reader)->info().warnings.size() == 1);
    CHECK((*reader)->info().warnings[0].find("'face' elements") != std::string::npos);
  }
  require_error(read_ply(path).status(), StatusCode::kFormatError, path, "'face' elements");
}

TEST_CASE("PLY streaming reports truncated vertex data with the index", "[io]") {
  Bytes b;
  for (int i = 0; i < 5; ++i) b.put(1.0f * static_cast<float>(i)).put(2.0f).put(3.0f);
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 9\n"
      "property float x\nproperty float y\nproperty float z\nend_header\n";
  TempDir dir;
  const std::string path = dir.file("cut.ply");
  write_file(path, header + b.str());
  require_error(read_path(path, 2).status(), StatusCode::kFormatError, path,
                "truncated: header declares 9 vertices but the data ends after 5");
  write_file(path,
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
             "property float z\nend_header\n1 2 3\n4 5 6\n");
  require_error(read_path(path, 2).status(), StatusCode::kFormatError, path,
                "truncated: header declares 3 vertices but the data ends after 2");
  write_file(path,
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
             "property float z\nend_header\n1 2 3\n4 nan 6\n7 8 9\n");
  require_error(read_path(path, 1).status(), StatusCode::kFormatError, path, "vertex 1");
}

// ---------------------------------------------------------------- dispatch

TEST_CASE("open_point_reader dispatch, missing files and unknown extensions", "[io]") {
  TempDir dir;
  for (const char* name : {"a.ply", "b.LAS", "c.xyz", "d.txt", "e.csv", "f.pts", "g.Pcd", "h.laz"}) {
    const std::string path = dir.file(name);
    const Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
    INFO(name);
    require_error(r.status(), StatusCode::kIoError, path, "No such file");
  }
  for (const char* name : {"cloud.fls", "cloud", "cloud.ply.gz"}) {
    const std::string path = dir.file(name);
    const Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
    INFO(name);
    require_error(r.status(), StatusCode::kUnsupported, path, ".ply, .las, .laz, .xyz, .txt, .csv, .pts, .pcd");
    require_error(read_point_file(path).status(), StatusCode::kUnsupported, path);
  }
  // The format comes from the extension, not the contents.
  const std::string ply_named_las = dir.file("really-ply.las");
  REQUIRE(write_ply(ply_named_las, xyz_cloud({{1, 2, 3}})).is_ok());
  require_error(read_point_file(ply_named_las).status(), StatusCode::kFormatError, ply_named_las, "LASF");
}

TEST_CASE("read_point_file reads every format", "[io]") {
  TempDir dir;
  LasSpec s;
  s.format = 2;
  s.points = las_points(50, true);
  write_file(dir.file("a.las"), make_las(s));
  const Result<PointCloud> las = read_point_file(dir.file("a.las"));
  REQUIRE(las.is_ok());
  require_same(*las, las_expected(s, true));

  write_file(dir.file("b.xyz"), "1 2 3\n4 5 6\n");
  const Result<PointCloud> xyz = read_point_file(dir.file("b.xyz"));
  REQUIRE(xyz.is_ok());
  require_same(*xyz, xyz_cloud({{1, 2, 3}, {4, 5, 6}}));

  write_file(dir.file("c.pcd"),
             pcd_header("x y z", "4 4 4", "F F F", "1 1 1", 2, 1, "ascii") + "1 2 3\nnan 0 0\n");
  const Result<PointCloud> pcd = read_point_file(dir.file("c.pcd"));
  REQUIRE(pcd.is_ok());
  require_same(*pcd, xyz_cloud({{1, 2, 3}}));
}

}  // namespace
}  // namespace relief

TEST_CASE("TextLineParser: one line at a time, LAS dimensions by name, checked values", "[io][stream]") {
  auto parser = relief::TextLineParser::create("x,y,z,r,g,b,_,intensity,gps_time,c,scan_angle", "stdin");
  REQUIRE(parser.is_ok());
  const relief::TextLineParser& p = **parser;
  CHECK(p.colors());
  CHECK(p.intensity());
  CHECK(p.las_attributes() == (relief::kLasGpsTime | relief::kLasClassification | relief::kLasScanAngle));
  relief::PointCloud batch;
  // Any run of blanks, ',' and ';' separates columns; columns after the last
  // one named are ignored.
  REQUIRE(p.parse("1 2 3 10 20 30 skip 0.5 100.25 7 -12.5 extra", 1, batch).is_ok());
  REQUIRE(p.parse("4,5;6 , 255;0;1\t99\t2.5 1e5 31 90", 2, batch).is_ok());
  REQUIRE(batch.size() == 2);
  CHECK(batch.positions[1] == relief::Vec3d{4, 5, 6});
  CHECK(batch.colors[0].r == 10);
  CHECK(batch.colors[1].r == 255);
  CHECK(batch.intensities[1] == 2.5f);
  CHECK(batch.las.gps_time[1] == 1e5);
  CHECK(batch.las.classification[0] == 7);
  CHECK(batch.las.scan_angle[0] == -12500);  // thousandths of a degree
  // Errors name the input and the line, and leave the batch as it was.
  const struct {
    const char* line;
    const char* says;
  } bad[] = {
      {"1 2 3 10 20", "expected 11 columns, found 5"},
      {"1 2 3 10 20 256 0 0.5 1 7 0", "colour level 256 is outside 0..255"},
      {"1 2 3 10 20 30 0 0.5 1 256 0", "classification"},
      {"1 2 nan 10 20 30 0 0.5 1 7 0", "non-finite coordinate"},
      {"1 2 3 x 20 30 0 0.5 1 7 0", "column 4 'x' is not a number"},
      {"1 2 3 10 20 30 0 1e39 1 7 0", "intensity"},
      {"1 2 3 10 20 30 0 0.5 1 7 200", "scan angle"},
  };
  for (const auto& b : bad) {
    CAPTURE(b.line);
    const relief::Status s = p.parse(b.line, 9, batch);
    REQUIRE_FALSE(s.is_ok());
    CHECK(s.message().find("stdin: line 9: ") == 0);
    CHECK(s.message().find(b.says) != std::string::npos);
    CHECK(batch.size() == 2);
    CHECK(batch.las.gps_time.size() == 2);
  }
  CHECK_FALSE(relief::TextLineParser::create("x,y", "stdin").is_ok());
  CHECK_FALSE(relief::TextLineParser::create("x,y,z,x", "stdin").is_ok());
  CHECK_FALSE(relief::TextLineParser::create("x,y,z,r,g", "stdin").is_ok());
}

TEST_CASE("TextLineParser names the first intensity a float does not give back, once", "[io][stream]") {
  auto parser = relief::TextLineParser::create("x,y,z,i", "stdin");
  REQUIRE(parser.is_ok());
  relief::TextLineParser& p = **parser;
  relief::PointCloud batch;
  // Whole numbers up to 2^24 and decimals of up to 6 significant digits come back.
  REQUIRE(p.parse("1 2 3 153", 1, batch).is_ok());
  REQUIRE(p.parse("1 2 3 0.12345", 2, batch).is_ok());
  REQUIRE(p.parse("1 2 3 16777216", 3, batch).is_ok());
  CHECK(p.take_warnings().empty());
  // A refused line says nothing of its intensity.
  CHECK_FALSE(p.parse("1 2 nan 1234.5678901", 4, batch).is_ok());
  CHECK(p.take_warnings().empty());
  REQUIRE(p.parse("1 2 3 1234.5678901", 5, batch).is_ok());
  REQUIRE(p.parse("1 2 3 16777217", 6, batch).is_ok());
  CHECK(batch.intensities[3] == 1234.5679f);
  const std::vector<std::string> warnings = p.take_warnings();
  REQUIRE(warnings.size() == 1);
  CHECK(warnings[0] ==
        "stdin: line 5: intensity 1234.5678901 is kept as the 32-bit float 1234.5679 (intensities are 32-bit floats: "
        "about 7 significant digits, integers exact up to 2^24); later ones are not listed");
  CHECK(p.take_warnings().empty());  // taken out, and later ones not listed
  REQUIRE(p.parse("1 2 3 0.123456789", 7, batch).is_ok());
  CHECK(p.take_warnings().empty());
}

TEST_CASE("TextLineParser says once that a line has columns its spec does not name", "[io][stream]") {
  auto parser = relief::TextLineParser::create("x,y,z,_", "stdin");
  REQUIRE(parser.is_ok());
  relief::TextLineParser& p = **parser;
  relief::PointCloud batch;
  // The spec's trailing skip names the fourth column, and separators closing a line add none.
  REQUIRE(p.parse("1 2 3 4", 1, batch).is_ok());
  REQUIRE(p.parse("1,2,3,4,", 2, batch).is_ok());
  CHECK(p.take_warnings().empty());
  REQUIRE(p.parse("1 2 3 4 -1200 7", 3, batch).is_ok());
  REQUIRE(p.parse("1 2 3 4 5", 4, batch).is_ok());
  const std::vector<std::string> warnings = p.take_warnings();
  REQUIRE(warnings.size() == 1);
  CHECK(warnings[0] == "stdin: line 3 has 6 columns but --columns names 4: the others are not kept (name them, or _ "
                       "to skip them; later lines are not listed)");
  CHECK(batch.size() == 4);
}

namespace {

// Little-endian bytes of each value, in turn.
struct RecordBytes {
  std::vector<std::uint8_t> bytes;
  template <typename T>
  RecordBytes& put(T v) {
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    bytes.insert(bytes.end(), b, b + sizeof(T));
    return *this;
  }
};

}  // namespace

TEST_CASE("BinaryRecordParser: fields in the order listed, LAS dimensions typed, checked values", "[io][stream]") {
  auto parser = relief::BinaryRecordParser::create(
      "rgb,intensity,gps_time,_3,return_number,scan_angle,point_source_id,synthetic", "stdin");
  REQUIRE(parser.is_ok());
  const relief::BinaryRecordParser& p = **parser;
  CHECK(p.record_size() == 24 + 3 + 4 + 8 + 3 + 1 + 4 + 2 + 1);
  CHECK(p.colors());
  CHECK(p.intensity());
  CHECK(p.las_attributes() == (relief::kLasGpsTime | relief::kLasReturnNumber | relief::kLasScanAngle |
                               relief::kLasPointSourceId | relief::kLasClassFlags));
  const auto record = [](double z, std::uint8_t ret, float angle, float intensity) {
    RecordBytes r;
    r.put(1.5).put(-2.25).put(z);
    r.put(std::uint8_t{10}).put(std::uint8_t{20}).put(std::uint8_t{255});
    r.put(intensity).put(123456.789);
    r.put(std::uint8_t{0xAA}).put(std::uint8_t{0xBB}).put(std::uint8_t{0xCC});  // skipped
    r.put(ret).put(angle).put(std::uint16_t{65535}).put(std::uint8_t{1});
    return r.bytes;
  };
  relief::PointCloud batch;
  const std::vector<std::uint8_t> good = record(3, 2, -12.5f, 17);
  REQUIRE(good.size() == p.record_size());
  REQUIRE(p.parse(good.data(), 1, batch).is_ok());
  REQUIRE(batch.size() == 1);
  CHECK(batch.positions[0] == relief::Vec3d{1.5, -2.25, 3});
  CHECK(batch.colors[0].r == 10);
  CHECK(batch.colors[0].g == 20);
  CHECK(batch.colors[0].b == 255);
  CHECK(batch.intensities[0] == 17.0f);
  CHECK(batch.las.gps_time[0] == 123456.789);
  CHECK(batch.las.return_number[0] == 2);
  CHECK(batch.las.scan_angle[0] == -12500);  // thousandths of a degree
  CHECK(batch.las.point_source_id[0] == 65535);
  CHECK(batch.las.class_flags[0] == 1);  // synthetic is bit 0
  // Errors name the input and the record, and leave the batch as it was.
  const struct {
    std::vector<std::uint8_t> bytes;
    const char* says;
  } bad[] = {
      {record(std::nan(""), 2, 0, 1), "non-finite coordinate"},
      {record(3, 16, 0, 1), "return number 16"},
      {record(3, 2, 200, 1), "scan angle"},
      {record(3, 2, 0, std::numeric_limits<float>::infinity()), "intensity"},
  };
  for (const auto& b : bad) {
    CAPTURE(b.says);
    const relief::Status s = p.parse(b.bytes.data(), 7, batch);
    REQUIRE_FALSE(s.is_ok());
    CHECK(s.message().find("stdin: record 7: ") == 0);
    CHECK(s.message().find(b.says) != std::string::npos);
    CHECK(batch.size() == 1);
    CHECK(batch.las.gps_time.size() == 1);
  }
  // Extra fields: their bytes as they are, described by an Extra Bytes VLR.
  auto extra = relief::BinaryRecordParser::create("amplitude:f32,_1,ring:u16,classification", "stdin");
  REQUIRE(extra.is_ok());
  CHECK((*extra)->record_size() == 24 + 4 + 1 + 2 + 1);
  CHECK((*extra)->extra_bytes_size() == 6);
  CHECK((*extra)->las_attributes() == (relief::kLasExtraBytes | relief::kLasClassification));
  auto fields = relief::parse_extra_bytes_vlr(
      {reinterpret_cast<const std::uint8_t*>((*extra)->extra_bytes_vlr().data()), (*extra)->extra_bytes_vlr().size()},
      6, "test");
  REQUIRE(fields.is_ok());
  REQUIRE(fields->size() == 2);
  CHECK((*fields)[0].name == "amplitude");
  CHECK((*fields)[0].type_name == "float32");
  CHECK((*fields)[1].name == "ring");
  CHECK((*fields)[1].offset == 4);
  RecordBytes with;
  with.put(1.0).put(2.0).put(3.0).put(2.5f).put(std::uint8_t{0xEE}).put(std::uint16_t{513}).put(std::uint8_t{6});
  relief::PointCloud eb;
  REQUIRE((*extra)->parse(with.bytes.data(), 1, eb).is_ok());
  CHECK(eb.las.extra_bytes_size == 6);
  const std::vector<std::uint8_t> want_extra = {0x00, 0x00, 0x20, 0x40, 0x01, 0x02};  // 2.5f, 513
  CHECK(eb.las.extra_bytes == want_extra);
  CHECK(eb.las.classification == std::vector<std::uint8_t>{6});
  // No fields: x y z alone.
  auto bare = relief::BinaryRecordParser::create("", "stdin");
  REQUIRE(bare.is_ok());
  CHECK((*bare)->record_size() == 24);
  CHECK((*bare)->las_attributes() == 0);
  for (const char* spec : {"color", "rgb,rgb", "rgb,", "x", "r", "intensity,rgb", "_0", "_1025", "_x", "gps_time,gps_time",
                           "a:f16", "x:f32", ":u8", "a:u8,a:i8", "a_name_of_more_than_thirty_two_bytes:u8"}) {
    CAPTURE(spec);
    const auto r = relief::BinaryRecordParser::create(spec, "stdin");
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == relief::StatusCode::kInvalidArgument);
  }
}
