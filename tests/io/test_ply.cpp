// PLY reader/writer: round trips in every encoding, hand-written files with
// extra elements and properties, and a corpus of inputs that must be rejected
// cleanly (truncation at every length, lying headers, bad values, bad paths).

#include <catch2/catch.hpp>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <charconv>
#include <cmath>
#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "relief/io.h"
#include "support/same_cloud.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"
#include "support/shared_data.h"

namespace fs = std::filesystem;
using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace relief {
namespace {

constexpr const char* kMemName = "mem.ply";

// A fresh directory under the system temp dir, removed with everything in it.
using relief::test::TempDir;

std::span<const std::uint8_t> as_bytes(const std::string& s) {
  return {reinterpret_cast<const std::uint8_t*>(s.data()), s.size()};
}

Result<PointCloud> parse(const std::string& s) { return read_ply_memory(as_bytes(s), kMemName); }

void write_text(const std::string& path, const std::string& s) {
  std::ofstream f(path, std::ios::binary);
  f << s;
}

std::string read_text(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

// Appends values to a PLY body in any encoding, for files write_ply cannot make.
class BodyBuilder {
 public:
  explicit BodyBuilder(PlyEncoding enc) : enc_(enc) {}

  template <typename T>
  BodyBuilder& put(T v) {
    if (enc_ == PlyEncoding::kAscii) {
      if constexpr (std::is_floating_point_v<T>) {
        char buf[64];
        out_.append(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
      } else {
        out_ += std::to_string(+v);
      }
      out_ += ' ';
      return *this;
    }
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    const bool little = enc_ == PlyEncoding::kBinaryLittleEndian;
    if (little != (std::endian::native == std::endian::little)) std::reverse(b, b + sizeof(T));
    out_.append(b, sizeof(T));
    return *this;
  }
  void end_record() {
    if (enc_ == PlyEncoding::kAscii && !out_.empty() && out_.back() == ' ') out_.back() = '\n';
  }
  const std::string& str() const { return out_; }

 private:
  PlyEncoding enc_;
  std::string out_;
};

const char* format_line(PlyEncoding enc) {
  switch (enc) {
    case PlyEncoding::kAscii: return "format ascii 1.0\n";
    case PlyEncoding::kBinaryLittleEndian: return "format binary_little_endian 1.0\n";
    case PlyEncoding::kBinaryBigEndian: return "format binary_big_endian 1.0\n";
  }
  return "";
}

const char* encoding_label(PlyEncoding enc) {
  switch (enc) {
    case PlyEncoding::kAscii: return "ascii";
    case PlyEncoding::kBinaryLittleEndian: return "binary_little_endian";
    case PlyEncoding::kBinaryBigEndian: return "binary_big_endian";
  }
  return "";
}

// A file with an element before the vertices (with a list), vertices with
// unrelated properties of many types (optionally a list too) and faces after.
// `expected` receives what the reader must return.
std::string mixed_file(PlyEncoding enc, bool vertex_list, std::size_t n, PointCloud& expected) {
  std::string h = std::string("ply\n") + format_line(enc) +
                  "comment written by hand\n"
                  "obj_info camera rig\n"
                  "element camera 2\n"
                  "property float px\n"
                  "property list uchar int ids\n"
                  "property double py\n"
                  "element vertex " + std::to_string(n) + "\n"
                  "property uchar flags\n"
                  "property float x\n"
                  "property double y\n"
                  "property short z\n";
  if (vertex_list) h += "property list uint8 float32 extra\n";
  h += "property uint8 red\nproperty uint8 green\nproperty uint8 blue\n"
       "property int16 nx\n"
       "property float64 scalar_intensity\n"
       "element face 2\n"
       "property list uchar int vertex_indices\n"
       "end_header\n";
  BodyBuilder b(enc);
  for (int cam = 0; cam < 2; ++cam) {
    b.put(1.5f * static_cast<float>(cam)).put(std::uint8_t(cam + 1));
    for (int k = 0; k <= cam; ++k) b.put(std::int32_t(1000 + k));
    b.put(-2.25 * cam);
    b.end_record();
  }
  expected = PointCloud();
  for (std::size_t i = 0; i < n; ++i) {
    const float x = static_cast<float>(i) * 0.25f - 3.0f;
    const double y = 6632629.73 + static_cast<double>(i) * 0.001;
    const auto z = static_cast<std::int16_t>(static_cast<int>(i % 200) - 100);
    const auto r = static_cast<std::uint8_t>(i % 256);
    const auto g = static_cast<std::uint8_t>((i * 7) % 256);
    const auto bl = static_cast<std::uint8_t>(255 - i % 256);
    const double intensity = static_cast<double>(i % 1000) * 0.5;
    b.put(std::uint8_t(7)).put(x).put(y).put(z);
    if (vertex_list) {
      b.put(std::uint8_t(i % 3));
      for (std::size_t k = 0; k < i % 3; ++k) b.put(0.5f * static_cast<float>(k));
    }
    b.put(r).put(g).put(bl).put(std::int16_t(-3)).put(intensity);
    b.end_record();
    expected.positions.push_back({x, y, static_cast<double>(z)});
    expected.colors.push_back({r, g, bl});
    expected.intensities.push_back(static_cast<float>(intensity));
    // flags and nx, the vertex properties beyond x y z, colour and
    // intensity: kept as extra bytes, little endian (the list is not).
    expected.las.extra_bytes.insert(expected.las.extra_bytes.end(), {7, 0xFD, 0xFF});
    expected.las.extra_bytes_size = 3;
  }
  for (int f = 0; f < 2; ++f) {
    b.put(std::uint8_t(3)).put(std::int32_t(0)).put(std::int32_t(1)).put(std::int32_t(f + 2));
    b.end_record();
  }
  return h + b.str();
}

// Exact comparison (bitwise for coordinates and intensities), reporting the
// first mismatch only so that large clouds cost one assertion.
using relief::test::require_same;

// The float32 writer rounds every coordinate to float, and nothing else.
PointCloud rounded_to_float(PointCloud c) {
  for (Vec3d& p : c.positions) {
    p = {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)};
  }
  return c;
}

void require_format_error(const Result<PointCloud>& r, const std::string& fragment = "") {
  REQUIRE_FALSE(r.is_ok());
  INFO(r.status().to_string());
  CHECK(r.status().code() == StatusCode::kFormatError);
  CHECK_THAT(r.status().message(), StartsWith(std::string(kMemName) + ": "));
  if (!fragment.empty()) CHECK_THAT(r.status().message(), Contains(fragment));
}

// ---------------------------------------------------------------- round trips

TEST_CASE("PLY round trip in every encoding and coordinate type", "[io]") {
  const PlyEncoding enc = GENERATE(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian,
                                   PlyEncoding::kBinaryBigEndian);
  const PlyCoordinateType ct = GENERATE(PlyCoordinateType::kFloat32, PlyCoordinateType::kFloat64);
  const bool colors = GENERATE(false, true);
  const bool intensity = GENERATE(false, true);
  CAPTURE(encoding_label(enc), ct == PlyCoordinateType::kFloat64, colors, intensity);

  test::SceneOptions o;
  o.points = 700;
  o.noise = 0.01;
  o.colors = colors;
  o.intensity = intensity;
  const PointCloud cloud = test::make_terrain(o, 20.0, 2.0);

  TempDir dir;
  const std::string path = dir.file("round trip.ply");
  const Status w = write_ply(path, cloud, {enc, ct});
  REQUIRE(w.is_ok());
  CHECK(dir.entries() == std::vector<std::string>{"round trip.ply"});
  CHECK_THAT(read_text(path), StartsWith(std::string("ply\n") + format_line(enc) +
                                         "comment generated by relief\nelement vertex 700\n"));

  const Result<PointCloud> r = read_ply(path);
  INFO(r.status().to_string());
  REQUIRE(r.is_ok());
  require_same(*r, ct == PlyCoordinateType::kFloat64 ? cloud : rounded_to_float(cloud));
}

TEST_CASE("PLY double coordinates round-trip bit-exactly, awkward values included", "[io]") {
  PointCloud cloud;
  const double kAwkward[] = {0.1,
                             1.0 / 3.0,
                             -0.0,
                             6632629.73,
                             512345.678901234,
                             1e300,
                             -1e-300,
                             std::numeric_limits<double>::max(),
                             std::numeric_limits<double>::min(),
                             std::numeric_limits<double>::denorm_min(),
                             std::nextafter(1.0, 2.0),
                             -123456789.123456789};
  for (double a : kAwkward) {
    for (double b : kAwkward) cloud.positions.push_back({a, b, -a});
  }
  const PlyEncoding enc = GENERATE(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian,
                                   PlyEncoding::kBinaryBigEndian);
  CAPTURE(encoding_label(enc));
  TempDir dir;
  const std::string path = dir.file("awkward.ply");
  REQUIRE(write_ply(path, cloud, {enc, PlyCoordinateType::kFloat64}).is_ok());
  const Result<PointCloud> r = read_ply(path);
  REQUIRE(r.is_ok());
  require_same(*r, cloud);
}

TEST_CASE("PLY keeps millimetres on georeferenced coordinates", "[io]") {
  test::SceneOptions o;
  o.points = 2000;
  o.offset = {6632629.73, 512345.678, 152.125};
  const PointCloud cloud = test::make_plane(o, {0.1, 0.2, 1.0}, 50.0);
  const PlyEncoding enc = GENERATE(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian,
                                   PlyEncoding::kBinaryBigEndian);
  CAPTURE(encoding_label(enc));
  TempDir dir;
  const std::string path = dir.file("geo.ply");
  REQUIRE(write_ply(path, cloud, {enc, PlyCoordinateType::kFloat64}).is_ok());
  const Result<PointCloud> r = read_ply(path);
  REQUIRE(r.is_ok());
  REQUIRE(r->size() == cloud.size());
  double worst = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3d& a = cloud.positions[i];
    const Vec3d& b = r->positions[i];
    worst = std::max({worst, std::abs(a.x - b.x), std::abs(a.y - b.y), std::abs(a.z - b.z)});
  }
  CHECK(worst < 1e-3);
  require_same(*r, cloud);
}

TEST_CASE("PLY files larger than one read block stream correctly", "[io]") {
  // 120k points of 31 bytes span several of the reader's 1 MiB blocks, so
  // records straddle block boundaries.
  test::SceneOptions o;
  o.points = 120000;
  o.colors = true;
  o.intensity = true;
  const PointCloud cloud = test::make_room(o, 8.0);
  const PlyEncoding enc = GENERATE(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian,
                                   PlyEncoding::kBinaryBigEndian);
  CAPTURE(encoding_label(enc));
  TempDir dir;
  const std::string path = dir.file("big.ply");
  REQUIRE(write_ply(path, cloud, {enc, PlyCoordinateType::kFloat64}).is_ok());
  const Result<PointCloud> r = read_ply(path);
  INFO(r.status().to_string());
  REQUIRE(r.is_ok());
  require_same(*r, cloud);
}

TEST_CASE("PLY empty cloud round-trips", "[io]") {
  TempDir dir;
  const std::string path = dir.file("empty.ply");
  REQUIRE(write_ply(path, PointCloud{}).is_ok());
  const Result<PointCloud> r = read_ply(path);
  REQUIRE(r.is_ok());
  CHECK(r->empty());
}

// ---------------------------------------------------------------- other writers' files

TEST_CASE("PLY elements before and after the vertices are skipped, other vertex scalars kept as extra bytes",
          "[io]") {
  const PlyEncoding enc = GENERATE(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian,
                                   PlyEncoding::kBinaryBigEndian);
  const bool vertex_list = GENERATE(false, true);
  CAPTURE(encoding_label(enc), vertex_list);
  PointCloud expected;
  const std::string file = mixed_file(enc, vertex_list, 50, expected);

  SECTION("from memory") {
    const Result<PointCloud> r = parse(file);
    INFO(r.status().to_string());
    REQUIRE(r.is_ok());
    require_same(*r, expected);
    CHECK(r->las.extra_bytes == expected.las.extra_bytes);
  }
  SECTION("from a file spanning several read blocks") {
    PointCloud big_expected;
    const std::string big = mixed_file(enc, vertex_list, 70000, big_expected);
    TempDir dir;
    const std::string path = dir.file("mixed.ply");
    write_text(path, big);
    const Result<PointCloud> r = read_ply(path);
    INFO(r.status().to_string());
    REQUIRE(r.is_ok());
    require_same(*r, big_expected);
    CHECK(r->las.extra_bytes == big_expected.las.extra_bytes);
  }
}

TEST_CASE("PLY read from a pipe, where the size is unknown", "[io]") {
  const PlyEncoding enc = GENERATE(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian);
  const bool vertex_list = GENERATE(false, true);
  CAPTURE(encoding_label(enc), vertex_list);
  PointCloud expected;
  const std::string file = mixed_file(enc, vertex_list, 40000, expected);
  TempDir dir;
  const std::string fifo = dir.file("pipe.ply");
  REQUIRE(::mkfifo(fifo.c_str(), 0600) == 0);
  // If the reader stopped early the writer must fail rather than kill the process.
  std::signal(SIGPIPE, SIG_IGN);
  std::thread writer([&] { write_text(fifo, file); });
  const Result<PointCloud> r = read_ply(fifo);
  writer.join();
  INFO(r.status().to_string());
  REQUIRE(r.is_ok());
  require_same(*r, expected);
  CHECK(r->las.extra_bytes == expected.las.extra_bytes);
}

TEST_CASE("PLY header accepts CRLF line endings and sized type names", "[io]") {
  const std::string crlf =
      "ply\r\nformat ascii 1.0\r\ncomment windows\r\nelement vertex 2\r\n"
      "property float32 x\r\nproperty float64 y\r\nproperty int32 z\r\n"
      "property uint8 r\r\nproperty uint8 g\r\nproperty uint8 b\r\nend_header\r\n"
      "1.5 2.25 -3 10 20 30\r\n4 5 6 40 50 60\r\n";
  const Result<PointCloud> r = parse(crlf);
  INFO(r.status().to_string());
  REQUIRE(r.is_ok());
  REQUIRE(r->size() == 2);
  CHECK(r->positions[0] == Vec3d{1.5, 2.25, -3});
  CHECK(r->positions[1] == Vec3d{4, 5, 6});
  REQUIRE(r->has_colors());
  CHECK(r->colors[1] == Rgb8{40, 50, 60});
  CHECK_FALSE(r->has_intensity());

  // Binary body after a CRLF header.
  BodyBuilder b(PlyEncoding::kBinaryLittleEndian);
  b.put(std::int8_t(-1)).put(std::uint16_t(2)).put(std::int16_t(-3)).put(std::uint32_t(4));
  b.put(std::int8_t(5)).put(std::uint16_t(6)).put(std::int16_t(7)).put(std::uint32_t(8));
  const std::string bin =
      "ply\r\nformat binary_little_endian 1.0\r\nelement vertex 2\r\n"
      "property int8 x\r\nproperty uint16 y\r\nproperty int16 z\r\nproperty uint32 intensity\r\n"
      "end_header\r\n" + b.str();
  const Result<PointCloud> rb = parse(bin);
  INFO(rb.status().to_string());
  REQUIRE(rb.is_ok());
  REQUIRE(rb->size() == 2);
  CHECK(rb->positions[0] == Vec3d{-1, 2, -3});
  CHECK(rb->positions[1] == Vec3d{5, 6, 7});
  REQUIRE(rb->has_intensity());
  CHECK(rb->intensities[0] == 4.0f);
  CHECK(rb->intensities[1] == 8.0f);
}

TEST_CASE("PLY colour and intensity property names", "[io]") {
  const std::string header_start = "ply\nformat ascii 1.0\nelement vertex 1\n"
                                   "property double x\nproperty double y\nproperty double z\n";
  SECTION("diffuse_* colours and a uchar intensity") {
    const Result<PointCloud> r =
        parse(header_start +
              "property uchar diffuse_red\nproperty uchar diffuse_green\nproperty uchar diffuse_blue\n"
              "property uchar intensity\nend_header\n0 0 0 1 2 3 200\n");
    REQUIRE(r.is_ok());
    CHECK(r->colors.at(0) == Rgb8{1, 2, 3});
    CHECK(r->intensities.at(0) == 200.0f);
  }
  SECTION("scalar_intensity as double") {
    const Result<PointCloud> r =
        parse(header_start + "property double scalar_intensity\nend_header\n0 0 0 0.125\n");
    REQUIRE(r.is_ok());
    CHECK_FALSE(r->has_colors());
    CHECK(r->intensities.at(0) == 0.125f);
  }
  SECTION("names in any case: X Y Z, Red Green Blue, CloudCompare's scalar_Intensity") {
    const Result<PointCloud> r = parse(
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty double X\nproperty double Y\nproperty double Z\n"
        "property uchar Red\nproperty uchar Green\nproperty uchar Blue\nproperty float scalar_Intensity\n"
        "end_header\n1 2 3 4 5 6 0.5\n");
    INFO(r.status().to_string());
    REQUIRE(r.is_ok());
    CHECK(r->positions.at(0).x == 1.0);
    CHECK(r->positions.at(0).z == 3.0);
    CHECK(r->colors.at(0) == Rgb8{4, 5, 6});
    CHECK(r->intensities.at(0) == 0.5f);
    CHECK(r->las.extra_bytes.empty());  // none of them left over as extra bytes
  }
  SECTION("a double or 32-bit integer intensity is kept as a float, with a warning") {
    TempDir dir;
    for (const char* type : {"double", "int", "uint", "float", "ushort"}) {
      CAPTURE(type);
      const std::string path = dir.file(std::string(type) + ".ply");
      write_text(path, header_start + "property " + type + " intensity\nend_header\n0 0 0 7\n");
      auto reader = open_point_reader(path);
      REQUIRE(reader.is_ok());
      const auto& w = (*reader)->info().warnings;
      const bool wide = std::string(type) == "double" || std::string(type) == "int" || std::string(type) == "uint";
      CHECK(std::any_of(w.begin(), w.end(), [](const std::string& m) {
              return m.find("kept as 32-bit floats") != std::string::npos;
            }) == wide);
    }
  }
  SECTION("an exact name wins over another case") {
    const Result<PointCloud> r =
        parse(header_start + "property float Intensity\nproperty float intensity\nend_header\n0 0 0 7 9\n");
    REQUIRE(r.is_ok());
    CHECK(r->intensities.at(0) == 9.0f);
  }
  SECTION("an incomplete colour set is ignored") {
    const Result<PointCloud> r =
        parse(header_start + "property uchar red\nproperty uchar green\nend_header\n0 0 0 1 2\n");
    REQUIRE(r.is_ok());
    CHECK_FALSE(r->has_colors());
  }
}

TEST_CASE("PLY 16-bit colours are shifted to 8 bits only when needed", "[io]") {
  const PlyEncoding enc = GENERATE(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian,
                                   PlyEncoding::kBinaryBigEndian);
  CAPTURE(encoding_label(enc));
  auto file = [&](const std::vector<std::array<std::uint16_t, 3>>& rgb) {
    BodyBuilder b(enc);
    for (const auto& c : rgb) {
      b.put(1.0f).put(2.0f).put(3.0f).put(c[0]).put(c[1]).put(c[2]);
      b.end_record();
    }
    return std::string("ply\n") + format_line(enc) + "element vertex " +
           std::to_string(rgb.size()) +
           "\nproperty float x\nproperty float y\nproperty float z\n"
           "property ushort red\nproperty ushort green\nproperty ushort blue\nend_header\n" +
           b.str();
  };
  SECTION("values above 255 shift every colour right by 8") {
    const Result<PointCloud> r = parse(file({{65535, 256, 0}, {1000, 2000, 300}, {255, 17, 1}}));
    INFO(r.status().to_string());
    REQUIRE(r.is_ok());
    REQUIRE(r->colors.size() == 3);
    CHECK(r->colors[0] == Rgb8{255, 1, 0});
    CHECK(r->colors[1] == Rgb8{3, 7, 1});
    CHECK(r->colors[2] == Rgb8{0, 0, 0});
  }
  SECTION("values that all fit 8 bits are kept") {
    const Result<PointCloud> r = parse(file({{255, 17, 1}, {0, 128, 254}}));
    REQUIRE(r.is_ok());
    REQUIRE(r->colors.size() == 2);
    CHECK(r->colors[0] == Rgb8{255, 17, 1});
    CHECK(r->colors[1] == Rgb8{0, 128, 254});
  }
}

TEST_CASE("PLY float colours are fractions 0..1, each rounded to the nearest level", "[io]") {
  // They were truncated to 0 or 1 without a word.
  const PlyEncoding enc =
      GENERATE(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian);
  const bool dbl = GENERATE(false, true);
  CAPTURE(encoding_label(enc), dbl);
  auto file = [&](const std::vector<std::array<double, 3>>& rgb) {
    BodyBuilder b(enc);
    for (const auto& c : rgb) {
      b.put(1.0f).put(2.0f).put(3.0f);
      for (const double v : c) dbl ? b.put(v) : b.put(static_cast<float>(v));
      b.end_record();
    }
    const std::string t = dbl ? "double" : "float";
    return std::string("ply\n") + format_line(enc) + "element vertex " + std::to_string(rgb.size()) +
           "\nproperty float x\nproperty float y\nproperty float z\nproperty " + t + " red\nproperty " + t +
           " green\nproperty " + t + " blue\nend_header\n" + b.str();
  };
  SECTION("levels back from level / 255") {
    const Result<PointCloud> r = parse(file({{0.0, 1.0, 128.0 / 255}, {0.5, 0.25, 17.0 / 255}}));
    INFO(r.status().to_string());
    REQUIRE(r.is_ok());
    REQUIRE(r->colors.size() == 2);
    CHECK(r->colors[0] == Rgb8{0, 255, 128});
    CHECK(r->colors[1] == Rgb8{128, 64, 17});
    CHECK(r->las.color_low.empty());
  }
  SECTION("a value outside 0..1 is refused, naming the vertex") {
    require_format_error(parse(file({{0.5, 0.5, 0.5}, {0.2, 255.0, 0.0}})),
                         "vertex 1 has the colour value 255");
    require_format_error(parse(file({{-0.5, 0.5, 0.5}})), "fractions from 0 to 1");
  }
}

// ---------------------------------------------------------------- must reject

TEST_CASE("PLY rejects inputs that are not PLY or have a broken header", "[io]") {
  const std::string ok_tail = "property float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n";
  SECTION("empty") { require_format_error(parse(""), "empty"); }
  SECTION("garbage") {
    require_format_error(parse("hello world\n"), "not a PLY");
    std::string junk(5000, '\0');
    test::Rng rng(7);
    for (char& c : junk) c = static_cast<char>(rng.next());
    require_format_error(parse(junk));
    require_format_error(parse("ply\n" + junk));
    require_format_error(parse("plyx\nformat ascii 1.0\n"));
  }
  SECTION("missing end_header") {
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"),
                         "end_header");
  }
  SECTION("missing format") {
    require_format_error(parse("ply\nelement vertex 1\n" + ok_tail), "format");
  }
  SECTION("unknown format") {
    require_format_error(parse("ply\nformat binary_middle_endian 1.0\nelement vertex 1\n" + ok_tail),
                         "binary_middle_endian");
  }
  SECTION("unsupported version") {
    const Result<PointCloud> r = parse("ply\nformat ascii 2.0\nelement vertex 1\n" + ok_tail);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kUnsupported);
  }
  SECTION("unknown property type") {
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex 1\nproperty quux x\n"
                               "property float y\nproperty float z\nend_header\n1 2 3\n"),
                         "unknown property type 'quux'");
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex 1\nproperty int64 x\n"
                               "property float y\nproperty float z\nend_header\n1 2 3\n"),
                         "int64");
  }
  SECTION("missing z") {
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"
                               "property float y\nend_header\n1 2\n"),
                         "'z'");
  }
  SECTION("no vertex element") {
    require_format_error(parse("ply\nformat ascii 1.0\nelement face 0\n"
                               "property list uchar int vertex_indices\nend_header\n"),
                         "vertex");
  }
  SECTION("negative or absurd vertex counts") {
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex -5\n" + ok_tail), "negative");
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex 99999999999999999999999\n" +
                               ok_tail),
                         "absurd");
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex 4398046511104\n" + ok_tail),
                         "absurd");
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex 12abc\n" + ok_tail));
  }
  SECTION("other malformed header lines") {
    require_format_error(parse("ply\nformat ascii 1.0\nproperty float x\n" + ok_tail), "before");
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex 1\nfrobnicate\n" + ok_tail),
                         "frobnicate");
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n" +
                               ok_tail),
                         "two properties");
    require_format_error(parse("ply\nformat ascii 1.0\nelement vertex 1\n"
                               "property list float int x\n" + ok_tail));
  }
}

