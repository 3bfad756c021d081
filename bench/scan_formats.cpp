// bench/scan_formats: read rates of the terrestrial scanners' exchange
// formats against CSV and LAS, through the public reader (open_point_reader,
// batches of 2^20 points, the way the ingest reads), median of --repeat runs.
//
// One generated scan of --points points (a sphere of ranges around the
// scanner with intensities and colours) is written as E57 (by the tests'
// E57 writer, tests/io/e57_writer.h: ScaledInteger x y z at 1 mm, integer
// intensity and 8-bit colours, bytestreams over packets of at most 64 KiB),
// PTX (one scan, an identity matrix), PTS, CSV with a header and LAS (1 mm
// scale, through open_point_writer). Each file is read back whole and its
// points compared on the 1 mm grid (and their intensities and colours) with
// the generated ones: the program exits 1 when a format gives other points.
// Prints CSV: format, bytes, points, wall and CPU seconds, points/s.
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "io/e57_writer.h"
#include "median.h"
#include "relief/io.h"
#include "relief/types.h"

namespace {

namespace fs = std::filesystem;
namespace e57 = relief::test::e57;

constexpr std::size_t kBatch = std::size_t{1} << 20;

double cpu_seconds() {
  timespec ts{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

// The generated scan: integer millimetres, so every format states it exactly.
struct Scan {
  std::vector<std::int64_t> x, y, z, intensity, r, g, b;
  std::size_t size() const { return x.size(); }
};

Scan make_scan(std::size_t n) {
  Scan s;
  std::mt19937_64 rng(42);
  for (std::size_t i = 0; i < n; ++i) {
    const double az = 6.283185307179586 * static_cast<double>(i % 2000) / 2000.0;
    const double el = -0.6 + 1.2 * static_cast<double>(i / 2000 % 1000) / 1000.0;
    const double range = 5.0 + 30.0 * static_cast<double>(rng() % 100000) / 100000.0;
    s.x.push_back(std::llround(1000 * range * std::cos(el) * std::cos(az)) + 500000);
    s.y.push_back(std::llround(1000 * range * std::cos(el) * std::sin(az)) + 500000);
    s.z.push_back(std::llround(1000 * range * std::sin(el)) + 500000);
    s.intensity.push_back(static_cast<std::int64_t>(rng() % 2048));
    s.r.push_back(static_cast<std::int64_t>(rng() % 256));
    s.g.push_back(static_cast<std::int64_t>(rng() % 256));
    s.b.push_back(static_cast<std::int64_t>(rng() % 256));
  }
  return s;
}

// Coordinates in metres: millimetres / 1000 (E57's ScaledInteger scale).
double metres(std::int64_t mm) { return static_cast<double>(mm) * 0.001; }

bool write_e57(const Scan& s, const std::string& path) {
  e57::Scan scan;
  scan.fields = {e57::Field::scaled("cartesianX", 0, 1000000, 0.001, 0, s.x),
                 e57::Field::scaled("cartesianY", 0, 1000000, 0.001, 0, s.y),
                 e57::Field::scaled("cartesianZ", 0, 1000000, 0.001, 0, s.z),
                 e57::Field::integer("intensity", 0, 2047, s.intensity),
                 e57::Field::integer("colorRed", 0, 255, s.r),
                 e57::Field::integer("colorGreen", 0, 255, s.g),
                 e57::Field::integer("colorBlue", 0, 255, s.b)};
  // About 20 bytes a record: packets of at most 64 KiB.
  scan.packets = static_cast<int>(s.size() * 20 / 60000 + 1);
  const std::vector<std::uint8_t> bytes = e57::write({scan});
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  return static_cast<bool>(out);
}

// The text formats: CSV with a header, PTS (its count first), PTX (one scan
// of size x 1 with an identity matrix).
bool write_text(const Scan& s, const std::string& path, const std::string& kind) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return false;
  const char sep = kind == "csv" ? ',' : ' ';
  if (kind == "csv") std::fprintf(f, "x,y,z,intensity,red,green,blue\n");
  if (kind == "pts") std::fprintf(f, "%zu\n", s.size());
  if (kind == "ptx") {
    std::fprintf(f, "%zu\n1\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n", s.size());
  }
  for (std::size_t i = 0; i < s.size(); ++i) {
    std::fprintf(f, "%.3f%c%.3f%c%.3f%c%lld%c%lld%c%lld%c%lld\n", metres(s.x[i]), sep, metres(s.y[i]), sep,
                 metres(s.z[i]), sep, static_cast<long long>(s.intensity[i]), sep, static_cast<long long>(s.r[i]),
                 sep, static_cast<long long>(s.g[i]), sep, static_cast<long long>(s.b[i]));
  }
  return std::fclose(f) == 0;
}

bool write_las(const Scan& s, const std::string& path) {
  relief::PointCloud c;
  for (std::size_t i = 0; i < s.size(); ++i) {
    c.positions.push_back({metres(s.x[i]), metres(s.y[i]), metres(s.z[i])});
    c.intensities.push_back(static_cast<float>(s.intensity[i]));
    c.colors.push_back({static_cast<std::uint8_t>(s.r[i]), static_cast<std::uint8_t>(s.g[i]),
                        static_cast<std::uint8_t>(s.b[i])});
  }
  relief::WriterOptions o;
  o.colors = o.intensity = true;
  o.scale = 0.001;
  auto w = relief::open_point_writer(path, o);
  return w.is_ok() && (*w)->write(c).is_ok() && (*w)->finish().is_ok();
}

struct Timing {
  double wall = -1;
  double cpu = -1;
  std::uint64_t points = 0;
  bool same = false;  // the generated points, in order, on the 1 mm grid
};

Timing time_read(const std::string& path, const Scan& s) {
  Timing t;
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = cpu_seconds();
  auto reader = relief::open_point_reader(path);
  if (!reader.is_ok()) {
    std::fprintf(stderr, "%s\n", reader.status().to_string().c_str());
    return t;
  }
  relief::PointCloud batch;
  bool same = true;
  for (;;) {
    auto n = (*reader)->read(batch, kBatch);
    if (!n.is_ok()) {
      std::fprintf(stderr, "%s\n", n.status().to_string().c_str());
      return t;
    }
    if (*n == 0) break;
    for (std::size_t k = 0; k < *n && same; ++k) {
      const std::size_t i = t.points + k;
      const relief::Vec3d& p = batch.positions[k];
      same = i < s.size() && std::llround(p.x * 1000) == s.x[i] && std::llround(p.y * 1000) == s.y[i] &&
             std::llround(p.z * 1000) == s.z[i] && batch.intensities[k] == static_cast<float>(s.intensity[i]) &&
             batch.colors[k].r == s.r[i] && batch.colors[k].g == s.g[i] && batch.colors[k].b == s.b[i];
    }
    t.points += *n;
  }
  t.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  t.cpu = cpu_seconds() - c0;
  t.same = same && t.points == s.size();
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  std::size_t points = 2000000;
  int repeat = 3;
  std::string dir;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--points" && i + 1 < argc) {
      points = static_cast<std::size_t>(std::strtoull(argv[++i], nullptr, 10));
    } else if (a == "--repeat" && i + 1 < argc) {
      repeat = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--dir" && i + 1 < argc) {
      dir = argv[++i];
    } else {
      std::fprintf(stderr,
                   "usage: scan_formats [--points N (2000000)] [--repeat R (3)] [--dir DIR (a temporary one)]\n"
                   "Read rates of E57, PTX, PTS, CSV and LAS holding one generated scan (see the source).\n");
      return a == "--help" ? 0 : 2;
    }
  }
  if (points == 0) {
    std::fprintf(stderr, "scan_formats: --points must be at least 1\n");
    return 2;
  }
  const bool own_dir = dir.empty();
  if (own_dir) dir = (fs::temp_directory_path() / ("relief-scan-formats-" + std::to_string(::getpid()))).string();
  fs::create_directories(dir);
  const Scan s = make_scan(points);
  struct Format {
    const char* name;
    std::string path;
    bool written;
  };
  std::vector<Format> formats = {{"e57", dir + "/scan.e57", false}, {"ptx", dir + "/scan.ptx", false},
                                 {"pts", dir + "/scan.pts", false}, {"csv", dir + "/scan.csv", false},
                                 {"las", dir + "/scan.las", false}};
  for (Format& f : formats) {
    const std::string kind = f.name;
    f.written = kind == "e57" ? write_e57(s, f.path) : kind == "las" ? write_las(s, f.path) : write_text(s, f.path, kind);
    if (!f.written) {
      std::fprintf(stderr, "scan_formats: cannot write %s\n", f.path.c_str());
      return 1;
    }
  }
  std::printf("format,bytes,points,wall_s,cpu_s,mpts_s,same_points\n");
  int status = 0;
  for (const Format& f : formats) {
    std::vector<double> wall, cpu;
    Timing last;
    for (int r = 0; r < repeat; ++r) {
      last = time_read(f.path, s);
      if (last.wall < 0) return 1;
      wall.push_back(last.wall);
      cpu.push_back(last.cpu);
    }
    const double w = relief::bench::median(wall), c = relief::bench::median(cpu);
    std::printf("%s,%llu,%llu,%.3f,%.3f,%.2f,%s\n", f.name, static_cast<unsigned long long>(fs::file_size(f.path)),
                static_cast<unsigned long long>(last.points), w, c, static_cast<double>(last.points) / w * 1e-6,
                last.same ? "yes" : "NO");
    std::fflush(stdout);
    if (!last.same) status = 1;
  }
  if (own_dir) fs::remove_all(dir);
  return status;
}
