// PLY vertex properties and PCD fields beyond x y z, colour and intensity are
// kept as LAS extra bytes (io/extra_fields.h): exactly, in every encoding,
// described by an Extra Bytes VLR, and written back by the PLY writer.
#include <catch2/catch.hpp>

#include <lzf.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "relief/io.h"
#include "support/temp_dir.h"

using Catch::Matchers::Contains;
using Catch::Matchers::StartsWith;

namespace relief {

namespace {

using test::write_file;

// Appends `v` in little or big endian.
template <typename T>
void put(std::string& out, T v, bool big = false) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big) std::reverse(b, b + sizeof(T));
  out.append(b, sizeof(T));
}

template <typename T>
void put_le(std::vector<std::uint8_t>& out, T v) {
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.insert(out.end(), b, b + sizeof(T));
}

// The values of one test point's kept properties (what the files hold).
struct Extras {
  std::uint8_t alpha;
  float nx;
  std::int32_t label;
  std::uint16_t sweep;
  double weight;
  std::int8_t flag;
};

std::vector<Extras> make_extras(std::size_t n) {
  std::mt19937 rng(17);
  std::vector<Extras> e(n);
  for (std::size_t i = 0; i < n; ++i) {
    e[i].alpha = static_cast<std::uint8_t>(rng() & 0xFF);
    e[i].nx = static_cast<float>(static_cast<int>(rng() % 20001) - 10000) / 7777.0f;
    e[i].label = static_cast<std::int32_t>(rng()) - 7;
    e[i].sweep = static_cast<std::uint16_t>(rng() & 0xFFFF);
    e[i].weight = static_cast<double>(rng()) / 3.0e7;
    e[i].flag = static_cast<std::int8_t>(rng() & 0xFF);
  }
  // Values a text round trip or a type mix-up would get wrong.
  e[0].nx = std::numeric_limits<float>::quiet_NaN();
  e[1].label = std::numeric_limits<std::int32_t>::min();
  e[2].weight = 1.0 / 3.0;
  return e;
}

// The extra bytes a point of `e` must carry: each value little endian, in
// the files' property order.
std::vector<std::uint8_t> expected_bytes(const std::vector<Extras>& e) {
  std::vector<std::uint8_t> out;
  for (const Extras& x : e) {
    put_le(out, x.alpha);
    put_le(out, x.nx);
    put_le(out, x.label);
    put_le(out, x.sweep);
    put_le(out, x.weight);
    put_le(out, x.flag);
  }
  return out;
}

constexpr std::size_t kExtraSize = 1 + 4 + 4 + 2 + 8 + 1;

std::string shortest(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

std::string shortest(float v) {
  if (std::isnan(v)) return "nan";
  std::ostringstream s;
  s.precision(9);
  s << v;
  return s.str();
}

// A PLY of n points: x y z red green blue, then the kept properties (with a
// list property between them when `with_list`, which the reader skips).
std::string make_ply(const std::string& encoding, const std::vector<Extras>& e, bool with_list) {
  std::string h = "ply\nformat " + encoding + " 1.0\nelement vertex " + std::to_string(e.size()) +
                  "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nproperty uchar "
                  "green\nproperty uchar blue\nproperty uchar alpha\nproperty float nx\n";
  if (with_list) h += "property list uchar int neighbours\n";
  h += "property int label\nproperty ushort scan_sweep\nproperty double weight\nproperty char flag\nend_header\n";
  const bool big = encoding == "binary_big_endian";
  std::string body;
  for (std::size_t i = 0; i < e.size(); ++i) {
    const float x = static_cast<float>(i % 50), y = static_cast<float>(i / 50), z = 0.25f * static_cast<float>(i % 7);
    if (encoding == "ascii") {
      body += shortest(x) + " " + shortest(y) + " " + shortest(z) + " 1 2 3 " + std::to_string(e[i].alpha) + " " +
              shortest(e[i].nx) + " ";
      if (with_list) body += "2 10 -11 ";
      body += std::to_string(e[i].label) + " " + std::to_string(e[i].sweep) + " " + shortest(e[i].weight) + " " +
              std::to_string(e[i].flag) + "\n";
      continue;
    }
    put(body, x, big);
    put(body, y, big);
    put(body, z, big);
    body += std::string("\x01\x02\x03", 3);
    put(body, e[i].alpha, big);
    put(body, e[i].nx, big);
    if (with_list) {
      put(body, std::uint8_t{2}, big);
      put(body, std::int32_t{10}, big);
      put(body, std::int32_t{-11}, big);
    }
    put(body, e[i].label, big);
    put(body, e[i].sweep, big);
    put(body, e[i].weight, big);
    put(body, e[i].flag, big);
  }
  return h + body;
}

// Reads every point in small batches, gathering the extra bytes.
struct ReadBack {
  PointStreamInfo info;
  std::size_t points = 0;
  std::vector<std::uint8_t> extra;
};

ReadBack read_extras(const std::string& path, const ReaderOptions& options = {}) {
  auto r = open_point_reader(path, options);
  REQUIRE(r.is_ok());
  ReadBack out;
  PointCloud batch;
  for (;;) {
    auto n = (*r)->read(batch, 37);
    REQUIRE(n.is_ok());
    if (*n == 0) break;
    out.points += *n;
    REQUIRE(batch.las.extra_bytes.size() == *n * (*r)->info().extra_bytes_size);
    out.extra.insert(out.extra.end(), batch.las.extra_bytes.begin(), batch.las.extra_bytes.end());
  }
  out.info = (*r)->info();
  return out;
}

std::vector<ExtraBytesField> fields_of(const PointStreamInfo& info) {
  const auto* p = reinterpret_cast<const std::uint8_t*>(info.extra_bytes_vlr.data());
  auto fields = parse_extra_bytes_vlr({p, info.extra_bytes_vlr.size()}, info.extra_bytes_size, "test");
  REQUIRE(fields.is_ok());
  return *fields;
}

// Memcmp that treats the whole byte vectors (NaN bits included) as values.
bool same_bytes(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b) { return a == b; }

}  // namespace

