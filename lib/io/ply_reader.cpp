// PLY reader. The header is parsed into ply::Header; the body is walked
// element by element in file order so that elements before and after the
// vertex element are skipped (and checked for completeness) in every encoding.
//
// The common case (binary in host byte order, x y z all float or all double,
// optional uchar colour and float intensity) is decoded by a small template
// kernel chosen once per file: fixed-size records, memcpy per field, no
// per-field dispatch. Everything else goes through a generic per-field loader.

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "io/byte_source.h"
#include "io/ply_format.h"
#include "relief/io.h"

namespace relief {

namespace {

using ply::Element;
using ply::Property;
using ply::ScalarType;

// Without a known input size (pipes) the header count is untrusted, so the
// first allocation is capped and vectors grow as data actually arrives.
constexpr std::uint64_t kBlindReserve = std::uint64_t{1} << 16;
// ascii records are one per line; a line this long is not a point record.
constexpr std::size_t kMaxAsciiLine = std::size_t{4} << 20;

// ---------------------------------------------------------------- lines

enum class LineStatus { kLine, kEnd, kTooLong };

// Reads the next line without its "\n" (and "\r" before it). The view stays
// valid until the next call on `src`. A last line without "\n" still counts.
Status next_line(ByteSource& src, std::size_t max_len, std::string_view& line, LineStatus& state) {
  std::span<const std::uint8_t> view;
  RELIEF_RETURN_IF_ERROR(src.fill(1, view));
  if (view.empty()) {
    state = LineStatus::kEnd;
    return Status::ok();
  }
  std::size_t scanned = 0;
  for (;;) {
    const auto* nl = static_cast<const std::uint8_t*>(
        std::memchr(view.data() + scanned, '\n', view.size() - scanned));
    std::size_t len = 0;
    std::size_t used = 0;
    if (nl != nullptr) {
      len = static_cast<std::size_t>(nl - view.data());
      used = len + 1;
    } else if (view.size() > max_len) {
      state = LineStatus::kTooLong;
      return Status::ok();
    } else {
      const std::size_t have = view.size();
      RELIEF_RETURN_IF_ERROR(src.fill(have + 1, view));
      if (view.size() > have) {
        scanned = have;
        continue;
      }
      len = used = have;  // end of input: the last line has no newline
    }
    if (len > max_len) {
      state = LineStatus::kTooLong;
      return Status::ok();
    }
    if (len > 0 && view[len - 1] == '\r') --len;
    line = std::string_view(reinterpret_cast<const char*>(view.data()), len);
    src.consume(used);  // consume() never moves bytes, so `line` stays valid
    state = LineStatus::kLine;
    return Status::ok();
  }
}

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// Returns the next whitespace-separated token of `line` from `pos`, or an
// empty view when there is none.
std::string_view next_token(std::string_view line, std::size_t& pos) {
  while (pos < line.size() && is_space(line[pos])) ++pos;
  const std::size_t start = pos;
  while (pos < line.size() && !is_space(line[pos])) ++pos;
  return line.substr(start, pos - start);
}

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t pos = 0;
  for (std::string_view t = next_token(line, pos); !t.empty(); t = next_token(line, pos)) {
    out.push_back(t);
  }
  return out;
}

std::string quoted(std::string_view s) {
  // Keep error messages short and printable even when the input is binary junk.
  constexpr std::size_t kMaxShown = 40;
  std::string out = "'";
  for (char c : s.substr(0, kMaxShown)) {
    out += (c >= 0x20 && c < 0x7f) ? c : '?';
  }
  if (s.size() > kMaxShown) out += "...";
  return out + "'";
}

// ---------------------------------------------------------------- header

Result<ply::Header> parse_header(ByteSource& src, const std::string& name) {
  std::span<const std::uint8_t> view;
  RELIEF_RETURN_IF_ERROR(src.fill(4, view));
  if (view.empty()) return format_error(name + ": not a PLY file: it is empty");
  const bool magic = view.size() >= 3 && std::memcmp(view.data(), "ply", 3) == 0 &&
                     (view.size() == 3 || view[3] == '\n' || view[3] == '\r' ||
                      view[3] == ' ' || view[3] == '\t');
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
    const std::vector<std::string_view> tok = split(line);
    if (line_no == 1) {
      if (tok.size() != 1 || tok[0] != "ply") {
        return format_error(name + ": not a PLY file: the first line is not 'ply'");
      }
      continue;
    }
    if (tok.empty()) continue;   // tolerated: some writers leave blank lines
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
                            " is absurdly large (limit " + std::to_string(ply::kMaxElementCount) +
                            ")");
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

enum Field : std::size_t { kX, kY, kZ, kRed, kGreen, kBlue, kIntensity, kFieldCount };

struct VertexPlan {
  // Property index feeding each field, or kNone.
  static constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
  std::array<std::size_t, kFieldCount> prop{};
  bool has_color = false;
  bool has_intensity = false;
  // Colours wider than 8 bits are collected as 16-bit and narrowed at the end,
  // because whether to shift depends on the maximum over the whole file.
  bool wide_color = false;
};

Result<VertexPlan> make_plan(const Element& vertex, const std::string& name) {
  VertexPlan plan;
  plan.prop.fill(VertexPlan::kNone);
  // A scalar (non-list) property called `prop_name`, if any.
  auto scalar = [&](std::string_view prop_name) -> std::optional<std::size_t> {
    const auto i = vertex.find(prop_name);
    if (!i || vertex.properties[*i].is_list) return std::nullopt;
    return i;
  };
  for (const char* axis : {"x", "y", "z"}) {
    const auto i = vertex.find(axis);
    if (!i) return format_error(name + ": the vertex element has no '" + axis + "' property");
    if (vertex.properties[*i].is_list) {
      return format_error(name + ": vertex property '" + axis + "' is a list, not a number");
    }
  }
  plan.prop[kX] = *vertex.find("x");
  plan.prop[kY] = *vertex.find("y");
  plan.prop[kZ] = *vertex.find("z");

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
      for (std::size_t i : {*r, *g, *b}) {
        const ScalarType t = vertex.properties[i].type;
        if (t != ScalarType::kUint8 && t != ScalarType::kInt8) plan.wide_color = true;
      }
      break;
    }
  }
  for (const char* intensity_name : {"intensity", "scalar_intensity"}) {
    if (const auto i = scalar(intensity_name)) {
      plan.prop[kIntensity] = *i;
      plan.has_intensity = true;
      break;
    }
  }
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
    case ScalarType::kInt8: return load<std::int8_t>(p, swap);
    case ScalarType::kUint8: return load<std::uint8_t>(p, swap);
    case ScalarType::kInt16: return load<std::int16_t>(p, swap);
    case ScalarType::kUint16: return load<std::uint16_t>(p, swap);
    case ScalarType::kInt32: return load<std::int32_t>(p, swap);
    case ScalarType::kUint32: return load<std::uint32_t>(p, swap);
    case ScalarType::kFloat32: return load<float>(p, swap);
    case ScalarType::kFloat64: return load<double>(p, swap);
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
      case ScalarType::kInt8: lo = INT8_MIN, hi = INT8_MAX; break;
      case ScalarType::kUint8: lo = 0, hi = UINT8_MAX; break;
      case ScalarType::kInt16: lo = INT16_MIN, hi = INT16_MAX; break;
      case ScalarType::kUint16: lo = 0, hi = UINT16_MAX; break;
      case ScalarType::kInt32: lo = INT32_MIN, hi = INT32_MAX; break;
      default: lo = 0, hi = UINT32_MAX; break;
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

