// bench/codec: rate, distortion and speed of the Relief chunk codec over a grid
// of configurations on the shared test files, beside Draco measured the same
// way, as CSV on stdout followed by a `#` summary (Pareto fronts and equal-error
// comparisons with Draco and the G-PCC anchors). See bench/README.md.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "bench_common.h"
#include "bounded.h"
#include "external_codec.h"
#include "relief/codec.h"
#include "relief/io.h"
#include "relief/metrics.h"
#include "relief/types.h"
#include "summary.h"

namespace fs = std::filesystem;
using relief::Decomposition;
using relief::ImageCodec;

// ---- The configuration grid (documented in bench/README.md).

// Map resolution r: the library default, and what suggest_cell_size is asked for.
constexpr int kMapResolution = 16;
// Octree n_l: split a leaf while it holds more points than this. 256 = one
// r x r map's worth of pixels (16 x 16), so a leaf is split once its points
// could no longer each get a pixel.
constexpr std::uint32_t kOctreeLeafPoints = 256;
const std::vector<double> kCellMultipliers = {0.35, 0.5, 0.7, 1.0, 1.4, 2.0, 2.8};
const std::vector<double> kCellMultipliersQuick = {0.7, 1.4};
const std::vector<int> kHeightQualities = {30, 50, 75, 90};
const std::vector<int> kHeightQualitiesQuick = {75};
// JPEG 2000 with 16-bit heights: one row per cell size at this quality.
constexpr int kHeightBits16Quality = 90;
// Colour is less visible than geometry error, so it gets a lower quality
// (method notes, idea 6), but never below this floor.
constexpr int kColourQualityOffset = 10;
constexpr int kColourQualityMin = 30;
// Down to qp 6 so Draco's curve covers the coarse errors Relief reaches.
const std::vector<int> kDracoQp = {6, 7, 8, 9, 10, 11, 12, 14};
// Fill comparison (the default block projection vs push-pull alone and the
// paper's 3 x 5x5 box filter): voxel + JPEG at these cells and this quality.
const std::vector<double> kFillCompareMultipliers = {0.7, 1.0, 1.4};
constexpr int kFillCompareQuality = 75;
constexpr int kDracoCompressionLevel = 7;  // what the anchors used

struct Options {
  std::string data_dir = RELIEF_BENCH_DATA_DIR;
  std::string anchors_dir = RELIEF_BENCH_ANCHORS_DIR;
  std::vector<std::string> file_filters;
  int repeat = 3;
  bool quick = false;
  bool draco = true;
  bool keep_intensity = false;
  std::string csv_path;
  std::string mode = "bounded";
};

struct ReliefConfig {
  Decomposition decomposition = Decomposition::kVoxelGrid;
  ImageCodec image = ImageCodec::kJpeg;
  double multiplier = 1;
  int quality = 75;
  int height_bits = 8;
  relief::FillMethod fill = relief::FillMethod::kBlockProjection;
};

const char* const kUsage =
    "usage: codec [options]\n"
    "Benchmarks the Relief chunk codec (and Draco, when installed) on the shared test files and\n"
    "prints one CSV row per configuration, then a summary in lines starting with '#'.\n"
    "\n"
    "  --data DIR        test data directory (default " RELIEF_BENCH_DATA_DIR ")\n"
    "                    every *.ply below it, except in orig/ folders, smallest first\n"
    "  --anchors DIR     peer-codec results, results-<stem>.csv (default " RELIEF_BENCH_ANCHORS_DIR ")\n"
    "  --files A,B       only files whose path contains one of these substrings\n"
    "  --repeat N        encode/decode timings are the median of N runs (default 3)\n"
    "  --quick           a small grid for smoke runs (cells 0.7,1.4 x c0; quality 75)\n"
    "  --no-draco        do not run Draco (the summary then uses the anchors' Draco rows)\n"
    "  --keep-intensity  also code the intensity attribute (default: dropped, as for the peers)\n"
    "  --csv PATH        also write everything printed on stdout to PATH\n"
    "  --mode M          bounded (default): the error-bounded mode's tolerance sweep through real\n"
    "                    archives, with Bjontegaard rate differences against G-PCC, LAZ and Draco;\n"
    "                    resample: the resampling codec's configuration grid (one chunk per file);\n"
    "                    both\n"
    "  --help            this text\n";

