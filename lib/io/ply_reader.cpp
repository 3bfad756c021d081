// PLY reader. The header is parsed into ply::Header; PlyPointReader then skips
// the elements before the vertex element and yields vertices in batches, so a
// file far larger than memory streams through a bounded buffer. read_ply and
// read_ply_memory drive the same reader to the end and additionally walk the
// elements after the vertices, so a file cut short anywhere is reported.
//
// The common case (binary in host byte order, x y z all float or all double,
// optional uchar colour and float intensity) is decoded by a small template
// kernel chosen once per file: fixed-size records, memcpy per field, no
// per-field dispatch. Everything else goes through a generic per-field loader.

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "io/byte_source.h"
#include "io/extra_fields.h"
#include "io/ply_format.h"
#include "io/readers.h"
#include "io/stream_support.h"
#include "io/text_columns.h"
#include "io/text_scan.h"
#include "relief/io.h"

namespace relief {

namespace {

using ply::Element;
using ply::Property;
using ply::ScalarType;

// Without a known input size (pipes) the header count is untrusted, so the
// whole-file reader reserves at most this much up front and vectors grow as
// data actually arrives.
constexpr std::uint64_t kBlindReserve = std::uint64_t{1} << 16;
// ascii records are one per line; a line this long is not a point record.
constexpr std::size_t kMaxAsciiLine = std::size_t{4} << 20;

// ---------------------------------------------------------------- header

Result<ply::Header> parse_header(ByteSource& src, const std::string& name) {
  std::span<const std::uint8_t> view;
  RELIEF_RETURN_IF_ERROR(src.fill(4, view));
  if (view.empty()) return format_error(name + ": not a PLY file: it is empty");
  const bool magic =
      view.size() >= 3 && std::memcmp(view.data(), "ply", 3) == 0 &&
      (view.size() == 3 || view[3] == '\n' || view[3] == '\r' || view[3] == ' ' || view[3] == '\t');
  if (!magic) return format_error(name + ": not a PLY file: it does not start with 'ply'");

  ply::Header header;
  bool have_format = false;
  std::size_t line_no = 0;
  for (;;) {
    std::string_view line;
    LineStatus state = LineStatus::kEnd;
    RELIEF_RETURN_IF_ERROR(next_line(src, ply::kMaxHeaderLine, line, state));
    ++line_no;
    const std::string where = name + ": header line " + std::to_string(line_no) + ": ";
    if (state == LineStatus::kEnd) return format_error(name + ": header has no end_header line");
    if (state == LineStatus::kTooLong || src.position() > ply::kMaxHeaderBytes) {
      return format_error(name + ": header has no end_header line in its first " +
                          std::to_string(ply::kMaxHeaderBytes) + " bytes");
    }
    const std::vector<std::string_view> tok = split_tokens(line);
    if (line_no == 1) {
      if (tok.size() != 1 || tok[0] != "ply") {
        return format_error(name + ": not a PLY file: the first line is not 'ply'");
      }
      continue;
    }
    if (tok.empty()) continue;  // tolerated: some writers leave blank lines
    const std::string_view kw = tok[0];
    if (kw == "comment" || kw == "obj_info") continue;
    if (kw == "end_header") break;
    if (kw == "format") {
      if (have_format) return format_error(where + "a second format line");
      if (tok.size() != 3) return format_error(where + "expected 'format <encoding> 1.0'");
      const auto enc = ply::parse_encoding(tok[1]);
      if (!enc) return format_error(where + "unknown format " + quoted(tok[1]));
      double version = 0;
      const auto [p, ec] = std::from_chars(tok[2].data(), tok[2].data() + tok[2].size(), version);
      if (ec != std::errc{} || p != tok[2].data() + tok[2].size()) {
        return format_error(where + "bad format version " + quoted(tok[2]));
      }
      if (version != 1.0) return unsupported(where + "PLY version " + quoted(tok[2]) + " (only 1.0)");
      header.encoding = *enc;
      have_format = true;
    } else if (kw == "element") {
      if (tok.size() != 3) return format_error(where + "expected 'element <name> <count>'");
      if (header.elements.size() >= ply::kMaxElements) {
        return format_error(where + "more than " + std::to_string(ply::kMaxElements) + " elements");
      }
      std::int64_t count = 0;
      const auto [p, ec] = std::from_chars(tok[2].data(), tok[2].data() + tok[2].size(), count);
      const bool whole = p == tok[2].data() + tok[2].size();
      if (ec == std::errc::result_out_of_range && whole) {
        return format_error(where + "element " + quoted(tok[1]) + " count " + quoted(tok[2]) +
                            " is absurdly large");
      }
      if (ec != std::errc{} || !whole) {
        return format_error(where + "element " + quoted(tok[1]) + " count " + quoted(tok[2]) +
                            " is not an integer");
      }
      if (count < 0) {
        return format_error(where + "element " + quoted(tok[1]) + " count " + quoted(tok[2]) +
                            " is negative");
      }
      if (static_cast<std::uint64_t>(count) > ply::kMaxElementCount) {
        return format_error(where + "element " + quoted(tok[1]) + " count " + quoted(tok[2]) +
                            " is absurdly large (limit " + std::to_string(ply::kMaxElementCount) + ")");
      }
      for (const Element& e : header.elements) {
        if (e.name == tok[1]) return format_error(where + "a second element " + quoted(tok[1]));
      }
      header.elements.push_back({std::string(tok[1]), static_cast<std::uint64_t>(count), {}});
    } else if (kw == "property") {
      if (header.elements.empty()) return format_error(where + "property before any element");
      Element& el = header.elements.back();
      if (el.properties.size() >= ply::kMaxProperties) {
        return format_error(where + "element " + quoted(el.name) + " has more than " +
                            std::to_string(ply::kMaxProperties) + " properties");
      }
      Property prop;
      if (tok.size() >= 2 && tok[1] == "list") {
        if (tok.size() != 5) {
          return format_error(where + "expected 'property list <count-type> <item-type> <name>'");
        }
        const auto count_type = ply::parse_scalar_type(tok[2]);
        const auto item_type = ply::parse_scalar_type(tok[3]);
        if (!count_type) return format_error(where + "unknown property type " + quoted(tok[2]));
        if (!item_type) return format_error(where + "unknown property type " + quoted(tok[3]));
        if (!ply::is_integer(*count_type)) {
          return format_error(where + "list count type " + quoted(tok[2]) + " is not an integer type");
        }
        prop.is_list = true;
        prop.count_type = *count_type;
        prop.type = *item_type;
        prop.name = std::string(tok[4]);
      } else {
        if (tok.size() != 3) return format_error(where + "expected 'property <type> <name>'");
        const auto type = ply::parse_scalar_type(tok[1]);
        if (!type) return format_error(where + "unknown property type " + quoted(tok[1]));
        prop.type = *type;
        prop.name = std::string(tok[2]);
      }
      if (el.find(prop.name)) {
        return format_error(where + "element " + quoted(el.name) + " has two properties " +
                            quoted(prop.name));
      }
      el.properties.push_back(std::move(prop));
    } else {
      return format_error(where + "unknown header keyword " + quoted(kw));
    }
  }
  if (!have_format) return format_error(name + ": header has no format line");
  return header;
}

// ---------------------------------------------------------------- vertex plan

// The fields a vertex property can feed: the coordinates, colours and
// intensity, then the LAS dimensions (kLasField + k is las_text_columns()[k]).
enum Field : std::size_t { kX, kY, kZ, kRed, kGreen, kBlue, kIntensity, kLasField };
constexpr std::size_t kLasFields = 15;
constexpr std::size_t kFieldCount = kLasField + kLasFields;

struct VertexPlan {
  // Property index feeding each field, or kNone.
  static constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
  std::array<std::size_t, kFieldCount> prop{};
  bool has_color = false;
  bool has_intensity = false;
  // Colours wider than 8 bits follow the 16-bit rule (io/stream_support.h):
  // whether to shift depends on the levels of the whole file or a sample.
  bool wide_color = false;
  // Colours of float or double properties are fractions 0..1 (as MeshLab,
  // Blender and trimesh write and read them), each rounded to the nearest
  // of 256 levels; a value outside 0..1 is refused.
  bool unit_color = false;
  // The LasAttributeBits the LAS dimension properties fill.
  std::uint32_t las_bits = 0;
  // Every other scalar vertex property (normals, labels, curvature, alpha,
  // scalar fields ...) is kept as LAS extra bytes: its value's bytes, little
  // endian, at extra_at[property] within extra_size bytes per point, and
  // described by extra_bytes_vlr (one field per property, its PLY type).
  std::vector<std::size_t> extra_at;  // per property; kNone when not kept
  std::size_t extra_size = 0;
  std::string extra_bytes_vlr;
  std::vector<std::string> warnings;
};

// The properties kept as extra bytes (VertexPlan::extra_at): every scalar one
// that is not a coordinate, the colour set taken or the intensity. Lists are
// not kept (with a warning).
Status plan_extras(const Element& vertex, const std::string& name, VertexPlan& plan) {
  std::vector<KeptField> fields;
  for (std::size_t j = 0; j < vertex.properties.size(); ++j) {
    const Property& prop = vertex.properties[j];
    if (std::find(plan.prop.begin(), plan.prop.end(), j) != plan.prop.end()) continue;
    if (prop.is_list) {
      plan.warnings.push_back(name + ": vertex property " + quoted(prop.name) +
                              " is a list; lists are not kept (every scalar property is)");
      continue;
    }
    plan.extra_at[j] = plan.extra_size;
    plan.extra_size += ply::scalar_size(prop.type);
    fields.push_back({prop.name, ply::extra_bytes_type(prop.type)});
  }
  if (fields.empty()) return Status::ok();
  RELIEF_ASSIGN_OR_RETURN(plan.extra_bytes_vlr,
                          kept_fields_vlr(fields, name, "vertex property", "PLY vertex property", plan.warnings));
  return Status::ok();
}

Result<VertexPlan> make_plan(const Element& vertex, const std::string& name, bool keep_extras) {
  VertexPlan plan;
  plan.prop.fill(VertexPlan::kNone);
  // A scalar (non-list) property called `prop_name`, if any.
  auto scalar = [&](std::string_view prop_name) -> std::optional<std::size_t> {
    const auto i = vertex.find_any_case(prop_name);
    if (!i || vertex.properties[*i].is_list) return std::nullopt;
    return i;
  };
  for (const char* axis : {"x", "y", "z"}) {
    const auto i = vertex.find_any_case(axis);
    if (!i) return format_error(name + ": the vertex element has no '" + axis + "' property");
    if (vertex.properties[*i].is_list) {
      return format_error(name + ": vertex property '" + axis + "' is a list, not a number");
    }
  }
  plan.prop[kX] = *vertex.find_any_case("x");
  plan.prop[kY] = *vertex.find_any_case("y");
  plan.prop[kZ] = *vertex.find_any_case("z");

  // Colour names used by common writers, most common first; a partial set is ignored.
  static constexpr std::array<std::array<const char*, 3>, 3> kColorNames = {{
      {"red", "green", "blue"},
      {"diffuse_red", "diffuse_green", "diffuse_blue"},
      {"r", "g", "b"},
  }};
  for (const auto& names : kColorNames) {
    const auto r = scalar(names[0]);
    const auto g = scalar(names[1]);
    const auto b = scalar(names[2]);
    if (r && g && b) {
      plan.prop[kRed] = *r;
      plan.prop[kGreen] = *g;
      plan.prop[kBlue] = *b;
      plan.has_color = true;
      const auto is_float = [&](std::size_t i) {
        const ScalarType t = vertex.properties[i].type;
        return t == ScalarType::kFloat32 || t == ScalarType::kFloat64;
      };
      plan.unit_color = is_float(*r) && is_float(*g) && is_float(*b);
      for (std::size_t i : {*r, *g, *b}) {
        const ScalarType t = vertex.properties[i].type;
        if (t != ScalarType::kUint8 && t != ScalarType::kInt8 && !plan.unit_color) plan.wide_color = true;
      }
      break;
    }
  }
  for (const char* intensity_name : {"intensity", "scalar_intensity"}) {
    if (const auto i = scalar(intensity_name)) {
      plan.prop[kIntensity] = *i;
      plan.has_intensity = true;
      // Intensities are 32-bit floats (exact for every LAS intensity and
      // every float): say so when the property's type can hold more.
      const ScalarType t = vertex.properties[*i].type;
      if (t == ScalarType::kFloat64 || t == ScalarType::kInt32 || t == ScalarType::kUint32) {
        plan.warnings.push_back(name + ": vertex property " + quoted(vertex.properties[*i].name) + " is " +
                                ply::scalar_name(t) +
                                "; intensities are kept as 32-bit floats (about 7 significant digits, "
                                "integers exact up to 2^24)");
      }
      break;
    }
  }
  // The LAS dimensions under their LAS or PDAL names (io/text_columns.h),
  // the first property of each; "class" alone is too common a label name
  // for other meanings to be taken as one.
  const std::span<const LasTextColumn> las = las_text_columns();
  static_assert(kLasFields == 15);
  for (std::size_t j = 0; j < vertex.properties.size(); ++j) {
    const Property& prop = vertex.properties[j];
    if (prop.is_list || std::find(plan.prop.begin(), plan.prop.end(), j) != plan.prop.end()) continue;
    const std::optional<TextColumn> column = text_column_of_name(prop.name);
    std::string lower = text_display_name(prop.name);
    for (char& c : lower) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (!column || lower == "class") continue;
    for (std::size_t k = 0; k < las.size(); ++k) {
      if (las[k].column == *column && plan.prop[kLasField + k] == VertexPlan::kNone) {
        plan.prop[kLasField + k] = j;
        plan.las_bits |= las[k].bit;
      }
    }
  }
  plan.extra_at.assign(vertex.properties.size(), VertexPlan::kNone);
  if (keep_extras) RELIEF_RETURN_IF_ERROR(plan_extras(vertex, name, plan));
  return plan;
}

// ---------------------------------------------------------------- values

template <typename T>
T load(const std::uint8_t* p, bool swap) {
  std::array<std::uint8_t, sizeof(T)> b;
  std::memcpy(b.data(), p, sizeof(T));
  if (swap) std::reverse(b.begin(), b.end());
  T v;
  std::memcpy(&v, b.data(), sizeof(T));
  return v;
}

// Every PLY scalar type fits a double exactly.
double load_scalar(const std::uint8_t* p, ScalarType t, bool swap) {
  switch (t) {
    case ScalarType::kInt8:
      return load<std::int8_t>(p, swap);
    case ScalarType::kUint8:
      return load<std::uint8_t>(p, swap);
    case ScalarType::kInt16:
      return load<std::int16_t>(p, swap);
    case ScalarType::kUint16:
      return load<std::uint16_t>(p, swap);
    case ScalarType::kInt32:
      return load<std::int32_t>(p, swap);
    case ScalarType::kUint32:
      return load<std::uint32_t>(p, swap);
    case ScalarType::kFloat32:
      return load<float>(p, swap);
    case ScalarType::kFloat64:
      return load<double>(p, swap);
  }
  return 0;
}

// Colour levels are integers; out-of-range or NaN values saturate (NaN -> 0).
std::uint16_t to_level16(double v) {
  if (!(v > 0)) return 0;
  if (v >= 65535.0) return 65535;
  return static_cast<std::uint16_t>(v);
}

std::uint8_t to_level8(double v) {
  if (!(v > 0)) return 0;
  if (v >= 255.0) return 255;
  return static_cast<std::uint8_t>(v);
}

// A colour fraction 0..1 (VertexPlan::unit_color) as the nearest level.
std::uint8_t unit_level8(double v) { return to_level8(v * 255.0 + 0.5); }

// Converting an out-of-range double to float is undefined; map it to the
// infinity it would round to, which the finiteness check then reports.
float to_float(double v) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (v > kMax) return std::numeric_limits<float>::infinity();
  if (v < -kMax) return -std::numeric_limits<float>::infinity();
  return static_cast<float>(v);
}

// Parses an ascii token as a value of PLY type `t`.
bool parse_ascii(std::string_view tok, ScalarType t, double& out) {
  const char* first = tok.data();
  const char* const last = tok.data() + tok.size();
  // from_chars rejects a leading '+', which some printf-based writers emit.
  if (first != last && *first == '+' && last - first > 1 && first[1] != '-') ++first;
  if (ply::is_integer(t)) {
    std::int64_t v = 0;
    const auto [p, ec] = std::from_chars(first, last, v);
    if (ec != std::errc{} || p != last) return false;
    std::int64_t lo = 0;
    std::int64_t hi = 0;
    switch (t) {
      case ScalarType::kInt8:
        lo = INT8_MIN, hi = INT8_MAX;
        break;
      case ScalarType::kUint8:
        lo = 0, hi = UINT8_MAX;
        break;
      case ScalarType::kInt16:
        lo = INT16_MIN, hi = INT16_MAX;
        break;
      case ScalarType::kUint16:
        lo = 0, hi = UINT16_MAX;
        break;
      case ScalarType::kInt32:
        lo = INT32_MIN, hi = INT32_MAX;
        break;
      default:
        lo = 0, hi = UINT32_MAX;
        break;
    }
    if (v < lo || v > hi) return false;
    out = static_cast<double>(v);
    return true;
  }
  if (t == ScalarType::kFloat32) {
    // Parse as float so that shortest float output round-trips exactly.
    float f = 0;
    const auto [p, ec] = std::from_chars(first, last, f);
    if (ec != std::errc{} || p != last) return false;
    out = f;
    return true;
  }
  const auto [p, ec] = std::from_chars(first, last, out);
  return ec == std::errc{} && p == last;
}

// ---------------------------------------------------------------- errors

// "x.ply: vertex 12"; built only when an error is reported.
std::string record_label(const std::string& name, std::string_view element, std::uint64_t index) {
  return name + ": " + std::string(element) + " " + std::to_string(index);
}

std::string vertex_label(const std::string& name, std::uint64_t index) {
  return record_label(name, "vertex", index);
}

Status non_finite_vertex(const std::string& name, std::uint64_t index, const Vec3d& p) {
  return format_error(vertex_label(name, index) + " has a non-finite coordinate (" + format_double(p.x) +
                      ", " + format_double(p.y) + ", " + format_double(p.z) + ")");
}

Status non_finite_intensity(const std::string& name, std::uint64_t index, float v) {
  return format_error(vertex_label(name, index) + " has a non-finite intensity (" + format_double(v) + ")");
}

bool is_unit(double v) { return v >= 0 && v <= 1; }  // false for NaN

Status colour_not_unit(const std::string& name, std::uint64_t index, double v) {
  return format_error(vertex_label(name, index) + " has the colour value " + format_double(v) +
                      ": colours stored as float or double are read as fractions from 0 to 1, as MeshLab and "
                      "Blender write them; store levels 0..255 as uchar (or 0..65535 as ushort) instead");
}

// Checks n decoded points; `first` is the file index of p[0], for messages.
// One branch-free pass in the common all-finite case; the offending index is
// searched only on failure.
Status check_finite(const Vec3d* p, const float* intensity, std::size_t n, std::uint64_t first,
                    const std::string& name) {
  double acc = 0;  // x - x is NaN exactly when x is NaN or infinite
  for (std::size_t i = 0; i < n; ++i) acc += (p[i].x - p[i].x) + (p[i].y - p[i].y) + (p[i].z - p[i].z);
  if (acc != 0) {
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(p[i].x) || !std::isfinite(p[i].y) || !std::isfinite(p[i].z)) {
        return non_finite_vertex(name, first + i, p[i]);
      }
    }
  }
  if (intensity != nullptr) {
    float facc = 0;
    for (std::size_t i = 0; i < n; ++i) facc += intensity[i] - intensity[i];
    if (facc != 0) {
      for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(intensity[i])) return non_finite_intensity(name, first + i, intensity[i]);
      }
    }
  }
  return Status::ok();
}

