#include "ingest_options.h"

#include <cstdio>

#include "relief/io.h"

namespace relief::cli {

const char* const kIngestOptionsHelp =
    "Ingest options:\n"
    "  --memory SIZE          working-memory budget, e.g. 512M, 2G (default 1G, minimum 64M;\n"
    "                         plain number = MiB)\n"
    "  --threads N            encoder threads (default: all cores)\n"
    "  --tmp DIR              directory for temporary bucket files (default: beside the archive)\n"
    "  --columns SPEC         XYZ/CSV columns, e.g. x,y,z,r,g,b,i,c (c = classification; LAS dimension names such as\n"
    "                         gps_time, return_number; name:type keeps a column as LAS extra bytes, type u8 i8\n"
    "                         u16 i16 u32 i32 u64 i64 f32 f64, e.g. amplitude:f32; default: header names, else x,y,z)\n"
    "  --pyramid auto|on|off  the level-of-detail pyramid that makes previews and coarse queries of\n"
    "                         large archives fast (default auto: for scans of 10 M points or more)\n"
    "  --verify               decode every blob back before committing it (about 10 % slower)\n"
    "  --quiet                no progress or summary\n";

const char* const kModeOptionsHelp =
    "Mode options (new archives):\n"
    "  --mode bounded|resample   bounded (default): every point back, each coordinate within the\n"
    "                         tolerance, colour and intensity exact; resample: the paper's maps\n"
    "                         alone, one point per occupied map pixel (smallest previews)\n"
    "  --tolerance T          bounded: largest error per coordinate, in coordinate units (default:\n"
    "                         half the LAS scale for LAS input, so its integers come back exactly;\n"
    "                         else 0.0005)\n"
    "  --color-tolerance C    bounded: largest error per colour channel, 0..127 (default 0 = exact)\n"
    "  --intensity-tolerance I  bounded: largest error of a 16-bit intensity, 0..32767 (default 0 =\n"
    "                         exact; float intensities stay exact)\n"
    "  --keep-order           bounded: each chunk gives its points back in the order they were read\n"
    "                         (as LAZ does), their geometry coded in that order: smaller for files in\n"
    "                         scan order without GPS times, larger for others; the archive then\n"
    "                         depends on the input order (default: cell order, an order-free archive)\n"
    "  --fast-geometry        bounded: code octree geometry without plane and near classes (chunk\n"
    "                         format 13 instead of 17): about 2.3x as fast to encode and decode, ~4 %\n"
    "                         more geometry bytes (scan-order geometry, --keep-order or GPS times, is\n"
    "                         the same either way); appends follow the archive\n";

std::vector<std::string> ingest_cli_options(IngestOptionSet set) { return cli_names(ingest_option_names(set)); }
std::vector<std::string> ingest_cli_flags(IngestOptionSet set) { return cli_names(ingest_flag_names(set)); }

const char* const kInputsHelp =
    "Inputs: files, or directories (the point files directly in each, by name);\n"
    "  --input-list FILE      more inputs, one path a line ('#' comments; for more files than a\n"
    "                         command line holds)\n";

std::vector<std::string> command_inputs(Args& args, std::size_t first, std::string& error) {
  std::vector<std::string> inputs;
  const std::vector<std::string>& pos = args.positional();
  if (pos.size() > first) inputs.assign(pos.begin() + static_cast<std::ptrdiff_t>(first), pos.end());
  if (const auto list = args.get("--input-list")) {
    Result<std::vector<std::string>> listed = read_input_list(*list);
    if (!listed) {
      error = listed.status().message();
      return {};
    }
    inputs.insert(inputs.end(), listed->begin(), listed->end());
  }
  if (inputs.empty()) error = "expected at least one input (a file, a directory or --input-list FILE)";
  return inputs;
}

std::string parse_ingest_options(Args& args, IngestOptionSet set, IngestOptions& o) {
  std::vector<std::string> names = ingest_option_names(set);
  for (const std::string& f : ingest_flag_names(set)) names.push_back(f);
  if (Status s = apply_ingest_options(set, given_options(args, names), OptionSpelling::kCli, o); !s) {
    return s.message();
  }
  o.creator = std::string("relief ") + RELIEF_VERSION;
  return "";
}

void print_ingest_warnings(const std::string& command, const IngestResult& r) {
  for (const std::string& w : r.warnings) std::fprintf(stderr, "relief %s: warning: %s\n", command.c_str(), w.c_str());
}

void print_ingest_summary(const std::string& path, const IngestResult& r) {
  const double n = static_cast<double>(r.points_read);
  std::printf("%s: %llu points -> %llu chunks, %s of blobs (%.3f bits/point), %llu points decodable\n",
              path.c_str(), static_cast<unsigned long long>(r.points_read),
              static_cast<unsigned long long>(r.chunks_written), format_bytes(r.blob_bytes).c_str(),
              n > 0 ? 8.0 * static_cast<double>(r.blob_bytes) / n : 0.0,
              static_cast<unsigned long long>(r.points_decoded));
  if (r.points_skipped > 0) {
    std::printf("%llu input records without a point skipped (PCD NaN points, PTX directions without a "
                "return)\n",
                static_cast<unsigned long long>(r.points_skipped));
  }
  std::printf("cell %.6g, chunk edge %.6g, %.2f s, %.2f M points/s\n", r.cell_size, r.chunk_edge, r.seconds,
              r.seconds > 0 ? n / r.seconds * 1e-6 : 0.0);
  if (r.pyramid.levels > 0) {
    std::printf("pyramid: %d levels, %llu nodes, %llu points, %s (%.2f %% of the blobs), %.2f s\n", r.pyramid.levels,
                static_cast<unsigned long long>(r.pyramid.chunks), static_cast<unsigned long long>(r.pyramid.points),
                format_bytes(r.pyramid.blob_bytes).c_str(),
                r.blob_bytes > 0 ? 100.0 * static_cast<double>(r.pyramid.blob_bytes) / static_cast<double>(r.blob_bytes)
                                 : 0.0,
                r.pyramid.seconds);
  }
}

}  // namespace relief::cli
