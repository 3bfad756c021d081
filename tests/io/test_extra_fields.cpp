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
  // Finite float32 values (ASCII PLY gives a NaN back without its payload),
  // some of them subnormal, and the extremes of every other type.
  for (int i = 0; i < 300; ++i) {
    std::uint8_t* f = cloud.las.extra_bytes.data() + i * size;
    float v = 0;
    std::memcpy(&v, f, 4);
    if (!std::isfinite(v)) v = i % 2 == 0 ? std::numeric_limits<float>::denorm_min() * static_cast<float>(i) : -1e38f;
    std::memcpy(f, &v, 4);
  }
  std::memset(cloud.las.extra_bytes.data() + 4, 0xFF, 8);  // point 0's int64: all ones

  for (const PlyEncoding enc : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kBinaryBigEndian, PlyEncoding::kAscii}) {
    INFO(static_cast<int>(enc));
    const std::string path = dir.file(enc == PlyEncoding::kBinaryBigEndian ? "be.ply"
                                      : enc == PlyEncoding::kAscii         ? "ascii.ply"
                                                                           : "le.ply");
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
        "x_extra:float32", "big_id_0:uint8", "big_id_1:uint8", "big_id_2:uint8", "big_id_3:uint8", "big_id_4:uint8",
        "big_id_5:uint8", "big_id_6:uint8", "big_id_7:uint8", "raw_0:uint8", "raw_1:uint8", "raw_2:uint8",
        "pair_0:uint16", "pair_1:uint16", "flag_0:uint8", "extra_20:uint8", "extra_21:uint8"};
    CHECK(names == expect);
  }

  // ASCII PLY: a NaN comes back as a NaN.
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(cloud.las.extra_bytes.data() + size, &nan, 4);  // point 1's float32
  WriterOptions a;
  a.colors = true;
  a.las_attributes = kLasExtraBytes;
  a.extra_bytes_vlr = *vlr;
  a.extra_bytes_size = size;
  a.ply_encoding = PlyEncoding::kAscii;
  auto writer = open_point_writer(dir.file("nan.ply"), a);
  REQUIRE(writer.is_ok());
  REQUIRE((*writer)->write(cloud).is_ok());
  REQUIRE((*writer)->finish().is_ok());
  const ReadBack got = read_extras(dir.file("nan.ply"));
  REQUIRE(got.extra.size() == cloud.las.extra_bytes.size());
  float back = 0;
  std::memcpy(&back, got.extra.data() + size, 4);
  CHECK(std::isnan(back));
  CHECK(std::equal(got.extra.begin() + size + 4, got.extra.end(), cloud.las.extra_bytes.begin() + size + 4));
}


namespace {

// Reads a whole text file in batches of `batch`, every array checked against
// the batch's count.
PointCloud read_text(const std::string& path, std::size_t batch, PointStreamInfo* info = nullptr,
                     const ReaderOptions& options = {}) {
  auto r = open_point_reader(path, options);
  INFO((r.is_ok() ? std::string() : r.status().to_string()));
  REQUIRE(r.is_ok());
  PointCloud all, part;
  for (;;) {
    auto n = (*r)->read(part, batch);
    INFO((n.is_ok() ? std::string() : n.status().to_string()));
    REQUIRE(n.is_ok());
    if (*n == 0) break;
    REQUIRE(part.las.extra_bytes.size() == *n * (*r)->info().extra_bytes_size);
    REQUIRE(part.las.carried() == ((*r)->info().las_attributes));
    all.append_points(part);
  }
  if (info != nullptr) *info = (*r)->info();
  return all;
}

Status read_text_status(const std::string& path, const ReaderOptions& options = {}) {
  auto r = open_point_reader(path, options);
  if (!r.is_ok()) return r.status();
  PointCloud part;
  for (;;) {
    auto n = (*r)->read(part, 1000);
    if (!n.is_ok()) return n.status();
    if (*n == 0) return Status::ok();
  }
}

double extra_f64(const PointCloud& c, std::size_t point, std::size_t field) {
  REQUIRE((point + 1) * c.las.extra_bytes_size <= c.las.extra_bytes.size());
  REQUIRE(8 * (field + 1) <= c.las.extra_bytes_size);
  double v = 0;
  std::memcpy(&v, c.las.extra_bytes.data() + point * c.las.extra_bytes_size + 8 * field, 8);
  return v;
}

std::uint64_t extra_u64(const PointCloud& c, std::size_t point, std::size_t field) {
  const double v = extra_f64(c, point, field);  // (its bounds checks)
  return std::bit_cast<std::uint64_t>(v);
}

}  // namespace

