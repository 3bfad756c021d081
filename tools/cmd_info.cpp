// relief info ARCHIVE [--json]: what an archive holds.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <optional>
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
    "usage: relief info ARCHIVE [--json] [--sections [--quiet]]\n"
    "Prints the format version, points, chunks, bounds, grid, codec parameters, size on disk,\n"
    "bits per point, attributes, CRS, sources and scans of an archive.\n"
    "  --sections   also where the bytes go: each chunk section (geometry, rgb, gps_time, the\n"
    "               maps ...) summed over the chunks, the blobs' framing, the pyramid and\n"
    "               SQLite's share; reads each blob's header and section table (relief check\n"
    "               verifies the blobs)\n"
    "  --quiet      no progress line on the terminal while --sections reads\n";

std::string crs_text(const std::string& crs) {
  if (crs.empty()) return "(none)";
  Result<CrsSummary> s = describe_crs(crs, "archive CRS");
  if (!s) return crs;
  return s->name + (s->epsg ? " (EPSG:" + std::to_string(*s->epsg) + ")" : " (no EPSG code)");
}

std::string attributes(const ArchiveInfo& i) {
  std::string a;
  for (const std::string& name : archive_attribute_names(i)) a += (a.empty() ? "" : ",") + name;
  return a.empty() ? "none" : a;
}

std::string las_text(const ArchiveInfo& i) {
  // Attributes from non-LAS inputs only (a PLY's extra properties, a CSV's
  // classification) have no LAS version; the format is the one LAS output uses.
  std::string out = "point format " + std::to_string(i.las_point_format) +
                    (i.las_version_minor >= 0 ? ", LAS 1." + std::to_string(i.las_version_minor)
                                              : " (for LAS output; no LAS input)");
  if (i.las_gps_time_type != GpsTimeType::kUnknown) {
    out += std::string(", GPS ") + gps_time_type_name(i.las_gps_time_type) + " time";
  }
  if ((i.las_attributes & kLasColorLow) != 0) {
    out += i.las_colors_8bit ? ", 8-bit colour levels in 16-bit fields" : ", 16-bit colour levels";
  }
  if (i.extra_bytes_size > 0) {
    out += ", " + std::to_string(i.extra_bytes_size) + " extra bytes";
    const std::vector<ExtraBytesField> fields = archive_extra_bytes_fields(i);
    for (std::size_t k = 0; k < fields.size(); ++k) {
      out += (k == 0 ? ": " : ", ") + fields[k].name + " (" + fields[k].type_name + ")";
    }
  }
  return out;
}

// One line per part of the file: bytes, share of the file, bits per input point.
void print_sections(const ArchiveSections& s) {
  const auto line = [&s](const std::string& name, std::uint64_t bytes, const std::string& note) {
    const double share = s.file_bytes > 0 ? 100.0 * static_cast<double>(bytes) / static_cast<double>(s.file_bytes) : 0.0;
    const double bpp =
        s.input_points > 0 ? 8.0 * static_cast<double>(bytes) / static_cast<double>(s.input_points) : 0.0;
    std::printf("  %-20s %14llu  %5.1f %%  %8.3f%s%s\n", name.c_str(), static_cast<unsigned long long>(bytes), share,
                bpp, note.empty() ? "" : "  ", note.c_str());
  };
  std::printf("sections        bytes, share of the file, bits per input point (%llu chunk%s read)\n",
              static_cast<unsigned long long>(s.chunks), s.chunks == 1 ? "" : "s");
  bool maps = false;
  for (const SectionTotal& t : s.sections) {
    if (!t.maps) line(t.name, t.bytes, "");
    maps = maps || t.maps;
  }
  if (maps) std::printf("  maps (the paper's layer; the base layer of error-bounded chunks):\n");
  for (const SectionTotal& t : s.sections) {
    if (t.maps) line("  " + t.name, t.bytes, "");
  }
  line("blob framing", s.framing_bytes, "headers, section tables, checksums");
  if (s.pyramid_chunks > 0) {
    line("pyramid", s.pyramid_bytes, std::to_string(s.pyramid_chunks) + " nodes of the level-of-detail pyramid");
  }
  line("sqlite", s.container_bytes(), "pages, indexes, metadata, scans and sources");
  line("file", s.file_bytes, "");
}

}  // namespace

