#include "query_output.h"

#include "relief/codec.h"

#include <atomic>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>

#include "relief/io.h"

namespace relief::cli {

namespace {

// Whether every source of the archive is a LAS/LAZ file whose header scale
// and offset are the archive's grid (step, origin): then each point's
// integer on that grid is the source's, which fits 32 bits at that offset.
bool grid_is_las_sources(const ArchiveInfo& info, const Vec3d& step, const Vec3d& origin) {
  if (info.sources.empty()) return false;
  const auto same = [](double a, double b) {
    return std::fabs(a - b) <= 1e-12 * std::max(std::fabs(a), std::fabs(b));
  };
  for (const ArchiveSource& s : info.sources) {
    const std::vector<std::uint8_t>& h = s.las.header;
    if (h.size() < 179) return false;  // not LAS, or no header block kept
    double v[6];
    std::memcpy(v, h.data() + 131, sizeof v);  // x y z scale, x y z offset (little endian)
    if constexpr (std::endian::native != std::endian::little) return false;
    if (!same(v[0], step.x) || !same(v[1], step.y) || !same(v[2], step.z) || !same(v[3], origin.x) ||
        !same(v[4], origin.y) || !same(v[5], origin.z)) {
      return false;
    }
  }
  return true;
}

// What the query read, for its summary line: the level of detail of its rows
// (a range when a max_points plan gave them different ones), the pyramid
// level it read from, and whether it thinned its points to the limit.
std::string plan_summary(const QueryStats& stats, const QueryOptions& options) {
  std::string text = "lod ";
  if (stats.lod_max == 0) {
    text += std::to_string(options.lod);  // no row was read
  } else if (stats.lod_min == stats.lod_max) {
    text += std::to_string(stats.lod_min);
  } else {
    text += std::to_string(stats.lod_min) + "-" + std::to_string(stats.lod_max) + " by chunk";
  }
  if (stats.pyramid_level > 0) text += ", up to pyramid level " + std::to_string(stats.pyramid_level);
  if (stats.thinned) text += ", thinned evenly to " + std::to_string(options.max_points);
  return text;
}

}  // namespace

QueryOptions query_options_from(Args& args, const std::string& command) {
  QueryOptions q;
  q.lod = static_cast<std::uint32_t>(args.get_int("--lod", 1, 1, kMaxLod));
  q.max_points = static_cast<std::uint64_t>(args.get_int("--max-points", 0, 1, 1LL << 50));
  if (args.has("--max-points") && args.has("--lod")) args.add_error("give --lod or --max-points, not both");
  q.threads = static_cast<unsigned>(args.get_int("--threads", 0, 0, 1024));
  q.skip_corrupt = args.has("--skip-corrupt");
  q.first_returns = args.has("--first-returns");
  q.last_returns = args.has("--last-returns");
  if (const auto classes = args.get("--class")) {
    // "2,6": LAS classification values 0..255.
    std::size_t start = 0;
    const std::string& text = *classes;
    while (start <= text.size()) {
      std::size_t end = text.find(',', start);
      if (end == std::string::npos) end = text.size();
      const std::string item = text.substr(start, end - start);
      unsigned value = 0;
      const auto [p, ec] = std::from_chars(item.data(), item.data() + item.size(), value);
      if (item.empty() || ec != std::errc{} || p != item.data() + item.size() || value > 255) {
        args.add_error("--class: expected classification values 0..255 separated by commas, got '" + text + "'");
        break;
      }
      q.classes.push_back(static_cast<std::uint8_t>(value));
      start = end + 1;
    }
  }
  if (const auto list = args.get("--attributes")) {
    auto set = parse_attribute_set(*list);
    if (set) {
      q.attributes = *set;
    } else {
      args.add_error("--attributes: " + set.status().message());
    }
  }
  if (const auto text = args.get("--polygon")) {
    auto polygon = Polygon2D::from_arg(*text);
    Status crs_status;
    if (polygon) {
      if (const auto crs = args.get("--polygon-crs")) crs_status = polygon->set_crs(*crs, "--polygon-crs");
    }
    if (!polygon) {
      args.add_error("--polygon: " + polygon.status().message());
    } else if (!crs_status) {
      args.add_error(crs_status.message());
    } else {
      q.polygon = std::make_shared<const Polygon2D>(std::move(polygon).value());
    }
  } else if (args.get("--polygon-crs")) {
    args.add_error("--polygon-crs needs --polygon");
  }
  q.on_warning = [command](const std::string& w) { std::cerr << "relief " << command << ": warning: " << w << "\n"; };
  return q;
}


int run_query_to_file(const std::string& command, const std::string& archive_path, const Box3d* box,
                      const std::string& out_path, const QueryOptions& options, bool quiet) {
  // Ctrl-C or SIGTERM stops the query at the next batch; the writer then
  // goes without a commit, which removes its temporary file (exit 130).
  // Caught from here on, before the writer creates that file.
  const std::atomic<bool>* cancel = install_interrupt_flag();
  auto reader = ArchiveReader::open(archive_path);
  if (!reader) return fail(command, reader.status());
  const ArchiveInfo& info = (*reader)->info();
  const AttributeSet& want = options.attributes;
  if (Status s = check_attributes(info, want, archive_path); !s) return fail(command, s);
  // The LAS attributes written: those asked for, the colour low bytes with the colours.
  const std::uint32_t las_kept = info.las_attributes & want.las_kept();
  WriterOptions w;
  w.read_from = archive_path;
  w.threads = options.threads;
  w.colors = info.has_colors && want.colors;
  w.intensity = info.has_intensity && want.intensity;
  w.crs = info.crs;
  w.crs_source = info.crs_source;
  w.expected_bounds = info.bounds;
  w.las_attributes = las_kept;
  w.las_point_format = info.las_point_format;
  w.las_version_minor = info.las_version_minor;
  if ((las_kept & kLasExtraBytes) != 0) {
    w.extra_bytes_vlr = info.extra_bytes_vlr;
    w.extra_bytes_size = info.extra_bytes_size;
  }
  w.las_colors_8bit = info.las_colors_8bit;
  w.las_gps_time_type = info.las_gps_time_type;
  for (const ArchiveSource& s : info.sources) {
    if (!s.las.empty()) w.las_sources.push_back(s.las);
  }
  // An error-bounded archive's points lie on its grid: LAS output uses that
  // grid as scale and offset, so a LAS source's integers come back as they were.
  if (auto params = encode_params_from_string(info.codec_params); params && params->bound) {
    w.grid_scale = params->bound->step;
    w.grid_offset = params->bound->origin;
    w.grid_offset_exact = grid_is_las_sources(info, params->bound->step, params->bound->origin);
  }
  if (box != nullptr && !info.bounds.empty()) {
    // The written data lies in the box and in the archive.
    Box3d b = info.bounds;
    b.min = {std::max(b.min.x, box->min.x), std::max(b.min.y, box->min.y), std::max(b.min.z, box->min.z)};
    b.max = {std::min(b.max.x, box->max.x), std::min(b.max.y, box->max.y), std::min(b.max.z, box->max.z)};
    if (!b.empty()) w.expected_bounds = b;
  }
  auto writer = open_point_writer(out_path, w);
  if (!writer) return fail(command, writer.status());
  // What the output format cannot hold is said, not dropped silently: LAS and
  // LAZ carry every LAS attribute, PLY too (16-bit colours as ushort
  // properties), text every one but the colour low bytes (its colours are
  // 8-bit): a property or column each.
  std::string ext = std::filesystem::path(out_path).extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".las" && ext != ".laz" && ext != ".ply") {
    const std::uint32_t dropped = las_kept & kLasColorLow;
    if (dropped != 0) {
      std::string names = las_attribute_list(dropped);
      for (std::size_t at = names.find(','); at != std::string::npos; at = names.find(',', at + 2)) {
        names.replace(at, 1, ", ");
      }
      std::cerr << "relief " << command << ": warning: " << (out_path == "-" ? "standard output" : out_path)
                << ": this format does not carry the archive's " << names
                << " (write .las or .laz to keep every LAS attribute)\n";
    }
  }
  const auto t0 = now_ns();
  // The share is known for a whole archive at full detail without filters.
  const bool whole = box == nullptr && options.lod == 1 && options.max_points == 0 && options.classes.empty() &&
                     !options.first_returns && !options.last_returns && !options.polygon;
  QueryProgress progress(out_path == "-" ? "standard output" : out_path, whole ? info.decoded_points : 0,
                         quiet || out_path == "-");
  const PointSink sink = [&](const PointCloud& batch) {
    if (cancel->load()) return io_error(out_path + ": interrupted");
    Status s = (*writer)->write(batch);
    progress.count(batch.size());
    return s;
  };
  auto stats = box != nullptr ? (*reader)->query(*box, options, sink) : (*reader)->query_all(options, sink);
  end_progress_line();
  if (cancel->load()) {
    writer->reset();  // removes the temporary file
    return interrupted(command, out_path == "-" ? std::string() : "; " + out_path + " not written");
  }
  if (!stats) return fail(command, stats.status());
  if (Status s = (*writer)->finish(); !s) return fail(command, s);
  for (const std::string& said : (*writer)->take_warnings()) {
    std::cerr << "relief " << command << ": warning: " << said << "\n";
  }
  const double secs = seconds_since(t0);
  if (!quiet && out_path != "-") {
    std::fprintf(
        stderr,
        "%s: %llu points from %llu of %llu chunks (%s read, %llu skipped), %s, %.3f s, %.2f M points/s\n",
        out_path.c_str(), static_cast<unsigned long long>(stats->points),
        static_cast<unsigned long long>(stats->chunks_decoded),
        static_cast<unsigned long long>(info.chunk_count), format_bytes(stats->blob_bytes_read).c_str(),
        static_cast<unsigned long long>(stats->chunks_skipped), plan_summary(*stats, options).c_str(), secs,
        secs > 0 ? static_cast<double>(stats->points) / secs * 1e-6 : 0.0);
  }
  return kExitOk;
}

}  // namespace relief::cli
