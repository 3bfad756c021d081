// Reader checks from issue 10: a PLY with more vertices than its header
// declares is reported as a warning; a LAS point format byte is called LAZ
// only when it is one.
#include <catch2/catch.hpp>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "relief/io.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"

using relief::test::TempDir;

namespace {

const char* const kXyzProperties = "property float x\nproperty float y\nproperty float z\n";

// `present` vertices on a line under a header that declares `declared`, then `tail`.
void write_ply(const std::string& path, bool binary, int declared, int present, const std::string& tail = "") {
  std::ofstream out(path, std::ios::binary);
  out << "ply\nformat " << (binary ? "binary_little_endian" : "ascii") << " 1.0\nelement vertex " << declared
      << "\n" << kXyzProperties << tail.substr(0, tail.find('|')) << "end_header\n";
  for (int i = 0; i < present; ++i) {
    const float v[3] = {static_cast<float>(i), static_cast<float>(i % 7), 0.5f};
    if (binary) {
      out.write(reinterpret_cast<const char*>(v), sizeof v);  // little-endian host (x86, arm64)
    } else {
      out << v[0] << " " << v[1] << " " << v[2] << "\n";
    }
  }
  if (tail.find('|') != std::string::npos) out << tail.substr(tail.find('|') + 1);
}

// Reads a whole file through the streaming reader; returns its info afterwards.
relief::PointStreamInfo read_all(const std::string& path, std::uint64_t& points) {
  auto reader = relief::open_point_reader(path);
  REQUIRE(reader.is_ok());
  relief::PointCloud batch;
  points = 0;
  for (;;) {
    auto n = (*reader)->read(batch, 1000);
    REQUIRE(n.is_ok());
    if (*n == 0) break;
    points += *n;
  }
  return (*reader)->info();
}

}  // namespace

TEST_CASE("PLY: vertices beyond the header's count are a warning naming the file and both counts", "[io]") {
  TempDir tmp;
  for (const bool binary : {false, true}) {
    INFO((binary ? "binary" : "ascii"));
    const std::string path = tmp.file(binary ? "more.bin.ply" : "more.ply");
    write_ply(path, binary, 4000, 5000);
    std::uint64_t points = 0;
    const relief::PointStreamInfo info = read_all(path, points);
    CHECK(points == 4000);
    REQUIRE(info.warnings.size() == 1);
    CHECK(info.warnings[0].find(path) != std::string::npos);
    CHECK(info.warnings[0].find("declares 4000 vertices but 5000 follow") != std::string::npos);
  }
}

TEST_CASE("PLY: no warning when the count is right or other elements follow", "[io]") {
  TempDir tmp;
  std::uint64_t points = 0;
  write_ply(tmp.file("exact.ply"), false, 300, 300, "|\n\n");
  CHECK(read_all(tmp.file("exact.ply"), points).warnings.empty());
  CHECK(points == 300);
  write_ply(tmp.file("exact.bin.ply"), true, 300, 300);
  CHECK(read_all(tmp.file("exact.bin.ply"), points).warnings.empty());
  // A face element after the vertices is data, not surplus vertices.
  write_ply(tmp.file("faces.ply"), false, 3, 3, "element face 1\nproperty list uchar int vertex_indices\n|3 0 1 2\n");
  CHECK(read_all(tmp.file("faces.ply"), points).warnings.empty());
  CHECK(points == 3);
}

TEST_CASE("PLY: a vertex count below the records present is found when faces follow too", "[io]") {
  // 10 vertices more than declared, then a face element: the extra vertices
  // were taken for the faces without a word (ascii), or read as faces
  // (binary), and dropped.
  TempDir tmp;
  const std::string faces = "element face 1\nproperty list uchar int vertex_indices\n|";
  std::uint64_t points = 0;
  write_ply(tmp.file("less.ply"), false, 990, 1000, faces + "3 0 1 2\n");
  const relief::PointStreamInfo info = read_all(tmp.file("less.ply"), points);
  CHECK(points == 990);
  REQUIRE(info.warnings.size() == 1);
  CHECK(info.warnings[0].find(tmp.file("less.ply")) != std::string::npos);
  // The face element took the first extra vertex's line; 9 and the face's are left.
  CHECK(info.warnings[0].find("10 lines follow the last element the header declares (face)") !=
        std::string::npos);
  CHECK(info.warnings[0].find("990 vertices") != std::string::npos);
  // Binary, 5 faces: the first extra vertex (990.0f: bytes 00 80 77 44) read
  // as faces, the second of 0x80 indices, runs past the end.
  std::string tail = "element face 5\nproperty list uchar int vertex_indices\n|";
  for (int f = 0; f < 5; ++f) {
    tail += '\x03';
    for (const std::int32_t i : {0, 1, 2}) tail.append(reinterpret_cast<const char*>(&i), 4);
  }
  write_ply(tmp.file("less.bin.ply"), true, 990, 1000, tail);
  const relief::PointStreamInfo bin = read_all(tmp.file("less.bin.ply"), points);
  CHECK(points == 990);
  REQUIRE(bin.warnings.size() == 1);
  CHECK(bin.warnings[0].find(tmp.file("less.bin.ply")) != std::string::npos);
  CHECK(bin.warnings[0].find("'face' elements") != std::string::npos);
  CHECK(bin.warnings[0].find("after the 990 vertices the header declares: is that count right?") !=
        std::string::npos);
}

