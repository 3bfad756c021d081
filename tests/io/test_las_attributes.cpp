// Every LAS attribute through the LAS/LAZ reader and writer: synthetic files
// of every point format with every field random, checked against the
// independent reference decoder of tests/support/las_records.h.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <iterator>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "relief/io.h"
#include "support/las_records.h"
#include "support/same_cloud.h"
#include "support/shared_data.h"
#include "support/temp_dir.h"

namespace {

using relief::test::LasRecord;
using relief::test::read_las_records;
using relief::test::TempDir;
using relief::test::TestLasOptions;
using relief::test::write_test_las;

// Reads a whole point file with its stream info.
struct ReadBack {
  relief::PointStreamInfo info;
  relief::PointCloud cloud;
};

ReadBack read_all(const std::string& path) {
  auto reader = relief::open_point_reader(path);
  REQUIRE(reader.is_ok());
  ReadBack out;
  out.info = (*reader)->info();
  relief::PointCloud batch;
  for (;;) {
    // Small batches: the colour rule's sample and batch joins are exercised.
    auto n = (*reader)->read(batch, 777);
    REQUIRE(n.is_ok());
    if (*n == 0) break;
    for (std::size_t i = 0; i < *n; ++i) out.cloud.push_back_from(batch, i);
  }
  out.info = (*reader)->info();
  return out;
}

// The records a PointCloud read from a file of `format` stands for.
std::vector<LasRecord> to_records(const ReadBack& r) {
  const relief::PointCloud& c = r.cloud;
  const relief::LasAttributes& a = c.las;
  const bool ext = r.info.las_point_format >= 6;
  std::vector<LasRecord> out(c.size());
  for (std::size_t i = 0; i < c.size(); ++i) {
    LasRecord& p = out[i];
    p.x = static_cast<std::int32_t>(std::llround((c.positions[i].x - r.info.offset.x) / r.info.scale.x));
    p.y = static_cast<std::int32_t>(std::llround((c.positions[i].y - r.info.offset.y) / r.info.scale.y));
    p.z = static_cast<std::int32_t>(std::llround((c.positions[i].z - r.info.offset.z) / r.info.scale.z));
    p.intensity = static_cast<std::uint16_t>(c.intensities[i]);
    p.return_number = a.return_number[i];
    p.number_of_returns = a.number_of_returns[i];
    p.scan_direction = a.scan_flags[i] & 1;
    p.edge = (a.scan_flags[i] >> 1) & 1;
    p.channel = a.scan_flags[i] >> 2;
    p.classification = a.classification[i];
    p.synthetic = a.class_flags[i] & 1;
    p.key_point = (a.class_flags[i] >> 1) & 1;
    p.withheld = (a.class_flags[i] >> 2) & 1;
    p.overlap = (a.class_flags[i] >> 3) & 1;
    p.scan_angle = ext ? a.scan_angle[i] / 6 : a.scan_angle[i] / 1000;
    p.user_data = a.user_data[i];
    p.point_source_id = a.point_source_id[i];
    if (!a.gps_time.empty()) p.gps_time = a.gps_time[i];
    if (!c.colors.empty() && r.info.las_colors_8bit) {
      p.red = c.colors[i].r;
      p.green = c.colors[i].g;
      p.blue = c.colors[i].b;
    } else if (!c.colors.empty()) {
      REQUIRE(a.color_low.size() == c.size());
      p.red = static_cast<std::uint16_t>((c.colors[i].r << 8) | a.color_low[i].r);
      p.green = static_cast<std::uint16_t>((c.colors[i].g << 8) | a.color_low[i].g);
      p.blue = static_cast<std::uint16_t>((c.colors[i].b << 8) | a.color_low[i].b);
    }
    if (!a.nir.empty()) p.nir = a.nir[i];
    const std::size_t w = a.extra_bytes_size;
    if (w > 0) {
      p.extra.assign(a.extra_bytes.begin() + static_cast<std::ptrdiff_t>(i * w),
                     a.extra_bytes.begin() + static_cast<std::ptrdiff_t>((i + 1) * w));
    }
  }
  return out;
}

// Wave packets are not part of LasRecord; the reference keeps the bytes after
// the format's minimum as `extra`, which for 4/5/9/10 starts after them.
std::vector<std::uint8_t> two_field_vlr() {
  std::vector<std::uint8_t> v = relief::test::extra_bytes_descriptor(3, 0, "height_above_ground");  // uint16
  const std::vector<std::uint8_t> b = relief::test::extra_bytes_descriptor(1, 8, "confidence", 0.5);  // uint8, scaled
  v.insert(v.end(), b.begin(), b.end());
  return v;
}

// Whether each coordinate of `b` lies on the same integer of the grid
// (scale, offset) as `a`'s and within a millionth of a step of it.
bool same_grid_integers(const std::vector<relief::Vec3d>& b, const std::vector<relief::Vec3d>& a,
                        const relief::Vec3d& scale, const relief::Vec3d& offset) {
  const auto axis = [](const relief::Vec3d& p, int k) { return k == 0 ? p.x : k == 1 ? p.y : p.z; };
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const double s = axis(scale, k), o = axis(offset, k);
      const double u = axis(a[i], k), v = axis(b[i], k);
      if (std::llround((u - o) / s) != std::llround((v - o) / s) || std::fabs(u - v) > 1e-6 * s) {
        UNSCOPED_INFO("point " << i << " axis " << k << ": " << v << " against " << u);
        return false;
      }
    }
  }
  return true;
}

