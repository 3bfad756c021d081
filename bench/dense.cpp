#include "dense.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <random>

#include "archive_blobs.h"
#include "median.h"
#include "relief/archive.h"
#include "run_child.h"

namespace fs = std::filesystem;

namespace relief::bench {

namespace {

// A binary little-endian PLY of float x y z.
bool write_xyz_ply(const std::string& path, const std::vector<float>& xyz) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return false;
  const std::size_t n = xyz.size() / 3;
  std::fprintf(f,
               "ply\nformat binary_little_endian 1.0\nelement vertex %zu\nproperty float x\nproperty float y\n"
               "property float z\nend_header\n",
               n);
  const bool ok = std::fwrite(xyz.data(), sizeof(float), xyz.size(), f) == xyz.size();
  return std::fclose(f) == 0 && ok;
}

// `points` points of float x y z, point i from `point(rng)`.
template <typename Point>
std::vector<float> generate(std::uint64_t points, std::uint64_t seed, Point&& point) {
  std::mt19937_64 rng(seed);
  std::vector<float> xyz(3 * points);
  for (std::uint64_t i = 0; i < points; ++i) {
    const auto [x, y, z] = point(rng);
    xyz[3 * i] = static_cast<float>(x);
    xyz[3 * i + 1] = static_cast<float>(y);
    xyz[3 * i + 2] = static_cast<float>(z);
  }
  return xyz;
}

// A terrestrial scan of flat ground from 1.5 m: uniform in azimuth and in the
// cosine of the angle below the horizon, so the density falls as 1/r^2 and
// the chunks beside the scanner hold ~1.7 M points each at 12 M.
std::vector<float> scanner_scene(std::uint64_t points, std::uint64_t seed) {
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> noise(0.0, 0.003);
  return generate(points, seed, [&](std::mt19937_64& rng) {
    const double az = u(rng) * 2 * M_PI;
    const double below = std::clamp(std::acos(u(rng) * 0.999), 0.015, 1.5);
    const double r = 1.5 / std::sin(below);
    const double x = r * std::cos(az), y = r * std::sin(az);
    return std::array<double, 3>{x, y, -1.5 + noise(rng) + 0.05 * std::sin(x)};
  });
}

// A wavy 10 x 10 m surface: with --chunk-edge 100 one chunk of every point.
std::vector<float> surface_scene(std::uint64_t points, std::uint64_t seed) {
  std::uniform_real_distribution<double> u(0.0, 10.0);
  std::normal_distribution<double> noise(0.0, 0.002);
  return generate(points, seed, [&](std::mt19937_64& rng) {
    const double x = u(rng), y = u(rng);
    return std::array<double, 3>{x, y, std::sin(x) * 0.5 + std::cos(y) * 0.3 + noise(rng)};
  });
}

// Runs `argv` (which writes the archive `out`) o.repeat times and prints its
// row: median time, largest peak RSS and its ratio to `budget_mib`, and the
// blobs of the first run against `first_hash` (set by the first row).
// Returns 1 when a run failed or the blobs differ.
int measure_row(const DenseOptions& o, const std::string& name, const std::string& memory, double budget_mib,
                std::uint64_t points, const std::vector<std::string>& argv, const std::string& out,
                std::uint64_t& first_hash) {
  std::vector<double> secs;
  long rss = 0;
  Blobs b;
  std::uintmax_t archive_bytes = 0;
  int status = 0;
  for (int r = 0; r < o.repeat; ++r) {
    fs::remove(out);
    const ChildRun run = run_child(argv);
    if (run.code != 0) {
      std::fprintf(stderr, "error: relief %s exited with %d (%s, --memory %s)\n", argv[1].c_str(), run.code,
                   name.c_str(), memory.c_str());
      status = 1;
      break;
    }
    secs.push_back(run.seconds);
    rss = std::max(rss, run.peak_rss_kib);
    if (r == 0) {
      b = blobs_of(out);
      archive_bytes = fs::file_size(out);
    }
    fs::remove(out);
  }
  if (secs.empty()) return status;
  if (first_hash == 0) first_hash = b.hash;
  const double s = median(secs);
  std::printf("%s,%s,%.2f,%.2f,%ld,%.2f,%llu,%llu,%llu,%llu,%016llx%s\n", name.c_str(), memory.c_str(), s,
              static_cast<double>(points) / s / 1e6, rss / 1024, static_cast<double>(rss) / 1024.0 / budget_mib,
              static_cast<unsigned long long>(b.chunks), static_cast<unsigned long long>(b.largest),
              static_cast<unsigned long long>(b.bytes), static_cast<unsigned long long>(archive_bytes),
              static_cast<unsigned long long>(b.hash), b.hash == first_hash ? "" : " BLOBS DIFFER");
  std::fflush(stdout);
  return b.hash == first_hash ? status : 1;
}

double budget_mib_of(const std::string& memory) {
  return std::strtod(memory.c_str(), nullptr) * (memory.back() == 'G' ? 1024.0 : 1.0);
}

// Stage 2 of a sharded build with every point in one key range: the scan
// planned with --ranges 1 and partitioned once, then `relief shard-encode` of
// that range at each budget (plus a run without --memory, the default 1 GiB,
// which older builds also accept).
int run_shard_range(const DenseOptions& o, const std::string& name, const std::string& in, std::uint64_t points) {
  const std::string work = o.tmp + "/relief-bench-shard";
  fs::remove_all(work);
  fs::create_directories(work + "/parts");
  const std::string plan = work + "/plan.txt";
  if (run_child({o.cli, "shard-plan", in, "-o", plan, "--tolerance", "0.001", "--ranges", "1", "--quiet"}).code != 0 ||
      run_child({o.cli, "shard-partition", plan, "--input", "0", "--dir", work + "/parts", "--quiet"}).code != 0) {
    std::fprintf(stderr, "error: shard-plan or shard-partition failed (%s)\n", name.c_str());
    return 1;
  }
  int status = 0;
  std::uint64_t first_hash = 0;
  std::vector<std::string> budgets = o.budgets;
  budgets.push_back("default");
  for (const std::string& memory : budgets) {
    const std::string out = work + "/shard.relief";
    std::vector<std::string> argv = {o.cli, "shard-encode", plan, "--range", "0", "--dir", work + "/parts", "-o",
                                     out, "--threads", "2", "--quiet"};
    if (memory != "default") {
      argv.push_back("--memory");
      argv.push_back(memory);
    }
    status |= measure_row(o, name, memory, budget_mib_of(memory == "default" ? "1G" : memory), points, argv, out,
                          first_hash);
  }
  fs::remove_all(work);
  return status;
}

}  // namespace

