// LAS attributes through the archive: LAS -> compress -> decompress/query ->
// LAS keeps every field of every point (as multisets), the archive records
// the attribute set, point format, version and Extra Bytes VLR, queries
// filter on classification and returns.
//
// The codec keeps per-point LAS attributes once the chunk codec carries them
// (error-bounded blobs); until then the tests tagged [needs-codec-attrs] find
// that out with a probe and skip visibly.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <string>
#include <vector>

#include "relief/archive.h"
#include "relief/codec.h"
#include "relief/ingest.h"
#include "relief/io.h"
#include "relief/query.h"
#include "support/las_records.h"
#include "support/run_cli.h"
#include "support/skip.h"
#include "support/temp_dir.h"

namespace {

using relief::test::LasRecord;
using relief::test::read_las_records;
using relief::test::TempDir;
using relief::test::TestLasOptions;
using relief::test::write_test_las;

// Whether the chunk codec gives back a cloud's LAS classification.
bool codec_keeps_las_attributes() {
  relief::PointCloud c;
  for (int i = 0; i < 200; ++i) {
    c.positions.push_back({0.01 * (i % 20), 0.01 * (i / 20), 0.001 * (i % 7)});
    c.las.classification.push_back(static_cast<std::uint8_t>(i % 9));
  }
  relief::EncodeParams p;
  p.cell_size = 0.05;
  p.bound = relief::ErrorBound{};
  p.bound->step = {0.001, 0.001, 0.001};
  auto blob = relief::encode_chunk(c, p);
  if (!blob) return false;
  auto back = relief::decode_chunk(*blob);
  if (!back || back->size() != c.size()) return false;
  std::vector<std::uint8_t> a = c.las.classification, b = back->las.classification;
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  return a == b;
}

// True, or false after marking the test case skipped (visible in ctest).
bool need_codec_attributes() {
  static const bool keeps = codec_keeps_las_attributes();
  if (!keeps) {
    WARN("skipped: the chunk codec does not yet keep per-point LAS attributes (probe: "
         "decode_chunk(encode_chunk(cloud with classification)) loses it)");
    relief::test::note_skipped();
  }
  return keeps;
}

std::vector<std::uint8_t> field_vlr() {
  std::vector<std::uint8_t> v = relief::test::extra_bytes_descriptor(3, 0, "height_above_ground");
  const std::vector<std::uint8_t> b = relief::test::extra_bytes_descriptor(1, 0, "confidence");
  v.insert(v.end(), b.begin(), b.end());
  return v;
}

std::string las_file(const TempDir& dir, const std::string& name, int format, std::uint32_t seed,
                     bool extra = true, std::size_t points = 4000) {
  TestLasOptions o;
  o.format = format;
  o.points = points;
  o.seed = seed;
  if (extra) {
    o.extra = 3;
    o.extra_bytes_vlr = field_vlr();
  }
  const std::string path = dir.file(name);
  REQUIRE(write_test_las(path, o));
  return path;
}

relief::ArchiveInfo archive_info(const std::string& path) {
  auto a = relief::Archive::open(path, relief::Archive::Mode::kReadOnly);
  REQUIRE(a.is_ok());
  auto info = (*a)->info();
  REQUIRE(info.is_ok());
  return *info;
}

std::vector<LasRecord> sorted_records(const std::string& path) {
  auto r = read_las_records(path);
  REQUIRE(r);
  std::vector<LasRecord> v = r->records;
  std::sort(v.begin(), v.end());
  return v;
}

using Catch::Matchers::Contains;

std::string cli() { return RELIEF_CLI; }

}  // namespace

TEST_CASE("the archive records the LAS attributes, point format, version and Extra Bytes VLR", "[las][archive]") {
  TempDir dir;
  for (const int format : {1, 3, 6, 7, 8}) {
    CAPTURE(format);
    const std::string in = las_file(dir, "in" + std::to_string(format) + ".las", format, 10 + format);
    const std::string archive = dir.file("a" + std::to_string(format) + ".relief");
    REQUIRE(relief::compress_files({in}, archive, {}).is_ok());
    auto reader = relief::open_point_reader(in);
    REQUIRE(reader.is_ok());
    const relief::ArchiveInfo info = archive_info(archive);
    CHECK(info.las_attributes == (*reader)->info().las_attributes);
    CHECK(info.las_point_format == format);
    CHECK(info.las_version_minor == (format >= 6 ? 4 : 2));
    CHECK(info.extra_bytes_size == 3);
    const std::vector<std::uint8_t> vlr = field_vlr();
    CHECK(info.extra_bytes_vlr == std::string(vlr.begin(), vlr.end()));
    // An empty result still writes the source's format and Extra Bytes VLR.
    const std::string empty = dir.file("empty" + std::to_string(format) + ".las");
    const auto run = relief::test::run_cli(cli(), "query " + archive + " --box 0,0,0,1,1,1 -o " + empty + " --quiet");
    REQUIRE(run.code == 0);
    const auto out = read_las_records(empty);
    REQUIRE(out);
    CHECK(out->format == format);
    CHECK(out->records.empty());
    CHECK(out->extra_bytes_vlr == vlr);
    // info lists them, by name, and the typed extra bytes fields.
    const auto text = relief::test::run_cli(cli(), "info --json " + archive);
    REQUIRE(text.code == 0);
    CHECK(text.output.find("\"classification\"") != std::string::npos);
    CHECK(text.output.find("\"height_above_ground\", \"type\": \"uint16\"") != std::string::npos);
  }
}

TEST_CASE("an archive without LAS attributes reads as before", "[las][archive][compat]") {
  TempDir dir;
  relief::PointCloud c;
  for (int i = 0; i < 3000; ++i) {
    c.positions.push_back({0.1 * (i % 60), 0.1 * (i / 60), 0.01 * (i % 13)});
    c.colors.push_back({static_cast<std::uint8_t>(i), 7, 9});
  }
  REQUIRE(relief::write_ply(dir.file("in.ply"), c).is_ok());
  const std::string archive = dir.file("a.relief");
  REQUIRE(relief::compress_files({dir.file("in.ply")}, archive, {}).is_ok());
  const relief::ArchiveInfo info = archive_info(archive);
  CHECK(info.las_attributes == 0);
  CHECK(info.las_point_format == -1);
  CHECK(info.extra_bytes_vlr.empty());
  // LAS output: format 2 in LAS 1.2, every point return 1 of 1, class 0.
  const std::string out = dir.file("out.las");
  REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " -o " + out + " --quiet").code == 0);
  const auto recs = read_las_records(out);
  REQUIRE(recs);
  CHECK(recs->format == 2);
  CHECK(recs->version_minor == 2);
  REQUIRE(recs->records.size() == c.size());
  for (const LasRecord& p : recs->records) {
    REQUIRE(p.return_number == 1);
    REQUIRE(p.number_of_returns == 1);
    REQUIRE(p.classification == 0);
  }
  // Filters need the attributes: a clear error.
  relief::QueryOptions q;
  q.classes = {2};
  auto reader = relief::ArchiveReader::open(archive);
  REQUIRE(reader.is_ok());
  auto r = (*reader)->query_all(q, [](const relief::PointCloud&) { return relief::Status::ok(); });
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().code() == relief::StatusCode::kInvalidArgument);
  CHECK(r.status().message().find("classification") != std::string::npos);
  const auto run = relief::test::run_cli(cli(), "query " + archive + " --box 0,0,0,9,9,9 --last-returns -o " +
                                                    dir.file("x.las"));
  CHECK(run.code != 0);
  CHECK(run.output.find("return numbers") != std::string::npos);
}

