#include "billion.h"
#include "disk_bytes.h"
#include "median.h"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <thread>

#include "relief/archive.h"
#include "relief/ingest.h"
#include "run_child.h"
#include "scene.h"

namespace fs = std::filesystem;

namespace relief::bench {

namespace {

constexpr std::size_t kBlockRecords = 8192;  // records per write to the pipe
// Points of the regular file the automatic grid is measured on.
constexpr std::uint64_t kCalibrationPoints = 2'000'000;

std::string count_label(std::uint64_t n) {
  if (n % 1'000'000'000 == 0) return std::to_string(n / 1'000'000'000) + "G";
  if (n % 1'000'000 == 0) return std::to_string(n / 1'000'000) + "M";
  return std::to_string(n);
}

bool write_all(int fd, const unsigned char* p, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd, p, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return false;
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return true;
}

// Writes the scene of `points` points to `fd`; returns the points written.
std::uint64_t write_scene(int fd, std::uint64_t points, std::uint64_t seed) {
  AerialScene scene(points, seed);
  const std::vector<unsigned char> header = scene.header();
  if (!write_all(fd, header.data(), header.size())) return 0;
  std::vector<unsigned char> buf(kBlockRecords * AerialScene::kRecordBytes);
  std::uint64_t total = 0;
  for (;;) {
    const std::size_t got = scene.next(buf.data(), kBlockRecords);
    if (got == 0) break;
    if (!write_all(fd, buf.data(), got * AerialScene::kRecordBytes)) break;
    total += got;
  }
  return total;
}

void remove_archive(const std::string& path) {
  for (const char* s : {"", "-wal", "-shm", "-journal"}) fs::remove(path + s);
}

struct Run {
  bool ok = false;
  double seconds = 0;
  double cpu_seconds = 0;
  long rss_kib = 0;
  std::uint64_t disk_peak = 0;
  std::uint64_t archive_bytes = 0;
  std::uint64_t chunks = 0;
};

// One `relief compress` of the generated scene read from a named pipe: this
// process generates and writes, the child reads; the child's wall time and
// peak RSS, and the peak of the work directory's disk use while it runs.
Run run_once(const BillionOptions& o, const std::string& work, std::uint64_t points,
             const std::vector<std::string>& grid_args) {
  Run run;
  const std::string fifo = work + "/scene-" + count_label(points) + ".las";
  const std::string out = work + "/scene.relief";
  remove_archive(out);
  fs::remove(fifo);
  if (::mkfifo(fifo.c_str(), 0600) != 0) {
    std::fprintf(stderr, "error: mkfifo %s: %s\n", fifo.c_str(), std::strerror(errno));
    return run;
  }
  std::atomic<bool> stop{false};
  std::uint64_t written = 0;
  std::thread writer([&] {
    // Non-blocking open, retried: a child that fails before opening the
    // pipe must not leave this thread stuck. O_CLOEXEC: the child must hold
    // no write end, or it would never see the end of its input.
    int fd = -1;
    while (!stop.load()) {
      fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK | O_CLOEXEC);
      if (fd >= 0 || errno != ENXIO) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    if (fd < 0) return;
    ::fcntl(fd, F_SETFL, ::fcntl(fd, F_GETFL) & ~O_NONBLOCK);
    ::fcntl(fd, F_SETPIPE_SZ, 1 << 20);  // fewer wake-ups; the default 64 KiB works too
    written = write_scene(fd, points, o.seed);
    ::close(fd);
  });
  std::vector<std::string> argv = {o.cli, "compress", fifo, "-o", out, "--tmp", work, "--quiet"};
  argv.insert(argv.end(), grid_args.begin(), grid_args.end());
  std::uint64_t peak = 0;
  const ChildRun r = run_child(argv, [&] { peak = std::max(peak, disk_bytes(work)); }, 0.5);
  stop.store(true);
  writer.join();
  fs::remove(fifo);
  if (r.code != 0 || written != points) {
    std::fprintf(stderr, "error: %s points: relief compress exited %d after %llu points were written\n",
                 count_label(points).c_str(), r.code, static_cast<unsigned long long>(written));
    remove_archive(out);
    return run;
  }
  bool recorded = false;
  {
    auto archive = Archive::open(out, Archive::Mode::kReadOnly);
    if (archive) {
      auto info = (*archive)->info();
      if (info && info->input_points == points) {
        recorded = true;
        run.chunks = info->chunk_count;
      }
    }
  }
  if (!recorded) {
    std::fprintf(stderr, "error: %s: the archive does not record the %llu points written\n", out.c_str(),
                 static_cast<unsigned long long>(points));
    remove_archive(out);
    return run;
  }
  run.archive_bytes = fs::file_size(out);
  peak = std::max(peak, disk_bytes(work));
  if (!o.keep.empty()) {
    // Renamed within a file system, copied across (then the original goes).
    const std::string kept = o.keep + "/scene-" + count_label(points) + ".relief";
    std::error_code ec;
    remove_archive(kept);
    fs::rename(out, kept, ec);
    if (ec) {
      ec.clear();
      fs::copy_file(out, kept, fs::copy_options::overwrite_existing, ec);
    }
    if (ec) std::fprintf(stderr, "warning: cannot keep %s as %s: %s\n", out.c_str(), kept.c_str(), ec.message().c_str());
  }
  remove_archive(out);
  run.ok = true;
  run.seconds = r.seconds;
  run.cpu_seconds = r.cpu_seconds;
  run.rss_kib = r.peak_rss_kib;
  run.disk_peak = peak;
  return run;
}

// The grid `relief compress` picks by default for this scene, measured on a
// regular file: a pipe can be read only once, and the automatic cell of the
// bounded mode comes from a pass over every input before the ingest proper.
// The chunk edge is kDefaultCellsPerChunk density cells and the base cell
// kBaseCellFactor density cells (the rule for inputs of more than ~5 M points;
// the density is the same at every size).
bool calibrate(const BillionOptions& o, const std::string& work, double* cell, double* edge) {
  const std::string path = work + "/calibration.las";
  const std::string out = work + "/calibration.relief";
  remove_archive(out);
  const int fd = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) return false;
  const bool wrote = write_scene(fd, kCalibrationPoints, o.seed) == kCalibrationPoints;
  ::close(fd);
  const ChildRun r =
      wrote ? run_child({o.cli, "compress", path, "-o", out, "--tmp", work, "--quiet"}) : ChildRun{};
  fs::remove(path);
  bool ok = false;
  if (r.code == 0) {
    auto archive = Archive::open(out, Archive::Mode::kReadOnly);
    if (archive) {
      auto info = (*archive)->info();
      if (info) {
        *edge = info->grid.chunk_edge;
        *cell = *edge * kBaseCellFactor / kDefaultCellsPerChunk;
        ok = *edge > 0;
      }
    }
  }
  remove_archive(out);
  return ok;
}

}  // namespace

