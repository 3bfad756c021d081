// libFuzzer target: opening an archive read-only and querying it. SQLite
// reads a file, so each input is written to one temporary file per process
// (rewritten for each input, removed after it) and the archive is either opened,
// listed, queried through the spatial index and its chunks and pyramid nodes
// read and decoded, or queried through ArchiveReader::query, and again at a
// coarse level of detail when it lists a pyramid (the input's size picks which). SQLite's side files (-wal, -shm,
// -journal) are removed after every input so one input cannot affect the next.
#include <fcntl.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "relief/archive.h"
#include "relief/codec.h"
#include "relief/query.h"

namespace {

// Chunks read and decoded per input: enough to reach every code path, few
// enough that an archive listing thousands of rows stays fast.
constexpr std::size_t kMaxChunksRead = 8;
constexpr std::uint64_t kMaxPoints = 1 << 16;

const std::string& temp_path() {
  static const std::string path = [] {
    const char* dir = std::getenv("TMPDIR");
    std::string p = std::string(dir != nullptr && *dir != '\0' ? dir : "/tmp") + "/relief-fuzz-archive-" +
                    std::to_string(::getpid()) + ".rla";
    return p;
  }();
  return path;
}

void remove_side_files(const std::string& path) {
  for (const char* suffix : {"-wal", "-shm", "-journal"}) std::remove((path + suffix).c_str());
}

bool write_file(const std::string& path, const std::uint8_t* data, std::size_t size) {
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0600);
  if (fd < 0) return false;
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, data + done, size - done);
    if (n <= 0) break;
    done += static_cast<std::size_t>(n);
  }
  ::close(fd);
  return done == size;
}

void exercise_archive(const std::string& path) {
  auto archive = relief::Archive::open(path, relief::Archive::Mode::kReadOnly);
  if (!archive.is_ok()) return;
  auto info = (*archive)->info();
  relief::Box3d box;
  if (info.is_ok() && !info->bounds.empty()) {
    box = info->bounds;
  } else {
    box.min = {-1e6, -1e6, -1e6};
    box.max = {1e6, 1e6, 1e6};
  }
  // Where the bytes go: every blob's section table; when it answers, every
  // blob byte is a section's or the framing's.
  if (auto parts = relief::archive_sections(**archive); parts.is_ok()) {
    std::uint64_t sum = parts->framing_bytes;
    for (const relief::SectionTotal& t : parts->sections) sum += t.bytes;
    if (sum != parts->blob_bytes) std::abort();
  }
  auto refs = (*archive)->find_chunks(box);
  if (!refs.is_ok()) refs = (*archive)->all_chunks();
  if (!refs.is_ok()) return;
  relief::DecodeOptions options;
  options.max_points = kMaxPoints;
  std::size_t read = 0;
  for (const relief::ChunkRef& ref : *refs) {
    if (read++ == kMaxChunksRead) break;
    auto row = (*archive)->read_chunk(ref.id);
    if (!row.is_ok()) continue;
    (void)relief::decode_chunk(row->blob, options);
  }
  // The pyramid's nodes (archive.md §9), of the levels the info lists.
  if (!info.is_ok()) return;
  read = 0;
  for (const relief::ScanPyramid& scan : info->pyramid) {
    for (const relief::PyramidLevel& level : scan.levels) {
      auto nodes = (*archive)->find_level_chunks(level.level, box);
      if (!nodes.is_ok()) continue;
      for (const relief::ChunkRef& ref : *nodes) {
        if (read++ == kMaxChunksRead) return;
        auto row = (*archive)->read_level_chunk(ref.id);
        if (!row.is_ok()) continue;
        (void)relief::decode_chunk(row->blob, options);
      }
    }
  }
}

void exercise_query(const std::string& path, bool skip_corrupt) {
  auto reader = relief::ArchiveReader::open(path);
  if (!reader.is_ok()) return;
  relief::QueryOptions options;
  options.threads = 1;
  options.skip_corrupt = skip_corrupt;
  options.on_warning = [](const std::string&) {};
  const relief::Box3d& bounds = (*reader)->info().bounds;
  relief::Box3d box = bounds;
  if (bounds.empty()) {
    box.min = {-1e6, -1e6, -1e6};
    box.max = {1e6, 1e6, 1e6};
  }
  const auto ignore = [](const relief::PointCloud&) { return relief::Status::ok(); };
  (void)(*reader)->query(box, options, ignore);
  // Some attributes alone (QueryOptions::attributes: the chunks skip the
  // others' sections) and statistics of what is decoded.
  const relief::ArchiveInfo& info = (*reader)->info();
  options.attributes = {false, info.has_intensity, info.las_attributes & (relief::kLasClassification | relief::kLasGpsTime)};
  (void)relief::archive_stats(**reader, &box, options);
  options.attributes = relief::AttributeSet::all();
  // With a pyramid listed: a coarse level of detail and a point limit, which
  // read its nodes.
  bool pyramid = false;
  for (const relief::ScanPyramid& scan : (*reader)->info().pyramid) pyramid = pyramid || !scan.levels.empty();
  if (!pyramid) return;
  options.lod = 16;
  (void)(*reader)->query(box, options, ignore);
  options.lod = 1;
  options.max_points = 64;
  (void)(*reader)->query(box, options, ignore);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string& path = temp_path();
  remove_side_files(path);
  if (!write_file(path, data, size)) std::abort();  // the fuzzer's own disk problem, not a finding
  // One entry path per input, picked by its size, so each execution opens
  // SQLite once: the low-level Archive calls, or ArchiveReader::query with
  // or without skip_corrupt. (Opening every input twice halved the rate.)
  switch (size % 3) {
    case 0: exercise_archive(path); break;
    case 1: exercise_query(path, true); break;
    default: exercise_query(path, false); break;
  }
  // Nothing is left behind: a replay or a fuzzer run ends with no files.
  remove_side_files(path);
  std::remove(path.c_str());
  return 0;
}
