// Streaming writers: PLY in every encoding read back bit for bit, LAS 1.2 and
// 1.4 checked both through our reader and byte by byte at the offsets of the
// LAS specification, CRS records, scale and offset choice, XYZ/CSV and
// stdout, and the failure paths (atomic output, unwritable places, bad
// points, out-of-range coordinates, attribute mismatches).

#include <fcntl.h>
#include <unistd.h>
#include <catch2/catch.hpp>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "relief/crs.h"
#include "relief/io.h"
#include "io/point_writers.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"
#include "support/shared_data.h"

namespace fs = std::filesystem;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace relief {
namespace {

// ---------------------------------------------------------------- helpers

using relief::test::TempDir;

std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream f(path, std::ios::binary | std::ios::trunc);
  f << text;
}

// A little-endian field of a file held in memory.
template <typename T>
T field(const std::string& bytes, std::size_t offset) {
  REQUIRE(offset + sizeof(T) <= bytes.size());
  unsigned char b[sizeof(T)];
  std::memcpy(b, bytes.data() + offset, sizeof(T));
  if (std::endian::native == std::endian::big) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

std::string text_field(const std::string& bytes, std::size_t offset, std::size_t width) {
  std::string s = bytes.substr(offset, width);
  return s.substr(0, s.find('\0'));
}

WriterOptions options_with(bool colors, bool intensity) {
  WriterOptions o;
  o.colors = colors;
  o.intensity = intensity;
  return o;
}

// A georeferenced-looking cloud with every attribute, plus values that are
// hard to round-trip in text (negative zero, subnormals, extremes).
PointCloud sample_cloud(std::size_t n, bool colors, bool intensity, bool extremes) {
  test::SceneOptions o;
  o.points = n;
  o.colors = colors;
  o.intensity = intensity;
  o.seed = 7;
  o.offset = {484000.25, 6632000.5, 120.125};
  PointCloud c = test::make_terrain(o, 200.0, 5.0);
  if (extremes && n >= 8) {
    c.positions[1] = {-0.0, 0.1, 1.0 / 3.0};
    c.positions[2] = {std::numeric_limits<double>::denorm_min(), -1e-310, 5e-324};
    c.positions[3] = {std::numeric_limits<double>::max(), -std::numeric_limits<double>::max(), 1e300};
    c.positions[4] = {std::numeric_limits<double>::min(), 123456789.123456789, -987654321.0625};
    c.positions[5] = {0.30000000000000004, 2.2250738585072009e-308, 9007199254740993.0};
  }
  return c;
}

PointCloud slice(const PointCloud& c, std::size_t begin, std::size_t end) {
  PointCloud s;
  s.positions.assign(c.positions.begin() + static_cast<std::ptrdiff_t>(begin),
                     c.positions.begin() + static_cast<std::ptrdiff_t>(end));
  if (c.has_colors()) {
    s.colors.assign(c.colors.begin() + static_cast<std::ptrdiff_t>(begin),
                    c.colors.begin() + static_cast<std::ptrdiff_t>(end));
  }
  if (c.has_intensity()) {
    s.intensities.assign(c.intensities.begin() + static_cast<std::ptrdiff_t>(begin),
                         c.intensities.begin() + static_cast<std::ptrdiff_t>(end));
  }
  return s;
}

// Writes `cloud` through a new writer in batches of the given sizes (the last
// one repeats until the cloud is done), then finishes.
Status write_batches(const std::string& path, const WriterOptions& options, const PointCloud& cloud,
                     const std::vector<std::size_t>& sizes = {1, 0, 7, 1000, 4096}) {
  Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, options);
  if (!w.is_ok()) return w.status();
  std::size_t at = 0;
  std::size_t k = 0;
  while (at < cloud.size()) {
    const std::size_t n = std::min(sizes[std::min(k++, sizes.size() - 1)], cloud.size() - at);
    RELIEF_RETURN_IF_ERROR((*w)->write(slice(cloud, at, at + n)));
    at += n;
  }
  REQUIRE((*w)->points_written() == cloud.size());
  return (*w)->finish();
}

struct ReadBack {
  PointStreamInfo info;
  PointCloud cloud;
};

ReadBack read_back(const std::string& path, const ReaderOptions& options = {}) {
  Result<std::unique_ptr<PointReader>> r = open_point_reader(path, options);
  INFO(r.status().to_string());
  REQUIRE(r.is_ok());
  ReadBack out;
  out.info = (*r)->info();
  PointCloud batch;
  for (;;) {
    Result<std::size_t> n = (*r)->read(batch, 3000);
    INFO(n.status().to_string());
    REQUIRE(n.is_ok());
    if (*n == 0) break;
    out.cloud.positions.insert(out.cloud.positions.end(), batch.positions.begin(), batch.positions.end());
    out.cloud.colors.insert(out.cloud.colors.end(), batch.colors.begin(), batch.colors.end());
    out.cloud.intensities.insert(out.cloud.intensities.end(), batch.intensities.begin(),
                                 batch.intensities.end());
  }
  return out;
}

bool same_bits(double a, double b) { return std::bit_cast<std::uint64_t>(a) == std::bit_cast<std::uint64_t>(b); }
bool same_bits(float a, float b) { return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b); }

// Bitwise equality of everything; reports the first mismatch only.
void require_identical(const PointCloud& got, const PointCloud& want) {
  REQUIRE(got.size() == want.size());
  REQUIRE(got.colors.size() == want.colors.size());
  REQUIRE(got.intensities.size() == want.intensities.size());
  for (std::size_t i = 0; i < want.size(); ++i) {
    const Vec3d& g = got.positions[i];
    const Vec3d& w = want.positions[i];
    const bool ok = same_bits(g.x, w.x) && same_bits(g.y, w.y) && same_bits(g.z, w.z) &&
                    (!want.has_colors() || got.colors[i] == want.colors[i]) &&
                    (!want.has_intensity() || same_bits(got.intensities[i], want.intensities[i]));
    if (ok) continue;
    INFO("point " << i << ": got (" << g.x << ", " << g.y << ", " << g.z << ") want (" << w.x << ", " << w.y
                  << ", " << w.z << ")");
    FAIL("point mismatch");
  }
}

void require_error(const Status& s, StatusCode code, const std::string& path, const std::string& fragment = "") {
  INFO(s.to_string());
  REQUIRE_FALSE(s.is_ok());
  CHECK(s.code() == code);
  CHECK_THAT(s.message(), StartsWith(path + ": "));
  if (!fragment.empty()) CHECK_THAT(s.message(), Contains(fragment));
}

