// bench/ingest: end-to-end ingest speed and peak memory of `relief compress`,
// and archive size against chunk size (the paper's Fig. 5). Prints CSV.
//
//   build/bench/ingest [--sizes 1,10,100] [--threads 1,2] [--repeat 3] [--data DIR]
//                      [--tmp DIR] [--no-shared] [--no-chunk-sweep]
//   build/bench/ingest --laz-vs-las [--threads 2] [--repeat 3] [--data DIR]
//   build/bench/ingest --billion [--sizes 10M,100M[,1G]] [--repeat 3] [--tmp DIR] [--keep DIR]
//   build/bench/ingest --dense [--memory 128M,256M,1G] [--cases A,B] [--repeat 3] [--tmp DIR] [--cli RELIEF]
//   build/bench/ingest --spool [--sizes 10M] [--repeat 3] [--tmp DIR] [--data DIR] [--cli RELIEF]
//
// --spool compresses a generated survey as LAZ and as text, and the shared
// aerial tile's LAZ at --memory 64M, with and without --no-spool (bench/spool.h).
//
// --dense compresses a generated terrestrial scan (chunks of 1.7 M points
// beside the scanner) and single chunks of 4 M and 16 M points at each budget
// (bench/dense.h); --cases picks some; --cli runs another build of relief, to compare.
//
// --billion feeds `relief compress` a generated aerial survey (bench/scene.h)
// through a named pipe, at a fixed density so the extent grows with the
// count, and prints seconds, points/s, cost per point, peak RSS, archive and
// peak disk bytes per size (bench/billion.h); 1 G is opt-in.
//
// --laz-vs-las times `relief compress` on each shared LAZ file against its LAS
// twin (the same points), the two runs interleaved so that both see the same
// machine load, and prints both rates and LAZ's share of the LAS rate (the
// target is >= 0.5); it skips the other measurements.
//
// Each measurement runs the CLI in a child process: wall time from fork to
// exit, peak RSS from wait4(). Generated inputs are written to --tmp (default
// /tmp) as binary PLY and removed afterwards.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "billion.h"
#include "dense.h"
#include "median.h"
#include "run_child.h"
#include "spool.h"
#include "relief/archive.h"
#include "relief/io.h"
#include "relief/metrics.h"
#include "relief/query.h"
#include "relief/types.h"

namespace fs = std::filesystem;

namespace {

using relief::bench::median;

struct Options {
  std::vector<int> sizes_m = {1, 10, 100};
  std::vector<int> threads = {1, 2};
  int repeat = 3;
  std::string data_dir = RELIEF_BENCH_DATA_DIR;
  std::string tmp = "/tmp";
  std::string cli = RELIEF_BENCH_CLI;
  bool shared = true;
  bool chunk_sweep = true;
  bool error_targets = true;
  bool laz_vs_las = false;
  bool billion = false;
  std::string keep;  // --billion --keep DIR: keep each size's archive there
  bool dense = false;
  bool spool = false;
  std::string memory_text;  // --dense --memory 128M,256M,1G
  std::string cases_text;   // --dense --cases scanner-12M,one-chunk-4M
  std::string sizes_text;  // --sizes as given (--billion reads it with suffixes)
  bool repeat_given = false;
};

using relief::bench::run_child;

// SplitMix64, as the test generator.
struct Rng {
  std::uint64_t s;
  std::uint64_t next() {
    std::uint64_t z = (s += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    return z ^ (z >> 31);
  }
  double uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }
};

void put_f64(unsigned char* p, double v) { std::memcpy(p, &v, 8); }  // x86-64 is little-endian

// A synthetic city of `points` points written straight to a binary PLY (never
// held in memory): blocks of 20 m with ground, facades and roofs, coloured.
bool write_city(const std::string& path, std::uint64_t points) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f) return false;
  std::fprintf(f,
               "ply\nformat binary_little_endian 1.0\nelement vertex %llu\nproperty double x\nproperty double y\n"
               "property double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n",
               static_cast<unsigned long long>(points));
  // Density ~ 100 points per square metre: the city grows with the count.
  const double area = static_cast<double>(points) / 100.0;
  const double side = std::sqrt(area);
  constexpr double kBlock = 20.0;
  Rng rng{42};
  constexpr std::size_t kRecord = 27;
  std::vector<unsigned char> buf(kRecord * 65536);
  std::size_t fill = 0;
  for (std::uint64_t i = 0; i < points; ++i) {
    // Spatially coherent order, as a scanner writes: sweep blocks row by row.
    const double t = static_cast<double>(i) / static_cast<double>(points);
    const double by = std::floor(t * side / kBlock) * kBlock;
    const double bx = rng.uniform() * side;
    const double u = rng.uniform() * kBlock, v = rng.uniform() * kBlock;
    const double bxs = std::floor(bx / kBlock) * kBlock;
    const double height = 6.0 + 10.0 * std::fmod(bxs * 0.37 + by * 0.11, 1.0);
    double x, y, z;
    unsigned char c[3];
    const std::uint64_t kind = rng.next() % 4;
    if (kind == 0) {  // facade
      x = bxs + 4.0;
      y = by + 4.0 + u * 0.6;
      z = v / kBlock * height;
      c[0] = 180, c[1] = 170, c[2] = 150;
    } else if (kind == 1) {  // roof
      x = bxs + 4.0 + u * 0.6;
      y = by + 4.0 + v * 0.6;
      z = height + 0.05 * std::sin(u);
      c[0] = 120, c[1] = 60, c[2] = 50;
    } else {  // ground
      x = bxs + u;
      y = by + v;
      z = 0.2 * std::sin(x * 0.05) * std::cos(y * 0.07);
      c[0] = 70, c[1] = static_cast<unsigned char>(110 + 40 * std::sin(x)), c[2] = 60;
    }
    unsigned char* p = buf.data() + fill;
    put_f64(p, x + 500000.0);
    put_f64(p + 8, y + 4000000.0);
    put_f64(p + 16, z + 100.0);
    p[24] = c[0], p[25] = c[1], p[26] = c[2];
    fill += kRecord;
    if (fill == buf.size()) {
      if (std::fwrite(buf.data(), 1, fill, f) != fill) return std::fclose(f), false;
      fill = 0;
    }
  }
  const bool ok = std::fwrite(buf.data(), 1, fill, f) == fill;
  return std::fclose(f) == 0 && ok;
}