TEST_CASE("PLY rejects a header count larger than the data", "[io]") {
  SECTION("binary") {
    BodyBuilder b(PlyEncoding::kBinaryLittleEndian);
    for (int i = 0; i < 3; ++i) b.put(1.0).put(2.0).put(3.0);
    b.put(1.0);  // a partial fourth vertex
    const std::string file = "ply\nformat binary_little_endian 1.0\nelement vertex 10\n"
                             "property double x\nproperty double y\nproperty double z\n"
                             "end_header\n" + b.str();
    const Result<PointCloud> r = parse(file);
    require_format_error(r);
    CHECK(r.status().message() ==
          "mem.ply: truncated: header declares 10 vertices but the data ends after 3");
  }
  SECTION("binary with a huge count does not allocate for it") {
    const std::string file = "ply\nformat binary_big_endian 1.0\nelement vertex 1000000000000\n"
                             "property double x\nproperty double y\nproperty double z\n"
                             "end_header\n" + std::string(48, '\0');
    const Result<PointCloud> r = parse(file);
    require_format_error(r, "header declares 1000000000000 vertices but the data ends after 2");
  }
  SECTION("ascii") {
    const std::string file = "ply\nformat ascii 1.0\nelement vertex 1000000000000\n"
                             "property double x\nproperty double y\nproperty double z\n"
                             "end_header\n1 2 3\n4 5 6\n\n";
    require_format_error(parse(file),
                         "truncated: header declares 1000000000000 vertices but the data ends after 2");
  }
  SECTION("an element after the vertices is cut short") {
    const std::string file = "ply\nformat ascii 1.0\nelement vertex 1\n"
                             "property double x\nproperty double y\nproperty double z\n"
                             "element face 3\nproperty list uchar int vertex_indices\n"
                             "end_header\n1 2 3\n3 0 0 0\n";
    require_format_error(parse(file), "'face' elements but the data ends after 1");
  }
}

