// compress_files / append_files: an external distribution sort into bucket
// files, then chunk-by-chunk parallel encoding into the archive.
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <tuple>
#include <unordered_map>

#include "core/grid_index.h"
#include "core/memory.h"
#include "core/parallel.h"
#include "ingest/bucket_encode.h"
#include "ingest/bucket_files.h"
#include "ingest/chunk_pipeline.h"
#include "ingest/ingest_common.h"
#include "ingest/las_columns.h"
#include "ingest/lazy_reader.h"
#include "ingest/prefetch.h"
#include "ingest/slice_pool.h"
#include "ingest/spool.h"
#include "relief/archive.h"
#include "relief/crs.h"
#include "relief/ingest.h"

namespace relief {

namespace ingest {

namespace {

// The shortest text that reads back as v, for messages.
std::string number_text(double v) {
  char buf[32];
  const std::to_chars_result r = std::to_chars(buf, buf + sizeof buf, v, std::chars_format::fixed);
  return r.ec == std::errc() ? std::string(buf, r.ptr) : std::to_string(v);
}

// Memory per point of the first batch, read before the archive exists to derive
// the cell size: the points (31) and suggest_cell_size's keys and radix
// scratch (32).
constexpr std::uint64_t kFirstBatchBytesPerPoint = 31 + 32;
// Cell when the inputs hold no point to measure a density from (1 unit,
// metres for most data; the bounded mode's base layer multiplies it by
// kBaseCellFactor); the chunk edge follows as for any cell. README "Inputs".
constexpr double kEmptyInputCellSize = 1.0;
// Bytes per point assumed for inputs whose header gives no count (ASCII).
constexpr std::uint64_t kUnknownBytesPerPoint = 12;

std::string gps_time_kind(GpsTimeType t) {
  return t == GpsTimeType::kStandard ? "adjusted standard GPS time" : "GPS week time";
}

// Refusal text for two sources whose GPS times count differently.
std::string gps_time_clash(const std::string& path, GpsTimeType type, const std::string& other, GpsTimeType other_type) {
  return path + " has " + gps_time_kind(type) + " but " + other + " has " + gps_time_kind(other_type) +
         " (LAS global encoding bit 0); one archive holds one kind of GPS time";
}

// GPS times of an input that does not say what they count, taken as the
// archive's GPS week time: each must be seconds of a week (0 <= t < 604800),
// or it is another kind of time, which the archive would write back wrong.
Status check_week_times(const PointCloud& batch, const InputSet& in, std::size_t reader,
                        const std::string& source, std::uint64_t first_index) {
  if (in.las_gps_time_type != GpsTimeType::kWeek || reader >= in.time_kind_unknown.size() ||
      !in.time_kind_unknown[reader]) {
    return Status::ok();
  }
  constexpr double kSecondsPerWeek = 604800.0;
  for (std::size_t i = 0; i < batch.las.gps_time.size(); ++i) {
    const double t = batch.las.gps_time[i];
    if (t >= 0 && t < kSecondsPerWeek) continue;
    char text[64];
    std::snprintf(text, sizeof text, "%.17g", t);
    return invalid_argument(source + ": point " + std::to_string(first_index + i) + ": GPS time " + text +
                            " is not seconds of a GPS week (0 to 604800), the kind of " + in.gps_time_from +
                            "'s; one archive holds one kind of GPS time");
  }
  return Status::ok();
}

std::uint64_t file_size_or_zero(const std::string& path) {
  std::error_code ec;
  const auto s = std::filesystem::file_size(path, ec);
  return ec ? 0 : static_cast<std::uint64_t>(s);
}

}  // namespace

bool same_crs(const std::string& a, const std::string& b) {
  if (a == b) return true;
  Result<bool> equivalent = crs_equivalent(a, b);
  return equivalent.is_ok() && *equivalent;
}

ReaderOptions ingest_reader_options(const IngestOptions& options) {
  ReaderOptions r = options.reader;
  r.color_sample_memory = std::max<std::uint64_t>(options.memory_budget, kMinMemoryBudget) / 8;
  r.decode_threads = resolve_threads(options.threads);
  return r;
}

Result<InputSet> open_inputs(const std::vector<std::string>& inputs, const ReaderOptions& reader_options,
                             bool assume_crs, const std::string& crs) {
  if (inputs.empty()) return invalid_argument("no input files");
  std::vector<std::string> without_crs;
  InputSet set;
  if (!crs.empty()) {
    RELIEF_ASSIGN_OR_RETURN(set.crs, crs_to_wkt2(crs, "--crs"));
    set.crs_from = "--crs";
  }
  set.colors = true;
  set.intensity = true;
  // An input with colour (intensity) and one without: the archive keeps one
  // attribute set, so the colours (intensities) go, with a warning.
  std::string colour_with, colour_without, intensity_with, intensity_without;
  for (const std::string& path : inputs) {
    // Open to check it and take its info, then closed until it is read.
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> r, open_lazy_reader(path, reader_options));
    const PointStreamInfo& info = r->info();
    set.colors = set.colors && info.has_colors;
    set.intensity = set.intensity && info.has_intensity;
    std::string& colour_name = info.has_colors ? colour_with : colour_without;
    if (colour_name.empty()) colour_name = path;
    std::string& intensity_name = info.has_intensity ? intensity_with : intensity_without;
    if (intensity_name.empty()) intensity_name = path;
    if (info.point_count) {
      set.estimated_points += *info.point_count;
    } else {
      set.estimated_points += file_size_or_zero(path) / kUnknownBytesPerPoint;
    }
    if (info.point_count) set.known_total += *info.point_count;
    set.all_counts_known = set.all_counts_known && info.point_count.has_value();
    if (!crs.empty()) {
      if (!info.crs.empty() && !same_crs(set.crs, info.crs)) {
        set.warnings.push_back(path + " has the CRS " + crs_label(info.crs) + "; --crs gives the archive " +
                               crs_label(set.crs) + " (the coordinates are not converted)");
      }
    } else if (info.crs.empty()) {
      without_crs.push_back(path);
    } else if (set.crs.empty()) {
      set.crs = info.crs;
      set.crs_from = path;
    } else if (!same_crs(set.crs, info.crs)) {
      const std::string both = path + " has the CRS " + crs_label(info.crs) + " but " + set.crs_from + " has " +
                               crs_label(set.crs);
      if (!assume_crs) {
        return invalid_argument(both + "; one archive holds one CRS (--assume-crs takes the first input's for all)");
      }
      set.warnings.push_back(both + "; --assume-crs: the archive takes " + crs_label(set.crs));
    }
    set.las_attributes |= info.las_attributes;
    // LAS attributes from a non-LAS input (a CSV classification column) may
    // hold values only the LAS 1.4 formats can: the archive then names 6.
    constexpr int kFirstExtendedFormat = 6;
    const int format = info.las_point_format < 0 && info.las_attributes != 0 ? kFirstExtendedFormat
                                                                              : info.las_point_format;
    set.las_point_format = std::max(set.las_point_format, format);
    set.las_version_minor = std::max(set.las_version_minor, info.las_version_minor);
    if ((info.las_attributes & kLasExtraBytes) != 0) {
      if (set.extra_bytes_from.empty()) {
        set.extra_bytes_vlr = info.extra_bytes_vlr;
        set.extra_bytes_size = info.extra_bytes_size;
        set.extra_bytes_from = path;
      } else if (set.extra_bytes_vlr != info.extra_bytes_vlr || set.extra_bytes_size != info.extra_bytes_size) {
        return invalid_argument(path + " has " + std::to_string(info.extra_bytes_size) +
                                " extra bytes per point described by a different Extra Bytes VLR than " +
                                set.extra_bytes_from + " (" + std::to_string(set.extra_bytes_size) +
                                " bytes); one archive holds one extra bytes layout");
      }
    }
    if (info.las_gps_time_type != GpsTimeType::kUnknown) {
      if (set.gps_time_from.empty()) {
        set.las_gps_time_type = info.las_gps_time_type;
        set.gps_time_from = path;
      } else if (set.las_gps_time_type != info.las_gps_time_type) {
        return invalid_argument(gps_time_clash(path, info.las_gps_time_type, set.gps_time_from,
                                               set.las_gps_time_type));
      }
    }
    set.time_kind_unknown.push_back((info.las_attributes & kLasGpsTime) != 0 &&
                                    info.las_gps_time_type == GpsTimeType::kUnknown);
    ArchiveSource src;
    src.path = path;
    src.format = info.format;
    src.crs = info.crs_source.empty() ? info.crs : info.crs_source;
    src.las = info.las_metadata;
    set.sources.push_back(src);
    set.readers.push_back(std::move(r));
  }
  set.colors_missing_from = colour_without;
  set.intensity_missing_from = intensity_without;
  for (const auto& [what, with, without] : {std::tuple<const char*, const std::string&, const std::string&>{
                                                "colours", colour_with, colour_without},
                                            {"intensities", intensity_with, intensity_without}}) {
    if (!with.empty() && !without.empty()) {
      set.warnings.push_back(with + " has " + what + " but " + without +
                             " has none: one archive holds one attribute "
                             "set, so the " +
                             what + " of every input are dropped (compress them apart to keep them)");
    }
  }
  // Colour low bytes only travel with colours.
  if (!set.colors) set.las_attributes &= ~std::uint32_t{kLasColorLow};
  if (!set.crs.empty()) {
    for (const std::string& path : without_crs) {
      set.warnings.push_back(path + " has no CRS; the archive takes " + crs_label(set.crs) + " of " + set.crs_from);
    }
  }
  return set;
}

void conform_attributes(PointCloud& batch, bool colors, bool intensity) {
  if (!colors) batch.colors.clear();
  if (!intensity) batch.intensities.clear();
}

Status stage_points(PointCloud& batch, double coordinate_limit, const std::string& source, std::uint64_t first_index,
                    bool colors, bool intensity, const EncodeParams& params) {
  RELIEF_RETURN_IF_ERROR(check_coordinates(batch, coordinate_limit, source, first_index));
  conform_attributes(batch, colors, intensity);
  if (params.bound) RELIEF_RETURN_IF_ERROR(snap_to_grid(batch, *params.bound, source, first_index));
  return Status::ok();
}

void widen_intensity_range(const PointCloud& batch, float& lo, float& hi) {
  for (const float v : batch.intensities) {
    lo = std::min(lo, v);
    hi = std::max(hi, v);
  }
}

EncodeParams with_intensity_range(const EncodeParams& params, bool intensity, float lo, float hi) {
  EncodeParams p = params;
  if (intensity && lo <= hi) p.intensity_range = std::make_pair(lo, hi);
  return p;
}

Result<std::int64_t> begin_scan(Archive& archive, const std::vector<ArchiveSource>& sources, bool colors,
                                bool intensity, const std::string& crs) {
  ScanAttributes attributes;
  attributes.has_colors = colors;
  attributes.has_intensity = intensity;
  attributes.crs = crs;
  return archive.begin_scan(sources, attributes);
}

Status finish_scan(Archive& archive, std::int64_t scan_id, bool colors, bool intensity, const std::string& crs) {
  return archive.finish_scan(scan_id, colors, intensity, crs);
}

void conform_attributes(PointCloud& batch, const InputSet& in) {
  conform_attributes(batch, in.colors, in.intensity);
  conform_las(batch, in.las_attributes, in.extra_bytes_size);
}

ScanAttributes scan_attributes(const InputSet& in) {
  ScanAttributes a;
  a.has_colors = in.colors;
  a.has_intensity = in.intensity;
  a.crs = in.crs;
  a.las_attributes = in.las_attributes;
  a.las_point_format = in.las_point_format;
  a.las_version_minor = in.las_version_minor;
  a.extra_bytes_vlr = in.extra_bytes_vlr;
  a.extra_bytes_size = in.extra_bytes_size;
  // 8-bit levels only when every LAS input with colours stored them so (or
  // had its 16-bit levels split as such: InputSet::split_wide_levels).
  a.las_colors_8bit = all_8bit_levels(colour_sources(in));
  a.las_gps_time_type = in.las_gps_time_type;
  return a;
}

std::vector<ColourSource> colour_sources(const InputSet& in) {
  std::vector<ColourSource> out;
  for (const auto& reader : in.readers) {
    const PointStreamInfo& r = reader->info();
    // Split 16-bit levels are 8-bit ones for the archive's rule.
    if ((r.las_attributes & kLasColorLow) != 0) {
      out.push_back({r.path, r.las_colors_8bit || in.split_wide_levels, r.las_colors_all_zero});
    }
  }
  return out;
}

void split_wide_levels(PointCloud& batch, const PointReader& reader) {
  const PointStreamInfo& info = reader.info();
  const std::size_t n = batch.size();
  if ((info.las_attributes & kLasColorLow) == 0 || info.las_colors_8bit || batch.colors.size() != n ||
      batch.las.color_low.size() != n) {
    return;
  }
  for (std::size_t i = 0; i < n; ++i) {
    Rgb8& c = batch.colors[i];
    Rgb8& l = batch.las.color_low[i];
    split_8bit_level(las_color_level(c.r, l.r, false), c.r, l.r);
    split_8bit_level(las_color_level(c.g, l.g, false), c.g, l.g);
    split_8bit_level(las_color_level(c.b, l.b, false), c.b, l.b);
  }
}

bool all_8bit_levels(const std::vector<ColourSource>& sources) {
  return !sources.empty() &&
         std::all_of(sources.begin(), sources.end(), [](const ColourSource& s) { return s.levels_8bit; });
}

std::vector<std::string> colour_rule_warnings(bool archive_rgb, bool archive_8bit,
                                              const std::vector<ColourSource>& sources) {
  std::vector<std::string> out;
  std::vector<std::string> narrow, wide;
  for (const ColourSource& s : sources) {
    // Levels all 0 stay 0 scaled (0 x 257): nothing to warn of.
    if (s.levels_8bit && s.all_zero) continue;
    (s.levels_8bit ? narrow : wide).push_back(s.path);
  }
  const bool new_8bit = wide.empty();
  if (archive_rgb ? archive_8bit && new_8bit : new_8bit) return out;
  const std::string scaled = "come back from LAS and LAZ output scaled to 16 bits (level x 257)";
  if (archive_rgb && archive_8bit) {
    out.push_back(wide.front() + " has 16-bit colour levels: the archive's earlier points, whose sources stored " +
                  "8-bit levels in their 16-bit colour fields, now " + scaled);
  }
  const std::string why = !wide.empty() ? wide.front() + " has 16-bit levels" : "the archive holds 16-bit levels";
  for (std::size_t i = 0; i < narrow.size() && i < 3; ++i) {
    out.push_back(narrow[i] + " stores 8-bit levels in its 16-bit colour fields, but " + why + ": its levels " +
                  scaled);
  }
  if (narrow.size() > 3) {
    out.push_back(std::to_string(narrow.size() - 3) + " more inputs store 8-bit levels: theirs " + scaled + " too");
  }
  return out;
}

namespace {

// The warnings above for a scan about to begin in `archive`, its readers
// having decided their rule.
std::vector<std::string> colour_rule_warnings(const Archive& archive, const InputSet& in) {
  const Result<ArchiveInfo> info = archive.info();
  if (!info) return {};
  return colour_rule_warnings((info->las_attributes & kLasColorLow) != 0, info->las_colors_8bit, colour_sources(in));
}

}  // namespace

namespace {

// The memory plan of run_ingest for these inputs (their LAS attributes as
// the archive will carry them).
IngestBudget ingest_plan(const InputSet& in, const IngestOptions& options, bool bounded) {
  const std::uint64_t las_bytes = las_record_bytes(in.las_attributes, in.extra_bytes_size);
  return plan_ingest_budget(options.memory_budget, resolve_threads(options.threads), las_bytes, in.estimated_points,
                            bounded);
}

// Whether run_ingest holds the whole input in memory (no bucket files).
bool whole_input_in_memory(const InputSet& in, const IngestBudget& plan) {
  return in.all_counts_known && in.known_total <= plan.in_memory_points;
}

}  // namespace

Result<IngestResult> run_ingest(Archive& archive, const ArchiveGrid& grid, const EncodeParams& params,
                                InputSet& in, PointCloud pending, const IngestOptions& options,
                                const std::string& tmp_parent) {
  const auto t0 = std::chrono::steady_clock::now();
  // Only the error-bounded codec keeps per-point LAS attributes; the
  // resampling mode keeps the majority classification of each map pixel
  // (chunk format 4) and nothing else, so its archives record at most that.
  if (!params.bound) {
    in.las_attributes &= kLasClassification;
    in.extra_bytes_size = 0;
    in.extra_bytes_vlr.clear();
  }
  // Error-bounded archives must not depend on the budget: chunks are encoded
  // whole (bucket slices hold whole buckets) and split by a fixed rule.
  const bool bounded = params.bound.has_value();
  const IngestBudget plan = ingest_plan(in, options, bounded);
  const ArchiveGrid* split_grid = bounded ? &grid : nullptr;
  const std::uint64_t task_points =
      bounded ? bounded_split_points(options.split_points, in.las_attributes, in.extra_bytes_size) : plan.part_points;

  Progress progress(options.progress, in.all_counts_known ? in.known_total : 0);
  const auto cancelled = [&] { return options.cancel != nullptr && options.cancel->load(); };

  // Points beyond this would overflow chunk keys or lose the cell's precision.
  const double coordinate_limit = max_coordinate_magnitude(params.cell_size, grid.chunk_edge);
  // Points staged so far per input (the stage runs once per batch, in input
  // order): the index of a refused point within its file.
  std::vector<std::uint64_t> staged_per_source(in.readers.size(), 0);
  std::uint64_t points_read = 0;
  float intensity_lo = std::numeric_limits<float>::infinity();
  float intensity_hi = -std::numeric_limits<float>::infinity();
  // Reads every input. A background thread reads ahead and runs `stage` on
  // each batch (after dropping attributes the archive does not carry); the
  // calling thread hands the staged batches to `sink` in input order.
  // With the input read ahead (InputSet::read_ahead) its batches are staged
  // here in turn, `prepare` first (the in-memory path's room for them).
  const auto read_all = [&](const std::function<Status(ReadBatch&)>& stage,
                            const std::function<Status(ReadBatch&)>& sink,
                            const std::function<void(const ReadBatch&)>& prepare = nullptr) -> Status {
    const auto full_stage = [&](ReadBatch& b) -> Status {
      RELIEF_RETURN_IF_ERROR(stage_points(b.points, coordinate_limit, in.sources[b.reader].path,
                                          staged_per_source[b.reader], in.colors, in.intensity, params));
      RELIEF_RETURN_IF_ERROR(
          check_week_times(b.points, in, b.reader, in.sources[b.reader].path, staged_per_source[b.reader]));
      staged_per_source[b.reader] += b.points.size();
      if (in.split_wide_levels) split_wide_levels(b.points, *in.readers[b.reader]);
      // LAS attributes the archive carries and this input lacks: zeros.
      conform_las(b.points, in.las_attributes, in.extra_bytes_size);
      widen_intensity_range(b.points, intensity_lo, intensity_hi);
      return stage(b);
    };
    std::vector<std::uint64_t> per_source(in.readers.size(), 0);
    const auto take = [&](ReadBatch& b) -> Status {
      RELIEF_RETURN_IF_ERROR(sink(b));
      per_source[b.reader] += b.points.size();
      points_read += b.points.size();
      progress.update("reading", points_read, 0, 0);
      if (cancelled()) return io_error("interrupted");
      return Status::ok();
    };
    ReadBatch batch;
    batch.points = std::move(pending);
    std::uint64_t first = 0;
    if (!batch.points.empty()) {
      // The batch read up front (for the cell size) is the first of input 0.
      RELIEF_RETURN_IF_ERROR(full_stage(batch));
      RELIEF_RETURN_IF_ERROR(take(batch));
      first = batch.points.size();
      batch = ReadBatch();  // larger than the batches to come: not recycled
    }
    if (!in.read_ahead.empty()) {
      for (ReadBatch& b : in.read_ahead) {
        if (prepare) prepare(b);
        RELIEF_RETURN_IF_ERROR(full_stage(b));
        RELIEF_RETURN_IF_ERROR(take(b));
        b = ReadBatch();  // its memory goes back as the archive's copy grows
      }
      in.read_ahead.clear();
    } else {
      Prefetcher prefetch(in.readers, static_cast<std::size_t>(plan.read_batch), 1, first, full_stage);
      for (;;) {
        RELIEF_ASSIGN_OR_RETURN(const bool more, prefetch.next(batch));
        if (!more) break;
        RELIEF_RETURN_IF_ERROR(take(batch));
      }
    }
    for (std::size_t i = 0; i < in.sources.size(); ++i) in.sources[i].point_count = per_source[i];
    return Status::ok();
  };

  // Every chunk of the scan quantises intensity over the scan's range, so the
  // step does not depend on how the points fall into chunks.
  const auto with_ranges = [&] { return with_intensity_range(params, in.intensity, intensity_lo, intensity_hi); };
  std::int64_t scan_id = 0;
  // Declared before the pipeline: its workers return slices here.
  SlicePool slices(plan.slice_points);
  std::unique_ptr<ChunkPipeline> pipeline;
  // Progress while encoding (called between commits, once the pipeline exists).
  const auto tick = [&] {
    const PipelineTotals t = pipeline->encoded();
    progress.update("encoding", points_read, t.chunks, t.blob_bytes, t.points_in);
  };
  Grouping grouping;
  if (in.all_counts_known && in.known_total <= plan.in_memory_points) {
    // The whole input fits in memory: no temporary files.
    const auto total = static_cast<std::size_t>(in.known_total);
    PointCloud all;
    all.reserve(total, in.colors, in.intensity);
    // Reserved whole, like the arrays above: cover() grows them while the
    // reading thread copies into the part already covered.
    if (in.las_attributes != 0) reserve_las(all.las, total, in.las_attributes, in.extra_bytes_size);
    grouping.ids.reserve(total);
    core::advise_huge_pages(all.positions);
    core::advise_huge_pages(all.colors);
    core::advise_huge_pages(all.intensities);
    core::advise_huge_pages(grouping.ids);
    // First writes to fresh memory are the dearest part of filling `all` (the
    // kernel zeroes every page; on a VM, a slow first touch). This thread,
    // which only keys points, therefore extends `all` (zero-filling it) ahead
    // of the reading thread, which copies each batch into place. The reader is
    // never more than one batch ahead of this thread (queue depth 1), and each
    // batch after the first holds at most `read_batch` points, so covering two
    // batches beyond the one just keyed means it never waits.
    Vec3d* const positions = all.positions.data();
    Rgb8* const colors = all.colors.data();
    float* const intensities = all.intensities.data();
    std::atomic<std::size_t> covered{0};
    const auto cover = [&](std::uint64_t upto) {
      const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(upto, total));
      if (n <= all.positions.size()) return;
      all.positions.resize(n);
      if (in.colors) all.colors.resize(n);
      if (in.intensity) all.intensities.resize(n);
      if (in.las_attributes != 0) resize_las(all.las, n, in.las_attributes, in.extra_bytes_size);
      covered.store(n, std::memory_order_release);
    };
    const auto copy_in = [&](ReadBatch& b) -> Status {
      const PointCloud& batch = b.points;
      const std::size_t n = batch.size();
      if (b.first + n > total) {
        return format_error(in.sources[b.reader].path + ": holds more points than its header says");
      }
      if (b.first + n > covered.load(std::memory_order_acquire)) {
        return internal_error("in-memory ingest: the reader overtook the buffer");
      }
      std::copy(batch.positions.begin(), batch.positions.end(), positions + b.first);
      if (in.colors) std::copy(batch.colors.begin(), batch.colors.end(), colors + b.first);
      if (in.intensity) std::copy(batch.intensities.begin(), batch.intensities.end(), intensities + b.first);
      // The LAS vectors are sized by cover() on this thread's side too, but
      // never reallocated after the first call (reserved below).
      if (in.las_attributes != 0) copy_las(batch.las, all.las, b.first);
      return Status::ok();
    };
    cover(pending.size() + 2 * plan.read_batch);
    RELIEF_RETURN_IF_ERROR(read_all(
        copy_in,
        [&](ReadBatch& b) -> Status {
          cover(b.first + b.points.size() + 2 * plan.read_batch);
          grouping.add(b.points.positions.data(), b.points.size(), grid);
          return Status::ok();
        },
        [&](const ReadBatch& b) { cover(b.first + b.points.size()); }));
    // Headers count the records a reader skips by design (PCD's no-depth
    // NaN points), so those are subtracted, and `all`, covered up to the
    // headers' total, shrinks to the points read.
    std::uint64_t skipped = 0;
    for (const auto& r : in.readers) skipped += r->info().skipped_points;
    if (points_read + skipped != total) {
      std::string names;
      for (const ArchiveSource& src : in.sources) names += (names.empty() ? "" : ", ") + src.path;
      return format_error(names + ": " + std::to_string(points_read) + " points read where the headers declare " +
                          std::to_string(total) +
                          (skipped > 0 ? " (" + std::to_string(skipped) + " skipped as having no depth)" : ""));
    }
    all.resize_points(static_cast<std::size_t>(points_read));
    for (std::string& w : colour_rule_warnings(archive, in)) in.warnings.push_back(std::move(w));
    RELIEF_ASSIGN_OR_RETURN(scan_id, archive.begin_scan(in.sources, scan_attributes(in)));
    pipeline = std::make_unique<ChunkPipeline>(archive, with_ranges(), grid, scan_id, plan.encode_threads,
                                               options.cancel, options.verify_blobs, plan.encode_memory);
    RELIEF_RETURN_IF_ERROR(pipeline->run(make_tasks(all, task_points, grouping, split_grid), tick));
  } else {
    // ---- External distribution sort: every point into its chunk's bucket
    // file. The reading thread keys each batch; this one packs and writes.
    RELIEF_ASSIGN_OR_RETURN(BucketFiles files, BucketFiles::create(tmp_parent, plan.buckets, grid, in.colors,
                                                                   in.intensity, plan.staging_bytes, in.las_attributes,
                                                                   in.extra_bytes_size));
    const auto key_batch = [&](ReadBatch& b) -> Status {
      b.keys.resize(b.points.size());
      grid.keys_of(b.points.positions.data(), b.points.size(), b.keys.data());
      return Status::ok();
    };
    RELIEF_RETURN_IF_ERROR(
        read_all(key_batch, [&](ReadBatch& b) -> Status { return files.append(b.points, b.keys.data()); }));
    RELIEF_RETURN_IF_ERROR(files.finish_writing());
    // ---- Each bucket, slice by slice: group by chunk, encode, store.
    for (std::string& w : colour_rule_warnings(archive, in)) in.warnings.push_back(std::move(w));
    RELIEF_ASSIGN_OR_RETURN(scan_id, archive.begin_scan(in.sources, scan_attributes(in)));
    pipeline = std::make_unique<ChunkPipeline>(archive, with_ranges(), grid, scan_id, plan.encode_threads,
                                               options.cancel, options.verify_blobs, plan.encode_memory);
    BucketEncodeOptions encode;
    encode.whole_chunks = bounded;
    encode.task_points = task_points;
    encode.split_grid = split_grid;
    encode.tmp_parent = tmp_parent;
    encode.cancel = options.cancel;
    RELIEF_RETURN_IF_ERROR(encode_bucket_files(files, grid, *pipeline, slices, plan, encode, tick));
  }
  // The encoders' threads and the recycled slices go before the pyramid is
  // built, so its memory does not stack on theirs.
  const PipelineTotals totals = pipeline->totals();
  pipeline.reset();
  slices.clear();
  core::release_free_memory();  // the encoder threads' arenas keep what they freed otherwise
  // The pyramid before the scan is marked complete: a run killed while
  // building it leaves an incomplete scan whose chunks read as usual.
  RELIEF_ASSIGN_OR_RETURN(const PyramidResult pyramid,
                          build_scan_pyramid(archive, scan_id, points_read, options, tmp_parent, progress));
  RELIEF_RETURN_IF_ERROR(finish_scan(archive, scan_id, in.colors, in.intensity, in.crs));

