#include <cstdio>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "relief/codec.h"
#include "relief/io.h"

namespace relief::cli {

namespace {
constexpr const char* kCommand = "encode-chunk";
}

int run_encode_chunk(int argc, char** argv) {
  static const std::string usage = std::string(
      "usage: relief encode-chunk IN.ply -o OUT.rlfc [options]\n"
      "Compresses every point of IN as one chunk blob (format-spec/chunk.md).\n\n") + kEncodeOptionsHelp +
      kBoundOptionsHelp;
  std::vector<std::string> options = encode_option_names();
  options.push_back("-o");
  for (const std::string& name : bound_option_names()) options.push_back(name);
  Args args(argc, argv, {"--help", "--quiet", kKeepOrderFlag}, options);
  if (args.has("--help")) {
    std::cout << usage;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one input file");
  const auto out_path = args.get("-o");
  if (!out_path) return usage_error(kCommand, "missing -o OUT");
  EncodeParams params;
  if (const std::string err = parse_encode_params(args, params); !err.empty()) {
    return usage_error(kCommand, err);
  }
  if (const std::string err = parse_bound_options(args, params); !err.empty()) return usage_error(kCommand, err);
  const std::string& in_path = args.positional()[0];
  auto cloud = read_point_file(in_path);
  if (!cloud) return fail(kCommand, cloud.status());
  if (Status s = check_chunk_coordinates(*cloud, in_path); !s) return fail(kCommand, s);
  if (params.cell_size == 0) params.cell_size = suggest_cell_size(*cloud, params.map_resolution);
  const auto t0 = now_ns();
  auto blob = encode_chunk(*cloud, params);
  if (!blob) return fail(kCommand, blob.status().with_context(in_path));
  const double secs = seconds_since(t0);
  if (Status s = write_file(*out_path, *blob); !s) return fail(kCommand, s);
  if (!args.has("--quiet") && *out_path != "-") {  // "-": standard output carries the blob
    const double n = static_cast<double>(cloud->size());
    std::printf("%s: %zu points -> %zu bytes (%.3f bits/point), cell %.6g, %.2f M points/s\n",
                out_path->c_str(), cloud->size(), blob->size(),
                n > 0 ? 8.0 * static_cast<double>(blob->size()) / n : 0.0, params.cell_size,
                secs > 0 ? n / secs * 1e-6 : 0.0);
  }
  return kExitOk;
}

}  // namespace relief::cli
