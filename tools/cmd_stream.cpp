// relief stream ARCHIVE: compress points arriving on standard input.
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "ingest_options.h"
#include "relief/ingest.h"
#include "relief/io.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "stream";
constexpr std::size_t kReadBlock = 1 << 16;

struct Layout {
  bool colors = false;
  bool intensity = false;
  std::uint32_t las = 0;  // LasAttributeBits the columns or fields fill
  // Text: the columns of --columns; binary: the fields of --attributes.
  std::unique_ptr<TextLineParser> text;
  std::unique_ptr<BinaryRecordParser> binary;
  // Binary: the extra bytes fields' Extra Bytes VLR and size (none in text).
  std::string extra_bytes_vlr;
  std::uint32_t extra_bytes_size = 0;
};

// Reads standard input in blocks; interrupted reads end the stream.
class StdinBlocks {
 public:
  // Appends what is available to `buf`; false at EOF or interruption.
  bool more(std::string& buf, const std::atomic<bool>* interrupted) {
    char block[kReadBlock];
    for (;;) {
      if (interrupted->load()) return false;
      const ssize_t n = ::read(STDIN_FILENO, block, sizeof block);
      if (n > 0) {
        buf.append(block, static_cast<std::size_t>(n));
        return true;
      }
      if (n == 0) return false;
      if (errno != EINTR) {
        error_ = std::strerror(errno);
        return false;
      }
    }
  }
  const std::string& error() const { return error_; }

 private:
  std::string error_;
};

}  // namespace