  IngestResult result = scan_result(totals, points_read, t0, params.cell_size, grid.chunk_edge, scan_id, progress);
  result.pyramid = pyramid;
  if (in.spool != nullptr) result.spooled_bytes = in.spool->bytes_written();
  if (!pyramid.skipped.empty()) result.warnings.push_back(pyramid.skipped);
  result.warnings.insert(result.warnings.end(), in.warnings.begin(), in.warnings.end());
  for (const auto& reader : in.readers) {
    for (const std::string& w : reader->info().warnings) result.warnings.push_back(w);
    result.points_skipped += reader->info().skipped_points;
  }
  return result;
}

Result<PyramidResult> build_scan_pyramid(Archive& archive, std::int64_t scan_id, std::uint64_t points,
                                         const IngestOptions& options, const std::string& tmp_parent,
                                         Progress& progress) {
  const bool build = options.pyramid == PyramidMode::kOn ||
                     (options.pyramid == PyramidMode::kAuto && points >= kPyramidAutoMinPoints);
  if (!build) return PyramidResult{};
  PyramidOptions p;
  p.threads = options.threads;
  p.memory_budget = options.memory_budget;
  p.tmp_dir = tmp_parent;
  p.cancel = options.cancel;
  p.progress = [&](int, std::uint64_t nodes) { progress.update("pyramid", points, nodes, 0, points); };
  Result<PyramidResult> built = build_pyramid(archive, scan_id, p);
  const bool cancelled = options.cancel != nullptr && options.cancel->load();
  if (built || options.pyramid != PyramidMode::kAuto || cancelled || built.status().code() == StatusCode::kIoError) {
    return built;
  }
  // An automatic pyramid is a convenience: the scan is complete without it.
  PyramidResult none;
  none.skipped = "no level-of-detail pyramid: " + built.status().message();
  return none;
}