// ---------------------------------------------------------------- sink

// Where vertices go while the body is read.
struct VertexSink {
  PointCloud cloud;
  std::vector<std::uint16_t> wide;  // r g b per point, only for wide colours
};

// "x.ply: vertex 12"; built only when an error is reported.
std::string record_label(const std::string& name, std::string_view element, std::uint64_t index) {
  return name + ": " + std::string(element) + " " + std::to_string(index);
}

std::string vertex_label(const std::string& name, std::uint64_t index) {
  return record_label(name, "vertex", index);
}

// Shortest round-trip text, so messages show the value actually read.
std::string format_double(double v) {
  std::array<char, 64> buf{};
  const auto [end, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return ec == std::errc{} ? std::string(buf.data(), end) : std::string("?");
}

Status non_finite_vertex(const std::string& name, std::uint64_t index, const Vec3d& p) {
  return format_error(vertex_label(name, index) + " has a non-finite coordinate (" +
                      format_double(p.x) + ", " + format_double(p.y) + ", " + format_double(p.z) +
                      ")");
}

Status non_finite_intensity(const std::string& name, std::uint64_t index, float v) {
  return format_error(vertex_label(name, index) + " has a non-finite intensity (" +
                      format_double(v) + ")");
}

// Checks points [first, first + n) of the cloud. One branch-free pass in the
// common all-finite case; the offending index is searched only on failure.
Status check_finite(const PointCloud& cloud, std::size_t first, std::size_t n,
                    const std::string& name) {
  const Vec3d* p = cloud.positions.data() + first;
  double acc = 0;  // x - x is NaN exactly when x is NaN or infinite
  for (std::size_t i = 0; i < n; ++i) acc += (p[i].x - p[i].x) + (p[i].y - p[i].y) + (p[i].z - p[i].z);
  if (acc != 0) {
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(p[i].x) || !std::isfinite(p[i].y) || !std::isfinite(p[i].z)) {
        return non_finite_vertex(name, first + i, p[i]);
      }
    }
  }
  if (!cloud.intensities.empty()) {
    const float* v = cloud.intensities.data() + first;
    float facc = 0;
    for (std::size_t i = 0; i < n; ++i) facc += v[i] - v[i];
    if (facc != 0) {
      for (std::size_t i = 0; i < n; ++i) {
        if (!std::isfinite(v[i])) return non_finite_intensity(name, first + i, v[i]);
      }
    }
  }
  return Status::ok();
}

