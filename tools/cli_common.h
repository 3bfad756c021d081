// Shared pieces of the `relief` command-line tool: argument parsing, exit
// codes, file helpers. The CLI sees only the public headers.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "relief/codec.h"
#include "relief/archive.h"
#include "relief/ingest.h"
#include "relief/query.h"
#include "relief/status.h"

namespace relief::cli {

// Documented in README "Exit codes": 0 ok, 2 usage, 10 + StatusCode otherwise.
inline constexpr int kExitOk = 0;
inline constexpr int kExitUsage = 2;
int exit_code_for(const Status& status);

// Prints "relief <command>: <message>" to stderr and returns the exit code.
int fail(const std::string& command, const Status& status);
// Prints the error and a hint to see `relief <command> --help`; returns kExitUsage.
int usage_error(const std::string& command, const std::string& message);
// Ctrl-C (or SIGTERM) stopped the command: prints "relief <command>:
// interrupted<what>" (what is left, e.g. "; no plan written") and returns
// kExitInterrupted.
inline constexpr int kExitInterrupted = 130;  // 128 + SIGINT, as shells report it
int interrupted(const std::string& command, const std::string& what);
// A --memory SIZE value read and checked as compress reads it (the same rules
// and messages): the budget in bytes in `budget`, or the error message.
std::string memory_option(const std::string& text, std::uint64_t& budget);

// A tiny option parser: `--name value`, `--name=value`, `-o value`, flags and
// positionals; `--` ends the options (every later argument is positional).
// Unknown options are an error.
class Args {
 public:
  // `flags` take no value; `options` take one.
  Args(int argc, char** argv, std::vector<std::string> flags, std::vector<std::string> options);

  bool ok() const { return error_.empty(); }
  const std::string& error() const { return error_; }
  bool has(const std::string& name) const;
  std::optional<std::string> get(const std::string& name) const;
  const std::vector<std::string>& positional() const { return positional_; }

  // Typed getters; on a malformed value they record an error and return the default.
  double get_double(const std::string& name, double fallback);
  long long get_int(const std::string& name, long long fallback, long long lo, long long hi);
  // Records a malformed value found by the caller (the first error is kept).
  void add_error(const std::string& message) {
    if (error_.empty()) error_ = message;
  }

 private:
  std::map<std::string, std::string> values_;
  std::vector<std::string> positional_;
  std::string error_;
};

// --lod L is 1..kMaxLod (relief::kMaxQueryLod says why).
inline constexpr long long kMaxLod = kMaxQueryLod;

// Encoder options shared by encode-chunk and roundtrip.
extern const char* const kEncodeOptionsHelp;
std::vector<std::string> encode_option_names();
// encode-chunk and roundtrip: --tolerance T makes an error-bounded blob (every
// point back within T per coordinate, on a grid of step 2T from the origin),
// with --color-tolerance, --intensity-tolerance and the flag --keep-order.
extern const char* const kBoundOptionsHelp;
inline constexpr const char* kKeepOrderFlag = "--keep-order";
// relief::bound_option_names with dashes (the flag --keep-order apart).
std::vector<std::string> bound_option_names();
// relief::apply_bound_options: sets params.bound when --tolerance is given; "" or the error.
std::string parse_bound_options(Args& args, EncodeParams& params);
// Fills params from args (relief::apply_encode_options); returns an error message or "".
std::string parse_encode_params(Args& args, EncodeParams& params);
// "--" before each library option name (relief::ingest_option_names ...).
std::vector<std::string> cli_names(const std::vector<std::string>& names);
// The options among `names` (library spelling, no dashes) that args holds, for
// relief::apply_ingest_options; flags come with an empty value.
std::vector<NamedOption> given_options(const Args& args, const std::vector<std::string>& names);

// kInvalidArgument naming `path`, the point and the value when a coordinate of
// `cloud` exceeds kMaxCoordinateMagnitude (2^50): a single chunk (encode-chunk,
// roundtrip) has no archive grid, so only the absolute limit applies.
Status check_chunk_coordinates(const PointCloud& cloud, const std::string& path);

Result<std::vector<std::uint8_t>> read_file(const std::string& path);

// Writes a decoded cloud with every attribute it holds (colours with their
// low bytes, intensity, LAS attributes, extra bytes) through the streaming
// writer: PLY, or LAS/LAZ/XYZ/CSV by `path`'s extension (decode-chunk,
// roundtrip; the whole-cloud write_ply keeps colour and intensity alone).
// The writer's warnings go to stderr as `command`'s.
Status write_decoded_cloud(const char* command, const std::string& path, const PointCloud& cloud,
                           bool ascii_ply = false);

double seconds_since(std::int64_t start_ns);
std::int64_t now_ns();

// "1G", "512M", "64K" (binary units) or a plain number of MiB; 0 on error.
std::uint64_t parse_size(const std::string& text);

// Ctrl-C sets the returned flag instead of killing the process (a second
// Ctrl-C kills it). Blocking reads are interrupted (no SA_RESTART).
const std::atomic<bool>* install_interrupt_flag();

// A progress line on stderr, redrawn in place; prints nothing unless stderr
// is a terminal and `quiet` is false.
std::function<void(const IngestProgress&)> progress_printer(bool quiet);
// Ends the progress line (newline) if one was drawn.
void end_progress_line();
// A progress line for `relief check` on a terminal (nothing when `quiet` or
// stderr is not one): "ARCHIVE: chunk blobs 120/5000 (2%), 3 s",
// redrawn at most 4 times a second and at each new stage.
CheckProgress check_progress_printer(const std::string& archive, bool quiet);
// A progress line for queries and decompression on a terminal (nothing
// when `quiet` or stderr is not one): count(points) after each batch
// redraws "OUT: 12.34M points (41%), 3.20 M points/s, 4 s" at most 4 times
// a second; `total` is the points expected, 0 when not known.
class QueryProgress {
 public:
  QueryProgress(std::string out, std::uint64_t total, bool quiet);
  void count(std::uint64_t points);

 private:
  std::string out_;
  std::uint64_t total_;
  bool on_;
  std::uint64_t points_ = 0;
  std::int64_t start_ns_;
  std::int64_t drawn_ns_ = 0;
};

// Human-readable byte count: "12.3 MB".
std::string format_bytes(std::uint64_t bytes);

}  // namespace relief::cli