IngestResult scan_result(const PipelineTotals& totals, std::uint64_t points_read,
                         std::chrono::steady_clock::time_point start, double cell_size, double chunk_edge,
                         std::int64_t scan_id, Progress& progress) {
  IngestResult r;
  r.points_read = points_read;
  r.points_decoded = totals.points_decoded;
  r.chunks_written = totals.chunks;
  r.blob_bytes = totals.blob_bytes;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  r.cell_size = cell_size;
  r.chunk_edge = chunk_edge;
  r.scan_id = scan_id;
  if (totals.exact_intensity_chunks > 0) {
    r.warnings.push_back("the intensity tolerance was not applied to " + std::to_string(totals.exact_intensity_chunks) +
                         " of " + std::to_string(totals.chunks) +
                         " chunks: their intensities are not all whole numbers 0..65535 (they stay exact)");
  }
  progress.finish("done", points_read, r.chunks_written, r.blob_bytes, totals.points_in);
  return r;
}

void Grouping::clear() {
  keys.clear();
  ids.clear();
  lookup.clear();
}

void Grouping::add(const Vec3d* points, std::size_t n, const ArchiveGrid& grid) {
  batch_keys.resize(n);
  grid.keys_of(points, n, batch_keys.data());
  add_keys(batch_keys.data(), n);
}