TEST_CASE("PDAL's text header gives every LAS dimension of a CSV", "[io][xyz][las]") {
  test::TempDir dir;
  const std::string path = dir.file("pdal.csv");
  // As PDAL's writers.text writes a LAS 1.4 file (quoted header, precision 3).
  write_file(path,
             "\"X\",\"Y\",\"Z\",\"Intensity\",\"ReturnNumber\",\"NumberOfReturns\",\"ScanDirectionFlag\","
             "\"EdgeOfFlightLine\",\"Classification\",\"ScanAngleRank\",\"UserData\",\"PointSourceId\",\"GpsTime\","
             "\"Red\",\"Green\",\"Blue\",\"Synthetic\",\"KeyPoint\",\"Withheld\",\"Overlap\",\"ScannerChannel\","
             "\"Infrared\"\n"
             "637012.240,849028.310,431.660,143.000,1.000,2.000,0.000,1.000,1.000,-9.006,132.000,7326.000,"
             "245380.783,68.000,77.000,88.000,1.000,0.000,1.000,0.000,2.000,4000.000\n"
             "637019.480,849018.350,446.390,18.000,2.000,2.000,1.000,0.000,65.000,12.000,0.000,65535.000,"
             "245381.010,70.000,80.000,90.000,0.000,1.000,0.000,1.000,3.000,65535.000\n");
  for (const std::size_t batch : {std::size_t{1}, std::size_t{100}}) {
    PointStreamInfo info;
    const PointCloud c = read_text(path, batch, &info);
    REQUIRE(c.size() == 2);
    CHECK(info.warnings.empty());
    CHECK(info.extra_bytes_size == 0);
    CHECK(c.positions[1].z == 446.39);
    CHECK(c.intensities == std::vector<float>{143, 18});
    CHECK(c.las.return_number == std::vector<std::uint8_t>{1, 2});
    CHECK(c.las.number_of_returns == std::vector<std::uint8_t>{2, 2});
    CHECK(c.las.classification == std::vector<std::uint8_t>{1, 65});
    CHECK(c.las.scan_angle == std::vector<std::int32_t>{-9006, 12000});  // thousandths of a degree
    CHECK(c.las.user_data == std::vector<std::uint8_t>{132, 0});
    CHECK(c.las.point_source_id == std::vector<std::uint16_t>{7326, 65535});
    CHECK(c.las.gps_time == std::vector<double>{245380.783, 245381.010});
    CHECK(c.las.class_flags == std::vector<std::uint8_t>{0b0101, 0b1010});
    CHECK(c.las.scan_flags == std::vector<std::uint8_t>{0b1010, 0b1101});  // direction, edge, channel << 2
    CHECK(c.las.nir == std::vector<std::uint16_t>{4000, 65535});
    REQUIRE(c.colors.size() == 2);
    CHECK(c.colors[1].b == 90);
  }
  // The same dimensions under LAS names through --columns.
  write_file(path, "1 2 3 245380.5 3 5 -90\n");
  ReaderOptions o;
  o.xyz_columns = "x,y,z,gps_time,return_number,number_of_returns,scan_angle";
  const PointCloud named = read_text(path, 10, nullptr, o);
  CHECK(named.las.gps_time == std::vector<double>{245380.5});
  CHECK(named.las.return_number == std::vector<std::uint8_t>{3});
  CHECK(named.las.number_of_returns == std::vector<std::uint8_t>{5});
  CHECK(named.las.scan_angle == std::vector<std::int32_t>{-90000});
  o.xyz_columns = "x,y,z,gps_time,GpsTime";
  CHECK(read_text_status(path, o).code() == StatusCode::kInvalidArgument);
  o.xyz_columns = "x,y,z,normal";
  CHECK_THAT(read_text_status(path, o).message(), Contains("unknown column 'normal'"));
}

