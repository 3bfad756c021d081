// What LAS sources say of themselves beyond their points, through the
// archive: the header's identity fields (file source ID, GUID, system
// identifier, creation date, synthetic-returns bit) and every VLR and
// extended VLR Relief does not write itself come back in LAS and LAZ output
// (format-spec/archive.md §2.3.1); damaged rows are refused by name.
#include <catch2/catch.hpp>
#include <sqlite3.h>

#include <algorithm>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "relief/archive.h"
#include "relief/ingest.h"
#include "relief/io.h"
#include "support/las_records.h"
#include "support/run_cli.h"
#include "support/temp_dir.h"

namespace {

using relief::LasVlr;
using relief::test::TempDir;
using relief::test::TestLasOptions;
using relief::test::TestVlr;

std::vector<std::uint8_t> bytes(std::size_t n, std::uint8_t seed) {
  std::vector<std::uint8_t> v(n);
  for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<std::uint8_t>(seed + i * 7);
  return v;
}

// The record a TestVlr becomes when kept.
LasVlr kept(const TestVlr& t, bool extended) {
  LasVlr r;
  r.extended = extended;
  std::memcpy(r.user_id.data(), t.user_id.data(), std::min<std::size_t>(t.user_id.size(), 16));
  r.record_id = t.record_id;
  std::memcpy(r.description.data(), t.description.data(), std::min<std::size_t>(t.description.size(), 32));
  r.data = t.data;
  return r;
}

// A file's kept header and records, as Relief's own reader sees them.
relief::PointStreamInfo info_of(const std::string& path) {
  auto reader = relief::open_point_reader(path);
  REQUIRE(reader.is_ok());
  return (*reader)->info();
}

std::uint16_t u16(const std::vector<std::uint8_t>& header, std::size_t at) {
  return static_cast<std::uint16_t>(header[at] | (header[at + 1] << 8));
}

std::string cli() { return RELIEF_CLI; }

// Survey tiles: vendor calibration records (one repeated within a file), a
// classification lookup, and records Relief writes itself or does not keep.
const TestVlr kCalibration{"SurveyVendor", 1, "boresight calibration", bytes(300, 1), false};
const TestVlr kLookup{"LASF_Spec", 0, "Classification", bytes(256 * 16, 2), false};
const TestVlr kWaveDescriptor{"LASF_Spec", 100, "waveform packet", bytes(26, 3), false};
const TestVlr kCopcInfo{"copc", 1, "COPC info", bytes(160, 4), false};
const TestVlr kLargeEvlr{"SurveyVendor", 9, "trajectory", bytes(70000, 5), true};
const TestVlr kSmallEvlr{"SurveyVendor", 10, "flight log", bytes(500, 6), true};
const TestVlr kLaxIndex{"LAStools", 30, "LAX spatial index", bytes(4000, 7), true};

TestLasOptions tile(int format, std::uint32_t seed, std::vector<TestVlr> vlrs) {
  TestLasOptions o;
  o.format = format;
  o.points = 3000;
  o.seed = seed;
  o.file_source_id = 17;
  o.system_identifier = "SurveyCo X1 #" + std::to_string(seed);
  o.creation_day = 200;
  o.creation_year = 2019;
  o.global_encoding = format >= 6 ? (1u << 3) : 0;  // synthetic return numbers (1.3+)
  o.vlrs = std::move(vlrs);
  return o;
}

}  // namespace