std::uint16_t expected_intensity(float v) {
  if (!(v > 0)) return 0;
  if (v >= 65535) return 65535;
  return static_cast<std::uint16_t>(std::floor(v + 0.5f));
}

// ---------------------------------------------------------------- PLY

TEST_CASE("PLY streaming writer output equals read_ply bit for bit in every encoding", "[io]") {
  TempDir dir;
  for (const PlyEncoding enc : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian,
                                PlyEncoding::kAscii}) {
    for (const auto& [colors, intensity] : {std::pair{false, false}, std::pair{true, false},
                                            std::pair{false, true}, std::pair{true, true}}) {
      INFO("encoding " << static_cast<int>(enc) << " colors " << colors << " intensity " << intensity);
      const PointCloud cloud = sample_cloud(12345, colors, intensity, true);
      WriterOptions o = options_with(colors, intensity);
      o.ply_encoding = enc;
      const std::string path = dir.file("out.ply");
      const Status s = write_batches(path, o, cloud);
      INFO(s.to_string());
      REQUIRE(s.is_ok());
      const std::string bytes = slurp(path);
      CHECK_THAT(bytes, Contains("element vertex 00000000000000012345\n"));
      const Result<PointCloud> back = read_ply(path);
      INFO(back.status().to_string());
      REQUIRE(back.is_ok());
      require_identical(*back, cloud);
      // The streaming reader agrees, and reports the attributes.
      const ReadBack r = read_back(path);
      CHECK(r.info.point_count == std::optional<std::uint64_t>(12345));
      CHECK(r.info.has_colors == colors);
      CHECK(r.info.has_intensity == intensity);
      CHECK(dir.entries() == std::vector<std::string>{"out.ply"});
    }
  }
}

TEST_CASE("PLY binary big endian stores the bytes swapped", "[io]") {
  TempDir dir;
  PointCloud c;
  c.positions = {{1.0, -2.0, 0.5}};
  c.intensities = {3.0f};
  WriterOptions o = options_with(false, true);
  o.ply_encoding = PlyEncoding::kBinaryBigEndian;
  const std::string path = dir.file("be.ply");
  REQUIRE(write_batches(path, o, c).is_ok());
  const std::string bytes = slurp(path);
  const std::size_t body = bytes.find("end_header\n") + 11;
  REQUIRE(bytes.size() == body + 28);
  // 1.0 is 3FF0000000000000, big endian first byte 0x3F.
  CHECK(static_cast<unsigned char>(bytes[body]) == 0x3F);
  CHECK(static_cast<unsigned char>(bytes[body + 1]) == 0xF0);
  // 3.0f is 40400000.
  CHECK(static_cast<unsigned char>(bytes[body + 24]) == 0x40);
  CHECK(static_cast<unsigned char>(bytes[body + 25]) == 0x40);
}

// ---------------------------------------------------------------- LAS

// The warnings of writing `intensities` (at x = 0, 1, ...) to `path` in
// batches of `batch` points.
std::vector<std::string> intensity_warnings(const std::string& path, const std::vector<float>& intensities,
                                            std::size_t batch) {
  PointCloud cloud;
  for (std::size_t i = 0; i < intensities.size(); ++i) cloud.positions.push_back({static_cast<double>(i), 0, 0});
  cloud.intensities = intensities;
  Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, options_with(false, true));
  REQUIRE(w.is_ok());
  for (std::size_t at = 0; at < cloud.size(); at += batch) {
    REQUIRE((*w)->write(slice(cloud, at, std::min(at + batch, cloud.size()))).is_ok());
  }
  CHECK((*w)->take_warnings().empty());  // said once the file is complete
  REQUIRE((*w)->finish().is_ok());
  return (*w)->take_warnings();
}

TEST_CASE("LAS output says which intensities it clamped or rounded", "[io]") {
  TempDir dir;
  for (const char* name : {"out.las", "out.laz"}) {
    const std::string path = dir.file(name);
    INFO(path);
    std::vector<std::string> said = intensity_warnings(path, {7, -1200, 12.5f, 70000, -3, 9.25f}, 2);
    REQUIRE(said.size() == 2);
    CHECK(said[0] == path + ": 3 intensities outside LAS's 0..65535 were clamped to it (the first: -1200)");
    CHECK(said[1] == path + ": 2 intensities with a fraction were rounded to a whole number (the first: 12.5): LAS "
                            "keeps whole numbers 0..65535, or 0..1 scaled to them when every intensity of the file "
                            "is within 0..1");
    const ReadBack r = read_back(path);
    CHECK(r.cloud.intensities == std::vector<float>{7, 0, 13, 65535, 0, 9});
    // Whole numbers in range, and a file within 0..1 (scaled to 16 bits), lose nothing.
    CHECK(intensity_warnings(path, {65535, 0, 12}, 1).empty());
    CHECK(intensity_warnings(path, {0.25f, 1, 0.5f}, 3).empty());
    said = intensity_warnings(path, {-1}, 1);
    REQUIRE(said.size() == 1);
    CHECK(said[0] == path + ": 1 intensity outside LAS's 0..65535 was clamped to it (the first: -1)");
  }
  // Written within 0..1 and then not (LAS only: LAZ refuses): the fractions before count too.
  const std::string path = dir.file("late.las");
  const std::vector<std::string> said = intensity_warnings(path, {0.25f, 0.5f, 3.5f}, 2);
  REQUIRE(said.size() == 1);
  CHECK_THAT(said[0], Contains("3 intensities with a fraction were rounded to a whole number (the first: 0.25)"));
  // PLY and text keep the floats as they are.
  CHECK(intensity_warnings(dir.file("out.ply"), {-1200, 0.25f}, 1).empty());
  CHECK(intensity_warnings(dir.file("out.csv"), {-1200, 0.25f}, 1).empty());
}