relief::WriterOptions options_from(const relief::PointStreamInfo& info, std::uint32_t extra_bytes_size) {
  relief::WriterOptions w;
  w.colors = info.has_colors;
  w.intensity = info.has_intensity;
  w.grid_scale = info.scale;
  w.grid_offset = info.offset;
  w.las_attributes = info.las_attributes;
  w.las_point_format = info.las_point_format;
  w.las_version_minor = info.las_version_minor;
  w.extra_bytes_vlr = info.extra_bytes_vlr;
  w.extra_bytes_size = extra_bytes_size;
  w.las_colors_8bit = info.las_colors_8bit;
  return w;
}

}  // namespace

TEST_CASE("LAS reader decodes every field of every point format", "[las][attributes]") {
  TempDir dir;
  for (int format = 0; format <= 10; ++format) {
    CAPTURE(format);
    TestLasOptions o;
    o.format = format;
    o.points = 2500;
    o.seed = static_cast<std::uint32_t>(100 + format);
    o.extra = 3;
    o.extra_bytes_vlr = two_field_vlr();
    const std::string path = dir.file("f" + std::to_string(format) + ".las");
    REQUIRE(write_test_las(path, o));
    const auto ref = read_las_records(path);
    REQUIRE(ref);
    const ReadBack got = read_all(path);
    CHECK(got.info.las_point_format == format);
    CHECK(got.info.las_version_minor == (format >= 6 ? 4 : 2));
    CHECK(got.info.extra_bytes_vlr == std::string(o.extra_bytes_vlr.begin(), o.extra_bytes_vlr.end()));
    CHECK(got.cloud.las.carried() == got.info.las_attributes);
    const bool wave = format == 4 || format == 5 || format == 9 || format == 10;
    std::vector<LasRecord> want = ref->records;
    if (wave) {
      for (LasRecord& p : want) p.extra.erase(p.extra.begin(), p.extra.end() - 3);
    }
    REQUIRE(relief::test::first_difference(to_records(got), want) == "");
    // Dropping the wave packets is said, not silent.
    const bool warned = std::any_of(got.info.warnings.begin(), got.info.warnings.end(), [](const std::string& w) {
      return w.find("wave packet descriptors") != std::string::npos;
    });
    CHECK(warned == wave);
  }
}