TEST_CASE("LAS headers and VLRs come back through the archive", "[las][archive][vlr]") {
  TempDir dir;
  const std::string a = dir.file("a.las");
  const std::string b = dir.file("b.las");
  REQUIRE(relief::test::write_test_las(a, tile(3, 1, {kCalibration, kCalibration, kLookup, kWaveDescriptor, kCopcInfo})));
  REQUIRE(relief::test::write_test_las(b, tile(6, 2, {kCalibration, kLargeEvlr, kSmallEvlr, kLaxIndex})));

  // The readers keep what LAS output could not rebuild, repeats included.
  const relief::PointStreamInfo ia = info_of(a);
  const std::vector<LasVlr> want_a{kept(kCalibration, false), kept(kCalibration, false), kept(kLookup, false)};
  const std::vector<LasVlr> want_b{kept(kCalibration, false), kept(kLargeEvlr, true), kept(kSmallEvlr, true)};
  CHECK(ia.las_metadata.records == want_a);
  CHECK(ia.las_metadata.header.size() == 227);
  CHECK(info_of(b).las_metadata.records == want_b);
  CHECK(info_of(b).las_metadata.header.size() == 375);

  const std::string archive = dir.file("x.relief");
  REQUIRE(relief::compress_files({a, b}, archive, {}).is_ok());
  {
    auto opened = relief::Archive::open(archive, relief::Archive::Mode::kReadOnly);
    REQUIRE(opened.is_ok());
    auto info = (*opened)->info();
    REQUIRE(info.is_ok());
    REQUIRE(info->sources.size() == 2);
    CHECK(info->sources[0].las == ia.las_metadata);
    CHECK(info->sources[1].las == info_of(b).las_metadata);
    const auto json = relief::test::run_cli(cli(), "info --json " + archive);
    REQUIRE(json.code == 0);
    CHECK(json.output.find("\"las_records\": 3}") != std::string::npos);
  }

  // LAS and LAZ output: each record once across sources (the calibration of
  // the second tile repeats the first's), the first tile's repeat kept; the
  // 70,000-byte record follows the points (LAS 1.4 here: format 6 source).
  const std::vector<LasVlr> want{kept(kCalibration, false), kept(kCalibration, false), kept(kLookup, false),
                                 kept(kLargeEvlr, true), kept(kSmallEvlr, true)};
  for (const char* ext : {".las", ".laz"}) {
    CAPTURE(ext);
    const std::string out = dir.file(std::string("out") + ext);
    const auto run = relief::test::run_cli(cli(), "decompress " + archive + " -o " + out + " --quiet");
    REQUIRE(run.code == 0);
    const relief::PointStreamInfo o = info_of(out);
    CHECK(o.las_metadata.records == want);
    const std::vector<std::uint8_t>& h = o.las_metadata.header;
    REQUIRE(h.size() == 375);
    CHECK(u16(h, 4) == 17);                                       // file source ID: both say 17
    CHECK(std::string(reinterpret_cast<const char*>(h.data() + 26)) == "Relief");  // they differ
    CHECK(u16(h, 90) == 200);                                     // creation day and year agree
    CHECK(u16(h, 92) == 2019);
    CHECK((u16(h, 6) & (1u << 3)) == 0);  // the 1.2 tile has no synthetic-returns bit
    // Relief's own records are not doubled: no waveform descriptor, COPC or
    // LAX record comes back.
    for (const LasVlr& r : o.las_metadata.records) CHECK(r.record_id != 100);
  }

  // One source: its system identifier and synthetic-returns bit come back too.
  const std::string single = dir.file("b.relief");
  REQUIRE(relief::compress_files({b}, single, {}).is_ok());
  const std::string out = dir.file("b_out.las");
  REQUIRE(relief::test::run_cli(cli(), "decompress " + single + " -o " + out + " --quiet").code == 0);
  const relief::PointStreamInfo o = info_of(out);
  CHECK(o.las_metadata.records == want_b);
  CHECK(std::string(reinterpret_cast<const char*>(o.las_metadata.header.data() + 26)) == "SurveyCo X1 #2");
  CHECK((u16(o.las_metadata.header, 6) & (1u << 3)) != 0);

  // A box query writes the same records.
  const std::string box = dir.file("box.las");
  REQUIRE(relief::test::run_cli(cli(), "query " + single + " --box 0,0,0,1,1,1 -o " + box + " --quiet").code == 0);
  CHECK(info_of(box).las_metadata.records == want_b);
}

