// Shared by `relief query` and `relief decompress`: stream a query into a
// point writer and report.
#pragma once

#include <string>

#include "cli_common.h"
#include "relief/query.h"

namespace relief::cli {

// Query options from --lod, --threads and --skip-corrupt (malformed values are
// recorded in `args`); warnings go to stderr prefixed "relief COMMAND: ".
QueryOptions query_options_from(Args& args, const std::string& command);

// Runs `box` (or everything when `all`) against the archive at `archive_path`
// into `out_path`. Returns the process exit code; prints errors and, unless
// quiet, a summary.
int run_query_to_file(const std::string& command, const std::string& archive_path, const Box3d* box,
                      const std::string& out_path, const QueryOptions& options, bool quiet);

}  // namespace relief::cli