TEST_CASE("inputs with different Extra Bytes VLRs are refused, naming both", "[las][archive][reject]") {
  TempDir dir;
  const std::string a = las_file(dir, "a.las", 3, 1);
  TestLasOptions o;
  o.format = 3;
  o.points = 4000;
  o.extra = 3;
  o.extra_bytes_vlr = relief::test::extra_bytes_descriptor(0, 3, "opaque");
  const std::string b = dir.file("b.las");
  REQUIRE(write_test_las(b, o));
  auto r = relief::compress_files({a, b}, dir.file("x.relief"), {});
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().message().find(a) != std::string::npos);
  CHECK(r.status().message().find(b) != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(dir.file("x.relief")));
  // The same against an archive on append.
  const std::string archive = dir.file("y.relief");
  REQUIRE(relief::compress_files({a}, archive, {}).is_ok());
  auto app = relief::append_files(archive, {b}, {});
  REQUIRE_FALSE(app.is_ok());
  CHECK(app.status().message().find(b) != std::string::npos);
  CHECK(app.status().message().find(archive) != std::string::npos);
}

TEST_CASE("several inputs: the archive carries the union", "[las][archive]") {
  TempDir dir;
  const std::string a = las_file(dir, "a.las", 1, 3, false);  // GPS time, no colour
  const std::string b = las_file(dir, "b.las", 8, 4, false);  // 1.4 with RGB and NIR
  const std::string archive = dir.file("u.relief");
  REQUIRE(relief::compress_files({a, b}, archive, {}).is_ok());
  const relief::ArchiveInfo info = archive_info(archive);
  // Colours only when every input has them; NIR from b.
  CHECK((info.las_attributes & relief::kLasNir) != 0);
  CHECK((info.las_attributes & relief::kLasGpsTime) != 0);
  CHECK((info.las_attributes & relief::kLasColorLow) == 0);
  CHECK(info.las_point_format == 8);
  CHECK(info.las_version_minor == 4);
}

TEST_CASE("LAS -> archive -> LAS keeps every field of every point", "[las][archive][needs-codec-attrs]") {
  if (!need_codec_attributes()) return;
  TempDir dir;
  for (const int format : {1, 3, 6, 7, 8}) {
    CAPTURE(format);
    const std::string in = las_file(dir, "in" + std::to_string(format) + ".las", format, 40 + format);
    const std::string archive = dir.file("a" + std::to_string(format) + ".relief");
    const std::string out = dir.file("out" + std::to_string(format) + ".las");
    REQUIRE(relief::test::run_cli(cli(), "compress " + in + " -o " + archive + " --quiet").code == 0);
    REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " -o " + out + " --quiet").code == 0);
    const auto back = read_las_records(out);
    REQUIRE(back);
    CHECK(back->format == format);
    REQUIRE(relief::test::first_difference(sorted_records(out), sorted_records(in)) == "");
  }
}

TEST_CASE("LAS -> archive --keep-order -> LAS gives every record back in the file's order", "[las][archive][needs-codec-attrs]") {
  if (!need_codec_attributes()) return;
  TempDir dir;
  for (const int format : {1, 3, 6, 8}) {
    CAPTURE(format);
    const std::string in = las_file(dir, "in" + std::to_string(format) + ".las", format, 60 + format);
    const std::string archive = dir.file("k" + std::to_string(format) + ".relief");
    const std::string out = dir.file("k" + std::to_string(format) + ".las");
    REQUIRE(relief::test::run_cli(cli(), "compress " + in + " -o " + archive + " --keep-order --quiet").code == 0);
    REQUIRE(archive_info(archive).codec_params.find("order=input") != std::string::npos);
    REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " -o " + out + " --quiet").code == 0);
    const auto want = read_las_records(in);
    const auto back = read_las_records(out);
    REQUIRE(want);
    REQUIRE(back);
    CHECK(back->format == format);
    // One chunk: record i is input record i, every field (as LAZ keeps them).
    REQUIRE(relief::test::first_difference(back->records, want->records) == "");
  }
}

TEST_CASE("compress --intensity-tolerance: every intensity within it, every other field exact",
          "[las][archive][needs-codec-attrs]") {
  if (!need_codec_attributes()) return;
  TempDir dir;
  const std::string in = las_file(dir, "in.las", 1, 77);
  const std::string exact = dir.file("exact.relief");
  const std::string lossy = dir.file("lossy.relief");
  REQUIRE(relief::test::run_cli(cli(), "compress " + in + " -o " + exact + " --quiet").code == 0);
  const auto made = relief::test::run_cli(cli(), "compress " + in + " -o " + lossy + " --quiet --intensity-tolerance 10");
  INFO(made.output);
  REQUIRE(made.code == 0);
  CHECK(std::filesystem::file_size(lossy) < std::filesystem::file_size(exact));
  const auto info = relief::test::run_cli(cli(), "info " + lossy);
  CHECK_THAT(info.output, Contains("colour exact, intensity within 10"));
  REQUIRE(relief::test::run_cli(cli(), "decompress " + lossy + " -o " + dir.file("out.las") + " --quiet").code == 0);
  // Pair the points by every other field; the intensities of a pair differ by at most 10.
  const auto split = [](const std::vector<LasRecord>& records) {
    std::vector<std::pair<LasRecord, int>> v;
    for (LasRecord r : records) {
      const int i = r.intensity;
      r.intensity = 0;
      v.emplace_back(r, i);
    }
    std::sort(v.begin(), v.end(), [](const auto& a, const auto& b) {
      return a.first < b.first || (a.first == b.first && a.second < b.second);
    });
    return v;
  };
  const auto want = split(sorted_records(in));
  const auto got = split(sorted_records(dir.file("out.las")));
  REQUIRE(got.size() == want.size());
  int worst = 0;
  std::size_t changed = 0;
  for (std::size_t k = 0; k < got.size(); ++k) {
    REQUIRE(got[k].first == want[k].first);
    worst = std::max(worst, std::abs(got[k].second - want[k].second));
    changed += got[k].second != want[k].second ? 1 : 0;
  }
  CHECK(worst <= 10);
  CHECK(changed > 0);
}

