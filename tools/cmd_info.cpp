// relief info ARCHIVE [--json]: what an archive holds.
#include <charconv>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cli_common.h"
#include "commands.h"
#include "relief/codec.h"
#include "relief/crs.h"
#include "relief/io.h"
#include "relief/query.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "info";
constexpr const char* kUsageText =
    "usage: relief info ARCHIVE [--json]\n"
    "Prints the format version, points, chunks, bounds, grid, codec parameters, size on disk,\n"
    "bits per point, attributes, CRS, sources and scans of an archive.\n";

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
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
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
    const std::string key = eq == std::string_view::npos ? "item" + std::to_string(position) : std::string(item.substr(0, eq));
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
  return "{\"name\": " + json_string(s->name) + ", \"epsg\": " + (s->epsg ? std::to_string(*s->epsg) : "null") +
         ", \"wkt\": " + json_string(s->wkt) + "}";
}

std::string crs_text(const std::string& crs) {
  if (crs.empty()) return "(none)";
  Result<CrsSummary> s = describe_crs(crs, "archive CRS");
  if (!s) return crs;
  return s->name + (s->epsg ? " (EPSG:" + std::to_string(*s->epsg) + ")" : " (no EPSG code)");
}

// Names of every attribute: rgb, intensity, then the LAS ones (relief/types.h).
std::vector<std::string> attribute_names(const ArchiveInfo& i) {
  std::vector<std::string> names;
  if (i.has_colors) names.push_back("rgb");
  if (i.has_intensity) names.push_back("intensity");
  for (std::uint32_t b = 0; b < kLasAttributeCount; ++b) {
    if ((i.las_attributes & (1u << b)) != 0) names.push_back(kLasAttributeNames[b]);
  }
  return names;
}

std::string json_attributes(const ArchiveInfo& i) {
  std::string a = "[";
  for (const std::string& name : attribute_names(i)) a += (a.size() > 1 ? ", " : "") + json_string(name);
  return a + "]";
}

std::string attributes(const ArchiveInfo& i) {
  std::string a;
  for (const std::string& name : attribute_names(i)) a += (a.empty() ? "" : ",") + name;
  return a.empty() ? "none" : a;
}

// The typed fields of the archive's Extra Bytes VLR (empty when none or when
// it does not parse, which the reader that stored it had checked).
std::vector<ExtraBytesField> extra_fields(const ArchiveInfo& i) {
  if (i.extra_bytes_vlr.empty()) return {};
  const std::span<const std::uint8_t> vlr(reinterpret_cast<const std::uint8_t*>(i.extra_bytes_vlr.data()),
                                          i.extra_bytes_vlr.size());
  Result<std::vector<ExtraBytesField>> fields = parse_extra_bytes_vlr(vlr, i.extra_bytes_size, "archive");
  return fields ? *fields : std::vector<ExtraBytesField>{};
}

std::string json_las(const ArchiveInfo& i) {
  if (i.las_point_format < 0) return "null";
  std::string out = "{\"point_format\": " + std::to_string(i.las_point_format) +
                    ", \"version\": " + json_string("1." + std::to_string(i.las_version_minor)) +
                    ", \"extra_bytes_per_point\": " + std::to_string(i.extra_bytes_size) + ", \"extra_bytes\": [";
  bool first = true;
  for (const ExtraBytesField& f : extra_fields(i)) {
    out += std::string(first ? "" : ", ") + "{\"name\": " + json_string(f.name) + ", \"type\": " +
           json_string(f.type_name) + ", \"offset\": " + std::to_string(f.offset) + ", \"size\": " +
           std::to_string(f.size) + ", \"scale\": " + json_number(f.scale) + ", \"value_offset\": " +
           json_number(f.value_offset) + ", \"description\": " + json_string(f.description) + "}";
    first = false;
  }
  return out + "]}";
}

std::string las_text(const ArchiveInfo& i) {
  std::string out = "point format " + std::to_string(i.las_point_format) + ", LAS 1." +
                    std::to_string(i.las_version_minor);
  if (i.extra_bytes_size > 0) {
    out += ", " + std::to_string(i.extra_bytes_size) + " extra bytes";
    const std::vector<ExtraBytesField> fields = extra_fields(i);
    for (std::size_t k = 0; k < fields.size(); ++k) {
      out += (k == 0 ? ": " : ", ") + fields[k].name + " (" + fields[k].type_name + ")";
    }
  }
  return out;
}

}  // namespace