TEST_CASE("CSV LAS dimensions out of their LAS range are refused, naming the line", "[io][xyz][las]") {
  test::TempDir dir;
  const std::string path = dir.file("bad.csv");
  const auto refused = [&](const std::string& header, const std::string& value, const std::string& what) {
    write_file(path, "x,y,z," + header + "\n1,2,3,1\n4,5,6," + value + "\n");
    const Status s = read_text_status(path);
    INFO(header << " = " << value << ": " << s.to_string());
    CHECK(s.code() == StatusCode::kFormatError);
    CHECK_THAT(s.message(), Contains("bad.csv: line 3: " + what));
  };
  refused("ReturnNumber", "16", "return number 16 is not a whole number from 0 to 15");
  refused("classification", "2.5", "classification 2.5 is not a whole number from 0 to 255");
  refused("scan_angle", "-181", "scan angle -181 is not from -180 to 180 degrees");
  refused("PointSourceId", "65536", "point source ID 65536 is not");
  refused("Withheld", "2", "withheld flag 2 is not");
  refused("ScannerChannel", "4", "scanner channel 4 is not");
  refused("GpsTime", "nan", "GPS time nan is not finite");
  refused("UserData", "x", "column 4 'x' is not a number");
}

TEST_CASE("CSV columns without a LAS meaning are kept as float64 extra bytes", "[io][xyz][extra]") {
  test::TempDir dir;
  const std::string path = dir.file("c.csv");
  // CloudCompare's comment header: normals and a scalar field.
  write_file(path, "//X,Y,Z,R,G,B,Nx,Ny,Nz,scalar_Deviation,scalar_GpsTime\n"
                   "1,2,3,10,20,30,0.1,-0.2,0.97467943448089633,1e-300,100.25\n"
                   "2,3,4,10,20,30,0,1,0,-7,100.5\n");
  PointStreamInfo info;
  PointCloud c = read_text(path, 1, &info);
  REQUIRE(c.size() == 2);
  CHECK(info.warnings.empty());
  CHECK(c.las.gps_time == std::vector<double>{100.25, 100.5});
  REQUIRE(info.extra_bytes_size == 32);
  const std::vector<ExtraBytesField> fields = fields_of(info);
  REQUIRE(fields.size() == 4);
  CHECK(fields[0].name == "Nx");
  CHECK(fields[3].name == "scalar_Deviation");
  for (const ExtraBytesField& f : fields) CHECK(f.type_name == "float64");
  CHECK(extra_f64(c, 0, 2) == 0.97467943448089633);  // every digit a double holds
  CHECK(extra_f64(c, 0, 3) == 1e-300);
  CHECK(extra_f64(c, 1, 1) == 1);
  CHECK(extra_f64(c, 1, 3) == -7);

  // A partial colour set and a repeated name are kept too, the repeat renamed;
  // an empty value is a NaN; a column of words is listed in a warning, as is a
  // second column for one LAS dimension.
  write_file(path, "x y z red t t label class Class\n1 2 3 4 5 6 a 2 3\n2 3 4 5 6 7 b 2 3\n");
  c = read_text(path, 100, &info);
  REQUIRE(info.warnings.size() == 1);
  CHECK_THAT(info.warnings[0], Contains("header columns 'label', 'Class' are not kept"));
  const std::vector<ExtraBytesField> kept = fields_of(info);
  REQUIRE(kept.size() == 3);
  CHECK(kept[0].name == "red");
  CHECK(kept[1].name == "t");
  CHECK(kept[2].name == "t_2");
  CHECK(extra_f64(c, 1, 2) == 7);
  CHECK(c.las.classification == std::vector<std::uint8_t>{2, 2});
  write_file(path, "x;y;z;w\n1;2;3;\n2;3;4;0,5\n");
  Status bad = read_text_status(path);
  CHECK_THAT(bad.message(), Contains("line 3: column 4 '0,5' is not a number (kept as float64 extra bytes 'w'; "
                                     "--no-extra-bytes skips such columns)"));
  write_file(path, "x;y;z;w\n1;2;3;\n2;3;4;5\n");
  c = read_text(path, 100, &info);
  CHECK(std::isnan(extra_f64(c, 0, 0)));
  CHECK(extra_f64(c, 1, 0) == 5);

  // --no-extra-bytes: not kept, no warning.
  ReaderOptions o;
  o.extra_bytes = false;
  write_file(path, "x y z nx\n1 2 3 0.5\n");
  c = read_text(path, 100, &info, o);
  CHECK(info.warnings.empty());
  CHECK(info.extra_bytes_size == 0);
  CHECK(c.las.extra_bytes.empty());
  // A header naming no LAS dimension or other column keeps none.
  write_file(path, "x,y,z,intensity\n1,2,3,4\n2,3,4,5\n");
  c = read_text(path, 100, &info);
  CHECK(info.warnings.empty());
  CHECK(info.las_attributes == 0);
}