TEST_CASE("text output names the LAS attributes it cannot carry, PLY carries 16-bit colours", "[las][archive]") {
  TempDir dir;
  const std::string in = las_file(dir, "in.las", 3, 7);
  const std::string archive = dir.file("a.relief");
  REQUIRE(relief::test::run_cli(cli(), "compress " + in + " -o " + archive + " --quiet").code == 0);
  const auto to = [&](const std::string& name) {
    const auto run = relief::test::run_cli(cli(), "decompress " + archive + " -o " + dir.file(name) + " --quiet");
    CHECK(run.code == 0);
    return run.output;
  };
  // Text carries every LAS attribute, as a column, but the colours' low
  // bytes; PLY every one, its colours as ushort levels.
  CHECK_THAT(to("out.xyz"), Contains("out.xyz: this format does not carry the archive's color_low (write"));
  CHECK(to("out.ply").find("warning") == std::string::npos);
  CHECK(to("out.las").find("warning") == std::string::npos);
  CHECK(to("out.laz").find("warning") == std::string::npos);
  // The PLY's 16-bit levels are the LAS file's.
  auto ply = relief::open_point_reader(dir.file("out.ply"));
  REQUIRE(ply.is_ok());
  CHECK(((*ply)->info().las_attributes & relief::kLasColorLow) != 0);
  relief::PointCloud from_ply, batch;
  for (;;) {
    auto n = (*ply)->read(batch, 1 << 20);
    REQUIRE(n.is_ok());
    if (*n == 0) break;
    for (std::size_t i = 0; i < *n; ++i) from_ply.push_back_from(batch, i);
  }
  std::vector<std::array<std::uint16_t, 3>> got, want;
  for (std::size_t i = 0; i < from_ply.size(); ++i) {
    const relief::Rgb8 c = from_ply.colors[i], l = from_ply.las.color_low[i];
    got.push_back({static_cast<std::uint16_t>(c.r << 8 | l.r), static_cast<std::uint16_t>(c.g << 8 | l.g),
                   static_cast<std::uint16_t>(c.b << 8 | l.b)});
  }
  for (const LasRecord& p : sorted_records(in)) want.push_back({p.red, p.green, p.blue});
  std::sort(got.begin(), got.end());
  std::sort(want.begin(), want.end());
  CHECK(got == want);
  // The file's levels are 16-bit ones (not 8-bit levels scaled by 257).
  CHECK(std::any_of(want.begin(), want.end(), [](const auto& c) { return (c[0] & 0xFF) != (c[0] >> 8); }));
}

TEST_CASE("query filters: --class, --first-returns, --last-returns", "[las][archive][needs-codec-attrs]") {
  if (!need_codec_attributes()) return;
  TempDir dir;
  const std::string in = las_file(dir, "in.las", 6, 77);
  const std::string archive = dir.file("a.relief");
  REQUIRE(relief::compress_files({in}, archive, {}).is_ok());
  const std::vector<LasRecord> all = sorted_records(in);
  struct Case {
    std::string args;
    bool (*keep)(const LasRecord&);
  };
  const std::vector<Case> cases = {
      {"--class 2,6", [](const LasRecord& p) { return p.classification == 2 || p.classification == 6; }},
      {"--first-returns", [](const LasRecord& p) { return p.return_number == 1; }},
      {"--last-returns", [](const LasRecord& p) { return p.return_number == p.number_of_returns; }},
      {"--first-returns --last-returns",
       [](const LasRecord& p) { return p.return_number == 1 && p.number_of_returns == 1; }},
      {"--class 1,2,3,4,5,6,7,8 --first-returns",
       [](const LasRecord& p) { return p.classification >= 1 && p.classification <= 8 && p.return_number == 1; }},
  };
  for (const Case& c : cases) {
    CAPTURE(c.args);
    const std::string out = dir.file("f.las");
    std::filesystem::remove(out);
    REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " " + c.args + " -o " + out + " --quiet").code == 0);
    std::vector<LasRecord> want;
    for (const LasRecord& p : all) {
      if (c.keep(p)) want.push_back(p);
    }
    REQUIRE_FALSE(want.empty());
    REQUIRE(relief::test::first_difference(sorted_records(out), want) == "");
  }
  // With a level of detail: only matching points, about 1/L of them.
  const std::string out = dir.file("lod.las");
  REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " --class 2 --lod 4 -o " + out + " --quiet").code == 0);
  const std::vector<LasRecord> lod = sorted_records(out);
  std::size_t class2 = 0;
  for (const LasRecord& p : all) class2 += p.classification == 2 ? 1 : 0;
  CHECK(lod.size() >= class2 / 4);
  CHECK(lod.size() <= class2 / 4 + 2);
  for (const LasRecord& p : lod) REQUIRE(p.classification == 2);
}

namespace {
// A record's x, y and z alone, as LAS output writes a point without LAS
// attributes ("return 1 of 1").
LasRecord bare_xyz(const LasRecord& p) {
  LasRecord bare;
  bare.x = p.x;
  bare.y = p.y;
  bare.z = p.z;
  bare.return_number = bare.number_of_returns = 1;
  return bare;
}
}  // namespace

TEST_CASE("query and decompress --attributes: output carries only those named, the others not decoded",
          "[las][archive][needs-codec-attrs]") {
  if (!need_codec_attributes()) return;
  TempDir dir;
  const std::string in = las_file(dir, "in.las", 8, 91);  // RGB, NIR, GPS time, extra bytes
  const std::string archive = dir.file("a.relief");
  REQUIRE(relief::compress_files({in}, archive, {}).is_ok());
  const std::vector<LasRecord> all = sorted_records(in);
  struct Case {
    std::string list;
    int format;
    void (*strip)(LasRecord&);
  };
  const std::vector<Case> cases = {
      {"none", 6, [](LasRecord& p) { p = bare_xyz(p); }},
      {"classification,gps_time,rgb", 7,
       [](LasRecord& p) {
         LasRecord q = bare_xyz(p);
         q.classification = p.classification;
         q.gps_time = p.gps_time;
         q.red = p.red, q.green = p.green, q.blue = p.blue;
         p = q;
       }},
      {"number_of_returns,extra_bytes,nir,intensity", 8,
       [](LasRecord& p) {
         LasRecord q = bare_xyz(p);
         q.number_of_returns = p.number_of_returns;
         q.extra = p.extra;
         q.nir = p.nir;
         q.intensity = p.intensity;
         p = q;
       }},
  };
  for (const Case& c : cases) {
    CAPTURE(c.list);
    const std::string out = dir.file("s.las");
    std::filesystem::remove(out);
    const auto run = relief::test::run_cli(cli(), "decompress " + archive + " --attributes " + c.list + " -o " + out);
    REQUIRE(run.code == 0);
    const auto back = read_las_records(out);
    REQUIRE(back);
    CHECK(back->format == c.format);
    CHECK(back->extra_bytes_vlr.empty() == (c.list.find("extra_bytes") == std::string::npos));
    std::vector<LasRecord> want = all;
    for (LasRecord& p : want) c.strip(p);
    std::sort(want.begin(), want.end());
    REQUIRE(relief::test::first_difference(sorted_records(out), want) == "");
  }
  // With a filter on an attribute not asked for: the filter still applies.
  const std::string out = dir.file("f.las");
  REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " --class 2 --attributes none -o " + out + " --quiet")
              .code == 0);
  std::size_t class2 = 0;
  for (const LasRecord& p : all) class2 += p.classification == 2 ? 1 : 0;
  const std::vector<LasRecord> filtered = sorted_records(out);
  CHECK(filtered.size() == class2);
  for (const LasRecord& p : filtered) REQUIRE(p.classification == 0);
  // Names the archive lacks, and unknown names, are refused.
  const std::string plain = dir.file("p.relief");
  REQUIRE(relief::test::run_cli(cli(), "compress " + las_file(dir, "p.las", 1, 5, false) + " -o " + plain +
                                           " --quiet").code == 0);
  const auto lacks = relief::test::run_cli(cli(), "decompress " + plain + " --attributes rgb,nir -o " +
                                                      dir.file("x.las"));
  CHECK(lacks.code != 0);
  CHECK_THAT(lacks.output, Contains("p.relief: the attributes asked for include rgb,nir, which this archive does not carry (it has "));
  const auto unknown = relief::test::run_cli(cli(), "query " + archive + " --box 0,0,1,1 --attributes colour -o " +
                                                        dir.file("x.las"));
  CHECK(unknown.code == 2);
  CHECK_THAT(unknown.output, Contains("attribute 'colour' is unknown"));
}