int run_dense(const DenseOptions& o) {
  struct Case {
    const char* name;
    std::uint64_t points;
    std::vector<std::string> extra;
  };
  const Case cases[] = {{"scanner-12M", 12'000'000, {}},
                        {"one-chunk-4M", 4'000'000, {"--chunk-edge", "100"}},
                        {"one-chunk-16M", 16'000'000, {"--chunk-edge", "100"}},
                        // The scanner scene as one key range of a sharded build (stage 2).
                        {"shard-range-12M", 12'000'000, {}}};
  std::printf("# bench/ingest --dense: relief compress --tolerance 0.001 (2 threads), median of %d runs\n", o.repeat);
  std::printf("case,memory,seconds,mpts_s,peak_rss_mib,peak_rss_over_budget,chunks,largest_chunk_points,blob_bytes,"
              "archive_bytes,blobs_fnv\n");
  int status = 0;
  for (const Case& c : cases) {
    if (!o.cases.empty() && std::find(o.cases.begin(), o.cases.end(), c.name) == o.cases.end()) continue;
    const std::string in = o.tmp + "/relief-bench-dense-" + c.name + ".ply";
    std::fprintf(stderr, "generating %s -> %s\n", c.name, in.c_str());
    const std::vector<float> xyz =
        std::string(c.name).rfind("one-chunk", 0) != 0 ? scanner_scene(c.points, o.seed) : surface_scene(c.points, o.seed);
    if (!write_xyz_ply(in, xyz)) {
      std::fprintf(stderr, "error: cannot write %s\n", in.c_str());
      return 1;
    }
    if (std::string(c.name).rfind("shard", 0) == 0) {
      status |= run_shard_range(o, c.name, in, c.points);
      fs::remove(in);
      continue;
    }
    std::uint64_t first_hash = 0;
    for (const std::string& memory : o.budgets) {
      const std::string out = o.tmp + "/relief-bench-dense.relief";
      std::vector<std::string> argv = {o.cli, "compress", in, "-o", out, "--tolerance", "0.001", "--memory", memory,
                                       "--threads", "2", "--quiet"};
      argv.insert(argv.end(), c.extra.begin(), c.extra.end());
      status |= measure_row(o, c.name, memory, budget_mib_of(memory), c.points, argv, out, first_hash);
    }
    fs::remove(in);
  }
  return status;
}

}  // namespace relief::bench