TEST_CASE("LAS 1.2 output writes a small extended VLR as a VLR, a large one makes it 1.4", "[las][archive][vlr]") {
  TempDir dir;
  // Sources in LAS 1.4 with extended VLRs, written as a legacy format: LAS
  // 1.2 holds the small record as a VLR; the 70,000-byte one needs an
  // extended VLR, hence LAS 1.4 with the same legacy format.
  const std::string small = dir.file("small.las");
  const std::string large = dir.file("large.las");
  REQUIRE(relief::test::write_test_las(small, tile(6, 3, {kSmallEvlr})));
  REQUIRE(relief::test::write_test_las(large, tile(6, 4, {kLargeEvlr})));
  CHECK(info_of(small).las_metadata.records == std::vector<LasVlr>{kept(kSmallEvlr, true)});
  const auto write = [&](const std::string& source, const std::string& out) {
    relief::WriterOptions w;
    w.las_point_format = 1;
    w.las_version_minor = 2;
    w.las_sources.push_back(info_of(source).las_metadata);
    auto writer = relief::open_point_writer(out, w);
    REQUIRE(writer.is_ok());
    relief::PointCloud c;
    c.positions = {{1, 2, 3}, {4, 5, 6}};
    REQUIRE((*writer)->write(c).is_ok());
    REQUIRE((*writer)->finish().is_ok());
    return info_of(out);
  };
  relief::PointStreamInfo i = write(small, dir.file("small_out.las"));
  CHECK(i.las_version_minor == 2);
  CHECK(i.las_metadata.records == std::vector<LasVlr>{kept(kSmallEvlr, false)});
  i = write(large, dir.file("large_out.las"));
  CHECK(i.las_version_minor == 4);
  CHECK(i.las_point_format < 6);
  CHECK(i.las_metadata.records == std::vector<LasVlr>{kept(kLargeEvlr, true)});
}

TEST_CASE("a LAS record too large to keep is dropped with a warning", "[las][archive][vlr]") {
  TempDir dir;
  const TestVlr huge{"SurveyVendor", 11, "raw log", bytes(relief::kMaxKeptLasRecord + 1, 8), true};
  const std::string in = dir.file("in.las");
  REQUIRE(relief::test::write_test_las(in, tile(6, 5, {kCalibration, huge})));
  const relief::PointStreamInfo i = info_of(in);
  CHECK(i.las_metadata.records == std::vector<LasVlr>{kept(kCalibration, false)});
  REQUIRE(i.warnings.size() == 1);
  CHECK(i.warnings[0].find(in) != std::string::npos);
  CHECK(i.warnings[0].find("record 11") != std::string::npos);
  CHECK(i.warnings[0].find("not kept") != std::string::npos);
}

TEST_CASE("a second Extra Bytes record that differs, and a negative scale factor, are warned about",
          "[las][archive][vlr]") {
  TempDir dir;
  // Two Extra Bytes records: the first (one uint16 "a") describes the 2 extra
  // bytes; the second (one int16 "b") is ignored, no longer without a word.
  TestLasOptions o =
      tile(3, 9, {TestVlr{"LASF_Spec", 4, "second", relief::test::extra_bytes_descriptor(4, 0, "b"), false}});
  o.extra = 2;
  o.extra_bytes_vlr = relief::test::extra_bytes_descriptor(3, 0, "a");
  const std::string twice = dir.file("twice.las");
  REQUIRE(relief::test::write_test_las(twice, o));
  const relief::PointStreamInfo i = info_of(twice);
  CHECK(i.extra_bytes_vlr == std::string(o.extra_bytes_vlr.begin(), o.extra_bytes_vlr.end()));
  REQUIRE(i.warnings.size() == 1);
  CHECK(i.warnings[0].find(twice) != std::string::npos);
  CHECK(i.warnings[0].find("second Extra Bytes record that differs") != std::string::npos);
  // The same record twice is no conflict.
  TestLasOptions same = o;
  same.vlrs = {TestVlr{"LASF_Spec", 4, "again", o.extra_bytes_vlr, false}};
  const std::string again = dir.file("again.las");
  REQUIRE(relief::test::write_test_las(again, same));
  CHECK(info_of(again).warnings.empty());

  // A negative x scale: the coordinates are kept (and come back), the
  // integers of LAS output are negated; say so.
  const std::string negative = dir.file("negative.las");
  REQUIRE(relief::test::write_test_las(negative, tile(1, 3, {})));
  {
    std::fstream f(negative, std::ios::in | std::ios::out | std::ios::binary);
    const double minus = -0.01;
    f.seekp(131);
    f.write(reinterpret_cast<const char*>(&minus), sizeof minus);
  }
  const auto run = relief::test::run_cli(cli(), "compress " + negative + " -o " + dir.file("n.relief"));
  CHECK(run.code == 0);
  CHECK(run.output.find(negative + ": the x scale factor is negative (-0.01)") != std::string::npos);
  CHECK(run.output.find("integers come back negated") != std::string::npos);
}