Status truncated(const std::string& name, const Element& el, std::uint64_t got) {
  const std::string what = el.name == "vertex" ? std::string(" vertices") : " '" + el.name + "' elements";
  return format_error(name + ": truncated: header declares " + std::to_string(el.count) + what +
                      " but the data ends after " + std::to_string(got));
}

// ---------------------------------------------------------------- binary

// Byte layout of a fixed-size vertex record, resolved once per file.
struct Layout {
  std::size_t stride = 0;
  std::array<std::size_t, kFieldCount> offset{};
  std::array<ScalarType, kFieldCount> type{};
  bool swap = false;
  bool has_color = false;
  bool wide_color = false;
  bool unit_color = false;  // VertexPlan::unit_color
  bool has_intensity = false;
  int color_shift = 0;  // for wide colours narrowed while decoding
  // The properties kept as extra bytes (VertexPlan::extra_at), in order:
  // offset in the record and size.
  struct Extra {
    std::size_t src = 0;
    std::size_t size = 0;
  };
  std::vector<Extra> extras;
  std::size_t extra_size = 0;
  bool big_endian = false;  // kept values are reversed into little endian
};

// Copies the kept properties of n fixed-size records to `dst`, extra_size
// bytes per point, each value little endian.
void copy_extras(const std::uint8_t* src, std::size_t n, const Layout& lay, std::uint8_t* dst) {
  for (std::size_t i = 0; i < n; ++i, src += lay.stride) {
    for (const Layout::Extra& e : lay.extras) {
      std::memcpy(dst, src + e.src, e.size);
      if (lay.big_endian) std::reverse(dst, dst + e.size);
      dst += e.size;
    }
  }
}