TEST_CASE("PLY rejects a binary file truncated at any length", "[io]") {
  const PlyEncoding enc = GENERATE(PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian);
  const bool vertex_list = GENERATE(false, true);
  CAPTURE(encoding_label(enc), vertex_list);
  PointCloud expected;
  const std::string file = mixed_file(enc, vertex_list, 4, expected);
  REQUIRE(parse(file).is_ok());
  for (std::size_t len = 0; len < file.size(); ++len) {
    // A copy of exactly `len` bytes, so ASan sees any read past the end.
    const std::vector<std::uint8_t> prefix(file.begin(), file.begin() + static_cast<std::ptrdiff_t>(len));
    const Result<PointCloud> r = read_ply_memory(prefix, kMemName);
    INFO("prefix length " << len);
    require_format_error(r);
  }
}

TEST_CASE("PLY survives random corruption without crashing", "[io]") {
  PointCloud expected;
  const std::string file = mixed_file(PlyEncoding::kBinaryLittleEndian, true, 6, expected);
  const std::size_t header_size = file.find("end_header\n") + 11;
  test::Rng rng(42);
  int accepted = 0;
  for (int round = 0; round < 3000; ++round) {
    std::vector<std::uint8_t> bytes(file.begin(), file.end());
    const int flips = 1 + static_cast<int>(rng.next() % 4);
    for (int f = 0; f < flips; ++f) {
      // Mostly hit the body, sometimes the header.
      const std::size_t at = rng.next() % 4 == 0
                                 ? rng.next() % bytes.size()
                                 : header_size + rng.next() % (bytes.size() - header_size);
      bytes[at] = static_cast<std::uint8_t>(rng.next());
    }
    const Result<PointCloud> r = read_ply_memory(bytes, kMemName);
    if (r.is_ok()) {
      ++accepted;
      REQUIRE(r->validate("fuzz").is_ok());
    } else {
      REQUIRE_THAT(r.status().message(), StartsWith(std::string(kMemName) + ": "));
    }
  }
  CHECK(accepted > 0);  // flips inside values are legitimately accepted
}