// Appends one vertex from field values (used by the per-record paths).
Status push_vertex(const std::array<double, kFieldCount>& v, const VertexPlan& plan,
                   std::uint64_t index, const std::string& name, VertexSink& sink) {
  const Vec3d p{v[kX], v[kY], v[kZ]};
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
    return non_finite_vertex(name, index, p);
  }
  sink.cloud.positions.push_back(p);
  if (plan.has_color) {
    if (plan.wide_color) {
      for (Field f : {kRed, kGreen, kBlue}) sink.wide.push_back(to_level16(v[f]));
    } else {
      sink.cloud.colors.push_back({to_level8(v[kRed]), to_level8(v[kGreen]), to_level8(v[kBlue])});
    }
  }
  if (plan.has_intensity) {
    const float f = to_float(v[kIntensity]);
    if (!std::isfinite(f)) return non_finite_intensity(name, index, f);
    sink.cloud.intensities.push_back(f);
  }
  return Status::ok();
}

// Narrows 16-bit colours: shift right by 8 only if some value needs it, so
// files that store 8-bit levels in a wider type keep their values.
void finish_colors(VertexSink& sink) {
  if (sink.wide.empty()) return;
  const std::uint16_t max = *std::max_element(sink.wide.begin(), sink.wide.end());
  const int shift = max > 255 ? 8 : 0;
  const std::size_t n = sink.wide.size() / 3;
  sink.cloud.colors.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    sink.cloud.colors[i] = {static_cast<std::uint8_t>(sink.wide[3 * i] >> shift),
                            static_cast<std::uint8_t>(sink.wide[3 * i + 1] >> shift),
                            static_cast<std::uint8_t>(sink.wide[3 * i + 2] >> shift)};
  }
  sink.wide.clear();
  sink.wide.shrink_to_fit();
}

void reserve_sink(VertexSink& sink, const VertexPlan& plan, std::uint64_t n) {
  const auto count = static_cast<std::size_t>(n);
  sink.cloud.reserve(count, plan.has_color && !plan.wide_color, plan.has_intensity);
  if (plan.wide_color) sink.wide.reserve(3 * count);
}

Status truncated(const std::string& name, const Element& el, std::uint64_t got) {
  const std::string what =
      el.name == "vertex" ? std::string(" vertices") : " '" + el.name + "' elements";
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
  bool has_intensity = false;
};

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
void decode_generic(const std::uint8_t* src, std::size_t n, const Layout& lay, Vec3d* pos,
                    Rgb8* col, std::uint16_t* wide, float* intensity) {
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
      } else {
        col[i] = Rgb8{to_level8(r), to_level8(g), to_level8(b)};
      }
    }
    if (lay.has_intensity) intensity[i] = to_float(get(src, kIntensity));
  }
}