void Grouping::add_keys(const ChunkKey* point_keys, std::size_t n) {
  const std::size_t base = ids.size();
  ids.resize(base + n);
  // Points in storage order mostly stay in one chunk for a while, so the
  // previous key is checked before the hash map.
  ChunkKey last{};
  std::uint32_t last_id = 0;
  bool have_last = false;
  for (std::size_t i = 0; i < n; ++i) {
    const ChunkKey& k = point_keys[i];
    if (!have_last || !(k == last)) {
      auto [it, inserted] = lookup.try_emplace(k, static_cast<std::uint32_t>(keys.size()));
      if (inserted) keys.push_back(k);
      last = k;
      last_id = it->second;
      have_last = true;
    }
    ids[base + i] = last_id;
  }
}

std::vector<std::uint32_t> Grouping::sort_by_key(std::vector<std::uint64_t>& start) {
  start.assign(keys.size() + 1, 0);
  for (const std::uint32_t id : ids) ++start[id + 1];
  for (std::size_t k = 0; k < keys.size(); ++k) start[k + 1] += start[k];
  order.resize(ids.size());
  std::vector<std::uint64_t> fill(start.begin(), start.end() - 1);
  for (std::size_t i = 0; i < ids.size(); ++i) order[fill[ids[i]]++] = static_cast<std::uint32_t>(i);
  std::vector<std::uint32_t> by_key(keys.size());
  for (std::uint32_t k = 0; k < by_key.size(); ++k) by_key[k] = k;
  std::sort(by_key.begin(), by_key.end(), [&](std::uint32_t a, std::uint32_t b) { return keys[a] < keys[b]; });
  return by_key;
}

void Grouping::add_run(const ChunkKey& key, std::size_t count) {
  auto [it, inserted] = lookup.try_emplace(key, static_cast<std::uint32_t>(keys.size()));
  if (inserted) keys.push_back(key);
  ids.insert(ids.end(), count, it->second);
}

namespace {

// Splits the points idx[0..n) of a chunk into the octants of the sub-cube
// (origin, edge) until each part holds at most `limit` points (or the cube is
// 2^kMaxSplitDepth times smaller than the chunk: identical points). Appends a
// task per non-empty part (the octants as Octants defines them).

void split_octants(const PointCloud& cloud, std::uint32_t* idx, std::size_t n, const ChunkKey& key, const Vec3d& origin,
                   double edge, int depth, const std::uint32_t sub[3], std::uint64_t limit, std::vector<std::uint32_t>& scratch,
                   std::vector<ChunkTask>& tasks) {
  if (n <= limit || depth >= kMaxSplitDepth) {
    ChunkTask t;
    t.key = key;
    t.split_depth = static_cast<std::uint8_t>(depth);
    for (int a = 0; a < 3; ++a) t.sub[a] = sub[a];
    t.source = &cloud;
    t.index = idx;
    t.count = n;
    tasks.push_back(std::move(t));
    return;
  }
  const Octants octants{origin, edge / 2};
  const Vec3d mid = octants.mid();
  const auto octant = [&](std::uint32_t i) { return octants.of(cloud.positions[i], mid); };
  std::size_t start[9] = {};
  for (std::size_t k = 0; k < n; ++k) ++start[octant(idx[k]) + 1];
  for (int o = 0; o < 8; ++o) start[o + 1] += start[o];
  scratch.resize(n);
  std::size_t fill[8];
  for (int o = 0; o < 8; ++o) fill[o] = start[o];
  for (std::size_t k = 0; k < n; ++k) scratch[fill[octant(idx[k])]++] = idx[k];
  std::copy(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(n), idx);
  for (int o = 0; o < 8; ++o) {
    if (start[o + 1] == start[o]) continue;
    std::uint32_t child[3];
    Octants::sub_of(sub, o, child);
    split_octants(cloud, idx + start[o], start[o + 1] - start[o], key, octants.origin_of(o, mid), octants.half,
                  depth + 1, child, limit, scratch, tasks);
  }
}

}  // namespace

std::uint64_t bounded_split_points(std::uint64_t split_points, std::uint32_t las_attributes,
                                   std::uint32_t extra_bytes_size) {
  const std::uint64_t bytes = std::max<std::uint64_t>(1, las_record_bytes(las_attributes, extra_bytes_size));
  const std::uint64_t by_width = std::max(kMinSplitPoints, kMaxChunkAttributeBytes / bytes);
  return std::max<std::uint64_t>(1, std::min(split_points, by_width));
}

std::vector<ChunkTask> make_tasks(const PointCloud& cloud, std::uint64_t part_points, Grouping& g,
                                  const ArchiveGrid* split_grid) {
  // Tasks in key order (deterministic archives), cut into parts.
  std::vector<std::uint64_t> start;
  const std::vector<std::uint32_t> by_key = g.sort_by_key(start);
  std::vector<ChunkTask> tasks;
  std::vector<std::uint32_t> scratch;
  for (std::uint32_t k : by_key) {
    if (split_grid != nullptr) {
      const std::uint32_t whole[3] = {0, 0, 0};
      split_octants(cloud, g.order.data() + start[k], static_cast<std::size_t>(start[k + 1] - start[k]), g.keys[k],
                    split_grid->chunk_box(g.keys[k]).min, split_grid->chunk_edge, 0, whole, part_points, scratch, tasks);
      continue;
    }
    for (std::uint64_t first = start[k]; first < start[k + 1]; first += part_points) {
      ChunkTask t;
      t.key = g.keys[k];
      t.source = &cloud;
      t.index = g.order.data() + first;
      t.count = static_cast<std::size_t>(std::min(part_points, start[k + 1] - first));
      tasks.push_back(std::move(t));
    }
  }
  // Largest first, so the last tasks to finish are short ones and no worker
  // idles long at the end (which chunk lands where does not depend on it).
  std::stable_sort(tasks.begin(), tasks.end(),
                   [](const ChunkTask& a, const ChunkTask& b) { return a.count > b.count; });
  return tasks;
}