TEST_CASE("an input without an attribute gets zeros", "[las][archive][needs-codec-attrs]") {
  if (!need_codec_attributes()) return;
  TempDir dir;
  const std::string a = las_file(dir, "a.las", 1, 5, false, 3000);
  relief::PointCloud c;
  for (int i = 0; i < 3000; ++i) c.positions.push_back({500000 + 0.03 * (i % 60), 4000000 + 0.03 * (i / 60), 1});
  REQUIRE(relief::write_ply(dir.file("b.ply"), c).is_ok());
  const std::string archive = dir.file("z.relief");
  REQUIRE(relief::compress_files({a, dir.file("b.ply")}, archive, {}).is_ok());
  auto reader = relief::ArchiveReader::open(archive);
  REQUIRE(reader.is_ok());
  std::size_t zero_class = 0, points = 0;
  REQUIRE((*reader)
              ->query_all({},
                          [&](const relief::PointCloud& b) {
                            REQUIRE(b.las.classification.size() == b.size());
                            REQUIRE(b.las.gps_time.size() == b.size());
                            for (std::size_t i = 0; i < b.size(); ++i) {
                              zero_class += b.las.gps_time[i] == 0 && b.las.return_number[i] == 0 ? 1 : 0;
                            }
                            points += b.size();
                            return relief::Status::ok();
                          })
              .is_ok());
  CHECK(points == 6000);
  CHECK(zero_class >= 3000);
}

TEST_CASE("a CSV classification column is a LAS attribute of the archive", "[las][archive]") {
  TempDir dir;
  const std::string csv = dir.file("c.csv");
  {
    std::ofstream f(csv);
    f << "x,y,z,classification\n";
    for (int i = 0; i < 3000; ++i) f << 0.1 * (i % 60) << "," << 0.1 * (i / 60) << ",1," << (i % 3 == 0 ? 65 : 2) << "\n";
  }
  const std::string archive = dir.file("c.relief");
  REQUIRE(relief::compress_files({csv}, archive, {}).is_ok());
  const relief::ArchiveInfo info = archive_info(archive);
  CHECK(info.las_attributes == relief::kLasClassification);
  // Classes above 31 need a LAS 1.4 format: the archive names 6.
  CHECK(info.las_point_format == 6);
}

namespace {

// The global encoding field (header bytes 6-7) of a LAS file.
std::uint16_t global_encoding_of(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  char b[8] = {};
  f.read(b, sizeof b);
  REQUIRE(f.gcount() == 8);
  return static_cast<std::uint16_t>(static_cast<std::uint8_t>(b[6]) | (static_cast<std::uint8_t>(b[7]) << 8));
}

// A test LAS file `name` in `dir` as `o` says.
std::string las_file_as(const TempDir& dir, const std::string& name, const TestLasOptions& o) {
  const std::string path = dir.file(name);
  REQUIRE(write_test_las(path, o));
  return path;
}

std::string las_with_time(const TempDir& dir, const std::string& name, int format, std::uint16_t global_encoding,
                          std::uint32_t seed) {
  TestLasOptions o;
  o.format = format;
  o.points = 2000;
  o.seed = seed;
  o.global_encoding = global_encoding;
  return las_file_as(dir, name, o);
}

}  // namespace

TEST_CASE("what the GPS times count (global encoding bit 0) is recorded and written back", "[las][archive]") {
  TempDir dir;
  for (const std::uint16_t bit : {std::uint16_t{0}, std::uint16_t{1}}) {
    for (const int format : {1, 3, 7}) {
      CAPTURE(bit, format);
      const std::string tag = std::to_string(bit) + "_" + std::to_string(format);
      const std::string in = las_with_time(dir, "t" + tag + ".las", format, bit, 7);
      const std::string archive = dir.file("t" + tag + ".relief");
      REQUIRE(relief::compress_files({in}, archive, {}).is_ok());
      const relief::ArchiveInfo info = archive_info(archive);
      CHECK(info.las_gps_time_type == (bit ? relief::GpsTimeType::kStandard : relief::GpsTimeType::kWeek));
      for (const char* ext : {".las", ".laz"}) {
        const std::string out = dir.file("t" + tag + ext);
        REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " -o " + out + " --quiet").code == 0);
        CHECK((global_encoding_of(out) & 1) == bit);
      }
      const auto json = relief::test::run_cli(cli(), "info " + archive + " --json");
      REQUIRE(json.code == 0);
      CHECK(json.output.find(std::string("\"gps_time_type\": \"") + (bit ? "standard" : "week") + "\"") !=
            std::string::npos);
    }
  }
  // No GPS time in the format: nothing is recorded and bit 0 stays clear.
  const std::string plain = las_with_time(dir, "f0.las", 0, 1, 8);
  const std::string archive = dir.file("f0.relief");
  REQUIRE(relief::compress_files({plain}, archive, {}).is_ok());
  CHECK(archive_info(archive).las_gps_time_type == relief::GpsTimeType::kUnknown);
  const std::string out = dir.file("f0_out.las");
  REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " -o " + out + " --quiet").code == 0);
  CHECK((global_encoding_of(out) & 1) == 0);
}

TEST_CASE("GPS times from text say what they count in LAS output", "[las][archive]") {
  TempDir dir;
  // Seconds of a week give bit 0 clear, adjusted standard GPS time sets it,
  // whatever the (1.4) point format a CSV's LAS columns give.
  for (const auto& [times, bit] : {std::pair{std::string("0.5\n604799.9"), 0}, std::pair{std::string("0.5\n4.1e8"), 1},
                                   std::pair{std::string("-3.5e7\n10"), 1}}) {
    CAPTURE(times);
    std::string csv = "x,y,z,gps_time\n";
    std::size_t start = 0;
    int k = 0;
    while (start <= times.size()) {
      const std::size_t nl = std::min(times.find('\n', start), times.size());
      csv += std::to_string(k++) + ",1,2," + times.substr(start, nl - start) + "\n";
      start = nl + 1;
    }
    const std::string in = dir.file("t.csv");
    { std::ofstream(in) << csv; }
    const std::string archive = dir.file("t.relief");
    std::filesystem::remove(archive);
    REQUIRE(relief::compress_files({in}, archive, {}).is_ok());
    CHECK(archive_info(archive).las_gps_time_type == relief::GpsTimeType::kUnknown);
    for (const char* ext : {".las", ".laz"}) {
      const std::string out = dir.file(std::string("t") + ext);
      REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " -o " + out + " --quiet").code == 0);
      CHECK((global_encoding_of(out) & 1) == bit);
    }
  }
}

