// relief stats ARCHIVE [--box B] [--attributes LIST] [--json]: what the
// points hold, attribute by attribute (lasinfo's summary for an archive).
#include <cstdio>
#include <iostream>
#include <iterator>
#include <string>

#include "box_arg.h"
#include "cli_common.h"
#include "commands.h"
#include "query_output.h"
#include "relief/query.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "stats";
constexpr const char* kUsageText =
    "usage: relief stats ARCHIVE|POINT_FILE [--box B] [--polygon AREA [--polygon-crs CRS]] [--attributes LIST] [--json]\n"
    "Decodes the points (of a box) and prints, per attribute, the range and mean of its values or\n"
    "the count of each value: x, y, z, colours, intensity, classification, flags, returns, scan\n"
    "angle, user data, point source IDs, GPS time, NIR and each scalar extra bytes field.\n"
    "A point file (.las, .laz, .ply, .xyz/.txt/.csv/.pts, .pcd, .ptx, .e57) is summarised the same way, so an\n"
    "archive can be checked against its source (without --box or filters).\n"
    "  --box B          6 numbers, or 4 (xmin,ymin,xmax,ymax) for all heights (default: everything)\n"
    "  --polygon AREA   only the points inside this x-y area (WKT or GeoJSON, or @FILE of WKT,\n"
    "                   GeoJSON or a .shp), as 'relief query --polygon'\n"
    "  --polygon-crs CRS   the CRS of the area's coordinates, as 'relief query --polygon-crs'\n"
    "  --attributes L   only these (as 'relief info' lists them; default all): only they are decoded,\n"
    "                   so e.g. '--attributes classification' takes a fraction of a full decode\n"

    "  --json           one JSON object instead of text\n"
    "  --threads N      decoder threads (default: all cores)\n"
    "  --skip-corrupt   report damaged chunks and go on instead of failing\n"
    "  --quiet          no progress line on the terminal\n";

std::string grouped(std::uint64_t v) {
  std::string digits = std::to_string(v), out;
  for (std::size_t i = 0; i < digits.size(); ++i) {
    if (i > 0 && (digits.size() - i) % 3 == 0) out += ',';
    out += digits[i];
  }
  return out;
}

void print_range(const char* name, const ValueSummary& v, const char* format, const char* unit = "") {
  if (v.count == 0) {
    std::printf("%-20s (none)\n", name);
    return;
  }
  char lo[64], hi[64], mean[64];
  std::snprintf(lo, sizeof lo, format, v.min);
  std::snprintf(hi, sizeof hi, format, v.max);
  std::snprintf(mean, sizeof mean, format, v.mean());
  std::printf("%-20s %s .. %s%s, mean %s", name, lo, hi, unit, mean);
  if (v.non_finite > 0) std::printf(", %s not finite", grouped(v.non_finite).c_str());
  std::printf("\n");
}

template <std::size_t N>
void print_histogram(const char* name, const std::array<std::uint64_t, N>& h, std::uint64_t points) {
  std::printf("%-20s", name);
  bool any = false;
  for (std::size_t k = 0; k < N; ++k) {
    if (h[k] == 0) continue;
    std::printf("%s%zu: %s (%.2f %%)", any ? ", " : " ", k, grouped(h[k]).c_str(),
                points > 0 ? 100.0 * static_cast<double>(h[k]) / static_cast<double>(points) : 0.0);
    any = true;
  }
  std::printf("%s\n", any ? "" : " (none)");
}

// ASPRS LAS 1.4 R15 Table 17: the standard classes (19-63 reserved, 64-255 user definable).
const char* class_name(std::size_t c) {
  constexpr const char* kNames[] = {"never classified", "unclassified", "ground", "low vegetation",
                                    "medium vegetation", "high vegetation", "building", "low point (noise)",
                                    "reserved", "water", "rail", "road surface", "reserved",
                                    "wire - guard (shield)", "wire - conductor (phase)", "transmission tower",
                                    "wire-structure connector", "bridge deck", "high noise"};
  if (c < std::size(kNames)) return kNames[c];
  return c < 64 ? "reserved" : "user defined";
}

// One line per class present: value, ASPRS name, count, share.
void print_classes(const std::array<std::uint64_t, 256>& h, std::uint64_t points) {
  bool any = false;
  for (std::size_t k = 0; k < h.size(); ++k) {
    if (h[k] == 0) continue;
    std::printf("%-20s %3zu %-26s %15s (%.2f %%)\n", any ? "" : "classification", k, class_name(k),
                grouped(h[k]).c_str(),
                points > 0 ? 100.0 * static_cast<double>(h[k]) / static_cast<double>(points) : 0.0);
    any = true;
  }
  if (!any) std::printf("%-20s (none)\n", "classification");
}