int run_info(int argc, char** argv) {
  Args args(argc, argv, {"--help", "--json"}, {});
  if (args.has("--help")) {
    std::cout << kUsageText;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one ARCHIVE");
  auto reader = ArchiveReader::open(args.positional()[0]);
  if (!reader) return fail(kCommand, reader.status());
  const ArchiveInfo& i = (*reader)->info();
  const double bpp = i.input_points > 0 ? 8.0 * static_cast<double>(i.file_bytes) / static_cast<double>(i.input_points) : 0.0;
  const double blob_bpp =
      i.input_points > 0 ? 8.0 * static_cast<double>(i.blob_bytes) / static_cast<double>(i.input_points) : 0.0;
  if (args.has("--json")) {
    std::printf("{\n");
    std::printf("  \"path\": %s,\n", json_string(args.positional()[0]).c_str());
    std::printf("  \"format_version\": %d,\n", i.format_version);
    std::printf("  \"points_in\": %llu,\n", static_cast<unsigned long long>(i.input_points));
    std::printf("  \"points_decoded\": %llu,\n", static_cast<unsigned long long>(i.decoded_points));
    std::printf("  \"chunks\": %llu,\n", static_cast<unsigned long long>(i.chunk_count));
    if (i.bounds.empty()) {
      std::printf("  \"bounds\": null,\n");
    } else {
      std::printf("  \"bounds\": {\"min\": [%s, %s, %s], \"max\": [%s, %s, %s]},\n", json_number(i.bounds.min.x).c_str(),
                  json_number(i.bounds.min.y).c_str(), json_number(i.bounds.min.z).c_str(),
                  json_number(i.bounds.max.x).c_str(), json_number(i.bounds.max.y).c_str(),
                  json_number(i.bounds.max.z).c_str());
    }
    std::printf("  \"grid\": {\"origin\": [%s, %s, %s], \"chunk_edge\": %s},\n", json_number(i.grid.origin.x).c_str(),
                json_number(i.grid.origin.y).c_str(), json_number(i.grid.origin.z).c_str(),
                json_number(i.grid.chunk_edge).c_str());
    std::printf("  \"codec_params\": %s,\n", json_params(i.codec_params).c_str());
    std::printf("  \"codec_params_text\": %s,\n", json_string(i.codec_params).c_str());
    std::printf("  \"file_bytes\": %llu,\n", static_cast<unsigned long long>(i.file_bytes));
    std::printf("  \"blob_bytes\": %llu,\n", static_cast<unsigned long long>(i.blob_bytes));
    std::printf("  \"bits_per_point\": %s,\n", json_number(bpp).c_str());
    std::printf("  \"attributes\": %s,\n", json_attributes(i).c_str());
    std::printf("  \"las\": %s,\n", json_las(i).c_str());
    std::printf("  \"crs\": %s,\n", json_crs(i.crs).c_str());
    std::printf("  \"creator\": %s,\n", json_string(i.creator).c_str());
    std::printf("  \"sources\": [");
    for (std::size_t k = 0; k < i.sources.size(); ++k) {
      const ArchiveSource& s = i.sources[k];
      std::printf("%s\n    {\"path\": %s, \"format\": %s, \"points\": %llu, \"crs\": %s, \"scan\": %lld}",
                  k ? "," : "", json_string(s.path).c_str(), json_string(s.format).c_str(),
                  static_cast<unsigned long long>(s.point_count), json_string(s.crs).c_str(),
                  static_cast<long long>(s.scan_id));
    }
    std::printf("%s],\n", i.sources.empty() ? "" : "\n  ");
    std::printf("  \"scans\": [");
    for (std::size_t k = 0; k < i.scans.size(); ++k) {
      const ArchiveScan& s = i.scans[k];
      std::printf("%s\n    {\"id\": %lld, \"complete\": %s, \"created_at\": %s}", k ? "," : "",
                  static_cast<long long>(s.id), s.complete ? "true" : "false", json_string(s.created_at).c_str());
    }
    std::printf("%s]\n}\n", i.scans.empty() ? "" : "\n  ");
    return kExitOk;
  }
  std::printf("archive         %s\n", args.positional()[0].c_str());
  std::printf("format version  %d\n", i.format_version);
  std::printf("points          %llu in, %llu decodable\n", static_cast<unsigned long long>(i.input_points),
              static_cast<unsigned long long>(i.decoded_points));
  std::printf("chunks          %llu\n", static_cast<unsigned long long>(i.chunk_count));
  if (i.bounds.empty()) {
    std::printf("bounds          (empty)\n");
  } else {
    std::printf("bounds          [%.6f, %.6f, %.6f] .. [%.6f, %.6f, %.6f]\n", i.bounds.min.x, i.bounds.min.y,
                i.bounds.min.z, i.bounds.max.x, i.bounds.max.y, i.bounds.max.z);
  }
  std::printf("grid            origin (%.6g, %.6g, %.6g), chunk edge %.6g\n", i.grid.origin.x, i.grid.origin.y,
              i.grid.origin.z, i.grid.chunk_edge);
  if (auto params = encode_params_from_string(i.codec_params); params && params->bound) {
    const ErrorBound& b = *params->bound;
    std::printf("mode            bounded: every point within %.6g, %.6g, %.6g (x, y, z; grid step %.6g, %.6g, %.6g), "
                "colour %s\n",
                b.step.x / 2, b.step.y / 2, b.step.z / 2, b.step.x, b.step.y, b.step.z,
                b.color_tolerance == 0 ? "exact" : ("within " + std::to_string(b.color_tolerance)).c_str());
  } else {
    std::printf("mode            resample: one point per occupied map pixel\n");
  }
  std::printf("codec           %s\n", i.codec_params.c_str());
  std::printf("size on disk    %s (%.3f bits/point; blobs %s = %.3f bits/point)\n", format_bytes(i.file_bytes).c_str(),
              bpp, format_bytes(i.blob_bytes).c_str(), blob_bpp);
  std::printf("attributes      %s\n", attributes(i).c_str());
  if (i.las_point_format >= 0) std::printf("las source      %s\n", las_text(i).c_str());
  std::printf("crs             %s\n", crs_text(i.crs).c_str());
  std::printf("creator         %s\n", i.creator.c_str());
  for (const ArchiveSource& s : i.sources) {
    std::printf("source          %s (%s, %llu points, scan %lld)\n", s.path.c_str(), s.format.c_str(),
                static_cast<unsigned long long>(s.point_count), static_cast<long long>(s.scan_id));
  }
  for (const ArchiveScan& s : i.scans) {
    std::printf("scan            %lld %s, %s\n", static_cast<long long>(s.id),
                s.complete ? "complete" : "INCOMPLETE (interrupted)", s.created_at.c_str());
  }
  return kExitOk;
}

}  // namespace relief::cli
