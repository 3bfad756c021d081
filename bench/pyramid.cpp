// bench/pyramid: what the level-of-detail pyramid buys on existing archives.
// For each archive: its size and its pyramid's share; a whole-archive preview
// read (a point budget of 2 per pixel of a 1024 x 1024 image, as `relief
// preview` asks for) from the pyramid against the same preview from the
// chunks alone (lod 16, the default of archives without a pyramid); and a
// box of 1 % of the area (centred) at lod 16 against lod 1. Time is the
// median of --repeat runs of the whole query (decode included, no drawing);
// bytes are blob bytes read. Prints CSV.
//
//   build/bench/pyramid [--repeat N] [--threads N] [--build] ARCHIVE...
//
// --build first builds the pyramid of every scan that lacks one (and prints
// the time), so archives made without one can be measured too.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "median.h"
#include "relief/archive.h"
#include "relief/ingest.h"
#include "relief/query.h"
#include "relief/types.h"

namespace {

using relief::bench::median;

using namespace relief;

struct Measure {
  double seconds = 0;
  std::uint64_t bytes = 0;
  std::uint64_t points = 0;
  int level = 0;
};

Measure measure(const std::string& path, const Box3d* box, const QueryOptions& o, int repeat) {
  std::vector<double> times;
  Measure m;
  for (int r = 0; r < repeat; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    auto reader = ArchiveReader::open(path);
    if (!reader) {
      std::fprintf(stderr, "%s\n", reader.status().message().c_str());
      std::exit(1);
    }
    const PointSink sink = [](const PointCloud&) { return Status::ok(); };
    auto stats = box ? (*reader)->query(*box, o, sink) : (*reader)->query_all(o, sink);
    if (!stats) {
      std::fprintf(stderr, "%s\n", stats.status().message().c_str());
      std::exit(1);
    }
    times.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    m.bytes = stats->blob_bytes_read;
    m.points = stats->points;
    m.level = stats->pyramid_level;
  }
  m.seconds = median(times);
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  relief::retain_freed_memory();  // as the relief CLI does (relief/types.h)
  int repeat = 3;
  unsigned threads = 0;
  bool build = false;
  std::vector<std::string> archives;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeat" && i + 1 < argc) {
      repeat = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--threads" && i + 1 < argc) {
      threads = static_cast<unsigned>(std::max(0, std::atoi(argv[++i])));
    } else if (a == "--build") {
      build = true;
    } else if (!a.empty() && a[0] != '-') {
      archives.push_back(a);
    } else {
      std::fprintf(stderr, "usage: pyramid [--repeat N] [--threads N] [--build] ARCHIVE...\n");
      return a == "--help" ? 0 : 2;
    }
  }
  if (archives.empty()) {
    std::fprintf(stderr, "pyramid: give at least one archive\n");
    return 2;
  }
  constexpr std::uint64_t kPreviewPoints = 2ull * 1024 * 1024;
  std::printf("archive,points,file_bytes,pyramid_bytes,pyramid_pct,levels,"
              "preview_s,preview_bytes,preview_pct_of_archive,preview_points,preview_level,"
              "chunks_lod16_s,chunks_lod16_bytes,chunks_lod16_points,speedup,"
              "box1pct_lod16_bytes,box1pct_lod1_bytes,box_ratio_pct,box1pct_lod16_s,box1pct_lod1_s\n");
  for (const std::string& path : archives) {
    if (build) {
      auto archive = Archive::open(path, Archive::Mode::kReadWrite);
      if (!archive) {
        std::fprintf(stderr, "%s\n", archive.status().message().c_str());
        return 1;
      }
      auto info = (*archive)->info();
      if (!info) return 1;
      for (const ScanPyramid& scan : info->pyramid) {
        if (!scan.levels.empty()) continue;
        PyramidOptions po;
        po.threads = threads;
        auto r = build_pyramid(**archive, scan.scan_id, po);
        if (!r) {
          std::fprintf(stderr, "%s\n", r.status().message().c_str());
          return 1;
        }
        std::printf("# built the pyramid of scan %lld: %d levels, %llu nodes, %.2f s\n",
                    static_cast<long long>(scan.scan_id), r->levels, static_cast<unsigned long long>(r->chunks),
                    r->seconds);
      }
    }
    auto reader = ArchiveReader::open(path);
    if (!reader) {
      std::fprintf(stderr, "%s\n", reader.status().message().c_str());
      return 1;
    }
    const ArchiveInfo info = (*reader)->info();
    reader->reset();
    int levels = 0;
    for (const ScanPyramid& s : info.pyramid) levels = std::max(levels, static_cast<int>(s.levels.size()));

    QueryOptions preview;
    preview.threads = threads;
    preview.max_points = kPreviewPoints;
    const Measure p = measure(path, nullptr, preview, repeat);
    QueryOptions chunks;
    chunks.threads = threads;
    chunks.lod = 16;
    chunks.use_pyramid = false;
    const Measure c = measure(path, nullptr, chunks, repeat);

    // 1 % of the x-y area, centred.
    const Box3d& b = info.bounds;
    const double cx = 0.5 * (b.min.x + b.max.x), cy = 0.5 * (b.min.y + b.max.y);
    const double hx = 0.05 * (b.max.x - b.min.x), hy = 0.05 * (b.max.y - b.min.y);
    const Box3d box = box_2d(cx - hx, cy - hy, cx + hx, cy + hy);
    QueryOptions lod16;
    lod16.threads = threads;
    lod16.lod = 16;
    const Measure q16 = measure(path, &box, lod16, repeat);
    QueryOptions lod1;
    lod1.threads = threads;
    const Measure q1 = measure(path, &box, lod1, repeat);

    const auto pct = [](std::uint64_t part, std::uint64_t whole) {
      return whole > 0 ? 100.0 * static_cast<double>(part) / static_cast<double>(whole) : 0.0;
    };
    std::printf("%s,%llu,%llu,%llu,%.2f,%d,%.3f,%llu,%.3f,%llu,%d,%.3f,%llu,%llu,%.1f,%llu,%llu,%.2f,%.3f,%.3f\n",
                path.c_str(), static_cast<unsigned long long>(info.decoded_points),
                static_cast<unsigned long long>(info.file_bytes), static_cast<unsigned long long>(info.pyramid_bytes),
                pct(info.pyramid_bytes, info.blob_bytes), levels, p.seconds,
                static_cast<unsigned long long>(p.bytes), pct(p.bytes, info.file_bytes),
                static_cast<unsigned long long>(p.points), p.level, c.seconds,
                static_cast<unsigned long long>(c.bytes), static_cast<unsigned long long>(c.points),
                p.seconds > 0 ? c.seconds / p.seconds : 0.0, static_cast<unsigned long long>(q16.bytes),
                static_cast<unsigned long long>(q1.bytes), pct(q16.bytes, q1.bytes), q16.seconds, q1.seconds);
    std::fflush(stdout);
  }
  return 0;
}