// Decodes n records. Colours go to `col`, or as 16-bit levels to `wide` when
// that is given (then `col` is null); `intensity` is null without intensity.
using BatchDecoder = void (*)(const std::uint8_t* src, std::size_t n, const Layout& lay, Vec3d* pos,
                              Rgb8* col, std::uint16_t* wide, float* intensity);

// The fast kernel: host byte order, coordinates all of type C, uchar colour,
// float intensity.
template <typename C, bool kWithColor, bool kWithIntensity>
void decode_fast(const std::uint8_t* src, std::size_t n, const Layout& lay, Vec3d* pos, Rgb8* col,
                 std::uint16_t* /*wide*/, float* intensity) {
  const std::size_t stride = lay.stride;
  const std::size_t ox = lay.offset[kX], oy = lay.offset[kY], oz = lay.offset[kZ];
  const std::size_t o_r = lay.offset[kRed], o_g = lay.offset[kGreen], o_b = lay.offset[kBlue];
  const std::size_t oi = lay.offset[kIntensity];
  for (std::size_t i = 0; i < n; ++i, src += stride) {
    C x, y, z;
    std::memcpy(&x, src + ox, sizeof(C));
    std::memcpy(&y, src + oy, sizeof(C));
    std::memcpy(&z, src + oz, sizeof(C));
    pos[i] = Vec3d{static_cast<double>(x), static_cast<double>(y), static_cast<double>(z)};
    if constexpr (kWithColor) col[i] = Rgb8{src[o_r], src[o_g], src[o_b]};
    if constexpr (kWithIntensity) std::memcpy(&intensity[i], src + oi, sizeof(float));
  }
}