void print_count(const char* name, std::uint64_t n, std::uint64_t points) {
  std::printf("%-20s %s (%.2f %%)\n", name, grouped(n).c_str(),
              points > 0 ? 100.0 * static_cast<double>(n) / static_cast<double>(points) : 0.0);
}

void print_text(const ArchiveStats& s) {
  std::printf("%-20s %s\n", "points", grouped(s.points).c_str());
  print_range("x", s.x, "%.6f");
  print_range("y", s.y, "%.6f");
  print_range("z", s.z, "%.6f");
  if (s.has_colors) {
    print_range("red", s.red, "%.0f");
    print_range("green", s.green, "%.0f");
    print_range("blue", s.blue, "%.0f");
  }
  if (s.has_intensity) print_range("intensity", s.intensity, "%.6g");
  const auto has = [&](std::uint32_t bit) { return (s.las & bit) != 0; };
  if (has(kLasClassification)) print_classes(s.classification, s.points);
  if (has(kLasClassFlags)) {
    print_count("synthetic", s.synthetic, s.points);
    print_count("key_point", s.key_point, s.points);
    print_count("withheld", s.withheld, s.points);
    print_count("overlap", s.overlap, s.points);
  }
  if (has(kLasReturnNumber)) print_histogram("return_number", s.return_number, s.points);
  if (has(kLasNumberOfReturns)) print_histogram("number_of_returns", s.number_of_returns, s.points);
  if (has(kLasScanFlags)) {
    print_count("scan_direction_flag", s.scan_direction, s.points);
    print_count("edge_of_flight_line", s.edge_of_flight_line, s.points);
    print_histogram("scanner_channel", s.scanner_channel, s.points);
  }
  if (has(kLasScanAngle)) print_range("scan_angle", s.scan_angle, "%.3f", " degrees");
  if (has(kLasUserData)) print_range("user_data", s.user_data, "%.0f");
  if (has(kLasPointSourceId)) {
    print_range("point_source_id", s.point_source_id, "%.0f");
    std::printf("%-20s %s\n", "point sources", grouped(s.point_sources).c_str());
  }
  if (has(kLasGpsTime)) print_range("gps_time", s.gps_time, "%.6f");
  if (has(kLasNir)) print_range("nir", s.nir, "%.0f");
  for (const auto& [name, v] : s.extra) print_range(("extra " + name).c_str(), v, "%.10g");
}

}  // namespace

int run_stats(int argc, char** argv) {
  Args args(argc, argv, {"--help", "--json", "--quiet", "--skip-corrupt", "--first-returns", "--last-returns"},
            {"--box", "--attributes", "--threads", "--class", "--polygon", "--polygon-crs"});
  if (args.has("--help")) {
    std::cout << kUsageText << kQueryFilterHelp;
    return kExitOk;
  }
  const QueryOptions q = query_options_from(args, kCommand);
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one ARCHIVE");
  Box3d box;
  const auto box_text = args.get("--box");
  std::string error;
  if (box_text && !parse_box(*box_text, box, error)) return usage_error(kCommand, "--box: " + error);
  const std::string& path = args.positional()[0];
  Result<ArchiveStats> stats = Status(internal_error("stats did not run"));
  if (is_point_file_name(path)) {
    if (box_text || q.polygon || !q.classes.empty() || q.first_returns || q.last_returns) {
      return usage_error(kCommand, "--box, --polygon and the LAS filters apply to archives, not to a point file");
    }
    ReaderOptions ro;
    ro.attributes = q.attributes;
    QueryProgress progress(path, 0, args.has("--quiet"));
    stats = point_file_stats(path, ro, [&](std::uint64_t n) { progress.count(n); });
    end_progress_line();
  } else {
    auto reader = ArchiveReader::open(path);
    if (!reader) return fail(kCommand, reader.status());
    // A progress line on a terminal (stderr), the share known for a whole archive unfiltered.
    const bool whole = !box_text && !q.polygon && q.classes.empty() && !q.first_returns && !q.last_returns;
    QueryProgress progress(path, whole ? (*reader)->info().decoded_points : 0, args.has("--quiet"));
    stats = archive_stats(**reader, box_text ? &box : nullptr, q, [&](std::uint64_t n) { progress.count(n); });
    end_progress_line();
  }
  if (!stats) return fail(kCommand, stats.status());
  if (args.has("--json")) {
    std::fputs(archive_stats_json(*stats).c_str(), stdout);
  } else {
    print_text(*stats);
  }
  return kExitOk;
}

}  // namespace relief::cli
