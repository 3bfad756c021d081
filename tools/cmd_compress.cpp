// relief compress IN... -o OUT.relief: out-of-core ingest into a new archive.
#include <sys/stat.h>

#include <cstdio>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "ingest_options.h"
#include "relief/ingest.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "compress";

}  // namespace

int run_compress(int argc, char** argv) {
  static const std::string usage = std::string(
      "usage: relief compress IN... -o OUT.relief [--chunk-edge METRES] [options]\n"
      "Compresses point files (PLY, LAS 1.0-1.4, XYZ/CSV, PCD) of any size into a new archive.\n"
      "  --chunk-edge M         edge of the archive's chunks (default 32 cells; bounded mode: an\n"
      "                         input of at most 2^20 points that fits in 4 x that is one chunk)\n"
      "  --error-target M       resample mode: choose the cell size for this RMSE_SNN (by trial\n"
      "                         encodes of the first points; overrides --cell; implies --mode resample)\n"
      "  --allow-sparse         go ahead although the cell or chunk edge puts on average fewer than\n"
      "                         2 points in a cell or 16 in a chunk (refused by default: exit 16)\n"
      "  --assume-crs           inputs with different CRSs: take the first input's for all (with a\n"
      "                         warning) instead of refusing them (exit 11)\n"
      "  --crs CRS              the inputs' CRS (EPSG:32633, WKT, PROJJSON): for XYZ, PLY, PCD or LAS\n"
      "                         inputs that name none; one an input names otherwise is replaced (with a\n"
      "                         warning; coordinates are not converted)\n"
      "  --no-extra-bytes       drop every input's extra bytes: LAS/LAZ extra bytes and the PLY\n"
      "                         properties and PCD fields kept as such (normals, labels ...)\n"
      "  --attributes LIST      keep only these attributes beside x y z, as 'relief info' lists them\n"
      "                         (rgb, intensity, classification, gps_time, extra_bytes ...; none; default\n"
      "                         all): a smaller archive when the others are not needed\n"
      "  --no-spool             read LAZ and text inputs twice (the pass that fixes the grid, then\n"
      "                         the ingest) instead of keeping their decoded points in temporary\n"
      "                         files under --tmp (28-56 bytes a point, freed as the ingest reads)\n\n") +
      kInputsHelp + "\n" + kModeOptionsHelp + "\n" + kIngestOptionsHelp + "\n" + kEncodeOptionsHelp;
  std::vector<std::string> options = ingest_cli_options(IngestOptionSet::kCompress);
  options.insert(options.end(), {"-o", "--input-list"});
  std::vector<std::string> flags = ingest_cli_flags(IngestOptionSet::kCompress);
  flags.insert(flags.end(), {"--help", "--quiet"});
  Args args(argc, argv, flags, options);
  if (args.has("--help")) {
    std::cout << usage;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  std::string input_error;
  const std::vector<std::string> inputs = command_inputs(args, 0, input_error);
  if (!input_error.empty()) return usage_error(kCommand, input_error);
  const auto out = args.get("-o");
  if (!out) return usage_error(kCommand, "missing -o OUT.relief");
  IngestOptions o;
  if (const std::string err = parse_ingest_options(args, IngestOptionSet::kCompress, o); !err.empty()) {
    return usage_error(kCommand, err);
  }
  const bool quiet = args.has("--quiet");
  o.progress = progress_printer(quiet);
  o.cancel = install_interrupt_flag();
  auto r = compress_files(inputs, *out, o);
  end_progress_line();
  if (!r) {
    if (o.cancel->load()) {
      // Stopped in the pass that fixes the grid, or before the scan began,
      // there is no archive.
      struct stat st {};
      return ::stat(out->c_str(), &st) != 0
                 ? interrupted(kCommand, " before anything was committed; " + *out + " not written")
                 : interrupted(kCommand,
                               "; " + *out + " keeps the chunks committed so far (an incomplete scan)");
    }
    return fail(kCommand, r.status());
  }
  print_ingest_warnings(kCommand, *r);
  if (!quiet) print_ingest_summary(*out, *r);
  return kExitOk;
}

}  // namespace relief::cli