// Returns nullopt after printing an error for a bad command line.
std::optional<Options> parse_options(int argc, char** argv, bool& help) {
  Options o;
  help = false;
  for (int i = 1; i < argc; ++i) {
    std::string arg = argv[i];
    std::optional<std::string> inline_value;
    if (const auto eq = arg.find('='); arg.rfind("--", 0) == 0 && eq != std::string::npos) {
      inline_value = arg.substr(eq + 1);
      arg.resize(eq);
    }
    auto value = [&]() -> std::optional<std::string> {
      if (inline_value) return inline_value;
      if (i + 1 < argc) return std::string(argv[++i]);
      std::fprintf(stderr, "codec: %s needs a value\n", arg.c_str());
      return std::nullopt;
    };
    if (arg == "--help" || arg == "-h") {
      help = true;
      return o;
    } else if (arg == "--quick") {
      o.quick = true;
    } else if (arg == "--no-draco") {
      o.draco = false;
    } else if (arg == "--keep-intensity") {
      o.keep_intensity = true;
    } else if (arg == "--data" || arg == "--anchors" || arg == "--files" || arg == "--csv" ||
               arg == "--repeat" || arg == "--mode") {
      const auto v = value();
      if (!v) return std::nullopt;
      if (arg == "--mode") {
        if (*v != "bounded" && *v != "resample" && *v != "both") {
          std::fprintf(stderr, "codec: --mode wants bounded, resample or both, got '%s'\n", v->c_str());
          return std::nullopt;
        }
        o.mode = *v;
      }
      if (arg == "--data") o.data_dir = *v;
      if (arg == "--anchors") o.anchors_dir = *v;
      if (arg == "--csv") o.csv_path = *v;
      if (arg == "--files") {
        std::size_t start = 0;
        while (start <= v->size()) {
          const std::size_t comma = std::min(v->find(',', start), v->size());
          if (comma > start) o.file_filters.push_back(v->substr(start, comma - start));
          start = comma + 1;
        }
      }
      if (arg == "--repeat") {
        char* end = nullptr;
        const long n = std::strtol(v->c_str(), &end, 10);
        if (v->empty() || *end != '\0' || n < 1 || n > 1000) {
          std::fprintf(stderr, "codec: --repeat wants an integer in 1..1000, got '%s'\n", v->c_str());
          return std::nullopt;
        }
        o.repeat = static_cast<int>(n);
      }
    } else {
      std::fprintf(stderr, "codec: unknown option '%s' (see --help)\n", arg.c_str());
      return std::nullopt;
    }
  }
  return o;
}

// Every *.ply below `dir`, except the untouched sources kept in orig/ folders,
// smallest file first so a run shows complete files early.
std::vector<fs::path> find_point_files(const fs::path& dir, const std::vector<std::string>& filters) {
  std::vector<std::pair<std::uintmax_t, fs::path>> found;
  std::error_code ec;
  fs::recursive_directory_iterator it(dir, fs::directory_options::skip_permission_denied, ec);
  for (; !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    // A separate error code per entry: one unreadable entry must not end the listing.
    std::error_code entry_ec;
    if (it->is_directory(entry_ec) && it->path().filename() == "orig") {
      it.disable_recursion_pending();
      continue;
    }
    if (!it->is_regular_file(entry_ec) || it->path().extension() != ".ply") continue;
    const std::string p = it->path().string();
    const bool wanted = filters.empty() || std::any_of(filters.begin(), filters.end(), [&p](const std::string& f) {
                          return p.find(f) != std::string::npos;
                        });
    if (wanted) found.emplace_back(it->file_size(entry_ec), it->path());
  }
  if (ec) note("warning: listing %s: %s", dir.c_str(), ec.message().c_str());
  std::sort(found.begin(), found.end());
  std::vector<fs::path> paths;
  for (auto& f : found) paths.push_back(std::move(f.second));
  return paths;
}