TEST_CASE("LAS 1.2 round trip: coordinates within half the scale, colours, intensity, header", "[io]") {
  TempDir dir;
  PointCloud cloud = sample_cloud(20000, true, true, false);
  // Intensity rule: clamp to [0, 65535], round to nearest.
  cloud.intensities[0] = -3.2f;
  cloud.intensities[1] = 70000.0f;
  cloud.intensities[2] = 12.4f;
  cloud.intensities[3] = 12.5f;
  cloud.intensities[4] = 65534.7f;
  cloud.colors[0] = {0, 1, 255};
  const std::string path = dir.file("out.las");
  const Status s = write_batches(path, options_with(true, true), cloud);
  INFO(s.to_string());
  REQUIRE(s.is_ok());
  CHECK(dir.entries() == std::vector<std::string>{"out.las"});

  const ReadBack r = read_back(path);
  CHECK(r.info.format == "las");
  CHECK(r.info.point_count == std::optional<std::uint64_t>(cloud.size()));
  CHECK(r.info.has_colors);
  CHECK(r.info.has_intensity);
  CHECK(r.info.crs.empty());
  CHECK(r.info.scale == Vec3d{1e-4, 1e-4, 1e-4});
  REQUIRE(r.cloud.size() == cloud.size());
  Box3d decoded;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3d& g = r.cloud.positions[i];
    const Vec3d& w = cloud.positions[i];
    INFO("point " << i);
    REQUIRE(std::abs(g.x - w.x) <= 0.5e-4 * (1 + 1e-9));
    REQUIRE(std::abs(g.y - w.y) <= 0.5e-4 * (1 + 1e-9));
    REQUIRE(std::abs(g.z - w.z) <= 0.5e-4 * (1 + 1e-9));
    REQUIRE(r.cloud.colors[i] == cloud.colors[i]);
    REQUIRE(r.cloud.intensities[i] == static_cast<float>(expected_intensity(cloud.intensities[i])));
    decoded.add(g);
  }
  CHECK(r.cloud.intensities[0] == 0.0f);
  CHECK(r.cloud.intensities[1] == 65535.0f);
  CHECK(r.cloud.intensities[2] == 12.0f);
  CHECK(r.cloud.intensities[3] == 13.0f);
  CHECK(r.cloud.intensities[4] == 65535.0f);
  // Header bounds are those of the stored (quantised) coordinates.
  REQUIRE(r.info.header_bounds.has_value());
  CHECK(r.info.header_bounds->min == decoded.min);
  CHECK(r.info.header_bounds->max == decoded.max);

  // Field by field at the LAS 1.2 offsets.
  const std::string b = slurp(path);
  REQUIRE(b.size() == 227 + cloud.size() * 26);
  CHECK(b.substr(0, 4) == "LASF");
  CHECK(field<std::uint16_t>(b, 4) == 0);  // file source id
  CHECK(field<std::uint16_t>(b, 6) == 0);  // global encoding
  CHECK(b.substr(8, 16) == std::string(16, '\0'));  // GUID
  CHECK(b[24] == 1);
  CHECK(b[25] == 2);
  CHECK(text_field(b, 26, 32) == "Relief");
  CHECK_THAT(text_field(b, 58, 32), StartsWith("relief "));
  const auto day = field<std::uint16_t>(b, 90);
  const auto year = field<std::uint16_t>(b, 92);
  CHECK(day >= 1);
  CHECK(day <= 366);
  CHECK(year >= 2024);
  CHECK(year < 2200);
  CHECK(field<std::uint16_t>(b, 94) == 227);
  CHECK(field<std::uint32_t>(b, 96) == 227);
  CHECK(field<std::uint32_t>(b, 100) == 0);
  CHECK(static_cast<unsigned char>(b[104]) == 2);
  CHECK(field<std::uint16_t>(b, 105) == 26);
  CHECK(field<std::uint32_t>(b, 107) == cloud.size());
  CHECK(field<std::uint32_t>(b, 111) == cloud.size());
  for (std::size_t k = 1; k < 5; ++k) CHECK(field<std::uint32_t>(b, 111 + 4 * k) == 0);
  for (std::size_t a = 0; a < 3; ++a) CHECK(field<double>(b, 131 + 8 * a) == 1e-4);
  // Offsets are whole metres at 0.1 mm, at or below the first batch (here
  // its single point: later points may lie below it).
  const Vec3d offset{field<double>(b, 155), field<double>(b, 163), field<double>(b, 171)};
  CHECK(offset.x == std::floor(cloud.positions[0].x));
  CHECK(offset.y == std::floor(cloud.positions[0].y));
  CHECK(offset.z == std::floor(cloud.positions[0].z));
  CHECK(field<double>(b, 179) == decoded.max.x);
  CHECK(field<double>(b, 187) == decoded.min.x);
  CHECK(field<double>(b, 195) == decoded.max.y);
  CHECK(field<double>(b, 203) == decoded.min.y);
  CHECK(field<double>(b, 211) == decoded.max.z);
  CHECK(field<double>(b, 219) == decoded.min.z);
  // First record: X Y Z, intensity, return 1 of 1, classification 0, RGB * 257.
  const std::size_t rec = 227;
  CHECK(field<std::int32_t>(b, rec) == static_cast<std::int32_t>(std::lround((cloud.positions[0].x - offset.x) * 1e4)));
  CHECK(field<std::uint16_t>(b, rec + 12) == 0);
  CHECK(static_cast<unsigned char>(b[rec + 14]) == 0x09);
  CHECK(b[rec + 15] == 0);
  CHECK(field<std::uint16_t>(b, rec + 20) == 0);
  CHECK(field<std::uint16_t>(b, rec + 22) == 257);
  CHECK(field<std::uint16_t>(b, rec + 24) == 65535);
}

TEST_CASE("LAS 1.2 without colours uses point format 0", "[io]") {
  TempDir dir;
  const PointCloud cloud = sample_cloud(500, false, false, false);
  const std::string path = dir.file("plain.las");
  REQUIRE(write_batches(path, {}, cloud).is_ok());
  const std::string b = slurp(path);
  CHECK(b[104] == 0);
  CHECK(field<std::uint16_t>(b, 105) == 20);
  CHECK(b.size() == 227 + 500 * 20);
  const ReadBack r = read_back(path);
  CHECK_FALSE(r.info.has_colors);
  REQUIRE(r.cloud.size() == 500);
  for (std::size_t i = 0; i < 500; ++i) REQUIRE(std::abs(r.cloud.positions[i].z - cloud.positions[i].z) <= 0.5e-4);
  // No intensity given: the field is 0.
  CHECK(std::all_of(r.cloud.intensities.begin(), r.cloud.intensities.end(), [](float v) { return v == 0; }));
}

const std::string kWkt =
    "PROJCS[\"RGF93 / Lambert-93\",GEOGCS[\"RGF93\",DATUM[\"Reseau_Geodesique_Francais_1993\","
    "SPHEROID[\"GRS 1980\",6378137,298.257222101]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],"
    "PROJECTION[\"Lambert_Conformal_Conic_2SP\"],PARAMETER[\"standard_parallel_1\",49],"
    "PARAMETER[\"standard_parallel_2\",44],PARAMETER[\"latitude_of_origin\",46.5],"
    "PARAMETER[\"central_meridian\",3],PARAMETER[\"false_easting\",700000],"
    "PARAMETER[\"false_northing\",6600000],UNIT[\"metre\",1],AUTHORITY[\"EPSG\",\"2154\"]]";