TEST_CASE("LAS writer gives back every field in the source's point format", "[las][attributes]") {
  TempDir dir;
  for (int format = 0; format <= 10; ++format) {
    CAPTURE(format);
    TestLasOptions o;
    o.format = format;
    o.seed = static_cast<std::uint32_t>(200 + format);
    o.extra = 3;
    o.extra_bytes_vlr = two_field_vlr();
    const std::string in = dir.file("in" + std::to_string(format) + ".las");
    const std::string out = dir.file("out" + std::to_string(format) + ".las");
    REQUIRE(write_test_las(in, o));
    const ReadBack got = read_all(in);
    auto writer = relief::open_point_writer(out, options_from(got.info, got.cloud.las.extra_bytes_size));
    REQUIRE(writer.status().to_string() == "ok");
    REQUIRE((*writer)->write(got.cloud).to_string() == "ok");
    REQUIRE((*writer)->finish().is_ok());
    const auto a = read_las_records(in);
    const auto b = read_las_records(out);
    REQUIRE(a);
    REQUIRE(b);
    // Wave packets are not kept: 4 -> 1, 5 -> 3, 9 -> 6, 10 -> 8.
    const int expect = format == 4 ? 1 : format == 5 ? 3 : format == 9 ? 6 : format == 10 ? 8 : format;
    CHECK(b->format == expect);
    CHECK(b->extra_bytes_vlr == o.extra_bytes_vlr);
    std::vector<LasRecord> want = a->records;
    for (LasRecord& p : want) p.extra.erase(p.extra.begin(), p.extra.end() - 3);
    REQUIRE(relief::test::first_difference(b->records, want) == "");
  }
}

TEST_CASE("LAS colours: 8-bit levels in 16-bit fields come back as they were", "[las][attributes]") {
  TempDir dir;
  TestLasOptions o;
  o.format = 2;
  o.wide_colors = false;
  const std::string in = dir.file("c8.las");
  REQUIRE(write_test_las(in, o));
  const ReadBack got = read_all(in);
  const auto ref = read_las_records(in);
  REQUIRE(ref);
  CHECK(got.info.las_colors_8bit);
  for (std::size_t i = 0; i < got.cloud.size(); ++i) {
    REQUIRE(got.cloud.colors[i].r == ref->records[i].red);  // narrowed: the level itself
    REQUIRE(got.cloud.las.color_low[i].r == ref->records[i].red);  // (v << 8) | v = v * 257 without the flag
  }
  const std::string out = dir.file("c8-out.las");
  auto writer = relief::open_point_writer(out, options_from(got.info, 0));
  REQUIRE(writer.is_ok());
  REQUIRE((*writer)->write(got.cloud).is_ok());
  REQUIRE((*writer)->finish().is_ok());
  const auto back = read_las_records(out);
  REQUIRE(back);
  REQUIRE(relief::test::first_difference(back->records, ref->records) == "");
}

TEST_CASE("LAS reader refuses lying extra bytes and short records", "[las][attributes][reject]") {
  TempDir dir;
  const std::string path = dir.file("bad.las");
  TestLasOptions o;
  o.format = 1;
  o.points = 10;
  SECTION("Extra Bytes VLR describes more bytes than the records have") {
    o.extra = 1;
    o.extra_bytes_vlr = two_field_vlr();  // 3 bytes
    REQUIRE(write_test_las(path, o));
    auto r = relief::open_point_reader(path);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find("Extra Bytes") != std::string::npos);
    CHECK(r.status().message().find(path) != std::string::npos);
  }
  SECTION("Extra Bytes VLR not a whole number of descriptors") {
    o.extra = 3;
    o.extra_bytes_vlr = two_field_vlr();
    o.extra_bytes_vlr.pop_back();
    REQUIRE(write_test_las(path, o));
    auto r = relief::open_point_reader(path);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find("192") != std::string::npos);
  }
  SECTION("reserved extra bytes data type") {
    o.extra = 3;
    o.extra_bytes_vlr = relief::test::extra_bytes_descriptor(31, 0, "x");
    REQUIRE(write_test_las(path, o));
    CHECK_FALSE(relief::open_point_reader(path).is_ok());
  }
  SECTION("a GPS time that is not finite, named by file and point") {
    // It reached the encoder, whose error named a chunk and a point in the
    // chunk's order but not the file.
    REQUIRE(write_test_las(path, o));
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    std::uint32_t point_offset = 0;
    std::uint16_t record_length = 0;
    f.seekg(96);
    f.read(reinterpret_cast<char*>(&point_offset), 4);
    f.seekg(105);
    f.read(reinterpret_cast<char*>(&record_length), 2);
    const double bad =
        GENERATE(std::numeric_limits<double>::quiet_NaN(), -std::numeric_limits<double>::infinity());
    f.seekp(static_cast<std::streamoff>(point_offset + 7 * std::uint32_t{record_length} +
                                        20));  // format 1's time
    f.write(reinterpret_cast<const char*>(&bad), 8);
    f.close();
    auto r = relief::open_point_reader(path);
    REQUIRE(r.is_ok());
    relief::PointCloud batch;
    const relief::Result<std::size_t> got = (*r)->read(batch, 100);
    REQUIRE_FALSE(got.is_ok());
    CHECK(got.status().message().find(path + ": point 7 (counted from 0) has a GPS time of") !=
          std::string::npos);
  }
  SECTION("record length smaller than the format needs") {
    REQUIRE(write_test_las(path, o));
    std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(105);
    const std::uint16_t len = 27;  // format 1 needs 28
    f.write(reinterpret_cast<const char*>(&len), 2);
    f.close();
    auto r = relief::open_point_reader(path);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find("record length 27") != std::string::npos);
  }
}

