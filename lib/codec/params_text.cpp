// EncodeParams <-> "key=value;..." text, as stored in archive metadata.
#include <charconv>
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

}  // namespace

std::string encode_params_to_string(const EncodeParams& p) {
  std::string s;
  s += "decomposition=";
  s += decomposition_name(p.decomposition);
  s += ";cell=" + exact(p.cell_size);
  s += ";max_points=" + std::to_string(p.octree_max_points);
  s += ";cone=" + exact(p.normal_cone_degrees);
  s += ";r=" + std::to_string(p.map_resolution);
  s += ";image=";
  s += image_codec_name(p.image_codec);
  s += ";q=" + std::to_string(p.height_quality);
  s += ";color_q=" + std::to_string(p.color_quality);
  s += ";intensity_q=" + std::to_string(p.intensity_quality);
  s += ";height_bits=" + std::to_string(p.height_bits);
  s += ";fill=";
  s += fill_name(p.fill);
  if (p.bound) {
    const ErrorBound& b = *p.bound;
    s += ";step=" + exact(b.step.x) + "," + exact(b.step.y) + "," + exact(b.step.z);
    s += ";origin=" + exact(b.origin.x) + "," + exact(b.origin.y) + "," + exact(b.origin.z);
    s += ";color_tol=" + std::to_string(b.color_tolerance);
  }
  return s;
}

Result<EncodeParams> encode_params_from_string(const std::string& text) {
  EncodeParams p;
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
    } else {
      return format_error("codec parameters: unknown key '" + key + "'");
    }
    if (!ok) return format_error("codec parameters: bad value '" + std::string(value) + "' for '" + key + "'");
  }
  return p;
}

}  // namespace relief