// Any scalar types, either byte order.
void decode_generic(const std::uint8_t* src, std::size_t n, const Layout& lay, Vec3d* pos, Rgb8* col,
                    std::uint16_t* wide, float* intensity) {
  auto get = [&](const std::uint8_t* rec, Field f) {
    return load_scalar(rec + lay.offset[f], lay.type[f], lay.swap);
  };
  for (std::size_t i = 0; i < n; ++i, src += lay.stride) {
    pos[i] = Vec3d{get(src, kX), get(src, kY), get(src, kZ)};
    if (lay.has_color) {
      const double r = get(src, kRed), g = get(src, kGreen), b = get(src, kBlue);
      if (wide != nullptr) {
        wide[3 * i] = to_level16(r);
        wide[3 * i + 1] = to_level16(g);
        wide[3 * i + 2] = to_level16(b);
      } else if (lay.wide_color) {
        col[i] =
            Rgb8{narrow_level(to_level16(r), lay.color_shift), narrow_level(to_level16(g), lay.color_shift),
                 narrow_level(to_level16(b), lay.color_shift)};
      } else if (lay.unit_color) {
        col[i] = Rgb8{unit_level8(r), unit_level8(g), unit_level8(b)};
      } else {
        col[i] = Rgb8{to_level8(r), to_level8(g), to_level8(b)};
      }
    }
    if (lay.has_intensity) intensity[i] = to_float(get(src, kIntensity));
  }
}

BatchDecoder pick_decoder(const Layout& lay, const VertexPlan& plan) {
  const ScalarType ct = lay.type[kX];
  const bool same_coord =
      lay.type[kY] == ct && lay.type[kZ] == ct && (ct == ScalarType::kFloat32 || ct == ScalarType::kFloat64);
  const bool plain_color =
      !plan.has_color || (lay.type[kRed] == ScalarType::kUint8 && lay.type[kGreen] == ScalarType::kUint8 &&
                          lay.type[kBlue] == ScalarType::kUint8);
  const bool plain_intensity = !plan.has_intensity || lay.type[kIntensity] == ScalarType::kFloat32;
  if (lay.swap || !same_coord || !plain_color || !plain_intensity) return decode_generic;
  const bool dbl = ct == ScalarType::kFloat64;
  const bool c = plan.has_color;
  const bool in = plan.has_intensity;
  if (dbl) {
    if (c) return in ? decode_fast<double, true, true> : decode_fast<double, true, false>;
    return in ? decode_fast<double, false, true> : decode_fast<double, false, false>;
  }
  if (c) return in ? decode_fast<float, true, true> : decode_fast<float, true, false>;
  return in ? decode_fast<float, false, true> : decode_fast<float, false, false>;
}

Layout make_layout(const Element& el, const VertexPlan& plan, bool swap, bool big_endian) {
  Layout lay;
  lay.swap = swap;
  lay.big_endian = big_endian;
  lay.has_color = plan.has_color;
  lay.wide_color = plan.wide_color;
  lay.unit_color = plan.unit_color;
  lay.has_intensity = plan.has_intensity;
  std::vector<std::size_t> prop_offset(el.properties.size());
  for (std::size_t i = 0; i < el.properties.size(); ++i) {
    prop_offset[i] = lay.stride;
    lay.stride += ply::scalar_size(el.properties[i].type);
  }
  for (std::size_t f = 0; f < kFieldCount; ++f) {
    if (plan.prop[f] == VertexPlan::kNone) continue;
    lay.offset[f] = prop_offset[plan.prop[f]];
    lay.type[f] = el.properties[plan.prop[f]].type;
  }
  for (std::size_t j = 0; j < el.properties.size(); ++j) {
    if (plan.extra_at[j] == VertexPlan::kNone) continue;
    lay.extras.push_back({prop_offset[j], ply::scalar_size(el.properties[j].type)});
  }
  lay.extra_size = plan.extra_size;
  return lay;
}

// Where one record's kept properties go (VertexPlan::extra_at): `dst` holds
// extra_size bytes; null when the record is only skipped.
struct ExtraSink {
  const std::vector<std::size_t>* at = nullptr;
  std::uint8_t* dst = nullptr;
  bool big_endian = false;

  bool keeps(std::size_t prop) const { return dst != nullptr && (*at)[prop] != VertexPlan::kNone; }
  // Stores a value given in the file's byte order, little endian.
  void put(std::size_t prop, const std::uint8_t* value, std::size_t size) const {
    std::uint8_t* d = dst + (*at)[prop];
    std::memcpy(d, value, size);
    if (big_endian) std::reverse(d, d + size);
  }
};