TEST_CASE("parse_extra_bytes_vlr names, types, offsets and scales", "[las][attributes]") {
  const std::vector<std::uint8_t> v = two_field_vlr();
  auto fields = relief::parse_extra_bytes_vlr(v, 3, "t");
  REQUIRE(fields.is_ok());
  REQUIRE(fields->size() == 2);
  CHECK((*fields)[0].name == "height_above_ground");
  CHECK((*fields)[0].type_name == "uint16");
  CHECK((*fields)[0].offset == 0);
  CHECK((*fields)[1].name == "confidence");
  CHECK((*fields)[1].offset == 2);
  CHECK((*fields)[1].scale == 0.5);
  CHECK_FALSE(relief::parse_extra_bytes_vlr(v, 2, "t").is_ok());
  // Component types: the deprecated arrays repeat the scalar types.
  for (const auto& [type, base] : std::vector<std::pair<int, int>>{{0, 0}, {1, 1}, {10, 10}, {11, 1}, {20, 10},
                                                                    {21, 1}, {30, 10}, {31, 0}, {-1, 0}}) {
    CHECK(relief::extra_bytes_base_type(type) == base);
  }
}

TEST_CASE("LAS writer refuses values a legacy format cannot hold", "[las][attributes][reject]") {
  TempDir dir;
  relief::PointCloud c;
  c.positions = {{1, 2, 3}};
  c.las.classification = {40};
  relief::WriterOptions w;
  w.las_attributes = relief::kLasClassification;
  w.las_point_format = 1;
  const std::string out = dir.file("o.las");
  auto writer = relief::open_point_writer(out, w);
  REQUIRE(writer.is_ok());
  const relief::Status s = (*writer)->write(c);
  REQUIRE_FALSE(s.is_ok());
  CHECK(s.message().find("classification 40") != std::string::npos);
}

TEST_CASE("Shared LAS/LAZ twins: every field matches the reference decode", "[las][attributes][shared-data]") {
  for (const char* name : {"simple", "autzen_trim", "1.2-with-color.copc", "laszip-generated_with2bytespadding"}) {
    CAPTURE(name);
    const auto las = relief::test::shared_file(std::string("laz/") + name + ".las");
    const auto laz = relief::test::shared_file(std::string("laz/") + name + ".laz");
    if (!las || !laz) continue;
    const auto ref = read_las_records(*las);
    REQUIRE(ref);
    for (const std::string& path : {*las, *laz}) {
      CAPTURE(path);
      const ReadBack got = read_all(path);
      REQUIRE(got.info.las_point_format == ref->format);
      REQUIRE(relief::test::first_difference(to_records(got), ref->records) == "");
    }
  }
}

TEST_CASE("CSV classification column fills the LAS classification", "[xyz][attributes]") {
  TempDir dir;
  const std::string path = dir.file("c.csv");
  {
    std::ofstream f(path);
    f << "X,Y,Z,Classification\n1,2,3,2\n4,5,6,65\n7,8,9,0\n";
  }
  const ReadBack got = read_all(path);
  CHECK(got.info.las_attributes == relief::kLasClassification);
  REQUIRE(got.cloud.las.classification == std::vector<std::uint8_t>{2, 65, 0});
  relief::ReaderOptions o;
  o.xyz_columns = "x,y,z,c";
  const std::string bad = dir.file("bad.txt");
  {
    std::ofstream f(bad);
    f << "1 2 3 2.5\n";
  }
  auto r = relief::open_point_reader(bad, o);
  REQUIRE(r.is_ok());
  relief::PointCloud batch;
  auto n = (*r)->read(batch, 10);
  REQUIRE_FALSE(n.is_ok());
  CHECK(n.status().message().find("classification 2.5") != std::string::npos);
}

