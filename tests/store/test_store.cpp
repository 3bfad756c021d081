// Tests of the SQLite archive (lib/store, format-spec/archive.md). Raw SQLite
// is used on purpose to fake, damage and inspect archives behind the store's back.
#include <signal.h>
#include <sqlite3.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>
#include <memory>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include <catch2/catch.hpp>

#include "relief/archive.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"

namespace relief {
using relief::test::TempDir;

namespace {

namespace fs = std::filesystem;

constexpr double kInf = std::numeric_limits<double>::infinity();

// A fresh directory per test case, removed afterwards.

// ---- Raw SQLite access, bypassing the store.

class RawDb {
 public:
  explicit RawDb(const std::string& file) {
    const int rc = sqlite3_open_v2(file.c_str(), &db_, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr);
    REQUIRE(rc == SQLITE_OK);
    sqlite3_busy_timeout(db_, 5000);
  }
  ~RawDb() { sqlite3_close(db_); }
  RawDb(const RawDb&) = delete;
  RawDb& operator=(const RawDb&) = delete;

  void exec(const std::string& sql) {
    char* error = nullptr;
    const int rc = sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &error);
    const std::string message = error != nullptr ? error : "";
    sqlite3_free(error);
    INFO(sql << ": " << message);
    REQUIRE(rc == SQLITE_OK);
  }

  std::int64_t integer(const std::string& sql) {
    sqlite3_stmt* stmt = nullptr;
    REQUIRE(sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr) == SQLITE_OK);
    REQUIRE(sqlite3_step(stmt) == SQLITE_ROW);
    const std::int64_t value = sqlite3_column_int64(stmt, 0);
    sqlite3_finalize(stmt);
    return value;
  }

  double real(const std::string& sql) {
    sqlite3_stmt* stmt = nullptr;
    REQUIRE(sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr) == SQLITE_OK);
    REQUIRE(sqlite3_step(stmt) == SQLITE_ROW);
    const double value = sqlite3_column_double(stmt, 0);
    sqlite3_finalize(stmt);
    return value;
  }

  std::string text(const std::string& sql) {
    sqlite3_stmt* stmt = nullptr;
    REQUIRE(sqlite3_prepare_v2(db_, sql.c_str(), -1, &stmt, nullptr) == SQLITE_OK);
    REQUIRE(sqlite3_step(stmt) == SQLITE_ROW);
    const unsigned char* text = sqlite3_column_text(stmt, 0);
    const std::string value = text != nullptr ? reinterpret_cast<const char*>(text) : "";
    sqlite3_finalize(stmt);
    return value;
  }

  std::vector<std::uint8_t> blob(std::int64_t chunk_id) {
    sqlite3_stmt* stmt = nullptr;
    REQUIRE(sqlite3_prepare_v2(db_, "SELECT blob FROM relief_chunk WHERE id = ?1", -1, &stmt, nullptr) ==
            SQLITE_OK);
    sqlite3_bind_int64(stmt, 1, chunk_id);
    REQUIRE(sqlite3_step(stmt) == SQLITE_ROW);
    const auto* data = static_cast<const std::uint8_t*>(sqlite3_column_blob(stmt, 0));
    const int size = sqlite3_column_bytes(stmt, 0);
    std::vector<std::uint8_t> bytes(data, data + size);
    sqlite3_finalize(stmt);
    return bytes;
  }

  void set_blob(std::int64_t chunk_id, const std::vector<std::uint8_t>& bytes) {
    sqlite3_stmt* stmt = nullptr;
    REQUIRE(sqlite3_prepare_v2(db_, "UPDATE relief_chunk SET blob = ?2 WHERE id = ?1", -1, &stmt, nullptr) ==
            SQLITE_OK);
    sqlite3_bind_int64(stmt, 1, chunk_id);
    sqlite3_bind_blob(stmt, 2, bytes.data(), static_cast<int>(bytes.size()), SQLITE_TRANSIENT);
    REQUIRE(sqlite3_step(stmt) == SQLITE_DONE);
    sqlite3_finalize(stmt);
  }

 private:
  sqlite3* db_ = nullptr;
};

std::vector<std::uint8_t> file_bytes(const std::string& file) {
  std::ifstream in(file, std::ios::binary);
  return std::vector<std::uint8_t>(std::istreambuf_iterator<char>(in), {});
}

using relief::test::write_file;

// ---- Archive helpers

ArchiveGrid grid_25m() {
  ArchiveGrid grid;
  grid.origin = {0, 0, 0};
  grid.chunk_edge = 25;
  return grid;
}

std::unique_ptr<Archive> create_ok(const std::string& file, const ArchiveGrid& grid = grid_25m()) {
  Result<std::unique_ptr<Archive>> archive =
      Archive::create(file, grid, "grid=voxel;cell=0.5", "relief-test 0.1");
  INFO(archive.status().to_string());
  REQUIRE(archive.is_ok());
  return std::move(archive).value();
}

std::unique_ptr<Archive> open_ok(const std::string& file, Archive::Mode mode) {
  Result<std::unique_ptr<Archive>> archive = Archive::open(file, mode);
  INFO(archive.status().to_string());
  REQUIRE(archive.is_ok());
  return std::move(archive).value();
}

ArchiveInfo info_ok(const Archive& archive) {
  Result<ArchiveInfo> info = archive.info();
  INFO(info.status().to_string());
  REQUIRE(info.is_ok());
  return std::move(info).value();
}

std::int64_t begin_ok(Archive& archive, const std::vector<ArchiveSource>& sources = {}) {
  Result<std::int64_t> scan = archive.begin_scan(sources);
  INFO(scan.status().to_string());
  REQUIRE(scan.is_ok());
  return *scan;
}

void put_ok(Archive& archive, std::vector<ChunkRow>& rows) {
  const Status status = archive.put_chunks(rows);
  INFO(status.to_string());
  REQUIRE(status.is_ok());
}

std::vector<ChunkRef> find_ok(const Archive& archive, const Box3d& box) {
  Result<std::vector<ChunkRef>> refs = archive.find_chunks(box);
  INFO(refs.status().to_string());
  REQUIRE(refs.is_ok());
  return std::move(refs).value();
}

std::vector<ChunkRef> all_ok(const Archive& archive) {
  Result<std::vector<ChunkRef>> refs = archive.all_chunks();
  INFO(refs.status().to_string());
  REQUIRE(refs.is_ok());
  return std::move(refs).value();
}

ChunkRow read_ok(const Archive& archive, std::int64_t id) {
  Result<ChunkRow> row = archive.read_chunk(id);
  INFO(row.status().to_string());
  REQUIRE(row.is_ok());
  return std::move(row).value();
}

std::vector<std::uint8_t> random_blob(std::size_t size, std::uint64_t seed) {
  test::Rng rng(seed);
  std::vector<std::uint8_t> blob(size);
  for (std::uint8_t& byte : blob) byte = static_cast<std::uint8_t>(rng.next() >> 56);
  return blob;
}

Box3d box_of(Vec3d min, Vec3d max) {
  Box3d box;
  box.min = min;
  box.max = max;
  return box;
}

Box3d cube(double min, double max) { return box_of({min, min, min}, {max, max, max}); }

ChunkRow make_row(ChunkKey key, std::int64_t scan_id, const Box3d& bounds, std::uint64_t points,
                  std::size_t blob_size, std::uint64_t seed) {
  ChunkRow row;
  row.ref.key = key;
  row.ref.scan_id = scan_id;
  row.ref.bounds = bounds;
  row.ref.input_points = points + 7;
  row.ref.decoded_points = bounds.empty() ? 0 : points;
  row.codec = 1;
  row.codec_params = "seed=" + std::to_string(seed);
  row.blob = random_blob(blob_size, seed);
  return row;
}

std::vector<std::int64_t> ids_of(const std::vector<ChunkRef>& refs) {
  std::vector<std::int64_t> ids;
  for (const ChunkRef& ref : refs) ids.push_back(ref.id);
  return ids;
}

bool starts_with(const std::string& text, const std::string& prefix) { return text.rfind(prefix, 0) == 0; }

// The CRS copies versions 1 and 2 keep in relief_meta, from the scans as
// version 3 reads them, in place of crs_crc32.
const char kCrsCopiesSql[] =
    "DELETE FROM relief_meta WHERE key = 'crs_crc32'; "
    "INSERT INTO relief_meta(key, value) VALUES('crs', COALESCE((SELECT crs FROM relief_scan WHERE crs <> '' "
    "ORDER BY id LIMIT 1), '')); "
    "INSERT INTO relief_meta(key, value) VALUES('crs_source', COALESCE((SELECT crs FROM relief_source WHERE crs "
    "<> '' AND scan_id = (SELECT id FROM relief_scan WHERE crs <> '' ORDER BY id LIMIT 1) ORDER BY id LIMIT 1), "
    "'')); ";

// Turns an archive into what format version 1 wrote: version 2 added the
// bounds index and the metadata checksum, version 3 replaced the CRS copies
// with their checksum (format-spec/archive.md, version log).
void downgrade_to_v1(const std::string& path) {
  RawDb raw(path);
  raw.exec(std::string(kCrsCopiesSql) +
           "DROP INDEX relief_chunk_bounds; DELETE FROM relief_meta WHERE key = 'meta_crc32'; "
           "UPDATE relief_meta SET value = '1' WHERE key = 'format_version'; PRAGMA user_version = 1");
}

// ---- Grid

TEST_CASE("ArchiveGrid keys follow floor((p - origin) / edge)", "[store]") {
  const ArchiveGrid grid = grid_25m();
  // The worked example of format-spec/archive.md.
  CHECK(grid.key_of({484649.36, 6632629.73, 99.65}) == ChunkKey{19385, 265305, 3});
  const Box3d box = grid.chunk_box({19385, 265305, 3});
  CHECK(box.min == Vec3d{484625, 6632625, 75});
  CHECK(box.max == Vec3d{484650, 6632650, 100});

  // floor, not truncation toward zero; faces belong to the upper chunk.
  CHECK(grid.key_of({-0.5, -25, -25.000001}) == ChunkKey{-1, -1, -2});
  CHECK(grid.key_of({25, 0, 49.999999}) == ChunkKey{1, 0, 1});

  ArchiveGrid shifted;
  shifted.origin = {100, 200, -10};
  shifted.chunk_edge = 2.5;
  CHECK(shifted.key_of({100, 202.5, -10.1}) == ChunkKey{0, 1, -1});
  CHECK(shifted.chunk_box({0, 1, -1}).min == Vec3d{100, 202.5, -12.5});

  SECTION("keys beyond int64 saturate instead of overflowing") {
    ArchiveGrid tiny;
    tiny.chunk_edge = 1e-300;
    const std::int64_t max = std::numeric_limits<std::int64_t>::max();
    const std::int64_t min = std::numeric_limits<std::int64_t>::min();
    CHECK(tiny.key_of({1e300, -1e300, 0}) == ChunkKey{max, min, 0});
    CHECK(tiny.key_of({std::nan(""), 0, 0}).ix == 0);
    CHECK(tiny.chunk_box({max, 0, 0}).max.x > 0);  // i + 1 computed without overflow
  }
}

// ---- Create and open

