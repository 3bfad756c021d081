// Point-file inputs beyond the basics (issue 9, item 5): PCD field-name case,
// separate colour fields and binary_compressed; CSV headers and 16-bit
// colours; float intensities through the writers.
#include <catch2/catch.hpp>

#include <lzf.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "relief/io.h"
#include "support/same_cloud.h"
#include "support/temp_dir.h"

using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace relief {

namespace {

using test::write_file;

// Reads a whole file in batches of `batch_size`, checking the batch contract.
Result<PointCloud> read_all(const std::string& path, std::size_t batch_size, const ReaderOptions& options = {}) {
  Result<std::unique_ptr<PointReader>> r = open_point_reader(path, options);
  if (!r.is_ok()) return r.status();
  PointReader& reader = **r;
  PointCloud all;
  PointCloud batch;
  for (;;) {
    Result<std::size_t> n = reader.read(batch, batch_size);
    if (!n.is_ok()) return n.status();
    REQUIRE(batch.size() == *n);
    REQUIRE(batch.colors.size() == (reader.info().has_colors ? *n : 0));
    REQUIRE(batch.intensities.size() == (reader.info().has_intensity ? *n : 0));
    REQUIRE(batch.las.color_low.size() == ((reader.info().las_attributes & kLasColorLow) != 0 ? *n : 0));
    if (*n == 0) break;
    all.las.color_low.insert(all.las.color_low.end(), batch.las.color_low.begin(), batch.las.color_low.end());
    all.positions.insert(all.positions.end(), batch.positions.begin(), batch.positions.end());
    all.colors.insert(all.colors.end(), batch.colors.begin(), batch.colors.end());
    all.intensities.insert(all.intensities.end(), batch.intensities.begin(), batch.intensities.end());
  }
  return all;
}

void require_error(const Status& s, const std::string& path, const std::string& fragment) {
  INFO(s.to_string());
  REQUIRE_FALSE(s.is_ok());
  CHECK(s.code() == StatusCode::kFormatError);
  CHECK_THAT(s.message(), StartsWith(path + ": "));
  CHECK_THAT(s.message(), Contains(fragment));
}

template <typename T>
void put(std::string& out, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (std::endian::native == std::endian::big) std::reverse(b, b + sizeof(T));
  out.append(b, sizeof(T));
}

// ---------------------------------------------------------------- PCD

TEST_CASE("PCD field names match in any case", "[io][pcd]") {
  test::TempDir dir;
  const std::string path = dir.file("upper.pcd");
  write_file(path,
             "VERSION 0.7\nFIELDS X Y Z RGB Intensity\nSIZE 4 4 4 4 4\nTYPE F F F U F\nCOUNT 1 1 1 1 1\n"
             "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
             "1 2 3 " + std::to_string((10u << 16) | (20u << 8) | 30u) + " 0.25\n4 5 6 255 0.75\n");
  const Result<PointCloud> got = read_all(path, 1);
  INFO(got.status().to_string());
  REQUIRE(got.is_ok());
  PointCloud want;
  want.positions = {{1, 2, 3}, {4, 5, 6}};
  want.colors = {{10, 20, 30}, {0, 0, 255}};
  want.intensities = {0.25f, 0.75f};
  test::require_same(*got, want);
}

TEST_CASE("PCD separate r g b fields follow their declared type", "[io][pcd]") {
  test::TempDir dir;
  const std::string path = dir.file("split.pcd");
  SECTION("uchar, binary") {
    std::string body;
    for (int i = 0; i < 3; ++i) {
      put(body, static_cast<float>(i));
      put(body, 0.0f);
      put(body, 1.0f);
      for (std::uint8_t c : {std::uint8_t(i), std::uint8_t(100), std::uint8_t(255 - i)}) put(body, c);
    }
    write_file(path, "FIELDS x y z r g b\nSIZE 4 4 4 1 1 1\nTYPE F F F U U U\nWIDTH 3\nHEIGHT 1\nDATA binary\n" + body);
    const Result<PointCloud> got = read_all(path, 2);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    PointCloud want;
    want.positions = {{0, 0, 1}, {1, 0, 1}, {2, 0, 1}};
    want.colors = {{0, 100, 255}, {1, 100, 254}, {2, 100, 253}};
    test::require_same(*got, want);
  }
  SECTION("ushort levels are 16-bit, even when small; floats and ints are 8-bit levels, saturated") {
    write_file(path,
               "FIELDS x y z Red Green Blue\nSIZE 4 4 4 2 2 2\nTYPE F F F U U U\nWIDTH 2\nDATA ascii\n"
               "0 0 0 65535 256 255\n1 1 1 32768 0 4660\n");
    Result<PointCloud> got = read_all(path, 10);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    CHECK(got->colors == std::vector<Rgb8>{{255, 1, 0}, {128, 0, 18}});
    // Each level's low byte is kept beside it: the 16-bit levels come back.
    CHECK(got->las.color_low == std::vector<Rgb8>{{255, 0, 255}, {0, 0, 0x34}});
    {
      Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
      REQUIRE(r.is_ok());
      CHECK(((*r)->info().las_attributes & kLasColorLow) != 0);
      CHECK_FALSE((*r)->info().las_colors_8bit);
    }
    write_file(path,
               "FIELDS x y z r g b\nSIZE 4 4 4 4 4 4\nTYPE F F F F I U\nWIDTH 2\nDATA ascii\n"
               "0 0 0 12.6 -5 300\n1 1 1 nan 255 7\n");
    got = read_all(path, 10);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    CHECK(got->colors == std::vector<Rgb8>{{13, 0, 255}, {0, 255, 7}});
    CHECK(got->las.color_low.empty());  // 8-bit levels: nothing below them
  }
  SECTION("an intensity field wider than a float is kept as one, with a warning") {
    for (const char* field : {"8\nTYPE F F F F", "4\nTYPE F F F U", "4\nTYPE F F F F", "2\nTYPE F F F U"}) {
      CAPTURE(field);
      write_file(path, std::string("FIELDS x y z intensity\nSIZE 4 4 4 ") + field +
                           "\nWIDTH 1\nDATA ascii\n0 0 0 7\n");
      Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
      REQUIRE(r.is_ok());
      const auto& w = (*r)->info().warnings;
      const bool wide = std::string(field).rfind("2", 0) != 0 && std::string(field) != "4\nTYPE F F F F";
      CHECK(std::any_of(w.begin(), w.end(), [](const std::string& m) {
              return m.find("kept as 32-bit floats") != std::string::npos;
            }) == wide);
    }
  }
  SECTION("a partial set is not colour") {
    write_file(path, "FIELDS x y z r g\nSIZE 4 4 4 1 1\nTYPE F F F U U\nWIDTH 1\nDATA ascii\n0 0 0 1 2\n");
    Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
    REQUIRE(r.is_ok());
    CHECK_FALSE((*r)->info().has_colors);
  }
}

// Fields in PCL's binary_compressed order: all values of each field in turn.
struct CompressedPcd {
  std::string header;
  std::string soa;  // uncompressed field arrays
};

CompressedPcd compressed_pcd(const std::vector<std::array<float, 3>>& pts) {
  const std::size_t n = pts.size();
  CompressedPcd c;
  c.header = "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb intensity\nSIZE 4 4 4 4 2\nTYPE F F F U U\nCOUNT 1 1 1 1 1\n"
             "WIDTH " + std::to_string(n) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(n) +
             "\nDATA binary_compressed\n";
  for (std::size_t axis = 0; axis < 3; ++axis) {
    for (const auto& p : pts) put(c.soa, p[axis]);
  }
  for (std::size_t i = 0; i < n; ++i) put(c.soa, static_cast<std::uint32_t>((i % 256) << 16 | 0x0080FF));
  for (std::size_t i = 0; i < n; ++i) put(c.soa, static_cast<std::uint16_t>(i * 3));
  return c;
}

std::string lzf(const std::string& raw) {
  std::string out(raw.size() + raw.size() / 16 + 64, '\0');
  const unsigned n = lzf_compress(raw.data(), static_cast<unsigned>(raw.size()), out.data(),
                                  static_cast<unsigned>(out.size()));
  REQUIRE(n > 0);
  out.resize(n);
  return out;
}

std::string sized(std::uint32_t packed, std::uint32_t unpacked, const std::string& data) {
  std::string out;
  put(out, packed);
  put(out, unpacked);
  return out + data;
}

TEST_CASE("PCD binary_compressed reads as PCL writes it", "[io][pcd]") {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::vector<std::array<float, 3>> pts;
  for (int i = 0; i < 1000; ++i) {
    pts.push_back({static_cast<float>(i % 10) * 0.5f, static_cast<float>(i / 10) * 0.25f, 1.0f});
  }
  pts[7] = {nan, nan, nan};  // a pixel without depth
  const CompressedPcd c = compressed_pcd(pts);
  const std::string packed = lzf(c.soa);
  REQUIRE(packed.size() < c.soa.size());  // the data repeats, so LZF used back references
  test::TempDir dir;
  const std::string path = dir.file("compressed.pcd");
  const std::string file = c.header + sized(static_cast<std::uint32_t>(packed.size()),
                                            static_cast<std::uint32_t>(c.soa.size()), packed);
  write_file(path, file);
  PointCloud want;
  for (std::size_t i = 0; i < pts.size(); ++i) {
    if (i == 7) continue;
    want.positions.push_back({pts[i][0], pts[i][1], pts[i][2]});
    want.colors.push_back({static_cast<std::uint8_t>(i % 256), 0x80, 0xFF});
    want.intensities.push_back(static_cast<float>(i * 3));
  }
  for (const std::size_t batch : {std::size_t{1}, std::size_t{333}, std::size_t{5000}}) {
    const Result<PointCloud> got = read_all(path, batch);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    test::require_same(*got, want);
  }

  SECTION("truncated at any length") {
    const std::size_t body = c.header.size();
    for (std::size_t len = body; len < file.size(); ++len) {
      INFO("prefix length " << len);
      write_file(path, file.substr(0, len));
      const Status s = read_all(path, 100).status();
      require_error(s, path, len < body + 8 ? "no size fields" : "only ");
    }
  }
  SECTION("lying sizes and corrupt data") {
    const auto packed_size = static_cast<std::uint32_t>(packed.size());
    const auto raw_size = static_cast<std::uint32_t>(c.soa.size());
    write_file(path, c.header + sized(packed_size, raw_size + 1, packed));
    require_error(read_all(path, 100).status(), path, "is not POINTS x point size = 1000 x 18");
    write_file(path, c.header + sized(packed_size + 1, raw_size, packed));
    require_error(read_all(path, 100).status(), path, "only " + std::to_string(packed.size()) + " bytes follow");
    // A huge declared expansion of a few bytes is refused before allocating.
    const std::string huge = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 100000000\nDATA binary_compressed\n";
    write_file(path, huge + sized(4, 1200000000, "abcd"));
    require_error(read_all(path, 100).status(), path, "4 compressed bytes cannot expand to 1200000000");
    // A back reference before the start of the output; then a stream one byte short.
    std::string corrupt = packed;
    corrupt[0] = static_cast<char>(0xE0);
    corrupt[1] = static_cast<char>(0xFF);
    write_file(path, c.header + sized(packed_size, raw_size, corrupt));
    require_error(read_all(path, 100).status(), path, "the LZF data is corrupt");
    write_file(path, c.header + sized(packed_size - 1, raw_size, packed.substr(0, packed.size() - 1)));
    require_error(read_all(path, 100).status(), path, "the LZF data is corrupt");
  }
  SECTION("no points") {
    write_file(path, "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 0\nDATA binary_compressed\n" + sized(0, 0, ""));
    const Result<PointCloud> got = read_all(path, 100);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    CHECK(got->empty());
  }
}

// ---------------------------------------------------------------- CSV / text

TEST_CASE("CSV header names give the columns without --columns", "[io][xyz]") {
  test::TempDir dir;
  const std::string path = dir.file("scan.csv");
  PointCloud want;
  want.positions = {{1, 2, 3}, {4, 5, 6}};
  want.colors = {{10, 20, 30}, {40, 50, 60}};
  want.intensities = {0.25f, 0.5f};
  SECTION("reordered upper-case names, a skipped classification column") {
    write_file(path, "Intensity,Classification,Z,Y,X,B,G,R\n0.25,2,3,2,1,30,20,10\n0.5,6,6,5,4,60,50,40\n");
    const Result<PointCloud> got = read_all(path, 1);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    test::require_same(*got, want);
  }
  SECTION("CloudCompare's comment header") {
    write_file(path, "// exported\n//X,Y,Z,R,G,B,Reflectance\n1,2,3,10,20,30,0.25\n4,5,6,40,50,60,0.5\n");
    const Result<PointCloud> got = read_all(path, 100);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    test::require_same(*got, want);
  }
  SECTION("a comment marker apart from the names") {
    // "# x y z" and "// X,Y,Z": the marker is not a column (it shifted every
    // column by one, or refused the file for a missing column).
    for (const char* header :
         {"# X Y Z R G B Reflectance\n", "//  X,Y,Z,R,G,B,Reflectance\n", "  #\tx y z red green blue i\n"}) {
      write_file(path, std::string(header) + "1 2 3 10 20 30 0.25\n4 5 6 40 50 60 0.5\n");
      const Result<PointCloud> got = read_all(path, 100);
      INFO(header << got.status().to_string());
      REQUIRE(got.is_ok());
      test::require_same(*got, want);
    }
  }
  SECTION("quoted names, semicolons, long colour names") {
    write_file(path, "\"x\";\"y\";\"z\";\"red\";\"green\";\"blue\";\"i\"\n1;2;3;10;20;30;0.25\n4;5;6;40;50;60;0.5\n");
    const Result<PointCloud> got = read_all(path, 100);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    test::require_same(*got, want);
  }
  SECTION("explicit columns win over the header") {
    write_file(path, "x y z r g b i\n1 2 3 10 20 30 0.25\n");
    ReaderOptions o;
    o.xyz_columns = "x,y,z";
    const Result<PointCloud> got = read_all(path, 100, o);
    REQUIRE(got.is_ok());
    CHECK_FALSE(got->has_colors());
    CHECK_FALSE(got->has_intensity());
    CHECK(got->positions == std::vector<Vec3d>{{1, 2, 3}});
  }
  SECTION("a header without x y z names keeps x y z; a partial colour set is no colour") {
    write_file(path, "lon lat h r g\n1 2 3 10 20\n");
    Result<PointCloud> got = read_all(path, 100);
    REQUIRE(got.is_ok());
    CHECK(got->positions == std::vector<Vec3d>{{1, 2, 3}});
    write_file(path, "z y x r g\n1 2 3 10 20\n");
    got = read_all(path, 100);
    REQUIRE(got.is_ok());
    CHECK_FALSE(got->has_colors());
    CHECK(got->positions == std::vector<Vec3d>{{3, 2, 1}});
  }
}

TEST_CASE("CSV 16-bit colours are narrowed by one rule for the whole file", "[io][xyz]") {
  test::TempDir dir;
  const std::string path = dir.file("wide.csv");
  // 3000 points with 8-bit-looking levels, then one above 255: the file has
  // 16-bit colours, whatever batch size reads it.
  std::string text = "x,y,z,red,green,blue\n";
  for (int i = 0; i < 3000; ++i) text += std::to_string(i) + ",0,0,200,255,1\n";
  text += "9,9,9,65535,4660,256\n";
  write_file(path, text);
  for (const std::size_t batch : {std::size_t{1}, std::size_t{7}, std::size_t{100000}}) {
    INFO("batch " << batch);
    const Result<PointCloud> got = read_all(path, batch);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    REQUIRE(got->size() == 3001);
    CHECK(got->colors.front() == Rgb8{0, 0, 0});
    CHECK(got->colors.back() == Rgb8{255, 18, 1});
    // Each level's low byte is kept beside it (a file decided at open).
    REQUIRE(got->las.color_low.size() == 3001);
    CHECK(got->las.color_low.front() == Rgb8{200, 255, 1});
    CHECK(got->las.color_low.back() == Rgb8{255, 0x34, 0});
  }
  {
    Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
    REQUIRE(r.is_ok());
    CHECK(((*r)->info().las_attributes & kLasColorLow) != 0);
  }
  // A first level above 255 after the first 2^16 points (but within the
  // rule's 2^20): the file is 16-bit all the same, decided by the first read,
  // but its low bytes are not kept (the open looks at 2^16 points only).
  {
    std::string late = "x,y,z,red,green,blue\n";
    for (int i = 0; i < 70000; ++i) late += std::to_string(i) + ",0,0,200,255,1\n";
    late += "9,9,9,65535,4660,256\n";
    write_file(path, late);
    const Result<PointCloud> all = read_all(path, 100000);
    REQUIRE(all.is_ok());
    REQUIRE(all->size() == 70001);
    CHECK(all->colors.front() == Rgb8{0, 0, 0});
    CHECK(all->colors.back() == Rgb8{255, 18, 1});
    CHECK(all->las.color_low.empty());
    // ... which the reader says.
    Result<std::unique_ptr<PointReader>> r = open_point_reader(path);
    REQUIRE(r.is_ok());
    PointCloud batch;
    while (true) {
      const Result<std::size_t> n = (*r)->read(batch, 100000);
      REQUIRE(n.is_ok());
      if (*n == 0) break;
    }
    REQUIRE((*r)->info().warnings.size() == 1);
    CHECK_THAT((*r)->info().warnings[0], Catch::Matchers::Contains("colour levels are 16-bit") &&
                                             Catch::Matchers::Contains("keeps its high byte"));
  }
  // Without a level above 255 the levels are 8-bit and kept, with nothing
  // below them.
  write_file(path, "x,y,z,red,green,blue\n0,0,0,200,255,1\n");
  const Result<PointCloud> got = read_all(path, 1);
  REQUIRE(got.is_ok());
  CHECK(got->colors == std::vector<Rgb8>{{200, 255, 1}});
  CHECK(got->las.color_low.empty());
}

TEST_CASE("CSV: a level above 255 after 2^20 points of 8-bit levels is kept as 255, with a warning", "[io][xyz]") {
  test::TempDir dir;
  const std::string path = dir.file("late.xyz");
  std::string text;
  text.reserve(16u << 20);
  const std::size_t points = (std::size_t{1} << 20) + 5;
  for (std::size_t i = 0; i < points; ++i) text += (i == points - 2) ? "1 2 3 10 1000 20\n" : "1 2 3 10 200 20\n";
  write_file(path, text);
  for (const std::size_t batch : {std::size_t{100000}, std::size_t{1} << 21}) {
    INFO("batch " << batch);
    ReaderOptions o;
    o.xyz_columns = "x,y,z,r,g,b";
    Result<std::unique_ptr<PointReader>> r = open_point_reader(path, o);
    REQUIRE(r.is_ok());
    PointCloud batch_cloud;
    std::size_t seen = 0;
    Rgb8 late{};
    while (true) {
      const Result<std::size_t> n = (*r)->read(batch_cloud, batch);
      REQUIRE(n.is_ok());
      if (*n == 0) break;
      if (seen + *n > points - 2) late = batch_cloud.colors[points - 2 - seen];
      seen += *n;
    }
    REQUIRE(seen == points);
    CHECK(late == Rgb8{10, 255, 20});
    REQUIRE((*r)->info().warnings.size() == 1);
    CHECK_THAT((*r)->info().warnings[0], Catch::Matchers::Contains("has the colour level 1000") &&
                                             Catch::Matchers::Contains("is kept as 255"));
  }
}

// ---------------------------------------------------------------- float intensities

// Writes `batches` to `path` and reads the intensities back.
std::vector<float> las_intensities(const std::string& path, const std::vector<std::vector<float>>& batches) {
  WriterOptions o;
  o.intensity = true;
  Result<std::unique_ptr<PointWriter>> w = open_point_writer(path, o);
  REQUIRE(w.is_ok());
  double x = 0;
  for (const std::vector<float>& values : batches) {
    PointCloud batch;
    for (const float v : values) {
      batch.positions.push_back({x, 0, 0});
      batch.intensities.push_back(v);
      x += 1;
    }
    const Status s = (*w)->write(batch);
    INFO(s.to_string());
    REQUIRE(s.is_ok());
  }
  const Status s = (*w)->finish();
  INFO(s.to_string());
  REQUIRE(s.is_ok());
  const Result<PointCloud> got = read_point_file(path);
  INFO(got.status().to_string());
  REQUIRE(got.is_ok());
  return got->intensities;
}

TEST_CASE("LAS output scales intensities in 0..1 by 65535, one rule per file", "[io][intensity]") {
  test::TempDir dir;
  const std::string path = dir.file("out.las");
  const std::vector<float> unit = {0.0f, 0.25f, 0.5f, 0.49999997f, 1.0f};
  CHECK(las_intensities(path, {unit}) == std::vector<float>{0, 16384, 32768, 32767, 65535});
  // A later intensity outside 0..1 turns the file to the plain rule, records
  // already written included; the result is the same in any batching.
  const std::vector<float> wide = {2.5f, 70000.0f, -3.0f, 0.75f};
  const std::vector<float> plain = {0, 0, 1, 0, 1, 3, 65535, 0, 1};
  for (std::size_t split = 0; split <= unit.size() + wide.size(); ++split) {
    INFO("split " << split);
    std::vector<float> all = unit;
    all.insert(all.end(), wide.begin(), wide.end());
    const std::vector<float> a(all.begin(), all.begin() + static_cast<std::ptrdiff_t>(split));
    const std::vector<float> b(all.begin() + static_cast<std::ptrdiff_t>(split), all.end());
    CHECK(las_intensities(path, {a, b}) == plain);
  }
}

}  // namespace

}  // namespace relief