TEST_CASE("an aborted scan leaves no LAS records, damaged rows are refused by name", "[las][archive][vlr]") {
  TempDir dir;
  const std::string in = dir.file("in.las");
  REQUIRE(relief::test::write_test_las(in, tile(3, 6, {kCalibration})));
  const std::string archive = dir.file("x.relief");
  REQUIRE(relief::compress_files({in}, archive, {}).is_ok());
  const auto count_rows = [&]() {
    sqlite3* db = nullptr;
    REQUIRE(sqlite3_open_v2(archive.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK);
    sqlite3_stmt* st = nullptr;
    REQUIRE(sqlite3_prepare_v2(db, "SELECT COUNT(*) FROM relief_source_las", -1, &st, nullptr) == SQLITE_OK);
    REQUIRE(sqlite3_step(st) == SQLITE_ROW);
    const auto n = sqlite3_column_int64(st, 0);
    sqlite3_finalize(st);
    sqlite3_close(db);
    return n;
  };
  CHECK(count_rows() == 2);  // the header block and the record
  {
    auto opened = relief::Archive::open(archive, relief::Archive::Mode::kReadWrite);
    REQUIRE(opened.is_ok());
    relief::ArchiveSource s;
    s.path = in;
    s.format = "las";
    s.las = info_of(in).las_metadata;
    auto scan = (*opened)->begin_scan({s}, relief::ScanAttributes{});
    REQUIRE(scan.is_ok());
    CHECK(count_rows() == 4);
    REQUIRE((*opened)->abort_scan(*scan).is_ok());
    // A malformed header block or record is refused before anything is written.
    relief::ArchiveSource bad = s;
    bad.las.header.resize(100);
    auto refused = (*opened)->begin_scan({bad}, relief::ScanAttributes{});
    REQUIRE_FALSE(refused.is_ok());
    CHECK(refused.status().code() == relief::StatusCode::kInvalidArgument);
    CHECK(refused.status().message().find("227, 235 or 375 bytes") != std::string::npos);
    bad = s;
    bad.las.records[0].data.resize(70000);  // a VLR holds at most 65,535 bytes
    CHECK_FALSE((*opened)->begin_scan({bad}, relief::ScanAttributes{}).is_ok());
    REQUIRE((*opened)->close().is_ok());
  }
  CHECK(count_rows() == 2);

  const char* damage[] = {
      "UPDATE relief_source_las SET user_id = x'00' WHERE kind = 1",        // a 1-byte user id
      "UPDATE relief_source_las SET data = x'4c415346' WHERE kind = 0",     // a 4-byte header
      "UPDATE relief_source_las SET source_id = 99 WHERE kind = 1",         // no such source
      "UPDATE relief_source_las SET kind = 0 WHERE kind = 1",               // a second header
  };
  for (const char* sql : damage) {
    CAPTURE(sql);
    const std::string copy = dir.file("damaged.relief");
    std::filesystem::copy_file(archive, copy, std::filesystem::copy_options::overwrite_existing);
    sqlite3* db = nullptr;
    REQUIRE(sqlite3_open_v2(copy.c_str(), &db, SQLITE_OPEN_READWRITE, nullptr) == SQLITE_OK);
    REQUIRE(sqlite3_exec(db, "PRAGMA ignore_check_constraints = 1", nullptr, nullptr, nullptr) == SQLITE_OK);
    REQUIRE(sqlite3_exec(db, sql, nullptr, nullptr, nullptr) == SQLITE_OK);
    sqlite3_close(db);
    auto opened = relief::Archive::open(copy, relief::Archive::Mode::kReadOnly);
    REQUIRE(opened.is_ok());
    auto info = (*opened)->info();
    REQUIRE_FALSE(info.is_ok());
    CHECK(info.status().message().find(copy) != std::string::npos);
    CHECK(info.status().message().find("relief_source_las row") != std::string::npos);
    const auto run = relief::test::run_cli(cli(), "check " + copy);
    CHECK(run.code != 0);
  }
}