TEST_CASE("LAS attributes without a source format give LAS 1.4 format 6", "[las][attributes]") {
  TempDir dir;
  relief::PointCloud c;
  c.positions = {{1, 2, 3}, {4, 5, 6}};
  c.las.classification = {40, 200};
  relief::WriterOptions w;
  w.las_attributes = relief::kLasClassification;
  const std::string out = dir.file("o.las");
  auto writer = relief::open_point_writer(out, w);
  REQUIRE(writer.is_ok());
  REQUIRE((*writer)->write(c).is_ok());
  REQUIRE((*writer)->finish().is_ok());
  const auto back = read_las_records(out);
  REQUIRE(back);
  CHECK(back->format == 6);
  CHECK(back->version_minor == 4);
  REQUIRE(back->records.size() == 2);
  CHECK(back->records[0].classification == 40);
  CHECK(back->records[1].classification == 200);
  CHECK(back->records[0].return_number == 1);  // not carried: "return 1 of 1"
}

TEST_CASE("PLY and text output carry every LAS attribute and the PLY and text readers take each back",
          "[xyz][ply][attributes]") {
  TempDir dir;
  int ply_colors16 = 0;  // PLY outputs of 16-bit colours (ushort properties)
  for (const int format : {1, 3, 6, 7, 8}) {
    CAPTURE(format);
    TestLasOptions o;
    o.format = format;
    o.points = 1500;
    o.seed = static_cast<std::uint32_t>(300 + format);
    o.extra = 3;
    o.extra_bytes_vlr = two_field_vlr();  // uint16 height_above_ground, uint8 confidence x 0.5
    const std::string in = dir.file("in" + std::to_string(format) + ".las");
    REQUIRE(write_test_las(in, o));
    const ReadBack src = read_all(in);
    for (const char* name : {"out.csv", "out.xyz", "out.ply", "big.ply", "ascii.ply"}) {
      CAPTURE(name);
      const std::string out = dir.file(name);
      relief::WriterOptions w = options_from(src.info, src.cloud.las.extra_bytes_size);
      if (std::string(name) == "big.ply") w.ply_encoding = relief::PlyEncoding::kBinaryBigEndian;
      if (std::string(name) == "ascii.ply") w.ply_encoding = relief::PlyEncoding::kAscii;
      auto writer = relief::open_point_writer(out, w);
      REQUIRE(writer.is_ok());
      REQUIRE((*writer)->write(src.cloud).to_string() == "ok");
      REQUIRE((*writer)->finish().is_ok());
      const ReadBack back = read_all(out);
      INFO((back.info.warnings.empty() ? std::string() : back.info.warnings[0]));
      CHECK(back.info.warnings.empty());
      const relief::PointCloud& a = src.cloud;
      const relief::PointCloud& b = back.cloud;
      REQUIRE(b.size() == a.size());
      // Text prints the LAS grid's decimals (849017.32, as las2txt), which
      // read back to the double nearest that decimal: the same grid integer,
      // within a rounding of X * scale + offset. Binary PLY keeps the doubles.
      const bool text = !std::string(name).ends_with(".ply") || std::string(name) == "ascii.ply";
      if (text) {
        CHECK(same_grid_integers(b.positions, a.positions, src.info.scale, src.info.offset));
      } else {
        CHECK(b.positions == a.positions);
      }
      CHECK(b.colors == a.colors);
      CHECK(b.intensities == a.intensities);
      // Every attribute; text leaves out the colours' low bytes (its colours
      // are 8-bit), PLY carries 16-bit colours as ushort properties.
      const bool ply = std::string(name).ends_with(".ply");
      const bool colors16 = (a.las.carried() & relief::kLasColorLow) != 0 && !src.info.las_colors_8bit;
      const std::uint32_t low = ply && colors16 ? 0u : std::uint32_t{relief::kLasColorLow};
      CHECK(b.las.carried() == (a.las.carried() & ~low));
      relief::test::check_same_las(b.las, a.las);
      if (ply && colors16) {
        ++ply_colors16;
        CHECK(b.las.color_low == a.las.color_low);
        CHECK_FALSE(back.info.las_colors_8bit);
      }
      if (ply) {
        // PLY keeps the extra bytes' types: the same bytes.
        CHECK(b.las.extra_bytes_size == 3);
        CHECK(b.las.extra_bytes == a.las.extra_bytes);
        continue;
      }
      // Text: float64 fields, the uint16 as it is, the scaled uint8 scaled.
      REQUIRE(b.las.extra_bytes_size == 16);
      std::size_t same = 0;
      for (std::size_t i = 0; i < a.size(); ++i) {
        const std::uint8_t* e = a.las.extra_bytes.data() + i * 3;
        double v[2];
        std::memcpy(v, b.las.extra_bytes.data() + i * 16, 16);
        same += v[0] == (e[0] | e[1] << 8) && v[1] == e[2] * 0.5 ? 1 : 0;
      }
      CHECK(same == a.size());
    }
  }
  CHECK(ply_colors16 == 9);  // formats 3, 7, 8: three PLY encodings each
}