std::vector<ChunkTask> group_into_tasks(const PointCloud& cloud, const ArchiveGrid& grid, std::uint64_t part_points,
                                        Grouping& g, bool split_spatially) {
  g.clear();
  g.add(cloud.positions.data(), cloud.size(), grid);
  return make_tasks(cloud, part_points, g, split_spatially ? &grid : nullptr);
}

ErrorBound resolve_error_bound(const IngestOptions& options, const InputSet& in) {
  ErrorBound b;
  b.color_tolerance = options.color_tolerance;
  b.intensity_tolerance = options.intensity_tolerance;
  b.keep_order = options.keep_order;
  b.fast_geometry = options.fast_geometry;
  // The first LAS input's grid, at the finest scale among the LAS inputs.
  bool las = false;
  Vec3d finest{0, 0, 0};
  for (const auto& r : in.readers) {
    const PointStreamInfo& info = r->info();
    const Vec3d s{std::fabs(info.scale.x), std::fabs(info.scale.y), std::fabs(info.scale.z)};
    if (!(s.x > 0 && s.y > 0 && s.z > 0)) continue;
    if (!las) {
      b.origin = info.offset;
      finest = s;
      las = true;
    } else {
      finest = Vec3d{std::min(finest.x, s.x), std::min(finest.y, s.y), std::min(finest.z, s.z)};
    }
  }
  if (options.tolerance > 0) {
    b.step = Vec3d{2 * options.tolerance, 2 * options.tolerance, 2 * options.tolerance};
    if (!las) b.origin = Vec3d{0, 0, 0};
  } else if (las) {
    b.step = finest;
  } else {
    b.step = Vec3d{2 * kDefaultTolerance, 2 * kDefaultTolerance, 2 * kDefaultTolerance};
  }
  return b;
}

Status snap_to_grid(PointCloud& batch, const ErrorBound& b, const std::string& source,
                    std::uint64_t first_index) {
  // The codec's own formula and index (core/grid_index.h), so its
  // re-snapping is exact. A coordinate too far from the origin for an exact
  // index is left as it is for the encoder to reject with a clear error.
  const double steps[3] = {b.step.x, b.step.y, b.step.z};
  const double origins[3] = {b.origin.x, b.origin.y, b.origin.z};
  for (std::size_t i = 0; i < batch.positions.size(); ++i) {
    Vec3d& p = batch.positions[i];
    double* c[3] = {&p.x, &p.y, &p.z};
    for (int a = 0; a < 3; ++a) {
      const double v = *c[a];
      const std::optional<std::int64_t> k = core::grid_index_within(v, origins[a], steps[a]);
      if (!k && !core::grid_index_in_range(v, origins[a], steps[a])) continue;
      if (!k) {
        return invalid_argument(source + ": point " + std::to_string(first_index + i) + ": " +
                                core::grid_too_fine_text(v, steps[a]));
      }
      *c[a] = core::grid_value(origins[a], *k, steps[a]);
    }
  }
  return Status::ok();
}

namespace {

// Another reader's points, read through it (which stays its owner's).
class BorrowedReader final : public PointReader {
 public:
  explicit BorrowedReader(PointReader& reader) : reader_(reader) {}
  const PointStreamInfo& info() const override { return reader_.info(); }
  Result<std::size_t> read(PointCloud& batch, std::size_t max_points) override {
    return reader_.read(batch, max_points);
  }

 private:
  PointReader& reader_;
};

// A reader's points after its first `skip` (read and dropped).
class SkipFirst final : public PointReader {
 public:
  SkipFirst(std::unique_ptr<PointReader> reader, std::uint64_t skip) : reader_(std::move(reader)), skip_(skip) {}
  const PointStreamInfo& info() const override { return reader_->info(); }
  Result<std::size_t> read(PointCloud& batch, std::size_t max_points) override {
    while (skip_ > 0) {
      RELIEF_ASSIGN_OR_RETURN(const std::size_t got,
                              reader_->read(batch, static_cast<std::size_t>(std::min<std::uint64_t>(skip_, max_points))));
      if (got == 0) return io_error(reader_->info().path + ": fewer points on a second read than on the first");
      skip_ -= got;
    }
    return reader_->read(batch, max_points);
  }

 private:
  std::unique_ptr<PointReader> reader_;
  std::uint64_t skip_;
};

}  // namespace

Result<OrderFreeCells> order_free_cells(const std::vector<std::string>& inputs,
                                        const ReaderOptions& reader_options, int map_resolution,
                                        Box3d* bounds, OrderFreeSample* extra, InputSet* keep_from,
                                        const PointCloud* first, Spool* spool, const IngestOptions* run,
                                        std::size_t read_batch) {
  // The points whose position hash falls below a threshold, halved whenever
  // more than 2k are kept: the final set is {p : h(p) < t} for the largest
  // power-of-two t that keeps at most 2k, whatever the order of the points.
  constexpr std::size_t kKeep = 2 * kOrderFreeSamplePoints;
  const auto hash = [](const Vec3d& p) {
    std::uint64_t h = 0x9E3779B97F4A7C15ULL;
    for (const double c : {p.x, p.y, p.z}) {
      std::uint64_t u = 0;
      std::memcpy(&u, &c, sizeof u);
      h ^= u + 0x9E3779B97F4A7C15ULL + (h << 6) + (h >> 2);
      h *= 0xBF58476D1CE4E5B9ULL;
      h ^= h >> 31;
    }
    return h;
  };
  std::uint64_t threshold = ~std::uint64_t{0};
  std::vector<std::pair<std::uint64_t, Vec3d>> kept;
  std::uint64_t total = 0;
  // The inputs are read (parsed, decompressed) on a second thread while this
  // one hashes the batch before: the two halves of this pass overlap.
  // Without `extra` (a shard plan also takes the intensity range and the
  // colour rule) only positions are used: a layered LAZ file then decodes
  // only its x, y and z.
  ReaderOptions first_pass = reader_options;
  first_pass.positions_only = extra == nullptr;
  // This pass comes before the main one, which has its inputs open already:
  // a pipe, read once, cannot give both (it would wait forever).
  for (const std::string& path : inputs) {
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0 && !S_ISREG(st.st_mode)) {
      return invalid_argument(path + ": not a regular file (a pipe?); the default cell size takes a pass over every "
                                     "point before the ingest reads them, and a pipe can be read only once: give "
                                     "--cell (a shard plan needs files), or use 'relief stream'");
    }
  }
  const auto take = [&](const PointCloud& batch) {
    total += batch.size();
    if (extra != nullptr) widen_intensity_range(batch, extra->intensity_lo, extra->intensity_hi);
    for (const Vec3d& p : batch.positions) {
      if (bounds != nullptr) bounds->add(p);
      const std::uint64_t h = hash(p);
      if (h < threshold) kept.emplace_back(h, p);
    }
    while (kept.size() > kKeep) {
      threshold >>= 1;
      std::erase_if(kept, [&](const auto& e) { return e.first >= threshold; });
    }
  };
  // The readers this pass reads: the ingest's own (after `first`, counted
  // here), or its own opened anew (positions only); with a spool, the
  // ingest's own for the inputs spooled (their colour rule's sample, which
  // their readers have settled, is not decoded again; see
  // derive_build_parameters for a spool given up), its own for the others.
  const bool keep = keep_from != nullptr && spool == nullptr;
  std::vector<std::unique_ptr<PointReader>> opened;
  for (std::size_t i = 0; i < inputs.size() && !keep; ++i) {
    if (spool != nullptr && spool->wants(i)) {
      opened.push_back(std::make_unique<BorrowedReader>(*keep_from->readers[i]));
    } else {
      RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> reader, open_lazy_reader(inputs[i], first_pass));
      opened.push_back(std::move(reader));
    }
  }
  std::vector<std::unique_ptr<PointReader>>& readers = keep ? keep_from->readers : opened;
  const bool continues_first = keep || (spool != nullptr && spool->wants(0));
  const PointCloud* already = continues_first ? first : nullptr;
  // Progress (a survey of a billion points takes minutes here), counted
  // against the inputs' total when every header states its count.
  std::uint64_t stated = 0;
  bool all_stated = true;
  for (const auto& reader : readers) {
    const std::optional<std::uint64_t> c = reader->info().point_count;
    all_stated = all_stated && c.has_value();
    stated += c.value_or(0);
  }
  Progress progress(run != nullptr ? run->progress : nullptr, all_stated ? stated : 0);
  const auto cancelled = [&] { return run != nullptr && run->cancel != nullptr && run->cancel->load(); };
  if (already != nullptr) take(*already);
  // The LAS grid of each input for the spool, taken before the reading
  // thread starts (info() is the reader's, which that thread then updates).
  std::vector<std::pair<Vec3d, Vec3d>> spool_grids;
  if (spool != nullptr) {
    for (const auto& reader : readers) spool_grids.emplace_back(reader->info().offset, reader->info().scale);
  }
  {
    // One batch ahead, as the main pass.
    Prefetcher prefetch(readers, spool != nullptr ? spool->batch_points() : read_batch, 1,
                        already != nullptr ? already->size() : 0, nullptr);
    ReadBatch read;
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool more, prefetch.next(read));
      if (!more) break;
      take(read.points);
      progress.update("scanning", total, 0, 0);
      if (cancelled()) return io_error("interrupted");
      if (spool != nullptr) {
        spool->append(read.reader, read.points, spool_grids[read.reader].first, spool_grids[read.reader].second);
      }
      if (keep) {
        keep_from->read_ahead.push_back(std::move(read));
        read = ReadBatch();
      }
    }
  }
  if (spool != nullptr) {
    for (std::size_t i = 0; i < readers.size(); ++i) spool->finish(i, readers[i]->info());
  }
  if (extra != nullptr) {
    extra->inputs = readers.size();
    for (const auto& reader : readers) {
      const PointStreamInfo& r = reader->info();
      if ((r.las_attributes & kLasColorLow) != 0) {
        extra->colour_sources.push_back({r.path, r.las_colors_8bit, r.las_colors_all_zero});
      }
    }
    extra->points = total;
  }
  if (kept.empty()) return OrderFreeCells{};  // no points at all: the caller picks the empty-input cell
  PointCloud sample;
  sample.positions.reserve(kept.size());
  // Sorted, so the estimate does not even see the order the points came in.
  std::sort(kept.begin(), kept.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
  for (const auto& e : kept) sample.positions.push_back(e.second);
  if (extra != nullptr) extra->positions = sample.positions;
  const double fraction = static_cast<double>(sample.size()) / static_cast<double>(total);
  OrderFreeCells cells;
  cells.points = total;
  cells.density_cell = cell_size_for_density(sample, static_cast<double>(map_resolution) * map_resolution * fraction);
  // The base layer's pixels should hold about kBasePointsPerPixel points
  // whatever the shape of the data (surfaces fill a cell's r x r pixels,
  // scan lines only a few). Measured on the sample while it still sees such
  // pixels (a pixel of n points holds n x fraction sample points); beyond
  // that (inputs of more than ~5 M points) the surface model decides.
  const double per_pixel = kBasePointsPerPixel * fraction;
  cells.base_cell = per_pixel >= kMinSamplePointsPerPixel
                        ? map_resolution * cell_size_for_density(sample, per_pixel)
                        : kBaseCellFactor * cells.density_cell;
  return cells;
}