TEST_CASE("inputs whose GPS times count differently are refused, naming both", "[las][archive][reject]") {
  TempDir dir;
  const std::string week = las_with_time(dir, "week.las", 1, 0, 1);
  const std::string standard = las_with_time(dir, "standard.las", 3, 1, 2);
  const std::string no_time = las_with_time(dir, "no_time.las", 2, 0, 3);
  auto r = relief::compress_files({week, standard}, dir.file("x.relief"), {});
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().code() == relief::StatusCode::kInvalidArgument);
  CHECK(r.status().message().find(week) != std::string::npos);
  CHECK(r.status().message().find(standard) != std::string::npos);
  CHECK(r.status().message().find("GPS") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(dir.file("x.relief")));
  // A file without GPS time joins either kind.
  REQUIRE(relief::compress_files({standard, no_time}, dir.file("ok.relief"), {}).is_ok());
  CHECK(archive_info(dir.file("ok.relief")).las_gps_time_type == relief::GpsTimeType::kStandard);
  // An append of the other kind is refused and leaves the archive as it was.
  const std::string archive = dir.file("y.relief");
  REQUIRE(relief::compress_files({week}, archive, {}).is_ok());
  const relief::ArchiveInfo before = archive_info(archive);
  auto app = relief::append_files(archive, {standard}, {});
  REQUIRE_FALSE(app.is_ok());
  CHECK(app.status().message().find(standard) != std::string::npos);
  CHECK(app.status().message().find(archive) != std::string::npos);
  const relief::ArchiveInfo after = archive_info(archive);
  CHECK(after.chunk_count == before.chunk_count);
  CHECK(after.las_gps_time_type == relief::GpsTimeType::kWeek);
  // The same kind appends.
  REQUIRE(relief::append_files(archive, {las_with_time(dir, "week2.las", 3, 0, 4)}, {}).is_ok());
  CHECK(archive_info(archive).las_gps_time_type == relief::GpsTimeType::kWeek);
  // Text GPS times say not what they count: they take the archive's week
  // time when they lie within a week, and are refused, named, when not.
  const auto csv = [&](const std::string& name, const char* second_time) {
    const std::string path = dir.file(name);
    std::ofstream(path) << "x,y,z,intensity,gps_time\n1,2,3,7,100.5\n2,2,3,9," << second_time << "\n";
    return path;
  };
  const relief::ArchiveInfo week_before = archive_info(archive);
  auto text = relief::append_files(archive, {csv("standard.csv", "1.0e9")}, {});
  REQUIRE_FALSE(text.is_ok());
  CHECK(text.status().code() == relief::StatusCode::kInvalidArgument);
  CHECK_THAT(text.status().message(),
             Catch::StartsWith(dir.file("standard.csv") +
                               ": point 1: GPS time 1000000000 is not seconds of a GPS week"));
  CHECK(archive_info(archive).chunk_count == week_before.chunk_count);
  REQUIRE(relief::append_files(archive, {csv("week.csv", "604799.5")}, {}).is_ok());
  // And beside a LAS file of week time in one compress.
  auto both = relief::compress_files({week, csv("late.csv", "-1")}, dir.file("z.relief"), {});
  REQUIRE_FALSE(both.is_ok());
  CHECK_THAT(both.status().message(), Catch::Contains("GPS time -1 is not seconds of a GPS week"));
  CHECK_THAT(both.status().message(), Catch::Contains("the kind of " + week));
}

TEST_CASE("compress --attributes keeps only those attributes of the inputs", "[las][archive][needs-codec-attrs]") {
  if (!need_codec_attributes()) return;
  TempDir dir;
  const std::string in = las_file(dir, "in.las", 8, 92);
  const std::string archive = dir.file("a.relief");
  const auto run = relief::test::run_cli(
      cli(), "compress " + in + " -o " + archive + " --attributes classification,gps_time,rgb --quiet");
  REQUIRE(run.code == 0);
  const relief::ArchiveInfo info = archive_info(archive);
  CHECK(info.has_colors);
  CHECK_FALSE(info.has_intensity);
  CHECK(info.las_attributes == (relief::kLasClassification | relief::kLasGpsTime | relief::kLasColorLow));
  CHECK(info.extra_bytes_vlr.empty());
  const std::string out = dir.file("out.las");
  REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " -o " + out + " --quiet").code == 0);
  const auto back = read_las_records(out);
  REQUIRE(back);
  CHECK(back->format == 7);
  std::vector<LasRecord> want;
  for (const LasRecord& p : sorted_records(in)) {
    LasRecord q = bare_xyz(p);
    q.classification = p.classification;
    q.gps_time = p.gps_time;
    q.red = p.red, q.green = p.green, q.blue = p.blue;  // 16-bit, with their low bytes
    want.push_back(q);
  }
  std::sort(want.begin(), want.end());
  REQUIRE(relief::test::first_difference(sorted_records(out), want) == "");
  // An unknown name is a usage error before anything is written.
  const auto bad = relief::test::run_cli(cli(), "compress " + in + " -o " + dir.file("b.relief") +
                                                    " --attributes classification,colour");
  CHECK(bad.code == 2);
  CHECK_THAT(bad.output, Contains("--attributes: attribute 'colour' is unknown"));
  CHECK_FALSE(std::filesystem::exists(dir.file("b.relief")));
}