TEST_CASE("create then open round-trips the metadata", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  ArchiveGrid grid;
  grid.origin = {0.1, 1e7 + 0.3, -123.456};  // not representable as short decimals in binary
  grid.chunk_edge = 0.7;
  {
    auto archive = create_ok(path, grid);
    CHECK(archive->path() == path);
    const ArchiveInfo info = info_ok(*archive);
    CHECK(info.format_version == 3);
    CHECK(info.grid.origin == grid.origin);
    CHECK(info.grid.chunk_edge == grid.chunk_edge);
    CHECK(info.codec_params == "grid=voxel;cell=0.5");
    CHECK(info.creator == "relief-test 0.1");
    CHECK(info.crs.empty());
    CHECK_FALSE(info.has_colors);
    CHECK_FALSE(info.has_intensity);
    CHECK(info.chunk_count == 0);
    CHECK(info.input_points == 0);
    CHECK(info.blob_bytes == 0);
    CHECK(info.bounds.empty());
    CHECK(info.file_bytes >= fs::file_size(path));
    CHECK(info.sources.empty());
    CHECK(info.scans.empty());
  }
  // No temporary file, journal or WAL left once the handle is closed.
  CHECK(dir.entries() == std::vector<std::string>{"a.relief"});

  {
    RawDb raw(path);
    CHECK(raw.integer("PRAGMA application_id") == 0x524C4946);
    CHECK(raw.integer("PRAGMA user_version") == 3);
    CHECK(raw.text("PRAGMA journal_mode") == "delete");
    CHECK(raw.text("SELECT value FROM relief_meta WHERE key = 'grid_origin_y'") == "10000000.3");
    CHECK(raw.text("SELECT value FROM relief_meta WHERE key = 'chunk_edge'") == "0.7");
    CHECK(raw.text("SELECT value FROM relief_meta WHERE key = 'format_version'") == "3");
    // Version 3 keeps no copy of the CRS texts, only their checksum (of two empty texts here).
    CHECK(raw.integer("SELECT COUNT(*) FROM relief_meta WHERE key IN ('crs', 'crs_source')") == 0);
    CHECK(raw.text("SELECT value FROM relief_meta WHERE key = 'crs_crc32'").size() == 8);
    const std::string created = raw.text("SELECT value FROM relief_meta WHERE key = 'created_at'");
    CHECK(created.size() == 20);
    CHECK(created.back() == 'Z');
  }

  for (const Archive::Mode mode : {Archive::Mode::kReadOnly, Archive::Mode::kReadWrite}) {
    auto archive = open_ok(path, mode);
    const ArchiveInfo info = info_ok(*archive);
    CHECK(info.grid.origin == grid.origin);
    CHECK(info.grid.chunk_edge == grid.chunk_edge);
    CHECK(info.creator == "relief-test 0.1");
  }
}

TEST_CASE("create refuses existing paths and bad places and leaves nothing behind", "[store]") {
  TempDir dir;

  SECTION("existing file") {
    const std::string path = dir.file("taken.relief");
    write_file(path, "precious");
    Result<std::unique_ptr<Archive>> archive = Archive::create(path, grid_25m(), "", "");
    REQUIRE_FALSE(archive.is_ok());
    CHECK(archive.status().code() == StatusCode::kIoError);
    CHECK(starts_with(archive.status().message(), path + ": "));
    CHECK_THAT(archive.status().message(), Catch::Contains("already exists"));
    CHECK(file_bytes(path) == std::vector<std::uint8_t>{'p', 'r', 'e', 'c', 'i', 'o', 'u', 's'});
    CHECK(dir.entries() == std::vector<std::string>{"taken.relief"});
  }

  SECTION("existing archive") {
    const std::string path = dir.file("a.relief");
    create_ok(path);
    Result<std::unique_ptr<Archive>> again = Archive::create(path, grid_25m(), "", "");
    CHECK(again.status().code() == StatusCode::kIoError);
    CHECK(dir.entries() == std::vector<std::string>{"a.relief"});
  }

  SECTION("directory that does not exist") {
    const std::string path = dir.file("missing/a.relief");
    Result<std::unique_ptr<Archive>> archive = Archive::create(path, grid_25m(), "", "");
    REQUIRE_FALSE(archive.is_ok());
    CHECK(archive.status().code() == StatusCode::kIoError);
    CHECK(starts_with(archive.status().message(), path + ": "));
    CHECK(dir.entries().empty());
  }

  SECTION("parent is a regular file") {
    write_file(dir.file("plain"), "x");
    const std::string path = dir.file("plain/a.relief");
    Result<std::unique_ptr<Archive>> archive = Archive::create(path, grid_25m(), "", "");
    CHECK(archive.status().code() == StatusCode::kIoError);
    CHECK(starts_with(archive.status().message(), path + ": "));
    CHECK(dir.entries() == std::vector<std::string>{"plain"});
  }

  SECTION("directory without write permission") {
    if (::geteuid() == 0) {
      WARN("running as root: permissions do not stop root, skipped");
      return;
    }
    const fs::path locked = dir.path() / "locked";
    fs::create_directories(locked);
    fs::permissions(locked, fs::perms::owner_read | fs::perms::owner_exec);
    const std::string path = (locked / "a.relief").string();
    Result<std::unique_ptr<Archive>> archive = Archive::create(path, grid_25m(), "", "");
    CHECK(archive.status().code() == StatusCode::kIoError);
    CHECK(starts_with(archive.status().message(), path + ": "));
    // Said plainly, not as SQLite's "unable to open database file (No such file or directory)".
    CHECK_THAT(archive.status().message(), Catch::Contains("is not writable (Permission denied)"));
    fs::permissions(locked, fs::perms::owner_all);
    CHECK(fs::is_empty(locked));
  }

  SECTION("an empty path") {
    const Result<std::unique_ptr<Archive>> archive = Archive::create("", grid_25m(), "", "");
    CHECK(archive.status().code() == StatusCode::kInvalidArgument);
    CHECK(archive.status().message() == "the archive path is empty");
  }

  SECTION("invalid grid") {
    const std::string path = dir.file("a.relief");
    ArchiveGrid grid = grid_25m();
    grid.chunk_edge = 0;
    CHECK(Archive::create(path, grid, "", "").status().code() == StatusCode::kInvalidArgument);
    grid.chunk_edge = std::nan("");
    CHECK(Archive::create(path, grid, "", "").status().code() == StatusCode::kInvalidArgument);
    grid = grid_25m();
    grid.origin.y = kInf;
    CHECK(Archive::create(path, grid, "", "").status().code() == StatusCode::kInvalidArgument);
    CHECK(dir.entries().empty());
  }
}

TEST_CASE("open rejects what is not an archive of a known version", "[store]") {
  TempDir dir;
  const std::string path = dir.file("x.relief");
  const auto open_status = [&](Archive::Mode mode) { return Archive::open(path, mode).status(); };

  SECTION("missing file") {
    const Status status = open_status(Archive::Mode::kReadOnly);
    CHECK(status.code() == StatusCode::kIoError);
    CHECK(starts_with(status.message(), path + ": "));
    CHECK(dir.entries().empty());
  }

  SECTION("a directory") {
    fs::create_directories(path);
    CHECK(open_status(Archive::Mode::kReadOnly).code() == StatusCode::kIoError);
  }

  SECTION("not a SQLite file") {
    const std::string text(2000, 'x');
    write_file(path, text);
    for (const Archive::Mode mode : {Archive::Mode::kReadOnly, Archive::Mode::kReadWrite}) {
      const Status status = open_status(mode);
      CHECK(status.code() == StatusCode::kFormatError);
      CHECK(starts_with(status.message(), path + ": not a Relief archive"));
    }
    CHECK(file_bytes(path) == std::vector<std::uint8_t>(text.begin(), text.end()));
    CHECK(dir.entries() == std::vector<std::string>{"x.relief"});
  }

  SECTION("empty file") {
    write_file(path, "");
    const Status status = open_status(Archive::Mode::kReadWrite);
    CHECK(status.code() == StatusCode::kFormatError);
    CHECK(starts_with(status.message(), path + ": not a Relief archive"));
    CHECK(fs::file_size(path) == 0);
  }

  SECTION("a SQLite database of another application") {
    {
      RawDb raw(path);
      raw.exec("PRAGMA application_id = 1196444487; CREATE TABLE t(x); INSERT INTO t VALUES(1)");
    }
    const std::vector<std::uint8_t> before = file_bytes(path);
    for (const Archive::Mode mode : {Archive::Mode::kReadOnly, Archive::Mode::kReadWrite}) {
      const Status status = open_status(mode);
      CHECK(status.code() == StatusCode::kFormatError);
      CHECK(starts_with(status.message(), path + ": not a Relief archive"));
      CHECK_THAT(status.message(), Catch::Contains("0x47504B47"));
    }
    // Identification reads only: the foreign file is untouched (no WAL switch).
    CHECK(file_bytes(path) == before);
  }

  SECTION("a newer format version") {
    create_ok(path);
    RawDb(path).exec("PRAGMA user_version = 4");
    for (const Archive::Mode mode : {Archive::Mode::kReadOnly, Archive::Mode::kReadWrite}) {
      const Status status = open_status(mode);
      CHECK(status.code() == StatusCode::kUnsupported);
      CHECK(status.message() == path + ": archive format version 4 is newer than this build supports (3)");
    }
  }

  SECTION("format version 0") {
    create_ok(path);
    RawDb(path).exec("PRAGMA user_version = 0");
    const Status status = open_status(Archive::Mode::kReadOnly);
    CHECK(status.code() == StatusCode::kFormatError);
    CHECK(starts_with(status.message(), path + ": "));
  }

  SECTION("a missing table") {
    create_ok(path);
    RawDb(path).exec("DROP TABLE relief_source");
    const Status status = open_status(Archive::Mode::kReadOnly);
    CHECK(status.code() == StatusCode::kFormatError);
    CHECK_THAT(status.message(), Catch::Contains("relief_source"));
  }

  SECTION("damaged grid metadata fails the metadata checksum") {
    create_ok(path);
    RawDb(path).exec("UPDATE relief_meta SET value = 'wide' WHERE key = 'chunk_edge'");
    const Status status = open_status(Archive::Mode::kReadOnly);
    CHECK(status.code() == StatusCode::kCorruptData);
    CHECK(starts_with(status.message(), path + ": metadata checksum mismatch"));
  }

  SECTION("damaged grid metadata of a version-1 archive (no checksum)") {
    create_ok(path);
    downgrade_to_v1(path);
    RawDb(path).exec("UPDATE relief_meta SET value = 'wide' WHERE key = 'chunk_edge'");
    const Status status = open_status(Archive::Mode::kReadOnly);
    CHECK(status.code() == StatusCode::kFormatError);
    CHECK_THAT(status.message(), Catch::Contains("chunk_edge"));
  }
}

// ---- Writing and reading chunks