void remove_archive_files(const std::string& path) {
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) ::unlink((path + suffix).c_str());
}

std::string default_tmp_parent(const std::string& archive_path, const IngestOptions& options) {
  return default_tmp_parent(archive_path, options.tmp_dir);
}

std::string default_tmp_parent(const std::string& archive_path, const std::string& tmp_dir) {
  if (!tmp_dir.empty()) return tmp_dir;
  const std::filesystem::path p(archive_path);
  const std::string parent = p.parent_path().string();
  return parent.empty() ? "." : parent;
}

Status validate_build_options(const IngestOptions& options) {
  RELIEF_RETURN_IF_ERROR(validate_encode_params(options.codec));
  if (!(options.chunk_edge >= 0) || options.chunk_edge > kMaxCoordinateMagnitude) {
    return invalid_argument("chunk edge must be a positive number up to 2^50 (0 = automatic)");
  }
  if (options.codec.cell_size > kMaxCoordinateMagnitude) {
    return invalid_argument("cell size must be at most 2^50");
  }
  // The step (twice the tolerance) is bounded as a cell is: a tolerance of
  // 8.9e307 overflowed the chunk keys (a chunk "(9223372036854775807, ...)").
  if (!(options.tolerance >= 0) || options.tolerance > kMaxCoordinateMagnitude / 2) {
    return invalid_argument("tolerance must be a positive number up to 2^49 (0 = automatic)");
  }
  return Status::ok();
}

namespace {

// Room kept free beside a spool and the bucket files after it.
constexpr std::uint64_t kSpoolDiskMargin = std::uint64_t{256} << 20;

// A spool for the order-free pass of `in` (IngestOptions::spool), or none:
// no LAZ or text input (PointStreamInfo::text_body), or less room under `parent` than twice what the
// spool would hold (the bucket files come after it), or no directory there
// (the bucket files will say why).
std::shared_ptr<Spool> start_spool(const InputSet& in, const std::string& parent, std::size_t batch_points) {
  std::vector<bool> wanted(in.readers.size(), false);
  std::uint64_t bytes = 0;
  for (std::size_t i = 0; i < in.readers.size(); ++i) {
    const PointStreamInfo& info = in.readers[i]->info();
    if (info.format != "laz" && !info.text_body) continue;
    wanted[i] = true;
    struct stat st {};
    // Text states no count: its size over 8 (a text point takes about that
    // at least).
    const std::uint64_t points = info.point_count ? *info.point_count
                                 : ::stat(info.path.c_str(), &st) == 0 ? static_cast<std::uint64_t>(st.st_size) / 8
                                                                       : 0;
    // Saturating: a header may state any count (the reader judges it).
    const std::uint64_t per_point = Spool::point_bytes(info);
    const std::uint64_t input_bytes = points > (UINT64_MAX - bytes) / per_point ? UINT64_MAX - bytes : points * per_point;
    bytes += input_bytes;
  }
  if (std::none_of(wanted.begin(), wanted.end(), [](bool w) { return w; })) return nullptr;
  struct statvfs fs {};
  if (::statvfs(parent.c_str(), &fs) != 0) return nullptr;
  const std::uint64_t free_bytes = static_cast<std::uint64_t>(fs.f_bavail) * fs.f_frsize;
  if (bytes > free_bytes / 2 || free_bytes / 2 - bytes < kSpoolDiskMargin) return nullptr;
  Result<std::shared_ptr<Spool>> spool = Spool::create(parent, std::move(wanted), batch_points);
  return spool ? *spool : nullptr;
}

}  // namespace