std::vector<ReliefConfig> relief_grid(bool quick) {
  const auto& multipliers = quick ? kCellMultipliersQuick : kCellMultipliers;
  const auto& qualities = quick ? kHeightQualitiesQuick : kHeightQualities;
  std::vector<ReliefConfig> grid;
  for (Decomposition d : {Decomposition::kVoxelGrid, Decomposition::kOctree}) {
    for (ImageCodec c : {ImageCodec::kJpeg, ImageCodec::kJpeg2000}) {
      for (double m : multipliers) {
        for (int q : qualities) grid.push_back({d, c, m, q, 8});
      }
    }
  }
  for (double m : multipliers) {
    grid.push_back({Decomposition::kVoxelGrid, ImageCodec::kJpeg2000, m, kHeightBits16Quality, 16});
  }
  if (!quick) {
    for (double m : kFillCompareMultipliers) {
      for (relief::FillMethod f : {relief::FillMethod::kBoxFilter, relief::FillMethod::kPushPull}) {
        grid.push_back({Decomposition::kVoxelGrid, ImageCodec::kJpeg, m, kFillCompareQuality, 8, f});
      }
    }
  }
  return grid;
}

std::string section_summary(const relief::ChunkInfo& info) {
  // Fixed order and every name present (0 when absent) so columns can be split mechanically.
  static const char* const kNames[] = {"tree", "patches", "occupancy", "height", "colour", "intensity"};
  std::uint64_t bytes[6] = {};
  for (const relief::ChunkSectionInfo& s : info.sections) {
    if (s.id >= 1 && s.id <= 6) bytes[s.id - 1] += s.coded_size;
  }
  std::string out;
  for (int k = 0; k < 6; ++k) {
    if (k > 0) out += ';';
    out += std::string(kNames[k]) + ':' + std::to_string(bytes[k]);
  }
  return out;
}

void fill_metrics(BenchRow& row, const relief::ErrorMetrics& m) {
  row.rmse_snn = m.rmse_snn;
  row.psnr = m.psnr;
  row.hausdorff = m.hausdorff;
  if (m.has_rgb) row.rmse_rgb_snn = m.rmse_rgb_snn;
}

// Decodes `blob` `repeat` times at `lod`; returns the median seconds and the last cloud.
std::optional<std::pair<double, relief::PointCloud>> timed_decode(const std::vector<std::uint8_t>& blob,
                                                                 std::uint32_t lod, int repeat,
                                                                 const std::string& what) {
  relief::DecodeOptions opt;
  opt.lod = lod;
  std::vector<double> times;
  std::optional<relief::PointCloud> cloud;
  for (int k = 0; k < repeat; ++k) {
    const auto t0 = BenchClock::now();
    auto decoded = relief::decode_chunk(blob, opt);
    const auto t1 = BenchClock::now();
    if (!decoded) {
      note("error: %s: decode lod %u: %s", what.c_str(), lod, decoded.status().to_string().c_str());
      return std::nullopt;
    }
    times.push_back(seconds_between(t0, t1));
    cloud = std::move(decoded).value();
  }
  return std::make_pair(median(times), std::move(*cloud));
}

