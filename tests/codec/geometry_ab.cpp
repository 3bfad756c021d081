// A/B tool (not a test; bench/README.md): geometry section bytes and CPU time of codec 13
// (plane classes) vs codec 14 (near classes) on whole files at G-PCC's grids (step = max
// extent / 2^g), one chunk per file. Usage: geometry_ab FILE.ply... [--grids 10,11,12,13,14]
// [--repeat N] (Until chunk format 10 it compared codec 7 with codec 8, until format 13 codec 8
// with codec 11, until format 16 codec 11 with codec 12, until format 17 codec 12 with codec
// 13: bench/README.md keeps those figures.)
#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "codec/geometry_coder.h"
#include "codec/octree.h"
#include "relief/io.h"

namespace {

double cpu_now() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

}  // namespace

int main(int argc, char** argv) {
  using namespace relief::codec;
  std::vector<std::string> files;
  std::vector<int> grids = {10, 11, 12, 13, 14};
  int repeat = 1;
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--repeat") == 0 && i + 1 < argc) {
      repeat = std::atoi(argv[++i]);
    } else if (std::strcmp(argv[i], "--grids") == 0 && i + 1 < argc) {
      grids.clear();
      std::string g = argv[++i];
      for (std::size_t p = 0; p < g.size();) {
        grids.push_back(std::atoi(g.c_str() + p));
        p = g.find(',', p);
        if (p == std::string::npos) break;
        ++p;
      }
    } else {
      files.push_back(argv[i]);
    }
  }
  std::printf("file,g,depth,cells,old_bytes,new_bytes,ratio,enc_cpu_old,enc_cpu_new,dec_cpu_old,dec_cpu_new\n");
  double sum_ratio = 0;
  int rows = 0;
  std::uint64_t tot_old = 0, tot_new = 0;
  double t_eo = 0, t_en = 0, t_do = 0, t_dn = 0;
  for (const std::string& f : files) {
    auto cloud = relief::read_ply(f);
    if (!cloud) {
      std::fprintf(stderr, "%s: %s\n", f.c_str(), cloud.status().to_string().c_str());
      return 1;
    }
    const auto b = cloud->bounds();
    const auto e = b.extent();
    const double extent = std::max({e.x, e.y, e.z});
    std::string stem = f.substr(f.find_last_of('/') + 1);
    for (int g : grids) {
      const double step = extent / std::ldexp(1.0, g);
      std::vector<std::uint64_t> keys;
      std::uint32_t span = 0;
      for (const auto& p : cloud->positions) {
        const auto x = static_cast<std::uint32_t>(std::llround((p.x - b.min.x) / step));
        const auto y = static_cast<std::uint32_t>(std::llround((p.y - b.min.y) / step));
        const auto z = static_cast<std::uint32_t>(std::llround((p.z - b.min.z) / step));
        span = std::max({span, x, y, z});
        keys.push_back(morton_encode(x, y, z));
      }
      std::sort(keys.begin(), keys.end());
      OccupiedCells cells;
      for (std::size_t i = 0; i < keys.size();) {
        std::size_t j = i + 1;
        while (j < keys.size() && keys[j] == keys[i]) ++j;
        cells.keys.push_back(keys[i]);
        cells.counts.push_back(static_cast<std::uint32_t>(j - i));
        i = j;
      }
      int depth = 0;
      while ((std::uint64_t{1} << depth) <= span) ++depth;
      double eo = 1e9, en = 1e9, dO = 1e9, dn = 1e9;
      std::vector<std::uint8_t> a, bb;
      for (int r = 0; r < repeat; ++r) {
        double t0 = cpu_now();
        a = encode_geometry(cells, depth, OctreeCoding::kPlanes);
        double t1 = cpu_now();
        bb = encode_geometry(cells, depth, OctreeCoding::kNearest);
        double t2 = cpu_now();
        auto da = decode_geometry(a, depth, keys.size(), OctreeCoding::kPlanes);
        double t3 = cpu_now();
        auto db = decode_geometry(bb, depth, keys.size(), OctreeCoding::kNearest);
        double t4 = cpu_now();
        if (!da || !db || da->keys != cells.keys || da->counts != cells.counts || db->keys != cells.keys ||
            db->counts != cells.counts) {
          std::fprintf(stderr, "%s g=%d: round trip FAILED\n", stem.c_str(), g);
          return 1;
        }
        eo = std::min(eo, t1 - t0);
        en = std::min(en, t2 - t1);
        dO = std::min(dO, t3 - t2);
        dn = std::min(dn, t4 - t3);
      }
      const double ratio = static_cast<double>(bb.size()) / static_cast<double>(a.size());
      std::printf("%s,%d,%d,%zu,%zu,%zu,%.4f,%.3f,%.3f,%.3f,%.3f\n", stem.c_str(), g, depth, cells.keys.size(), a.size(),
                  bb.size(), ratio, eo, en, dO, dn);
      std::fflush(stdout);
      sum_ratio += ratio;
      ++rows;
      tot_old += a.size();
      tot_new += bb.size();
      t_eo += eo;
      t_en += en;
      t_do += dO;
      t_dn += dn;
    }
  }
  std::printf("# mean ratio %.4f over %d rows; total %llu -> %llu (%.4f); enc cpu x%.2f dec cpu x%.2f\n",
              sum_ratio / rows, rows, static_cast<unsigned long long>(tot_old), static_cast<unsigned long long>(tot_new),
              static_cast<double>(tot_new) / static_cast<double>(tot_old), t_en / t_eo, t_dn / t_do);
  return 0;
}
