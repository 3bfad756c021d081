// relief append ARCHIVE IN...: add point files to an existing archive.
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "ingest_options.h"
#include "relief/ingest.h"

namespace relief::cli {

int run_append(int argc, char** argv) {
  static const std::string usage =
      std::string(
          "usage: relief append ARCHIVE IN... [options]\n"
          "Adds point files to an existing archive with the archive's grid and codec parameters.\n"
          "If it fails, the archive is left as it was; Ctrl-C (exit 130) keeps the chunks committed so far,\n"
          "as an incomplete scan.\n"
          "  --assume-crs           inputs whose CRS differs from the archive's (or each other's):\n"
          "                         keep the archive's (with a warning) instead of refusing (exit 11)\n"
          "  --crs CRS              the new inputs' CRS, as 'relief compress --crs' (it must be the\n"
          "                         archive's, unless --assume-crs; an archive without one takes it)\n"
          "  --no-extra-bytes       drop the inputs' extra bytes (LAS/LAZ extra bytes, PLY properties\n"
          "                         and PCD fields beyond x y z, colour and intensity)\n"
          "  --attributes LIST      read only these attributes of the inputs (as compress): the\n"
          "                         archive's LAS attributes left out are 0 for the new points;\n"
          "                         its colours and intensity cannot be left out\n\n") +
      kInputsHelp + "\n" + kIngestOptionsHelp;
  std::vector<std::string> flags = ingest_cli_flags(IngestOptionSet::kAppend);
  flags.insert(flags.end(), {"--help", "--quiet"});
  std::vector<std::string> options = ingest_cli_options(IngestOptionSet::kAppend);
  options.push_back("--input-list");
  Args args(argc, argv, flags, options);
  if (args.has("--help")) {
    std::cout << usage;
    return kExitOk;
  }
  if (!args.ok()) return usage_error("append", args.error());
  if (args.positional().empty()) return usage_error("append", "expected ARCHIVE and at least one input");
  std::string input_error;
  const std::vector<std::string> inputs = command_inputs(args, 1, input_error);
  if (!input_error.empty()) return usage_error("append", input_error);
  IngestOptions o;
  if (const std::string err = parse_ingest_options(args, IngestOptionSet::kAppend, o); !err.empty()) {
    return usage_error("append", err);
  }
  const bool quiet = args.has("--quiet");
  o.progress = progress_printer(quiet);
  o.cancel = install_interrupt_flag();
  const std::string archive = args.positional()[0];
  auto r = append_files(archive, inputs, o);
  end_progress_line();
  if (!r) {
    if (o.cancel->load()) return interrupted("append", "; " + archive + " keeps the chunks committed so far");
    return fail("append", r.status());
  }
  print_ingest_warnings("append", *r);
  if (!quiet) print_ingest_summary(archive, *r);
  return kExitOk;
}

}  // namespace relief::cli