TEST_CASE("put_chunks assigns ids and per-voxel seqs, read_chunk returns the bytes", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto archive = create_ok(path);
  const std::int64_t scan = begin_ok(*archive, {{"a.ply", "ply", 100, "", 0}});

  std::vector<ChunkRow> first = {
      make_row({0, 0, 0}, scan, cube(1, 2), 40, 300, 1), make_row({1, 0, 0}, scan, cube(26, 27), 50, 1000, 2),
      make_row({0, 0, 0}, scan, cube(3, 4), 60, 5000, 3),  // same voxel in one call
  };
  put_ok(*archive, first);
  CHECK(first[0].ref.seq == 0);
  CHECK(first[1].ref.seq == 0);
  CHECK(first[2].ref.seq == 1);
  CHECK(first[0].ref.id > 0);
  CHECK(first[1].ref.id > first[0].ref.id);
  CHECK(first[2].ref.id > first[1].ref.id);

  const std::int64_t min = std::numeric_limits<std::int64_t>::min();
  std::vector<ChunkRow> second = {
      make_row({0, 0, 0}, scan, cube(5, 6), 70, 64, 4),  // an appended scan's blob
      make_row({5, -3, min}, scan, cube(-1, 0), 1, 100000, 5),
  };
  put_ok(*archive, second);
  CHECK(second[0].ref.seq == 2);
  CHECK(second[1].ref.seq == 0);

  // all_chunks lists them in content order (scan, level, key, bounds ...),
  // not in the order they were put: the three blobs of voxel (0, 0, 0) by
  // their bounds, then (1, 0, 0), then (5, -3, min).
  const std::vector<ChunkRow> expected = {first[0], first[2], second[0], first[1], second[1]};

  const std::vector<ChunkRef> refs = all_ok(*archive);
  REQUIRE(refs.size() == expected.size());
  std::uint64_t bytes = 0;
  for (std::size_t i = 0; i < refs.size(); ++i) {
    const ChunkRow& want = expected[i];
    CHECK(refs[i].id == want.ref.id);
    CHECK(refs[i].key == want.ref.key);
    CHECK(refs[i].seq == want.ref.seq);
    CHECK(refs[i].scan_id == scan);
    CHECK(refs[i].bounds.min == want.ref.bounds.min);
    CHECK(refs[i].bounds.max == want.ref.bounds.max);
    CHECK(refs[i].input_points == want.ref.input_points);
    CHECK(refs[i].decoded_points == want.ref.decoded_points);
    CHECK(refs[i].blob_size == want.blob.size());

    const ChunkRow row = read_ok(*archive, want.ref.id);
    CHECK(row.blob == want.blob);
    CHECK(row.codec == want.codec);
    CHECK(row.codec_params == want.codec_params);
    CHECK(row.ref.key == want.ref.key);
    CHECK(row.ref.seq == want.ref.seq);
    bytes += want.blob.size();
  }
  CHECK(archive->blob_bytes_read() == bytes);

  // Still there for a fresh reader.
  auto reader = open_ok(path, Archive::Mode::kReadOnly);
  CHECK(ids_of(all_ok(*reader)) == ids_of(refs));
  CHECK(read_ok(*reader, second[1].ref.id).blob == second[1].blob);

  SECTION("unknown id") {
    const Result<ChunkRow> missing = archive->read_chunk(9999);
    CHECK(missing.status().code() == StatusCode::kInvalidArgument);
    CHECK(starts_with(missing.status().message(), path + ": "));
  }
}

TEST_CASE("a chunk without decoded points has no extent but is stored", "[store]") {
  TempDir dir;
  auto archive = create_ok(dir.file("a.relief"));
  const std::int64_t scan = begin_ok(*archive);
  std::vector<ChunkRow> rows = {make_row({0, 0, 0}, scan, Box3d{}, 0, 0, 1)};
  put_ok(*archive, rows);
  const ChunkRow row = read_ok(*archive, rows[0].ref.id);
  CHECK(row.blob.empty());
  CHECK(row.ref.bounds.empty());
  CHECK(find_ok(*archive, cube(-1e300, 1e300)).empty());
  CHECK(all_ok(*archive).size() == 1);
  CHECK(info_ok(*archive).bounds.empty());
}

TEST_CASE("find_chunks filters by the exact double bounds", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto archive = create_ok(path);
  const std::int64_t scan = begin_ok(*archive);

  const double big = 1e7;
  std::vector<ChunkRow> rows = {
      make_row({0, 0, 0}, scan, cube(0.1, 0.2), 10, 10, 1),                             // A
      make_row({400000, 400000, 400000}, scan, cube(big + 0.3, big + 0.7), 10, 10, 2),  // B
      make_row({-1, -1, -1}, scan, cube(-5, -1), 10, 10, 3),                            // C
      make_row({0, 0, 0}, scan, box_of({0.1, 0.1, 0.3}, {0.2, 0.2, 0.4}), 10, 10, 4),   // D above A
  };
  put_ok(*archive, rows);
  const std::int64_t a = rows[0].ref.id;
  const std::int64_t b = rows[1].ref.id;
  const std::int64_t c = rows[2].ref.id;
  const std::int64_t d = rows[3].ref.id;

  // The R*Tree keeps float bounds rounded outward, so on its own it would
  // answer "maybe" to every box just outside A and B below.
  {
    RawDb raw(path);
    const std::string where = " FROM relief_chunk_index WHERE id = " + std::to_string(b);
    CHECK(raw.real("SELECT min_x" + where) < big + 0.3);
    CHECK(raw.real("SELECT max_x" + where) > big + 0.7);
  }

  const auto up = [](double v) { return std::nextafter(v, kInf); };
  const auto down = [](double v) { return std::nextafter(v, -kInf); };
  using Ids = std::vector<std::int64_t>;

  // Inside, containing, crossing. In content order: C's key (-1, -1, -1)
  // first, then A and D (key 0, 0, 0: A's bounds start lower), then B.
  CHECK(ids_of(find_ok(*archive, cube(0.15, 0.16))) == Ids{a});
  CHECK(ids_of(find_ok(*archive, cube(big + 0.4, big + 0.5))) == Ids{b});
  CHECK(ids_of(find_ok(*archive, cube(-10, 10))) == Ids{c, a, d});
  CHECK(ids_of(find_ok(*archive, cube(-1e300, 1e300))) == Ids{c, a, d, b});
  CHECK(ids_of(find_ok(*archive, cube(-kInf, kInf))) == Ids{c, a, d, b});
  CHECK(ids_of(find_ok(*archive, box_of({0.15, 0.15, 0}, {0.16, 0.16, 0.35}))) == Ids{a, d});

  // Touching is intersecting (closed boxes); one ulp away is not.
  CHECK(ids_of(find_ok(*archive, cube(0.2, 0.25))) == Ids{a});
  CHECK(find_ok(*archive, box_of({up(0.2), 0, 0}, {1, 1, 1})).empty());
  CHECK(ids_of(find_ok(*archive, box_of({-0.5, -0.5, -0.5}, {0.1, 0.1, 0.1}))) == Ids{a});
  CHECK(find_ok(*archive, box_of({-0.5, -0.5, -0.5}, {down(0.1), 1, 1})).empty());
  CHECK(ids_of(find_ok(*archive, cube(big + 0.7, big + 0.9))) == Ids{b});
  CHECK(find_ok(*archive, cube(big + 0.8, big + 0.9)).empty());
  CHECK(find_ok(*archive, cube(up(big + 0.7), big + 0.9)).empty());
  CHECK(ids_of(find_ok(*archive, cube(big - 5, big + 0.3))) == Ids{b});
  CHECK(find_ok(*archive, cube(big - 5, down(big + 0.3))).empty());
  CHECK(find_ok(*archive, cube(big - 5, big + 0.1)).empty());

  // Overlapping on two axes only.
  CHECK(find_ok(*archive, box_of({0.15, 0.15, 0.25}, {0.16, 0.16, 0.29})).empty());
  CHECK(find_ok(*archive, box_of({-3, 0.15, 0.15}, {-2, 0.16, 0.16})).empty());

  // Empty and NaN query boxes.
  CHECK(find_ok(*archive, Box3d{}).empty());
  const Result<std::vector<ChunkRef>> nan = archive->find_chunks(cube(std::nan(""), 1));
  CHECK(nan.status().code() == StatusCode::kInvalidArgument);

  // Several blobs of one voxel are all returned.
  const std::vector<ChunkRef> voxel = find_ok(*archive, cube(0.1, 0.4));
  REQUIRE(voxel.size() == 2);
  CHECK(voxel[0].seq == 0);
  CHECK(voxel[1].seq == 1);
}

TEST_CASE("read_chunk reports a damaged blob as corrupt data naming chunk and file", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto archive = create_ok(path);
  const std::int64_t scan = begin_ok(*archive);
  std::vector<ChunkRow> rows = {make_row({1, 2, 3}, scan, cube(30, 40), 5, 2000, 1),
                                make_row({1, 2, 4}, scan, cube(30, 40), 5, 2000, 2)};
  put_ok(*archive, rows);
  const std::int64_t id = rows[0].ref.id;
  const std::string expected =
      path + ": chunk (1,2,3) seq 0 (id " + std::to_string(id) + "): checksum mismatch, the blob is damaged";

  SECTION("a flipped byte in the blob") {
    RawDb raw(path);
    std::vector<std::uint8_t> blob = raw.blob(id);
    blob[1234] ^= 0x10;
    raw.set_blob(id, blob);
  }
  SECTION("a changed checksum") {
    RawDb(path).exec("UPDATE relief_chunk SET crc32 = (crc32 + 1) % 4294967296 WHERE id = " +
                     std::to_string(id));
  }
  SECTION("a truncated blob") {
    RawDb raw(path);
    std::vector<std::uint8_t> blob = raw.blob(id);
    blob.resize(1000);
    raw.set_blob(id, blob);
  }

  const Result<ChunkRow> row = archive->read_chunk(id);
  REQUIRE_FALSE(row.is_ok());
  CHECK(row.status().code() == StatusCode::kCorruptData);
  CHECK(row.status().message() == expected);
  // The neighbour is fine.
  CHECK(read_ok(*archive, rows[1].ref.id).blob == rows[1].blob);
}

TEST_CASE("columns of the wrong type are format errors, not crashes", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto archive = create_ok(path);
  const std::int64_t scan = begin_ok(*archive);
  std::vector<ChunkRow> rows = {make_row({0, 0, 0}, scan, cube(1, 2), 5, 20, 1)};
  put_ok(*archive, rows);

  // The CHECK constraints pass text ('lots' sorts above every number).
  RawDb(path).exec("UPDATE relief_chunk SET input_points = 'lots'");
  const Result<std::vector<ChunkRef>> refs = archive->all_chunks();
  CHECK(refs.status().code() == StatusCode::kFormatError);
  CHECK(starts_with(refs.status().message(), path + ": "));
  CHECK_THAT(refs.status().message(), Catch::Contains("input_points"));
  CHECK(archive->read_chunk(rows[0].ref.id).status().code() == StatusCode::kFormatError);
  CHECK(archive->info().status().code() == StatusCode::kFormatError);
}

// ---- Scans