TEST_CASE("LAS 1.4 with a WKT CRS: formats 7 and 6, WKT VLR, 64-bit counts", "[io]") {
  TempDir dir;
  for (const bool colors : {true, false}) {
    INFO("colors " << colors);
    const PointCloud cloud = sample_cloud(3000, colors, true, false);
    WriterOptions o = options_with(colors, true);
    o.crs = kWkt;
    const std::string path = dir.file("wkt.las");
    REQUIRE(write_batches(path, o, cloud).is_ok());
    const ReadBack r = read_back(path);
    CHECK(r.info.crs_source == kWkt);  // the WKT VLR holds the text as given
    CHECK(r.info.has_colors == colors);
    REQUIRE(r.cloud.size() == cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      REQUIRE(std::abs(r.cloud.positions[i].x - cloud.positions[i].x) <= 0.5e-4 * (1 + 1e-9));
      if (colors) REQUIRE(r.cloud.colors[i] == cloud.colors[i]);
    }

    const std::string b = slurp(path);
    const std::size_t record = colors ? 36 : 30;
    const std::size_t vlr = 54 + kWkt.size() + 1;
    CHECK(b[24] == 1);
    CHECK(b[25] == 4);
    CHECK((field<std::uint16_t>(b, 6) & 16) != 0);  // WKT bit
    CHECK(field<std::uint16_t>(b, 94) == 375);
    CHECK(field<std::uint32_t>(b, 96) == 375 + vlr);
    CHECK(field<std::uint32_t>(b, 100) == 1);
    CHECK(static_cast<int>(b[104]) == (colors ? 7 : 6));
    CHECK(field<std::uint16_t>(b, 105) == record);
    // Formats 6-10 are not legacy compatible: the legacy counts are 0.
    CHECK(field<std::uint32_t>(b, 107) == 0);
    CHECK(field<std::uint32_t>(b, 111) == 0);
    CHECK(field<std::uint64_t>(b, 227) == 0);  // waveform data
    CHECK(field<std::uint64_t>(b, 235) == 0);  // first EVLR
    CHECK(field<std::uint32_t>(b, 243) == 0);  // EVLR count
    CHECK(field<std::uint64_t>(b, 247) == cloud.size());
    CHECK(field<std::uint64_t>(b, 255) == cloud.size());
    for (std::size_t k = 1; k < 15; ++k) CHECK(field<std::uint64_t>(b, 255 + 8 * k) == 0);
    // The VLR right after the header.
    CHECK(field<std::uint16_t>(b, 375) == 0);
    CHECK(text_field(b, 377, 16) == "LASF_Projection");
    CHECK(field<std::uint16_t>(b, 393) == 2112);
    CHECK(field<std::uint16_t>(b, 395) == kWkt.size() + 1);
    CHECK(b.substr(375 + 54, kWkt.size() + 1) == kWkt + std::string(1, '\0'));
    CHECK(b.size() == 375 + vlr + cloud.size() * record);
    // Return 1 of 1 in the 1.4 layout.
    CHECK(static_cast<unsigned char>(b[375 + vlr + 14]) == 0x11);
  }
}

TEST_CASE("LAS 1.4 puts a WKT too long for a VLR into an extended VLR", "[io]") {
  TempDir dir;
  std::string wkt = kWkt;
  wkt.insert(wkt.size() - 1, ",EXTENSION[\"" + std::string(70000, 'x') + "\"]");
  const PointCloud cloud = sample_cloud(100, false, false, false);
  WriterOptions o;
  o.crs = wkt;
  const std::string path = dir.file("long.las");
  REQUIRE(write_batches(path, o, cloud).is_ok());
  const std::string b = slurp(path);
  CHECK(field<std::uint32_t>(b, 100) == 0);
  CHECK(field<std::uint32_t>(b, 96) == 375);
  CHECK(field<std::uint64_t>(b, 235) == 375 + 100 * 30);
  CHECK(field<std::uint32_t>(b, 243) == 1);
  CHECK(text_field(b, 375 + 3000 + 2, 16) == "LASF_Projection");
  CHECK(field<std::uint64_t>(b, 375 + 3000 + 20) == wkt.size() + 1);
  const ReadBack r = read_back(path);
  CHECK(r.info.crs_source == wkt);
  CHECK(r.cloud.size() == 100);
}

TEST_CASE("LAZ output reads back as the same points as LAS output", "[io][laz]") {
  TempDir dir;
  for (const std::string& crs : {std::string(), std::string("EPSG:2154"), kWkt}) {
    for (const bool colors : {false, true}) {
      DYNAMIC_SECTION("crs '" << crs.substr(0, 12) << "', colours " << colors) {
        // 120,000 points: three LASzip chunks of 50,000.
        const PointCloud cloud = sample_cloud(120000, colors, true, false);
        WriterOptions o = options_with(colors, true);
        o.crs = crs;
        const Status wl = write_batches(dir.file("a.laz"), o, cloud);
        INFO(wl.to_string());
        REQUIRE(wl.is_ok());
        REQUIRE(write_batches(dir.file("a.las"), o, cloud).is_ok());
        const ReadBack laz = read_back(dir.file("a.laz"));
        const ReadBack las = read_back(dir.file("a.las"));
        require_identical(laz.cloud, las.cloud);
        CHECK(laz.info.format == "laz");
        CHECK(laz.info.crs == las.info.crs);
        CHECK(laz.info.crs_source == las.info.crs_source);
        CHECK(laz.info.header_bounds->min == las.info.header_bounds->min);
        CHECK(laz.info.header_bounds->max == las.info.header_bounds->max);
        const std::string b = slurp(dir.file("a.laz"));
        // LAS 1.2, or 1.4 for WKT, with the legacy format 2/0 and the LAZ bit.
        CHECK(static_cast<int>(b[25]) == (crs == kWkt ? 4 : 2));
        CHECK(static_cast<std::uint8_t>(b[104]) == (colors ? 0x82 : 0x80));
        CHECK(b.size() < fs::file_size(dir.file("a.las")));
      }
    }
  }
  SECTION("no points") {
    REQUIRE(write_batches(dir.file("empty.laz"), options_with(true, true), PointCloud{}).is_ok());
    const ReadBack r = read_back(dir.file("empty.laz"));
    CHECK(r.info.point_count == std::optional<std::uint64_t>(0));
    CHECK(r.cloud.empty());
  }
}

// The EPSG code of a CRS read back (0 when PROJ finds none).
int epsg_of(const std::string& crs) {
  Result<CrsSummary> d = describe_crs(crs, "read back");
  INFO(crs);
  REQUIRE(d.is_ok());
  return d->epsg.value_or(0);
}

