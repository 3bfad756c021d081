// Options and output shared by the ingest subcommands (compress, append, stream).
#pragma once

#include <string>
#include <vector>

#include "cli_common.h"
#include "relief/ingest.h"

namespace relief::cli {

// Help for how inputs are given (compress, append, shard-plan).
extern const char* const kInputsHelp;
// The input paths of a command: its positional arguments from `first` on,
// then the lines of --input-list FILE. Sets `error` (a usage error) when
// there are none or the list cannot be read.
std::vector<std::string> command_inputs(Args& args, std::size_t first, std::string& error);

extern const char* const kIngestOptionsHelp;
// --mode, --tolerance, --color-tolerance (commands that create archives).
extern const char* const kModeOptionsHelp;
// The options and flags of `set` as the CLI spells them ("--tolerance").
std::vector<std::string> ingest_cli_options(IngestOptionSet set);
std::vector<std::string> ingest_cli_flags(IngestOptionSet set);
// Fills `o` from args through relief::apply_ingest_options (the parser the
// Python bindings use too) and sets the creator; returns an error or "".
std::string parse_ingest_options(Args& args, IngestOptionSet set, IngestOptions& o);
void print_ingest_summary(const std::string& path, const IngestResult& r);
// The readers' warnings (IngestResult::warnings) on stderr, even with --quiet.
void print_ingest_warnings(const std::string& command, const IngestResult& r);

}  // namespace relief::cli