std::vector<std::uint64_t> parse_point_counts(const std::string& text) {
  std::vector<std::uint64_t> v;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t comma = std::min(text.find(',', pos), text.size());
    std::string item = text.substr(pos, comma - pos);
    std::uint64_t unit = 1;
    if (!item.empty()) {
      switch (item.back()) {
        case 'K': case 'k': unit = 1'000; break;
        case 'M': case 'm': unit = 1'000'000; break;
        case 'G': case 'g': case 'B': case 'b': unit = 1'000'000'000; break;
        default: break;
      }
      if (unit != 1) item.pop_back();
    }
    if (item.empty() || item.find_first_not_of("0123456789") != std::string::npos || item.size() > 10) return {};
    const std::uint64_t n = std::stoull(item) * unit;
    // LAS 1.2's point count is 32 bits.
    if (n == 0 || n > 0xffffffffULL) return {};
    v.push_back(n);
    pos = comma + 1;
  }
  return v;
}

int run_billion(const BillionOptions& o) {
  ::signal(SIGPIPE, SIG_IGN);  // a child that stops reading must not kill the generator
  const std::string work = o.tmp + "/relief-bench-billion-" + std::to_string(::getpid());
  std::error_code ec;
  fs::create_directories(work, ec);
  if (ec) {
    std::fprintf(stderr, "error: cannot create %s: %s\n", work.c_str(), ec.message().c_str());
    return 1;
  }
  struct statvfs vfs {};
  if (::statvfs(work.c_str(), &vfs) == 0) {
    std::printf("# work directory %s: %.1f GiB free\n", work.c_str(),
                static_cast<double>(vfs.f_bavail) * static_cast<double>(vfs.f_frsize) / (1u << 30));
  }
  // The generator alone (into memory), for context: it shares the machine
  // with the ingest it feeds.
  {
    constexpr std::uint64_t kProbe = 20'000'000;
    AerialScene scene(kProbe, o.seed);
    std::vector<unsigned char> buf(kBlockRecords * AerialScene::kRecordBytes);
    const auto t0 = std::chrono::steady_clock::now();
    std::uint64_t n = 0;
    for (std::size_t got; (got = scene.next(buf.data(), kBlockRecords)) > 0;) n += got;
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("# generator alone: %.1f M points/s on one core (%llu points, %zu-byte LAS 1.2 format 3 records)\n",
                static_cast<double>(n) / s * 1e-6, static_cast<unsigned long long>(n), AerialScene::kRecordBytes);
  }
  double cell = 0, edge = 0;
  if (!calibrate(o, work, &cell, &edge)) {
    std::fprintf(stderr, "error: the calibration compress of %llu points failed\n",
                 static_cast<unsigned long long>(kCalibrationPoints));
    fs::remove_all(work, ec);
    return 1;
  }
  char cell_text[32], edge_text[32];
  std::snprintf(cell_text, sizeof cell_text, "%.17g", cell);
  std::snprintf(edge_text, sizeof edge_text, "%.17g", edge);
  std::printf("# automatic grid of the scene (from a %llu-point file): chunk edge %s m, base cell %s m; passed as "
              "--chunk-edge/--cell since a pipe is read once\n",
              static_cast<unsigned long long>(kCalibrationPoints), edge_text, cell_text);
  std::printf("# default mode (error-bounded, lossless at the LAS scale of 1 cm), default 1 GiB budget, all cores; "
              "sizes up to 10 M: median of %d runs, larger sizes: one run\n",
              o.repeat);
  std::printf("kind,points,runs,seconds,mpts_s,ns_per_point,ns_per_point_vs_first,cpu_ns_per_point,"
              "cpu_ns_per_point_vs_first,peak_rss_mib,rss_within_1gib,chunks,archive_bytes,bytes_per_point,"
              "disk_peak_mib\n");
  std::fflush(stdout);
  const std::vector<std::string> grid_args = {"--cell", cell_text, "--chunk-edge", edge_text};
  double first_ns = 0, first_cpu_ns = 0;
  int failures = 0;
  for (const std::uint64_t n : o.sizes) {
    const int runs = n <= 10'000'000 ? o.repeat : 1;
    std::vector<double> secs, cpu;
    Run last;
    long rss = 0;
    std::uint64_t disk = 0;
    for (int k = 0; k < runs; ++k) {
      std::fprintf(stderr, "compressing %s points from the pipe (run %d of %d)\n", count_label(n).c_str(), k + 1,
                   runs);
      last = run_once(o, work, n, grid_args);
      if (!last.ok) break;
      secs.push_back(last.seconds);
      cpu.push_back(last.cpu_seconds);
      rss = std::max(rss, last.rss_kib);
      disk = std::max(disk, last.disk_peak);
    }
    if (!last.ok) {
      ++failures;
      std::printf("billion,%llu,failed,,,,,,,,,,,,\n", static_cast<unsigned long long>(n));
      std::fflush(stdout);
      continue;
    }
    const double s = median(secs);
    const double points = static_cast<double>(n);
    const double ns = s / points * 1e9;
    const double cpu_ns = median(cpu) / points * 1e9;
    if (first_ns == 0) first_ns = ns, first_cpu_ns = cpu_ns;
    const double rss_mib = static_cast<double>(rss) / 1024.0;
    std::printf("billion,%llu,%d,%.2f,%.3f,%.1f,%.2f,%.1f,%.2f,%.1f,%s,%llu,%llu,%.3f,%.0f\n",
                static_cast<unsigned long long>(n), runs, s, points / s * 1e-6, ns, ns / first_ns, cpu_ns,
                cpu_ns / first_cpu_ns, rss_mib,
                rss_mib <= 1024.0 ? "yes" : "NO", static_cast<unsigned long long>(last.chunks),
                static_cast<unsigned long long>(last.archive_bytes),
                static_cast<double>(last.archive_bytes) / points, static_cast<double>(disk) / (1 << 20));
    std::fflush(stdout);
  }
  fs::remove_all(work, ec);
  return failures == 0 ? 0 : 1;
}

}  // namespace relief::bench