TEST_CASE("LAS GeoTIFF keys for EPSG codes and key lists", "[io]") {
  TempDir dir;
  const PointCloud cloud = sample_cloud(50, false, false, false);
  const std::string path = dir.file("geo.las");
  auto write_crs = [&](const std::string& crs) {
    WriterOptions o;
    o.crs = crs;
    const Status s = write_batches(path, o, cloud);
    INFO(s.to_string());
    REQUIRE(s.is_ok());
    return slurp(path);
  };
  auto key_words = [](const std::string& b) {
    REQUIRE(field<std::uint32_t>(b, 100) == 1);
    REQUIRE(text_field(b, 229, 16) == "LASF_Projection");
    REQUIRE(field<std::uint16_t>(b, 245) == 34735);
    const std::size_t length = field<std::uint16_t>(b, 247);
    REQUIRE(field<std::uint32_t>(b, 96) == 227 + 54 + length);
    std::vector<std::uint16_t> words;
    for (std::size_t i = 0; i < length / 2; ++i) words.push_back(field<std::uint16_t>(b, 281 + 2 * i));
    return words;
  };

  SECTION("projected EPSG code") {
    const std::string b = write_crs("EPSG:32633");
    CHECK(b[25] == 2);
    CHECK(key_words(b) ==
          std::vector<std::uint16_t>{1, 1, 0, 3, 1024, 0, 1, 1, 1025, 0, 1, 1, 3072, 0, 1, 32633});
    CHECK(epsg_of(read_back(path).info.crs) == 32633);
  }
  SECTION("geographic EPSG code, with a degree scale for x and y") {
    PointCloud lonlat = cloud;
    for (Vec3d& p : lonlat.positions) p = {7.0 + p.x * 1e-7, 45.0 + p.y * 1e-7, p.z};
    WriterOptions o;
    o.crs = "EPSG:4326";
    REQUIRE(write_batches(path, o, lonlat).is_ok());
    const std::string b = slurp(path);
    CHECK(key_words(b) ==
          std::vector<std::uint16_t>{1, 1, 0, 3, 1024, 0, 1, 2, 1025, 0, 1, 1, 2048, 0, 1, 4326});
    const ReadBack r = read_back(path);
    CHECK(epsg_of(r.info.crs) == 4326);
    CHECK(r.info.scale == Vec3d{1e-9, 1e-9, 1e-4});
    for (std::size_t i = 0; i < lonlat.size(); ++i) {
      REQUIRE(std::abs(r.cloud.positions[i].x - lonlat.positions[i].x) <= 0.5e-9 * (1 + 1e-6));
    }
  }
  SECTION("a geographic WKT also gets the degree scale, a projected one the metric scale") {
    const std::string geog =
        "COMPD_CS[\"WGS 84 + EGM96 height\",GEOGCS[\"WGS 84\",DATUM[\"WGS_1984\",SPHEROID[\"WGS 84\","
        "6378137,298.257223563]],PRIMEM[\"Greenwich\",0],UNIT[\"degree\",0.0174532925199433]],"
        "VERT_CS[\"EGM96 height\",VERT_DATUM[\"EGM96 geoid\",2005],UNIT[\"metre\",1]]]";
    for (const auto& [crs, xy] : {std::pair{geog, 1e-9}, std::pair{kWkt, 1e-4}}) {
      WriterOptions o;
      o.crs = crs;
      REQUIRE(write_batches(path, o, PointCloud{}).is_ok());
      const ReadBack r = read_back(path);
      CHECK(r.info.crs_source == crs);
      CHECK(r.info.scale == Vec3d{xy, xy, 1e-4});
    }
  }
  SECTION("GeoTIFF keys are written back as given, in key order") {
    const std::string keys = "GeoTIFF keys: 1024=3, 1025=2, 2048=4326";
    const std::string b = write_crs(keys);
    CHECK(key_words(b) ==
          std::vector<std::uint16_t>{1, 1, 0, 3, 1024, 0, 1, 3, 1025, 0, 1, 2, 2048, 0, 1, 4326});
    // A geocentric model with a geographic code names no CRS: read back as none.
    CHECK(read_back(path).info.crs.empty());
    // GeoTIFF wants increasing key ids, so a list in another order comes back sorted.
    const std::string sorted = write_crs("GeoTIFF keys: 3072=32633, 1024=1");
    CHECK(key_words(sorted) == std::vector<std::uint16_t>{1, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32633});
    CHECK(epsg_of(read_back(path).info.crs) == 32633);
  }
  SECTION("malformed CRS strings are refused before anything is created") {
    for (const std::string crs :
         {"EPSG:", "EPSG:abc", "EPSG:0", "EPSG:32767", "EPSG:70000", "EPSG:-4326", "GeoTIFF keys:",
          "GeoTIFF keys: 1024", "GeoTIFF keys: 1024=1, 1024=2", "GeoTIFF keys: 70000=1", "GeoTIFF keys: 1=x"}) {
      INFO(crs);
      WriterOptions o;
      o.crs = crs;
      const Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, o);
      require_error(w.status(), StatusCode::kInvalidArgument, path, "CRS");
    }
    CHECK(dir.entries().empty());
  }
}