std::optional<BenchRow> run_relief(const relief::PointCloud& cloud, const std::string& stem, double c0,
                                   const ReliefConfig& cfg, int repeat) {
  relief::EncodeParams params;
  params.decomposition = cfg.decomposition;
  params.cell_size = cfg.multiplier * c0;
  if (cfg.decomposition == Decomposition::kOctree) params.octree_max_points = kOctreeLeafPoints;
  params.map_resolution = kMapResolution;
  params.image_codec = cfg.image;
  params.height_quality = cfg.quality;
  params.color_quality = std::max(kColourQualityMin, cfg.quality - kColourQualityOffset);
  params.height_bits = cfg.height_bits;
  params.fill = cfg.fill;

  BenchRow row;
  row.file = stem;
  row.codec = "relief";
  row.decomposition = relief::decomposition_name(cfg.decomposition);
  row.image = relief::image_codec_name(cfg.image);
  row.fill = cfg.fill == relief::FillMethod::kBoxFilter  ? "box"
             : cfg.fill == relief::FillMethod::kPushPull ? "pushpull"
                                                         : "project";
  row.cell = params.cell_size;
  row.cell_multiplier = cfg.multiplier;
  row.quality = cfg.quality;
  row.color_quality = cloud.has_colors() ? params.color_quality : -1;
  row.height_bits = cfg.height_bits;
  row.points_in = cloud.size();
  const std::string what = stem + " " + row_label(row);

  std::vector<double> enc_times;
  std::vector<std::uint8_t> blob;
  for (int k = 0; k < repeat; ++k) {
    const auto t0 = BenchClock::now();
    auto encoded = relief::encode_chunk(cloud, params);
    const auto t1 = BenchClock::now();
    if (!encoded) {
      note("error: %s: encode: %s", what.c_str(), encoded.status().to_string().c_str());
      return std::nullopt;
    }
    enc_times.push_back(seconds_between(t0, t1));
    blob = std::move(encoded).value();
  }
  auto info = relief::inspect_chunk(blob);
  if (!info) {
    note("error: %s: inspect: %s", what.c_str(), info.status().to_string().c_str());
    return std::nullopt;
  }
  auto full = timed_decode(blob, 1, repeat, what);
  if (!full) return std::nullopt;
  auto lod4 = timed_decode(blob, 4, repeat, what);
  if (!lod4) return std::nullopt;
  const relief::PointCloud& decoded = full->second;
  if (decoded.empty()) {
    note("error: %s: decoded cloud is empty", what.c_str());
    return std::nullopt;
  }
  relief::MetricsOptions mopt;
  mopt.threads = 0;  // all cores: the metric is not what is being timed
  auto metrics = relief::compare_clouds(cloud, decoded, mopt);
  if (!metrics) {
    note("error: %s: compare: %s", what.c_str(), metrics.status().to_string().c_str());
    return std::nullopt;
  }

  row.points_out = decoded.size();
  row.bytes = blob.size();
  row.bpp = 8.0 * static_cast<double>(blob.size()) / static_cast<double>(cloud.size());
  fill_metrics(row, *metrics);
  row.enc_mpts_s = mpts_per_s(cloud.size(), median(enc_times));
  row.dec_seconds = full->first;
  row.dec_mpts_s = mpts_per_s(decoded.size(), full->first);
  row.dec_in_mpts_s = mpts_per_s(cloud.size(), full->first);
  // Full-resolution points over the LOD-4 time, so dec_lod4_mpts_s / dec_mpts_s
  // is the wall-time speed-up of a coarse preview decode.
  row.lod4_seconds = lod4->first;
  row.dec_lod4_mpts_s = mpts_per_s(decoded.size(), lod4->first);
  row.section_bytes = section_summary(*info);
  return row;
}

struct DracoTools {
  fs::path encoder;
  fs::path decoder;
};

