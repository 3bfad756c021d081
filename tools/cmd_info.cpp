// relief info ARCHIVE [--json]: what an archive holds.
#include <cmath>
#include <cstdio>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "relief/codec.h"
#include "relief/query.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "info";
constexpr const char* kUsageText =
    "usage: relief info ARCHIVE [--json]\n"
    "Prints the format version, points, chunks, bounds, grid, codec parameters, size on disk,\n"
    "bits per point, attributes, CRS, sources and scans of an archive.\n";

std::string json_string(const std::string& s) {
  std::string out = "\"";
  for (const char c : s) {
    switch (c) {
      case '"': out += "\\\""; break;
      case '\\': out += "\\\\"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      case '\t': out += "\\t"; break;
      default:
        if (static_cast<unsigned char>(c) < 0x20) {
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

std::string attributes(const ArchiveInfo& i) {
  std::string a;
  if (i.has_colors) a += "rgb";
  if (i.has_intensity) a += a.empty() ? "intensity" : ",intensity";
  return a.empty() ? "none" : a;
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
    std::printf("  \"codec_params\": %s,\n", json_string(i.codec_params).c_str());
    std::printf("  \"file_bytes\": %llu,\n", static_cast<unsigned long long>(i.file_bytes));
    std::printf("  \"blob_bytes\": %llu,\n", static_cast<unsigned long long>(i.blob_bytes));
    std::printf("  \"bits_per_point\": %s,\n", json_number(bpp).c_str());
    std::printf("  \"attributes\": %s,\n", json_string(attributes(i)).c_str());
    std::printf("  \"crs\": %s,\n", json_string(i.crs).c_str());
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
  std::printf("crs             %s\n", i.crs.empty() ? "(none)" : i.crs.c_str());
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
