// The archive's description as JSON (relief/query.h archive_info_json): what
// `relief info --json` prints and Python's Archive.info holds.
#include <charconv>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <span>
#include <vector>
#include <string_view>

#include "relief/codec.h"
#include "relief/crs.h"
#include "relief/io.h"
#include "relief/query.h"
#include "query/json_text.h"

namespace relief {

using json::json_number;
using json::json_string;

namespace {

// printf into a growing string (the JSON is a few lines per source and scan).
[[gnu::format(printf, 2, 3)]] void appendf(std::string& out, const char* format, ...) {
  va_list args;
  va_start(args, format);
  va_list again;
  va_copy(again, args);
  const int n = std::vsnprintf(nullptr, 0, format, args);
  va_end(args);
  if (n > 0) {
    const std::size_t at = out.size();
    out.resize(at + static_cast<std::size_t>(n) + 1);
    std::vsnprintf(out.data() + at, static_cast<std::size_t>(n) + 1, format, again);
    out.resize(at + static_cast<std::size_t>(n));
  }
  va_end(again);
}

// Length of the valid UTF-8 sequence at s[i], 0 when it is not one
// (overlong forms, surrogates and code points past U+10FFFF included).
std::size_t utf8_sequence(const std::string& s, std::size_t i) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned char c = byte(i);
  if (c < 0x80) return 1;
  std::size_t n = 0;
  unsigned lo = 0x80;
  unsigned hi = 0xBF;
  if (c >= 0xC2 && c <= 0xDF) {
    n = 2;
  } else if (c >= 0xE0 && c <= 0xEF) {
    n = 3;
    if (c == 0xE0) lo = 0xA0;
    if (c == 0xED) hi = 0x9F;
  } else if (c >= 0xF0 && c <= 0xF4) {
    n = 4;
    if (c == 0xF0) lo = 0x90;
    if (c == 0xF4) hi = 0x8F;
  } else {
    return 0;
  }
  if (s.size() - i < n) return 0;
  if (byte(i + 1) < lo || byte(i + 1) > hi) return 0;
  for (std::size_t k = 2; k < n; ++k) {
    if (byte(i + k) < 0x80 || byte(i + k) > 0xBF) return 0;
  }
  return n;
}

// A decimal number that is the whole of `text`.
bool parse_number(std::string_view text, double& out) {
  if (text.empty()) return false;
  const auto [p, ec] = std::from_chars(text.data(), text.data() + text.size(), out);
  return ec == std::errc{} && p == text.data() + text.size() && std::isfinite(out);
}

// A codec parameter value: a number, an array of numbers ("1,2,3"), or a string.
std::string json_param_value(std::string_view v) {
  double d = 0;
  if (parse_number(v, d)) return json_number(d);
  if (v.find(',') != std::string_view::npos) {
    std::string array = "[";
    std::string_view rest = v;
    for (;;) {
      const std::size_t comma = rest.find(',');
      if (!parse_number(rest.substr(0, comma), d)) return json_string(std::string(v));
      array += (array.size() > 1 ? ", " : "") + json_number(d);
      if (comma == std::string_view::npos) break;
      rest.remove_prefix(comma + 1);
    }
    return array + "]";
  }
  return json_string(std::string(v));
}

// "key=value;key=value" (encode_params_to_string) as a JSON object; items
// without '=' keep their text under their position.
std::string json_params(const std::string& text) {
  std::string out = "{";
  std::string_view rest(text);
  std::size_t position = 0;
  while (!rest.empty()) {
    const std::size_t semi = rest.find(';');
    const std::string_view item = rest.substr(0, semi);
    rest.remove_prefix(semi == std::string_view::npos ? rest.size() : semi + 1);
    if (item.empty()) continue;
    const std::size_t eq = item.find('=');
    const std::string key =
        eq == std::string_view::npos ? "item" + std::to_string(position) : std::string(item.substr(0, eq));
    const std::string_view value = eq == std::string_view::npos ? item : item.substr(eq + 1);
    out += (out.size() > 1 ? ", " : "") + json_string(key) + ": " + json_param_value(value);
    ++position;
  }
  return out + "}";
}

// The archive's CRS as {name, epsg, wkt}, null when none. A CRS PROJ cannot
// read (an old archive's text) keeps its text under "wkt" with a null name.
std::string json_crs(const std::string& crs) {
  if (crs.empty()) return "null";
  Result<CrsSummary> s = describe_crs(crs, "archive CRS");
  if (!s) return "{\"name\": null, \"epsg\": null, \"wkt\": " + json_string(crs) + "}";
  return "{\"name\": " + json_string(s->name) +
         ", \"epsg\": " + (s->epsg ? std::to_string(*s->epsg) : "null") +
         ", \"wkt\": " + json_string(s->wkt) + "}";
}

std::string json_attributes(const ArchiveInfo& i) {
  std::string a = "[";
  for (const std::string& name : archive_attribute_names(i)) a += (a.size() > 1 ? ", " : "") + json_string(name);
  return a + "]";
}

// The LAS source: point format, version, extra bytes and their typed fields
// (null when the archive has no LAS attributes; version null when no input was
// LAS, e.g. a PLY's extra properties).
std::string json_las(const ArchiveInfo& i) {
  if (i.las_point_format < 0) return "null";
  std::string out =
      "{\"point_format\": " + std::to_string(i.las_point_format) + ", \"version\": " +
      (i.las_version_minor >= 0 ? json_string("1." + std::to_string(i.las_version_minor))
                                : std::string("null")) +
      ", \"gps_time_type\": " +
      (i.las_gps_time_type == GpsTimeType::kUnknown ? std::string("null")
                                                    : json_string(gps_time_type_name(i.las_gps_time_type))) +
      ", \"color_levels\": " +
      ((i.las_attributes & kLasColorLow) == 0 ? std::string("null")
                                              : std::string(i.las_colors_8bit ? "8" : "16")) +
      ", \"extra_bytes_per_point\": " + std::to_string(i.extra_bytes_size) + ", \"extra_bytes\": [";
  bool first = true;
  for (const ExtraBytesField& f : archive_extra_bytes_fields(i)) {
    out += std::string(first ? "" : ", ") + "{\"name\": " + json_string(f.name) + ", \"type\": " +
           json_string(f.type_name) + ", \"offset\": " + std::to_string(f.offset) + ", \"size\": " +
           std::to_string(f.size) + ", \"scale\": " + json_number(f.scale) + ", \"value_offset\": " +
           json_number(f.value_offset) + ", \"description\": " + json_string(f.description) + "}";
    first = false;
  }
  return out + "]}";
}

}  // namespace