// Reads one binary record property by property; used when the element has
// list properties. `values` receives the fields named in `field_of` (may be
// empty when the record is only skipped), `extras` the kept properties.
// `complete` is false if the input ended.
Status read_binary_record(ByteSource& src, const Element& el, bool swap, const std::vector<int>& field_of,
                          const ExtraSink& extras, std::array<double, kFieldCount>& values, bool& complete,
                          const std::string& name, std::uint64_t index) {
  complete = false;
  for (std::size_t j = 0; j < el.properties.size(); ++j) {
    const Property& prop = el.properties[j];
    std::span<const std::uint8_t> view;
    if (prop.is_list) {
      const std::size_t cs = ply::scalar_size(prop.count_type);
      RELIEF_RETURN_IF_ERROR(src.fill(cs, view));
      if (view.size() < cs) return Status::ok();
      const double count = load_scalar(view.data(), prop.count_type, swap);
      src.consume(cs);
      if (count < 0) {
        return format_error(record_label(name, el.name, index) + ": list " + quoted(prop.name) +
                            " has a negative length (" + std::to_string(static_cast<std::int64_t>(count)) +
                            ")");
      }
      // count <= 2^32 and items <= 8 bytes: no overflow.
      const auto bytes = static_cast<std::uint64_t>(count) * ply::scalar_size(prop.type);
      std::uint64_t skipped = 0;
      RELIEF_RETURN_IF_ERROR(src.skip(bytes, skipped));
      if (skipped < bytes) return Status::ok();
    } else {
      const std::size_t sz = ply::scalar_size(prop.type);
      RELIEF_RETURN_IF_ERROR(src.fill(sz, view));
      if (view.size() < sz) return Status::ok();
      if (!field_of.empty() && field_of[j] >= 0) {
        values[static_cast<std::size_t>(field_of[j])] = load_scalar(view.data(), prop.type, swap);
      }
      if (extras.keeps(j)) extras.put(j, view.data(), sz);
      src.consume(sz);
    }
  }
  complete = true;
  return Status::ok();
}

std::vector<int> fields_of_properties(const Element& el, const VertexPlan& plan) {
  std::vector<int> field_of(el.properties.size(), -1);
  for (std::size_t f = 0; f < kFieldCount; ++f) {
    if (plan.prop[f] != VertexPlan::kNone) field_of[plan.prop[f]] = static_cast<int>(f);
  }
  return field_of;
}

Status skip_binary_element(ByteSource& src, const Element& el, bool swap, const std::string& name) {
  if (el.fixed_size()) {
    const std::uint64_t size = el.min_record_size();
    if (size == 0) return Status::ok();
    std::uint64_t skipped = 0;
    RELIEF_RETURN_IF_ERROR(src.skip(el.count * size, skipped));  // < 2^56, see ply_format.h
    if (skipped < el.count * size) return truncated(name, el, skipped / size);
    return Status::ok();
  }
  std::array<double, kFieldCount> unused{};
  for (std::uint64_t i = 0; i < el.count; ++i) {
    bool complete = false;
    RELIEF_RETURN_IF_ERROR(read_binary_record(src, el, swap, {}, ExtraSink{}, unused, complete, name, i));
    if (!complete) return truncated(name, el, i);
  }
  return Status::ok();
}

// ---------------------------------------------------------------- ascii

// Next non-blank line; `found` is false at the end of the input.
Status next_record_line(ByteSource& src, std::string_view& line, bool& found, const std::string& name,
                        const Element& el, std::uint64_t index) {
  for (;;) {
    LineStatus state = LineStatus::kEnd;
    RELIEF_RETURN_IF_ERROR(next_line(src, kMaxAsciiLine, line, state));
    if (state == LineStatus::kEnd) {
      found = false;
      return Status::ok();
    }
    if (state == LineStatus::kTooLong) {
      return format_error(record_label(name, el.name, index) + ": line longer than " +
                          std::to_string(kMaxAsciiLine) + " bytes");
    }
    std::size_t pos = 0;
    if (!next_token(line, pos).empty()) {
      found = true;
      return Status::ok();
    }
  }
}

// The little-endian bytes of `v`, a value of PLY type `t` that parse_ascii
// read (so it is in range and, for float, exactly a float).
void put_ascii_value(double v, ScalarType t, std::uint8_t* dst) {
  auto put = [&](auto x) {
    std::array<std::uint8_t, sizeof(x)> b;
    std::memcpy(b.data(), &x, sizeof(x));
    if constexpr (std::endian::native == std::endian::big) std::reverse(b.begin(), b.end());
    std::memcpy(dst, b.data(), b.size());
  };
  switch (t) {
    case ScalarType::kInt8: return put(static_cast<std::int8_t>(v));
    case ScalarType::kUint8: return put(static_cast<std::uint8_t>(v));
    case ScalarType::kInt16: return put(static_cast<std::int16_t>(v));
    case ScalarType::kUint16: return put(static_cast<std::uint16_t>(v));
    case ScalarType::kInt32: return put(static_cast<std::int32_t>(v));
    case ScalarType::kUint32: return put(static_cast<std::uint32_t>(v));
    case ScalarType::kFloat32: return put(static_cast<float>(v));
    case ScalarType::kFloat64: return put(v);
  }
}

// Parses one ascii vertex line into `values` and `extra` (the kept
// properties, at VertexPlan::extra_at; null when there are none).
Status parse_ascii_vertex(std::string_view line, const Element& el, const std::vector<int>& field_of,
                          const std::vector<std::size_t>& extra_at, std::uint8_t* extra,
                          std::array<double, kFieldCount>& values, const std::string& name,
                          std::uint64_t index) {
  std::size_t pos = 0;
  for (std::size_t j = 0; j < el.properties.size(); ++j) {
    const Property& prop = el.properties[j];
    const std::string_view tok = next_token(line, pos);
    if (tok.empty()) {
      return format_error(vertex_label(name, index) + ": the line ends before property " + quoted(prop.name));
    }
    if (prop.is_list) {
      double count = 0;
      if (!parse_ascii(tok, prop.count_type, count) || count < 0) {
        return format_error(vertex_label(name, index) + ": " + quoted(tok) +
                            " is not a valid length for list " + quoted(prop.name));
      }
      for (std::uint64_t k = 0; k < static_cast<std::uint64_t>(count); ++k) {
        if (next_token(line, pos).empty()) {
          return format_error(vertex_label(name, index) + ": the line ends inside list " + quoted(prop.name));
        }
      }
      continue;
    }
    const bool kept = extra != nullptr && extra_at[j] != VertexPlan::kNone;
    if (field_of[j] < 0 && !kept) continue;
    double v = 0;
    if (!parse_ascii(tok, prop.type, v)) {
      return format_error(vertex_label(name, index) + ": " + quoted(tok) + " is not a valid " +
                          ply::scalar_name(prop.type) + " for property " + quoted(prop.name));
    }
    if (field_of[j] >= 0) values[static_cast<std::size_t>(field_of[j])] = v;
    if (kept) put_ascii_value(v, prop.type, extra + extra_at[j]);
  }
  if (!next_token(line, pos).empty()) {
    return format_error(vertex_label(name, index) + ": more values than the header declares");
  }
  return Status::ok();
}

Status skip_ascii_element(ByteSource& src, const Element& el, const std::string& name) {
  for (std::uint64_t i = 0; i < el.count; ++i) {
    std::string_view line;
    bool found = false;
    RELIEF_RETURN_IF_ERROR(next_record_line(src, line, found, name, el, i));
    if (!found) return truncated(name, el, i);
  }
  return Status::ok();
}

// ---------------------------------------------------------------- reader