Result<BuildParameters> derive_build_parameters(const std::vector<std::string>& inputs, const IngestOptions& options,
                                                InputSet& in, PointCloud& first, OrderFreeSample* sample,
                                                const std::string& tmp_parent) {
  EncodeParams params = options.codec;
  // The first points set the cell size (from their density, or by trial
  // encodes for an error target) and are checked against it; they are then
  // ingested like every batch. At most a quarter of the budget for them (with
  // the cell-size scratch).
  const bool bounded = options.mode == IngestMode::kBounded;
  if (bounded) {
    params.bound = resolve_error_bound(options, in);
    if (options.error_target > 0) return invalid_argument("--error-target applies to the resampling mode (--mode resample)");
  } else {
    params.bound.reset();
  }
  const std::uint64_t budget = std::max<std::uint64_t>(options.memory_budget, kMinMemoryBudget);
  // The bounded mode derives the base-layer cell from all points (below);
  // the resampling mode from these first points.
  const bool derive_from_first = !bounded && (params.cell_size == 0 || options.error_target > 0);
  // Otherwise only the coordinate and density checks need them: read no
  // more, so the reading thread takes over sooner.
  const auto first_points = static_cast<std::size_t>(std::min<std::uint64_t>(
      derive_from_first ? kReadBatchPoints : kDensitySamplePoints, (budget / 4) / kFirstBatchBytesPerPoint));
  RELIEF_ASSIGN_OR_RETURN(std::size_t got, in.readers[0]->read(first, first_points));
  conform_attributes(first, in);
  // The absolute bound first, so no absurd coordinate reaches the cell-size
  // estimate; the bound for the chosen cell follows below.
  RELIEF_RETURN_IF_ERROR(check_coordinates(first, kMaxCoordinateMagnitude, inputs[0], 0));
  Box3d all_bounds;
  // Bounded mode: chunks are kDefaultCellsPerChunk density cells across,
  // whatever the base layer's cell.
  double density_cell = 0;
  std::uint64_t input_points = 0;  // counted by the order-free pass
  if (bounded && params.cell_size == 0) {
    // The base layer's cells: from a sample that depends only on the set of
    // input points (not their order, not the memory budget).
    // A compress whose whole input fits its memory keeps what this pass
    // reads (through the inputs' own readers, so every attribute), and the
    // ingest stages it instead of reading every input a second time.
    const IngestBudget plan = ingest_plan(in, options, true);
    InputSet* keep = sample == nullptr && whole_input_in_memory(in, plan) ? &in : nullptr;
    // Otherwise the pass may keep what it decodes of LAZ and text inputs.
    std::shared_ptr<Spool> spool = keep == nullptr && sample == nullptr && options.spool && !tmp_parent.empty()
                                       ? start_spool(in, tmp_parent, static_cast<std::size_t>(plan.read_batch))
                                       : nullptr;
    RELIEF_ASSIGN_OR_RETURN(
        const OrderFreeCells cells,
        order_free_cells(inputs, ingest_reader_options(options), params.map_resolution, &all_bounds, sample,
                         keep != nullptr || spool != nullptr ? &in : nullptr, &first, spool.get(), &options,
                         static_cast<std::size_t>(plan.read_batch)));
    if (spool != nullptr && spool->failure().empty()) {
      // The pass read the spooled inputs through the ingest's readers (input
      // 0 after `first`): the ingest reads them from the spool.
      for (std::size_t i = 0; i < in.readers.size(); ++i) {
        if (spool->wants(i)) in.readers[i] = spool->reader(i);
      }
      in.spool = std::move(spool);
    } else if (spool != nullptr) {
      // Given up (a full disk): those readers are spent; the ingest reads
      // the inputs anew (input 0 after `first`).
      for (std::size_t i = 0; i < in.readers.size(); ++i) {
        if (!spool->wants(i)) continue;
        RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> again,
                                open_lazy_reader(inputs[i], ingest_reader_options(options)));
        in.readers[i] = i == 0 ? std::make_unique<SkipFirst>(std::move(again), got) : std::move(again);
      }
      in.warnings.push_back("the decoded points of LAZ and text inputs could not be kept in temporary files (" +
                            spool->failure() + "): they are read a second time");
    }
    // Inputs without a single point still make a valid (empty) archive, on a
    // documented default grid, so scripted pipelines need no special case.
    params.cell_size = cells.density_cell > 0 ? cells.base_cell : kBaseCellFactor * kEmptyInputCellSize;
    density_cell = cells.density_cell;
    input_points = cells.points;
  } else if (sample != nullptr) {
    // The caller wants the pass anyway (a shard plan): the sample, not the
    // cells, and no bounds, so the grid is the one this branch would get.
    RELIEF_RETURN_IF_ERROR(order_free_cells(inputs, options.reader, params.map_resolution, nullptr, sample, nullptr,
                                            nullptr, nullptr, &options)
                               .status());
  }
  if (derive_from_first) {
    if (got == 0 && inputs.size() > 1) {
      return invalid_argument(inputs[0] + ": no points to derive a cell size from (put a non-empty input first)");
    }
    if (got == 0) {
      params.cell_size = kEmptyInputCellSize;  // a single empty input: an empty archive
    } else if (options.error_target > 0) {
      RELIEF_ASSIGN_OR_RETURN(params.cell_size, choose_cell_for_error(first, params, options.error_target));
    } else {
      params.cell_size = suggest_cell_size(first, params.map_resolution);
    }
  }
  ArchiveGrid grid;
  if (!all_bounds.empty()) {
    // The chunk grid starts at the inputs' minimum corner (known from the
    // pass above, whatever the order of the points): a scan smaller than a
    // chunk is one chunk, not up to eight cut at the coordinate axes. One
    // grid step below it, so no point snaps out of the first chunk.
    const ErrorBound& b = *params.bound;
    grid.origin = Vec3d{all_bounds.min.x - b.step.x, all_bounds.min.y - b.step.y, all_bounds.min.z - b.step.z};
  }
  const double cells_per_chunk = bounded ? kDefaultCellsPerChunk / kBaseCellFactor : kDefaultCellsPerChunk;
  grid.chunk_edge = options.chunk_edge > 0    ? options.chunk_edge
                    : density_cell > 0        ? density_cell * kDefaultCellsPerChunk
                                              : params.cell_size * cells_per_chunk;
  if (bounded && options.chunk_edge == 0 && density_cell > 0 && input_points <= kSmallArchiveMaxPoints) {
    // A small, compact input is one chunk: each chunk costs a blob header,
    // its maps' fixed cost and a row (KITTI's 115 k points made 2 chunks, one
    // of 40 points, 1.5 KB more). The edge doubles (the base cells' ladder
    // edge / 2^D stays the same) until the inputs' box, snapped, fits from
    // the grid origin, when that takes at most kMaxSmallChunkGrowth times the
    // default edge; scattered inputs keep the default. The depth limit below
    // may still halve it.
    const ErrorBound& b = *params.bound;
    const double widest = std::max({all_bounds.max.x - grid.origin.x + b.step.x,
                                    all_bounds.max.y - grid.origin.y + b.step.y,
                                    all_bounds.max.z - grid.origin.z + b.step.z});
    const double grown = grid.chunk_edge * kMaxSmallChunkGrowth;
    if (widest < grown && grown <= kMaxCoordinateMagnitude) {
      while (grid.chunk_edge <= widest) grid.chunk_edge *= 2;
    }
  }
  double edge_capped_by_step = 0;
  if (bounded) {
    // A chunk spans at most 2^21 grid steps (the octree's depth limit), with
    // room for points snapped half a step beyond its faces: the automatic
    // edge halves to fit; a given one that does not, over inputs that span
    // more than that, is refused now rather than by the encoder after a pass
    // over every point.
    const double finest = std::min({params.bound->step.x, params.bound->step.y, params.bound->step.z});
    const double most = (std::ldexp(1.0, 21) - 4) * finest;
    const double extent =
        all_bounds.empty()
            ? 0.0
            : std::max({all_bounds.max.x - all_bounds.min.x, all_bounds.max.y - all_bounds.min.y,
                        all_bounds.max.z - all_bounds.min.z});
    if (options.chunk_edge > 0 && grid.chunk_edge > most && extent > most) {
      return invalid_argument(
          "--chunk-edge " + number_text(grid.chunk_edge) + " spans " + number_text(grid.chunk_edge / finest) +
          " grid steps of " + number_text(finest) +
          " (twice the tolerance), more than a chunk holds (2^21), and the inputs span " +
          number_text(extent) + ": use a chunk edge up to " + number_text(most) + " or a larger --tolerance");
    }
    while (grid.chunk_edge > most) {
      grid.chunk_edge /= 2;
      edge_capped_by_step = finest;
    }
  }
  if (!(grid.chunk_edge > 0) || !std::isfinite(grid.chunk_edge) || grid.chunk_edge > kMaxCoordinateMagnitude) {
    return invalid_argument("chunk edge must be a positive number up to 2^50");
  }
  if (grid.chunk_edge / params.cell_size > std::ldexp(1.0, 21)) {
    return invalid_argument("chunk edge " + std::to_string(grid.chunk_edge) + " is more than 2^21 cells of " +
                            std::to_string(params.cell_size));
  }
  RELIEF_RETURN_IF_ERROR(
      check_coordinates(first, max_coordinate_magnitude(params.cell_size, grid.chunk_edge), inputs[0], 0));
  if (!options.allow_sparse) {
    RELIEF_RETURN_IF_ERROR(
        check_sample_density(first, grid, params.cell_size, inputs[0], edge_capped_by_step));
  }
  BuildParameters built;
  built.params = params;
  built.grid = grid;
  return built;
}

}  // namespace ingest

std::uint32_t ingest_page_size(std::uint64_t input_points) {
  if (input_points <= kSmallArchiveMaxPoints) return kSmallArchivePageSize;
  return input_points <= kMediumArchiveMaxPoints ? kArchivePageSize : kLargeArchivePageSize;
}

Result<IngestResult> compress_files(const std::vector<std::string>& given, const std::string& archive_path,
                                    const IngestOptions& options) {
  using namespace ingest;
  RELIEF_RETURN_IF_ERROR(validate_build_options(options));
  RELIEF_ASSIGN_OR_RETURN(const std::vector<std::string> inputs, expand_inputs(given));
  struct stat st {};
  if (::stat(archive_path.c_str(), &st) == 0) {
    // Say what is there: an archive to append to, or some other file.
    if (Archive::open(archive_path, Archive::Mode::kReadOnly)) {
      return io_error(archive_path +
                      ": already exists (a Relief archive; compress never overwrites, use 'relief append' to add to it)");
    }
    return io_error(archive_path + ": already exists and is not a Relief archive (compress never overwrites a file)");
  }
  RELIEF_RETURN_IF_ERROR(check_output_directory(archive_path));
  RELIEF_ASSIGN_OR_RETURN(InputSet in, open_inputs(inputs, ingest_reader_options(options), options.assume_crs, options.crs));
  PointCloud first;
  RELIEF_ASSIGN_OR_RETURN(const BuildParameters built,
                          derive_build_parameters(inputs, options, in, first, nullptr,
                                                  default_tmp_parent(archive_path, options)));
  const EncodeParams& params = built.params;
  const ArchiveGrid& grid = built.grid;
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Archive> archive,
                          Archive::create(archive_path, grid, encode_params_to_string(params, ParamsText::kCompact), options.creator,
                                          ingest_page_size(in.estimated_points)));
  auto result = run_ingest(*archive, grid, params, in, std::move(first), options,
                           default_tmp_parent(archive_path, options));
  if (!result) {
    bool keep = options.cancel != nullptr && options.cancel->load();
    if (keep) {
      // An interruption keeps what is committed, when there is something:
      // stopped before its scan began, the archive would hold nothing.
      auto info = archive->info();
      keep = info && !info->scans.empty();
    }
    archive.reset();
    // A clean failure leaves no archive.
    if (!keep) remove_archive_files(archive_path);
    return result.status();
  }
  // One file, or no archive: a full disk can stop SQLite folding its log in.
  if (Status closed = archive->close(); !closed) {
    archive.reset();
    remove_archive_files(archive_path);
    return Status(closed.code(), closed.message() + "; nothing of the new archive is kept");
  }
  return result;
}