namespace json {

// A JSON string: quotes, backslashes and control characters escaped, and
// anything that is not valid UTF-8 (paths and CRS names come from files)
// replaced by U+FFFD, so the output is always valid UTF-8 JSON.
std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (std::size_t i = 0; i < s.size();) {
    const char c = s[i];
    const std::size_t n = utf8_sequence(s, i);
    if (n == 0) {
      out += "\xEF\xBF\xBD";
      ++i;
      continue;
    }
    if (n > 1) {
      out.append(s, i, n);
      i += n;
      continue;
    }
    ++i;
    switch (c) {
      case '"':
        out += "\\\"";
        break;
      case '\\':
        out += "\\\\";
        break;
      case '\n':
        out += "\\n";
        break;
      case '\r':
        out += "\\r";
        break;
      case '\t':
        out += "\\t";
        break;
      default:
        if (static_cast<unsigned char>(c) < 0x20 || c == 0x7F) {
          char buf[8];
          std::snprintf(buf, sizeof buf, "\\u%04x", static_cast<unsigned>(static_cast<unsigned char>(c)));
          out += buf;
        } else {
          out += c;
        }
    }
  }
  return out + "\"";
}

std::string json_number(double v) {
  if (!std::isfinite(v)) return "null";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

}  // namespace json

std::vector<std::string> archive_attribute_names(const ArchiveInfo& i) {
  std::vector<std::string> names;
  if (i.has_colors) names.push_back("rgb");
  if (i.has_intensity) names.push_back("intensity");
  for (std::uint32_t b = 0; b < kLasAttributeCount; ++b) {
    if ((i.las_attributes & (1u << b)) != 0) names.push_back(kLasAttributeNames[b]);
  }
  return names;
}

std::vector<ExtraBytesField> archive_extra_bytes_fields(const ArchiveInfo& i) {
  if (i.extra_bytes_vlr.empty()) return {};
  const std::span<const std::uint8_t> vlr(reinterpret_cast<const std::uint8_t*>(i.extra_bytes_vlr.data()),
                                          i.extra_bytes_vlr.size());
  Result<std::vector<ExtraBytesField>> fields = parse_extra_bytes_vlr(vlr, i.extra_bytes_size, "archive");
  return fields ? *fields : std::vector<ExtraBytesField>{};
}