TEST_CASE("CSV integer columns beyond 2^53 are kept as 64-bit integers, never rounded", "[io][xyz][extra]") {
  test::TempDir dir;
  const std::string path = dir.file("t.csv");
  // Nanosecond timestamps (a double would round them to 256 ns), a uint64 ID
  // above INT64_MAX, and a float column beside them.
  write_file(path, "x,y,z,stamp_ns,id,w\n"
                   "1,2,3,1700000000123456789,18446744073709551615,0.5\n"
                   "2,3,4,-1700000000123456781,9223372036854775808,7\n"
                   "3,4,5,+17,0,-0.25\n");
  PointStreamInfo info;
  PointCloud c = read_text(path, 2, &info);
  REQUIRE(c.size() == 3);
  CHECK(info.warnings.empty());
  const std::vector<ExtraBytesField> fields = fields_of(info);
  REQUIRE(fields.size() == 3);
  CHECK(fields[0].type_name == "int64");
  CHECK(fields[1].type_name == "uint64");
  CHECK(fields[2].type_name == "float64");
  CHECK(static_cast<std::int64_t>(extra_u64(c, 0, 0)) == 1700000000123456789);
  CHECK(static_cast<std::int64_t>(extra_u64(c, 1, 0)) == -1700000000123456781);
  CHECK(static_cast<std::int64_t>(extra_u64(c, 2, 0)) == 17);
  CHECK(extra_u64(c, 0, 1) == ~std::uint64_t{0});
  CHECK(extra_u64(c, 1, 1) == (std::uint64_t{1} << 63));
  CHECK(extra_u64(c, 2, 1) == 0);
  CHECK(extra_f64(c, 1, 2) == 7);

  // Text output prints them whole, and the reader takes them back.
  WriterOptions w;
  w.las_attributes = kLasExtraBytes;
  w.extra_bytes_size = info.extra_bytes_size;
  w.extra_bytes_vlr = info.extra_bytes_vlr;
  const std::string out = dir.file("out.csv");
  {
    auto writer = open_point_writer(out, w);
    REQUIRE(writer.is_ok());
    REQUIRE((*writer)->write(c).to_string() == "ok");
    REQUIRE((*writer)->finish().to_string() == "ok");
  }
  PointStreamInfo again_info;
  const PointCloud again = read_text(out, 100, &again_info);
  REQUIRE(again.size() == 3);
  CHECK(again.las.extra_bytes == c.las.extra_bytes);
  CHECK(again_info.extra_bytes_vlr == info.extra_bytes_vlr);

  // What an integer column refuses, naming the line and the type.
  const auto refused = [&](const std::string& second, const std::string& what) {
    write_file(path, "x,y,z,stamp_ns\n1,2,3,1700000000123456789\n2,3,4," + second + "\n");
    const Status s = read_text_status(path);
    INFO(second << ": " << s.to_string());
    CHECK(s.code() == StatusCode::kFormatError);
    CHECK_THAT(s.message(), Contains("t.csv: line 3: column 4 " + what));
    CHECK_THAT(s.message(), Contains("kept as int64 extra bytes 'stamp_ns'"));
  };
  refused("1.5", "'1.5' is not an integer");
  refused("1e18", "'1e18' is not an integer");
  refused("", "is empty");
  refused("9223372036854775808", "'9223372036854775808' is out of range");
  refused("nan", "'nan' is not an integer");

  // A float64 column (its first value small) refuses an integer it would
  // round, and keeps those it holds exactly.
  write_file(path, "x,y,z,n\n1,2,3,5\n2,3,4,9007199254740993\n");
  Status s = read_text_status(path);
  CHECK_THAT(s.message(), Contains("line 3: column 4 '9007199254740993' is an integer a float64 cannot hold exactly"));
  write_file(path, "x,y,z,n\n1,2,3,5\n2,3,4,9007199254740992\n3,4,5,-10000000000000000000000\n"
                   "4,5,6,0000000000000000000001\n");
  c = read_text(path, 100, &info);
  REQUIRE(c.size() == 4);
  CHECK(fields_of(info)[0].type_name == "float64");
  CHECK(extra_f64(c, 1, 0) == 9007199254740992.0);
  CHECK(extra_f64(c, 2, 0) == -1e22);  // exactly a double
  CHECK(extra_f64(c, 3, 0) == 1);
}