Result<IngestResult> append_files(const std::string& archive_path, const std::vector<std::string>& given,
                                  const IngestOptions& options) {
  using namespace ingest;
  RELIEF_ASSIGN_OR_RETURN(const std::vector<std::string> inputs, expand_inputs(given));
  RELIEF_ASSIGN_OR_RETURN(InputSet in, open_inputs(inputs, ingest_reader_options(options), options.assume_crs, options.crs));
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Archive> archive, Archive::open(archive_path, Archive::Mode::kReadWrite));
  RELIEF_ASSIGN_OR_RETURN(ArchiveInfo info, archive->info());
  // One CRS per archive: the archive's wins over the inputs' when they differ
  // and the user said --assume-crs; otherwise a different one is refused.
  if (!info.crs.empty() && !in.crs.empty() && !same_crs(info.crs, in.crs)) {
    const std::string both = archive_path + " has the CRS " + crs_label(info.crs) + " but " + in.crs_from +
                             " has " + crs_label(in.crs);
    if (!options.assume_crs) {
      return invalid_argument(both + "; one archive holds one CRS (--assume-crs keeps the archive's)");
    }
    in.warnings.push_back(both + "; --assume-crs: the archive keeps " + crs_label(info.crs));
    in.crs = info.crs;
  } else if (!info.crs.empty() && in.crs.empty()) {
    in.warnings.push_back("the new input has no CRS; the archive keeps " + crs_label(info.crs));
  } else if (info.crs.empty() && !in.crs.empty() && !info.sources.empty()) {
    in.warnings.push_back(archive_path + " had no CRS; it takes " + crs_label(in.crs) + " of " + in.crs_from);
  }
  RELIEF_ASSIGN_OR_RETURN(EncodeParams params, encode_params_from_string(info.codec_params));
  // An archive of 8-bit colour levels with exact colour keeps its rule: the
  // new inputs' 16-bit levels are split as 8-bit ones, so both kinds come
  // back. (With a colour tolerance the levels that come back are the decoded
  // 8-bit colours, which would drop the 16-bit ones' scale: there the rule
  // turns to 16 bits as before, with a warning.)
  in.split_wide_levels = params.bound && params.bound->color_tolerance == 0 && info.las_colors_8bit &&
                         (info.las_attributes & kLasColorLow) != 0;
  if (info.chunk_count > 0) {
    // Keep one attribute set per archive so every chunk decodes alike.
    // Named: the first input without them, and --attributes when it left them out.
    const auto refuse = [&](const char* what, const char* name, const std::string& from, bool kept) {
      return invalid_argument(archive_path + " has " + what + " but " +
                              (kept ? from + " has none: every point of an archive carries its " + what +
                                          " (compress it into an archive of its own)"
                                    : "--attributes leaves them out of " + from +
                                          ": every point of an archive " + "carries its " + what + " (add " +
                                          name + " to the list)"));
    };
    if (info.has_colors && !in.colors) {
      return refuse("colours", "rgb", in.colors_missing_from, options.reader.attributes.colors);
    }
    if (info.has_intensity && !in.intensity) {
      return refuse("intensity", "intensity", in.intensity_missing_from, options.reader.attributes.intensity);
    }
    // The other way round the archive keeps its attribute set: say what goes,
    // as compress does for inputs with and without them.
    if (!info.has_colors && in.colors) {
      in.warnings.push_back(archive_path + " has no colours, so the new input's colours are dropped");
    }
    if (!info.has_intensity && in.intensity) {
      in.warnings.push_back(archive_path + " has no intensity, so the new input's intensities are dropped");
    }
    in.colors = info.has_colors;
    in.intensity = info.has_intensity;
  }
  // LAS attributes: the archive's set and the inputs' make one (the points of
  // either side that lack one read it as 0); the extra bytes must agree.
  if ((info.las_attributes & kLasExtraBytes) != 0 && (in.las_attributes & kLasExtraBytes) != 0 &&
      (info.extra_bytes_vlr != in.extra_bytes_vlr || info.extra_bytes_size != in.extra_bytes_size)) {
    return invalid_argument(in.extra_bytes_from + " has " + std::to_string(in.extra_bytes_size) +
                            " extra bytes per point described by a different Extra Bytes VLR than " + archive_path +
                            " (" + std::to_string(info.extra_bytes_size) +
                            " bytes); one archive holds one extra bytes layout");
  }
  if (info.las_gps_time_type != GpsTimeType::kUnknown && in.las_gps_time_type != GpsTimeType::kUnknown &&
      info.las_gps_time_type != in.las_gps_time_type) {
    return invalid_argument(gps_time_clash(in.gps_time_from, in.las_gps_time_type, archive_path,
                                           info.las_gps_time_type));
  }
  if (info.las_gps_time_type != GpsTimeType::kUnknown) {
    if (in.gps_time_from.empty()) in.gps_time_from = archive_path;
    in.las_gps_time_type = info.las_gps_time_type;
  } else if ((info.las_attributes & kLasGpsTime) != 0 && in.las_gps_time_type != GpsTimeType::kUnknown) {
    in.warnings.push_back(archive_path + " holds GPS times of an unrecorded kind (made before Relief kept it); the " +
                          "archive now records " + gps_time_kind(in.las_gps_time_type) + " of " + in.gps_time_from);
  }
  if ((info.las_attributes & kLasExtraBytes) != 0) {
    in.extra_bytes_vlr = info.extra_bytes_vlr;
    in.extra_bytes_size = info.extra_bytes_size;
  }
  // A LAS input whose integers the archive's grid cannot give back (a finer
  // scale, or an offset between its steps) comes back within the archive's
  // tolerance, as any other input would: said, since on its own it would
  // have been lossless at its scale.
  if (params.bound) {
    const Vec3d& step = params.bound->step;
    const Vec3d& origin = params.bound->origin;
    for (const auto& reader : in.readers) {
      const PointStreamInfo& ri = reader->info();
      if (ri.las_point_format < 0 || !(ri.scale.x > 0 && ri.scale.y > 0 && ri.scale.z > 0)) continue;
      bool on_grid = true;
      const double sc[3] = {ri.scale.x, ri.scale.y, ri.scale.z},
                   of[3] = {ri.offset.x, ri.offset.y, ri.offset.z};
      const double st[3] = {step.x, step.y, step.z}, og[3] = {origin.x, origin.y, origin.z};
      for (int a = 0; a < 3; ++a) {
        // Every X * scale + offset on the grid: scale a whole number of
        // steps, offset a whole number of steps from the origin.
        const double k = sc[a] / st[a], m = (of[a] - og[a]) / st[a];
        on_grid = on_grid && std::fabs(k - std::round(k)) <= 1e-9 * std::max(1.0, k) && std::round(k) >= 1 &&
                  std::fabs(m - std::round(m)) <= 1e-6;
      }
      if (!on_grid) {
        in.warnings.push_back(ri.path + ": its LAS grid (scale " + number_text(ri.scale.x) + ", offset " +
                              number_text(ri.offset.x) + " in x) is not on " + archive_path + "'s (step " +
                              number_text(step.x) + ", origin " + number_text(origin.x) +
                              "): its points come back within the archive's tolerance " +
                              number_text(step.x / 2) + ", not as its own integers");
      }
    }
  }
  in.las_attributes |= info.las_attributes;
  if (!in.colors) in.las_attributes &= ~std::uint32_t{kLasColorLow};
  in.las_point_format = std::max(in.las_point_format, info.las_point_format);
  in.las_version_minor = std::max(in.las_version_minor, info.las_version_minor);
  auto result = run_ingest(*archive, info.grid, params, in, PointCloud(), options,
                           default_tmp_parent(archive_path, options));
  if (!result) {
    const bool interrupted = options.cancel != nullptr && options.cancel->load();
    if (!interrupted) {
      // Remove whatever this append committed: the archive is as before. The
      // store kept room for this on a full disk (Archive::put_chunks); should
      // it fail anyway, say so rather than leave a half append unmentioned.
      Status undone;
      auto scans = archive->info();
      if (!scans) undone = scans.status();
      if (scans) {
        for (const ArchiveScan& s : scans->scans) {
          bool existed = false;
          for (const ArchiveScan& old : info.scans) existed = existed || old.id == s.id;
          if (existed) continue;
          const Status aborted = archive->abort_scan(s.id);
          if (undone && !aborted) undone = aborted;
        }
      }
      if (!undone) {
        return Status(result.status().code(), result.status().message() +
                                                  "; removing what this append added failed too, its chunks stay "
                                                  "as an incomplete scan: " + undone.message());
      }
    }
    return result.status();
  }
  // The append is committed; a full disk can keep its last writes in the
  // write-ahead log, which the error says must stay beside the archive.
  if (Status closed = archive->close(); !closed) {
    return Status(closed.code(), closed.message() + kept_in_wal_note(archive_path));
  }
  return result;
}

}  // namespace relief