std::uint64_t archive_blob_bytes(const std::string& path, std::uint64_t* chunks, std::uint64_t* points) {
  auto a = relief::Archive::open(path, relief::Archive::Mode::kReadOnly);
  if (!a) return 0;
  auto info = (*a)->info();
  if (!info) return 0;
  if (chunks) *chunks = info->chunk_count;
  if (points) *points = info->input_points;
  return info->blob_bytes;
}

void remove_archive(const std::string& path) {
  for (const char* s : {"", "-wal", "-shm"}) fs::remove(path + s);
}

// One ingest configuration: median wall time and peak RSS over `repeat` runs.
void measure(const Options& o, const std::string& label, const std::string& input, std::uint64_t points,
             unsigned threads, const std::vector<std::string>& extra) {
  const std::string out = o.tmp + "/relief-bench-ingest.relief";
  std::vector<double> secs;
  long rss = 0;
  std::uint64_t blob = 0, chunks = 0;
  for (int k = 0; k < o.repeat; ++k) {
    remove_archive(out);
    std::vector<std::string> argv = {o.cli, "compress", input, "-o", out, "--threads", std::to_string(threads),
                                     "--quiet"};
    argv.insert(argv.end(), extra.begin(), extra.end());
    const auto r = run_child(argv);
    if (r.code != 0) {
      std::fprintf(stderr, "error: %s: relief compress exited %d\n", label.c_str(), r.code);
      remove_archive(out);
      return;
    }
    secs.push_back(r.seconds);
    rss = std::max(rss, r.peak_rss_kib);
    blob = archive_blob_bytes(out, &chunks, nullptr);
  }
  const std::uint64_t file_bytes = fs::file_size(out);
  remove_archive(out);
  const double s = median(secs);
  std::printf("ingest,%s,%llu,%u,%.3f,%.3f,%.1f,%llu,%llu,%.4f\n", label.c_str(),
              static_cast<unsigned long long>(points), threads, s, static_cast<double>(points) / s * 1e-6,
              static_cast<double>(rss) / 1024.0, static_cast<unsigned long long>(chunks),
              static_cast<unsigned long long>(file_bytes),
              8.0 * static_cast<double>(blob) / static_cast<double>(points));
  std::fflush(stdout);
}