TEST_CASE("archive_stats summarises every attribute as the input holds it, only those asked for",
          "[las][archive][stats][needs-codec-attrs]") {
  if (!need_codec_attributes()) return;
  TempDir dir;
  const std::string in = las_file(dir, "in.las", 8, 123);  // RGB, NIR, GPS time, extra bytes
  const std::string archive = dir.file("a.relief");
  REQUIRE(relief::compress_files({in}, archive, {}).is_ok());
  const auto file = read_las_records(in);
  REQUIRE(file);
  const std::vector<LasRecord>& recs = file->records;
  auto reader = relief::ArchiveReader::open(archive);
  REQUIRE(reader.is_ok());
  auto stats = relief::archive_stats(**reader, nullptr, {});
  REQUIRE(stats.is_ok());
  const relief::ArchiveStats& s = *stats;
  REQUIRE(s.points == recs.size());
  std::array<std::uint64_t, 256> classes{};
  std::array<std::uint64_t, 16> returns{}, counts{};
  std::set<std::uint16_t> sources;
  double gps_lo = recs[0].gps_time, gps_hi = recs[0].gps_time, z_lo = 1e300, z_hi = -1e300;
  int angle_lo = 1 << 30, angle_hi = -(1 << 30), height_lo = 1 << 30, height_hi = -1, red_hi = 0;
  std::uint64_t withheld = 0, edge = 0;
  for (const LasRecord& p : recs) {
    ++classes[p.classification];
    ++returns[p.return_number];
    ++counts[p.number_of_returns];
    sources.insert(p.point_source_id);
    gps_lo = std::min(gps_lo, p.gps_time);
    gps_hi = std::max(gps_hi, p.gps_time);
    z_lo = std::min(z_lo, p.z * file->scale[2] + file->offset[2]);
    z_hi = std::max(z_hi, p.z * file->scale[2] + file->offset[2]);
    angle_lo = std::min(angle_lo, p.scan_angle);
    angle_hi = std::max(angle_hi, p.scan_angle);
    const int height = p.extra[0] | (p.extra[1] << 8);  // uint16 "height_above_ground"
    height_lo = std::min(height_lo, height);
    height_hi = std::max(height_hi, height);
    red_hi = std::max(red_hi, p.red >> 8);
    withheld += p.withheld;
    edge += p.edge;
  }
  CHECK(s.classification == classes);
  CHECK(s.return_number == returns);
  CHECK(s.number_of_returns == counts);
  CHECK(s.point_sources == sources.size());
  CHECK(s.gps_time.min == gps_lo);
  CHECK(s.gps_time.max == gps_hi);
  CHECK(s.z.min == Approx(z_lo).margin(1e-9));
  CHECK(s.z.max == Approx(z_hi).margin(1e-9));
  CHECK(s.scan_angle.min == Approx(angle_lo * 0.006).margin(1e-9));  // LAS 1.4 steps of 0.006 degree
  CHECK(s.scan_angle.max == Approx(angle_hi * 0.006).margin(1e-9));
  CHECK(s.withheld == withheld);
  CHECK(s.edge_of_flight_line == edge);
  CHECK(s.red.max == red_hi);
  REQUIRE(s.extra.size() == 2);
  CHECK(s.extra[0].first == "height_above_ground");
  CHECK(s.extra[0].second.min == height_lo);
  CHECK(s.extra[0].second.max == height_hi);
  CHECK(s.extra[0].second.count == recs.size());
  // Only what is asked for, and a box: the points a query of it returns.
  relief::QueryOptions some;
  some.attributes = {false, false, relief::kLasClassification};
  const relief::Box3d box{{-1e9, -1e9, -1e9}, {1e9, 1e9, z_lo + (z_hi - z_lo) / 2}};
  auto part = relief::archive_stats(**reader, &box, some);
  REQUIRE(part.is_ok());
  CHECK(part->las == relief::kLasClassification);
  CHECK_FALSE(part->has_colors);
  std::uint64_t in_box = 0;
  REQUIRE((*reader)->query(box, some, [&](const relief::PointCloud& c) {
    in_box += c.size();
    return relief::Status::ok();
  }).is_ok());
  CHECK(part->points == in_box);
  std::uint64_t classified = 0;
  for (const std::uint64_t n : part->classification) classified += n;
  CHECK(classified == in_box);
  CHECK(part->z.max <= box.max.z);
  // The CLI prints them, as text or JSON.
  const auto text = relief::test::run_cli(cli(), "stats " + archive + " --attributes classification,gps_time");
  REQUIRE(text.code == 0);
  CHECK_THAT(text.output, Contains("points               " ));
  CHECK_THAT(text.output, Contains("gps_time"));
  CHECK(text.output.find("intensity") == std::string::npos);
  // One line per class present, with its ASPRS name.
  REQUIRE(classes[2] > 0);
  CHECK_THAT(text.output, Contains("  2 ground "));
  const auto json = relief::test::run_cli(cli(), "stats " + archive + " --json --attributes point_source_id");
  REQUIRE(json.code == 0);
  CHECK_THAT(json.output, Contains("\"point_sources\": " + std::to_string(sources.size())));
  relief::QueryOptions coarse;
  coarse.lod = 4;
  CHECK(relief::archive_stats(**reader, nullptr, coarse).status().code() == relief::StatusCode::kInvalidArgument);
  // The source file summarises to the same JSON, byte for byte: the archive
  // gives every value back (means compensated, so the order of the points
  // does not show).
  const auto from_file = relief::test::run_cli(cli(), "stats " + in + " --json");
  const auto from_archive = relief::test::run_cli(cli(), "stats " + archive + " --json");
  REQUIRE(from_file.code == 0);
  REQUIRE(from_archive.code == 0);
  CHECK(from_file.output == from_archive.output);
  auto direct = relief::point_file_stats(in);
  REQUIRE(direct.is_ok());
  CHECK(relief::archive_stats_json(*direct) == relief::archive_stats_json(s));
  CHECK(relief::test::run_cli(cli(), "stats " + in + " --box 0,0,1,1").code == 2);
}

TEST_CASE("a mean of doubles near the largest finite one is finite and the same in any order", "[stats]") {
  // A float64 extra bytes field may hold values near 1.8e308: two of them
  // overflowed a double sum to inf, and inf + -inf to NaN; which pairs met
  // depended on the order, so a file and its archive printed different means.
  std::vector<double> values;
  std::uint64_t state = 7;
  for (int i = 0; i < 2000; ++i) {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    const double unit = static_cast<double>(state >> 11) / 9007199254740992.0;  // [0, 1)
    values.push_back((i % 3 == 0 ? -1.5e308 : 1.5e308) * unit);
  }
  values.push_back(std::numeric_limits<double>::quiet_NaN());
  values.push_back(std::numeric_limits<double>::infinity());
  relief::ValueSummary forward, backward;
  for (const double v : values) forward.add(v);
  for (auto it = values.rbegin(); it != values.rend(); ++it) backward.add(*it);
  long double exact = 0;
  for (const double v : values) {
    if (std::isfinite(v)) exact += v;
  }
  CHECK(forward.count == 2000);
  CHECK(forward.non_finite == 2);
  CHECK(std::isfinite(forward.mean()));
  CHECK(forward.mean() == backward.mean());
  CHECK(forward.mean() == Approx(static_cast<double>(exact / 2000)).epsilon(1e-12));
}

TEST_CASE("an archive of format version 2 (a committed file) reads, and a writer upgrades it to 3",
          "[las][archive][compat]") {
  TempDir dir;
  // tests/fuzz/corpus/archive/seed_bounded_simple_las.relief: tests/data/simple.las compressed
  // by an early format-2 build (chunk format 2: x y z at the LAS scale, intensity and 8-bit
  // colours exact, no other LAS attribute).
  const std::string source = std::string(RELIEF_SOURCE_DIR) + "/tests/data/simple.las";
  const std::string archive = dir.file("v2.relief");
  std::filesystem::copy_file(std::string(RELIEF_SOURCE_DIR) + "/tests/fuzz/corpus/archive/seed_bounded_simple_las.relief",
                             archive);
  std::filesystem::permissions(archive, std::filesystem::perms::owner_write, std::filesystem::perm_options::add);
  CHECK(archive_info(archive).format_version == 2);
  // What that build kept of each record: the LAS integers, intensity and the 8-bit colour
  // levels (simple.las stores them as they are in its 16-bit fields; that build wrote them
  // back as 16-bit levels, level * 257).
  using Kept = std::array<std::int64_t, 7>;
  const auto kept = [](const std::string& path) {
    const auto level = [](std::uint16_t c) { return c > 255 ? c >> 8 : c; };
    std::vector<Kept> v;
    for (const LasRecord& r : sorted_records(path)) {
      v.push_back({r.x, r.y, r.z, r.intensity, level(r.red), level(r.green), level(r.blue)});
    }
    std::sort(v.begin(), v.end());
    return v;
  };
  const std::vector<Kept> want = kept(source);
  REQUIRE(want.size() == 1065);
  const std::string out = dir.file("v2.las");
  REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " -o " + out + " --quiet").code == 0);
  CHECK(kept(out) == want);
  // A writer (append) upgrades it in place; both scans then read back.
  REQUIRE(relief::test::run_cli(cli(), "append " + archive + " " + source + " --quiet").code == 0);
  const relief::ArchiveInfo info = archive_info(archive);
  CHECK(info.format_version == 3);
  CHECK(info.input_points == 2 * 1065);
  CHECK(relief::test::run_cli(cli(), "check " + archive).code == 0);
  const std::string both = dir.file("both.las");
  REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " -o " + both + " --quiet").code == 0);
  std::vector<Kept> twice = want;
  twice.insert(twice.end(), want.begin(), want.end());
  std::sort(twice.begin(), twice.end());
  CHECK(kept(both) == twice);
}