TEST_CASE("LAS scale and offset choice", "[io]") {
  TempDir dir;
  const std::string path = dir.file("scale.las");

  SECTION("an extent too large for 0.1 mm gets the next power of ten that fits, per axis") {
    WriterOptions o;
    o.expected_bounds.min = {-1000.5, 5e6, 10};
    o.expected_bounds.max = {1e6, 5e6 + 50, 20};
    PointCloud c;
    c.positions = {o.expected_bounds.min, o.expected_bounds.max, {12345.6789, 5e6 + 3.25, 15}};
    REQUIRE(write_batches(path, o, c).is_ok());
    const ReadBack r = read_back(path);
    CHECK(r.info.scale == Vec3d{1e-3, 1e-4, 1e-4});
    const std::string b = slurp(path);
    CHECK(field<double>(b, 155) == -1010.0);  // a multiple of scale * 1e4 = 10
    CHECK(field<double>(b, 163) == 5e6);
    CHECK(field<double>(b, 171) == 10.0);
    for (std::size_t i = 0; i < c.size(); ++i) {
      REQUIRE(std::abs(r.cloud.positions[i].x - c.positions[i].x) <= 0.5e-3 * (1 + 1e-9));
      REQUIRE(std::abs(r.cloud.positions[i].y - c.positions[i].y) <= 0.5e-4 * (1 + 1e-9));
    }
  }
  SECTION("automatic scales keep 10 % headroom above the expected extent") {
    WriterOptions o;
    o.expected_bounds.min = {0, 0, 0};
    o.expected_bounds.max = {1.9e5, 2e5, 1};  // 2e5 m fits 0.1 mm exactly, but not with headroom
    REQUIRE(write_batches(path, o, PointCloud{}).is_ok());
    CHECK(read_back(path).info.scale == Vec3d{1e-4, 1e-3, 1e-4});
  }
  SECTION("a caller's scale is used as given") {
    WriterOptions o;
    o.scale = 0.01;
    const PointCloud c = sample_cloud(100, false, false, false);
    REQUIRE(write_batches(path, o, c).is_ok());
    CHECK(read_back(path).info.scale == Vec3d{0.01, 0.01, 0.01});
    const std::string b = slurp(path);
    CHECK(std::fmod(field<double>(b, 155), 100.0) == 0.0);
  }
  SECTION("a caller's scale that cannot hold the expected bounds is refused at open") {
    WriterOptions o;
    o.scale = 1e-9;
    o.expected_bounds.min = {0, 0, 0};
    o.expected_bounds.max = {100, 100, 100};
    const Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, o);
    require_error(w.status(), StatusCode::kInvalidArgument, path, "scale");
    CHECK(dir.entries().empty());
  }
  SECTION("bad scale and bounds options") {
    for (const double scale : {-1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
      WriterOptions o;
      o.scale = scale;
      require_error(open_point_writer(path, o).status(), StatusCode::kInvalidArgument, path, "scale");
    }
    WriterOptions o;
    o.expected_bounds.min = {0, 0, 0};
    o.expected_bounds.max = {std::numeric_limits<double>::infinity(), 1, 1};
    require_error(open_point_writer(path, o).status(), StatusCode::kInvalidArgument, path, "bounds");
    CHECK(dir.entries().empty());
  }
}

TEST_CASE("LAS refuses points beyond the 32-bit range instead of wrapping them", "[io]") {
  TempDir dir;
  const std::string path = dir.file("range.las");
  PointCloud first;
  first.positions = {{0, 0, 0}, {1, 1, 1}};

  SECTION("beyond the expected bounds") {
    WriterOptions o;
    o.expected_bounds.min = {0, 0, 0};
    o.expected_bounds.max = {100, 100, 100};
    Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, o);
    REQUIRE(w.is_ok());
    REQUIRE((*w)->write(first).is_ok());
    PointCloud near;
    near.positions = {{150, -20, 100}};  // outside the bounds but still representable
    REQUIRE((*w)->write(near).is_ok());
    PointCloud far;
    far.positions = {{5, 5, 5}, {5, 1e6, 5}};
    const Status s = (*w)->write(far);
    require_error(s, StatusCode::kInvalidArgument, path, "point 4 ");
    CHECK_THAT(s.message(), Contains("(5, 1e+06, 5)"));
    // The error sticks and nothing is committed.
    CHECK((*w)->finish().code() == StatusCode::kInvalidArgument);
    CHECK(dir.entries().empty());
  }
  SECTION("beyond the first batch's bounds") {
    Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, {});
    REQUIRE(w.is_ok());
    REQUIRE((*w)->write(first).is_ok());
    PointCloud far;
    far.positions = {{-3e5, 0, 0}};
    require_error((*w)->write(far), StatusCode::kInvalidArgument, path, "point 2 ");
  }
}

// ---------------------------------------------------------------- XYZ

TEST_CASE("XYZ and CSV round trip through the XYZ reader", "[io]") {
  TempDir dir;
  const PointCloud cloud = sample_cloud(5000, true, true, true);
  ReaderOptions ro;
  ro.xyz_columns = "x,y,z,r,g,b,i";
  for (const std::string name : {"out.xyz", "out.txt", "out.csv", "OUT.XYZ"}) {
    INFO(name);
    const std::string path = dir.file(name);
    REQUIRE(write_batches(path, options_with(true, true), cloud).is_ok());
    const std::string text = slurp(path);
    const std::string first_line = text.substr(0, text.find('\n'));
    const char sep = name == "out.csv" ? ',' : ' ';
    CHECK(std::count(first_line.begin(), first_line.end(), sep) == 6);
    const ReadBack r = read_back(path, ro);
    require_identical(r.cloud, cloud);
    if (name == "out.csv") {
      // CSV names its columns: read back without a column list.
      CHECK(first_line == "X,Y,Z,Red,Green,Blue,Intensity");
      require_identical(read_back(path).cloud, cloud);
    }
    fs::remove(path);
  }
  // Coordinates only.
  const std::string path = dir.file("plain.xyz");
  const PointCloud plain = sample_cloud(100, false, false, true);
  REQUIRE(write_batches(path, {}, plain).is_ok());
  require_identical(read_back(path).cloud, plain);
}

// Points fd 1 at a file for the lifetime of the object.
class StdoutToFile {
 public:
  explicit StdoutToFile(const std::string& path) {
    std::cout.flush();
    std::fflush(stdout);
    saved_ = ::dup(STDOUT_FILENO);
    const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, STDOUT_FILENO);
    ::close(fd);
  }
  StdoutToFile(const StdoutToFile&) = delete;
  StdoutToFile& operator=(const StdoutToFile&) = delete;
  ~StdoutToFile() {
    std::fflush(stdout);
    ::dup2(saved_, STDOUT_FILENO);
    ::close(saved_);
  }

 private:
  int saved_ = -1;
};

TEST_CASE("XYZ to standard output with '-'", "[io]") {
  TempDir dir;
  const std::string captured = dir.file("stdout.xyz");
  const PointCloud cloud = sample_cloud(3000, false, true, true);
  Status s;
  std::vector<std::string> entries;
  {
    StdoutToFile redirect(captured);
    s = write_batches("-", options_with(false, true), cloud);
    entries = dir.entries();
  }
  INFO(s.to_string());
  REQUIRE(s.is_ok());
  CHECK(entries == std::vector<std::string>{"stdout.xyz"});  // no temporary file anywhere
  ReaderOptions ro;
  ro.xyz_columns = "x,y,z,i";
  require_identical(read_back(captured, ro).cloud, cloud);
}

// ---------------------------------------------------------------- every format

const std::vector<std::string> kFormats = {"a.ply", "b.las", "c.xyz", "d.csv"};

