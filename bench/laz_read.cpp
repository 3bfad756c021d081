// bench/laz_read: time to read each shared LAZ file against its LAS twin
// through the public reader (open_point_reader, batches of 2^20 points, the
// way the ingest reads), median of --repeat runs. Prints CSV with wall and
// process CPU seconds: on a shared machine the CPU time is the steadier one.
// Then the LAS twin's points written back as LAZ (open_point_writer) with
// one compressing thread and with every core (WriterOptions::threads): wall
// seconds, median of --repeat.
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "relief/io.h"
#include "relief/types.h"

namespace {

constexpr std::size_t kBatch = std::size_t{1} << 20;

struct Pair {
  const char* name;
  const char* laz;
  const char* las;
};

double cpu_seconds() {
  timespec ts{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

struct Timing {
  double wall = 0;
  double cpu = 0;
};

// Seconds to read every point, or a negative wall time (after a message) on error.
Timing time_read(const std::string& path, std::uint64_t& points, bool positions_only) {
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = cpu_seconds();
  relief::ReaderOptions options;
  options.positions_only = positions_only;
  auto reader = relief::open_point_reader(path, options);
  if (!reader.is_ok()) {
    std::fprintf(stderr, "%s\n", reader.status().to_string().c_str());
    return {-1, -1};
  }
  relief::PointCloud batch;
  points = 0;
  for (;;) {
    auto n = (*reader)->read(batch, kBatch);
    if (!n.is_ok()) {
      std::fprintf(stderr, "%s\n", n.status().to_string().c_str());
      return {-1, -1};
    }
    if (*n == 0) break;
    points += *n;
  }
  return {std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), cpu_seconds() - c0};
}

Timing median_read(const std::string& path, int repeat, std::uint64_t& points, bool positions_only = false) {
  std::vector<double> wall, cpu;
  for (int i = 0; i < repeat; ++i) {
    const Timing t = time_read(path, points, positions_only);
    if (t.wall < 0) return t;
    wall.push_back(t.wall);
    cpu.push_back(t.cpu);
  }
  std::sort(wall.begin(), wall.end());
  std::sort(cpu.begin(), cpu.end());
  return {wall[wall.size() / 2], cpu[cpu.size() / 2]};
}

// Wall seconds to write `cloud` as LAZ to `out` with `threads`, or < 0.
double time_write(const relief::PointCloud& cloud, const relief::PointStreamInfo& info, const std::string& out,
                  unsigned threads) {
  relief::WriterOptions w;
  w.colors = cloud.has_colors();
  w.intensity = cloud.has_intensity();
  w.las_attributes = cloud.las.carried();
  w.extra_bytes_size = cloud.las.extra_bytes_size;
  w.extra_bytes_vlr = info.extra_bytes_vlr;
  w.las_point_format = info.las_point_format;
  w.las_version_minor = info.las_version_minor;
  w.threads = threads;
  const auto t0 = std::chrono::steady_clock::now();
  auto writer = relief::open_point_writer(out, w);
  if (!writer.is_ok() || !(*writer)->write(cloud).is_ok() || !(*writer)->finish().is_ok()) {
    std::fprintf(stderr, "%s: the LAZ write failed\n", out.c_str());
    return -1;
  }
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

double median_write(const std::string& las, const std::string& out, int repeat, unsigned threads) {
  auto cloud = relief::read_point_file(las);
  auto reader = relief::open_point_reader(las);
  if (!cloud.is_ok() || !reader.is_ok()) return -1;
  std::vector<double> wall;
  for (int i = 0; i < repeat; ++i) {
    const double t = time_write(*cloud, (*reader)->info(), out, threads);
    std::filesystem::remove(out);
    if (t < 0) return t;
    wall.push_back(t);
  }
  std::sort(wall.begin(), wall.end());
  return wall[wall.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  relief::retain_freed_memory();  // as the relief CLI does (relief/types.h)
  int repeat = 5;
  std::string data = RELIEF_BENCH_DATA_DIR;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeat" && i + 1 < argc) {
      repeat = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--data" && i + 1 < argc) {
      data = argv[++i];
    } else {
      std::fprintf(stderr, "usage: laz_read [--repeat N] [--data DIR (default ../shared/data)]\n");
      return 2;
    }
  }
  const Pair pairs[] = {
      {"simple", "laz/simple.laz", "laz/simple.las"},
      {"autzen_trim", "laz/autzen_trim.laz", "laz/autzen_trim.las"},
      {"1.2-with-color.copc", "laz/1.2-with-color.copc.laz", "laz/1.2-with-color.copc.las"},
      {"fr_aerial_rgb_698k", "laz/fr_aerial_rgb_698k.laz", "medium/orig/fr_aerial_rgb_698k.las"},
      {"lone_star_tls_519k", "laz/lone_star_tls_519k.laz", "medium/orig/lone_star_tls_519k.las"},
  };
  std::printf("# median of %d runs, batches of %zu points; LAZ chunks decode on up to %u threads\n", repeat, kBatch,
              std::max(1u, std::min(4u, std::thread::hardware_concurrency())));
  std::printf("file,points,laz_bytes,las_bytes,laz_wall_s,laz_wall_mpts_s,laz_cpu_s,laz_cpu_mpts_s,las_wall_s,"
              "las_cpu_s,las_cpu_mpts_s,laz_over_las_cpu,laz_xyz_cpu_s,laz_xyz_cpu_mpts_s,write_laz_1_thread_s,"
              "write_laz_s\n");
  int status = 0;
  for (const Pair& p : pairs) {
    const std::string laz = data + "/" + p.laz;
    const std::string las = data + "/" + p.las;
    if (!std::filesystem::exists(laz) || !std::filesystem::exists(las)) {
      std::printf("# %s: skipped (%s or its twin is absent)\n", p.name, laz.c_str());
      continue;
    }
    std::uint64_t n_laz = 0, n_las = 0;
    const Timing t_laz = median_read(laz, repeat, n_laz);
    const Timing t_las = median_read(las, repeat, n_las);
    std::uint64_t n_xyz = 0;
    const Timing t_xyz = median_read(laz, repeat, n_xyz, /*positions_only=*/true);
    if (t_laz.wall < 0 || t_las.wall < 0 || t_xyz.wall < 0 || n_laz != n_las || n_xyz != n_laz) {
      std::printf("# %s: failed\n", p.name);
      status = 1;
      continue;
    }
    const auto n = static_cast<double>(n_laz);
    const std::string out = (std::filesystem::temp_directory_path() / "relief-bench-laz-write.laz").string();
    const double w1 = median_write(las, out, repeat, 1);
    const double wn = median_write(las, out, repeat, 0);
    if (w1 < 0 || wn < 0) {
      std::printf("# %s: failed\n", p.name);
      status = 1;
      continue;
    }
    std::printf("%s,%llu,%llu,%llu,%.4f,%.2f,%.4f,%.2f,%.4f,%.4f,%.2f,%.1f,%.4f,%.2f,%.4f,%.4f\n", p.name,
                static_cast<unsigned long long>(n_laz),
                static_cast<unsigned long long>(std::filesystem::file_size(laz)),
                static_cast<unsigned long long>(std::filesystem::file_size(las)), t_laz.wall, n / t_laz.wall / 1e6, t_laz.cpu,
                n / t_laz.cpu / 1e6, t_las.wall, t_las.cpu, n / t_las.cpu / 1e6, t_laz.cpu / t_las.cpu, t_xyz.cpu,
                n / t_xyz.cpu / 1e6, w1, wn);
  }
  return status;
}