class PlyPointReader final : public BatchPointReader {
 public:
  // `check_trailing`: after the last vertex, also walk the elements that
  // follow and report them if they are cut short (the whole-file readers do;
  // a stream stops at the last vertex).
  // `keep_extras`: deliver the other scalar vertex properties as extra bytes
  // (ReaderOptions::extra_bytes).
  static Result<std::unique_ptr<PlyPointReader>> open(const InputSpec& input, bool check_trailing,
                                                      bool keep_extras) {
    RELIEF_ASSIGN_OR_RETURN(ByteSource src, input.open());
    std::unique_ptr<PlyPointReader> reader(
        new PlyPointReader(input, std::move(src), check_trailing, keep_extras));
    RELIEF_RETURN_IF_ERROR(reader->start());
    return reader;
  }

  Result<std::size_t> read_into(PointCloud& out, std::vector<std::uint16_t>* wide, std::size_t at,
                                std::size_t max_points) override;

  bool wide_colors() const { return wide_colors_; }

  // How many vertices to reserve for a whole-file read: the declared count
  // bounded by what the remaining bytes can hold.
  std::uint64_t reserve_hint() {
    const Element& el = header_.elements[vertex_el_];
    const std::uint64_t left = el.count - done_;
    const auto rem = src_.remaining();
    if (!rem) return std::min(left, kBlindReserve);
    if (header_.encoding == PlyEncoding::kAscii) {
      // A record needs at least one character and one separator per property.
      return std::min(left, *rem / (2 * el.properties.size()) + 1);
    }
    return std::min(left, *rem / el.min_record_size());
  }

 protected:
  Result<std::unique_ptr<BatchPointReader>> reopen() const override {
    // A pipe cannot be read twice; a regular file or memory can.
    if (!input_.memory && !src_.size()) return std::unique_ptr<BatchPointReader>();
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PlyPointReader> again, open(input_, false, keep_extras_));
    return std::unique_ptr<BatchPointReader>(std::move(again));
  }

 private:
  PlyPointReader(InputSpec input, ByteSource src, bool check_trailing, bool keep_extras)
      : input_(std::move(input)), src_(std::move(src)), check_trailing_(check_trailing), keep_extras_(keep_extras) {}

  Status start();
  Result<std::size_t> read_fixed(PointCloud& out, std::vector<std::uint16_t>* wide, std::size_t at,
                                 std::size_t want);
  Result<std::size_t> read_records(PointCloud& out, std::vector<std::uint16_t>* wide, std::size_t at,
                                   std::size_t want);
  Status push_vertex(const std::array<double, kFieldCount>& v, std::uint64_t index, PointCloud& out,
                     std::vector<std::uint16_t>* wide) const;
  // Appends a vertex's LAS dimensions (fields kLasField on of `v`), or an
  // error naming the vertex and property when a value does not fit its
  // dimension.
  Status push_las(const std::array<double, kFieldCount>& v, std::uint64_t index, PointCloud& out) const;
  // Appends the LAS dimensions of n fixed-size records (vertex `first` on).
  Status decode_las(const std::uint8_t* src, std::size_t n, std::uint64_t first, PointCloud& out) const;
  // Float colours (VertexPlan::unit_color) of n fixed-size records: each from 0 to 1.
  Status check_unit_colors(const std::uint8_t* src, std::size_t n, std::uint64_t first) const;
  // Sizes out.las.extra_bytes for n points (nothing when no property is kept).
  void size_extras(PointCloud& out, std::size_t n) const;
  Status finish_trailing();
  // When the vertex element is the file's last: records after the declared
  // count become a warning in info().warnings (the header count is kept).
  Status note_extra_vertices();
  Status note_leftover();

  const std::string& name() const { return input_.name; }
  const Element& vertex() const { return header_.elements[vertex_el_]; }

  InputSpec input_;
  ByteSource src_;
  bool check_trailing_;
  bool keep_extras_;
  bool trailing_checked_ = false;
  ply::Header header_;
  std::size_t vertex_el_ = 0;
  VertexPlan plan_;
  bool swap_ = false;
  bool fixed_binary_ = false;
  Layout layout_;
  BatchDecoder decode_ = nullptr;
  std::vector<int> field_of_;
  // The remaining bytes are known to hold every vertex, so batches may be
  // sized before they are read.
  bool backed_ = false;
  std::uint64_t done_ = 0;  // vertices delivered so far
  std::vector<std::uint16_t> levels_;  // wide colours' levels of a batch (read_into)
};

Status PlyPointReader::start() {
  RELIEF_ASSIGN_OR_RETURN(header_, parse_header(src_, name()));
  const auto it = std::find_if(header_.elements.begin(), header_.elements.end(),
                               [](const Element& e) { return e.name == "vertex"; });
  if (it == header_.elements.end()) {
    return format_error(name() + ": the header declares no vertex element");
  }
  vertex_el_ = static_cast<std::size_t>(it - header_.elements.begin());
  RELIEF_ASSIGN_OR_RETURN(plan_, make_plan(vertex(), name(), keep_extras_));
  const bool binary = header_.encoding != PlyEncoding::kAscii;
  const bool file_little = header_.encoding == PlyEncoding::kBinaryLittleEndian;
  swap_ = binary && file_little != (std::endian::native == std::endian::little);
  field_of_ = fields_of_properties(vertex(), plan_);

  for (std::size_t e = 0; e < vertex_el_; ++e) {
    const Element& el = header_.elements[e];
    RELIEF_RETURN_IF_ERROR(binary ? skip_binary_element(src_, el, swap_, name())
                                  : skip_ascii_element(src_, el, name()));
  }

  fixed_binary_ = binary && vertex().fixed_size();
  if (fixed_binary_) {
    layout_ = make_layout(vertex(), plan_, swap_, header_.encoding == PlyEncoding::kBinaryBigEndian);
    decode_ = pick_decoder(layout_, plan_);
    // Check the declared count against the bytes actually there before any
    // allocation is sized by it.
    if (const auto rem = src_.remaining()) {
      const std::uint64_t holds = *rem / layout_.stride;  // stride >= 3: x, y, z
      if (vertex().count > holds) return truncated(name(), vertex(), holds);
      backed_ = true;
    }
  }

  info_.path = name();
  info_.format = "ply";
  info_.text_body = header_.encoding == PlyEncoding::kAscii;
  info_.point_count = vertex().count;
  info_.has_colors = plan_.has_color;
  info_.has_intensity = plan_.has_intensity;
  info_.las_attributes = plan_.las_bits;
  if (plan_.extra_size > 0) {
    info_.las_attributes |= kLasExtraBytes;
    info_.extra_bytes_vlr = plan_.extra_bytes_vlr;
    info_.extra_bytes_size = static_cast<std::uint32_t>(plan_.extra_size);
  }
  info_.warnings = plan_.warnings;
  wide_colors_ = plan_.wide_color;
  // Colour properties wider than 8 bits (ushort, as PDAL writes them) keep
  // each level's low byte beside the narrowed level, as LAS colours do
  // (LasAttributes::color_low): the 16-bit levels come back exactly.
  if (plan_.has_color && plan_.wide_color) {
    color_low_ = true;
    info_.las_attributes |= kLasColorLow;
  }
  return Status::ok();
}

void PlyPointReader::size_extras(PointCloud& out, std::size_t n) const {
  if (plan_.extra_size == 0) return;
  out.las.extra_bytes_size = static_cast<std::uint32_t>(plan_.extra_size);
  out.las.extra_bytes.resize(n * plan_.extra_size);
}

