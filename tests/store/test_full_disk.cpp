// Archive::close() on a disk that fills up after the last commit: SQLite's
// write-ahead log holds every committed page, but folding it into the
// archive file needs room the disk no longer has (support/limited_vfs.h).
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "relief/archive.h"
#include "support/limited_vfs.h"
#include "support/temp_dir.h"

namespace relief {
namespace {

namespace fs = std::filesystem;

ArchiveGrid grid() {
  ArchiveGrid g;
  g.chunk_edge = 10;
  return g;
}

// `count` chunk rows of `size` random bytes each, keys (k, 0, 0).
std::vector<ChunkRow> rows(std::int64_t scan_id, int count, std::size_t size, int first_key) {
  std::mt19937 rng(static_cast<std::uint32_t>(first_key));
  std::vector<ChunkRow> out;
  for (int k = 0; k < count; ++k) {
    ChunkRow row;
    row.ref.key = {first_key + k, 0, 0};
    row.ref.scan_id = scan_id;
    row.ref.bounds.min = {10.0 * (first_key + k), 0, 0};
    row.ref.bounds.max = {10.0 * (first_key + k) + 1, 1, 1};
    row.ref.input_points = row.ref.decoded_points = 10;
    row.blob.resize(size);
    for (auto& b : row.blob) b = static_cast<std::uint8_t>(rng());
    out.push_back(std::move(row));
  }
  return out;
}

// Writes one complete scan of `count` rows.
void add_scan(Archive& a, int count, int first_key) {
  auto scan = a.begin_scan({});
  REQUIRE(scan.is_ok());
  std::vector<ChunkRow> r = rows(*scan, count, 40000, first_key);
  REQUIRE(a.put_chunks(r).is_ok());
  REQUIRE(a.finish_scan(*scan, false, false, "").is_ok());
}

}  // namespace

TEST_CASE("Archive::close reports a write-ahead log it cannot fold in, and the archive stays intact",
          "[store][full-disk]") {
  test::LimitedVfs vfs;
  REQUIRE(vfs.ok());
  test::TempDir tmp;
  const std::string path = tmp.file("a.relief");
  {
    auto created = Archive::create(path, grid(), "", "test");
    REQUIRE(created.is_ok());
    add_scan(**created, 4, 0);
    REQUIRE((*created)->close().is_ok());
    CHECK_FALSE(fs::exists(path + "-wal"));
    CHECK((*created)->close().is_ok());  // twice: nothing to do
  }
  const std::uintmax_t size = fs::file_size(path);
  auto archive = Archive::open(path, Archive::Mode::kReadWrite);
  REQUIRE(archive.is_ok());
  // The disk fills up: the next scan's pages reach the log, not the file.
  vfs.limit_main_files(static_cast<std::int64_t>(size));
  add_scan(**archive, 6, 100);
  const Status closed = (*archive)->close();
  INFO(closed.to_string());
  CHECK(closed.code() == StatusCode::kIoError);
  CHECK(closed.message().find(path + ": cannot fold the write-ahead log into the archive file: ") == 0);
  CHECK(closed.message().find("full") != std::string::npos);
  archive->reset();
  CHECK(fs::exists(path + "-wal"));
  CHECK(fs::file_size(path) == size);
  // Every committed row is there, read through the log.
  vfs.limit_main_files(-1);
  {
    auto reader = Archive::open(path, Archive::Mode::kReadOnly);
    REQUIRE(reader.is_ok());
    auto info = (*reader)->info();
    REQUIRE(info.is_ok());
    CHECK(info->chunk_count == 10);
    CHECK(info->scans.size() == 2);
  }
  // With room again, a writer's close folds the log in: one file.
  auto writer = Archive::open(path, Archive::Mode::kReadWrite);
  REQUIRE(writer.is_ok());
  REQUIRE((*writer)->close().is_ok());
  writer->reset();
  CHECK_FALSE(fs::exists(path + "-wal"));
  CHECK(fs::file_size(path) > size);
  auto reader = Archive::open(path, Archive::Mode::kReadOnly);
  REQUIRE(reader.is_ok());
  CHECK((*reader)->info()->chunk_count == 10);
  CHECK((*reader)->close().is_ok());  // read-only: nothing to do
}

}  // namespace relief