TEST_CASE("PLY vertex properties named as LAS dimensions fill the LAS attributes", "[ply][attributes]") {
  TempDir dir;
  const std::string path = dir.file("pdal.ply");
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\nproperty double z\n"
      "property uchar Classification\nproperty double GpsTime\nproperty float ScanAngleRank\n"
      "property uchar ReturnNumber\nproperty int class\nproperty float scalar_Withheld\nend_header\n";
  {
    std::ofstream f(path);
    f << header << "1 2 3 6 100.5 -12.006 2 900 1\n4 5 6 2 101.25 7 1 -3 0\n";
  }
  const ReadBack got = read_all(path);
  CHECK(got.info.las_attributes == (relief::kLasClassification | relief::kLasGpsTime | relief::kLasScanAngle |
                                    relief::kLasReturnNumber | relief::kLasClassFlags | relief::kLasExtraBytes));
  CHECK(got.cloud.las.classification == std::vector<std::uint8_t>{6, 2});
  CHECK(got.cloud.las.gps_time == std::vector<double>{100.5, 101.25});
  CHECK(got.cloud.las.scan_angle == std::vector<std::int32_t>{-12006, 7000});
  CHECK(got.cloud.las.return_number == std::vector<std::uint8_t>{2, 1});
  CHECK(got.cloud.las.class_flags == std::vector<std::uint8_t>{4, 0});
  // "class" is a label of its own: kept as extra bytes.
  REQUIRE(got.cloud.las.extra_bytes_size == 4);
  std::int32_t label = 0;
  std::memcpy(&label, got.cloud.las.extra_bytes.data() + 4, 4);
  CHECK(label == -3);
  // A value the LAS dimension cannot hold is refused, naming vertex and property.
  {
    std::ofstream f(path);
    f << header << "1 2 3 6 100.5 -12.006 2 900 1\n4 5 6 2 101.25 7 16 -3 0\n";
  }
  auto r = relief::open_point_reader(path);
  REQUIRE(r.is_ok());
  relief::PointCloud batch;
  auto n = (*r)->read(batch, 10);
  REQUIRE_FALSE(n.is_ok());
  CHECK(n.status().message().find("pdal.ply: vertex 1: property 'ReturnNumber': return number 16 is not a whole "
                                  "number from 0 to 15") != std::string::npos);
}

TEST_CASE("PLY and text writers refuse a batch without the LAS attributes they were opened with",
          "[xyz][ply][attributes]") {
  TempDir dir;
  relief::PointCloud c;
  c.positions = {{1, 2, 3}, {4, 5, 6}};
  c.las.classification = {2, 6};
  relief::WriterOptions w;
  w.las_attributes = relief::kLasClassification | relief::kLasGpsTime;
  for (const char* name : {"a.csv", "a.ply"}) {
    INFO(name);
    auto writer = relief::open_point_writer(dir.file(name), w);
    REQUIRE(writer.is_ok());
    const relief::Status s = (*writer)->write(c);  // no GPS times
    CHECK(s.code() == relief::StatusCode::kInvalidArgument);
    CHECK(s.message().find("lacks a LAS attribute or extra bytes the writer was opened with") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir.file(name)));
  }
}