namespace relief {

TEST_CASE("directories expand to their point files by name, input lists give one path a line", "[io][inputs]") {
  test::TempDir dir;
  const std::string tiles = dir.file("tiles");
  std::filesystem::create_directories(tiles + "/sub");
  for (const char* name : {"b.las", "a.LAZ", "c.ply", ".hidden.las", "notes.md", "sub/d.las", "e.csv"}) {
    write_file(tiles + "/" + name, "x");
  }
  auto files = expand_inputs({dir.file("one.xyz"), tiles});
  REQUIRE(files.is_ok());
  // The file as it is (missing: its reader names it), then the directory's
  // point files, sorted, without the hidden one, other files or subdirectories.
  CHECK(*files == std::vector<std::string>{dir.file("one.xyz"), tiles + "/a.LAZ", tiles + "/b.las",
                                           tiles + "/c.ply", tiles + "/e.csv"});
  const std::string none = dir.file("none");
  std::filesystem::create_directories(none);
  write_file(none + "/readme.txt.bak", "x");
  auto empty = expand_inputs({none});
  REQUIRE_FALSE(empty.is_ok());
  CHECK(empty.status().code() == StatusCode::kInvalidArgument);
  CHECK_THAT(empty.status().message(), Contains("none: a directory without point files"));

  const std::string list = dir.file("list.txt");
  write_file(list, "# tiles of block 7\r\n  a.las  \r\n\r\n\tb dir/c.laz\n#x.las\n");
  auto listed = read_input_list(list);
  REQUIRE(listed.is_ok());
  CHECK(*listed == std::vector<std::string>{"a.las", "b dir/c.laz"});
  write_file(list, "# nothing\n\n");
  CHECK(read_input_list(list).status().code() == StatusCode::kInvalidArgument);
  const auto missing = read_input_list(dir.file("missing.txt"));
  CHECK(missing.status().code() == StatusCode::kIoError);
  CHECK_THAT(missing.status().message(), Contains("missing.txt: cannot open the input list"));
}

}  // namespace relief