Result<std::size_t> PlyPointReader::read_into(PointCloud& out, std::vector<std::uint16_t>* wide,
                                              std::size_t at, std::size_t max_points) {
  const std::uint64_t left = vertex().count - done_;
  const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(max_points, left));
  // Wide colours once the shift is known: the levels are decoded, then
  // narrowed here with their low bytes kept (BatchPointReader::read does
  // the same for the batch that decides the shift).
  const bool keep_low = color_low_ && wide == nullptr;
  // The points before `at` keep their colours (reading levels empties them).
  std::vector<Rgb8> colors_before, low_before;
  if (keep_low && at > 0) {
    colors_before = out.colors;
    low_before = out.las.color_low;
    colors_before.resize(at);
    low_before.resize(at);
  }
  std::vector<std::uint16_t>* levels = keep_low ? &levels_ : wide;
  if (keep_low) levels_.clear();
  std::size_t got = 0;
  if (fixed_binary_) {
    RELIEF_ASSIGN_OR_RETURN(got, read_fixed(out, levels, at, want));
  } else {
    RELIEF_ASSIGN_OR_RETURN(got, read_records(out, levels, at, want));
  }
  if (keep_low) {
    if (at > 0) {
      out.colors = std::move(colors_before);
      out.las.color_low = std::move(low_before);
    }
    out.colors.resize(at + got);
    out.las.color_low.resize(at + got);
    narrow_colors(levels_.data() + 3 * at, got, color_shift_, out.colors.data() + at, out.las.color_low.data() + at);
    note_levels_above_255(levels_.data() + 3 * at, got, done_);
  }
  done_ += got;
  if (done_ == vertex().count && !trailing_checked_) {
    trailing_checked_ = true;
    if (check_trailing_) {
      RELIEF_RETURN_IF_ERROR(finish_trailing());
    } else if (vertex_el_ + 1 == header_.elements.size()) {
      RELIEF_RETURN_IF_ERROR(note_extra_vertices());
    } else {
      // Elements follow the vertices (faces): walked, so that a vertex count
      // below the records present does not pass for faces silently (the
      // extra vertices then make faces cut short, or bytes left over). The
      // vertices read stand (a stream needs no faces): a warning.
      if (Status s = finish_trailing(); !s) {
        if (s.code() != StatusCode::kFormatError) return s;  // cannot read
        info_.warnings.push_back(
            s.message() + " (after the " + std::to_string(vertex().count) +
            " vertices the header declares: is that count right?); the vertices were read");
      } else {
        RELIEF_RETURN_IF_ERROR(note_leftover());
      }
    }
  }
  return got;
}

Status PlyPointReader::note_extra_vertices() {
  // Only a file of known size can be looked at past the last vertex without
  // waiting on a pipe; the bytes present bound the work.
  const auto rem = src_.remaining();
  if (!rem || *rem == 0) return Status::ok();
  std::uint64_t extra = 0;
  if (fixed_binary_) {
    extra = *rem / layout_.stride;
  } else if (header_.encoding == PlyEncoding::kAscii) {
    RELIEF_ASSIGN_OR_RETURN(const ByteSource::Rest rest, src_.read_rest());
    extra = rest.lines;  // non-blank lines after the last declared vertex
  } else {
    info_.warnings.push_back(name() + ": " + std::to_string(*rem) + " bytes follow the last of the " +
                             std::to_string(vertex().count) + " vertices the header declares; they were ignored");
    return Status::ok();
  }
  if (extra > 0) {
    info_.warnings.push_back(name() + ": the header declares " + std::to_string(vertex().count) + " vertices but " +
                             std::to_string(vertex().count + extra) + " follow; the last " + std::to_string(extra) +
                             " were ignored");
  }
  return Status::ok();
}

Status PlyPointReader::note_leftover() {
  RELIEF_ASSIGN_OR_RETURN(const ByteSource::Rest rest, src_.read_rest());
  const bool ascii = header_.encoding == PlyEncoding::kAscii;
  if (ascii ? rest.lines == 0 : rest.bytes == 0) return Status::ok();
  info_.warnings.push_back(name() + ": " + std::to_string(ascii ? rest.lines : rest.bytes) +
                           (ascii ? " lines" : " bytes") + " follow the last element the header declares (" +
                           header_.elements.back().name + "); they were ignored (is its count of " +
                           std::to_string(vertex().count) + " vertices right?)");
  return Status::ok();
}

Result<std::size_t> PlyPointReader::read_fixed(PointCloud& out, std::vector<std::uint16_t>* wide,
                                               std::size_t at, std::size_t want) {
  const bool to_wide = wide != nullptr && plan_.wide_color;
  const bool col8 = plan_.has_color && !to_wide;
  auto size_to = [&](std::size_t n) {
    size_batch(out, n, col8, plan_.has_intensity);
    size_extras(out, n);
    if (to_wide) wide->resize(3 * n);
  };
  // Sized once when the data is known to be there, so that a batch reused at
  // the same size is never touched twice; otherwise grown as data arrives.
  if (backed_) size_to(at + want);
  size_las_columns(out.las, plan_.las_bits, at);  // grown record by record
  layout_.color_shift = color_shift_;
  const std::size_t stride = layout_.stride;
  std::size_t got = 0;
  while (got < want) {
    std::span<const std::uint8_t> view;
    RELIEF_RETURN_IF_ERROR(src_.fill(stride, view));
    const std::size_t avail = view.size() / stride;
    if (avail == 0) return truncated(name(), vertex(), done_ + got);
    const std::size_t n = std::min(want - got, avail);
    const std::size_t i0 = at + got;
    if (!backed_) size_to(i0 + n);
    float* intensity = plan_.has_intensity ? out.intensities.data() + i0 : nullptr;
    decode_(view.data(), n, layout_, out.positions.data() + i0, col8 ? out.colors.data() + i0 : nullptr,
            to_wide ? wide->data() + 3 * i0 : nullptr, intensity);
    RELIEF_RETURN_IF_ERROR(check_finite(out.positions.data() + i0, intensity, n, done_ + got, name()));
    if (plan_.unit_color) RELIEF_RETURN_IF_ERROR(check_unit_colors(view.data(), n, done_ + got));
    if (layout_.extra_size > 0) {
      copy_extras(view.data(), n, layout_, out.las.extra_bytes.data() + i0 * layout_.extra_size);
    }
    if (plan_.las_bits != 0) RELIEF_RETURN_IF_ERROR(decode_las(view.data(), n, done_ + got, out));
    src_.consume(n * stride);
    got += n;
  }
  size_to(at + got);
  return got;
}