TEST_CASE("PLY rejects non-finite coordinates naming the vertex", "[io]") {
  const PlyEncoding enc = GENERATE(PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian,
                                   PlyEncoding::kBinaryBigEndian);
  const double bad = GENERATE(std::numeric_limits<double>::quiet_NaN(),
                              std::numeric_limits<double>::infinity());
  const bool doubles = GENERATE(false, true);
  CAPTURE(encoding_label(enc), bad, doubles);
  BodyBuilder b(enc);
  for (int i = 0; i < 4; ++i) {
    const double y = i == 2 ? bad : 1.0;
    if (doubles) {
      b.put(0.5).put(y).put(2.0);
    } else {
      b.put(0.5f).put(static_cast<float>(y)).put(2.0f);
    }
    b.end_record();
  }
  const char* type = doubles ? "double" : "float";
  const std::string file = std::string("ply\n") + format_line(enc) + "element vertex 4\n" +
                           "property " + type + " x\nproperty " + type + " y\nproperty " + type +
                           " z\nend_header\n" + b.str();
  require_format_error(parse(file), "vertex 2 has a non-finite coordinate");
}

TEST_CASE("PLY rejects a non-finite intensity", "[io]") {
  BodyBuilder b(PlyEncoding::kBinaryLittleEndian);
  b.put(1.0f).put(2.0f).put(3.0f).put(std::numeric_limits<float>::quiet_NaN());
  const std::string file = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
                           "property float x\nproperty float y\nproperty float z\n"
                           "property float intensity\nend_header\n" + b.str();
  require_format_error(parse(file), "vertex 0 has a non-finite intensity");
}