// Draco on one cloud for every qp, measured like the anchors: float32 PLY
// shifted to the bbox minimum in, whole-process wall times, errors against the
// original double-precision cloud.
std::vector<BenchRow> run_draco(const relief::PointCloud& cloud, const std::string& stem, const DracoTools& tools,
                                int repeat, Output& out) {
  std::vector<BenchRow> rows;
  auto scratch = ScratchDir::create("relief-bench-draco-");
  if (!scratch) {
    note("error: %s: draco: %s", stem.c_str(), scratch.status().to_string().c_str());
    return rows;
  }
  const fs::path in_ply = scratch->path() / "in.ply";
  const fs::path drc = scratch->path() / "out.drc";
  const fs::path out_ply = scratch->path() / "out.ply";
  const fs::path log = scratch->path() / "tool.log";

  // Draco quantises in float; georeferenced coordinates (~5e6 m) would lose
  // centimetres in float32, so move to the bbox minimum first and back after.
  const relief::Box3d box = cloud.bounds();
  relief::PointCloud shifted;
  shifted.positions.reserve(cloud.size());
  for (const relief::Vec3d& p : cloud.positions) {
    shifted.positions.push_back({p.x - box.min.x, p.y - box.min.y, p.z - box.min.z});
  }
  shifted.colors = cloud.colors;  // no intensity: the peers were measured without it
  relief::PlyWriteOptions wopt;
  wopt.coordinate_type = relief::PlyCoordinateType::kFloat32;
  if (relief::Status s = relief::write_ply(in_ply.string(), shifted, wopt); !s) {
    note("error: %s: draco input: %s", stem.c_str(), s.to_string().c_str());
    return rows;
  }

  for (int qp : kDracoQp) {
    BenchRow row;
    row.file = stem;
    row.codec = "draco";
    row.quality = qp;
    row.points_in = cloud.size();
    const std::string what = stem + " draco qp=" + std::to_string(qp);
    note("  %s", what.c_str());

    const std::vector<std::string> enc_cmd = {tools.encoder.string(), "-point_cloud", "-i", in_ply.string(), "-o",
                                              drc.string(), "-qp", std::to_string(qp), "-cl",
                                              std::to_string(kDracoCompressionLevel)};
    const std::vector<std::string> dec_cmd = {tools.decoder.string(), "-i", drc.string(), "-o", out_ply.string()};
    std::vector<double> enc_times, dec_times;
    bool failed = false;
    for (int k = 0; k < repeat && !failed; ++k) {
      auto t = run_timed(enc_cmd, log);
      if (!t) {
        note("error: %s: encode: %s", what.c_str(), t.status().to_string().c_str());
        failed = true;
      } else {
        enc_times.push_back(*t);
      }
    }
    std::error_code ec;
    const std::uintmax_t drc_size = failed ? 0 : fs::file_size(drc, ec);
    if (!failed && ec) {
      note("error: %s: %s: %s", what.c_str(), drc.c_str(), ec.message().c_str());
      failed = true;
    }
    for (int k = 0; k < repeat && !failed; ++k) {
      auto t = run_timed(dec_cmd, log);
      if (!t) {
        note("error: %s: decode: %s", what.c_str(), t.status().to_string().c_str());
        failed = true;
      } else {
        dec_times.push_back(*t);
      }
    }
    if (failed) continue;
    auto decoded = relief::read_ply(out_ply.string());
    if (!decoded) {
      note("error: %s: reading the decoded PLY: %s", what.c_str(), decoded.status().to_string().c_str());
      continue;
    }
    if (decoded->empty()) {
      note("error: %s: decoded cloud is empty", what.c_str());
      continue;
    }
    for (relief::Vec3d& p : decoded->positions) {
      p.x += box.min.x;
      p.y += box.min.y;
      p.z += box.min.z;
    }
    auto metrics = relief::compare_clouds(cloud, *decoded, relief::MetricsOptions{});
    if (!metrics) {
      note("error: %s: compare: %s", what.c_str(), metrics.status().to_string().c_str());
      continue;
    }
    row.points_out = decoded->size();
    row.bytes = static_cast<std::size_t>(drc_size);
    row.bpp = 8.0 * static_cast<double>(drc_size) / static_cast<double>(cloud.size());
    fill_metrics(row, *metrics);
    row.enc_mpts_s = mpts_per_s(cloud.size(), median(enc_times));
    row.dec_seconds = median(dec_times);
    row.dec_mpts_s = mpts_per_s(decoded->size(), row.dec_seconds);
    out.line(csv_line(row));
    rows.push_back(std::move(row));
  }
  return rows;
}