namespace {

// Colour low bytes' share of an archive (0 when it has none).
std::uint64_t color_low_bytes(const std::string& path) {
  auto a = relief::Archive::open(path, relief::Archive::Mode::kReadOnly);
  REQUIRE(a.is_ok());
  auto s = relief::archive_sections(**a);
  REQUIRE(s.is_ok());
  for (const relief::SectionTotal& t : s->sections) {
    if (t.name == "color_low") return t.bytes;
  }
  return 0;
}

// Sets point `i`'s colour channel `channel` (0 red, 1 green, 2 blue) of a
// LAS 1.2 file of point format 2 or 3 to `level`.
void set_las_level(const std::string& path, std::size_t i, int channel, std::uint16_t level) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  REQUIRE(f);
  unsigned char h[107];
  f.read(reinterpret_cast<char*>(h), sizeof h);
  const std::uint32_t offset = h[96] | h[97] << 8 | h[98] << 16 | static_cast<std::uint32_t>(h[99]) << 24;
  const int format = h[104] & 0x3F;
  const std::size_t length = h[105] | h[106] << 8;
  REQUIRE((format == 2 || format == 3));
  const std::size_t rgb = format == 2 ? 20 : 28;
  f.seekp(static_cast<std::streamoff>(offset + i * length + rgb + 2 * static_cast<std::size_t>(channel)));
  const char b[2] = {static_cast<char>(level & 0xFF), static_cast<char>(level >> 8)};
  f.write(b, 2);
  REQUIRE(f);
}

}  // namespace

TEST_CASE("colour levels above 255 after a sample of 8-bit levels come back exactly, with a warning",
          "[las][archive][needs-codec-attrs]") {
  if (!need_codec_attributes()) return;
  TempDir dir;
  // 2^20 + 64 points on a 1 cm grid whose levels are 0..255 (8-bit levels in
  // the 16-bit fields; a smooth pattern, so the archive is quick to make),
  // then three levels above 255 after the rule's sample.
  const std::size_t points = (std::size_t{1} << 20) + 64;
  const std::string in = dir.file("late.las");
  {
    relief::PointCloud c;
    for (std::size_t i = 0; i < points; ++i) {
      c.positions.push_back({0.01 * static_cast<double>(i % 1024), 0.01 * static_cast<double>(i / 1024), 0});
      c.colors.push_back({static_cast<std::uint8_t>(i / 4096), static_cast<std::uint8_t>((i % 1024) / 4),
                          static_cast<std::uint8_t>(i % 7)});
    }
    relief::WriterOptions w;
    w.colors = true;
    w.scale = 0.01;
    w.las_point_format = 2;
    w.las_colors_8bit = true;
    auto writer = relief::open_point_writer(in, w);
    REQUIRE(writer.is_ok());
    REQUIRE((*writer)->write(c).is_ok());
    REQUIRE((*writer)->finish().is_ok());
  }
  const std::size_t first_late = (std::size_t{1} << 20) + 10;
  set_las_level(in, first_late, 0, 1000);
  set_las_level(in, first_late + 10, 1, 65535);
  set_las_level(in, first_late + 20, 2, 256);

  // The reader, in small batches and in one: the split levels give every
  // level back, and one warning names the first.
  const auto want = read_las_records(in);
  REQUIRE(want);
  for (const std::size_t batch_size : {std::size_t{50000}, std::size_t{1} << 21}) {
    CAPTURE(batch_size);
    auto reader = relief::open_point_reader(in);
    REQUIRE(reader.is_ok());
    relief::PointCloud batch;
    std::size_t at = 0;
    for (;;) {
      auto n = (*reader)->read(batch, batch_size);
      REQUIRE(n.is_ok());
      if (*n == 0) break;
      for (std::size_t i = 0; i < *n; ++i, ++at) {
        const relief::Rgb8 c = batch.colors[i], l = batch.las.color_low[i];
        const relief::test::LasRecord& r = want->records[at];
        if (relief::las_color_level(c.r, l.r, true) != r.red || relief::las_color_level(c.g, l.g, true) != r.green ||
            relief::las_color_level(c.b, l.b, true) != r.blue) {
          FAIL("point " << at << ": levels " << r.red << " " << r.green << " " << r.blue << " read as " << int{c.r}
                        << "/" << int{l.r} << " " << int{c.g} << "/" << int{l.g} << " " << int{c.b} << "/" << int{l.b});
        }
      }
    }
    CHECK(at == points);
    CHECK((*reader)->info().las_colors_8bit);
    const std::vector<std::string>& warnings = (*reader)->info().warnings;
    REQUIRE(warnings.size() == 1);
    CHECK_THAT(warnings[0], Contains("point 1048586 has the colour level 1000") &&
                                Contains("the first 1048576 points held none above 255") &&
                                Contains("kept exactly"));
  }

  // Through an archive: LAS output gives every record back.
  const std::string archive = dir.file("late.relief");
  const std::string out = dir.file("late-out.las");
  const auto made = relief::test::run_cli(cli(), "compress " + in + " -o " + archive + " --quiet");
  REQUIRE(made.code == 0);
  CHECK_THAT(made.output, Contains("warning: " + in + ": point 1048586 has the colour level 1000"));
  CHECK(archive_info(archive).las_colors_8bit);
  REQUIRE(relief::test::run_cli(cli(), "decompress " + archive + " -o " + out + " --quiet").code == 0);
  REQUIRE(relief::test::first_difference(sorted_records(out), sorted_records(in)) == "");
}

TEST_CASE("a colour tolerance on 8-bit levels: the low bytes cost nothing, LAS output is within it",
          "[las][archive][needs-codec-attrs]") {
  if (!need_codec_attributes()) return;
  TempDir dir;
  for (const bool wide : {false, true}) {
    CAPTURE(wide);
    // 8-bit levels in the 16-bit fields, or 16-bit levels v * 257 (low byte = high byte).
    TestLasOptions o;
    o.format = 3;
    o.points = 6000;
    o.seed = 5;
    o.wide_colors = false;
    const std::string in = las_file_as(dir, wide ? "w.las" : "n.las", o);
    if (wide) {
      const auto records = read_las_records(in);
      REQUIRE(records);
      for (std::size_t i = 0; i < records->records.size(); ++i) {
        const relief::test::LasRecord& r = records->records[i];
        set_las_level(in, i, 0, static_cast<std::uint16_t>(r.red * 257));
        set_las_level(in, i, 1, static_cast<std::uint16_t>(r.green * 257));
        set_las_level(in, i, 2, static_cast<std::uint16_t>(r.blue * 257));
      }
    }
    const std::string exact = dir.file(wide ? "we.relief" : "ne.relief");
    const std::string lossy = dir.file(wide ? "wl.relief" : "nl.relief");
    REQUIRE(relief::test::run_cli(cli(), "compress " + in + " -o " + exact + " --quiet").code == 0);
    REQUIRE(relief::test::run_cli(cli(), "compress " + in + " -o " + lossy + " --quiet --color-tolerance 4").code == 0);
    CHECK(archive_info(lossy).las_colors_8bit == !wide);
    // Before, the low bytes kept the exact levels: the lossy archive was the larger.
    CHECK(color_low_bytes(lossy) < 16);
    CHECK(std::filesystem::file_size(lossy) < std::filesystem::file_size(exact));
    const std::string out = dir.file(wide ? "w-out.las" : "n-out.las");
    REQUIRE(relief::test::run_cli(cli(), "decompress " + lossy + " -o " + out + " --quiet").code == 0);
    // Pair the points by every other field; each level within 4 levels of 8 bits.
    const auto split = [](const std::vector<LasRecord>& records) {
      std::vector<std::pair<LasRecord, std::array<int, 3>>> v;
      for (LasRecord r : records) {
        const std::array<int, 3> levels = {r.red, r.green, r.blue};
        r.red = r.green = r.blue = 0;
        v.emplace_back(r, levels);
      }
      std::sort(v.begin(), v.end());
      return v;
    };
    const auto want = split(sorted_records(in));
    const auto got = split(sorted_records(out));
    REQUIRE(got.size() == want.size());
    const int unit = wide ? 257 : 1;
    int worst = 0;
    for (std::size_t k = 0; k < got.size(); ++k) {
      REQUIRE(got[k].first == want[k].first);
      for (int c = 0; c < 3; ++c) {
        REQUIRE(got[k].second[static_cast<std::size_t>(c)] % unit == 0);
        worst = std::max(worst, std::abs(got[k].second[static_cast<std::size_t>(c)] - want[k].second[static_cast<std::size_t>(c)]) / unit);
      }
    }
    CHECK(worst <= 4);
    CHECK(worst > 0);
  }
}