TEST_CASE("PLY ascii rejects bad tokens and wrong value counts", "[io]") {
  const std::string header = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                             "property float y\nproperty float z\nproperty uchar red\n"
                             "property uchar green\nproperty uchar blue\nend_header\n";
  require_format_error(parse(header + "1 2 3 4 5 6\n1.0 abc 3 4 5 6\n"),
                       "vertex 1: 'abc' is not a valid float for property 'y'");
  require_format_error(parse(header + "1 2 3 4 5 6\n1 2 3 4 5\n"), "vertex 1");
  require_format_error(parse(header + "1 2 3 4 5 6 7\n1 2 3 4 5 6\n"), "more values");
  require_format_error(parse(header + "1 2 3 4 5 300\n1 2 3 4 5 6\n"), "uchar");
  require_format_error(parse(header + "1 2 3 4 5 6\n1 2 3e999 4 5 6\n"), "vertex 1");
  require_format_error(parse(header + "1 2 3 4 5 6\nnan 2 3 4 5 6\n"), "vertex 1");
  // A leading '+' is valid printf output.
  CHECK(parse(header + "+1 2 3 4 5 6\n1 +2.5e1 3 4 5 +6\n").is_ok());
}

TEST_CASE("PLY binary rejects a negative list length", "[io]") {
  BodyBuilder b(PlyEncoding::kBinaryLittleEndian);
  b.put(1.0f).put(2.0f).put(3.0f).put(std::int32_t(-2));
  const std::string file = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
                           "property float x\nproperty float y\nproperty float z\n"
                           "property list int float extra\nend_header\n" + b.str();
  require_format_error(parse(file), "negative");
}

