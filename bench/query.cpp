// bench/query: latency and bytes read of box queries at several levels of
// detail, full decompression speed, and the time of an lod-16 preview of a
// ~10 M-point archive. Prints CSV.
//
//   build/bench/query [--data DIR] [--tmp DIR] [--repeat N] [--chunk-edge M]
//   build/bench/query --decode ARCHIVE [--repeat N] [--threads N]
//
// --decode: a whole-archive decode of an existing archive (e.g. the survey
// `bench/ingest --billion --keep DIR` leaves) through the library, with every
// attribute, x y z alone, the classification, GPS times, and colours
// (QueryOptions::attributes), the five alternated; median seconds and
// M points/s.
//
// Boxes are 2D (all heights) covering 0.1 %, 1 %, 10 % and 100 % of the
// scene's x-y bounding-box area, at 9 positions each (a 3 x 3 grid over the
// area the box can slide in); latency is the median, bytes read the mean.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "median.h"
#include "run_child.h"
#include "relief/ingest.h"
#include "relief/io.h"
#include "relief/polygon.h"
#include "relief/query.h"
#include "relief/types.h"

namespace fs = std::filesystem;

namespace {

using relief::bench::median;

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void remove_archive(const std::string& p) {
  for (const char* s : {"", "-wal", "-shm"}) fs::remove(p + s);
}

// A star of 256 vertices inscribed in the x-y rectangle of `box` (radius
// between 0.6 and 1 of the half side, 9 points), as WKT would give it.
relief::Polygon2D star_in(const relief::Box3d& box) {
  const double cx = 0.5 * (box.min.x + box.max.x), cy = 0.5 * (box.min.y + box.max.y);
  const double rx = 0.5 * (box.max.x - box.min.x), ry = 0.5 * (box.max.y - box.min.y);
  std::string wkt = "POLYGON ((";
  char v[64];
  for (int i = 0; i <= 256; ++i) {
    const double a = 2 * M_PI * (i % 256) / 256.0;
    const double r = 0.8 + 0.2 * std::cos(9 * a);
    std::snprintf(v, sizeof v, "%s%.6f %.6f", i ? ", " : "", cx + r * rx * std::cos(a), cy + r * ry * std::sin(a));
    wkt += v;
  }
  wkt += "))";
  return *relief::Polygon2D::from_wkt(wkt, "star");
}

int decode_subsets(const std::string& path, int repeat, unsigned threads, const std::string& only) {
  auto reader = relief::ArchiveReader::open(path);
  if (!reader) {
    std::fprintf(stderr, "%s\n", reader.status().to_string().c_str());
    return 1;
  }
  const relief::ArchiveInfo& info = (*reader)->info();
  struct Run {
    const char* name;
    relief::AttributeSet attributes;
    std::vector<double> times;
    std::uint64_t points = 0;
  };
  std::vector<Run> runs = {{"all", relief::AttributeSet::all(), {}},
                           {"none", relief::AttributeSet::none(), {}},
                           {"classification", {false, false, relief::kLasClassification}, {}},
                           {"gps_time", {false, false, relief::kLasGpsTime}, {}},
                           {"rgb", {true, false, 0}, {}}};
  if (!only.empty()) {
    std::erase_if(runs, [&](const Run& r) { return r.name != only; });
    if (runs.empty()) {
      std::fprintf(stderr, "--only: no subset '%s' (all, none, classification, gps_time, rgb)\n", only.c_str());
      return 2;
    }
  }
  std::printf("# %s: %llu points, %llu chunks, attributes %s; %u decoder threads, median of %d\n", path.c_str(),
              static_cast<unsigned long long>(info.decoded_points), static_cast<unsigned long long>(info.chunk_count),
              relief::attribute_set_list({info.has_colors, info.has_intensity, info.las_attributes}).c_str(), threads,
              repeat);
  std::printf("attributes,median_s,points,mpts_s,vs_all\n");
  for (int k = 0; k < repeat; ++k) {
    for (Run& r : runs) {
      if (!relief::check_attributes(info, r.attributes, path)) continue;  // the archive lacks it
      relief::QueryOptions q;
      q.threads = threads;
      q.attributes = r.attributes;
      const auto t0 = std::chrono::steady_clock::now();
      auto s = (*reader)->query_all(q, [](const relief::PointCloud&) { return relief::Status::ok(); });
      if (!s) {
        std::fprintf(stderr, "%s\n", s.status().to_string().c_str());
        return 1;
      }
      r.times.push_back(seconds_since(t0));
      r.points = s->points;
    }
  }
  const double all = median(runs[0].times);  // the first run's (all, unless --only)
  for (const Run& r : runs) {
    if (r.times.empty()) continue;
    const double t = median(r.times);
    std::printf("%s,%.3f,%llu,%.2f,%.2f\n", r.name, t, static_cast<unsigned long long>(r.points),
                static_cast<double>(r.points) / t * 1e-6, all / t);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  relief::retain_freed_memory();  // as the relief CLI does (relief/types.h)
  std::string data = RELIEF_BENCH_DATA_DIR;
  std::string tmp = "/tmp";
  std::string cli = RELIEF_BENCH_CLI;
  int repeat = 3;
  double chunk_edge = 24.0;  // 4 cells of the aerial tile's ~6 m default cell
  std::string decode;
  std::string only;  // --decode: one subset
  unsigned threads = 2;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> const char* { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--data") {
      data = value();
    } else if (a == "--tmp") {
      tmp = value();
    } else if (a == "--repeat") {
      repeat = std::max(1, std::atoi(value()));
    } else if (a == "--chunk-edge") {
      chunk_edge = std::atof(value());
    } else if (a == "--decode") {
      decode = value();
    } else if (a == "--only") {
      only = value();
    } else if (a == "--threads") {
      threads = static_cast<unsigned>(std::max(1, std::atoi(value())));
    } else {
      std::fprintf(stderr,
                   "usage: query [--data DIR] [--tmp DIR] [--repeat N] [--chunk-edge M]\n"
                   "       query --decode ARCHIVE [--repeat N] [--threads N] [--only all|none|classification|gps_time|rgb]\n");
      return a == "--help" ? 0 : 2;
    }
  }
  if (!decode.empty()) return decode_subsets(decode, repeat, threads, only);
  const std::string input = data + "/medium/fr_aerial_rgb_698k.ply";
  if (!fs::exists(input)) {
    std::printf("# skipped: %s absent\n", input.c_str());
    return 0;
  }
  // ---- The largest shared file, in chunks small enough for local queries.
  const std::string archive = tmp + "/relief-bench-query.relief";
  remove_archive(archive);
  relief::IngestOptions o;
  o.chunk_edge = chunk_edge;
  auto made = relief::compress_files({input}, archive, o);
  if (!made) {
    std::fprintf(stderr, "error: %s\n", made.status().to_string().c_str());
    return 1;
  }
  auto reader = relief::ArchiveReader::open(archive);
  if (!reader) return 1;
  const relief::ArchiveInfo& info = (*reader)->info();
  const relief::Box3d b = info.bounds;
  std::printf("# archive: %s, %llu points in, %llu decodable, %llu chunks (edge %.0f m), %llu blob bytes, %.3f bpp\n",
              input.c_str(), static_cast<unsigned long long>(info.input_points),
              static_cast<unsigned long long>(info.decoded_points), static_cast<unsigned long long>(info.chunk_count),
              chunk_edge, static_cast<unsigned long long>(info.blob_bytes),
              8.0 * static_cast<double>(info.blob_bytes) / static_cast<double>(info.input_points));
  std::printf("kind,box_area_pct,lod,median_ms,points,chunks_read,bytes_read_pct\n");
  const double w = b.max.x - b.min.x, h = b.max.y - b.min.y;
  for (double pct : {0.1, 1.0, 10.0, 100.0}) {
    const double side = std::sqrt(pct / 100.0);
    for (std::uint32_t lod : {1u, 4u, 16u}) {
      // Per query kind (the box; at lod 1 also its inscribed star): the
      // boxes' median times and their summed figures.
      struct Row {
        std::vector<double> ms;
        double bytes = 0, points = 0, chunks = 0;
        void time(relief::ArchiveReader& reader, const relief::Box3d& box, const relief::QueryOptions& q, int repeat) {
          std::vector<double> times;
          relief::QueryStats last;
          for (int k = 0; k < repeat; ++k) {
            const auto t0 = std::chrono::steady_clock::now();
            auto s = reader.query(box, q, [](const relief::PointCloud&) { return relief::Status::ok(); });
            times.push_back(seconds_since(t0) * 1e3);
            if (s) last = *s;
          }
          ms.push_back(median(times));
          bytes += static_cast<double>(last.blob_bytes_read);
          points += static_cast<double>(last.points);
          chunks += static_cast<double>(last.chunks_decoded);
        }
      } box_row, polygon_row;
      int boxes = 0;
      for (int gy = 0; gy < 3; ++gy) {
        for (int gx = 0; gx < 3; ++gx) {
          const double x0 = b.min.x + (1 - side) * w * (0.1 + 0.4 * gx);
          const double y0 = b.min.y + (1 - side) * h * (0.1 + 0.4 * gy);
          const relief::Box3d box = relief::box_2d(x0, y0, x0 + side * w, y0 + side * h);
          relief::QueryOptions q;
          q.lod = lod;
          q.threads = 2;
          box_row.time(**reader, box, q, repeat);
          ++boxes;
          if (lod != 1) continue;
          // The same box's inscribed 256-vertex star (QueryOptions::polygon):
          // the chunks outside it unread, those it crosses tested point by point.
          q.polygon = std::make_shared<const relief::Polygon2D>(star_in(box));
          polygon_row.time(**reader, box, q, repeat);
        }
      }
      for (const auto& [kind, row] : {std::pair<const char*, const Row*>{"box", &box_row}, {"polygon", &polygon_row}}) {
        if (row->ms.empty()) continue;
        std::printf("%s,%.1f,%u,%.2f,%.0f,%.1f,%.2f\n", kind, pct, lod, median(row->ms), row->points / boxes,
                    row->chunks / boxes, 100.0 * row->bytes / boxes / static_cast<double>(info.blob_bytes));
      }
      std::fflush(stdout);
    }
  }
  // ---- A ~10 M-point archive: 15 shifted copies of the tile side by side.
  const std::string big = tmp + "/relief-bench-query-10m.relief";
  remove_archive(big);
  std::vector<std::string> copies;
  {
    auto cloud = relief::read_ply(input);
    if (!cloud) return 1;
    for (int k = 0; k < 15; ++k) {
      relief::PointCloud c = *cloud;
      for (relief::Vec3d& p : c.positions) {
        p.x += (k % 5) * 400.0;
        p.y += (k / 5) * 400.0;
      }
      copies.push_back(tmp + "/relief-bench-copy-" + std::to_string(k) + ".ply");
      if (!relief::write_ply(copies.back(), c)) return 1;
    }
  }
  relief::IngestOptions bo;
  auto made_big = relief::compress_files(copies, big, bo);
  for (const std::string& c : copies) fs::remove(c);
  if (!made_big) {
    std::fprintf(stderr, "error: %s\n", made_big.status().to_string().c_str());
    return 1;
  }
  auto big_reader = relief::ArchiveReader::open(big);
  if (!big_reader) return 1;
  std::printf("# 10M archive: %llu points in, %llu decodable, %llu chunks\n",
              static_cast<unsigned long long>((*big_reader)->info().input_points),
              static_cast<unsigned long long>((*big_reader)->info().decoded_points),
              static_cast<unsigned long long>((*big_reader)->info().chunk_count));
  std::printf("kind,archive,threads,median_s,points,mpts_s\n");
  // Every attribute, then x y z alone (QueryOptions::attributes: the colour
  // sections are not decoded), alternated so that drift slows both alike.
  struct Run {
    const char* kind;
    unsigned threads;
    relief::AttributeSet attributes;
    std::vector<double> times;
    std::uint64_t points = 0;
  };
  std::vector<Run> runs = {{"decompress_library", 1, relief::AttributeSet::all(), {}},
                           {"decompress_library", 2, relief::AttributeSet::all(), {}},
                           {"decompress_library_xyz_only", 2, relief::AttributeSet::none(), {}}};
  for (int k = 0; k < repeat; ++k) {
    for (Run& r : runs) {
      relief::QueryOptions q;
      q.threads = r.threads;
      q.attributes = r.attributes;
      const auto t0 = std::chrono::steady_clock::now();
      auto s = (*big_reader)->query_all(q, [](const relief::PointCloud&) { return relief::Status::ok(); });
      r.times.push_back(seconds_since(t0));
      if (s) r.points = s->points;
    }
  }
  for (const Run& r : runs) {
    std::printf("%s,10M,%u,%.3f,%llu,%.2f\n", r.kind, r.threads, median(r.times),
                static_cast<unsigned long long>(r.points), static_cast<double>(r.points) / median(r.times) * 1e-6);
  }
  {
    std::vector<double> times;
    const std::string out = tmp + "/relief-bench-decompressed.ply";
    for (int k = 0; k < repeat; ++k) {
      times.push_back(relief::bench::run_child({cli, "decompress", big, "-o", out, "--threads", "2", "--quiet"}).seconds);
    }
    const auto points = (*big_reader)->info().decoded_points;
    std::printf("decompress_cli_to_ply,10M,2,%.3f,%llu,%.2f\n", median(times),
                static_cast<unsigned long long>(points), static_cast<double>(points) / median(times) * 1e-6);
    fs::remove(out);
  }
  {
    std::vector<double> times;
    const std::string png = tmp + "/relief-bench-preview.png";
    for (int k = 0; k < repeat; ++k) {
      times.push_back(relief::bench::run_child({cli, "preview", big, "--lod", "16", "-o", png, "--quiet"}).seconds);
    }
    std::printf("preview_lod16_png,10M,2,%.3f,,\n", median(times));
    fs::remove(png);
  }
  remove_archive(archive);
  remove_archive(big);
  return 0;
}