TEST_CASE("PLY colours wider than 8 bits come back as the same 16-bit levels", "[ply][attributes]") {
  TempDir dir;
  // ushort red green blue (as PDAL writes them): true 16-bit levels, and
  // 8-bit levels stored in ushort fields (every level <= 255).
  for (const bool sixteen : {true, false}) {
    for (const char* encoding : {"binary_little_endian", "binary_big_endian", "ascii"}) {
      CAPTURE(sixteen, encoding);
      const bool ascii = std::string(encoding) == "ascii";
      const bool big = std::string(encoding) == "binary_big_endian";
      const std::size_t n = 2000;  // beyond the 777-point batches of read_all
      std::vector<std::array<std::uint16_t, 3>> levels(n);
      std::uint32_t state = 12345;
      const auto next = [&] {
        state = state * 1664525u + 1013904223u;
        return static_cast<std::uint16_t>(state >> 16);
      };
      for (auto& l : levels) {
        for (auto& v : l) v = sixteen ? next() : static_cast<std::uint16_t>(next() & 0xFF);
      }
      const std::string in = dir.file(std::string("in-") + (sixteen ? "16" : "8") + "-" + encoding + ".ply");
      {
        std::ofstream f(in, std::ios::binary);
        f << "ply\nformat " << encoding << " 1.0\nelement vertex " << n
          << "\nproperty float x\nproperty float y\nproperty float z\n"
             "property ushort red\nproperty ushort green\nproperty ushort blue\nend_header\n";
        for (std::size_t i = 0; i < n; ++i) {
          const float xyz[3] = {static_cast<float>(i), 1.5f, -2.0f};
          if (ascii) {
            f << xyz[0] << ' ' << xyz[1] << ' ' << xyz[2] << ' ' << levels[i][0] << ' ' << levels[i][1] << ' '
              << levels[i][2] << '\n';
            continue;
          }
          for (const float v : xyz) {
            std::uint8_t b[4];
            std::memcpy(b, &v, 4);
            if (big) std::reverse(b, b + 4);
            f.write(reinterpret_cast<const char*>(b), 4);
          }
          for (const std::uint16_t v : levels[i]) {
            const std::uint8_t b[2] = {static_cast<std::uint8_t>(big ? v >> 8 : v & 0xFF),
                                       static_cast<std::uint8_t>(big ? v & 0xFF : v >> 8)};
            f.write(reinterpret_cast<const char*>(b), 2);
          }
        }
      }
      const auto levels_of = [](const relief::PointCloud& c, bool low) {
        std::vector<std::array<std::uint16_t, 3>> out;
        for (std::size_t i = 0; i < c.size(); ++i) {
          const relief::Rgb8 h = c.colors[i];
          const relief::Rgb8 l = low ? c.las.color_low[i] : relief::Rgb8{};
          out.push_back({static_cast<std::uint16_t>(low ? h.r << 8 | l.r : h.r),
                         static_cast<std::uint16_t>(low ? h.g << 8 | l.g : h.g),
                         static_cast<std::uint16_t>(low ? h.b << 8 | l.b : h.b)});
        }
        return out;
      };
      const ReadBack got = read_all(in);
      REQUIRE(got.cloud.size() == n);
      CHECK((got.info.las_attributes & relief::kLasColorLow) != 0);
      CHECK(got.info.las_colors_8bit == !sixteen);
      // 16-bit: narrowed level and low byte give the level back; 8-bit
      // levels in 16-bit fields: the levels themselves (low byte = level).
      CHECK(levels_of(got.cloud, sixteen) == levels);
      // Written back as PLY: ushort for 16-bit levels, uchar for 8-bit ones,
      // and read again, the same levels.
      const std::string out = dir.file("out.ply");
      std::filesystem::remove(out);
      auto writer = relief::open_point_writer(out, options_from(got.info, 0));
      REQUIRE(writer.is_ok());
      REQUIRE((*writer)->write(got.cloud).to_string() == "ok");
      REQUIRE((*writer)->finish().is_ok());
      std::ifstream header(out);
      std::string text((std::istreambuf_iterator<char>(header)), {});
      CHECK(text.find(sixteen ? "property ushort red" : "property uchar red") != std::string::npos);
      const ReadBack again = read_all(out);
      REQUIRE(again.cloud.size() == n);
      CHECK(levels_of(again.cloud, sixteen) == levels);
    }
  }
}