// LAZ against LAS: one `relief compress` of each per round, alternating, so
// that load on a shared machine falls on both alike; medians of the rounds.
void measure_laz_vs_las(const Options& o) {
  struct Pair {
    const char* name;
    const char* laz;
    const char* las;
  };
  const Pair pairs[] = {
      {"fr_aerial_rgb_698k", "laz/fr_aerial_rgb_698k.laz", "medium/orig/fr_aerial_rgb_698k.las"},
      {"lone_star_tls_519k", "laz/lone_star_tls_519k.laz", "medium/orig/lone_star_tls_519k.las"},
      {"autzen_trim", "laz/autzen_trim.laz", "laz/autzen_trim.las"},
  };
  std::printf("kind,input,points,threads,las_seconds,las_mpts_s,laz_seconds,laz_mpts_s,laz_over_las_rate\n");
  const std::string out = o.tmp + "/relief-bench-laz-vs-las.relief";
  for (const Pair& p : pairs) {
    const std::string laz = o.data_dir + "/" + p.laz, las = o.data_dir + "/" + p.las;
    if (!fs::exists(laz) || !fs::exists(las)) {
      std::printf("# skipped %s: %s or its twin absent\n", p.name, laz.c_str());
      continue;
    }
    auto info = relief::open_point_reader(las);
    if (!info) continue;
    const std::uint64_t n = (*info)->info().point_count.value_or(0);
    for (int t : o.threads) {
      std::vector<double> las_s, laz_s;
      bool failed = false;
      for (int k = 0; k < o.repeat && !failed; ++k) {
        for (const std::string* in : {&las, &laz}) {
          remove_archive(out);
          const auto r = run_child({o.cli, "compress", *in, "-o", out, "--threads", std::to_string(t), "--quiet"});
          if (r.code != 0) {
            std::fprintf(stderr, "error: %s: relief compress exited %d\n", in->c_str(), r.code);
            failed = true;
            break;
          }
          (in == &las ? las_s : laz_s).push_back(r.seconds);
        }
      }
      remove_archive(out);
      if (failed) continue;
      const double a = median(las_s), b = median(laz_s);
      const double points = static_cast<double>(n);
      std::printf("laz_vs_las,%s,%llu,%d,%.3f,%.3f,%.3f,%.3f,%.2f\n", p.name, static_cast<unsigned long long>(n), t,
                  a, points / a * 1e-6, b, points / b * 1e-6, a / b);
      std::fflush(stdout);
    }
  }
}

std::vector<int> parse_list(const char* s) {
  std::vector<int> v;
  for (const char* p = s; *p;) {
    v.push_back(std::atoi(p));
    const char* c = std::strchr(p, ',');
    if (!c) break;
    p = c + 1;
  }
  return v;
}

}  // namespace

