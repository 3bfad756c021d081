// E57 input: files written here by a small writer of the standard's layout
// (tests/io/e57_writer.h), read back through open_point_reader: scans with
// poses in cartesian and spherical coordinates, invalid points, colours,
// intensities, times, returns and other fields, bytestreams split over
// packets, every batch size; and the files that must be refused, each with
// a message naming the file and the problem. Also `relief compress` of one.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "io/e57_writer.h"
#include "relief/io.h"
#include "support/run_cli.h"
#include "support/temp_dir.h"

namespace relief {
namespace {

namespace e57 = test::e57;
using test::TempDir;

void spit(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                               static_cast<std::streamsize>(bytes.size()));
}

// Every point and attribute of the file, read in batches of `batch`.
struct Read {
  PointCloud cloud;
  PointStreamInfo info;
};
Read read_all(const std::string& path, std::size_t batch, const ReaderOptions& options = {}) {
  auto reader = open_point_reader(path, options);
  if (!reader.is_ok()) FAIL(reader.status().message());
  Read out;
  PointCloud b;
  for (;;) {
    auto n = (*reader)->read(b, batch);
    if (!n.is_ok()) FAIL(n.status().message());
    REQUIRE(*n <= batch);
    REQUIRE(b.size() == *n);
    if (*n == 0) break;
    if (out.cloud.size() == 0) {
      out.cloud = b;
    } else {
      out.cloud.append_points(b);
    }
  }
  out.info = (*reader)->info();
  return out;
}

// The message of the error opening or reading `path` gives.
std::string error_of(const std::string& path, const ReaderOptions& options = {}) {
  auto reader = open_point_reader(path, options);
  if (!reader.is_ok()) return reader.status().message();
  PointCloud b;
  for (;;) {
    auto n = (*reader)->read(b, 1000);
    if (!n.is_ok()) return n.status().message();
    if (*n == 0) return "";
  }
}

void require_error(const std::string& path, const std::string& what) {
  const std::string m = error_of(path);
  INFO(m);
  REQUIRE(m.rfind(path + ": ", 0) == 0);
  REQUIRE(m.find(what) != std::string::npos);
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

void require_point(const Vec3d& got, double x, double y, double z) {
  INFO("got (" << got.x << ", " << got.y << ", " << got.z << ") want (" << x << ", " << y << ", " << z << ")");
  REQUIRE(same_bits(got.x, x));
  REQUIRE(same_bits(got.y, y));
  REQUIRE(same_bits(got.z, z));
}

// Two registered scans: A with ScaledInteger coordinates turned a quarter
// about z and moved, over three packets (with index and empty packets
// between them); B with double coordinates, moved only.
std::vector<e57::Scan> two_scans(int n) {
  std::vector<std::int64_t> xs, ys, zs, is;
  std::vector<double> bx, by, bz, bi;
  for (int i = 0; i < n; ++i) {
    xs.push_back((i * 37) % 4001 - 2000);
    ys.push_back((i * 91) % 4001 - 2000);
    zs.push_back(i % 100);
    is.push_back((i * 13) % 4096);
    bx.push_back(0.1 * i);
    by.push_back(-3.7 + i);
    bz.push_back(1e-3 * (i % 7));
    bi.push_back(static_cast<float>(0.01 * (i % 100)));
  }
  e57::Scan a;
  a.fields = {e57::Field::scaled("cartesianX", -2000, 2000, 0.25, 100, xs),
              e57::Field::scaled("cartesianY", -2000, 2000, 0.25, -50, ys),
              e57::Field::scaled("cartesianZ", 0, 99, 0.5, 0, zs), e57::Field::integer("intensity", 0, 4095, is)};
  a.pose = e57::Pose{std::sqrt(0.5), 0, 0, std::sqrt(0.5), 10, 20, 30};
  a.packets = 3;
  a.extra_packets = true;
  e57::Scan b;
  b.fields = {e57::Field::real("cartesianX", bx), e57::Field::real("cartesianY", by), e57::Field::real("cartesianZ", bz),
              e57::Field::real("intensity", bi, true)};
  b.pose = e57::Pose{1, 0, 0, 0, 1000.5, -20.25, 3};
  return {a, b};
}

TEST_CASE("E57: the test writer's CRC-32C gives the standard check value", "[io][e57]") {
  const char* digits = "123456789";
  CHECK(e57::crc32c(reinterpret_cast<const std::uint8_t*>(digits), 9) == 0xE3069283u);
}

TEST_CASE("E57: two scans with poses, every batch size, in the file's frame exactly", "[io][e57]") {
  TempDir dir;
  const int n = 700;
  const auto scans = two_scans(n);
  spit(dir.file("two.e57"), e57::write(scans));
  const Read all = read_all(dir.file("two.e57"), std::size_t{1} << 20);
  CHECK(all.info.format == "e57");
  REQUIRE(all.info.point_count == std::uint64_t{2 * n});
  CHECK(all.info.has_intensity);
  CHECK_FALSE(all.info.has_colors);
  CHECK(all.info.las_attributes == 0);
  CHECK(all.info.skipped_points == 0);
  CHECK(all.info.warnings.empty());
  REQUIRE(all.cloud.size() == 2u * n);
  const auto& a = scans[0].fields;
  const auto& b = scans[1].fields;
  for (int i = 0; i < n; ++i) {
    // A: a quarter turn about z (x, y) -> (-y, x), then (10, 20, 30).
    const double x = static_cast<double>(a[0].ints[i]) * 0.25 + 100;
    const double y = static_cast<double>(a[1].ints[i]) * 0.25 - 50;
    const double z = static_cast<double>(a[2].ints[i]) * 0.5;
    require_point(all.cloud.positions[i], -y + 10, x + 20, z + 30);
    REQUIRE(all.cloud.intensities[i] == static_cast<float>(a[3].ints[i]));
    require_point(all.cloud.positions[n + i], b[0].reals[i] + 1000.5, b[1].reals[i] - 20.25, b[2].reals[i] + 3);
    REQUIRE(all.cloud.intensities[n + i] == static_cast<float>(b[3].reals[i]));
  }
  for (std::size_t batch : {std::size_t{1}, std::size_t{7}, std::size_t{699}}) {
    INFO("batch " << batch);
    const Read again = read_all(dir.file("two.e57"), batch);
    REQUIRE(again.cloud.size() == all.cloud.size());
    REQUIRE(std::memcmp(again.cloud.positions.data(), all.cloud.positions.data(),
                        all.cloud.size() * sizeof(Vec3d)) == 0);
    REQUIRE(again.cloud.intensities == all.cloud.intensities);
  }
}

TEST_CASE("E57: a spherical scan becomes x y z", "[io][e57]") {
  TempDir dir;
  std::vector<double> r, az, el;
  for (int i = 0; i < 50; ++i) {
    r.push_back(1 + 0.5 * i);
    az.push_back(-3 + 0.12 * i);
    el.push_back(-1.2 + 0.05 * i);
  }
  e57::Scan s;
  s.fields = {e57::Field::real("sphericalRange", r), e57::Field::real("sphericalAzimuth", az),
              e57::Field::real("sphericalElevation", el)};
  s.packets = 2;
  spit(dir.file("sph.e57"), e57::write({s}));
  const Read got = read_all(dir.file("sph.e57"), 16);
  REQUIRE(got.cloud.size() == 50);
  CHECK_FALSE(got.info.has_intensity);
  for (std::size_t i = 0; i < 50; ++i) {
    require_point(got.cloud.positions[i], r[i] * std::cos(el[i]) * std::cos(az[i]),
                  r[i] * std::cos(el[i]) * std::sin(az[i]), r[i] * std::sin(el[i]));
  }
}

TEST_CASE("E57: points marked invalid are skipped and counted", "[io][e57]") {
  TempDir dir;
  std::vector<double> x, y, z;
  std::vector<std::int64_t> state;
  for (int i = 0; i < 30; ++i) {
    x.push_back(i);
    y.push_back(2 * i);
    z.push_back(3 * i);
    state.push_back(i % 5 == 1 ? 1 : i % 5 == 3 ? 2 : 0);
  }
  e57::Scan s;
  s.fields = {e57::Field::real("cartesianX", x), e57::Field::real("cartesianY", y), e57::Field::real("cartesianZ", z),
              e57::Field::integer("cartesianInvalidState", 0, 2, state)};
  spit(dir.file("holes.e57"), e57::write({s}));
  const Read got = read_all(dir.file("holes.e57"), 4);
  CHECK(got.info.point_count == std::uint64_t{30});
  CHECK(got.info.skipped_points == 12);
  REQUIRE(got.cloud.size() == 18);
  std::size_t k = 0;
  for (int i = 0; i < 30; ++i) {
    if (state[i] != 0) continue;
    require_point(got.cloud.positions[k++], i, 2 * i, 3 * i);
  }
}

// One scan of `n` points with the given extra fields.
e57::Scan scan_with(int n, std::vector<e57::Field> more) {
  std::vector<std::int64_t> c;
  for (int i = 0; i < n; ++i) c.push_back(i);
  e57::Scan s;
  s.fields = {e57::Field::integer("cartesianX", 0, n, c), e57::Field::integer("cartesianY", 0, n, c),
              e57::Field::integer("cartesianZ", 0, n, c)};
  for (auto& f : more) s.fields.push_back(std::move(f));
  return s;
}

TEST_CASE("E57: 8-bit and 16-bit colours come back exactly", "[io][e57]") {
  TempDir dir;
  const int n = 300;
  std::vector<std::int64_t> r8, g8, b8, r16, g16, b16;
  for (int i = 0; i < n; ++i) {
    r8.push_back(i % 256);
    g8.push_back((i * 7) % 256);
    b8.push_back(255 - i % 256);
    r16.push_back((i * 211) % 65536);
    g16.push_back((i * 4099) % 65536);
    b16.push_back(65535 - i);
  }
  spit(dir.file("c8.e57"), e57::write({scan_with(n, {e57::Field::integer("colorRed", 0, 255, r8),
                                                     e57::Field::integer("colorGreen", 0, 255, g8),
                                                     e57::Field::integer("colorBlue", 0, 255, b8)})}));
  const Read c8 = read_all(dir.file("c8.e57"), 100);
  REQUIRE(c8.info.has_colors);
  CHECK(c8.info.las_attributes == 0);
  REQUIRE(c8.cloud.colors.size() == n);
  for (int i = 0; i < n; ++i) {
    REQUIRE(c8.cloud.colors[i] == Rgb8{static_cast<std::uint8_t>(r8[i]), static_cast<std::uint8_t>(g8[i]),
                                       static_cast<std::uint8_t>(b8[i])});
  }
  spit(dir.file("c16.e57"), e57::write({scan_with(n, {e57::Field::integer("colorRed", 0, 65535, r16),
                                                      e57::Field::integer("colorGreen", 0, 65535, g16),
                                                      e57::Field::integer("colorBlue", 0, 65535, b16)})}));
  const Read c16 = read_all(dir.file("c16.e57"), 100);
  REQUIRE(c16.info.has_colors);
  CHECK(c16.info.las_attributes == kLasColorLow);
  REQUIRE(c16.cloud.las.color_low.size() == n);
  for (int i = 0; i < n; ++i) {
    const Rgb8 c = c16.cloud.colors[i], lo = c16.cloud.las.color_low[i];
    REQUIRE(las_color_level(c.r, lo.r, false) == r16[i]);
    REQUIRE(las_color_level(c.g, lo.g, false) == g16[i]);
    REQUIRE(las_color_level(c.b, lo.b, false) == b16[i]);
  }
}

TEST_CASE("E57: times, returns and other fields", "[io][e57]") {
  TempDir dir;
  const int n = 120;
  std::vector<double> t;
  std::vector<std::int64_t> index, count, row, wide;
  for (int i = 0; i < n; ++i) {
    t.push_back(1e5 + 0.001 * i);
    count.push_back(1 + i % 4);
    index.push_back(i % (1 + i % 4));
    row.push_back(i * 3);
    wide.push_back(i * 100);  // returnCount up to 12000: no LAS field holds it
  }
  std::vector<e57::Field> fields = {e57::Field::real("timeStamp", t), e57::Field::integer("returnIndex", 0, 3, index),
                                    e57::Field::integer("returnCount", 0, 4, count),
                                    e57::Field::integer("rowIndex", 0, 1000, row)};
  spit(dir.file("t.e57"), e57::write({scan_with(n, fields)}));
  const Read got = read_all(dir.file("t.e57"), 50);
  CHECK(got.info.las_attributes == (kLasGpsTime | kLasReturnNumber | kLasNumberOfReturns | kLasExtraBytes));
  REQUIRE(got.info.extra_bytes_size == 2);  // rowIndex 0..1000: u16
  REQUIRE(got.cloud.las.gps_time.size() == n);
  REQUIRE(got.cloud.las.extra_bytes.size() == 2 * n);
  for (int i = 0; i < n; ++i) {
    REQUIRE(same_bits(got.cloud.las.gps_time[i], t[i]));
    REQUIRE(got.cloud.las.return_number[i] == index[i] + 1);
    REQUIRE(got.cloud.las.number_of_returns[i] == count[i]);
    REQUIRE(got.cloud.las.extra_bytes[2 * i] + 256 * got.cloud.las.extra_bytes[2 * i + 1] == row[i]);
  }
  // A return count LAS cannot hold stays a field of its own; without extra
  // bytes the other fields are skipped, with a warning naming them.
  fields[2] = e57::Field::integer("returnCount", 0, 20000, wide);
  spit(dir.file("w.e57"), e57::write({scan_with(n, fields)}));
  const Read w = read_all(dir.file("w.e57"), 50);
  CHECK(w.info.las_attributes == (kLasGpsTime | kLasReturnNumber | kLasExtraBytes));
  CHECK(w.info.extra_bytes_size == 4);
  ReaderOptions off;
  off.extra_bytes = false;
  const Read none = read_all(dir.file("w.e57"), 50, off);
  CHECK(none.info.las_attributes == (kLasGpsTime | kLasReturnNumber));
  CHECK(none.cloud.las.extra_bytes.empty());
  REQUIRE(none.info.warnings.size() == 1);
  CHECK(none.info.warnings[0].find("'returnCount', 'rowIndex'") != std::string::npos);
}

TEST_CASE("E57: damaged and unsupported files are refused, naming the file and the problem", "[io][e57]") {
  TempDir dir;
  const auto scans = two_scans(200);
  const std::vector<std::uint8_t> good = e57::write(scans);
  const std::string path = dir.file("bad.e57");

  auto bytes = good;
  bytes[3] = 'X';
  spit(path, bytes);
  require_error(path, "not an E57 file");

  bytes = good;
  bytes[e57::kPage + 100] ^= 0x10;  // a byte of page 1, whose CRC no longer matches
  spit(path, bytes);
  require_error(path, "page 1 (bytes 1024..2047) fails its CRC-32C check");

  spit(path, std::vector<std::uint8_t>(good.begin(), good.end() - 1000));
  require_error(path, "(a truncated file)");

  auto s = scans;
  s[1].file_offset = good.size() + 4096;
  spit(path, e57::write(s));
  require_error(path, "scan 1 (data3D child 1): the points' fileOffset " + std::to_string(good.size() + 4096) +
                          " is beyond the end of the file");

  s = scans;
  s[0].record_count = 201;
  spit(path, e57::write(s));
  require_error(path, "scan 0 (data3D child 0): the bytestream of field 'cartesianX' ends after 200 values but "
                      "recordCount is 201");
  s[0].record_count = 1000000;
  spit(path, e57::write(s));
  require_error(path, "recordCount 1000000 needs 43 bits a record");

  s = scans;
  s[1].codecs = "<vectorChild type=\"Structure\"><inputs type=\"Vector\"/><zlibCodec type=\"Structure\"/></vectorChild>";
  spit(path, e57::write(s));
  require_error(path, "scan 1 (data3D child 1) is compressed with the codec 'zlibCodec'; Relief reads the default "
                      "bitpack codec only");

  s = scans;
  s[1].fields[3].precision = "half";
  spit(path, e57::write(s));
  require_error(path, "field 'intensity': precision 'half' is neither");

  s = scans;
  s[1].fields.pop_back();  // no intensity in the second scan
  spit(path, e57::write(s));
  require_error(path, "scan 1 (data3D child 1) carries other attributes than scan 0");

  s = scans;
  s[0].fields[2].ints[17] = 120;  // above cartesianZ's maximum 99, within its 7 bits
  spit(path, e57::write(s));
  require_error(path, "record 17: field 'cartesianZ' holds a value above its maximum 99");

  // Every prefix: an error or the whole file, never a crash.
  for (std::size_t cut = 0; cut < good.size(); cut += 97) {
    spit(path, std::vector<std::uint8_t>(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(cut)));
    CHECK_FALSE(error_of(path).empty());
  }
}

TEST_CASE("E57: an invalid point is skipped before its other values are checked", "[io][e57]") {
  TempDir dir;
  const double nan = std::nan("");
  // Point 1: no return, with NaN coordinates, intensity and time and a row
  // above its maximum; point 2: valid, its intensity and time flagged
  // invalid (and NaN); points 0 and 3 valid.
  e57::Scan s;
  s.fields = {e57::Field::real("cartesianX", {1, nan, 3, 4}),
              e57::Field::real("cartesianY", {1, nan, 3, 4}),
              e57::Field::real("cartesianZ", {1, nan, 3, 4}),
              e57::Field::integer("cartesianInvalidState", 0, 2, {0, 2, 0, 0}),
              e57::Field::real("intensity", {0.5, nan, nan, 0.25}),
              e57::Field::integer("isIntensityInvalid", 0, 1, {0, 0, 1, 0}),
              e57::Field::real("timeStamp", {10, nan, nan, 13}),
              e57::Field::integer("isTimeStampInvalid", 0, 1, {0, 0, 1, 0}),
              e57::Field::integer("rowIndex", 0, 5, {0, 7, 2, 3})};
  spit(dir.file("skip.e57"), e57::write({s}));
  const Read got = read_all(dir.file("skip.e57"), 2);
  CHECK(got.info.skipped_points == 1);
  REQUIRE(got.cloud.size() == 3);
  require_point(got.cloud.positions[1], 3, 3, 3);
  CHECK(got.cloud.intensities == std::vector<float>{0.5f, 0.0f, 0.25f});
  CHECK(got.cloud.las.gps_time == std::vector<double>{10, 0, 13});
  // The flags stay fields of their own.
  CHECK(got.info.extra_bytes_size == 3);

  // On a valid point that does not flag it, a NaN intensity or time is an
  // error naming the record, and so is a value above its maximum.
  const std::string path = dir.file("bad.e57");
  auto bad = s;
  bad.fields[5].ints[2] = 0;
  spit(path, e57::write({bad}));
  require_error(path, "scan 0 (data3D child 0): record 2: intensity nan is not a finite float");
  bad = s;
  bad.fields[7].ints[2] = 0;
  spit(path, e57::write({bad}));
  require_error(path, "scan 0 (data3D child 0): record 2: timeStamp nan is not a finite number");
  bad = s;
  bad.fields[3].ints[1] = 0;
  bad.fields[0].reals[1] = bad.fields[1].reals[1] = bad.fields[2].reals[1] = 2;
  bad.fields[4].reals[1] = bad.fields[6].reals[1] = 1;
  spit(path, e57::write({bad}));
  require_error(path,
                "scan 0 (data3D child 0): record 1: field 'rowIndex' holds a value above its maximum 5");
  bad.fields[8].ints[1] = 1;
  bad.fields[6].reals[1] = std::numeric_limits<double>::infinity();
  spit(path, e57::write({bad}));
  require_error(path, "scan 0 (data3D child 0): record 1: timeStamp inf is not a finite number");
}

TEST_CASE("E57: colours of other ranges than 0..255 and 0..65535 are scaled to 16 bits", "[io][e57]") {
  TempDir dir;
  const int n = 64;
  std::vector<std::int64_t> r, g, b;
  for (int i = 0; i < n; ++i) {
    r.push_back((i * 16) % 1024);
    g.push_back(1023 - (i * 16) % 1024);
    b.push_back((i * 37) % 1024);
  }
  const auto scaled = [](std::int64_t v, double lo, double hi) {
    return std::clamp<long>(std::lround((static_cast<double>(v) - lo) * 65535 / (hi - lo)), 0, 65535);
  };
  const std::string limits =
      "<colorLimits type=\"Structure\"><colorRedMinimum type=\"Integer\">0</colorRedMinimum><colorRedMaximum "
      "type=\"Integer\">1023</colorRedMaximum><colorGreenMinimum type=\"Integer\">0</colorGreenMinimum>"
      "<colorGreenMaximum type=\"Integer\">1023</colorGreenMaximum><colorBlueMinimum "
      "type=\"Integer\">0</colorBlueMinimum><colorBlueMaximum "
      "type=\"Integer\">1023</colorBlueMaximum></colorLimits>";
  // 10-bit levels: the range of colorLimits, or else of the fields (here
  // 0..1023 but for blue's 0..2047, of which 1023 is about half).
  for (const bool with_limits : {true, false}) {
    INFO("colorLimits " << with_limits);
    e57::Scan s = scan_with(
        n, {e57::Field::integer("colorRed", 0, 1023, r), e57::Field::integer("colorGreen", 0, 1023, g),
            e57::Field::integer("colorBlue", 0, with_limits ? 1023 : 2047, b)});
    if (with_limits) s.extra_xml = limits;
    spit(dir.file("c10.e57"), e57::write({s}));
    const Read got = read_all(dir.file("c10.e57"), 10);
    REQUIRE(got.info.has_colors);
    CHECK(got.info.las_attributes == kLasColorLow);
    REQUIRE(got.cloud.las.color_low.size() == n);
    for (int i = 0; i < n; ++i) {
      const Rgb8 c = got.cloud.colors[i], lo = got.cloud.las.color_low[i];
      REQUIRE(las_color_level(c.r, lo.r, false) == scaled(r[i], 0, 1023));
      REQUIRE(las_color_level(c.g, lo.g, false) == scaled(g[i], 0, 1023));
      REQUIRE(las_color_level(c.b, lo.b, false) == scaled(b[i], 0, with_limits ? 1023 : 2047));
    }
  }
  // 16-bit fields whose colorLimits say 0..255: levels above 255 are clamped.
  e57::Scan s = scan_with(3, {e57::Field::integer("colorRed", 0, 65535, {0, 128, 300}),
                              e57::Field::integer("colorGreen", 0, 65535, {255, 1, 2}),
                              e57::Field::integer("colorBlue", 0, 65535, {3, 4, 5})});
  s.extra_xml =
      "<colorLimits type=\"Structure\"><colorRedMaximum type=\"Integer\">255</colorRedMaximum>"
      "<colorGreenMaximum type=\"Integer\">255</colorGreenMaximum><colorBlueMaximum "
      "type=\"Integer\">255</colorBlueMaximum></colorLimits>";
  spit(dir.file("c255.e57"), e57::write({s}));
  const Read got = read_all(dir.file("c255.e57"), 10);
  REQUIRE(got.cloud.las.color_low.size() == 3);
  CHECK(las_color_level(got.cloud.colors[0].r, got.cloud.las.color_low[0].r, false) == 0);
  CHECK(las_color_level(got.cloud.colors[1].r, got.cloud.las.color_low[1].r, false) == 128 * 257);
  CHECK(las_color_level(got.cloud.colors[2].r, got.cloud.las.color_low[2].r, false) == 65535);
  CHECK(las_color_level(got.cloud.colors[0].g, got.cloud.las.color_low[0].g, false) == 65535);
}

TEST_CASE("E57: scans of other grid sizes and scans without points", "[io][e57]") {
  TempDir dir;
  // rowIndex 0..100 (u8 alone) and 0..1000 (u16): both as u16.
  std::vector<std::int64_t> rows_a, rows_b;
  for (int i = 0; i < 20; ++i) {
    rows_a.push_back(i * 5);
    rows_b.push_back(i * 50);
  }
  e57::Scan a = scan_with(20, {e57::Field::integer("rowIndex", 0, 100, rows_a)});
  e57::Scan b = scan_with(20, {e57::Field::integer("rowIndex", 0, 1000, rows_b)});
  // Scans without points: one with another prototype, one never written
  // (fileOffset 0, as libE57Format leaves it).
  e57::Scan other = scan_with(0, {e57::Field::integer("colorRed", 0, 255, {})});
  e57::Scan unwritten = scan_with(0, {e57::Field::real("intensity", {})});
  unwritten.file_offset = 0;
  spit(dir.file("grids.e57"), e57::write({other, a, unwritten, b}));
  const Read got = read_all(dir.file("grids.e57"), 7);
  CHECK(got.info.point_count == 40);
  CHECK_FALSE(got.info.has_colors);
  CHECK_FALSE(got.info.has_intensity);
  CHECK(got.info.las_attributes == kLasExtraBytes);
  REQUIRE(got.info.extra_bytes_size == 2);
  REQUIRE(got.cloud.size() == 40);
  for (std::size_t i = 0; i < 40; ++i) {
    const std::int64_t want = i < 20 ? rows_a[i] : rows_b[i - 20];
    REQUIRE(got.cloud.las.extra_bytes[2 * i] + 256 * got.cloud.las.extra_bytes[2 * i + 1] == want);
  }
  // Messages name scans by their place in data3D, empty ones counted.
  b.fields[3].ints[4] = 1023;  // above rowIndex's maximum, within its 10 bits
  spit(dir.file("grids.e57"), e57::write({other, a, unwritten, b}));
  require_error(dir.file("grids.e57"),
                "scan 3 (data3D child 3): record 4: field 'rowIndex' holds a value above");
  // Scans with points still must carry the same attributes.
  spit(dir.file("grids.e57"), e57::write({other, a, unwritten, scan_with(3, {})}));
  require_error(dir.file("grids.e57"),
                "scan 3 (data3D child 3) carries other attributes than scan 1 (data3D child 1)");
}

TEST_CASE("E57: XML elements with too many attributes, or too long ones, are refused", "[io][e57]") {
  TempDir dir;
  const std::string path = dir.file("xml.e57");
  e57::Scan s = scan_with(3, {});
  s.extra_xml = "<note a=\"" + std::string((std::size_t{1} << 20) + 1, 'b') + "\"/>";
  spit(path, e57::write({s}));
  require_error(
      path,
      "the XML section: attribute 'a' of element 'note' is 1048577 bytes long; at most 1048576 are read");
  s.extra_xml = "<note>" + std::string((std::size_t{1} << 20) + 1, 'b') + "</note>";
  spit(path, e57::write({s}));
  require_error(path, "the XML section: element 'note' has more than 1048576 bytes of text");
  s.extra_xml = "<note";
  for (int i = 0; i < 1025; ++i) s.extra_xml += " a" + std::to_string(i) + "=\"\"";
  s.extra_xml += "/>";
  spit(path, e57::write({s}));
  require_error(path, "the XML section: element 'note' has more than 1024 attributes");
  // '=' in comments, CDATA, text and quoted values are no attributes.
  const std::string equals(2000, '=');
  s.extra_xml = "<!-- " + equals + " --><note a=\"" + equals + ">\" b='" + equals + "'><![CDATA[" + equals +
                "]]>" + equals + "</note>";
  spit(path, e57::write({s}));
  CHECK(read_all(path, 10).cloud.size() == 3);
  // Up to the limits, the file reads (the attributes not read are dropped).
  s.extra_xml = "<note";
  for (int i = 0; i < 1024; ++i) s.extra_xml += " a" + std::to_string(i) + "=\"\"";
  s.extra_xml += ">" + std::string(std::size_t{1} << 20, 'b') + "</note>";
  spit(path, e57::write({s}));
  CHECK(read_all(path, 10).cloud.size() == 3);
}

TEST_CASE("E57: relief compress reads one end to end", "[io][e57][cli]") {
  TempDir dir;
  spit(dir.file("x.e57"), e57::write(two_scans(500)));
  const auto r = test::run_cli(RELIEF_CLI, "compress " + dir.file("x.e57") + " -o " + dir.file("x.relief") +
                                               " --cell 0.01 --quiet");
  INFO(r.output);
  REQUIRE(r.code == 0);
  const auto d = test::run_cli(RELIEF_CLI, "decompress " + dir.file("x.relief") + " -o " + dir.file("x.xyz") + " --quiet");
  INFO(d.output);
  REQUIRE(d.code == 0);
  std::ifstream in(dir.file("x.xyz"));
  std::size_t lines = 0;
  for (std::string line; std::getline(in, line);) lines += line.empty() ? 0 : 1;
  CHECK(lines == 1000);
}

// Not a test: writes the fuzz seeds of the e57 target (tests/fuzz/corpus/e57)
// when RELIEF_FUZZ_SEED_DIR names that folder.
TEST_CASE("E57: fuzz seeds", "[.seed]") {
  const char* dir = std::getenv("RELIEF_FUZZ_SEED_DIR");
  if (dir == nullptr) return;
  // Two small scans with a pose, split packets, an index and an empty packet.
  auto scans = two_scans(12);
  spit(std::string(dir) + "/seed-two-scans.e57", e57::write(scans));
  // Spherical with invalid states, 16-bit colours, time and returns.
  e57::Scan s;
  s.fields = {e57::Field::real("sphericalRange", {1, 2, 3, 4}, true), e57::Field::real("sphericalAzimuth", {0, 1, 2, 3}, true),
              e57::Field::real("sphericalElevation", {0, 0.1, 0.2, 0.3}, true),
              e57::Field::integer("sphericalInvalidState", 0, 2, {0, 1, 0, 2}),
              e57::Field::integer("colorRed", 0, 65535, {1, 300, 65535, 9}),
              e57::Field::integer("colorGreen", 0, 65535, {2, 3, 4, 5}),
              e57::Field::integer("colorBlue", 0, 65535, {7, 8, 9, 10}), e57::Field::real("timeStamp", {1, 2, 3, 4}),
              e57::Field::integer("returnIndex", 0, 1, {0, 1, 0, 0}), e57::Field::integer("returnCount", 1, 2, {1, 2, 1, 1}),
              e57::Field::integer("rowIndex", -5, 5, {-5, 0, 5, 1})};
  s.packets = 2;
  spit(std::string(dir) + "/seed-spherical-attributes.e57", e57::write({s}));
}

}  // namespace
}  // namespace relief
