// relief check ARCHIVE: verifies a whole archive and lists what is damaged.
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <system_error>

#include "cli_common.h"
#include "commands.h"
#include "relief/archive.h"
#include "relief/query.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "check";
constexpr const char* kUsageText =
    "usage: relief check ARCHIVE [--fold-log] [--quiet]\n"
    "Verifies the whole archive without trusting any part of it: SQLite's integrity check, the\n"
    "metadata and CRS checksums, every chunk blob's CRC-32, and the spatial index against the\n"
    "chunk table. Prints what it checked and every damage found. Exit 0 when intact, 14 when\n"
    "damaged.\n\n"
    "  --quiet      no progress line on the terminal while it reads\n"
    "  --fold-log   first fold a write-ahead log left beside the archive (ARCHIVE-wal, kept when\n"
    "               the disk filled up as a writer finished) into the file, so that the archive\n"
    "               is one file again; needs write access and room on the disk\n";

}  // namespace

int run_check(int argc, char** argv) {
  Args args(argc, argv, {"--help", "--fold-log", "--quiet"}, {});
  if (args.has("--help")) {
    std::cout << kUsageText;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one ARCHIVE");
  const std::string& path = args.positional()[0];
  const std::string wal = path + "-wal";
  std::error_code ec;
  const bool had_log = std::filesystem::file_size(wal, ec) > 0 && !ec;
  if (args.has("--fold-log")) {
    // A writer's open and close: SQLite folds the log into the file.
    auto writer = Archive::open(path, Archive::Mode::kReadWrite);
    if (!writer) return fail(kCommand, writer.status());
    if (Status closed = (*writer)->close(); !closed) return fail(kCommand, closed);
  }
  const Result<ArchiveCheck> result =
      check_archive(path, check_progress_printer(path, args.has("--quiet")), chunk_row_check());
  end_progress_line();
  if (!result) return fail(kCommand, result.status());
  std::printf("archive   %s (format version %d)\n", path.c_str(), result->format_version);
  if (args.has("--fold-log") && had_log) std::printf("folded    the write-ahead log %s into the file\n", wal.c_str());
  if (std::filesystem::file_size(wal, ec) > 0 && !ec) {
    std::printf("note      %s holds writes not yet in the file: keep it beside the archive (a writer, or "
                "'relief check --fold-log', folds it in)\n",
                wal.c_str());
  }
  for (const std::string& line : result->checked) std::printf("checked   %s\n", line.c_str());
  for (const std::string& line : result->problems) std::printf("DAMAGED   %s\n", line.c_str());
  if (result->problems.empty()) {
    std::printf("result    intact\n");
    return kExitOk;
  }
  std::printf("result    damaged (%zu finding%s)\n", result->problems.size(),
              result->problems.size() == 1 ? "" : "s");
  // The same code as any corrupt-data error (README "Exit codes").
  return exit_code_for(Status(StatusCode::kCorruptData, "damaged"));
}

}  // namespace relief::cli