TEST_CASE("PCD: records beyond POINTS are a warning, an ascii line with more values than FIELDS an error",
          "[io]") {
  TempDir tmp;
  const auto header = [](int points, const char* data) {
    return "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH " + std::to_string(points) +
           "\nHEIGHT 1\nPOINTS " + std::to_string(points) + "\nDATA " + data + "\n";
  };
  for (const bool binary : {false, true}) {
    INFO((binary ? "binary" : "ascii"));
    const std::string path = tmp.file(binary ? "more.bin.pcd" : "more.pcd");
    {
      std::ofstream out(path, std::ios::binary);
      out << header(990, binary ? "binary" : "ascii");
      for (int i = 0; i < 1000; ++i) {
        const float v[3] = {static_cast<float>(i), 1.0f, 2.0f};
        if (binary) {
          out.write(reinterpret_cast<const char*>(v), sizeof v);
        } else {
          out << v[0] << " " << v[1] << " " << v[2] << "\n";
        }
      }
      if (!binary) out << "\n\n";  // blank lines are no records
    }
    std::uint64_t points = 0;
    const relief::PointStreamInfo info = read_all(path, points);
    CHECK(points == 990);
    REQUIRE(info.warnings.size() == 1);
    CHECK(info.warnings[0].find(path) != std::string::npos);
    CHECK(info.warnings[0].find("declares 990 points but 1000 follow; the last 10 were ignored") !=
          std::string::npos);
  }
  const std::string exact = tmp.file("exact.pcd");
  std::ofstream(exact) << header(2, "ascii") << "1 2 3\n4 5 6\n\n";
  std::uint64_t points = 0;
  CHECK(read_all(exact, points).warnings.empty());
  CHECK(points == 2);
  const std::string extra = tmp.file("extra.pcd");
  std::ofstream(extra) << header(2, "ascii") << "1 2 3 4\n5 6 7\n";
  auto reader = relief::open_point_reader(extra);
  REQUIRE(reader.is_ok());
  relief::PointCloud batch;
  const auto n = (*reader)->read(batch, 100);
  REQUIRE_FALSE(n.is_ok());
  CHECK(n.status().code() == relief::StatusCode::kFormatError);
  CHECK(n.status().message().find("point 0: more values than the 3 the header declares") !=
        std::string::npos);
}

TEST_CASE("LAS: a point format byte is LAZ only when a real format lies under the compression bits", "[io]") {
  TempDir tmp;
  relief::test::SceneOptions o;
  o.points = 100;
  const relief::PointCloud cloud = relief::test::make_terrain(o, 10.0, 0.5);
  {
    auto writer = relief::open_point_writer(tmp.file("ok.las"), {});
    REQUIRE(writer.is_ok());
    REQUIRE((*writer)->write(cloud).is_ok());
    REQUIRE((*writer)->finish().is_ok());
  }
  std::vector<char> bytes;
  {
    std::ifstream in(tmp.file("ok.las"), std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  REQUIRE(bytes.size() > 105);
  const auto with_format = [&](std::uint8_t format) {
    std::vector<char> b = bytes;
    b[104] = static_cast<char>(format);  // point data format id, LAS header offset 104
    const std::string path = tmp.file("f" + std::to_string(format) + ".las");
    std::ofstream(path, std::ios::binary).write(b.data(), static_cast<std::streamsize>(b.size()));
    return relief::open_point_reader(path).status();
  };
  for (const std::uint8_t format : {std::uint8_t{99}, std::uint8_t{0x4B}, std::uint8_t{0xFF}}) {
    INFO(int{format});
    const relief::Status s = with_format(format);
    CHECK(s.code() == relief::StatusCode::kUnsupported);
    CHECK(s.message().find("format " + std::to_string(format)) != std::string::npos);
    CHECK(s.message().find("LAZ") == std::string::npos);
  }
  // A real format under the bits (the file holds format-0 records): LAZ, whose VLR is missing here.
  const relief::Status laz = with_format(0x80 | 0);
  INFO(laz.message());
  CHECK(laz.message().find("LAZ") != std::string::npos);
}

TEST_CASE("writers name a missing output directory", "[io]") {
  TempDir tmp;
  const std::string dir = tmp.file("nodir");
  for (const char* name : {"/out.ply", "/out.las", "/out.xyz"}) {
    INFO(name);
    auto writer = relief::open_point_writer(dir + name, {});
    REQUIRE_FALSE(writer.is_ok());
    CHECK(writer.status().code() == relief::StatusCode::kIoError);
    CHECK(writer.status().message() == dir + name + ": cannot create: the directory " + dir + " does not exist");
  }
}
