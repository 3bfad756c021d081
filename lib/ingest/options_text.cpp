// Ingest and encoder options from text (relief/ingest.h): the parser shared by
// the CLI and the Python bindings.
#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <map>
#include <optional>

#include "relief/codec.h"
#include "relief/crs.h"
#include "relief/ingest.h"

namespace relief {

namespace {

// Colour tolerance range of the bounded mode (levels per 8-bit channel).
constexpr long long kMaxColorTolerance = 127;
// Encoder threads: far more than any machine, so a typo is caught.
constexpr long long kMaxThreads = 1024;
constexpr long long kMaxOctreePoints = 1LL << 30;

const std::vector<std::string> kEncodeNames = {
    "cell",    "decomposition", "max-points",        "resolution",  "codec",
    "quality", "color-quality", "intensity-quality", "height-bits", "fill"};
const std::vector<std::string> kModeNames = {"mode", "tolerance", "color-tolerance", "intensity-tolerance"};
const std::vector<std::string> kRunNames = {"memory", "threads", "tmp", "columns", "pyramid", "crs"};
const std::vector<std::string> kCompressOnlyNames = {"chunk-edge", "error-target"};
// Options of the commands that read input files (not stream, whose
// --attributes names its binary record's fields).
const std::vector<std::string> kFileInputNames = {"attributes"};

std::string canonical(std::string_view name) {
  while (!name.empty() && name.front() == '-') name.remove_prefix(1);
  std::string out(name);
  std::replace(out.begin(), out.end(), '_', '-');
  return out;
}

// The given options by canonical name, with a checked vocabulary and the
// spelling for messages.
class Given {
 public:
  Given(const std::vector<NamedOption>& given, OptionSpelling spelling) : spelling_(spelling) {
    for (const NamedOption& o : given) values_[canonical(o.name)] = o.value;
  }

  // kInvalidArgument for the first name outside `options` and `flags`.
  Status check_names(const std::vector<std::string>& options, const std::vector<std::string>& flags) const {
    for (const auto& [name, value] : values_) {
      if (std::find(options.begin(), options.end(), name) == options.end() &&
          std::find(flags.begin(), flags.end(), name) == flags.end()) {
        return invalid_argument("unknown option " + show(name));
      }
    }
    return Status::ok();
  }

  std::string show(const std::string& name) const {
    if (spelling_ == OptionSpelling::kCli) return "--" + name;
    std::string out = name;
    std::replace(out.begin(), out.end(), '-', '_');
    return out;
  }

  bool has(const std::string& name) const { return values_.count(name) != 0; }
  std::optional<std::string> get(const std::string& name) const {
    const auto it = values_.find(name);
    if (it == values_.end()) return std::nullopt;
    return it->second;
  }

  Status get_double(const std::string& name, double& out) const {
    const auto v = get(name);
    if (!v) return Status::ok();
    double d = 0;
    const char* end = v->data() + v->size();
    const auto r = std::from_chars(v->data(), end, d);
    if (r.ec != std::errc() || r.ptr != end || !std::isfinite(d)) {
      return invalid_argument("option " + show(name) + " expects a number, got '" + *v + "'");
    }
    out = d;
    return Status::ok();
  }

  template <typename T>
  Status get_int(const std::string& name, T& out, long long lo, long long hi) const {
    const auto v = get(name);
    if (!v) return Status::ok();
    long long n = 0;
    const char* end = v->data() + v->size();
    const auto r = std::from_chars(v->data(), end, n);
    if (r.ec != std::errc() || r.ptr != end || n < lo || n > hi) {
      return invalid_argument("option " + show(name) + " expects a whole number from " + std::to_string(lo) +
                              " to " + std::to_string(hi) + ", got '" + *v + "'");
    }
    out = static_cast<T>(n);
    return Status::ok();
  }

  Status get_flag(const std::string& name, bool& out) const {
    const auto v = get(name);
    if (!v) return Status::ok();
    if (v->empty() || *v == "true" || *v == "1") {
      out = true;
    } else if (*v == "false" || *v == "0") {
      out = false;
    } else {
      return invalid_argument("option " + show(name) + " is a flag (true or false), got '" + *v + "'");
    }
    return Status::ok();
  }