// ---------------------------------------------------------------- paths

TEST_CASE("PLY read errors name the path", "[io]") {
  TempDir dir;
  const std::string missing = dir.file("missing.ply");
  const Result<PointCloud> r = read_ply(missing);
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().code() == StatusCode::kIoError);
  CHECK_THAT(r.status().message(), StartsWith(missing + ": "));
  CHECK_THAT(r.status().message(), Contains(std::strerror(ENOENT)));

  const Result<PointCloud> d = read_ply(dir.path().string());
  REQUIRE_FALSE(d.is_ok());
  CHECK(d.status().code() == StatusCode::kIoError);

  const std::string bad = dir.file("bad.ply");
  write_text(bad, "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"
                  "property float y\nproperty float z\nend_header\n1 2 3\n");
  const Result<PointCloud> t = read_ply(bad);
  REQUIRE_FALSE(t.is_ok());
  CHECK(t.status().code() == StatusCode::kFormatError);
  CHECK(t.status().message() == bad + ": truncated: header declares 2 vertices but the data ends after 1");
}

TEST_CASE("PLY write failures are clean", "[io]") {
  test::SceneOptions o;
  o.points = 100;
  const PointCloud cloud = test::make_sphere(o, 1.0);
  TempDir dir;

  SECTION("unwritable locations") {
    for (const std::string& path :
         {std::string("/proc/relief-nope/x.ply"), dir.file("no-such-dir/x.ply")}) {
      const Status s = write_ply(path, cloud);
      REQUIRE_FALSE(s.is_ok());
      CHECK(s.code() == StatusCode::kIoError);
      CHECK_THAT(s.message(), StartsWith(path + ": "));
    }
    CHECK(dir.entries().empty());
  }
  SECTION("rename onto a directory leaves no temporary file") {
    fs::create_directory(dir.path() / "target.ply");
    const Status s = write_ply(dir.file("target.ply"), cloud);
    REQUIRE_FALSE(s.is_ok());
    CHECK(s.code() == StatusCode::kIoError);
    CHECK(dir.entries() == std::vector<std::string>{"target.ply"});
  }
  SECTION("an invalid cloud is refused before anything is written") {
    PointCloud broken = cloud;
    broken.colors.resize(3);
    const Status s = write_ply(dir.file("broken.ply"), broken);
    CHECK(s.code() == StatusCode::kInvalidArgument);
    PointCloud nan_cloud = cloud;
    nan_cloud.positions[5].y = std::numeric_limits<double>::quiet_NaN();
    CHECK(write_ply(dir.file("nan.ply"), nan_cloud).code() == StatusCode::kInvalidArgument);
    PointCloud huge = cloud;
    huge.positions[0].x = 1e300;
    CHECK(write_ply(dir.file("huge.ply"), huge, {PlyEncoding::kBinaryLittleEndian,
                                                PlyCoordinateType::kFloat32})
              .code() == StatusCode::kInvalidArgument);
    CHECK(dir.entries().empty());
  }
  SECTION("an existing file is replaced") {
    const std::string path = dir.file("again.ply");
    write_text(path, "old contents");
    REQUIRE(write_ply(path, cloud).is_ok());
    const Result<PointCloud> r = read_ply(path);
    REQUIRE(r.is_ok());
    CHECK(r->size() == cloud.size());
    CHECK(dir.entries() == std::vector<std::string>{"again.ply"});
  }
}