TEST_CASE("PLY properties beyond x y z, colour and intensity come back as typed extra bytes", "[io][ply][extra]") {
  test::TempDir dir;
  const std::vector<Extras> e = make_extras(500);
  const std::vector<std::uint8_t> want = expected_bytes(e);
  for (const std::string encoding : {"binary_little_endian", "binary_big_endian", "ascii"}) {
    for (const bool with_list : {false, true}) {
      INFO(encoding << (with_list ? " with a list property" : ""));
      const std::string path = dir.file("p.ply");
      write_file(path, make_ply(encoding, e, with_list));
      const ReadBack got = read_extras(path);
      REQUIRE(got.points == e.size());
      CHECK(got.info.las_attributes == kLasExtraBytes);
      CHECK(got.info.extra_bytes_size == kExtraSize);
      CHECK(same_bytes(got.extra, want));
      const std::vector<ExtraBytesField> f = fields_of(got.info);
      REQUIRE(f.size() == 6);
      CHECK(f[0].name == "alpha");
      CHECK(f[0].type_name == "uint8");
      CHECK(f[1].name == "nx");
      CHECK(f[1].type_name == "float32");
      CHECK(f[2].type_name == "int32");
      CHECK(f[3].name == "scan_sweep");
      CHECK(f[3].type_name == "uint16");
      CHECK(f[4].type_name == "float64");
      CHECK(f[5].type_name == "int8");
      CHECK(f[5].offset == kExtraSize - 1);
      // A list is not kept, and the reader says so.
      const bool warned = std::any_of(got.info.warnings.begin(), got.info.warnings.end(), [](const std::string& w) {
        return w.find("'neighbours' is a list") != std::string::npos;
      });
      CHECK(warned == with_list);

      // The whole-file reader carries them too.
      auto whole = read_ply(path);
      REQUIRE(whole.is_ok());
      CHECK(same_bytes(whole->las.extra_bytes, want));

      // And they can be turned off.
      ReaderOptions off;
      off.extra_bytes = false;
      const ReadBack none = read_extras(path, off);
      CHECK(none.points == e.size());
      CHECK(none.info.las_attributes == 0);
      CHECK(none.info.extra_bytes_vlr.empty());
      CHECK(none.extra.empty());
    }
  }
}

TEST_CASE("PLY property names: cut to 32 characters with a warning, refused when two then agree", "[io][ply][extra]") {
  test::TempDir dir;
  const std::string path = dir.file("names.ply");
  const std::string long_name(40, 'q');
  write_file(path, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                   "property float " + long_name + "\nend_header\n1 2 3 4.5\n");
  const ReadBack got = read_extras(path);
  REQUIRE(got.points == 1);
  REQUIRE(fields_of(got.info).size() == 1);
  CHECK(fields_of(got.info)[0].name == std::string(32, 'q'));
  REQUIRE(got.info.warnings.size() == 1);
  CHECK_THAT(got.info.warnings[0], Contains("named '" + std::string(32, 'q') + "'"));

  write_file(path, "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
                   "property float " + long_name + "\nproperty float " + std::string(32, 'q') + "z\nend_header\n1 2 3 4 5\n");
  auto r = open_point_reader(path);
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().code() == StatusCode::kFormatError);
  CHECK_THAT(r.status().message(), StartsWith(path + ": "));
  CHECK_THAT(r.status().message(), Contains("--no-extra-bytes"));
  ReaderOptions off;
  off.extra_bytes = false;
  CHECK(open_point_reader(path, off).is_ok());
}

