// relief query ARCHIVE --box ... -o OUT: the points inside a box.
#include <iostream>

#include "box_arg.h"
#include "cli_common.h"
#include "commands.h"
#include "query_output.h"

namespace relief::cli {

namespace {
constexpr const char* kCommand = "query";
constexpr const char* kUsageText =
    "usage: relief query ARCHIVE --box xmin,ymin,zmin,xmax,ymax,zmax [--lod L | --max-points N] [--class "
    "C,...]\n"
    "                    [--first-returns] [--last-returns] [--attributes LIST] [--polygon AREA "
    "[--polygon-crs CRS]] -o OUT\n"
    "Writes the archive's points inside the box (faces included, to the rounding of decoded coordinates)\n"
    "and the polygon, when given (then --box is optional). Only the chunks they touch are read and decoded.\n"
    "  --box B          6 numbers, or 4 (xmin,ymin,xmax,ymax) for all heights\n"
    "  --lod L          level of detail: a spatially uniform ~1/L of the points (1..1024, default 1);\n"
    "                   read from the archive's pyramid where it has one\n"
    "  --max-points N   at most N points: the finest level of detail of the pyramid whose nodes in the\n"
    "                   box hold at most N by their bounds' share of it (or the next finer level,\n"
    "                   when it holds at most 4N and the fitting one under N/2); when they hold\n"
    "                   more, every node keeps its share of N, evenly spread: a spatially uniform\n"
    "                   subset)\n"
    "  -o OUT           .las, .laz, .ply or .xyz/.txt/.csv; '-' writes XYZ text to stdout\n"
    "  --skip-corrupt   report damaged chunks and go on instead of failing\n"
    "  --threads N      decoder threads, and LAZ output's compressing threads (up to 4)\n"
    "                   (default: all cores)\n"
    "  --quiet          no summary on stderr\n";
}  // namespace

int run_query(int argc, char** argv) {
  Args args(argc, argv, {"--help", "--quiet", "--skip-corrupt", "--first-returns", "--last-returns"}, {"--box", "--lod", "--max-points", "-o", "--threads", "--class", "--attributes", "--polygon", "--polygon-crs"});
  if (args.has("--help")) {
    std::cout << kUsageText << kQueryFilterHelp;
    return kExitOk;
  }
  const QueryOptions q = query_options_from(args, kCommand);
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one ARCHIVE");
  const auto box_text = args.get("--box");
  if (!box_text && !q.polygon) return usage_error(kCommand, "missing --box (or --polygon)");
  Box3d box;
  std::string error;
  if (box_text && !parse_box(*box_text, box, error)) return usage_error(kCommand, "--box: " + error);
  const auto out = args.get("-o");
  if (!out) return usage_error(kCommand, "missing -o OUT");
  return run_query_to_file(kCommand, args.positional()[0], box_text ? &box : nullptr, *out, q, args.has("--quiet"));
}

}  // namespace relief::cli