TEST_CASE("read_point_file dispatches on the extension", "[io]") {
  test::SceneOptions o;
  o.points = 50;
  const PointCloud cloud = test::make_plane(o, {0, 0, 1}, 1.0);
  TempDir dir;
  const std::string upper = dir.file("CLOUD.PLY");
  REQUIRE(write_ply(upper, cloud).is_ok());
  const Result<PointCloud> r = read_point_file(upper);
  REQUIRE(r.is_ok());
  CHECK(r->size() == 50);

  for (const std::string& path : {dir.file("cloud.fls"), dir.file("cloud")}) {
    const Result<PointCloud> u = read_point_file(path);
    REQUIRE_FALSE(u.is_ok());
    CHECK(u.status().code() == StatusCode::kUnsupported);
    CHECK_THAT(u.status().message(), StartsWith(path + ": "));
    CHECK_THAT(u.status().message(), Contains(".ply"));
  }
}

TEST_CASE("PLY reads the shared aerial sample", "[io][shared-data]") {
  const auto path = test::shared_file("medium/fr_aerial_rgb_698k.ply");
  if (!path) return;
  const Result<PointCloud> r = read_point_file(*path);
  INFO(r.status().to_string());
  REQUIRE(r.is_ok());
  CHECK(r->size() == 697721);
  CHECK(r->has_colors());
  CHECK(r->has_intensity());
  CHECK(r->validate(*path).is_ok());
}

}  // namespace
}  // namespace relief