TEST_CASE("PLY with more properties than one Extra Bytes VLR describes is refused unless dropped", "[io][ply][extra]") {
  test::TempDir dir;
  const std::string path = dir.file("wide.ply");
  std::string h = "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                  "property float z\n";
  for (int k = 0; k < 342; ++k) h += "property uchar f" + std::to_string(k) + "\n";
  h += "end_header\n" + std::string(12 + 342, '\0');
  write_file(path, h);
  auto r = open_point_reader(path);
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().code() == StatusCode::kUnsupported);
  CHECK_THAT(r.status().message(), Contains("at most 341"));
  ReaderOptions off;
  off.extra_bytes = false;
  CHECK(open_point_reader(path, off).is_ok());

  // 341 is fine.
  h = "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n";
  for (int k = 0; k < 341; ++k) h += "property uchar f" + std::to_string(k) + "\n";
  std::string body(12, '\0');
  for (int k = 0; k < 341; ++k) body += static_cast<char>(k & 0xFF);
  write_file(path, h + "end_header\n" + body);
  const ReadBack got = read_extras(path);
  REQUIRE(got.extra.size() == 341);
  CHECK(got.extra[340] == 340 % 256);
}

TEST_CASE("PCD fields beyond x y z, colour and intensity come back as typed extra bytes", "[io][pcd][extra]") {
  test::TempDir dir;
  // normal_x F4, label U4, seg I8, hist U1 x 3, padding "_" (skipped); one
  // NaN point (skipped, as organised clouds mark no-depth pixels).
  const std::size_t n = 200;
  std::mt19937 rng(5);
  std::string bin, ascii;
  std::vector<std::uint8_t> want;
  std::vector<std::string> soa(7);
  for (std::size_t i = 0; i < n; ++i) {
    const bool nan_point = i == 17;
    const float x = nan_point ? std::numeric_limits<float>::quiet_NaN() : static_cast<float>(i % 20);
    const float y = static_cast<float>(i / 20), z = 1.5f;
    const float nx = static_cast<float>(rng() % 1000) / 999.0f;
    const std::uint32_t label = rng();
    const std::int64_t seg = -static_cast<std::int64_t>(rng()) * 4096 - 3;
    const std::uint8_t h0 = rng() & 0xFF, h1 = rng() & 0xFF, h2 = rng() & 0xFF;
    std::string rec;
    put(rec, x);
    put(rec, y);
    put(rec, z);
    put(rec, nx);
    put(rec, label);
    put(rec, std::uint16_t{0xBEEF});  // padding
    put(rec, seg);
    rec += static_cast<char>(h0);
    rec += static_cast<char>(h1);
    rec += static_cast<char>(h2);
    bin += rec;
    ascii += (nan_point ? std::string("nan") : shortest(x)) + " " + shortest(y) + " " + shortest(z) + " " +
             shortest(nx) + " " + std::to_string(label) + " 7 " + std::to_string(seg) + " " + std::to_string(h0) +
             " " + std::to_string(h1) + " " + std::to_string(h2) + "\n";
    if (nan_point) continue;
    put_le(want, nx);
    put_le(want, label);
    put_le(want, seg);
    want.insert(want.end(), {h0, h1, h2});
  }
  const std::string header = "VERSION 0.7\nFIELDS x y z normal_x label _ seg hist\nSIZE 4 4 4 4 4 2 8 1\n"
                             "TYPE F F F F U U I U\nCOUNT 1 1 1 1 1 1 1 3\nWIDTH " + std::to_string(n) +
                             "\nHEIGHT 1\nPOINTS " + std::to_string(n) + "\n";
  // binary_compressed: the same records, structure of arrays, LZF.
  const std::vector<std::size_t> widths = {4, 4, 4, 4, 4, 2, 8, 3};
  std::string fields;
  std::size_t off = 0;
  for (const std::size_t w : widths) {
    for (std::size_t i = 0; i < n; ++i) fields += bin.substr(i * 33 + off, w);
    off += w;
  }
  std::string packed(fields.size() * 2 + 64, '\0');
  const unsigned packed_size = lzf_compress(fields.data(), static_cast<unsigned>(fields.size()), packed.data(),
                                            static_cast<unsigned>(packed.size()));
  REQUIRE(packed_size > 0);
  std::string compressed;
  put(compressed, static_cast<std::uint32_t>(packed_size));
  put(compressed, static_cast<std::uint32_t>(fields.size()));
  compressed += packed.substr(0, packed_size);

  const std::string path = dir.file("p.pcd");
  for (const auto& [data, body] : {std::pair<std::string, std::string>{"binary", bin}, {"ascii", ascii},
                                   {"binary_compressed", compressed}}) {
    INFO(data);
    write_file(path, header + "DATA " + data + "\n" + body);
    const ReadBack got = read_extras(path);
    REQUIRE(got.points == n - 1);
    CHECK(got.info.skipped_points == 1);
    CHECK(got.info.extra_bytes_size == 4 + 4 + 8 + 3);
    CHECK(same_bytes(got.extra, want));
    const std::vector<ExtraBytesField> f = fields_of(got.info);
    REQUIRE(f.size() == 6);
    CHECK(f[0].name == "normal_x");
    CHECK(f[0].type_name == "float32");
    CHECK(f[1].type_name == "uint32");
    CHECK(f[2].name == "seg");
    CHECK(f[2].type_name == "int64");
    CHECK(f[3].name == "hist_0");
    CHECK(f[5].name == "hist_2");
    CHECK(f[5].type_name == "uint8");
  }
  // An ascii value out of its field's range is an error naming the point.
  write_file(path, header + "DATA ascii\n" + "1 2 3 0.5 4294967296 0 1 2 3 4\n");
  auto r = open_point_reader(path);
  REQUIRE(r.is_ok());
  PointCloud batch;
  auto bad = (*r)->read(batch, 10);
  REQUIRE_FALSE(bad.is_ok());
  CHECK_THAT(bad.status().message(), Contains("point 0"));
}

