#include <cstdio>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "relief/codec.h"
#include "relief/io.h"

namespace relief::cli {

namespace {
constexpr const char* kCommand = "decode-chunk";
constexpr const char* kUsageText =
    "usage: relief decode-chunk IN.rlfc -o OUT.ply [--lod L] [--ascii] [--quiet]\n"
    "Decompresses a chunk blob to PLY (binary little endian, double x y z; --ascii for text) with\n"
    "every attribute it holds (colour, intensity, LAS attributes as properties); OUT.las, .laz or\n"
    ".xyz/.csv write those formats instead.\n"
    "  --lod L   level of detail: keep a spatially uniform ~1/L of the points (1..1024, default 1)\n";
}  // namespace

int run_decode_chunk(int argc, char** argv) {
  Args args(argc, argv, {"--help", "--ascii", "--quiet"}, {"-o", "--lod"});
  if (args.has("--help")) {
    std::cout << kUsageText;
    return kExitOk;
  }
  DecodeOptions options;
  options.lod = static_cast<std::uint32_t>(args.get_int("--lod", 1, 1, kMaxLod));
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one input file");
  const auto out_path = args.get("-o");
  if (!out_path) return usage_error(kCommand, "missing -o OUT");
  const std::string& in_path = args.positional()[0];
  auto blob = read_file(in_path);
  if (!blob) return fail(kCommand, blob.status());
  const auto t0 = now_ns();
  auto cloud = decode_chunk(*blob, options);
  if (!cloud) return fail(kCommand, cloud.status().with_context(in_path));
  const double secs = seconds_since(t0);
  if (Status s = write_decoded_cloud(kCommand, *out_path, *cloud, args.has("--ascii")); !s) return fail(kCommand, s);
  if (!args.has("--quiet") && *out_path != "-") {  // "-": standard output carries the points
    std::printf("%s: %zu points, %.2f M points/s\n", out_path->c_str(), cloud->size(),
                secs > 0 ? static_cast<double>(cloud->size()) / secs * 1e-6 : 0.0);
  }
  return kExitOk;
}

}  // namespace relief::cli