BatchDecoder pick_decoder(const Layout& lay, const VertexPlan& plan) {
  const ScalarType ct = lay.type[kX];
  const bool same_coord = lay.type[kY] == ct && lay.type[kZ] == ct &&
                          (ct == ScalarType::kFloat32 || ct == ScalarType::kFloat64);
  const bool plain_color = !plan.has_color || (lay.type[kRed] == ScalarType::kUint8 &&
                                               lay.type[kGreen] == ScalarType::kUint8 &&
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

Status read_binary_vertices_fixed(ByteSource& src, const Element& el, const VertexPlan& plan,
                                  bool swap, const std::string& name, VertexSink& sink) {
  Layout lay;
  lay.swap = swap;
  lay.has_color = plan.has_color;
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
  const std::size_t stride = lay.stride;  // >= 3: x, y and z are present

  // Check the declared count against the bytes actually there before any
  // allocation is sized by it.
  std::uint64_t reserve = std::min(el.count, kBlindReserve);
  if (const auto rem = src.remaining()) {
    if (el.count > *rem / stride) return truncated(name, el, *rem / stride);
    reserve = el.count;
  }
  reserve_sink(sink, plan, reserve);
  PointCloud& cloud = sink.cloud;

  const BatchDecoder decode = pick_decoder(lay, plan);
  std::uint64_t done = 0;
  while (done < el.count) {
    std::span<const std::uint8_t> view;
    RELIEF_RETURN_IF_ERROR(src.fill(stride, view));
    const std::uint64_t avail = view.size() / stride;
    if (avail == 0) return truncated(name, el, done);
    const auto n = static_cast<std::size_t>(std::min(el.count - done, avail));
    const auto at = static_cast<std::size_t>(done);
    cloud.positions.resize(at + n);
    if (plan.has_color) {
      if (plan.wide_color) {
        sink.wide.resize(3 * (at + n));
      } else {
        cloud.colors.resize(at + n);
      }
    }
    if (plan.has_intensity) cloud.intensities.resize(at + n);
    decode(view.data(), n, lay, cloud.positions.data() + at,
           plan.has_color && !plan.wide_color ? cloud.colors.data() + at : nullptr,
           plan.wide_color ? sink.wide.data() + 3 * at : nullptr,
           plan.has_intensity ? cloud.intensities.data() + at : nullptr);
    RELIEF_RETURN_IF_ERROR(check_finite(cloud, at, n, name));
    src.consume(n * stride);
    done += n;
  }
  return Status::ok();
}

// Reads one binary record property by property; used when the element has
// list properties. `values` receives the fields named in `field_of` (may be
// empty when the record is only skipped). `complete` is false if the input ended.
Status read_binary_record(ByteSource& src, const Element& el, bool swap,
                          const std::vector<int>& field_of,
                          std::array<double, kFieldCount>& values, bool& complete,
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
                            " has a negative length (" +
                            std::to_string(static_cast<std::int64_t>(count)) + ")");
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

Status read_binary_vertices_var(ByteSource& src, const Element& el, const VertexPlan& plan,
                                bool swap, const std::string& name, VertexSink& sink) {
  // Each record holds at least min_record_size() bytes, which bounds the count.
  std::uint64_t reserve = std::min(el.count, kBlindReserve);
  if (const auto rem = src.remaining()) reserve = std::min(el.count, *rem / el.min_record_size());
  reserve_sink(sink, plan, reserve);
  const std::vector<int> field_of = fields_of_properties(el, plan);
  for (std::uint64_t i = 0; i < el.count; ++i) {
    std::array<double, kFieldCount> values{};
    bool complete = false;
    RELIEF_RETURN_IF_ERROR(read_binary_record(src, el, swap, field_of, values, complete, name, i));
    if (!complete) return truncated(name, el, i);
    RELIEF_RETURN_IF_ERROR(push_vertex(values, plan, i, name, sink));
  }
  return Status::ok();
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
    RELIEF_RETURN_IF_ERROR(read_binary_record(src, el, swap, {}, unused, complete, name, i));
    if (!complete) return truncated(name, el, i);
  }
  return Status::ok();
}

// ---------------------------------------------------------------- ascii

// Next non-blank line; `found` is false at the end of the input.
Status next_record_line(ByteSource& src, std::string_view& line, bool& found,
                        const std::string& name, const Element& el, std::uint64_t index) {
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

Status read_ascii_vertices(ByteSource& src, const Element& el, const VertexPlan& plan,
                           const std::string& name, VertexSink& sink) {
  // A record needs at least one character and one separator per property.
  const std::uint64_t min_line = 2 * el.properties.size();
  std::uint64_t reserve = std::min(el.count, kBlindReserve);
  if (const auto rem = src.remaining()) reserve = std::min(el.count, *rem / min_line + 1);
  reserve_sink(sink, plan, reserve);
  const std::vector<int> field_of = fields_of_properties(el, plan);
  for (std::uint64_t i = 0; i < el.count; ++i) {
    std::string_view line;
    bool found = false;
    RELIEF_RETURN_IF_ERROR(next_record_line(src, line, found, name, el, i));
    if (!found) return truncated(name, el, i);
    std::array<double, kFieldCount> values{};
    std::size_t pos = 0;
    for (std::size_t j = 0; j < el.properties.size(); ++j) {
      const Property& prop = el.properties[j];
      const std::string_view tok = next_token(line, pos);
      if (tok.empty()) {
        return format_error(vertex_label(name, i) + ": the line ends before property " +
                            quoted(prop.name));
      }
      if (prop.is_list) {
        double count = 0;
        if (!parse_ascii(tok, prop.count_type, count) || count < 0) {
          return format_error(vertex_label(name, i) + ": " + quoted(tok) +
                              " is not a valid length for list " + quoted(prop.name));
        }
        for (std::uint64_t k = 0; k < static_cast<std::uint64_t>(count); ++k) {
          if (next_token(line, pos).empty()) {
            return format_error(vertex_label(name, i) + ": the line ends inside list " +
                                quoted(prop.name));
          }
        }
        continue;
      }
      if (field_of[j] < 0) continue;
      if (!parse_ascii(tok, prop.type, values[static_cast<std::size_t>(field_of[j])])) {
        return format_error(vertex_label(name, i) + ": " + quoted(tok) + " is not a valid " +
                            ply::scalar_name(prop.type) + " for property " + quoted(prop.name));
      }
    }
    if (!next_token(line, pos).empty()) {
      return format_error(vertex_label(name, i) + ": more values than the header declares");
    }
    RELIEF_RETURN_IF_ERROR(push_vertex(values, plan, i, name, sink));
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

// ---------------------------------------------------------------- driver

Result<PointCloud> read_ply_source(ByteSource& src, const std::string& name) {
  RELIEF_ASSIGN_OR_RETURN(const ply::Header header, parse_header(src, name));
  const auto vertex_it = std::find_if(header.elements.begin(), header.elements.end(),
                                      [](const Element& e) { return e.name == "vertex"; });
  if (vertex_it == header.elements.end()) {
    return format_error(name + ": the header declares no vertex element");
  }
  RELIEF_ASSIGN_OR_RETURN(const VertexPlan plan, make_plan(*vertex_it, name));

  const bool file_little = header.encoding == PlyEncoding::kBinaryLittleEndian;
  const bool swap = header.encoding != PlyEncoding::kAscii &&
                    file_little != (std::endian::native == std::endian::little);
  VertexSink sink;
  // Walk every element, including those after the vertices, so a file cut
  // short anywhere is reported rather than half-read silently.
  for (const Element& el : header.elements) {
    const bool is_vertex = &el == &*vertex_it;
    if (header.encoding == PlyEncoding::kAscii) {
      RELIEF_RETURN_IF_ERROR(is_vertex ? read_ascii_vertices(src, el, plan, name, sink)
                                       : skip_ascii_element(src, el, name));
    } else if (!is_vertex) {
      RELIEF_RETURN_IF_ERROR(skip_binary_element(src, el, swap, name));
    } else if (el.fixed_size()) {
      RELIEF_RETURN_IF_ERROR(read_binary_vertices_fixed(src, el, plan, swap, name, sink));
    } else {
      RELIEF_RETURN_IF_ERROR(read_binary_vertices_var(src, el, plan, swap, name, sink));
    }
  }
  finish_colors(sink);
  return std::move(sink.cloud);
}

}  // namespace

Result<PointCloud> read_ply(const std::string& path) {
  RELIEF_ASSIGN_OR_RETURN(ByteSource src, ByteSource::open_file(path));
  return read_ply_source(src, path);
}

Result<PointCloud> read_ply_memory(std::span<const std::uint8_t> data, const std::string& name) {
  ByteSource src = ByteSource::from_memory(data);
  return read_ply_source(src, name);
}

}  // namespace relief