TEST_CASE("Text columns named name:type are kept as extra bytes of that type", "[io][xyz][extra]") {
  test::TempDir dir;
  const std::string path = dir.file("t.txt");
  // A scanner export without a header: amplitude, ring, a 64-bit ID, a flag.
  write_file(path, "1 2 3 0.25 17.000000 -5 skipped 1\n"
                   "4 5 6 1e-3 65535 9007199254740993 0 0\n"
                   "7 8 9 -2.5 0 -9223372036854775808 255 1\n");
  ReaderOptions o;
  o.xyz_columns = "x,y,z,amplitude:f32,ring:u16,id:i64,_,c";
  PointStreamInfo info;
  PointCloud c = read_text(path, 2, &info, o);
  REQUIRE(c.size() == 3);
  CHECK(info.las_attributes == (kLasExtraBytes | kLasClassification));
  REQUIRE(info.extra_bytes_size == 4 + 2 + 8);
  const std::vector<ExtraBytesField> fields = fields_of(info);
  REQUIRE(fields.size() == 3);
  CHECK(fields[0].name == "amplitude");
  CHECK(fields[0].type_name == "float32");
  CHECK(fields[1].type_name == "uint16");
  CHECK(fields[1].offset == 4);
  CHECK(fields[2].type_name == "int64");
  CHECK(fields[2].offset == 6);
  const auto at = [&](std::size_t point, std::size_t offset, auto v) {
    std::memcpy(&v, c.las.extra_bytes.data() + point * 14 + offset, sizeof v);
    return v;
  };
  CHECK(at(0, 0, 0.0f) == 0.25f);
  CHECK(at(1, 0, 0.0f) == 1e-3f);  // the nearest float
  CHECK(at(2, 0, 0.0f) == -2.5f);
  CHECK(at(0, 4, std::uint16_t{0}) == 17);
  CHECK(at(1, 4, std::uint16_t{0}) == 65535);
  CHECK(at(0, 6, std::int64_t{0}) == -5);
  CHECK(at(1, 6, std::int64_t{0}) == 9007199254740993);  // every digit, as an integer
  CHECK(at(2, 6, std::int64_t{0}) == std::numeric_limits<std::int64_t>::min());
  CHECK(c.las.classification == std::vector<std::uint8_t>{1, 0, 1});

  // What each type refuses, naming the line, the column and the field.
  const auto refused = [&](const std::string& columns, const std::string& value, const std::string& what) {
    write_file(path, "1,2,3,0\n4,5,6," + value + "\n");
    ReaderOptions typed;
    typed.xyz_columns = "x,y,z," + columns;
    const Status s = read_text_status(path, typed);
    INFO(columns << " = " << value << ": " << s.to_string());
    CHECK(s.code() == StatusCode::kFormatError);
    CHECK_THAT(s.message(), Contains("t.txt: line 2: column 4 " + what));
    CHECK_THAT(s.message(), Contains("extra bytes '" + columns.substr(0, columns.find(':')) + "' as the columns say"));
  };
  refused("ring:u16", "65536", "'65536' is out of range");
  refused("ring:u16", "-1", "'-1' is out of range");
  refused("ring:u8", "2.5", "'2.5' is not an integer");
  refused("ring:i8", "-129", "'-129' is out of range");
  refused("ring:u32", "", "is empty");
  refused("ring:u64", "1e300", "'1e300' is not an integer written in digits");
  refused("amp:f32", "1e39", "'1e39' is outside the float32 range");
  refused("amp:f64", "abc", "'abc' is not a number");
  // An empty float is a NaN, the missing value.
  write_file(path, "1 2 3 0.5\n4 5 6\n");
  o.xyz_columns = "x,y,z,amp:f32";
  REQUIRE(read_text_status(path, o).code() == StatusCode::kFormatError);  // a column short, not empty
  write_file(path, "1,2,3,0.5\n4,5,6,\n");
  c = read_text(path, 100, &info, o);
  REQUIRE(c.size() == 2);
  float missing = 0;
  std::memcpy(&missing, c.las.extra_bytes.data() + 4, 4);
  CHECK(std::isnan(missing));

  // Specs refused before anything is read, and --no-extra-bytes with typed columns.
  for (const char* spec : {"x,y,z,a:f16", "x,y,z,x:f32", "x,y,z,:u8", "x,y,z,a:u8,a:i8", "x,y,z,rgb:u8",
                           "x,y,z,intensity:f32", "x,y,z,a_name_of_more_than_thirty_two_bytes:u8", "x,y,z,amp"}) {
    ReaderOptions bad;
    bad.xyz_columns = spec;
    INFO(spec);
    CHECK(open_point_reader(path, bad).status().code() == StatusCode::kInvalidArgument);
  }
  ReaderOptions none;
  none.xyz_columns = "x,y,z,amp:f32";
  none.extra_bytes = false;
  const auto refused_none = open_point_reader(path, none);
  REQUIRE_FALSE(refused_none.is_ok());
  CHECK_THAT(refused_none.status().message(), Contains("--no-extra-bytes"));

  // The stream parser takes the same columns.
  auto parser = TextLineParser::create("x,y,z,ring:u16,_,amp:f32", "stdin");
  REQUIRE(parser.is_ok());
  CHECK((*parser)->extra_bytes_size() == 6);
  CHECK((*parser)->las_attributes() == kLasExtraBytes);
  CHECK((*parser)->extra_bytes_vlr().size() == 2 * 192);
  PointCloud batch;
  REQUIRE((*parser)->parse("1;2;3;513;skip;2.5", 1, batch).is_ok());
  CHECK(batch.las.extra_bytes == std::vector<std::uint8_t>{0x01, 0x02, 0x00, 0x00, 0x20, 0x40});
  CHECK(batch.las.extra_bytes_size == 6);
  const Status s = (*parser)->parse("1 2 3 70000 skip 1", 2, batch);
  CHECK_THAT(s.message(), Contains("stdin: line 2: column 4 '70000' is out of range (the uint16 field 'ring')"));
  CHECK(batch.size() == 1);
  CHECK(batch.las.extra_bytes.size() == 6);
}

}  // namespace relief

