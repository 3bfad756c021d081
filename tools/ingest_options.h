// Options and output shared by the ingest subcommands (compress, append, stream).
#pragma once

#include <string>
#include <vector>

#include "cli_common.h"
#include "relief/ingest.h"

namespace relief::cli {

extern const char* const kIngestOptionsHelp;
std::vector<std::string> ingest_option_names();
// Fills memory, threads, tmp dir, columns and creator; returns an error or "".
std::string parse_ingest_options(Args& args, IngestOptions& o);
// --mode, --tolerance, --color-tolerance (commands that create archives).
extern const char* const kModeOptionsHelp;
std::vector<std::string> mode_option_names();
std::string parse_mode_options(Args& args, IngestOptions& o);
void print_ingest_summary(const std::string& path, const IngestResult& r);
// The readers' warnings (IngestResult::warnings) on stderr, even with --quiet.
void print_ingest_warnings(const std::string& command, const IngestResult& r);

}  // namespace relief::cli