int main(int argc, char** argv) {
  relief::retain_freed_memory();  // as the relief CLI does (relief/types.h)
  Options o;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    const auto value = [&]() -> const char* { return i + 1 < argc ? argv[++i] : ""; };
    if (a == "--sizes") {
      o.sizes_text = value();
      o.sizes_m = parse_list(o.sizes_text.c_str());
    } else if (a == "--threads") {
      o.threads = parse_list(value());
    } else if (a == "--repeat") {
      o.repeat = std::max(1, std::atoi(value()));
      o.repeat_given = true;
    } else if (a == "--data") {
      o.data_dir = value();
    } else if (a == "--tmp") {
      o.tmp = value();
    } else if (a == "--no-shared") {
      o.shared = false;
    } else if (a == "--no-chunk-sweep") {
      o.chunk_sweep = false;
    } else if (a == "--no-error-targets") {
      o.error_targets = false;
    } else if (a == "--laz-vs-las") {
      o.laz_vs_las = true;
    } else if (a == "--billion") {
      o.billion = true;
    } else if (a == "--keep") {
      o.keep = value();
    } else if (a == "--dense") {
      o.dense = true;
    } else if (a == "--spool") {
      o.spool = true;
    } else if (a == "--memory") {
      o.memory_text = value();
    } else if (a == "--cases") {
      o.cases_text = value();
    } else if (a == "--cli") {
      o.cli = value();
    } else {
      std::fprintf(stderr,
                   "usage: ingest [--sizes 1,10,100] [--threads 1,2] [--repeat N] [--data DIR] [--tmp DIR]\n"
                   "              [--no-shared] [--no-chunk-sweep] [--no-error-targets]\n"
                   "       ingest --laz-vs-las [--threads 2] [--repeat N] [--data DIR] [--tmp DIR]\n"
                   "       ingest --billion [--sizes 10M,100M[,1G]] [--repeat N] [--tmp DIR] [--keep DIR]\n"
                   "       ingest --dense [--memory 128M,256M,1G] [--cases A,B] [--repeat N] [--tmp DIR] [--cli RELIEF]\n"
                   "       ingest --spool [--sizes 10M] [--repeat N] [--tmp DIR] [--data DIR] [--cli RELIEF]\n");
      return a == "--help" ? 0 : 2;
    }
  }
  if (o.laz_vs_las) {
    measure_laz_vs_las(o);
    return 0;
  }
  if (o.dense) {
    relief::bench::DenseOptions d;
    const auto split_list = [](const std::string& text) {
      std::vector<std::string> items;
      std::string item;
      for (char ch : text + ",") {
        if (ch != ',') {
          item += ch;
        } else if (!item.empty()) {
          items.push_back(item);
          item.clear();
        }
      }
      return items;
    };
    if (!o.memory_text.empty()) d.budgets = split_list(o.memory_text);
    d.cases = split_list(o.cases_text);
    if (o.repeat_given) d.repeat = o.repeat;
    d.tmp = o.tmp;
    d.cli = o.cli;
    return relief::bench::run_dense(d);
  }
  if (o.spool) {
    relief::bench::SpoolOptions sp;
    if (!o.sizes_text.empty()) {
      const std::vector<std::uint64_t> sizes = relief::bench::parse_point_counts(o.sizes_text);
      if (sizes.size() != 1) {
        std::fprintf(stderr, "error: --spool --sizes expects one count such as 10M, got '%s'\n", o.sizes_text.c_str());
        return 2;
      }
      sp.points = sizes[0];
      sp.text_points = std::min(sp.text_points, sp.points);
    }
    if (o.repeat_given) sp.repeat = o.repeat;
    sp.tmp = o.tmp;
    sp.cli = o.cli;
    sp.data_dir = o.data_dir;
    return relief::bench::run_spool(sp);
  }
  if (o.billion) {
    relief::bench::BillionOptions b;
    if (!o.sizes_text.empty()) {
      b.sizes = relief::bench::parse_point_counts(o.sizes_text);
      if (b.sizes.empty()) {
        std::fprintf(stderr, "error: --sizes expects counts such as 10M,100M,1G (at most 4294967295), got '%s'\n",
                     o.sizes_text.c_str());
        return 2;
      }
    }
    if (o.repeat_given) b.repeat = o.repeat;
    b.tmp = o.tmp;
    b.cli = o.cli;
    b.keep = o.keep;
    return relief::bench::run_billion(b);
  }
  std::printf("kind,input,points,threads,seconds,mpts_s,peak_rss_mib,chunks,archive_bytes,bpp\n");
  for (int m : o.sizes_m) {
    const std::uint64_t n = static_cast<std::uint64_t>(m) * 1000000;
    const std::string in = o.tmp + "/relief-bench-city-" + std::to_string(m) + "M.ply";
    std::fprintf(stderr, "generating %d M points -> %s\n", m, in.c_str());
    if (!write_city(in, n)) {
      std::fprintf(stderr, "error: cannot write %s\n", in.c_str());
      continue;
    }
    for (int t : o.threads) {
      std::fprintf(stderr, "compressing %d M points, %d thread(s)\n", m, t);
      // The automatic cell (from the first million points' density), as users get it.
      measure(o, "city-" + std::to_string(m) + "M", in, n, static_cast<unsigned>(t), {});
    }
    fs::remove(in);
  }
  if (o.shared) {
    if (!fs::exists(o.data_dir)) {
      std::printf("# skipped shared data: %s absent\n", o.data_dir.c_str());
    } else {
      for (const char* f : {"small/stanford_bunny.ply", "small/kitti_000000.ply", "small/kinect_milk_scene_rgb.ply",
                            "medium/lone_star_tls_519k.ply", "medium/fr_aerial_rgb_698k.ply",
                            "medium/orig/fr_aerial_rgb_698k.las"}) {
        const std::string path = o.data_dir + "/" + f;
        if (!fs::exists(path)) continue;
        auto info = relief::open_point_reader(path);
        if (!info) continue;
        const std::uint64_t n = (*info)->info().point_count.value_or(0);
        // The LAS source beside its PLY conversion: labelled by file name.
        const std::string label = fs::path(path).extension() == ".las" ? fs::path(path).filename().string()
                                                                      : fs::path(path).stem().string();
        for (int t : o.threads) measure(o, label, path, n, static_cast<unsigned>(t), {});
      }
    }
  }
  if (o.chunk_sweep) {
    // Fig. 5: archive size against chunk volume relative to the scene's
    // bounding cube, on the aerial tile.
    const std::string path = o.data_dir + "/medium/fr_aerial_rgb_698k.ply";
    auto cloud = relief::read_ply(path);
    if (cloud) {
      const relief::Vec3d e = cloud->bounds().extent();
      const double side = std::max({e.x, e.y, e.z});
      constexpr double cell = 4.0;  // the aerial tile's automatic cell is ~6 m
      std::printf("kind,input,chunk_edge,log10_volume_fraction,chunks,blob_bytes,growth_vs_whole\n");
      double whole = 0;
      const std::string out = o.tmp + "/relief-bench-sweep.relief";
      // Chunk edges are cell * 2^k so cells tile every chunk exactly; 512 m
      // holds the whole 370 m tile in one chunk.
      for (int k = 7; k >= 1; --k) {
        const double edge = cell * std::ldexp(1.0, k);
        remove_archive(out);
        const auto r = run_child({o.cli, "compress", path, "-o", out, "--cell", "4", "--chunk-edge",
                                 std::to_string(edge), "--quiet"});
        if (r.code != 0) continue;
        std::uint64_t chunks = 0;
        const std::uint64_t blob = archive_blob_bytes(out, &chunks, nullptr);
        if (whole == 0) whole = static_cast<double>(blob);
        const double frac = std::pow(std::min(1.0, edge / side), 3.0);
        std::printf("chunks,fr_aerial_rgb_698k,%.0f,%.2f,%llu,%llu,%+.1f%%\n", edge, std::log10(frac),
                    static_cast<unsigned long long>(chunks), static_cast<unsigned long long>(blob),
                    100.0 * (static_cast<double>(blob) / whole - 1.0));
        std::fflush(stdout);
      }
      remove_archive(out);
    }
  }
  if (o.error_targets && fs::exists(o.data_dir)) {
    // --error-target: wanted RMSE_SNN against what the whole file gets.
    std::printf("kind,input,target_rmse,achieved_rmse,ratio,cell,bpp\n");
    const std::string out = o.tmp + "/relief-bench-target.relief";
    struct Case {
      const char* file;
      double targets[3];
    };
    const Case cases[] = {{"small/stanford_bunny.ply", {0.0005, 0.001, 0.002}},
                          {"small/kinect_milk_scene_rgb.ply", {0.001, 0.002, 0.004}},
                          {"small/kitti_000000.ply", {0.05, 0.1, 0.2}},
                          {"medium/lone_star_tls_519k.ply", {0.03, 0.05, 0.1}},
                          {"medium/fr_aerial_rgb_698k.ply", {0.1, 0.2, 0.4}}};
    for (const Case& c : cases) {
      const std::string path = o.data_dir + "/" + c.file;
      auto original = relief::read_ply(path);
      if (!original) continue;
      for (double target : c.targets) {
        remove_archive(out);
        char t[32];
        std::snprintf(t, sizeof t, "%.6g", target);
        const auto r = run_child({o.cli, "compress", path, "-o", out, "--error-target", t, "--quiet"});
        if (r.code != 0) {
          std::printf("target,%s,%s,failed (exit %d),,,\n", fs::path(path).stem().c_str(), t, r.code);
          continue;
        }
        auto reader = relief::ArchiveReader::open(out);
        if (!reader) continue;
        relief::PointCloud decoded;
        auto q = (*reader)->query_all({}, [&](const relief::PointCloud& b) {
          decoded.positions.insert(decoded.positions.end(), b.positions.begin(), b.positions.end());
          return relief::Status::ok();
        });
        if (!q || decoded.empty()) continue;
        relief::PointCloud geometry;
        geometry.positions = original->positions;
        auto m = relief::compare_clouds(geometry, decoded);
        if (!m) continue;
        auto params = (*reader)->info().codec_params;
        const double bpp = 8.0 * static_cast<double>((*reader)->info().blob_bytes) /
                           static_cast<double>(original->size());
        const auto cell_at = params.find("cell=");
        const std::string cell = cell_at == std::string::npos ? "" : params.substr(cell_at + 5, params.find(';', cell_at) - cell_at - 5);
        std::printf("target,%s,%s,%.6g,%.3f,%s,%.4f\n", fs::path(path).stem().c_str(), t, m->rmse_snn,
                    m->rmse_snn / target, cell.c_str(), bpp);
        std::fflush(stdout);
      }
    }
    remove_archive(out);
  }
  return 0;
}