TEST_CASE("make_extra_bytes_vlr is what parse_extra_bytes_vlr reads, and refuses what a VLR cannot hold",
          "[io][extra]") {
  std::vector<ExtraBytesField> fields(3);
  fields[0].name = "height above ground";
  fields[0].data_type = 9;
  fields[0].options = (1u << 3) | (1u << 4);
  fields[0].scale = 0.01;
  fields[0].value_offset = -5;
  fields[0].description = "metres";
  fields[1].name = "raw";
  fields[1].data_type = 0;
  fields[1].options = 5;  // 5 undocumented bytes
  fields[2].name = "xyz";
  fields[2].data_type = 26;  // three int32
  auto vlr = make_extra_bytes_vlr(fields);
  REQUIRE(vlr.is_ok());
  REQUIRE(vlr->size() == 3 * 192);
  auto back = parse_extra_bytes_vlr({reinterpret_cast<const std::uint8_t*>(vlr->data()), vlr->size()}, 21, "t");
  REQUIRE(back.is_ok());
  REQUIRE(back->size() == 3);
  CHECK((*back)[0].name == "height above ground");
  CHECK((*back)[0].description == "metres");
  CHECK((*back)[0].scale == 0.01);
  CHECK((*back)[0].value_offset == -5);
  CHECK((*back)[1].size == 5);
  CHECK((*back)[2].type_name == "int32[3]");
  CHECK((*back)[2].offset == 9);

  fields[2].name = std::string(33, 'n');
  CHECK(make_extra_bytes_vlr(fields).status().code() == StatusCode::kInvalidArgument);
  fields[2].name = "ok";
  fields[2].data_type = 31;
  CHECK(make_extra_bytes_vlr(fields).status().code() == StatusCode::kInvalidArgument);
  CHECK(make_extra_bytes_vlr(std::vector<ExtraBytesField>(342)).status().code() == StatusCode::kInvalidArgument);
  CHECK(make_extra_bytes_vlr(std::vector<ExtraBytesField>(341, fields[1])).is_ok());
}