Status PlyPointReader::push_vertex(const std::array<double, kFieldCount>& v, std::uint64_t index,
                                   PointCloud& out, std::vector<std::uint16_t>* wide) const {
  const Vec3d p{v[kX], v[kY], v[kZ]};
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
    return non_finite_vertex(name(), index, p);
  }
  out.positions.push_back(p);
  if (plan_.has_color) {
    if (wide != nullptr && plan_.wide_color) {
      for (const Field f : {kRed, kGreen, kBlue}) wide->push_back(to_level16(v[f]));
    } else if (plan_.wide_color) {
      out.colors.push_back({narrow_level(to_level16(v[kRed]), color_shift_),
                            narrow_level(to_level16(v[kGreen]), color_shift_),
                            narrow_level(to_level16(v[kBlue]), color_shift_)});
    } else if (plan_.unit_color) {
      for (const Field f : {kRed, kGreen, kBlue}) {
        if (!is_unit(v[f])) return colour_not_unit(name(), index, v[f]);
      }
      out.colors.push_back({unit_level8(v[kRed]), unit_level8(v[kGreen]), unit_level8(v[kBlue])});
    } else {
      out.colors.push_back({to_level8(v[kRed]), to_level8(v[kGreen]), to_level8(v[kBlue])});
    }
  }
  if (plan_.has_intensity) {
    const float f = to_float(v[kIntensity]);
    if (!std::isfinite(f)) return non_finite_intensity(name(), index, f);
    out.intensities.push_back(f);
  }
  return plan_.las_bits != 0 ? push_las(v, index, out) : Status::ok();
}

Status PlyPointReader::push_las(const std::array<double, kFieldCount>& v, std::uint64_t index,
                                PointCloud& out) const {
  std::array<double, kTextColumnKinds> las{};
  for (std::size_t k = 0; k < kLasFields; ++k) {
    if (plan_.prop[kLasField + k] == VertexPlan::kNone) continue;
    const std::string error = las_column_error(las_text_columns()[k], v[kLasField + k]);
    if (!error.empty()) {
      return format_error(vertex_label(name(), index) + ": property " +
                          quoted(vertex().properties[plan_.prop[kLasField + k]].name) + ": " + error);
    }
    las[static_cast<std::size_t>(las_text_columns()[k].column)] = v[kLasField + k];
  }
  push_las_columns(las.data(), plan_.las_bits, out.las);
  return Status::ok();
}

Status PlyPointReader::check_unit_colors(const std::uint8_t* src, std::size_t n, std::uint64_t first) const {
  for (std::size_t i = 0; i < n; ++i, src += layout_.stride) {
    for (const Field f : {kRed, kGreen, kBlue}) {
      const double v = load_scalar(src + layout_.offset[f], layout_.type[f], layout_.swap);
      if (!is_unit(v)) return colour_not_unit(name(), first + i, v);
    }
  }
  return Status::ok();
}

Status PlyPointReader::decode_las(const std::uint8_t* src, std::size_t n, std::uint64_t first, PointCloud& out) const {
  std::array<double, kFieldCount> v{};
  for (std::size_t i = 0; i < n; ++i, src += layout_.stride) {
    for (std::size_t k = 0; k < kLasFields; ++k) {
      if (plan_.prop[kLasField + k] == VertexPlan::kNone) continue;
      v[kLasField + k] = load_scalar(src + layout_.offset[kLasField + k], layout_.type[kLasField + k], layout_.swap);
    }
    RELIEF_RETURN_IF_ERROR(push_las(v, first + i, out));
  }
  return Status::ok();
}

// Binary records with lists, and ascii lines: one record at a time.
Result<std::size_t> PlyPointReader::read_records(PointCloud& out, std::vector<std::uint16_t>* wide,
                                                 std::size_t at, std::size_t want) {
  const bool to_wide = wide != nullptr && plan_.wide_color;
  size_batch(out, at, plan_.has_color && !to_wide, plan_.has_intensity);
  size_extras(out, at);
  size_las_columns(out.las, plan_.las_bits, at);
  if (to_wide) wide->resize(3 * at);
  const bool ascii = header_.encoding == PlyEncoding::kAscii;
  const std::size_t extra_size = plan_.extra_size;
  for (std::size_t i = 0; i < want; ++i) {
    const std::uint64_t index = done_ + i;
    std::array<double, kFieldCount> values{};
    // This record's kept properties go straight into the batch.
    std::uint8_t* extra = nullptr;
    if (extra_size > 0) {
      size_extras(out, at + i + 1);
      extra = out.las.extra_bytes.data() + (at + i) * extra_size;
    }
    if (ascii) {
      std::string_view line;
      bool found = false;
      RELIEF_RETURN_IF_ERROR(next_record_line(src_, line, found, name(), vertex(), index));
      if (!found) return truncated(name(), vertex(), index);
      RELIEF_RETURN_IF_ERROR(
          parse_ascii_vertex(line, vertex(), field_of_, plan_.extra_at, extra, values, name(), index));
    } else {
      bool complete = false;
      const ExtraSink sink{&plan_.extra_at, extra, header_.encoding == PlyEncoding::kBinaryBigEndian};
      RELIEF_RETURN_IF_ERROR(
          read_binary_record(src_, vertex(), swap_, field_of_, sink, values, complete, name(), index));
      if (!complete) return truncated(name(), vertex(), index);
    }
    RELIEF_RETURN_IF_ERROR(push_vertex(values, index, out, wide));
  }
  return want;
}

Status PlyPointReader::finish_trailing() {
  const bool binary = header_.encoding != PlyEncoding::kAscii;
  for (std::size_t e = vertex_el_ + 1; e < header_.elements.size(); ++e) {
    const Element& el = header_.elements[e];
    RELIEF_RETURN_IF_ERROR(binary ? skip_binary_element(src_, el, swap_, name())
                                  : skip_ascii_element(src_, el, name()));
  }
  return Status::ok();
}

Result<PointCloud> read_ply_input(const InputSpec& input) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PlyPointReader> reader, PlyPointReader::open(input, true, true));
  const PointStreamInfo& info = reader->info();
  const bool wide_colors = reader->wide_colors();
  PointCloud cloud;
  std::vector<std::uint16_t> wide;
  const auto reserve = static_cast<std::size_t>(reader->reserve_hint());
  cloud.reserve(reserve, info.has_colors && !wide_colors, info.has_intensity);
  if (wide_colors) wide.reserve(3 * reserve);
  // One call reads every vertex when the data is known to hold them; the loop
  // covers the inputs that are read record by record or from a pipe.
  for (;;) {
    RELIEF_ASSIGN_OR_RETURN(const std::size_t n, reader->read_into(cloud, &wide, cloud.size(),
                                                                   std::numeric_limits<std::size_t>::max()));
    if (n == 0) break;
  }
  if (wide_colors) {
    // The whole file is at hand, so the 16-bit rule uses every level rather
    // than a sample.
    const int shift = color_shift_for(max_level(wide.data(), wide.size()));
    // Each level's low byte too, as the streaming reader keeps it.
    cloud.colors.resize(cloud.size());
    cloud.las.color_low.resize(cloud.size());
    narrow_colors(wide.data(), cloud.size(), shift, cloud.colors.data(), cloud.las.color_low.data());
  }
  return cloud;
}

}  // namespace

Result<std::unique_ptr<PointReader>> open_ply_reader(const InputSpec& input, const ReaderOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PlyPointReader> reader,
                          PlyPointReader::open(input, false, options.extra_bytes));
  return std::unique_ptr<PointReader>(std::move(reader));
}

Result<PointCloud> read_ply(const std::string& path) { return read_ply_input(InputSpec{path, std::nullopt}); }

Result<PointCloud> read_ply_memory(std::span<const std::uint8_t> data, const std::string& name) {
  return read_ply_input(InputSpec{name, data});
}

}  // namespace relief