TEST_CASE("scans: finish records attributes, abort removes everything of the scan", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto archive = create_ok(path);

  const std::int64_t first =
      begin_ok(*archive, {{"one.las", "las", 1000, "EPSG:25832", 0}, {"two.las", "las", 500, "", 0}});
  std::vector<ChunkRow> kept = {make_row({0, 0, 0}, first, cube(1, 2), 100, 64, 1),
                                make_row({1, 0, 0}, first, cube(26, 27), 200, 64, 2)};
  put_ok(*archive, kept);
  REQUIRE(archive->finish_scan(first, true, false, "EPSG:25832").is_ok());

  const std::int64_t second = begin_ok(*archive, {{"three.xyz", "xyz", 77, "", 0}});
  CHECK(second > first);
  std::vector<ChunkRow> doomed = {make_row({0, 0, 0}, second, cube(1.5, 2.5), 300, 64, 3),
                                  make_row({9, 9, 9}, second, cube(230, 240), 400, 64, 4)};
  put_ok(*archive, doomed);
  CHECK(doomed[0].ref.seq == 1);

  {
    const ArchiveInfo info = info_ok(*archive);
    CHECK(info.chunk_count == 4);
    REQUIRE(info.scans.size() == 2);
    CHECK(info.scans[0].complete);
    CHECK_FALSE(info.scans[1].complete);
    CHECK(info.sources.size() == 3);
    CHECK(info.has_colors);
    CHECK_FALSE(info.has_intensity);
    CHECK(info.crs == "EPSG:25832");
  }

  REQUIRE(archive->abort_scan(second).is_ok());
  CHECK(ids_of(all_ok(*archive)) == ids_of({kept[0].ref, kept[1].ref}));
  CHECK(ids_of(find_ok(*archive, cube(-1e9, 1e9))) == ids_of({kept[0].ref, kept[1].ref}));
  {
    RawDb raw(path);
    CHECK(raw.integer("SELECT COUNT(*) FROM relief_chunk_index") == 2);
    CHECK(raw.integer("SELECT COUNT(*) FROM relief_source WHERE scan_id = " + std::to_string(second)) == 0);
  }
  const ArchiveInfo info = info_ok(*archive);
  REQUIRE(info.scans.size() == 1);
  CHECK(info.scans[0].id == first);
  REQUIRE(info.sources.size() == 2);
  CHECK(info.sources[0].path == "one.las");
  CHECK(info.sources[0].format == "las");
  CHECK(info.sources[0].point_count == 1000);
  CHECK(info.sources[0].crs == "EPSG:25832");
  CHECK(info.sources[0].scan_id == first);
  CHECK(info.input_points == kept[0].ref.input_points + kept[1].ref.input_points);

  // Ids are never reused; the voxel's next seq follows what is left.
  const std::int64_t third = begin_ok(*archive);
  std::vector<ChunkRow> later = {make_row({0, 0, 0}, third, cube(1, 2), 1, 8, 5)};
  put_ok(*archive, later);
  CHECK(later[0].ref.id > doomed[1].ref.id);
  CHECK(later[0].ref.seq == 1);
  CHECK(third > second);

  SECTION("unknown scans are refused") {
    CHECK(archive->abort_scan(12345).code() == StatusCode::kInvalidArgument);
    CHECK(archive->finish_scan(12345, false, false, "").code() == StatusCode::kInvalidArgument);
    std::vector<ChunkRow> orphan = {make_row({0, 0, 0}, 12345, cube(1, 2), 1, 8, 6)};
    const Status status = archive->put_chunks(orphan);
    CHECK(status.code() == StatusCode::kInvalidArgument);
    CHECK(starts_with(status.message(), path + ": "));
    CHECK(orphan[0].ref.id == 0);
  }
}

TEST_CASE("info sums every chunk row and reports the scans", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto archive = create_ok(path);
  const std::int64_t s1 = begin_ok(*archive, {{"a.ply", "ply", 10, "", 0}});
  std::vector<ChunkRow> rows = {
      make_row({0, 0, 0}, s1, box_of({1, 2, 3}, {4, 5, 6}), 100, 1000, 1),
      make_row({-1, 0, 0}, s1, box_of({-7, 0.5, 0.25}, {-6, 1, 2}), 200, 2000, 2),
  };
  put_ok(*archive, rows);
  REQUIRE(archive->finish_scan(s1, false, true, "").is_ok());
  const std::int64_t s2 = begin_ok(*archive, {{"b.pcd", "pcd", 20, "EPSG:4326", 0}});
  std::vector<ChunkRow> more = {make_row({0, 0, 1}, s2, box_of({3, 4, 30}, {4, 8, 31}), 50, 500, 3)};
  put_ok(*archive, more);
  REQUIRE(archive->finish_scan(s2, true, false, "EPSG:4326").is_ok());

  const ArchiveInfo info = info_ok(*archive);
  CHECK(info.chunk_count == 3);
  CHECK(info.decoded_points == 350);
  CHECK(info.input_points == 350 + 3 * 7);
  CHECK(info.blob_bytes == 3500);
  CHECK(info.bounds.min == Vec3d{-7, 0.5, 0.25});
  CHECK(info.bounds.max == Vec3d{4, 8, 31});
  CHECK(info.has_colors);
  CHECK(info.has_intensity);
  CHECK(info.crs == "EPSG:4326");  // the first complete scan with a CRS
  CHECK(info.file_bytes >= fs::file_size(path));
  REQUIRE(info.scans.size() == 2);
  CHECK(info.scans[0].complete);
  CHECK(info.scans[1].complete);
  CHECK(info.scans[1].created_at.size() == 20);
  REQUIRE(info.sources.size() == 2);
  CHECK(info.sources[1].scan_id == s2);
  CHECK(info.sources[1].crs == "EPSG:4326");
}

TEST_CASE("a scan left unfinished keeps its committed chunks readable", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  std::vector<ChunkRow> rows;
  {
    auto archive = create_ok(path);
    const std::int64_t scan = begin_ok(*archive, {{"big.las", "las", 1 << 20, "", 0}});
    rows = {make_row({3, 3, 3}, scan, cube(80, 90), 10, 300, 1)};
    put_ok(*archive, rows);
    // The process "dies" here: no finish_scan.
  }
  auto archive = open_ok(path, Archive::Mode::kReadOnly);
  const ArchiveInfo info = info_ok(*archive);
  REQUIRE(info.scans.size() == 1);
  CHECK_FALSE(info.scans[0].complete);
  CHECK(info.chunk_count == 1);
  CHECK(read_ok(*archive, rows[0].ref.id).blob == rows[0].blob);
}

// ---- Transactions and concurrency

TEST_CASE("put_chunks is all or nothing", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto archive = create_ok(path);
  const std::int64_t scan = begin_ok(*archive);
  std::vector<ChunkRow> before = {make_row({0, 0, 0}, scan, cube(1, 2), 5, 16, 1)};
  put_ok(*archive, before);

  std::vector<ChunkRow> rows = {make_row({0, 0, 0}, scan, cube(1, 2), 5, 16, 2),
                                make_row({7, 0, 0}, scan, cube(176, 177), 5, 16, 3),
                                make_row({8, 0, 0}, scan, cube(201, 202), 5, 16, 4)};

  SECTION("the second row's index insert collides with a stray index entry") {
    // Ids are handed out in order, so the second new row gets id + 2.
    RawDb(path).exec("INSERT INTO relief_chunk_index VALUES(" + std::to_string(before[0].ref.id + 2) +
                     ", 0, 1, 0, 1, 0, 1)");
  }
  SECTION("a trigger refuses the second row") {
    RawDb(path).exec(
        "CREATE TRIGGER refuse BEFORE INSERT ON relief_chunk WHEN NEW.ix = 7 "
        "BEGIN SELECT RAISE(ABORT, 'refused by test'); END");
  }

  const Status status = archive->put_chunks(rows);
  REQUIRE_FALSE(status.is_ok());
  CHECK(starts_with(status.message(), path + ": "));
  for (const ChunkRow& row : rows) {
    CHECK(row.ref.id == 0);
    CHECK(row.ref.seq == 0);
  }
  CHECK(ids_of(all_ok(*archive)) == std::vector<std::int64_t>{before[0].ref.id});
  CHECK(info_ok(*archive).chunk_count == 1);
  // The handle is still usable: a later call lands normally.
  std::vector<ChunkRow> fine = {make_row({0, 0, 0}, scan, cube(1, 2), 5, 16, 5)};
  put_ok(*archive, fine);
  CHECK(fine[0].ref.seq == 1);
}

TEST_CASE("invalid rows and read-only handles are refused before anything is written", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto archive = create_ok(path);
  const std::int64_t scan = begin_ok(*archive);

  std::vector<ChunkRow> rows = {make_row({0, 0, 0}, scan, cube(1, 2), 5, 16, 1),
                                make_row({1, 0, 0}, scan, cube(26, 27), 5, 16, 2)};
  SECTION("NaN bounds") { rows[1].ref.bounds.max.y = std::nan(""); }
  SECTION("infinite bounds") { rows[1].ref.bounds.max.y = kInf; }
  SECTION("points without bounds") { rows[1].ref.bounds = Box3d{}; }
  SECTION("bounds without points") { rows[1].ref.decoded_points = 0; }
  SECTION("a count SQLite cannot hold") { rows[1].ref.input_points = ~std::uint64_t{0}; }
  const Status status = archive->put_chunks(rows);
  CHECK(status.code() == StatusCode::kInvalidArgument);
  CHECK(starts_with(status.message(), path + ": "));
  CHECK(all_ok(*archive).empty());

  auto reader = open_ok(path, Archive::Mode::kReadOnly);
  std::vector<ChunkRow> good = {make_row({0, 0, 0}, scan, cube(1, 2), 5, 16, 1)};
  CHECK(reader->begin_scan({}).status().code() == StatusCode::kInvalidArgument);
  CHECK(reader->put_chunks(good).code() == StatusCode::kInvalidArgument);
  CHECK(reader->finish_scan(scan, false, false, "").code() == StatusCode::kInvalidArgument);
  CHECK(reader->abort_scan(scan).code() == StatusCode::kInvalidArgument);
}

TEST_CASE("a read-only handle sees whole transactions while a writer appends", "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto writer = create_ok(path);
  const std::int64_t scan = begin_ok(*writer);
  auto reader = open_ok(path, Archive::Mode::kReadOnly);  // opened while the writer is open

  constexpr int kBatches = 40;
  constexpr std::uint64_t kRowsPerBatch = 5;
  constexpr std::uint64_t kPointsPerRow = 10;
  std::atomic<bool> done{false};
  std::string writer_error;  // Catch2 assertions are not thread-safe
  std::thread appender([&] {
    for (int batch = 0; batch < kBatches && writer_error.empty(); ++batch) {
      std::vector<ChunkRow> rows;
      for (std::uint64_t i = 0; i < kRowsPerBatch; ++i) {
        const double x = 25.0 * static_cast<double>(i);
        rows.push_back(make_row({static_cast<std::int64_t>(i), 0, 0}, scan, cube(x + 1, x + 2), kPointsPerRow,
                                2000, static_cast<std::uint64_t>(batch) * 10 + i));
      }
      const Status status = writer->put_chunks(rows);
      if (!status.is_ok()) writer_error = status.to_string();
    }
    done = true;
  });

  int observations = 0;
  bool consistent = true;
  std::string reader_error;
  while (!done || observations < 3) {
    const Result<ArchiveInfo> info = reader->info();
    const Result<std::vector<ChunkRef>> refs = reader->all_chunks();
    if (!info.is_ok() || !refs.is_ok()) {
      reader_error = info.is_ok() ? refs.status().to_string() : info.status().to_string();
      break;
    }
    ++observations;
    // Each put_chunks commits kRowsPerBatch rows at once; nothing in between.
    consistent = consistent && info->chunk_count % kRowsPerBatch == 0 && refs->size() % kRowsPerBatch == 0 &&
                 info->decoded_points == info->chunk_count * kPointsPerRow;
    if (!refs->empty()) {
      const Result<ChunkRow> row = reader->read_chunk(refs->back().id);
      if (!row.is_ok()) {
        reader_error = row.status().to_string();
        break;
      }
    }
    if (done && observations >= 3) break;
  }
  appender.join();
  INFO(writer_error);
  INFO(reader_error);
  CHECK(writer_error.empty());
  CHECK(reader_error.empty());
  CHECK(consistent);
  CHECK(info_ok(*reader).chunk_count == kBatches * kRowsPerBatch);
}

}  // namespace
}  // namespace relief

