// EncodeParams <-> "key=value;..." text, as stored in archive metadata.
#include <charconv>
#include <cmath>
#include <cstdio>
#include <string>
#include <string_view>

#include "relief/codec.h"

namespace relief {

namespace {

const char* fill_name(FillMethod f) {
  switch (f) {
    case FillMethod::kBlockProjection: return "project";
    case FillMethod::kPushPull: return "pushpull";
    case FillMethod::kBoxFilter: return "box";
  }
  return "project";
}

// Shortest decimal that parses back to the same double.
std::string exact(double v) {
  char buf[64];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

template <typename T>
bool parse_number(std::string_view s, T& out) {
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return r.ec == std::errc() && r.ptr == s.data() + s.size();
}

// "x,y,z" -> Vec3d.
bool parse_vec3(std::string_view s, Vec3d& out) {
  const std::size_t a = s.find(',');
  if (a == std::string_view::npos) return false;
  const std::size_t b = s.find(',', a + 1);
  if (b == std::string_view::npos) return false;
  return parse_number(s.substr(0, a), out.x) && parse_number(s.substr(a + 1, b - a - 1), out.y) &&
         parse_number(s.substr(b + 1), out.z);
}

// The values a key takes when the text leaves it out: frozen here and in
// format-spec/archive.md (§2.1.1), never taken from EncodeParams' defaults,
// which may change while stored texts must keep their meaning.
EncodeParams text_defaults() {
  EncodeParams p;
  p.decomposition = Decomposition::kVoxelGrid;
  p.cell_size = 0;
  p.octree_max_points = 1024;
  p.normal_cone_degrees = 0;
  p.map_resolution = 16;
  p.image_codec = ImageCodec::kJpeg;
  p.height_quality = 75;
  p.color_quality = 70;
  p.intensity_quality = 70;
  p.height_bits = 8;
  p.fill = FillMethod::kBlockProjection;
  p.bound.reset();
  return p;
}

}  // namespace

std::string encode_params_to_string(const EncodeParams& p, ParamsText form) {
  const bool all = form == ParamsText::kFull;
  const EncodeParams d = text_defaults();
  std::string s;
  const auto add = [&s](std::string_view key, const std::string& value) {
    if (!s.empty()) s += ';';
    s += key;
    s += '=';
    s += value;
  };
  if (all || p.decomposition != d.decomposition) add("decomposition", decomposition_name(p.decomposition));
  add("cell", exact(p.cell_size));
  if (all || p.octree_max_points != d.octree_max_points) add("max_points", std::to_string(p.octree_max_points));
  if (all || p.normal_cone_degrees != d.normal_cone_degrees) add("cone", exact(p.normal_cone_degrees));
  if (all || p.map_resolution != d.map_resolution) add("r", std::to_string(p.map_resolution));
  if (all || p.image_codec != d.image_codec) add("image", image_codec_name(p.image_codec));
  if (all || p.height_quality != d.height_quality) add("q", std::to_string(p.height_quality));
  if (all || p.color_quality != d.color_quality) add("color_q", std::to_string(p.color_quality));
  if (all || p.intensity_quality != d.intensity_quality) add("intensity_q", std::to_string(p.intensity_quality));
  if (all || p.height_bits != d.height_bits) add("height_bits", std::to_string(p.height_bits));
  if (all || p.fill != d.fill) add("fill", fill_name(p.fill));
  if (p.bound) {
    // "step" is always written: it marks the error-bounded mode.
    const ErrorBound& b = *p.bound;
    add("step", exact(b.step.x) + "," + exact(b.step.y) + "," + exact(b.step.z));
    if (all || b.origin.x != 0 || b.origin.y != 0 || b.origin.z != 0 || std::signbit(b.origin.x) ||
        std::signbit(b.origin.y) || std::signbit(b.origin.z)) {
      add("origin", exact(b.origin.x) + "," + exact(b.origin.y) + "," + exact(b.origin.z));
    }
    if (all || b.color_tolerance != 0) add("color_tol", std::to_string(b.color_tolerance));
    if (all || b.intensity_tolerance != 0) add("intensity_tol", std::to_string(b.intensity_tolerance));
    if (all || b.keep_order) add("order", b.keep_order ? "input" : "any");
    // In the compact form only when set: archives made without it keep
    // their parameter text.
    if (all || b.fast_geometry) add("geometry", b.fast_geometry ? "fast" : "planes");
  }
  return s;
}

Result<EncodeParams> encode_params_from_string(const std::string& text) {
  EncodeParams p = text_defaults();
  std::string_view rest(text);
  while (!rest.empty()) {
    const std::size_t semi = rest.find(';');
    const std::string_view item = rest.substr(0, semi);
    rest = semi == std::string_view::npos ? std::string_view() : rest.substr(semi + 1);
    const std::size_t eq = item.find('=');
    if (eq == std::string_view::npos) {
      return format_error("codec parameters: '" + std::string(item) + "' is not key=value");
    }
    const std::string key(item.substr(0, eq));
    const std::string_view value = item.substr(eq + 1);
    bool ok = true;
    if (key == "decomposition") {
      ok = value == "voxel" || value == "octree";
      p.decomposition = value == "octree" ? Decomposition::kOctree : Decomposition::kVoxelGrid;
    } else if (key == "cell") {
      ok = parse_number(value, p.cell_size);
    } else if (key == "max_points") {
      ok = parse_number(value, p.octree_max_points);
    } else if (key == "cone") {
      ok = parse_number(value, p.normal_cone_degrees);
    } else if (key == "r") {
      ok = parse_number(value, p.map_resolution);
    } else if (key == "image") {
      ok = value == "jpeg" || value == "jpeg2000";
      p.image_codec = value == "jpeg2000" ? ImageCodec::kJpeg2000 : ImageCodec::kJpeg;
    } else if (key == "q") {
      ok = parse_number(value, p.height_quality);
    } else if (key == "color_q") {
      ok = parse_number(value, p.color_quality);
    } else if (key == "intensity_q") {
      ok = parse_number(value, p.intensity_quality);
    } else if (key == "height_bits") {
      ok = parse_number(value, p.height_bits);
    } else if (key == "fill") {
      ok = value == "project" || value == "pushpull" || value == "box";
      p.fill = value == "box" ? FillMethod::kBoxFilter
               : value == "pushpull" ? FillMethod::kPushPull
                                     : FillMethod::kBlockProjection;
    } else if (key == "step") {
      if (!p.bound) p.bound = ErrorBound{};
      ok = parse_vec3(value, p.bound->step);
    } else if (key == "origin") {
      if (!p.bound) p.bound = ErrorBound{};
      ok = parse_vec3(value, p.bound->origin);
    } else if (key == "color_tol") {
      if (!p.bound) p.bound = ErrorBound{};
      ok = parse_number(value, p.bound->color_tolerance);
    } else if (key == "intensity_tol") {
      if (!p.bound) p.bound = ErrorBound{};
      ok = parse_number(value, p.bound->intensity_tolerance);
    } else if (key == "order") {
      if (!p.bound) p.bound = ErrorBound{};
      ok = value == "input" || value == "any";
      p.bound->keep_order = value == "input";
    } else if (key == "geometry") {
      if (!p.bound) p.bound = ErrorBound{};
      ok = value == "fast" || value == "planes";
      p.bound->fast_geometry = value == "fast";
    } else {
      return format_error("codec parameters: unknown key '" + key + "'");
    }
    if (!ok) return format_error("codec parameters: bad value '" + std::string(value) + "' for '" + key + "'");
  }
  return p;
}

std::string full_params_text(const std::string& text) {
  Result<EncodeParams> p = encode_params_from_string(text);
  return p ? encode_params_to_string(*p) : text;
}

}  // namespace relief