int run_stream(int argc, char** argv) {
  static const std::string usage = std::string(
      "usage: relief stream ARCHIVE [--format xyz|binary] [options]\n"
      "Compresses points read from standard input as a scanner produces them. Each chunk is\n"
      "buffered until --idle batches in a row bring it no point (or the buffer bound is hit),\n"
      "then encoded. On end of input or Ctrl-C everything received is written. A new archive\n"
      "needs --cell (and optionally --chunk-edge); an existing one keeps its parameters.\n\n"
      "  --format xyz           text lines 'x y z [..]' per --columns (x y z, r g b as 0..255, i, c\n"
      "                         and the LAS dimensions by name, name:type kept as LAS extra bytes as\n"
      "                         in --attributes, _ to skip; default x,y,z), columns\n"
      "                         separated by blanks, ',' or ';'; a blank line ends a scan (batch)\n"
      "  --format binary        little-endian records: f64 x y z, then the fields --attributes\n"
      "                         lists, in its order\n"
      "  --attributes LIST      binary fields after x y z (default none): rgb (3 x u8), intensity\n"
      "                         (f32), gps_time (f64), scan_angle (f32 degrees), point_source_id\n"
      "                         and nir (u16), the other LAS dimensions by name (u8:\n"
      "                         classification, return_number, number_of_returns, user_data,\n"
      "                         scanner_channel, synthetic, key_point, withheld, overlap,\n"
      "                         scan_direction_flag, edge_of_flight_line), _N to skip N bytes,\n"
      "                         name:type a field kept as LAS extra bytes (type u8 i8 u16 i16 u32\n"
      "                         i32 u64 i64 f32 f64, e.g. amplitude:f32); rgb before intensity\n"
      "  --batch N              points per batch when no blank line comes first (default 65536)\n"
      "  --idle N               batches without new points before a chunk is encoded (default 2)\n"
      "  --max-buffered N       bound on buffered points (default 4000000)\n"
      "  --immediate            encode every batch at once (no buffering)\n"
      "  --chunk-edge M         chunk edge of a new archive (default 32 cells; 8 in bounded mode)\n"
      "  --crs CRS              the points' CRS (EPSG:32633, WKT, PROJJSON); an existing archive's\n"
      "                         must be the same\n\n") +
      kModeOptionsHelp + "\n" + kIngestOptionsHelp + "\n" + kEncodeOptionsHelp;
  std::vector<std::string> options = ingest_cli_options(IngestOptionSet::kStream);
  options.insert(options.end(), {"--format", "--attributes", "--batch", "--idle", "--max-buffered", "--chunk-edge"});
  std::vector<std::string> flags = ingest_cli_flags(IngestOptionSet::kStream);
  flags.insert(flags.end(), {"--help", "--quiet", "--immediate"});
  Args args(argc, argv, flags, options);
  if (args.has("--help")) {
    std::cout << usage;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one ARCHIVE");
  StreamOptions so;
  if (const std::string err = parse_ingest_options(args, IngestOptionSet::kStream, so.ingest); !err.empty()) {
    return usage_error(kCommand, err);
  }
  so.ingest.chunk_edge = args.get_double("--chunk-edge", 0);
  so.immediate = args.has("--immediate");
  so.idle_batches = static_cast<std::uint32_t>(args.get_int("--idle", 2, 1, 1 << 30));
  so.max_buffered_points = static_cast<std::uint64_t>(args.get_int("--max-buffered", 4000000, 1, 1LL << 40));
  const auto batch_points = static_cast<std::size_t>(args.get_int("--batch", 65536, 1, 1 << 26));
  if (!args.ok()) return usage_error(kCommand, args.error());
  const std::string format = args.get("--format").value_or("xyz");
  if (format != "xyz" && format != "binary") {
    return usage_error(kCommand, "--format must be xyz or binary");
  }
  if (format == "xyz" && args.has("--attributes")) {
    return usage_error(kCommand, "--attributes names the fields of --format binary; text takes --columns");
  }
  if (format == "binary" && so.ingest.reader.xyz_columns) {
    return usage_error(kCommand, "--columns names text columns; --format binary takes --attributes");
  }
  Layout layout;
  if (format == "xyz") {
    auto parser = TextLineParser::create(so.ingest.reader.xyz_columns.value_or("x,y,z"), "stdin");
    if (!parser) return usage_error(kCommand, parser.status().message());
    layout.text = std::move(*parser);
    layout.colors = layout.text->colors();
    layout.intensity = layout.text->intensity();
    layout.las = layout.text->las_attributes();
    layout.extra_bytes_vlr = layout.text->extra_bytes_vlr();
    layout.extra_bytes_size = layout.text->extra_bytes_size();
  } else {
    auto parser = BinaryRecordParser::create(args.get("--attributes").value_or(""), "stdin");
    if (!parser) return usage_error(kCommand, "--attributes: " + parser.status().message());
    layout.binary = std::move(*parser);
    layout.colors = layout.binary->colors();
    layout.intensity = layout.binary->intensity();
    layout.las = layout.binary->las_attributes();
    layout.extra_bytes_vlr = layout.binary->extra_bytes_vlr();
    layout.extra_bytes_size = layout.binary->extra_bytes_size();
  }
  const bool quiet = args.has("--quiet");
  so.ingest.progress = progress_printer(quiet);
  // Ctrl-C ends the input; the pipeline itself must still write what arrived.
  const std::atomic<bool>* interrupted = install_interrupt_flag();
  so.ingest.cancel = nullptr;
  const std::string archive = args.positional()[0];
  auto stream = StreamIngest::open(archive, so, layout.colors, layout.intensity, layout.las, layout.extra_bytes_vlr,
                                   layout.extra_bytes_size);
  if (!stream) return fail(kCommand, stream.status());

  StdinBlocks input;
  std::string buf;
  std::size_t pos = 0;
  PointCloud batch;
  std::uint64_t line_no = 0;
  Status status;
  const std::size_t record = layout.binary ? layout.binary->record_size() : 0;
  const auto push = [&]() -> Status {
    if (batch.empty()) return Status::ok();
    Status s = (*stream)->push(batch);
    batch = PointCloud();
    return s;
  };
  bool eof = false;
  while (status && !eof) {
    eof = !input.more(buf, interrupted);
    if (format == "xyz") {
      for (;;) {
        const std::size_t nl = buf.find('\n', pos);
        if (nl == std::string::npos) {
          if (!eof) break;
          if (pos >= buf.size()) break;
        }
        const std::size_t end = nl == std::string::npos ? buf.size() : nl;
        std::string_view line(buf.data() + pos, end - pos);
        pos = nl == std::string::npos ? buf.size() : nl + 1;
        ++line_no;
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        const auto first = line.find_first_not_of(" \t");
        if (first == std::string_view::npos) {  // blank line: end of a scan
          status = push();
          if (!status) break;
          continue;
        }
        if (line[first] == '#') continue;
        status = layout.text->parse(line, line_no, batch);
        if (!status) break;
        if (batch.size() >= batch_points) {
          status = push();
          if (!status) break;
        }
      }
    } else {
      while (buf.size() - pos >= record) {
        const auto* p = reinterpret_cast<const std::uint8_t*>(buf.data() + pos);
        status = layout.binary->parse(p, line_no + 1, batch);
        if (!status) break;
        pos += record;
        ++line_no;
        if (batch.size() >= batch_points) {
          status = push();
          if (!status) break;
        }
      }
      if (eof && status && buf.size() > pos) {
        std::cerr << "relief stream: ignoring " << buf.size() - pos << " trailing bytes (a partial record)\n";
      }
    }
    buf.erase(0, pos);
    pos = 0;
  }
  if (status) status = push();
  if (!input.error().empty()) std::cerr << "relief stream: reading stdin: " << input.error() << "\n";
  // A failure (bad input, a chunk that cannot be written) leaves nothing
  // behind: no new archive, or the archive as it was before this stream.
  const auto give_up = [&](const Status& why) {
    end_progress_line();
    const Status undone = (*stream)->abort();
    if (!undone) std::cerr << "relief stream: could not remove what this stream added: " << undone.message() << "\n";
    return fail(kCommand, why);
  };
  if (!status) return give_up(status);
  // End of input, a read error or Ctrl-C: what arrived is written.
  auto done = (*stream)->finish();
  end_progress_line();
  if (!done) return give_up(done.status());
  // After the progress line, as compress prints its readers' warnings.
  if (layout.text) {
    for (const std::string& w : layout.text->take_warnings()) std::cerr << "relief stream: warning: " << w << "\n";
  }
  for (const std::string& w : done->warnings) std::cerr << "relief stream: warning: " << w << "\n";
  if (!quiet) {
    if (interrupted->load()) std::cerr << "relief stream: interrupted; everything received is in " << archive << "\n";
    print_ingest_summary(archive, *done);
  }
  return kExitOk;
}

}  // namespace relief::cli