namespace relief {

TEST_CASE("A PCD rgba field's alpha is kept as uint8 extra bytes", "[io][pcd][extra]") {
  test::TempDir dir;
  const std::string path = dir.file("rgba.pcd");
  // PCL's PointXYZRGBA: rgba as U 4, alpha in the top byte.
  const std::uint32_t rgba[3] = {0xFF102030u, 0x80405060u, 0x00708090u};
  std::string pcd = "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgba\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n"
                    "WIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\nDATA binary\n";
  for (int i = 0; i < 3; ++i) {
    const float xyz[3] = {static_cast<float>(i), 1, 2};
    pcd.append(reinterpret_cast<const char*>(xyz), sizeof xyz);
    pcd.append(reinterpret_cast<const char*>(&rgba[i]), 4);
  }
  write_file(path, pcd);
  ReadBack got = read_extras(path);
  REQUIRE(got.points == 3);
  CHECK(got.extra == std::vector<std::uint8_t>{0xFF, 0x80, 0x00});
  std::vector<ExtraBytesField> fields = fields_of(got.info);
  REQUIRE(fields.size() == 1);
  CHECK(fields[0].name == "alpha");
  CHECK(fields[0].type_name == "uint8");
  auto colors = read_point_file(path);
  REQUIRE(colors.is_ok());
  CHECK(colors->colors[1].r == 0x40);
  CHECK(colors->colors[1].b == 0x60);
  // ASCII, beside a field already called alpha; --no-extra-bytes drops both.
  write_file(path, "VERSION 0.7\nFIELDS x y z rgba alpha\nSIZE 4 4 4 4 4\nTYPE F F F U F\nCOUNT 1 1 1 1 1\n"
                   "WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n0 1 2 4278194208 0.5\n1 1 2 2151698528 0.25\n");
  got = read_extras(path);
  fields = fields_of(got.info);
  REQUIRE(fields.size() == 2);
  CHECK(fields[0].name == "alpha");
  CHECK(fields[1].name == "rgba_alpha");
  REQUIRE(got.extra.size() == 10);
  CHECK(got.extra[4] == 0xFF);
  CHECK(got.extra[9] == 0x80);
  ReaderOptions none;
  none.extra_bytes = false;
  CHECK(read_extras(path, none).extra.empty());
}

}  // namespace relief