TEST_CASE("8-bit and 16-bit colour levels in one archive: the scaled levels are named in a warning",
          "[las][archive]") {
  TempDir dir;
  const auto file = [&](const std::string& name, bool wide, std::uint32_t seed) {
    TestLasOptions o;
    o.format = 3;
    o.points = 500;
    o.seed = seed;
    o.wide_colors = wide;
    return las_file_as(dir, name, o);
  };
  const std::string narrow = file("narrow.las", false, 1), wide = file("wide.las", true, 2);
  const std::string narrow2 = file("narrow2.las", false, 3);
  SECTION("one compress of both kinds") {
    const auto r = relief::test::run_cli(cli(), "compress " + narrow + " " + wide + " -o " + dir.file("m.relief") + " --quiet");
    REQUIRE(r.code == 0);
    CHECK_THAT(r.output, Contains(narrow + " stores 8-bit levels in its 16-bit colour fields, but " + wide +
                                  " has 16-bit levels: its levels come back from LAS and LAZ output scaled to 16 bits"));
    CHECK_FALSE(archive_info(dir.file("m.relief")).las_colors_8bit);
    // The sharded build's plan says the same.
    const auto plan = relief::test::run_cli(cli(), "shard-plan " + narrow + " " + wide + " -o " + dir.file("m.plan") + " --quiet");
    REQUIRE(plan.code == 0);
    CHECK_THAT(plan.output, Contains(narrow + " stores 8-bit levels in its 16-bit colour fields, but " + wide +
                                     " has 16-bit levels"));
  }
  SECTION("inputs of levels all 0 or of no point go unnamed") {
    TestLasOptions o;
    o.format = 3;
    o.points = 400;
    o.seed = 4;
    o.zero_colors = true;
    const std::string dark = las_file_as(dir, "dark.las", o);
    o.points = 0;
    const std::string empty = las_file_as(dir, "empty.las", o);
    const std::string m = dir.file("z.relief");
    const auto r = relief::test::run_cli(cli(), "compress " + dark + " " + empty + " " + wide + " " + narrow + " -o " + m + " --quiet");
    REQUIRE(r.code == 0);
    CHECK_THAT(r.output, Contains(narrow + " stores 8-bit levels"));
    CHECK(r.output.find(dark) == std::string::npos);
    CHECK(r.output.find(empty) == std::string::npos);
    CHECK_FALSE(archive_info(m).las_colors_8bit);
    const auto plan = relief::test::run_cli(cli(), "shard-plan " + dark + " " + empty + " " + wide + " -o " + dir.file("z.plan") + " --quiet");
    REQUIRE(plan.code == 0);
    INFO(plan.output);
    CHECK(plan.output.find("8-bit") == std::string::npos);
    // The colourless file's points come back as they were, levels 0.
    const std::string out = dir.file("z-out.las");
    REQUIRE(relief::test::run_cli(cli(), "decompress " + m + " -o " + out + " --quiet").code == 0);
    std::size_t zero = 0;
    for (const LasRecord& rec : sorted_records(out)) zero += rec.red == 0 && rec.green == 0 && rec.blue == 0 ? 1 : 0;
    CHECK(zero >= 400);
  }
  SECTION("8-bit levels, then a 16-bit scan appended: both kinds come back exactly") {
    const std::string a = dir.file("a.relief");
    const auto made = relief::test::run_cli(cli(), "compress " + narrow + " " + narrow2 + " -o " + a + " --quiet");
    REQUIRE(made.code == 0);
    CHECK(made.output.find("scaled") == std::string::npos);
    CHECK(archive_info(a).las_colors_8bit);
    CHECK_THAT(relief::test::run_cli(cli(), "info " + a).output, Contains("8-bit colour levels in 16-bit fields"));
    CHECK_THAT(relief::test::run_cli(cli(), "info --json " + a).output, Contains("\"color_levels\": 8,"));
    const auto r = relief::test::run_cli(cli(), "append " + a + " " + wide + " --quiet");
    REQUIRE(r.code == 0);
    CHECK(r.output.find("scaled") == std::string::npos);
    // The archive keeps its rule; the 16-bit levels are stored split.
    CHECK(archive_info(a).las_colors_8bit);
    const std::string out = dir.file("a-out.las");
    REQUIRE(relief::test::run_cli(cli(), "decompress " + a + " -o " + out + " --quiet").code == 0);
    std::vector<LasRecord> want = sorted_records(narrow);
    for (const std::string& f : {narrow2, wide}) {
      const std::vector<LasRecord> more = sorted_records(f);
      want.insert(want.end(), more.begin(), more.end());
    }
    std::sort(want.begin(), want.end());
    REQUIRE(relief::test::first_difference(sorted_records(out), want) == "");
  }
  SECTION("with a colour tolerance, a 16-bit scan appended turns the archive to 16-bit levels, with a warning") {
    const std::string a = dir.file("t.relief");
    REQUIRE(relief::test::run_cli(cli(), "compress " + narrow + " -o " + a + " --quiet --color-tolerance 2").code == 0);
    CHECK(archive_info(a).las_colors_8bit);
    const auto r = relief::test::run_cli(cli(), "append " + a + " " + wide + " --quiet");
    REQUIRE(r.code == 0);
    CHECK_THAT(r.output, Contains(wide + " has 16-bit colour levels: the archive's earlier points") &&
                             Contains("now come back from LAS and LAZ output scaled to 16 bits (level x 257)"));
    CHECK_FALSE(archive_info(a).las_colors_8bit);
    CHECK_THAT(relief::test::run_cli(cli(), "info " + a).output, Contains(", 16-bit colour levels"));
    CHECK_THAT(relief::test::run_cli(cli(), "info --json " + a).output, Contains("\"color_levels\": 16,"));
  }
  SECTION("16-bit levels, then an 8-bit scan appended") {
    const std::string a = dir.file("b.relief");
    REQUIRE(relief::test::run_cli(cli(), "compress " + wide + " -o " + a + " --quiet").code == 0);
    const auto r = relief::test::run_cli(cli(), "append " + a + " " + narrow + " --quiet");
    REQUIRE(r.code == 0);
    CHECK_THAT(r.output, Contains(narrow + " stores 8-bit levels in its 16-bit colour fields, but the archive holds "
                                  "16-bit levels"));
  }
}