TEST_CASE("an output with no points is a valid file in every format", "[io]") {
  TempDir dir;
  for (const PlyEncoding enc : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian,
                                PlyEncoding::kAscii}) {
    WriterOptions o = options_with(true, true);
    o.ply_encoding = enc;
    const std::string path = dir.file("empty.ply");
    Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, o);
    REQUIRE(w.is_ok());
    REQUIRE((*w)->write(PointCloud{}).is_ok());
    REQUIRE((*w)->finish().is_ok());
    CHECK((*w)->points_written() == 0);
    const Result<PointCloud> r = read_ply(path);
    INFO(r.status().to_string());
    REQUIRE(r.is_ok());
    CHECK(r->empty());
  }
  for (const std::string& crs : {std::string(), std::string("EPSG:2154"), kWkt}) {
    WriterOptions o = options_with(true, true);
    o.crs = crs;
    const std::string path = dir.file("empty.las");
    REQUIRE(write_batches(path, o, PointCloud{}).is_ok());
    const ReadBack r = read_back(path);
    CHECK(r.info.point_count == std::optional<std::uint64_t>(0));
    if (crs.empty()) {
      CHECK(r.info.crs.empty());
    } else {
      CHECK(epsg_of(r.info.crs) == 2154);
    }
    CHECK(r.cloud.empty());
    CHECK(r.info.scale == Vec3d{1e-4, 1e-4, 1e-4});
  }
  for (const std::string name : {"empty.xyz", "empty.csv"}) {
    const std::string path = dir.file(name);
    REQUIRE(write_batches(path, options_with(true, false), PointCloud{}).is_ok());
    // CSV names its columns even with no point under them.
    CHECK(slurp(path) == (name == "empty.csv" ? "X,Y,Z,Red,Green,Blue\n" : ""));
    CHECK(read_back(path).cloud.empty());
  }
}

TEST_CASE("a writer destroyed without finish() leaves no trace", "[io]") {
  TempDir dir;
  const PointCloud cloud = sample_cloud(3000, true, true, false);
  for (const std::string& name : kFormats) {
    INFO(name);
    const std::string path = dir.file(name);
    write_text(path, "old contents");
    {
      Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, options_with(true, true));
      REQUIRE(w.is_ok());
      REQUIRE((*w)->write(cloud).is_ok());
      // The temporary file sits beside the destination meanwhile.
      CHECK(dir.entries().size() == 2);
    }
    CHECK(slurp(path) == "old contents");
    fs::remove(path);
    CHECK(dir.entries().empty());
  }
}

TEST_CASE("a finished writer replaces an existing file", "[io]") {
  TempDir dir;
  const PointCloud cloud = sample_cloud(100, false, false, false);
  for (const std::string& name : kFormats) {
    const std::string path = dir.file(name);
    write_text(path, "old contents");
    REQUIRE(write_batches(path, {}, cloud).is_ok());
    CHECK(read_back(path).cloud.size() == 100);
  }
  CHECK(dir.entries() == std::vector<std::string>{"a.ply", "b.las", "c.xyz", "d.csv"});
}

TEST_CASE("non-finite points are refused naming the point, the writer stays failed", "[io]") {
  TempDir dir;
  const double kNaN = std::numeric_limits<double>::quiet_NaN();
  const double kInf = std::numeric_limits<double>::infinity();
  for (const std::string& name : kFormats) {
    for (const Vec3d bad : {Vec3d{kNaN, 0, 0}, Vec3d{0, kInf, 0}, Vec3d{0, 0, -kInf}}) {
      INFO(name << " " << bad.x << " " << bad.y << " " << bad.z);
      const std::string path = dir.file(name);
      write_text(path, "old contents");
      Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, {});
      REQUIRE(w.is_ok());
      PointCloud first = sample_cloud(10, false, false, false);
      REQUIRE((*w)->write(first).is_ok());
      PointCloud second = sample_cloud(10, false, false, false);
      second.positions[3] = bad;
      const Status s = (*w)->write(second);
      require_error(s, StatusCode::kInvalidArgument, path, "point 13 has a non-finite coordinate");
      CHECK((*w)->write(first).code() == StatusCode::kInvalidArgument);
      CHECK((*w)->finish().code() == StatusCode::kInvalidArgument);
      // The temporary file is gone at once, not only when the writer is.
      CHECK(dir.entries() == std::vector<std::string>{name});
      CHECK(slurp(path) == "old contents");
      fs::remove(path);
    }
  }
  // Non-finite intensity too.
  const std::string path = dir.file("i.ply");
  Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, options_with(false, true));
  REQUIRE(w.is_ok());
  PointCloud c = sample_cloud(5, false, true, false);
  c.intensities[2] = std::numeric_limits<float>::quiet_NaN();
  require_error((*w)->write(c), StatusCode::kInvalidArgument, path, "point 2 has a non-finite intensity");
}

TEST_CASE("batches whose attributes disagree with the options are refused", "[io]") {
  TempDir dir;
  for (const std::string& name : kFormats) {
    INFO(name);
    const std::string path = dir.file(name);
    struct Case {
      bool colors, intensity;  // options
      PointCloud batch;
      const char* fragment;
    };
    PointCloud plain = sample_cloud(10, false, false, false);
    PointCloud both = sample_cloud(10, true, true, false);
    PointCloud short_colors = both;
    short_colors.colors.pop_back();
    for (const Case& c : {Case{true, false, plain, "opened with colours"},
                          Case{false, true, plain, "opened with intensity"},
                          Case{false, false, both, "opened without them"},
                          Case{true, true, short_colors, "9 colours"}}) {
      Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, options_with(c.colors, c.intensity));
      REQUIRE(w.is_ok());
      require_error((*w)->write(c.batch), StatusCode::kInvalidArgument, path, c.fragment);
    }
    CHECK(dir.entries().empty());
  }
}

TEST_CASE("unwritable destinations fail at open with an I/O error naming the path", "[io]") {
  TempDir dir;
  for (const std::string& name : kFormats) {
    for (const std::string& path : {"/proc/relief-nope/" + name, dir.file("no-such-dir/" + name)}) {
      INFO(path);
      require_error(open_point_writer(path, {}).status(), StatusCode::kIoError, path);
    }
    // A directory where the file should go.
    const std::string taken = dir.file(name);
    fs::create_directory(taken);
    require_error(open_point_writer(taken, {}).status(), StatusCode::kIoError, taken, "directory");
    fs::remove(taken);
  }
  CHECK(dir.entries().empty());
}