int main(int argc, char** argv) {
  relief::retain_freed_memory();  // as the relief CLI does (relief/types.h)
  const auto start = BenchClock::now();
  bool help = false;
  const std::optional<Options> parsed = parse_options(argc, argv, help);
  if (help) {
    std::fputs(kUsage, stdout);
    return 0;
  }
  if (!parsed) return 2;
  const Options& opt = *parsed;

  Output out;
  if (!opt.csv_path.empty()) {
    std::string error;
    if (!out.open_copy(opt.csv_path, error)) {
      std::fprintf(stderr, "codec: cannot write --csv file %s\n", error.c_str());
      return 2;
    }
  }

  // No data is not a failure: the benchmark runs wherever the shared files are.
  std::error_code ec;
  if (!fs::is_directory(opt.data_dir, ec)) {
    note("skipped: data directory %s absent", opt.data_dir.c_str());
    out.line("# skipped: data directory " + opt.data_dir + " absent");
    return 0;
  }
  const std::vector<fs::path> files = find_point_files(opt.data_dir, opt.file_filters);
  if (files.empty()) {
    note("skipped: no matching .ply files under %s", opt.data_dir.c_str());
    out.line("# skipped: no matching .ply files under " + opt.data_dir);
    return 0;
  }
  std::string anchors_dir = opt.anchors_dir;
  if (!fs::is_directory(anchors_dir, ec)) {
    note("note: anchors directory %s absent; no G-PCC comparison", anchors_dir.c_str());
    anchors_dir.clear();
  }

  std::optional<DracoTools> draco;
  if (opt.draco) {
    auto enc = find_on_path("draco_encoder");
    auto dec = find_on_path("draco_decoder");
    if (enc && dec) {
      draco = DracoTools{*enc, *dec};
    } else {
      note("note: draco_encoder/draco_decoder not on PATH (Debian package 'draco'); Draco rows skipped, "
           "the summary compares with the anchors' Draco rows");
    }
  }

  if (opt.mode != "resample") {
    BoundedBenchOptions b;
    b.repeat = opt.repeat;
    run_bounded_bench(out, files, anchors_dir, b);
    if (opt.mode == "bounded") {
      out.linef("# total runtime %.1f s", seconds_between(start, BenchClock::now()));
      return 0;
    }
  }
  const std::vector<ReliefConfig> grid = relief_grid(opt.quick);
  note("bench/codec: %zu file(s), %zu relief configurations each, %s, repeat %d", files.size(), grid.size(),
       draco ? "draco on" : "draco off", opt.repeat);
  out.line(csv_header());

  std::vector<FileSummaryInput> summaries;
  for (const fs::path& path : files) {
    const std::string stem = path.stem().string();
    const auto t_file = BenchClock::now();
    auto loaded = relief::read_ply(path.string());
    if (!loaded) {
      note("error: %s", loaded.status().to_string().c_str());
      continue;
    }
    relief::PointCloud cloud = std::move(loaded).value();
    if (cloud.empty()) {
      note("error: %s: no points", path.c_str());
      continue;
    }
    // The peers (anchors, Draco here) code xyz + RGB only; coding intensity as
    // well would charge Relief for an attribute nobody else carries.
    if (!opt.keep_intensity) cloud.intensities.clear();
    const double c0 = relief::suggest_cell_size(cloud, kMapResolution);
    note("%s: %zu points%s%s, c0 = %.6g", stem.c_str(), cloud.size(), cloud.has_colors() ? ", rgb" : "",
         cloud.has_intensity() ? ", intensity" : "", c0);

    FileSummaryInput summary;
    summary.stem = stem;
    summary.points = cloud.size();
    summary.has_colour = cloud.has_colors();
    summary.anchors_dir = anchors_dir;
    for (std::size_t k = 0; k < grid.size(); ++k) {
      auto row = run_relief(cloud, stem, c0, grid[k], opt.repeat);
      if (!row) continue;
      note("  [%zu/%zu] %s: %.4f bpp, rmse_snn %.4g", k + 1, grid.size(), row_label(*row).c_str(), row->bpp,
           row->rmse_snn);
      out.line(csv_line(*row));
      summary.rows.push_back(std::move(*row));
    }
    if (draco) {
      std::vector<BenchRow> draco_rows = run_draco(cloud, stem, *draco, opt.repeat, out);
      summary.draco_measured = !draco_rows.empty();
      for (BenchRow& r : draco_rows) summary.rows.push_back(std::move(r));
    }
    note("%s done in %.1f s", stem.c_str(), seconds_between(t_file, BenchClock::now()));
    summaries.push_back(std::move(summary));
  }

  out.line("#");
  out.line("# SUMMARY. bpp = 8 x bytes / input points; rmse_snn in coordinate units (metres);");
  out.line("# <codec>_bpp = that codec's bpp at the same rmse_snn, log-log interpolated on its Pareto front;");
  out.line("# relief/<codec> < 1 means Relief needs fewer bits for the same error.");
  for (const FileSummaryInput& s : summaries) print_file_summary(out, s);
  out.line("#");
  out.linef("# total runtime %.1f s", seconds_between(start, BenchClock::now()));
  return 0;
}