// ---- One file at rest; readers create nothing

namespace relief {
namespace {

// Runs `body` in a child process that, when this test runs as root (as CI
// does), first drops to the unprivileged user 65534, so file permission bits
// apply to it. Returns the child's exit code (0 = body returned true).
int run_unprivileged(const std::function<bool()>& body) {
  const pid_t pid = ::fork();
  REQUIRE(pid >= 0);
  if (pid == 0) {
    if (::geteuid() == 0 && (::setgid(65534) != 0 || ::setuid(65534) != 0)) ::_exit(3);
    ::_exit(body() ? 0 : 1);
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// Opens read-only and reads everything there is; true when all of it worked.
bool reads_fully(const std::string& path, std::size_t chunks) {
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  if (!archive) return false;
  auto info = (*archive)->info();
  auto refs = (*archive)->find_chunks(cube(-1e9, 1e9));
  if (!info || !refs || info->chunk_count != chunks || refs->size() != chunks) return false;
  for (const ChunkRef& ref : *refs) {
    if (!(*archive)->read_chunk(ref.id)) return false;
  }
  return true;
}

TEST_CASE("a closed archive is one file in rollback mode, readers create no file beside it", "[store][readonly]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  {
    auto writer = create_ok(path);
    const std::int64_t scan = begin_ok(*writer);
    std::vector<ChunkRow> rows = {make_row({0, 0, 0}, scan, cube(1, 2), 5, 3000, 1),
                                  make_row({1, 0, 0}, scan, cube(26, 27), 5, 3000, 2)};
    put_ok(*writer, rows);
    // While it writes, the archive is in WAL mode: readers do not block it.
    CHECK(fs::exists(path + "-wal"));
    CHECK(reads_fully(path, 2));
    REQUIRE(writer->finish_scan(scan, false, false, "").is_ok());
  }
  CHECK(dir.entries() == std::vector<std::string>{"a.relief"});
  CHECK(RawDb(path).text("PRAGMA journal_mode") == "delete");
  CHECK(dir.entries() == std::vector<std::string>{"a.relief"});
  CHECK(reads_fully(path, 2));
  CHECK(dir.entries() == std::vector<std::string>{"a.relief"});
}

TEST_CASE("an archive on read-only media answers queries", "[store][readonly]") {
  TempDir dir;
  fs::create_directories(dir.file("media"));
  const std::string path = dir.file("media/a.relief");
  {
    auto writer = create_ok(path);
    const std::int64_t scan = begin_ok(*writer);
    std::vector<ChunkRow> rows = {make_row({0, 0, 0}, scan, cube(1, 2), 5, 3000, 1)};
    put_ok(*writer, rows);
  }
  SECTION("a closed archive") {}
  SECTION("an archive left in WAL mode (its writer was killed after a checkpoint)") {
    RawDb(path).exec("PRAGMA journal_mode = WAL");
    REQUIRE(fs::exists(path));
    REQUIRE_FALSE(fs::exists(path + "-wal"));
  }
  fs::permissions(path, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  fs::permissions(dir.file("media"), fs::perms::owner_read | fs::perms::owner_exec | fs::perms::group_read |
                                         fs::perms::group_exec | fs::perms::others_read | fs::perms::others_exec);
  // The parent must let the unprivileged user reach the directory.
  fs::permissions(dir.path(), fs::perms::others_exec | fs::perms::others_read, fs::perm_options::add);
  const int code = run_unprivileged([&] {
    // Proof that the media is read-only for this process, then the reads.
    const bool writable = ::access(dir.file("media").c_str(), W_OK) == 0;
    return !writable && reads_fully(path, 1);
  });
  CHECK(code == 0);
  CHECK(dir.entries() == std::vector<std::string>{"media"});
  CHECK(TempDir::list(dir.file("media")) == std::vector<std::string>{"a.relief"});
  fs::permissions(dir.file("media"), fs::perms::owner_all);
}

}  // namespace
}  // namespace relief

// ---- Damage: metadata checksum, spatial index, check_archive

namespace relief {
namespace {

// An archive of `n` chunks in a row along x, all coordinates >= 1 (so that
// flipping a float's exponent bit sends it far away), finished.
std::vector<ChunkRow> fill_row_of_chunks(const std::string& path, int n) {
  auto archive = create_ok(path);
  const std::int64_t scan = begin_ok(*archive);
  std::vector<ChunkRow> rows;
  for (int i = 0; i < n; ++i) {
    const double x = 25.0 * (i + 1);
    rows.push_back(make_row({i + 1, 0, 0}, scan, box_of({x + 1, 1, 1}, {x + 2, 2, 2}), 5, 64,
                            static_cast<std::uint64_t>(i)));
  }
  put_ok(*archive, rows);
  REQUIRE(archive->finish_scan(scan, false, false, "").is_ok());
  return rows;
}

// R*Tree node blobs (SQLite's rtree format: big-endian; the root starts with
// its u16 depth, every node with its u16 cell count; a cell is an i64 id or
// child node number, then six f32 bounds).
constexpr std::size_t kNodeHeader = 4;
constexpr std::size_t kCellBytes = 8 + 6 * 4;

std::int64_t cell_id(const std::vector<std::uint8_t>& node, std::size_t cell) {
  std::int64_t id = 0;
  for (std::size_t i = 0; i < 8; ++i) id = (id << 8) | node[kNodeHeader + cell * kCellBytes + i];
  return id;
}

std::vector<std::uint8_t> node_blob(RawDb& raw, std::int64_t node) {
  const std::int64_t size = raw.integer("SELECT length(data) FROM relief_chunk_index_node WHERE nodeno = " +
                                        std::to_string(node));
  const std::string hex = raw.text("SELECT hex(data) FROM relief_chunk_index_node WHERE nodeno = " +
                                   std::to_string(node));
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  for (std::size_t i = 0; i < bytes.size(); ++i) bytes[i] = static_cast<std::uint8_t>(std::stoi(hex.substr(2 * i, 2), nullptr, 16));
  return bytes;
}

void set_node_blob(RawDb& raw, std::int64_t node, const std::vector<std::uint8_t>& bytes) {
  std::string hex;
  constexpr char kHex[] = "0123456789ABCDEF";
  for (const std::uint8_t b : bytes) {
    hex += kHex[b >> 4];
    hex += kHex[b & 15];
  }
  raw.exec("UPDATE relief_chunk_index_node SET data = X'" + hex + "' WHERE nodeno = " + std::to_string(node));
}

// Flips the exponent's high bit of the first cell's min_x or max_x: a value
// between 2 and 2^64 becomes a tiny positive number.
void flip_first_min_x(std::vector<std::uint8_t>& node) { node[kNodeHeader + 8] ^= 0x40; }
void flip_first_max_x(std::vector<std::uint8_t>& node) { node[kNodeHeader + 8 + 4] ^= 0x40; }

ArchiveCheck check_ok(const std::string& path) {
  Result<ArchiveCheck> check = check_archive(path);
  INFO(check.status().to_string());
  REQUIRE(check.is_ok());
  return std::move(check).value();
}

std::string joined(const std::vector<std::string>& lines) {
  std::string all;
  for (const std::string& line : lines) all += line + "\n";
  return all;
}

TEST_CASE("a new archive does not take the log files a deleted one left under its name", "[store]") {
  // A writer killed mid-run leaves A.relief-wal (and -shm); the user deletes
  // A.relief and compresses again. SQLite replayed the old log into the new
  // file when the writer switched it to WAL: a malformed schema, or the old
  // run's scan inside the new archive.
  TempDir dir;
  const std::string path = dir.file("a.relief");
  {
    auto old = create_ok(path);
    const std::int64_t scan = begin_ok(*old, {{"old.ply", "ply", 100, "", 0}});
    std::vector<ChunkRow> rows;
    for (int i = 0; i < 40; ++i)
      rows.push_back(
          make_row({i, 0, 0}, scan, box_of({25.0 * i + 1, 1, 1}, {25.0 * i + 2, 2, 2}), 40, 3000, 1));
    put_ok(*old, rows);
    REQUIRE(fs::exists(path + "-wal"));
    fs::copy_file(path + "-wal", dir.file("kept-wal"));
    fs::copy_file(path + "-shm", dir.file("kept-shm"));
  }
  fs::remove(path);
  fs::copy_file(dir.file("kept-wal"), path + "-wal");
  fs::copy_file(dir.file("kept-shm"), path + "-shm");
  fs::copy_file(dir.file("kept-wal"), path + "-journal");
  {
    auto fresh = create_ok(path);
    const ArchiveInfo info = info_ok(*fresh);
    CHECK(info.scans.empty());
    CHECK(info.chunk_count == 0);
    REQUIRE(fresh->close().is_ok());
  }
  const ArchiveCheck check = check_ok(path);
  INFO(joined(check.problems));
  CHECK(check.problems.empty());
  CHECK_FALSE(fs::exists(path + "-wal"));
  CHECK_FALSE(fs::exists(path + "-journal"));
}

TEST_CASE("point bounds narrower than a row's are kept beside it, summed by info and removed with their scan",
          "[store]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto archive = create_ok(path);
  const std::int64_t s1 = begin_ok(*archive);
  // Row 0's points lie within its bounds (a base layer overhangs them), row
  // 1 has none narrower; the archive's point bounds take row 1's bounds.
  std::vector<ChunkRow> rows = {make_row({0, 0, 0}, s1, box_of({-1, -1, -1}, {26, 26, 26}), 100, 1000, 1),
                                make_row({1, 0, 0}, s1, box_of({25, 2, 3}, {40, 4, 5}), 100, 1000, 2)};
  rows[0].ref.point_bounds = box_of({0.5, 0.25, 0}, {24, 25, 25});
  {
    RawDb raw(path);
    CHECK(raw.integer("SELECT COUNT(*) FROM sqlite_master WHERE name = 'relief_chunk_extent'") == 0);
  }
  put_ok(*archive, rows);
  REQUIRE(archive->finish_scan(s1, false, false, "").is_ok());
  ArchiveInfo info = info_ok(*archive);
  CHECK(info.bounds.min == Vec3d{-1, -1, -1});
  CHECK(info.bounds.max == Vec3d{40, 26, 26});
  CHECK(info.point_bounds.min == Vec3d{0.5, 0.25, 0});
  CHECK(info.point_bounds.max == Vec3d{40, 25, 25});
  CHECK(read_ok(*archive, rows[0].ref.id).ref.point_bounds.min == Vec3d{0.5, 0.25, 0});
  CHECK(read_ok(*archive, rows[1].ref.id).ref.point_bounds.empty());
  {
    RawDb raw(path);
    CHECK(raw.integer("SELECT COUNT(*) FROM relief_chunk_extent") == 1);
  }

  // Refused before anything is written: point bounds outside the row's.
  const std::int64_t s2 = begin_ok(*archive);
  std::vector<ChunkRow> bad = {make_row({2, 0, 0}, s2, cube(50, 60), 10, 100, 3)};
  bad[0].ref.point_bounds = cube(49, 55);
  CHECK(archive->put_chunks(bad).code() == StatusCode::kInvalidArgument);
  bad[0].ref.point_bounds = box_of({51, 51, 51}, {52, 52, kInf});
  CHECK(archive->put_chunks(bad).code() == StatusCode::kInvalidArgument);
  bad[0].ref.point_bounds = cube(51, 59);
  put_ok(*archive, bad);
  CHECK(info_ok(*archive).point_bounds.max == Vec3d{59, 59, 59});
  REQUIRE(archive->abort_scan(s2).is_ok());
  info = info_ok(*archive);
  CHECK(info.point_bounds.max == Vec3d{40, 25, 25});
  {
    RawDb raw(path);
    CHECK(raw.integer("SELECT COUNT(*) FROM relief_chunk_extent") == 1);
  }
  archive.reset();

  SECTION("a row of no chunk (a writer that does not know the table removed it) is ignored") {
    {
      RawDb raw(path);
      raw.exec("INSERT INTO relief_chunk_extent VALUES(9999, -500, -500, -500, 500, 500, 500)");
    }
    auto reader = open_ok(path, Archive::Mode::kReadOnly);
    CHECK(info_ok(*reader).point_bounds.min == Vec3d{0.5, 0.25, 0});
    const ArchiveCheck check = check_ok(path);
    CHECK(check.problems.empty());
    CHECK_THAT(joined(check.checked), Catch::Contains("1 rows that name no chunk"));
  }
  SECTION("a damaged row is not used, and check reports it; the chunk still reads") {
    for (const char* damage : {"UPDATE relief_chunk_extent SET max_x = 30",  // beyond the chunk's bounds
                               "UPDATE relief_chunk_extent SET min_y = 'text'"}) {
      {
        RawDb raw(path);
        raw.exec(damage);
      }
      auto reader = open_ok(path, Archive::Mode::kReadOnly);
      CHECK(info_ok(*reader).point_bounds.min == Vec3d{-1, -1, -1});
      const ChunkRow row = read_ok(*reader, rows[0].ref.id);
      CHECK(row.ref.point_bounds.empty());
      CHECK(row.blob == rows[0].blob);
      const ArchiveCheck check = check_ok(path);
      CHECK_THAT(joined(check.problems), Catch::Contains(path + ": relief_chunk_extent row "));
    }
  }
}

TEST_CASE("an intact archive passes check_archive", "[store][check]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  fill_row_of_chunks(path, 150);  // more than one R*Tree node
  const ArchiveCheck check = check_ok(path);
  INFO(joined(check.problems));
  CHECK(check.problems.empty());
  CHECK(check.format_version == 3);
  CHECK_THAT(joined(check.checked), Catch::Contains("150 chunk blobs"));
  CHECK_THAT(joined(check.checked), Catch::Contains("integrity_check"));
  CHECK_THAT(joined(check.checked), Catch::Contains("metadata checksum"));
  CHECK_THAT(joined(check.checked), Catch::Contains("the CRS checksum relief_meta crs_crc32"));

  // Progress: each stage in order, the chunk-by-chunk ones counted to their total.
  std::vector<std::string> stages;
  std::map<std::string, std::pair<std::uint64_t, std::uint64_t>> last;  // stage -> (done, total)
  bool monotonic = true;
  auto with_progress = check_archive(path, [&](const char* stage, std::uint64_t done, std::uint64_t total) {
    if (stages.empty() || stages.back() != stage) stages.push_back(stage);
    auto& [d, t] = last[stage];
    monotonic = monotonic && done >= d && (total == 0 || done <= total);
    d = done;
    t = total;
  });
  REQUIRE(with_progress.is_ok());
  CHECK(with_progress->problems.empty());
  CHECK(monotonic);
  CHECK(stages == std::vector<std::string>{"SQLite integrity check", "chunk blobs", "spatial index", "spatial index tree"});
  // The SQLite check counts the pages it has read (no total), at least the archive's.
  CHECK(last["SQLite integrity check"].second == 0);
  CHECK(last["SQLite integrity check"].first >= static_cast<std::uint64_t>(std::filesystem::file_size(path) / 4096));
  CHECK(last["chunk blobs"] == std::pair<std::uint64_t, std::uint64_t>{150, 150});
  CHECK(last["spatial index"] == std::pair<std::uint64_t, std::uint64_t>{150, 150});
}

TEST_CASE("a damaged R*Tree leaf entry makes a query fail naming the chunk, and check report it", "[store][check]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  fill_row_of_chunks(path, 20);  // one node: the root is a leaf
  std::int64_t damaged = 0;
  {
    RawDb raw(path);
    std::vector<std::uint8_t> root = node_blob(raw, 1);
    REQUIRE(raw.integer("SELECT COUNT(*) FROM relief_chunk_index_node") == 1);
    damaged = cell_id(root, 0);
    flip_first_min_x(root);
    set_node_blob(raw, 1, root);
  }
  auto archive = open_ok(path, Archive::Mode::kReadOnly);
  const Result<std::vector<ChunkRef>> refs = archive->find_chunks(cube(-1e9, 1e9));
  REQUIRE_FALSE(refs.is_ok());
  CHECK(refs.status().code() == StatusCode::kCorruptData);
  CHECK(starts_with(refs.status().message(), path + ": chunk ("));
  CHECK_THAT(refs.status().message(), Catch::Contains("(id " + std::to_string(damaged) + ")"));
  CHECK_THAT(refs.status().message(), Catch::Contains("spatial index"));
  // Boxes away from the damaged chunk still work.
  CHECK(find_ok(*archive, box_of({25.0 * 10 + 1, 1, 1}, {25.0 * 10 + 2, 2, 2})).size() == 1);

  const ArchiveCheck check = check_ok(path);
  CHECK_THAT(joined(check.problems), Catch::Contains("(id " + std::to_string(damaged) + ")"));
}

TEST_CASE("a damaged R*Tree inner node cannot hide chunks from a query", "[store][check]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  fill_row_of_chunks(path, 300);
  {
    RawDb raw(path);
    REQUIRE(raw.integer("SELECT COUNT(*) FROM relief_chunk_index_node") > 1);
    std::vector<std::uint8_t> root = node_blob(raw, 1);
    REQUIRE(((root[0] << 8) | root[1]) >= 1);  // depth: the root is an inner node
    flip_first_max_x(root);  // the first subtree's box now ends left of every chunk
    set_node_blob(raw, 1, root);
  }
  auto archive = open_ok(path, Archive::Mode::kReadOnly);
  CHECK(all_ok(*archive).size() == 300);  // the chunk table is intact
  // A box over every chunk, starting above the damaged subtree's new end.
  const Result<std::vector<ChunkRef>> refs = archive->find_chunks(cube(1, 1e9));
  REQUIRE_FALSE(refs.is_ok());
  CHECK(refs.status().code() == StatusCode::kCorruptData);
  CHECK(starts_with(refs.status().message(), path + ": chunk ("));
  CHECK_THAT(refs.status().message(), Catch::Contains("missing from the spatial index"));

  const ArchiveCheck check = check_ok(path);
  CHECK_FALSE(check.problems.empty());
  CHECK_THAT(joined(check.problems), Catch::Contains("does not find it in the spatial index"));
  CHECK_THAT(joined(check.problems), Catch::Contains("rtreecheck"));
}

TEST_CASE("an index entry naming no chunk is reported", "[store][check]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  fill_row_of_chunks(path, 5);
  RawDb(path).exec("INSERT INTO relief_chunk_index VALUES(999, 26, 27, 1, 2, 1, 2)");
  auto archive = open_ok(path, Archive::Mode::kReadOnly);
  const Result<std::vector<ChunkRef>> refs = archive->find_chunks(cube(-1e9, 1e9));
  REQUIRE_FALSE(refs.is_ok());
  CHECK(refs.status().code() == StatusCode::kCorruptData);
  CHECK(starts_with(refs.status().message(), path + ": spatial index entry 999 names no chunk"));
  CHECK_THAT(joined(check_ok(path).problems), Catch::Contains("spatial index entry 999 names no chunk"));
}

TEST_CASE("check reports a chunk row whose codec, scan, key or counts are wrong", "[store][check]") {
  // Each passed as intact: a row moved to another key, naming no scan, or of
  // an unknown codec; counts against the blob are the codec's to say
  // (ChunkRowCheck, relief/query.h chunk_row_check).
  TempDir dir;
  const std::string path = dir.file("a.relief");
  fill_row_of_chunks(path, 5);
  CHECK(check_ok(path).problems.empty());
  {
    RawDb raw(path);
    raw.exec("UPDATE relief_chunk SET ix = ix + 10 WHERE id = 1");
    raw.exec("UPDATE relief_chunk SET scan_id = 999 WHERE id = 2");
    raw.exec("UPDATE relief_chunk SET codec = 7 WHERE id = 3");
  }
  const std::string problems = joined(check_ok(path).problems);
  CHECK_THAT(
      problems,
      Catch::Contains("(id 1): its bounds (26 .. 27 on axis x) lie outside its key's cube (275 .. 300)"));
  CHECK_THAT(problems, Catch::Contains("(id 2): names scan 999, which does not exist"));
  CHECK_THAT(problems, Catch::Contains("(id 3): codec 7, which no reader knows"));
  // The row check sees each row and blob whose CRC-32 matches.
  std::vector<std::int64_t> seen;
  const Result<ArchiveCheck> asked =
      check_archive(path, nullptr, [&](const ChunkRef& row, std::span<const std::uint8_t> blob) {
        seen.push_back(row.id);
        return row.id == 4 && blob.size() == 64 ? std::string("row 4 disagrees") : std::string();
      });
  REQUIRE(asked.is_ok());
  std::sort(seen.begin(), seen.end());
  CHECK(seen == std::vector<std::int64_t>{1, 2, 3, 4, 5});
  CHECK_THAT(joined(asked->problems), Catch::Contains("(id 4): row 4 disagrees"));
}

TEST_CASE("damaged metadata fails its checksum on open and in check", "[store][check]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  fill_row_of_chunks(path, 3);
  // One byte of a value changed, as a flipped bit in the page would.
  RawDb(path).exec("UPDATE relief_meta SET value = 'relief-tesu 0.1' WHERE key = 'creator'");
  for (const Archive::Mode mode : {Archive::Mode::kReadOnly, Archive::Mode::kReadWrite}) {
    const Status status = Archive::open(path, mode).status();
    CHECK(status.code() == StatusCode::kCorruptData);
    CHECK(starts_with(status.message(), path + ": metadata checksum mismatch"));
  }
  const ArchiveCheck check = check_ok(path);
  REQUIRE(check.problems.size() == 1);
  CHECK(starts_with(check.problems[0], path + ": metadata checksum mismatch"));
}

TEST_CASE("check_archive reports every damaged blob", "[store][check]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  const std::vector<ChunkRow> rows = fill_row_of_chunks(path, 4);
  {
    RawDb raw(path);
    for (const std::size_t i : {std::size_t{1}, std::size_t{3}}) {
      std::vector<std::uint8_t> blob = raw.blob(rows[i].ref.id);
      blob[10] ^= 0x01;
      raw.set_blob(rows[i].ref.id, blob);
    }
  }
  const ArchiveCheck check = check_ok(path);
  REQUIRE(check.problems.size() == 2);
  CHECK_THAT(check.problems[0], Catch::Contains("(id " + std::to_string(rows[1].ref.id) + "): checksum mismatch"));
  CHECK_THAT(check.problems[1], Catch::Contains("(id " + std::to_string(rows[3].ref.id) + "): checksum mismatch"));
}

TEST_CASE("version-1 archives still read, check without a checksum, and are upgraded by a writer", "[store][check]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  const std::vector<ChunkRow> rows = fill_row_of_chunks(path, 10);
  downgrade_to_v1(path);
  {
    auto archive = open_ok(path, Archive::Mode::kReadOnly);
    CHECK(info_ok(*archive).format_version == 1);
    CHECK(find_ok(*archive, cube(-1e9, 1e9)).size() == 10);
    CHECK(find_ok(*archive, box_of({51, 1, 1}, {52, 2, 2})).size() == 1);
    CHECK(read_ok(*archive, rows[4].ref.id).blob == rows[4].blob);
  }
  {
    const ArchiveCheck check = check_ok(path);
    INFO(joined(check.problems));
    CHECK(check.problems.empty());
    CHECK(check.format_version == 1);
    CHECK_THAT(joined(check.checked), Catch::Contains("absent in format version 1"));
  }
  {
    auto writer = open_ok(path, Archive::Mode::kReadWrite);
    CHECK(info_ok(*writer).format_version == 3);
  }
  RawDb raw(path);
  CHECK(raw.integer("PRAGMA user_version") == 3);
  CHECK(raw.text("SELECT value FROM relief_meta WHERE key = 'format_version'") == "3");
  CHECK(raw.integer("SELECT COUNT(*) FROM relief_meta WHERE key IN ('crs', 'crs_source')") == 0);
  CHECK(raw.integer("SELECT COUNT(*) FROM sqlite_master WHERE name = 'relief_chunk_bounds'") == 1);
  CHECK(check_ok(path).problems.empty());
}

TEST_CASE("create takes the page size it is given and writes the schema compactly", "[store]") {
  TempDir dir;
  for (const std::uint32_t page_size : {kSmallArchivePageSize, kArchivePageSize, std::uint32_t{4096}}) {
    const std::string path = dir.file("p" + std::to_string(page_size) + ".relief");
    {
      Result<std::unique_ptr<Archive>> archive = Archive::create(path, grid_25m(), "", "", page_size);
      INFO(archive.status().to_string());
      REQUIRE(archive.is_ok());
      const std::int64_t scan = begin_ok(**archive, {{"a.ply", "ply", 100, "", 0}});
      // Blobs that span several overflow pages at every page size.
      std::vector<ChunkRow> rows = {make_row({0, 0, 0}, scan, cube(1, 2), 40, 20000, 1),
                                    make_row({1, 0, 0}, scan, cube(26, 27), 50, 3, 2)};
      put_ok(**archive, rows);
      REQUIRE((*archive)->finish_scan(scan, true, false, "").is_ok());
      CHECK(read_ok(**archive, rows[0].ref.id).blob == rows[0].blob);
    }
    RawDb raw(path);
    CHECK(raw.integer("PRAGMA page_size") == page_size);
    // No line breaks, runs of spaces or spaces beside punctuation in the
    // CREATE text Relief wrote (SQLite's own R*Tree tables are its business).
    CHECK(raw.integer("SELECT COUNT(*) FROM sqlite_master WHERE name LIKE 'relief%' AND name NOT LIKE "
                      "'relief_chunk_index_%' AND (instr(sql, char(10)) OR instr(sql, '  ') OR instr(sql, ', ') "
                      "OR instr(sql, ' (') OR instr(sql, '( '))") == 0);
    CHECK(raw.integer("SELECT COUNT(*) FROM sqlite_master WHERE name = 'relief_chunk' AND "
                      "sql LIKE 'CREATE TABLE relief_chunk(id INTEGER PRIMARY KEY AUTOINCREMENT,ix INTEGER NOT NULL,%'") == 1);
    // One b-tree for the metadata, none for relief_source's scan_id.
    CHECK(raw.integer("SELECT COUNT(*) FROM sqlite_master WHERE name IN ('sqlite_autoindex_relief_meta_1', "
                      "'relief_source_scan')") == 0);
    auto reader = open_ok(path, Archive::Mode::kReadOnly);
    CHECK(read_ok(*reader, 1).blob.size() == 20000);
    CHECK(info_ok(*reader).grid.chunk_edge == 25);
    const ArchiveCheck check = check_ok(path);
    INFO(joined(check.problems));
    CHECK(check.problems.empty());
  }
  for (const std::uint32_t bad : {0u, 256u, 1000u, 131072u}) {
    const std::string path = dir.file("bad.relief");
    CHECK(Archive::create(path, grid_25m(), "", "", bad).status().code() == StatusCode::kInvalidArgument);
    CHECK_FALSE(fs::exists(path));
  }
}

TEST_CASE("the index of chunks by scan comes with the second scan", "[store]") {
  TempDir dir;
  const std::string path = dir.file("scans.relief");
  const auto has_index = [&path] {
    RawDb raw(path);
    return raw.integer("SELECT COUNT(*) FROM sqlite_master WHERE name = 'relief_chunk_scan'") == 1;
  };
  std::vector<ChunkRow> first;
  {
    auto archive = Archive::create(path, grid_25m(), "", "", kSmallArchivePageSize);
    REQUIRE(archive.is_ok());
    // A first scan that is given up leaves no other scan behind it.
    const std::int64_t dropped = begin_ok(**archive, {{"x.ply", "ply", 10, "", 0}});
    std::vector<ChunkRow> gone = {make_row({5, 0, 0}, dropped, cube(126, 127), 10, 50, 9)};
    put_ok(**archive, gone);
    REQUIRE((*archive)->abort_scan(dropped).is_ok());
    const std::int64_t scan = begin_ok(**archive, {{"a.ply", "ply", 100, "", 0}});
    first = {make_row({0, 0, 0}, scan, cube(1, 2), 40, 300, 1), make_row({1, 0, 0}, scan, cube(26, 27), 50, 3, 2)};
    put_ok(**archive, first);
    REQUIRE((*archive)->finish_scan(scan, false, false, "").is_ok());
  }
  CHECK_FALSE(has_index());
  {
    auto archive = open_ok(path, Archive::Mode::kReadWrite);
    const std::int64_t second = begin_ok(*archive, {{"b.ply", "ply", 100, "", 0}});
    std::vector<ChunkRow> rows = {make_row({2, 0, 0}, second, cube(51, 52), 40, 100, 3)};
    put_ok(*archive, rows);
    // Removing the second scan keeps the first one's chunks, through the index.
    REQUIRE(archive->abort_scan(second).is_ok());
    for (const ChunkRow& row : first) CHECK(read_ok(*archive, row.ref.id).blob == row.blob);
    CHECK(info_ok(*archive).chunk_count == first.size());
  }
  CHECK(has_index());
  const ArchiveCheck check = check_ok(path);
  INFO(joined(check.problems));
  CHECK(check.problems.empty());
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// Bitwise CRC-32 (IEEE 802.3), independent of the library's.
std::uint32_t reference_crc32(const std::vector<std::uint8_t>& bytes) {
  std::uint32_t crc = 0xFFFFFFFFu;
  for (const std::uint8_t byte : bytes) {
    crc ^= byte;
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0xEDB88320u & (0u - (crc & 1u)));
  }
  return ~crc;
}

void put_field(std::vector<std::uint8_t>& out, const std::string& text) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(text.size() >> (8 * i)));
  out.insert(out.end(), text.begin(), text.end());
}

std::string hex8(std::uint32_t value) {
  char buffer[16];
  std::snprintf(buffer, sizeof buffer, "%08X", value);
  return buffer;
}

// meta_crc32 as format-spec/archive.md 2.1 lays it out, computed here from the rows.
std::string reference_meta_checksum(RawDb& raw) {
  const std::int64_t rows = raw.integer("SELECT COUNT(*) FROM relief_meta WHERE key <> 'meta_crc32'");
  std::vector<std::uint8_t> bytes;
  for (std::int64_t i = 0; i < rows; ++i) {
    const std::string where =
        " FROM relief_meta WHERE key <> 'meta_crc32' ORDER BY key LIMIT 1 OFFSET " + std::to_string(i);
    put_field(bytes, raw.text("SELECT key" + where));
    put_field(bytes, raw.text("SELECT value" + where));
  }
  return hex8(reference_crc32(bytes));
}

TEST_CASE("meta_crc32 is the CRC-32 of the other rows as format-spec/archive.md 2.1 lays them out", "[store][check]") {
  // The worked example of the spec.
  std::vector<std::uint8_t> example;
  put_field(example, "a");
  put_field(example, "1");
  put_field(example, "bc");
  put_field(example, "");
  CHECK(example.size() == 20);
  CHECK(hex8(reference_crc32(example)) == "32DF8018");

  TempDir dir;
  const std::string path = dir.file("a.relief");
  fill_row_of_chunks(path, 2);
  RawDb raw(path);
  CHECK(raw.text("SELECT value FROM relief_meta WHERE key = 'meta_crc32'") == reference_meta_checksum(raw));
}

// Turns a version-3 archive into what version 2 wrote: the CRS copies in
// place of crs_crc32, and meta_crc32 over them.
void downgrade_to_v2(const std::string& path) {
  RawDb raw(path);
  raw.exec(std::string(kCrsCopiesSql) +
           "UPDATE relief_meta SET value = '2' WHERE key = 'format_version'; PRAGMA user_version = 2");
  raw.exec("UPDATE relief_meta SET value = '" + reference_meta_checksum(raw) + "' WHERE key = 'meta_crc32'");
}

// An archive of two finished scans, the first with a CRS its first source gave in another form.
std::string archive_with_crs(TempDir& dir) {
  const std::string path = dir.file("crs.relief");
  auto archive = create_ok(path);
  const std::int64_t first = begin_ok(*archive, {{"one.las", "las", 10, "SOURCE FORM", 0}, {"two.las", "las", 5, "", 0}});
  std::vector<ChunkRow> rows = {make_row({0, 0, 0}, first, cube(1, 2), 10, 64, 1)};
  put_ok(*archive, rows);
  REQUIRE(archive->finish_scan(first, false, false, "EPSG:25832").is_ok());
  const std::int64_t second = begin_ok(*archive, {{"three.las", "las", 5, "OTHER", 0}});
  REQUIRE(archive->finish_scan(second, false, false, "EPSG:4326").is_ok());
  return path;
}

TEST_CASE("crs_crc32 is the CRC-32 of the CRS and its source form as format-spec/archive.md 2.1 lays them out",
          "[store][check]") {
  TempDir dir;
  const std::string path = archive_with_crs(dir);
  CHECK(info_ok(*open_ok(path, Archive::Mode::kReadOnly)).crs == "EPSG:25832");
  CHECK(info_ok(*open_ok(path, Archive::Mode::kReadOnly)).crs_source == "SOURCE FORM");
  std::vector<std::uint8_t> bytes;
  put_field(bytes, "EPSG:25832");
  put_field(bytes, "SOURCE FORM");
  RawDb raw(path);
  CHECK(raw.text("SELECT value FROM relief_meta WHERE key = 'crs_crc32'") == hex8(reference_crc32(bytes)));
  // The worked example of the spec: no CRS.
  CHECK(hex8(reference_crc32(std::vector<std::uint8_t>(8, 0))) == "6522DF69");
}

TEST_CASE("a damaged CRS text is corrupt data, for info and check", "[store][check]") {
  TempDir dir;
  const std::string path = archive_with_crs(dir);
  RawDb(path).exec("UPDATE relief_scan SET crs = 'EPSG:25833' WHERE crs = 'EPSG:25832'");
  const auto archive = open_ok(path, Archive::Mode::kReadOnly);
  const Result<ArchiveInfo> info = archive->info();
  REQUIRE_FALSE(info.is_ok());
  CHECK(info.status().code() == StatusCode::kCorruptData);
  CHECK_THAT(info.status().message(), Catch::StartsWith(path + ": CRS checksum mismatch (stored "));
  CHECK_THAT(info.status().message(), Catch::EndsWith("the CRS text of relief_scan or relief_source is damaged"));
  const ArchiveCheck check = check_ok(path);
  REQUIRE(check.problems.size() == 1);
  CHECK_THAT(check.problems[0], Catch::Contains("CRS checksum mismatch"));
  // A source form changed is caught alike; a missing checksum too.
  RawDb raw(path);
  raw.exec("UPDATE relief_scan SET crs = 'EPSG:25832' WHERE crs = 'EPSG:25833'");
  REQUIRE(open_ok(path, Archive::Mode::kReadOnly)->info().is_ok());
  raw.exec("UPDATE relief_source SET crs = 'SOURCE FORN' WHERE crs = 'SOURCE FORM'");
  CHECK(open_ok(path, Archive::Mode::kReadOnly)->info().status().code() == StatusCode::kCorruptData);
}

TEST_CASE("version-2 archives read their CRS from relief_meta and are upgraded by a writer", "[store]") {
  TempDir dir;
  const std::string path = archive_with_crs(dir);
  downgrade_to_v2(path);
  // What a scan killed before version 2 recorded its CRS left: none in the
  // scan rows; the metadata's copy is the archive's CRS.
  RawDb(path).exec("UPDATE relief_scan SET crs = ''; UPDATE relief_source SET crs = ''");
  {
    auto archive = open_ok(path, Archive::Mode::kReadOnly);
    const ArchiveInfo info = info_ok(*archive);
    CHECK(info.format_version == 2);
    CHECK(info.crs == "EPSG:25832");
    CHECK(info.crs_source == "SOURCE FORM");
    CHECK(check_ok(path).problems.empty());
  }
  {
    auto writer = open_ok(path, Archive::Mode::kReadWrite);
    const ArchiveInfo info = info_ok(*writer);
    CHECK(info.format_version == 3);
    CHECK(info.crs == "EPSG:25832");  // moved to the earliest scan and its first source
    CHECK(info.crs_source == "SOURCE FORM");
  }
  RawDb raw(path);
  CHECK(raw.integer("PRAGMA user_version") == 3);
  CHECK(raw.integer("SELECT COUNT(*) FROM relief_meta WHERE key IN ('crs', 'crs_source')") == 0);
  CHECK(raw.text("SELECT crs FROM relief_scan ORDER BY id LIMIT 1") == "EPSG:25832");
  CHECK(raw.text("SELECT crs FROM relief_source ORDER BY id LIMIT 1") == "SOURCE FORM");
  CHECK(raw.text("SELECT crs FROM relief_source ORDER BY id LIMIT 1 OFFSET 1") == "");
  CHECK(check_ok(path).problems.empty());
  // A version-2 archive whose scans hold the CRS keeps them as they are.
  TempDir other;
  const std::string kept = archive_with_crs(other);
  downgrade_to_v2(kept);
  { open_ok(kept, Archive::Mode::kReadWrite); }
  RawDb k(kept);
  CHECK(k.text("SELECT group_concat(crs, '|') FROM (SELECT crs FROM relief_scan ORDER BY id)") == "EPSG:25832|EPSG:4326");
  CHECK(k.text("SELECT group_concat(crs, '|') FROM (SELECT crs FROM relief_source ORDER BY id)") == "SOURCE FORM||OTHER");
  CHECK(info_ok(*open_ok(kept, Archive::Mode::kReadOnly)).crs == "EPSG:25832");
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

TEST_CASE("a writer closing while a reader is connected leaves its data in the file itself", "[store][readonly]") {
  TempDir dir;
  const std::string path = dir.file("a.relief");
  auto writer = create_ok(path);
  const std::int64_t scan = begin_ok(*writer);
  std::vector<ChunkRow> rows = {make_row({0, 0, 0}, scan, cube(1, 2), 5, 3000, 1),
                                make_row({1, 0, 0}, scan, cube(26, 27), 5, 3000, 2)};
  put_ok(*writer, rows);
  auto reader = open_ok(path, Archive::Mode::kReadOnly);
  CHECK(all_ok(*reader).size() == 2);
  writer.reset();  // cannot switch back to rollback mode: the reader is connected
  CHECK(all_ok(*reader).size() == 2);
  // The database file alone (what a copy without the -wal would hold).
  sqlite3* raw = nullptr;
  REQUIRE(sqlite3_open_v2(("file:" + path + "?immutable=1").c_str(), &raw, SQLITE_OPEN_READONLY | SQLITE_OPEN_URI,
                          nullptr) == SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  REQUIRE(sqlite3_prepare_v2(raw, "SELECT COUNT(*) FROM relief_chunk", -1, &stmt, nullptr) == SQLITE_OK);
  REQUIRE(sqlite3_step(stmt) == SQLITE_ROW);
  CHECK(sqlite3_column_int64(stmt, 0) == 2);
  sqlite3_finalize(stmt);
  sqlite3_close(raw);
}

}  // namespace
}  // namespace relief

namespace relief {
namespace {

// Runs `body` in a child process whose files may not grow beyond `bytes`
// (RLIMIT_FSIZE, a full disk for one file; SIGXFSZ ignored, so writes fail
// with EFBIG) and returns its exit code: `body`'s, 10 when the limit could
// not be set, -1 when the child did not exit.
int exit_code_with_file_limit(std::uint64_t bytes, const std::function<int()>& body) {
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    struct rlimit limit {};
    limit.rlim_cur = limit.rlim_max = static_cast<rlim_t>(bytes);
    if (::setrlimit(RLIMIT_FSIZE, &limit) != 0) ::_exit(10);
    ::_exit(body());
  }
  int status = 0;
  ::waitpid(pid, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST_CASE("room to undo is kept on archives a handle opened, not on ones it created", "[store][diskfull]") {
  TempDir dir;
  const std::string fresh = dir.file("fresh.relief");
  const std::string old = dir.file("old.relief");
  create_ok(old);
  const auto rows_for = [](std::int64_t scan) {
    std::vector<ChunkRow> rows;
    for (int i = 0; i < 200; ++i) {
      const double x = 25.0 * i;
      rows.push_back(make_row({i, 0, 0}, scan, cube(x + 1, x + 2), 5, 64, static_cast<std::uint64_t>(i)));
    }
    return rows;
  };
  // 2 MB more per file: plenty for 200 small rows (~1 MB of WAL), not for
  // them plus the room to remove them again (~4 MB by the store's bound).
  const int code = exit_code_with_file_limit(fs::file_size(old) + (2u << 20), [&] {
    {
      auto created = Archive::create(fresh, grid_25m(), "", "test");
      if (!created) return 11;
      auto scan = (*created)->begin_scan({});
      std::vector<ChunkRow> rows = rows_for(scan ? *scan : 0);
      if (!scan || !(*created)->put_chunks(rows)) return 12;  // a new archive: no reserve
    }
    auto opened = Archive::open(old, Archive::Mode::kReadWrite);
    if (!opened) return 13;
    auto scan = (*opened)->begin_scan({});
    std::vector<ChunkRow> rows = rows_for(scan ? *scan : 0);
    const Status status = (*opened)->put_chunks(rows);
    if (status.is_ok()) return 14;
    const bool full = status.code() == StatusCode::kIoError &&
                      status.message().find(old + ": the disk is full") == 0;
    if (!full) return 15;
    return (*opened)->abort_scan(*scan).is_ok() ? 0 : 16;
  });
  CHECK(code == 0);
  CHECK(info_ok(*open_ok(fresh, Archive::Mode::kReadOnly)).chunk_count == 200);
  const ArchiveInfo info = info_ok(*open_ok(old, Archive::Mode::kReadOnly));
  CHECK(info.chunk_count == 0);
  CHECK(info.scans.empty());
}

TEST_CASE("a failed append of large blobs is undone within the room kept", "[store][diskfull]") {
  // Debian's SQLite zeroes every freed page (secure_delete): removing the
  // rows of a failed append rewrote all their overflow pages, an undo as
  // large as the append, which a full disk cannot take. Writers turn it off.
  TempDir dir;
  const std::string old = dir.file("old.relief");
  create_ok(old);
  const int code = exit_code_with_file_limit(fs::file_size(old) + (4u << 20), [&] {
    auto opened = Archive::open(old, Archive::Mode::kReadWrite);
    if (!opened) return 11;
    auto scan = (*opened)->begin_scan({});
    if (!scan) return 12;
    Status status;
    int batches = 0;
    for (int b = 0; b < 40 && status.is_ok(); ++b, ++batches) {
      std::vector<ChunkRow> rows;
      for (int i = 0; i < 2; ++i) {
        const double x = 25.0 * (2 * b + i);
        rows.push_back(make_row({2 * b + i, 0, 0}, *scan, cube(x + 1, x + 2), 5, 150000,
                                static_cast<std::uint64_t>(2 * b + i)));
      }
      status = (*opened)->put_chunks(rows);
    }
    if (status.is_ok()) return 13;
    if (status.code() != StatusCode::kIoError ||
        status.message().find("the disk is full") == std::string::npos) {
      return 14;
    }
    if (batches < 3) return 15;  // some committed, so there is something to undo
    return (*opened)->abort_scan(*scan).is_ok() ? 0 : 16;
  });
  CHECK(code == 0);
  const ArchiveInfo info = info_ok(*open_ok(old, Archive::Mode::kReadOnly));
  CHECK(info.chunk_count == 0);
  CHECK(info.scans.empty());
  CHECK(check_ok(old).problems.empty());
}

}  // namespace
}  // namespace relief