std::string archive_info_json(const ArchiveInfo& i, const std::string& path) {
  const double bpp = i.input_points > 0
                         ? 8.0 * static_cast<double>(i.file_bytes) / static_cast<double>(i.input_points)
                         : 0.0;
  std::string out;
  appendf(out, "{\n");
  appendf(out, "  \"path\": %s,\n", json_string(path).c_str());
  appendf(out, "  \"format_version\": %d,\n", i.format_version);
  appendf(out, "  \"points_in\": %llu,\n", static_cast<unsigned long long>(i.input_points));
  appendf(out, "  \"points_decoded\": %llu,\n", static_cast<unsigned long long>(i.decoded_points));
  appendf(out, "  \"chunks\": %llu,\n", static_cast<unsigned long long>(i.chunk_count));
  const auto box = [&](const char* name, const Box3d& b) {
    if (b.empty()) {
      appendf(out, "  \"%s\": null,\n", name);
    } else {
      appendf(out, "  \"%s\": {\"min\": [%s, %s, %s], \"max\": [%s, %s, %s]},\n", name,
              json_number(b.min.x).c_str(), json_number(b.min.y).c_str(), json_number(b.min.z).c_str(),
              json_number(b.max.x).c_str(), json_number(b.max.y).c_str(), json_number(b.max.z).c_str());
    }
  };
  // The points' bounds, and those of what any level of detail returns.
  box("bounds", i.point_bounds);
  box("lod_bounds", i.bounds);
  appendf(out, "  \"grid\": {\"origin\": [%s, %s, %s], \"chunk_edge\": %s},\n",
          json_number(i.grid.origin.x).c_str(), json_number(i.grid.origin.y).c_str(),
          json_number(i.grid.origin.z).c_str(), json_number(i.grid.chunk_edge).c_str());
  // Every key shown, though archives store only those off their defaults.
  const std::string params = full_params_text(i.codec_params);
  appendf(out, "  \"codec_params\": %s,\n", json_params(params).c_str());
  appendf(out, "  \"codec_params_text\": %s,\n", json_string(params).c_str());
  appendf(out, "  \"file_bytes\": %llu,\n", static_cast<unsigned long long>(i.file_bytes));
  appendf(out, "  \"blob_bytes\": %llu,\n", static_cast<unsigned long long>(i.blob_bytes));
  appendf(out, "  \"bits_per_point\": %s,\n", json_number(bpp).c_str());
  appendf(out, "  \"attributes\": %s,\n", json_attributes(i).c_str());
  appendf(out, "  \"las\": %s,\n", json_las(i).c_str());
  appendf(out, "  \"crs\": %s,\n", json_crs(i.crs).c_str());
  appendf(out, "  \"creator\": %s,\n", json_string(i.creator).c_str());
  appendf(out, "  \"sources\": [");
  for (std::size_t k = 0; k < i.sources.size(); ++k) {
    const ArchiveSource& s = i.sources[k];
    appendf(out,
            "%s\n    {\"path\": %s, \"format\": %s, \"points\": %llu, \"crs\": %s, \"scan\": %lld, "
            "\"las_records\": %llu}",
            k ? "," : "", json_string(s.path).c_str(), json_string(s.format).c_str(),
            static_cast<unsigned long long>(s.point_count), json_string(s.crs).c_str(),
            static_cast<long long>(s.scan_id), static_cast<unsigned long long>(s.las.records.size()));
  }
  appendf(out, "%s],\n", i.sources.empty() ? "" : "\n  ");
  appendf(out, "  \"scans\": [");
  for (std::size_t k = 0; k < i.scans.size(); ++k) {
    const ArchiveScan& s = i.scans[k];
    appendf(out, "%s\n    {\"id\": %lld, \"complete\": %s, \"created_at\": %s, \"pyramid\": [", k ? "," : "",
            static_cast<long long>(s.id), s.complete ? "true" : "false", json_string(s.created_at).c_str());
    // The scan's finished pyramid, level by level (empty: none).
    for (const ScanPyramid& p : i.pyramid) {
      if (p.scan_id != s.id) continue;
      for (std::size_t l = 0; l < p.levels.size(); ++l) {
        const PyramidLevel& v = p.levels[l];
        appendf(out, "%s{\"level\": %d, \"chunks\": %llu, \"points\": %llu, \"blob_bytes\": %llu}",
                l ? ", " : "", v.level, static_cast<unsigned long long>(v.chunks),
                static_cast<unsigned long long>(v.points), static_cast<unsigned long long>(v.blob_bytes));
      }
    }
    appendf(out, "]}");
  }
  appendf(out, "%s]\n}\n", i.scans.empty() ? "" : "\n  ");
  return out;
}

}  // namespace relief
