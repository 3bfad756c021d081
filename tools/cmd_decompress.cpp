// relief decompress ARCHIVE -o OUT: every point of an archive.
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "query_output.h"

namespace relief::cli {

int run_decompress(int argc, char** argv) {
  constexpr const char* kUsage =
      "usage: relief decompress ARCHIVE -o OUT [--lod L] [--class C,...] [--first-returns] [--last-returns]\n"
      "                         [--attributes LIST] [--skip-corrupt] [--threads N] [--quiet]\n"
      "Writes every point of the archive (.las, .laz, .ply, .xyz/.txt/.csv; '-' = XYZ text on stdout).\n";
  Args args(argc, argv, {"--help", "--quiet", "--skip-corrupt", "--first-returns", "--last-returns"}, {"--lod", "-o", "--threads", "--class", "--attributes", "--polygon", "--polygon-crs"});
  if (args.has("--help")) {
    std::cout << kUsage << kQueryFilterHelp;
    return kExitOk;
  }
  const QueryOptions q = query_options_from(args, "decompress");
  if (!args.ok()) return usage_error("decompress", args.error());
  if (args.positional().size() != 1) return usage_error("decompress", "expected one ARCHIVE");
  const auto out = args.get("-o");
  if (!out) return usage_error("decompress", "missing -o OUT");
  return run_query_to_file("decompress", args.positional()[0], nullptr, *out, q, args.has("--quiet"));
}

}  // namespace relief::cli