 private:
  OptionSpelling spelling_;
  std::map<std::string, std::string> values_;
};

Status apply_encode(const Given& g, EncodeParams& p) {
  RELIEF_RETURN_IF_ERROR(g.get_double("cell", p.cell_size));
  if (g.has("cell") && !(p.cell_size > 0)) return invalid_argument(g.show("cell") + " must be positive");
  if (auto d = g.get("decomposition")) {
    if (*d == "voxel") {
      p.decomposition = Decomposition::kVoxelGrid;
    } else if (*d == "octree") {
      p.decomposition = Decomposition::kOctree;
    } else {
      return invalid_argument(g.show("decomposition") + " must be voxel or octree, got '" + *d + "'");
    }
  }
  RELIEF_RETURN_IF_ERROR(g.get_int("max-points", p.octree_max_points, 1, kMaxOctreePoints));
  RELIEF_RETURN_IF_ERROR(g.get_int("resolution", p.map_resolution, 8, 64));
  if (auto c = g.get("codec")) {
    if (*c == "jpeg") {
      p.image_codec = ImageCodec::kJpeg;
    } else if (*c == "jpeg2000" || *c == "j2k") {
      p.image_codec = ImageCodec::kJpeg2000;
    } else {
      return invalid_argument(g.show("codec") + " must be jpeg or jpeg2000, got '" + *c + "'");
    }
  }
  RELIEF_RETURN_IF_ERROR(g.get_int("quality", p.height_quality, 1, 100));
  RELIEF_RETURN_IF_ERROR(g.get_int("color-quality", p.color_quality, 1, 100));
  RELIEF_RETURN_IF_ERROR(g.get_int("intensity-quality", p.intensity_quality, 1, 100));
  RELIEF_RETURN_IF_ERROR(g.get_int("height-bits", p.height_bits, 8, 16));
  if (auto f = g.get("fill")) {
    if (*f == "project") {
      p.fill = FillMethod::kBlockProjection;
    } else if (*f == "pushpull") {
      p.fill = FillMethod::kPushPull;
    } else if (*f == "box") {
      p.fill = FillMethod::kBoxFilter;
    } else {
      return invalid_argument(g.show("fill") + " must be project, pushpull or box, got '" + *f + "'");
    }
  }
  // Caught here, before any work, rather than as a failure of the first chunk.
  if (p.map_resolution % 8 != 0) {
    return invalid_argument(g.show("resolution") + " must be a multiple of 8 from 8 to 64, got " +
                            std::to_string(p.map_resolution));
  }
  if (p.height_bits != 8 && p.height_bits != 16) {
    return invalid_argument(g.show("height-bits") + " must be 8 or 16, got " + std::to_string(p.height_bits));
  }
  if (p.height_bits == 16 && p.image_codec != ImageCodec::kJpeg2000) {
    return invalid_argument(g.show("height-bits") + " 16 needs " + g.show("codec") +
                            " jpeg2000 (JPEG is 8-bit)");
  }
  return validate_encode_params(p);
}

Status apply_mode(const Given& g, IngestOptions& o) {
  if (auto m = g.get("mode")) {
    if (*m == "bounded") {
      o.mode = IngestMode::kBounded;
    } else if (*m == "resample") {
      o.mode = IngestMode::kResample;
    } else {
      return invalid_argument(g.show("mode") + " must be bounded or resample, got '" + *m + "'");
    }
  }
  if (g.has("tolerance")) {
    RELIEF_RETURN_IF_ERROR(g.get_double("tolerance", o.tolerance));
    if (!(o.tolerance > 0)) return invalid_argument(g.show("tolerance") + " must be a positive number");
  }
  RELIEF_RETURN_IF_ERROR(g.get_int("color-tolerance", o.color_tolerance, 0, kMaxColorTolerance));
  RELIEF_RETURN_IF_ERROR(g.get_int("intensity-tolerance", o.intensity_tolerance, 0, kMaxIntensityTolerance));
  const bool bounded_only = g.has("tolerance") || g.has("color-tolerance");
  if (o.mode == IngestMode::kResample && bounded_only) {
    return invalid_argument(g.show("tolerance") + " and " + g.show("color-tolerance") + " apply to " +
                            g.show("mode") + " bounded");
  }
  if (o.mode == IngestMode::kResample && g.has("intensity-tolerance")) {
    return invalid_argument(g.show("intensity-tolerance") + " applies to " + g.show("mode") + " bounded");
  }
  RELIEF_RETURN_IF_ERROR(g.get_flag("keep-order", o.keep_order));
  if (o.mode == IngestMode::kResample && o.keep_order) {
    return invalid_argument(g.show("keep-order") + " applies to " + g.show("mode") + " bounded");
  }
  RELIEF_RETURN_IF_ERROR(g.get_flag("fast-geometry", o.fast_geometry));
  if (o.mode == IngestMode::kResample && o.fast_geometry) {
    return invalid_argument(g.show("fast-geometry") + " applies to " + g.show("mode") + " bounded");
  }
  return Status::ok();
}

Status apply_run(const Given& g, IngestOptions& o) {
  if (auto m = g.get("pyramid")) {
    const std::optional<PyramidMode> mode = pyramid_mode_from_text(*m);
    if (!mode) return invalid_argument(g.show("pyramid") + " must be auto, on or off, got '" + *m + "'");
    o.pyramid = *mode;
  }
  if (auto m = g.get("memory")) {
    o.memory_budget = parse_byte_size(*m);
    if (o.memory_budget == 0) {
      return invalid_argument(g.show("memory") + " expects a size such as 512M or 2G, got '" + *m + "'");
    }
    if (o.memory_budget < kMinMemoryBudget) {
      return invalid_argument(g.show("memory") + " " + *m + " is below the minimum of " +
                              std::to_string(kMinMemoryBudget >> 20) + "M");
    }
  }
  RELIEF_RETURN_IF_ERROR(g.get_int("threads", o.threads, 0, kMaxThreads));
  if (auto t = g.get("tmp")) o.tmp_dir = *t;
  if (auto c = g.get("columns")) o.reader.xyz_columns = *c;
  return g.get_flag("verify", o.verify_blobs);
}

void append_names(std::vector<std::string>& out, const std::vector<std::string>& more) {
  out.insert(out.end(), more.begin(), more.end());
}

}  // namespace

std::optional<PyramidMode> pyramid_mode_from_text(std::string_view text) {
  if (text == "auto") return PyramidMode::kAuto;
  if (text == "on") return PyramidMode::kOn;
  if (text == "off") return PyramidMode::kOff;
  return std::nullopt;
}

std::vector<std::string> encode_option_names() { return kEncodeNames; }

std::vector<std::string> ingest_option_names(IngestOptionSet set) {
  std::vector<std::string> names;
  if (set != IngestOptionSet::kAppend) {
    append_names(names, kEncodeNames);
    append_names(names, kModeNames);
  }
  append_names(names, kRunNames);
  if (set == IngestOptionSet::kCompress) append_names(names, kCompressOnlyNames);
  if (set != IngestOptionSet::kStream) append_names(names, kFileInputNames);
  return names;
}

std::vector<std::string> ingest_flag_names(IngestOptionSet set) {
  switch (set) {
    case IngestOptionSet::kCompress:
      return {"verify",     "allow-sparse",  "assume-crs", "no-extra-bytes",
              "keep-order", "fast-geometry", "no-spool"};
    case IngestOptionSet::kAppend:
      return {"verify", "assume-crs", "no-extra-bytes"};
    case IngestOptionSet::kStream:
      return {"verify", "keep-order", "fast-geometry"};
  }
  return {};
}

Status apply_encode_options(const std::vector<NamedOption>& given, OptionSpelling spelling,
                            EncodeParams& params) {
  const Given g(given, spelling);
  RELIEF_RETURN_IF_ERROR(g.check_names(kEncodeNames, {}));
  return apply_encode(g, params);
}

std::vector<std::string> bound_option_names() { return {"tolerance", "color-tolerance", "intensity-tolerance"}; }
std::vector<std::string> bound_flag_names() { return {"keep-order", "fast-geometry"}; }

Status apply_bound_options(const std::vector<NamedOption>& given, OptionSpelling spelling, EncodeParams& params) {
  const Given g(given, spelling);
  RELIEF_RETURN_IF_ERROR(g.check_names(bound_option_names(), bound_flag_names()));
  if (!g.has("tolerance")) {
    for (const std::string& name : {std::string("color-tolerance"), std::string("intensity-tolerance"),
                                    std::string("keep-order"), std::string("fast-geometry")}) {
      if (g.has(name)) return invalid_argument(g.show(name) + " applies only with " + g.show("tolerance"));
    }
    return Status::ok();
  }
  // The ingest's own checks of these options (mode bounded, as given).
  IngestOptions o;
  RELIEF_RETURN_IF_ERROR(apply_mode(g, o));
  const double step = 2 * o.tolerance;
  if (!std::isfinite(step)) return invalid_argument(g.show("tolerance") + " is too large");
  ErrorBound b;
  b.step = {step, step, step};
  b.color_tolerance = o.color_tolerance;
  b.intensity_tolerance = o.intensity_tolerance;
  b.keep_order = o.keep_order;
  b.fast_geometry = o.fast_geometry;
  params.bound = b;
  return Status::ok();
}

Status apply_ingest_options(IngestOptionSet set, const std::vector<NamedOption>& given,
                            OptionSpelling spelling, IngestOptions& o) {
  const Given g(given, spelling);
  RELIEF_RETURN_IF_ERROR(g.check_names(ingest_option_names(set), ingest_flag_names(set)));
  if (set != IngestOptionSet::kAppend) RELIEF_RETURN_IF_ERROR(apply_encode(g, o.codec));
  if (set == IngestOptionSet::kCompress) {
    RELIEF_RETURN_IF_ERROR(g.get_double("chunk-edge", o.chunk_edge));
    if (g.has("chunk-edge") && !(o.chunk_edge > 0))
      return invalid_argument(g.show("chunk-edge") + " must be positive");
    if (g.has("error-target")) {
      RELIEF_RETURN_IF_ERROR(g.get_double("error-target", o.error_target));
      if (!(o.error_target > 0)) return invalid_argument(g.show("error-target") + " must be positive");
      if (g.has("mode") && *g.get("mode") != "resample") {
        return invalid_argument(g.show("error-target") + " needs " + g.show("mode") + " resample");
      }
      // The error target chooses the resampling cell, so it implies that mode.
      o.mode = IngestMode::kResample;
    }
    RELIEF_RETURN_IF_ERROR(g.get_flag("allow-sparse", o.allow_sparse));
    bool no_spool = false;
    RELIEF_RETURN_IF_ERROR(g.get_flag("no-spool", no_spool));
    o.spool = !no_spool;
  }
  if (set != IngestOptionSet::kAppend) RELIEF_RETURN_IF_ERROR(apply_mode(g, o));
  RELIEF_RETURN_IF_ERROR(apply_run(g, o));
  if (const auto crs = g.get("crs")) {
    if (Result<std::string> wkt = crs_to_wkt2(*crs, g.show("crs")); !wkt) return invalid_argument(wkt.status().message());
    o.crs = *crs;
  }
  if (set != IngestOptionSet::kStream) {
    RELIEF_RETURN_IF_ERROR(g.get_flag("assume-crs", o.assume_crs));
    bool drop_extra = false;
    RELIEF_RETURN_IF_ERROR(g.get_flag("no-extra-bytes", drop_extra));
    o.reader.extra_bytes = !drop_extra;
    if (const auto list = g.get("attributes")) {
      Result<AttributeSet> keep = parse_attribute_set(*list);
      if (!keep) return invalid_argument(g.show("attributes") + ": " + keep.status().message());
      o.reader.attributes = *keep;
    }
  }
  return Status::ok();
}

std::uint64_t parse_byte_size(std::string_view text) {
  if (text.empty()) return 0;
  double v = 0;
  const char* end = text.data() + text.size();
  const auto r = std::from_chars(text.data(), end, v);
  if (r.ec != std::errc() || !(v > 0) || !std::isfinite(v)) return 0;
  std::string unit(r.ptr, end);
  for (char& ch : unit) ch = static_cast<char>(std::toupper(static_cast<unsigned char>(ch)));
  if (!unit.empty() && unit.back() == 'B') unit.pop_back();
  if (!unit.empty() && unit.back() == 'I') unit.pop_back();  // GiB, MiB
  double scale = 0;
  if (unit.empty() || unit == "M") {
    scale = 1024.0 * 1024.0;
  } else if (unit == "K") {
    scale = 1024.0;
  } else if (unit == "G") {
    scale = 1024.0 * 1024.0 * 1024.0;
  } else if (unit == "T") {
    scale = 1024.0 * 1024.0 * 1024.0 * 1024.0;
  } else {
    return 0;
  }
  // Beyond 2^63 bytes is no budget any machine has; refused rather than wrapped.
  const double bytes = v * scale;
  if (!(bytes < 9.2e18)) return 0;
  return static_cast<std::uint64_t>(bytes);
}

}  // namespace relief