TEST_CASE("PLY output writes extra bytes as properties of their types, read back exactly", "[io][ply][extra]") {
  test::TempDir dir;
  // A LAS-style layout: float32, int64 (no PLY type: 8 uchar), 3 undocumented
  // bytes, uint16[2] (an array), 1 undocumented byte, and 2 bytes the VLR
  // leaves undescribed.
  std::vector<ExtraBytesField> fields(5);
  fields[0].name = "x";  // clashes with the coordinate: becomes x_2
  fields[0].data_type = 9;
  fields[1].name = "big id";  // a blank: becomes big_id
  fields[1].data_type = 8;
  fields[2].name = "raw";
  fields[2].data_type = 0;
  fields[2].options = 3;
  fields[3].name = "pair";
  fields[3].data_type = 13;
  fields[4].name = "flag";
  fields[4].data_type = 0;
  fields[4].options = 1;
  auto vlr = make_extra_bytes_vlr(fields);
  REQUIRE(vlr.is_ok());
  const std::uint32_t size = 4 + 8 + 3 + 4 + 1 + 2;

  PointCloud cloud;
  std::mt19937 rng(9);
  for (int i = 0; i < 300; ++i) {
    cloud.positions.push_back({i * 0.5, -i * 0.25, 3.0});
    cloud.colors.push_back({static_cast<std::uint8_t>(i), 2, 3});
    for (std::uint32_t b = 0; b < size; ++b) cloud.las.extra_bytes.push_back(static_cast<std::uint8_t>(rng()));
  }
  cloud.las.extra_bytes_size = size;

  for (const PlyEncoding enc : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian}) {
    INFO(static_cast<int>(enc));
    const std::string path = dir.file(enc == PlyEncoding::kBinaryBigEndian ? "be.ply" : "le.ply");
    WriterOptions w;
    w.colors = true;
    w.las_attributes = kLasExtraBytes;
    w.extra_bytes_vlr = *vlr;
    w.extra_bytes_size = size;
    w.ply_encoding = enc;
    auto writer = open_point_writer(path, w);
    REQUIRE(writer.is_ok());
    REQUIRE((*writer)->write(cloud).is_ok());
    REQUIRE((*writer)->finish().is_ok());

    const ReadBack got = read_extras(path);
    REQUIRE(got.points == cloud.size());
    CHECK(got.info.has_colors);
    CHECK(same_bytes(got.extra, cloud.las.extra_bytes));
    std::vector<std::string> names;
    for (const ExtraBytesField& f : fields_of(got.info)) names.push_back(f.name + ":" + f.type_name);
    const std::vector<std::string> expect = {
        "x_2:float32", "big_id_0:uint8", "big_id_1:uint8", "big_id_2:uint8", "big_id_3:uint8", "big_id_4:uint8",
        "big_id_5:uint8", "big_id_6:uint8", "big_id_7:uint8", "raw_0:uint8", "raw_1:uint8", "raw_2:uint8",
        "pair_0:uint16", "pair_1:uint16", "flag_0:uint8", "extra_20:uint8", "extra_21:uint8"};
    CHECK(names == expect);
  }

  // ASCII PLY has no way to carry them here: refused, nothing written.
  WriterOptions a;
  a.las_attributes = kLasExtraBytes;
  a.extra_bytes_vlr = *vlr;
  a.extra_bytes_size = size;
  a.ply_encoding = PlyEncoding::kAscii;
  auto refused = open_point_writer(dir.file("a.ply"), a);
  REQUIRE_FALSE(refused.is_ok());
  CHECK(refused.status().code() == StatusCode::kUnsupported);
  CHECK_FALSE(std::filesystem::exists(dir.file("a.ply")));
}


TEST_CASE("CSV header columns that text inputs do not keep are listed in a warning", "[io][xyz][extra]") {
  test::TempDir dir;
  const auto warnings_of = [&](const std::string& text) {
    const std::string path = dir.file("c.csv");
    write_file(path, text);
    const ReadBack got = read_extras(path);
    CHECK(got.points == 2);
    CHECK(got.extra.empty());
    return got.info.warnings;
  };
  const auto w = warnings_of("//X,Y,Z,R,G,B,Nx,Ny,Nz\n1,2,3,10,20,30,0,0,1\n2,3,4,10,20,30,0,1,0\n");
  REQUIRE(w.size() == 1);
  CHECK_THAT(w[0], Contains("header columns 'Nx', 'Ny', 'Nz' are not kept"));
  // A partial colour set is not read either.
  const auto partial = warnings_of("x y z red time\n1 2 3 4 5\n2 3 4 5 6\n");
  REQUIRE(partial.size() == 1);
  CHECK_THAT(partial[0], Contains("'red', 'time' are not kept"));
  CHECK(warnings_of("x,y,z,intensity\n1,2,3,4\n2,3,4,5\n").empty());
}

}  // namespace relief