namespace relief {

TEST_CASE("Text output of points with thousands of extra byte columns writes whole lines", "[io][xyz][extra]") {
  // 40,000 undescribed extra bytes a point: 40,000 integer columns, whose
  // widest line needs more room than the output's 1 MiB block
  // (OutputFile::room grows for it).
  test::TempDir dir;
  constexpr std::uint32_t kWidth = 40000;
  PointCloud c;
  c.positions = {{1, 2, 3}, {4, 5, 6}, {7, 8, 9}};
  c.las.extra_bytes_size = kWidth;
  c.las.extra_bytes.resize(3 * kWidth);
  for (std::size_t i = 0; i < c.las.extra_bytes.size(); ++i) c.las.extra_bytes[i] = static_cast<std::uint8_t>(i * 7);
  WriterOptions w;
  w.las_attributes = kLasExtraBytes;
  w.extra_bytes_size = kWidth;
  const std::string path = dir.file("wide.csv");
  auto writer = open_point_writer(path, w);
  REQUIRE(writer.is_ok());
  REQUIRE((*writer)->write(c).to_string() == "ok");
  REQUIRE((*writer)->finish().is_ok());
  std::ifstream in(path);
  std::string line;
  std::vector<std::string> lines;
  while (std::getline(in, line)) lines.push_back(line);
  REQUIRE(lines.size() == 4);
  CHECK(lines[0].starts_with("X,Y,Z,extra_0,extra_1,"));
  CHECK(lines[0].ends_with(",extra_39999"));
  for (std::size_t k = 1; k < 4; ++k) {
    CHECK(std::count(lines[k].begin(), lines[k].end(), ',') == 3 + kWidth - 1);
  }
  // Point 2's last byte: (2 * 40000 + 39999) * 7 mod 256.
  CHECK(lines[3].ends_with("," + std::to_string(static_cast<std::uint8_t>((2 * kWidth + kWidth - 1) * 7))));
}

}  // namespace relief
