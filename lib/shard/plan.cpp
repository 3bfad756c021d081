// Stage 0 of a sharded build: every decision compress_files derives from all
// the inputs, made by the same functions (lib/ingest) and written to a plan
// file (format-spec/shard.md, "Plan file").
#include <algorithm>
#include <cerrno>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <optional>

#include "core/hex.h"
#include "ingest/ingest_common.h"
#include "relief/codec.h"
#include "relief/shard.h"
#include "shard/shard_files.h"

namespace relief {

namespace {

// The Extra Bytes VLR payload in a plan line: lower-case hexadecimal only.
bool decode_vlr_hex(const std::string& text, std::string& out) {
  std::optional<std::string> bytes = bytes_from_hex(text, false);
  if (!bytes) return false;
  out = std::move(*bytes);
  return true;
}

// Bytes (a LAS header, a record's fields) as a string for hex_lower.
template <typename Bytes>
std::string as_text(const Bytes& bytes) {
  return std::string(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

constexpr char kPlanMagic[] = "relief-shard-plan";
// A plan is a few lines per input; anything larger is not a plan.
constexpr std::uint64_t kMaxPlanBytes = std::uint64_t{64} << 20;

std::string number(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

std::string number(float v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", static_cast<double>(v));
  return buf;
}


// Bounds of the LAS fields (LAS 1.4 R15): point formats 0-10, a u8 minor
// version, and extra bytes that fit a record (u16 length) described by a VLR
// (u16 payload length).
constexpr int kMaxLasPointFormat = 10;
constexpr int kMaxLasVersionMinor = 255;
constexpr std::int64_t kMaxExtraBytesSize = 65535;
constexpr std::size_t kMaxExtraBytesVlrBytes = 65535;

}  // namespace

std::uint32_t ShardPlan::range_of(const ChunkKey& key) const {
  const auto it = std::upper_bound(range_starts.begin() + 1, range_starts.end(), key);
  return static_cast<std::uint32_t>(it - range_starts.begin() - 1);
}

ReaderOptions ShardPlan::reader_options() const {
  ReaderOptions r;
  if (has_xyz_columns) r.xyz_columns = xyz_columns;
  r.extra_bytes = !no_extra_bytes;
  r.attributes = keep;
  return r;
}

Result<ShardPlan> plan_shards(const std::vector<std::string>& given, const ShardPlanOptions& options) {
  using namespace ingest;
  RELIEF_ASSIGN_OR_RETURN(const std::vector<std::string> inputs, expand_inputs(given));
  const IngestOptions& o = options.ingest;
  if (o.mode != IngestMode::kBounded) {
    return invalid_argument("a sharded build makes error-bounded archives (the resampling mode's chunks depend on "
                            "the memory budget and the first input's first points)");
  }
  if (options.ranges > kMaxShardRanges) {
    return invalid_argument("at most " + std::to_string(kMaxShardRanges) + " key ranges");
  }
  if (o.pyramid != PyramidMode::kAuto) {
    return invalid_argument("the pyramid is not part of a plan: merge builds it from the merged chunks "
                            "(MergeOptions::pyramid, relief merge --pyramid)");
  }
  RELIEF_RETURN_IF_ERROR(validate_build_options(o));
  // open_inputs makes the LAS decisions of compress (the union of the
  // attribute sets, one Extra Bytes layout: different VLRs are refused there,
  // naming both inputs).
  RELIEF_ASSIGN_OR_RETURN(InputSet in, open_inputs(inputs, o.reader, o.assume_crs, o.crs));
  PointCloud first;
  OrderFreeSample sample;
  RELIEF_ASSIGN_OR_RETURN(const BuildParameters built, derive_build_parameters(inputs, o, in, first, &sample));
  ShardPlan plan;
  plan.attributes = scan_attributes(in);
  // Whether a LAS input stored 8-bit colour levels is known once it has
  // returned points (its reader samples the file's first points, whatever
  // the batch size): the sample pass read every input, so its readers know.
  // The rule of scan_attributes: 8-bit only when every LAS input with
  // colours stored them so.
  if (sample.inputs != in.readers.size()) {
    return internal_error("shard plan: the sample pass saw " + std::to_string(sample.inputs) + " of " +
                          std::to_string(in.readers.size()) + " inputs");
  }
  plan.attributes.las_colors_8bit = all_8bit_levels(sample.colour_sources);
  plan.creator = o.creator;
  plan.archive_params = encode_params_to_string(built.params, ParamsText::kCompact);
  plan.grid = built.grid;
  // compress_files' with_intensity_range over the same points.
  const EncodeParams chunk_params =
      with_intensity_range(built.params, in.intensity, sample.intensity_lo, sample.intensity_hi);
  if (chunk_params.intensity_range) {
    plan.has_intensity_range = true;
    plan.intensity_lo = chunk_params.intensity_range->first;
    plan.intensity_hi = chunk_params.intensity_range->second;
  }
  // The split compress_files would use for these attributes (recorded, so
  // every stage-2 task uses it).
  plan.split_points = bounded_split_points(o.split_points, in.las_attributes, in.extra_bytes_size);
  plan.has_xyz_columns = o.reader.xyz_columns.has_value();
  if (plan.has_xyz_columns) plan.xyz_columns = *o.reader.xyz_columns;
  plan.no_extra_bytes = !o.reader.extra_bytes;
  plan.keep = o.reader.attributes;
  plan.points = sample.points;
  plan.sources = in.sources;
  for (ArchiveSource& s : plan.sources) s.point_count = 0;
  plan.warnings = in.warnings;
  for (const auto& reader : in.readers) {
    for (const std::string& w : reader->info().warnings) plan.warnings.push_back(w);
  }
  for (std::string& w : colour_rule_warnings(false, false, sample.colour_sources)) plan.warnings.push_back(std::move(w));
  // Key ranges of about equal point counts: quantiles of the order-free
  // sample's chunk keys (a uniform sample of the points), so the ranges too
  // depend only on the set of input points. Balance only: no blob depends on
  // where a range ends.
  std::uint32_t want = options.ranges;
  if (want == 0) {
    want = static_cast<std::uint32_t>(
        std::clamp<std::uint64_t>((sample.points + kDefaultRangePoints - 1) / kDefaultRangePoints, 1, kMaxShardRanges));
  }
  PointCloud snapped;
  snapped.positions = sample.positions;
  // A point no grid index takes is refused by stage 1, naming its file.
  if (built.params.bound) (void)snap_to_grid(snapped, *built.params.bound);
  std::vector<ChunkKey> keys(snapped.size());
  built.grid.keys_of(snapped.positions.data(), snapped.size(), keys.data());
  std::sort(keys.begin(), keys.end());
  constexpr std::int64_t kLowest = std::numeric_limits<std::int64_t>::min();
  plan.range_starts.push_back(ChunkKey{kLowest, kLowest, kLowest});
  // A new range starts at the first chunk after the sample points seen so far
  // reach the next multiple of 1/want: no range is empty of sample chunks,
  // and a chunk larger than a share makes fewer, not empty, ranges.
  std::uint64_t seen = 0;
  for (std::size_t j = 0; j < keys.size();) {
    std::size_t end = j;
    while (end < keys.size() && keys[end] == keys[j]) ++end;
    const auto r = static_cast<std::uint64_t>(plan.range_starts.size());
    if (j > 0 && r < want && seen * want >= r * keys.size()) plan.range_starts.push_back(keys[j]);
    seen += end - j;
    j = end;
  }
  return plan;
}

std::string shard_plan_text(const ShardPlan& plan) {
  using shard::escape_field;
  std::string t;
  const auto line = [&t](const std::string& key, const std::vector<std::string>& fields) {
    t += key;
    for (const std::string& f : fields) {
      t += '\t';
      t += escape_field(f);
    }
    t += "\n";
  };
  // Version 1 when there is nothing of version 2 to say: the bytes (and the
  // plan id) of a plan without LAS attributes are those earlier builds wrote.
  // Version 2 when there is no input's LAS header to give (the bytes of
  // plans of inputs with LAS attributes but no LAS file, e.g. a CSV column).
  const bool las_sources = std::any_of(plan.sources.begin(), plan.sources.end(),
                                       [](const ArchiveSource& s) { return !s.las.empty(); });
  line(kPlanMagic, {las_sources ? std::to_string(kShardPlanVersion) : plan.has_las() ? "2" : "1"});
  line("creator", {plan.creator});
  line("archive_params", {plan.archive_params});
  if (plan.has_intensity_range) line("intensity_range", {number(plan.intensity_lo), number(plan.intensity_hi)});
  line("grid", {number(plan.grid.origin.x), number(plan.grid.origin.y), number(plan.grid.origin.z),
                number(plan.grid.chunk_edge)});
  const ScanAttributes& a = plan.attributes;
  line("attributes", {a.has_colors ? "1" : "0", a.has_intensity ? "1" : "0"});
  if (plan.has_las()) {
    line("las", {las_attribute_list(a.las_attributes), std::to_string(a.las_point_format),
                 std::to_string(a.las_version_minor), a.las_colors_8bit ? "1" : "0"});
    if (a.las_gps_time_type != GpsTimeType::kUnknown) {
      line("gps_time_type", {gps_time_type_name(a.las_gps_time_type)});
    }
    if ((a.las_attributes & kLasExtraBytes) != 0) {
      line("extra_bytes", {std::to_string(a.extra_bytes_size), hex_lower(a.extra_bytes_vlr)});
    }
  }
  line("crs", {a.crs});
  line("split_points", {std::to_string(plan.split_points)});
  if (plan.has_xyz_columns) line("xyz_columns", {plan.xyz_columns});
  if (plan.no_extra_bytes) line("no_extra_bytes", {});
  if (!plan.keep.everything()) line("keep_attributes", {attribute_set_list(plan.keep)});
  line("points", {std::to_string(plan.points)});
  for (const ArchiveSource& s : plan.sources) {
    line("input", {s.path, s.format, s.crs});
    if (!s.las.header.empty()) line("las_header", {hex_lower(as_text(s.las.header))});
    for (const LasVlr& r : s.las.records) {
      line("las_record", {r.extended ? "evlr" : "vlr", hex_lower(as_text(r.user_id)), std::to_string(r.record_id),
                          hex_lower(as_text(r.description)), hex_lower(as_text(r.data))});
    }
  }
  line("ranges", {std::to_string(plan.range_count())});
  for (std::size_t r = 1; r < plan.range_starts.size(); ++r) {
    const ChunkKey& k = plan.range_starts[r];
    line("range_start", {std::to_string(k.ix), std::to_string(k.iy), std::to_string(k.iz)});
  }
  line("end", {});
  return t;
}

std::uint64_t shard_plan_id(const ShardPlan& plan) { return shard::fnv1a64(shard_plan_text(plan)); }

Status write_shard_plan(const ShardPlan& plan, const std::string& path) {
  const std::string text = shard_plan_text(plan);
  if (text.size() > kMaxPlanBytes) {
    return limit_exceeded(path + ": the plan would take " + std::to_string(text.size() >> 20) + " MiB (at most " +
                          std::to_string(kMaxPlanBytes >> 20) + "): its inputs' LAS records are too large together");
  }
  return shard::write_text_atomic(path, text);
}

Result<ShardPlan> read_shard_plan(const std::string& path) {
  using shard::TextLine;
  RELIEF_ASSIGN_OR_RETURN(const std::string text, shard::read_text(path, kMaxPlanBytes));
  RELIEF_ASSIGN_OR_RETURN(const std::vector<TextLine> lines, shard::split_lines(path, text));
  const auto bad = [&path](std::size_t line, const std::string& what) {
    return format_error(path + ": line " + std::to_string(line) + ": " + what + " (not a Relief shard plan?)");
  };
  if (lines.empty() || lines[0].key != kPlanMagic || lines[0].fields.size() != 1) {
    return format_error(path + ": not a Relief shard plan (no '" + kPlanMagic + "' line)");
  }
  const std::string& version = lines[0].fields[0];
  if (version != "1" && version != "2" && version != std::to_string(kShardPlanVersion)) {
    return unsupported(path + ": shard plan version " + version + " (this build reads versions 1 to " +
                       std::to_string(kShardPlanVersion) + ")");
  }
  const bool v2 = version != "1";
  const bool v3 = version == "3";
  ShardPlan plan;
  ScanAttributes& a = plan.attributes;
  constexpr std::int64_t kLowest = std::numeric_limits<std::int64_t>::min();
  plan.range_starts.push_back(ChunkKey{kLowest, kLowest, kLowest});
  std::uint64_t declared_ranges = 0;
  bool ended = false, have_grid = false, have_params = false, have_ranges = false, have_las = false,
       have_extra = false;
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const TextLine& l = lines[i];
    const std::size_t n = i + 1;
    if (ended) return bad(n, "text after 'end'");
    const auto want = [&](std::size_t count) -> Status {
      if (l.fields.size() != count) {
        return bad(n, "'" + l.key + "' takes " + std::to_string(count) + " fields, not " +
                          std::to_string(l.fields.size()));
      }
      return Status::ok();
    };
    const auto parse_double = [&](const std::string& f, double& out) -> Status {
      char* end = nullptr;
      errno = 0;
      out = std::strtod(f.c_str(), &end);
      if (f.empty() || *end != '\0' || errno != 0 || !std::isfinite(out)) return bad(n, "not a number: " + f);
      return Status::ok();
    };
    const auto parse_int = [&](const std::string& f, std::int64_t& out) -> Status {
      char* end = nullptr;
      errno = 0;
      const long long v = std::strtoll(f.c_str(), &end, 10);
      if (f.empty() || *end != '\0' || errno != 0) return bad(n, "not an integer: " + f);
      out = v;
      return Status::ok();
    };
    const auto parse_flag = [&](const std::string& f, bool& out) -> Status {
      if (f != "0" && f != "1") return bad(n, "not 0 or 1: " + f);
      out = f == "1";
      return Status::ok();
    };
    if (l.key == "creator") {
      RELIEF_RETURN_IF_ERROR(want(1));
      plan.creator = l.fields[0];
    } else if (l.key == "archive_params") {
      RELIEF_RETURN_IF_ERROR(want(1));
      plan.archive_params = l.fields[0];
      auto params = encode_params_from_string(plan.archive_params);
      if (!params) return bad(n, "codec parameters: " + params.status().message());
      if (!params->bound) return bad(n, "codec parameters without an error bound");
      have_params = true;
    } else if (l.key == "intensity_range") {
      RELIEF_RETURN_IF_ERROR(want(2));
      double lo = 0, hi = 0;
      RELIEF_RETURN_IF_ERROR(parse_double(l.fields[0], lo));
      RELIEF_RETURN_IF_ERROR(parse_double(l.fields[1], hi));
      if (!(lo <= hi)) return bad(n, "an empty intensity range");
      plan.has_intensity_range = true;
      plan.intensity_lo = static_cast<float>(lo);
      plan.intensity_hi = static_cast<float>(hi);
    } else if (l.key == "grid") {
      RELIEF_RETURN_IF_ERROR(want(4));
      RELIEF_RETURN_IF_ERROR(parse_double(l.fields[0], plan.grid.origin.x));
      RELIEF_RETURN_IF_ERROR(parse_double(l.fields[1], plan.grid.origin.y));
      RELIEF_RETURN_IF_ERROR(parse_double(l.fields[2], plan.grid.origin.z));
      RELIEF_RETURN_IF_ERROR(parse_double(l.fields[3], plan.grid.chunk_edge));
      if (!(plan.grid.chunk_edge > 0) || plan.grid.chunk_edge > kMaxCoordinateMagnitude) {
        return bad(n, "chunk edge out of range");
      }
      have_grid = true;
    } else if (l.key == "attributes") {
      RELIEF_RETURN_IF_ERROR(want(2));
      RELIEF_RETURN_IF_ERROR(parse_flag(l.fields[0], a.has_colors));
      RELIEF_RETURN_IF_ERROR(parse_flag(l.fields[1], a.has_intensity));
    } else if (l.key == "las") {
      if (!v2) return bad(n, "a version 1 plan has no 'las' line");
      if (have_las) return bad(n, "a second 'las' line");
      RELIEF_RETURN_IF_ERROR(want(4));
      a.las_attributes = las_attributes_from_list(l.fields[0]);
      // Strict: every name known, in bit order, each once.
      if (las_attribute_list(a.las_attributes) != l.fields[0]) {
        return bad(n, "not a list of LAS attribute names: " + l.fields[0]);
      }
      std::int64_t format = 0, minor = 0;
      RELIEF_RETURN_IF_ERROR(parse_int(l.fields[1], format));
      RELIEF_RETURN_IF_ERROR(parse_int(l.fields[2], minor));
      if (format < -1 || format > kMaxLasPointFormat) return bad(n, "LAS point format out of range");
      if (minor < -1 || minor > kMaxLasVersionMinor) return bad(n, "LAS minor version out of range");
      a.las_point_format = static_cast<int>(format);
      a.las_version_minor = static_cast<int>(minor);
      RELIEF_RETURN_IF_ERROR(parse_flag(l.fields[3], a.las_colors_8bit));
      have_las = true;
    } else if (l.key == "gps_time_type") {
      if (!have_las) return bad(n, "'gps_time_type' before (or without) the 'las' line");
      if (a.las_gps_time_type != GpsTimeType::kUnknown) return bad(n, "a second 'gps_time_type' line");
      RELIEF_RETURN_IF_ERROR(want(1));
      a.las_gps_time_type = parse_gps_time_type(l.fields[0]);
      if (a.las_gps_time_type == GpsTimeType::kUnknown) return bad(n, "GPS time type is not 'week' or 'standard'");
    } else if (l.key == "extra_bytes") {
      if (!have_las) return bad(n, "'extra_bytes' before (or without) the 'las' line");
      if (have_extra) return bad(n, "a second 'extra_bytes' line");
      RELIEF_RETURN_IF_ERROR(want(2));
      std::int64_t size = 0;
      RELIEF_RETURN_IF_ERROR(parse_int(l.fields[0], size));
      if (size < 1 || size > kMaxExtraBytesSize) return bad(n, "extra bytes per point out of range (1..65535)");
      a.extra_bytes_size = static_cast<std::uint32_t>(size);
      if (l.fields[1].size() > 2 * kMaxExtraBytesVlrBytes || !decode_vlr_hex(l.fields[1], a.extra_bytes_vlr)) {
        return bad(n, "the Extra Bytes VLR is not lower-case hexadecimal of at most 65535 bytes");
      }
      have_extra = true;
    } else if (l.key == "crs") {
      RELIEF_RETURN_IF_ERROR(want(1));
      a.crs = l.fields[0];
    } else if (l.key == "split_points") {
      RELIEF_RETURN_IF_ERROR(want(1));
      std::int64_t v = 0;
      RELIEF_RETURN_IF_ERROR(parse_int(l.fields[0], v));
      if (v < 1) return bad(n, "split_points must be positive");
      plan.split_points = static_cast<std::uint64_t>(v);
    } else if (l.key == "xyz_columns") {
      RELIEF_RETURN_IF_ERROR(want(1));
      plan.has_xyz_columns = true;
      plan.xyz_columns = l.fields[0];
    } else if (l.key == "no_extra_bytes") {
      RELIEF_RETURN_IF_ERROR(want(0));
      plan.no_extra_bytes = true;
    } else if (l.key == "keep_attributes") {
      RELIEF_RETURN_IF_ERROR(want(1));
      Result<AttributeSet> keep = parse_attribute_set(l.fields[0].empty() ? "none" : l.fields[0]);
      if (!keep) return bad(n, keep.status().message());
      plan.keep = *keep;
    } else if (l.key == "points") {
      RELIEF_RETURN_IF_ERROR(want(1));
      std::int64_t v = 0;
      RELIEF_RETURN_IF_ERROR(parse_int(l.fields[0], v));
      if (v < 0) return bad(n, "a negative point count");
      plan.points = static_cast<std::uint64_t>(v);
    } else if (l.key == "input") {
      RELIEF_RETURN_IF_ERROR(want(3));
      ArchiveSource s;
      s.path = l.fields[0];
      s.format = l.fields[1];
      s.crs = l.fields[2];
      plan.sources.push_back(s);
    } else if (l.key == "las_header") {
      RELIEF_RETURN_IF_ERROR(want(1));
      if (!v3) return bad(n, "'las_header' in a plan of version " + version);
      if (plan.sources.empty() || !plan.sources.back().las.empty()) {
        return bad(n, "'las_header' not right after an 'input' line");
      }
      std::optional<std::string> bytes = bytes_from_hex(l.fields[0], false);
      if (!bytes) return bad(n, "not a LAS header block in hexadecimal");
      plan.sources.back().las.header.assign(bytes->begin(), bytes->end());
      if (const std::string problem = las_metadata_problem(plan.sources.back().las); !problem.empty()) {
        return bad(n, problem);
      }
    } else if (l.key == "las_record") {
      RELIEF_RETURN_IF_ERROR(want(5));
      if (!v3) return bad(n, "'las_record' in a plan of version " + version);
      if (plan.sources.empty() || plan.sources.back().las.header.empty()) {
        return bad(n, "'las_record' without its input's 'las_header'");
      }
      LasVlr r;
      if (l.fields[0] != "vlr" && l.fields[0] != "evlr") return bad(n, "not vlr or evlr: " + l.fields[0]);
      r.extended = l.fields[0] == "evlr";
      std::int64_t id = 0;
      RELIEF_RETURN_IF_ERROR(parse_int(l.fields[2], id));
      if (id < 0 || id > 65535) return bad(n, "record id out of range");
      r.record_id = static_cast<std::uint16_t>(id);
      std::optional<std::string> user = bytes_from_hex(l.fields[1], false);
      std::optional<std::string> description = bytes_from_hex(l.fields[3], false);
      std::optional<std::string> data = bytes_from_hex(l.fields[4], false);
      if (!user || user->size() != r.user_id.size() || !description ||
          description->size() != r.description.size() || !data || data->size() > kMaxKeptLasRecord) {
        return bad(n, "a malformed LAS record");
      }
      std::memcpy(r.user_id.data(), user->data(), r.user_id.size());
      std::memcpy(r.description.data(), description->data(), r.description.size());
      r.data.assign(data->begin(), data->end());
      if (!r.extended && r.data.size() > 65535) return bad(n, "a VLR of more than 65535 bytes");
      plan.sources.back().las.records.push_back(std::move(r));
    } else if (l.key == "ranges") {
      RELIEF_RETURN_IF_ERROR(want(1));
      std::int64_t v = 0;
      RELIEF_RETURN_IF_ERROR(parse_int(l.fields[0], v));
      if (v < 1 || v > static_cast<std::int64_t>(kMaxShardRanges)) return bad(n, "ranges out of range");
      declared_ranges = static_cast<std::uint64_t>(v);
      have_ranges = true;
    } else if (l.key == "range_start") {
      RELIEF_RETURN_IF_ERROR(want(3));
      ChunkKey k;
      RELIEF_RETURN_IF_ERROR(parse_int(l.fields[0], k.ix));
      RELIEF_RETURN_IF_ERROR(parse_int(l.fields[1], k.iy));
      RELIEF_RETURN_IF_ERROR(parse_int(l.fields[2], k.iz));
      if (!(plan.range_starts.back() < k)) return bad(n, "range starts must increase");
      if (plan.range_starts.size() >= kMaxShardRanges) return bad(n, "too many ranges");
      plan.range_starts.push_back(k);
    } else if (l.key == "end") {
      RELIEF_RETURN_IF_ERROR(want(0));
      ended = true;
    } else {
      return bad(n, "unknown key '" + l.key + "'");
    }
  }
  if (!ended) return format_error(path + ": truncated shard plan (no 'end' line)");
  if (!have_grid || !have_params || !have_ranges || plan.sources.empty()) {
    return format_error(path + ": shard plan lacks its grid, codec parameters, ranges or inputs");
  }
  if (v2 && !have_las) return format_error(path + ": a version 2 shard plan without its 'las' line");
  if (have_las && !plan.has_las()) {
    return format_error(path + ": a 'las' line without LAS metadata (such a plan is written as version 1)");
  }
  if (((a.las_attributes & kLasExtraBytes) != 0) != have_extra) {
    return format_error(path + ": the 'las' line and the 'extra_bytes' line disagree on extra bytes");
  }
  if ((a.las_attributes & kLasColorLow) != 0 && !a.has_colors) {
    return format_error(path + ": LAS colour low bytes without colours");
  }
  if (declared_ranges != plan.range_starts.size()) {
    return format_error(path + ": shard plan declares " + std::to_string(declared_ranges) + " ranges but lists " +
                        std::to_string(plan.range_starts.size()));
  }
  return plan;
}

}  // namespace relief
