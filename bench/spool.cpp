#include "spool.h"

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <vector>

#include "archive_blobs.h"
#include "disk_bytes.h"
#include "median.h"
#include "relief/io.h"
#include "run_child.h"
#include "scene.h"

namespace fs = std::filesystem;

namespace relief::bench {

namespace {

// The generated survey as a LAS file (its header and records as they come).
bool write_scene_las(const std::string& path, std::uint64_t points, std::uint64_t seed) {
  AerialScene scene(points, seed);
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return false;
  const std::vector<unsigned char> header = scene.header();
  bool ok = std::fwrite(header.data(), 1, header.size(), f) == header.size();
  std::vector<unsigned char> buf(65536 * AerialScene::kRecordBytes);
  for (std::size_t got; ok && (got = scene.next(buf.data(), 65536)) > 0;) {
    ok = std::fwrite(buf.data(), AerialScene::kRecordBytes, got, f) == got;
  }
  return std::fclose(f) == 0 && ok;
}

// The first `limit` points of a LAS file rewritten through the library's
// writers: LAZ keeps every attribute and the LAS grid, text keeps x y z, RGB
// and intensity.
bool convert(const std::string& las, const std::string& out, std::uint64_t limit) {
  auto reader = open_point_reader(las);
  if (!reader) return false;
  const PointStreamInfo& info = (*reader)->info();
  WriterOptions w;
  w.colors = info.has_colors;
  w.intensity = info.has_intensity;
  if (fs::path(out).extension() == ".laz") {
    w.las_attributes = info.las_attributes;
    w.las_point_format = info.las_point_format;
    w.las_version_minor = info.las_version_minor;
    w.grid_scale = info.scale;
    w.grid_offset = info.offset;
  }
  auto writer = open_point_writer(out, w);
  if (!writer) return false;
  PointCloud batch;
  std::uint64_t done = 0;
  while (done < limit) {
    auto got =
        (*reader)->read(batch, static_cast<std::size_t>(std::min<std::uint64_t>(1 << 20, limit - done)));
    if (!got) return false;
    if (*got == 0) break;
    if (!(*writer)->write(batch)) return false;
    done += *got;
  }
  return static_cast<bool>((*writer)->finish());
}

struct Side {
  std::vector<double> seconds, cpu;
  long rss_kib = 0;
  std::uint64_t disk_peak = 0;  // the work directory's (temporary files and archive)
  Blobs blobs;
};

// One row: `input` compressed `repeat` times each way, alternating.
int measure(const SpoolOptions& o, const std::string& name, const std::string& input, std::uint64_t points,
            const std::vector<std::string>& extra) {
  // The archive and the temporary files in a directory of their own, whose
  // disk use is sampled while each run goes.
  const std::string work = o.tmp + "/relief-bench-spool-work";
  fs::create_directories(work);
  const std::string out = work + "/out.relief";
  Side sides[2];  // with the spool, with --no-spool
  for (int r = 0; r < o.repeat; ++r) {
    for (int s = 0; s < 2; ++s) {
      std::vector<std::string> argv = {o.cli, "compress", input, "-o", out, "--tmp", work, "--quiet"};
      argv.insert(argv.end(), extra.begin(), extra.end());
      if (s == 1) argv.push_back("--no-spool");
      fs::remove(out);
      std::uint64_t peak = 0;
      const ChildRun run = run_child(
          argv, [&] { peak = std::max(peak, disk_bytes(work)); }, 0.25);
      sides[s].disk_peak = std::max(sides[s].disk_peak, peak);
      if (run.code != 0) {
        std::fprintf(stderr, "error: relief compress %s exited with %d\n", input.c_str(), run.code);
        fs::remove_all(work);
        return 1;
      }
      sides[s].seconds.push_back(run.seconds);
      sides[s].cpu.push_back(run.cpu_seconds);
      sides[s].rss_kib = std::max(sides[s].rss_kib, run.peak_rss_kib);
      if (r == 0) sides[s].blobs = blobs_of(out);
      fs::remove(out);
    }
  }
  fs::remove_all(work);
  const double a = median(sides[0].seconds), b = median(sides[1].seconds);
  const bool same = sides[0].blobs.chunks > 0 && sides[0].blobs.hash == sides[1].blobs.hash &&
                    sides[0].blobs.bytes == sides[1].blobs.bytes;
  std::printf("spool,%s,%llu,%.2f,%.2f,%.3f,%.2f,%.2f,%.2f,%.2f,%ld,%ld,%.0f,%.0f,%016llx%s\n", name.c_str(),
              static_cast<unsigned long long>(points), a, b, a / b, static_cast<double>(points) / a * 1e-6,
              static_cast<double>(points) / b * 1e-6, median(sides[0].cpu), median(sides[1].cpu),
              sides[0].rss_kib / 1024, sides[1].rss_kib / 1024,
              static_cast<double>(sides[0].disk_peak) / (1 << 20),
              static_cast<double>(sides[1].disk_peak) / (1 << 20),
              static_cast<unsigned long long>(sides[0].blobs.hash), same ? "" : " BLOBS DIFFER");
  std::fflush(stdout);
  return same ? 0 : 1;
}

}  // namespace

int run_spool(const SpoolOptions& o) {
  std::printf("# median of %d runs each way, alternating; spool = the default, twice = --no-spool\n",
              o.repeat);
  std::printf(
      "kind,input,points,spool_s,twice_s,spool_over_twice,spool_mpts_s,twice_mpts_s,spool_cpu_s,twice_cpu_s,"
      "spool_rss_mib,twice_rss_mib,spool_disk_peak_mib,twice_disk_peak_mib,blob_hash\n");
  std::fflush(stdout);
  const std::string las = o.tmp + "/relief-bench-spool-scene.las";
  const std::string laz = o.tmp + "/relief-bench-spool-scene.laz";
  const std::string csv = o.tmp + "/relief-bench-spool-scene.csv";
  int status = 0;
  std::fprintf(stderr, "generating %llu points -> %s, %s\n", static_cast<unsigned long long>(o.points),
               laz.c_str(), csv.c_str());
  if (!write_scene_las(las, o.points, o.seed) || !convert(las, laz, o.points) ||
      !convert(las, csv, o.text_points)) {
    std::fprintf(stderr, "error: cannot write the inputs under %s\n", o.tmp.c_str());
    status = 1;
  } else {
    fs::remove(las);
    status |= measure(o, "scene.laz (LAS 1.2 fmt 3)", laz, o.points, {});
    status |= measure(o, "scene.csv (x y z rgb i)", csv, o.text_points, {});
  }
  fs::remove(las);
  fs::remove(laz);
  fs::remove(csv);
  const std::string tile = o.data_dir + "/laz/fr_aerial_rgb_698k.laz";
  if (fs::exists(tile)) {
    // A layered LAZ (LAS 1.4 format 8): without the spool its first pass
    // decodes x y z alone; at 64M it is beyond the in-memory path.
    status |= measure(o, "fr_aerial_rgb_698k.laz --memory 64M", tile, 697721, {"--memory", "64M"});
  } else {
    std::printf("# skipped the aerial tile: %s absent\n", tile.c_str());
  }
  return status;
}

}  // namespace relief::bench
