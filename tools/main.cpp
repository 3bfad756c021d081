// relief: compress point clouds into queryable archives (Golla & Klein 2015).
#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <iostream>
#include <new>
#include <string>

#include "cli_common.h"
#include "commands.h"
#include "relief/types.h"

namespace {

constexpr const char* kUsage =
    "usage: relief <command> [options]\n"
    "\n"
    "Commands:\n"
    "  compress IN... -o OUT.relief      compress point files of any size into an archive\n"
    "  append ARCHIVE IN...              add point files to an archive\n"
    "  stream ARCHIVE                    compress points arriving on standard input\n"
    "  preview ARCHIVE -o VIEW.png       a quick-look image, top-down or oblique, of all or a box\n"
    "  query ARCHIVE --box B -o OUT      the points inside a box, at any level of detail\n"
    "  decompress ARCHIVE -o OUT         every point of an archive\n"
    "  info ARCHIVE [--json]             what an archive holds\n"
    "  stats ARCHIVE [--box B] [--json]  what its points hold: ranges, classes, returns ...\n"
    "  check ARCHIVE                     verify a whole archive and list what is damaged\n"
    "  merge SHARD... -o OUT.relief      join the shard archives of a sharded build\n"
    "  shard-plan IN... -o PLAN          sharded build, stage 0: fix every parameter\n"
    "  shard-partition PLAN --input I --dir DIR    stage 1: one input into key-range files\n"
    "  shard-encode PLAN --range R --dir DIR -o SHARD    stage 2: one key range into a shard\n"
    "  roundtrip IN.ply          compress one file as a chunk, decompress it, print size and error\n"
    "  encode-chunk IN.ply -o OUT.rlfc   compress a point file into one chunk blob\n"
    "  decode-chunk IN.rlfc -o OUT.ply   decompress a chunk blob\n"
    "  eval ORIGINAL RECONSTRUCTED       error measures between two point files\n"
    "\n"
    "Run 'relief <command> --help' for the options of a command.\n";

// Runs the command. Out of memory on this thread unwinds (writers remove
// their temporary files, a new archive is removed) to a clear message.
int dispatch(const std::string& command, int sub_argc, char** sub_argv);

// A worker thread out of memory cannot unwind to main(): say so plainly
// rather than "terminate called after throwing ...", and exit with the
// limit code (its temporary files are left for the next run of that output
// to remove, as a killed run's are).
[[noreturn]] void on_terminate() {
  bool out_of_memory = false;
  if (const std::exception_ptr e = std::current_exception()) {
    try {
      std::rethrow_exception(e);
    } catch (const std::bad_alloc&) {
      out_of_memory = true;
    } catch (...) {
    }
  }
  if (out_of_memory) {
    std::fputs(
        "relief: out of memory: the process could not allocate what it needed (a lower --memory, fewer "
        "--threads, or a higher memory limit)\n",
        stderr);
    std::_Exit(16);
  }
  std::fputs("relief: internal error: an unexpected exception ended the process\n", stderr);
  std::_Exit(17);
}

}  // namespace

int main(int argc, char** argv) {
  relief::retain_freed_memory();
  // A file-size limit (ulimit -f) makes a write fail with EFBIG, reported
  // like a full disk (exit 12, nothing half-written kept), instead of
  // killing the process with SIGXFSZ.
  std::signal(SIGXFSZ, SIG_IGN);
  std::set_terminate(on_terminate);
  if (argc < 2 || std::strcmp(argv[1], "--help") == 0 || std::strcmp(argv[1], "-h") == 0 ||
      std::strcmp(argv[1], "help") == 0) {
    std::cout << kUsage;
    return argc < 2 ? relief::cli::kExitUsage : relief::cli::kExitOk;
  }
  if (std::strcmp(argv[1], "--version") == 0) {
    std::cout << "relief " << RELIEF_VERSION << " (chunk format " << relief::kChunkFormatVersion << ")\n";
    return 0;
  }
  const std::string command = argv[1];
  int rc = 0;
  try {
    rc = dispatch(command, argc - 2, argv + 2);
  } catch (const std::bad_alloc&) {
    std::cerr << "relief " << command
              << ": out of memory: the process could not allocate what it needed (a lower --memory, fewer "
                 "--threads, or a higher memory limit)\n";
    return 16;
  }
  // Output that never arrived is a failure, not success: stdout on a full
  // disk or a closed pipe.
  const bool flushed = std::fflush(stdout) == 0 && std::ferror(stdout) == 0 && std::cout.flush();
  if (!flushed && rc == relief::cli::kExitOk) {
    std::cerr << "relief " << command << ": standard output: write failed (" << std::strerror(errno) << ")\n";
    return relief::cli::exit_code_for(relief::io_error("standard output"));
  }
  return rc;
}

namespace {

int dispatch(const std::string& command, int sub_argc, char** sub_argv) {
  if (command == "compress") return relief::cli::run_compress(sub_argc, sub_argv);
  if (command == "append") return relief::cli::run_append(sub_argc, sub_argv);
  if (command == "stream") return relief::cli::run_stream(sub_argc, sub_argv);
  if (command == "preview") return relief::cli::run_preview(sub_argc, sub_argv);
  if (command == "query") return relief::cli::run_query(sub_argc, sub_argv);
  if (command == "decompress") return relief::cli::run_decompress(sub_argc, sub_argv);
  if (command == "info") return relief::cli::run_info(sub_argc, sub_argv);
  if (command == "stats") return relief::cli::run_stats(sub_argc, sub_argv);
  if (command == "check") return relief::cli::run_check(sub_argc, sub_argv);
  if (command == "merge") return relief::cli::run_merge(sub_argc, sub_argv);
  if (command == "shard-plan") return relief::cli::run_shard_plan(sub_argc, sub_argv);
  if (command == "shard-partition") return relief::cli::run_shard_partition(sub_argc, sub_argv);
  if (command == "shard-encode") return relief::cli::run_shard_encode(sub_argc, sub_argv);
  if (command == "roundtrip") return relief::cli::run_roundtrip(sub_argc, sub_argv);
  if (command == "encode-chunk") return relief::cli::run_encode_chunk(sub_argc, sub_argv);
  if (command == "decode-chunk") return relief::cli::run_decode_chunk(sub_argc, sub_argv);
  if (command == "eval") return relief::cli::run_eval(sub_argc, sub_argv);
  std::cerr << "relief: unknown command '" << command << "'\nsee 'relief --help'\n";
  return relief::cli::kExitUsage;
}

}  // namespace