TEST_CASE("open_point_writer dispatch and misuse", "[io]") {
  TempDir dir;
  for (const std::string& path : {dir.file("out.e57"), dir.file("out.pcd"), dir.file("out")}) {
    require_error(open_point_writer(path, {}).status(), StatusCode::kUnsupported, path, ".ply, .las, .laz");
  }
  CHECK(dir.entries().empty());

  const std::string upper = dir.file("OUT.LAS");
  const PointCloud cloud = sample_cloud(10, false, false, false);
  REQUIRE(write_batches(upper, {}, cloud).is_ok());
  CHECK(read_back(upper).info.format == "las");

  Result<std::unique_ptr<PointWriter>> w = open_point_writer(dir.file("twice.ply"), {});
  REQUIRE(w.is_ok());
  REQUIRE((*w)->write(cloud).is_ok());
  REQUIRE((*w)->finish().is_ok());
  CHECK((*w)->write(cloud).code() == StatusCode::kInvalidArgument);
  CHECK((*w)->finish().code() == StatusCode::kInvalidArgument);
  CHECK(read_ply(dir.file("twice.ply"))->size() == 10);  // still the finished file
}

// ---------------------------------------------------------------- real data

using relief::test::shared_file;

TEST_CASE("real LAS files survive a read and write round trip", "[io][shared-data]") {
  TempDir dir;
  for (const char* rel : {"medium/orig/fr_aerial_rgb_698k.las", "medium/orig/lone_star_tls_519k.las"}) {
    const auto las = shared_file(rel);
    if (!las) continue;
    INFO(rel);
    const ReadBack in = read_back(*las);
    WriterOptions o = options_with(in.info.has_colors, in.info.has_intensity);
    o.crs = in.info.crs;
    o.crs_source = in.info.crs_source;
    o.scale = in.info.scale.x;
    REQUIRE(in.info.header_bounds.has_value());
    o.expected_bounds = *in.info.header_bounds;
    const std::string path = dir.file("copy.las");
    const Status s = write_batches(path, o, in.cloud, {65536});
    INFO(s.to_string());
    REQUIRE(s.is_ok());
    const ReadBack out = read_back(path);
    // The CRS comes back as the source gave it.
    CHECK(out.info.crs == in.info.crs);
    CHECK(out.info.crs_source == in.info.crs_source);
    CHECK(out.info.scale == in.info.scale);
    REQUIRE(out.cloud.size() == in.cloud.size());
    for (std::size_t i = 0; i < in.cloud.size(); ++i) {
      const Vec3d& a = in.cloud.positions[i];
      const Vec3d& b = out.cloud.positions[i];
      // Same grid, possibly another offset: equal to far below the scale.
      REQUIRE(std::abs(a.x - b.x) < 1e-6);
      REQUIRE(std::abs(a.y - b.y) < 1e-6);
      REQUIRE(std::abs(a.z - b.z) < 1e-6);
      REQUIRE(out.cloud.intensities[i] == in.cloud.intensities[i]);
      if (in.info.has_colors) REQUIRE(out.cloud.colors[i] == in.cloud.colors[i]);
    }
    CHECK(out.info.header_bounds->min.x == Approx(in.info.header_bounds->min.x).margin(1e-6));
    CHECK(out.info.header_bounds->max.y == Approx(in.info.header_bounds->max.y).margin(1e-6));
  }
}

TEST_CASE("write_file puts bytes in place whole, or fails naming the path and leaves nothing", "[io][writers]") {
  TempDir dir;
  const std::vector<std::uint8_t> data = {1, 2, 3, 0, 255};
  const std::string path = dir.file("blob.bin");
  REQUIRE(relief::write_file(path, data).is_ok());
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> back{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  CHECK(back == data);
  // Replacing it: the new bytes, nothing else beside it.
  REQUIRE(relief::write_file(path, std::vector<std::uint8_t>{7}).is_ok());
  CHECK(std::filesystem::file_size(path) == 1);
  const auto missing = relief::write_file(dir.file("no/such/dir/x.bin"), data);
  CHECK(missing.code() == relief::StatusCode::kIoError);
  CHECK(missing.message().find("does not exist") != std::string::npos);
  const auto onto_dir = relief::write_file(dir.path().string(), data);
  CHECK(onto_dir.code() == relief::StatusCode::kIoError);
  CHECK(onto_dir.message().find("is a directory") != std::string::npos);
  CHECK(dir.entries() == std::vector<std::string>{"blob.bin"});  // no temporary left
}

}  // namespace
}  // namespace relief

TEST_CASE("text coordinates of a decimal grid print its decimals, others the shortest exact text", "[io][xyz]") {
  using relief::grid_decimals;
  // A LAS grid: scale 10^-k and an offset on it.
  CHECK(grid_decimals(0.01, 849000) == 2);
  CHECK(grid_decimals(0.001, -0.0) == 3);
  CHECK(grid_decimals(1, 500000) == 0);
  CHECK(grid_decimals(1e-9, 0) == 9);
  CHECK(grid_decimals(0.01, 0.005) == -1);    // an offset between the decimals
  CHECK(grid_decimals(0.0199, 0) == -1);      // an error-bounded grid of 2T
  CHECK(grid_decimals(0.25, 0) == -1);        // binary steps print exactly anyway
  CHECK(grid_decimals(1e-10, 0) == -1);       // beyond nine decimals
  CHECK(grid_decimals(0.01, 1e300) == -1);    // an offset beyond 2^52 steps
  CHECK(grid_decimals(std::nan(""), 0) == -1);
  CHECK(grid_decimals(0, 0) == -1);
  const auto text = [](double v, int k) {
    std::uint8_t buf[64];
    const std::uint8_t* end = relief::put_coordinate(buf, v, k);
    return std::string(reinterpret_cast<const char*>(buf), static_cast<std::size_t>(end - buf));
  };
  // 84901732 * 0.01 + 0 is the double 849017.3200000001 (what LAS readers compute).
  const double x = 84901732 * 0.01;
  CHECK(text(x, -1) == "849017.3200000001");
  CHECK(text(x, 2) == "849017.32");
  CHECK(std::llround(std::stod(text(x, 2)) / 0.01) == 84901732);
  CHECK(text(849050, 2) == "849050.00");
  CHECK(text(-3.5, 3) == "-3.500");
  CHECK(text(0.004, 2) == "0.00");
  CHECK(text(-0.004, 2) == "0.00");  // no "-0.00"
  CHECK(text(-0.005001, 2) == "-0.01");
  CHECK(text(0.005, 3) == "0.005");
  CHECK(text(1e-9, 9) == "0.000000001");
  CHECK(text(-1e-9, 9) == "-0.000000001");
  CHECK(text(12.5, 0) == "12");  // to the nearest, ties to even (nearbyint)
  CHECK(text(13.5, 0) == "14");
  CHECK(text(4503599627370495.0, 0) == "4503599627370495");
  // Beyond 2^53 digits, or not finite: the shortest text.
  CHECK(text(1e10, 9) == "10000000000");
  CHECK(text(std::numeric_limits<double>::infinity(), 2) == "inf");
  CHECK(text(std::nan(""), 2) == "nan");
}
