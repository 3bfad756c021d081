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