int run_info(int argc, char** argv) {
  Args args(argc, argv, {"--help", "--json", "--sections", "--quiet"}, {});
  if (args.has("--help")) {
    std::cout << kUsageText;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one ARCHIVE");
  const std::string& path = args.positional()[0];
  auto reader = ArchiveReader::open(path);
  if (!reader) return fail(kCommand, reader.status());
  const ArchiveInfo& i = (*reader)->info();
  std::optional<ArchiveSections> sections;
  if (args.has("--sections")) {
    auto archive = Archive::open(path, Archive::Mode::kReadOnly);
    if (!archive) return fail(kCommand, archive.status());
    QueryProgress progress(path, i.input_points, args.has("--quiet"));
    auto s = archive_sections(**archive, [&](std::uint64_t n) { progress.count(n); });
    end_progress_line();
    if (!s) return fail(kCommand, s.status());
    sections = std::move(*s);
  }
  const double bpp = i.input_points > 0 ? 8.0 * static_cast<double>(i.file_bytes) / static_cast<double>(i.input_points) : 0.0;
  const double blob_bpp =
      i.input_points > 0 ? 8.0 * static_cast<double>(i.blob_bytes) / static_cast<double>(i.input_points) : 0.0;
  if (args.has("--json")) {
    std::string json = archive_info_json(i, path);
    if (sections) {
      // One more member of the object: before its closing "}\n".
      json.resize(json.size() - 2);
      json += ",\n  \"sections\": " + archive_sections_json(*sections) + "\n}\n";
    }
    std::fputs(json.c_str(), stdout);
    return kExitOk;
  }
  std::printf("archive         %s\n", args.positional()[0].c_str());
  std::printf("format version  %d\n", i.format_version);
  std::printf("points          %llu in, %llu decodable\n", static_cast<unsigned long long>(i.input_points),
              static_cast<unsigned long long>(i.decoded_points));
  std::printf("chunks          %llu\n", static_cast<unsigned long long>(i.chunk_count));
  const auto print_box = [](const char* label, const Box3d& b) {
    std::printf("%-16s[%.6f, %.6f, %.6f] .. [%.6f, %.6f, %.6f]\n", label, b.min.x, b.min.y, b.min.z, b.max.x,
                b.max.y, b.max.z);
  };
  if (i.point_bounds.empty()) {
    std::printf("bounds          (empty)\n");
  } else {
    print_box("bounds", i.point_bounds);
    // Coarse levels of detail rebuild points from the maps, which may reach
    // beyond the points: what a preview or LOD query can return.
    if (i.bounds.min != i.point_bounds.min || i.bounds.max != i.point_bounds.max)
      print_box("lod bounds", i.bounds);
  }
  std::printf("grid            origin (%.6g, %.6g, %.6g), chunk edge %.6g\n", i.grid.origin.x, i.grid.origin.y,
              i.grid.origin.z, i.grid.chunk_edge);
  if (auto params = encode_params_from_string(i.codec_params); params && params->bound) {
    const ErrorBound& b = *params->bound;
    std::printf(
        "mode            bounded: every point within %.6g, %.6g, %.6g (x, y, z; grid step %.6g, %.6g, %.6g), "
        "colour %s, intensity %s%s%s\n",
        b.step.x / 2, b.step.y / 2, b.step.z / 2, b.step.x, b.step.y, b.step.z,
        b.color_tolerance == 0 ? "exact" : ("within " + std::to_string(b.color_tolerance)).c_str(),
        b.intensity_tolerance == 0 ? "exact" : ("within " + std::to_string(b.intensity_tolerance)).c_str(),
        b.keep_order ? "; each chunk's points in the order they were read" : "",
        b.fast_geometry ? "; octree geometry without plane and near classes (--fast-geometry)" : "");
  } else {
    std::printf("mode            resample: one point per occupied map pixel\n");
  }
  std::printf("codec           %s\n", full_params_text(i.codec_params).c_str());
  std::printf("size on disk    %s (%.3f bits/point; blobs %s = %.3f bits/point)\n", format_bytes(i.file_bytes).c_str(),
              bpp, format_bytes(i.blob_bytes).c_str(), blob_bpp);
  std::printf("attributes      %s\n", attributes(i).c_str());
  if (i.las_point_format >= 0) std::printf("las source      %s\n", las_text(i).c_str());
  std::printf("crs             %s\n", crs_text(i.crs).c_str());
  std::printf("creator         %s\n", i.creator.c_str());
  for (const ArchiveSource& s : i.sources) {
    std::printf("source          %s (%s, %llu points, scan %lld", s.path.c_str(), s.format.c_str(),
                static_cast<unsigned long long>(s.point_count), static_cast<long long>(s.scan_id));
    // The VLRs and extended VLRs LAS output gives back (the CRS and Extra
    // Bytes records are counted elsewhere: Relief writes those itself).
    if (!s.las.records.empty()) std::printf(", %zu LAS records kept", s.las.records.size());
    std::printf(")\n");
  }
  for (const ArchiveScan& s : i.scans) {
    std::printf("scan            %lld %s, %s\n", static_cast<long long>(s.id),
                s.complete ? "complete" : "INCOMPLETE (interrupted)", s.created_at.c_str());
    for (const ScanPyramid& p : i.pyramid) {
      if (p.scan_id != s.id || p.levels.empty()) continue;
      std::printf("pyramid         scan %lld:", static_cast<long long>(s.id));
      for (const PyramidLevel& l : p.levels) {
        std::printf(" L%d %llu pts/%llu nodes/%s%s", l.level, static_cast<unsigned long long>(l.points),
                    static_cast<unsigned long long>(l.chunks), format_bytes(l.blob_bytes).c_str(),
                    &l == &p.levels.back() ? "" : ",");
      }
      std::printf("\n");
    }
  }
  if (sections) print_sections(*sections);
  return kExitOk;
}

}  // namespace relief::cli
