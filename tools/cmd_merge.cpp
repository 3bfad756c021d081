// relief merge SHARD... -o OUT: joins the shard archives of a sharded build.
#include <cstdio>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "relief/shard.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "merge";

}  // namespace

int run_merge(int argc, char** argv) {
  static const std::string usage =
      "usage: relief merge SHARD... -o OUT.relief [--pyramid auto|on|off] [--threads N] [--memory SIZE]\n"
      "                    [--quiet]\n"
      "Joins the shard archives of a sharded build (shard-encode) into one new archive: the\n"
      "chunk rows are copied as they are, under one spatial index and one scan. The shards must\n"
      "come from one plan (same grid, codec parameters, CRS, attributes and sources), hold\n"
      "disjoint chunks and, together, every point of the plan's inputs (a missing shard is\n"
      "refused). OUT appears only when complete and is never overwritten.\n"
      "  --pyramid auto|on|off  the level-of-detail pyramid, built from the merged chunks as\n"
      "                         'relief compress --pyramid' builds it (default auto: for 10 M\n"
      "                         points or more)\n"
      "  --threads N            threads that build the pyramid (default: all cores)\n"
      "  --memory SIZE          its working memory, e.g. 512M, 2G (default 1G)\n";
  Args args(argc, argv, {"--help", "--quiet"}, {"-o", "--pyramid", "--threads", "--memory"});
  if (args.has("--help")) {
    std::cout << usage;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().empty()) return usage_error(kCommand, "expected at least one shard");
  const auto out = args.get("-o");
  if (!out) return usage_error(kCommand, "missing -o OUT.relief");
  MergeOptions options;
  if (const auto p = args.get("--pyramid")) {
    const std::optional<PyramidMode> mode = pyramid_mode_from_text(*p);
    if (!mode) return usage_error(kCommand, "--pyramid must be auto, on or off, got '" + *p + "'");
    options.pyramid = *mode;
  }
  options.threads = static_cast<unsigned>(args.get_int("--threads", 0, 0, 1024));
  if (const auto m = args.get("--memory")) {
    if (const std::string err = memory_option(*m, options.memory_budget); !err.empty())
      return usage_error(kCommand, err);
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  auto r = merge_archives(args.positional(), *out, options);
  if (!r) return fail(kCommand, r.status());
  if (!args.has("--quiet")) {
    std::printf("%s: %llu shards -> %llu chunks, %llu points, %s of blobs\n", out->c_str(),
                static_cast<unsigned long long>(r->shards), static_cast<unsigned long long>(r->chunks),
                static_cast<unsigned long long>(r->input_points), format_bytes(r->blob_bytes).c_str());
  }
  return kExitOk;
}

}  // namespace relief::cli
