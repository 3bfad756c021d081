// relief shard-plan IN... -o PLAN: stage 0 of a sharded build (README,
// "Sharded builds"): every global parameter, from one pass over the inputs.
#include <cstdio>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "ingest_options.h"
#include "relief/shard.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "shard-plan";

}  // namespace

int run_shard_plan(int argc, char** argv) {
  static const std::string usage = std::string(
      "usage: relief shard-plan IN... -o PLAN [--ranges N] [compress options]\n"
      "Stage 0 of a sharded build: reads every input once and writes the plan (grid, codec\n"
      "parameters, attributes, CRS, inputs, chunk-key ranges) that shard-partition and\n"
      "shard-encode follow, so the merged archive has the blobs 'relief compress' makes.\n"
      "  --ranges N             key ranges = shards (default: about 8 M points each; at most 512)\n"
      "  --quiet                print nothing but errors and warnings\n"
      "Every option of 'relief compress' (below) is taken and recorded in the plan\n"
      "(--chunk-edge, --allow-sparse, --assume-crs, --crs, --columns...), but --pyramid,\n"
      "which 'relief merge' takes.\n\n") +
      kInputsHelp + "\n" + kModeOptionsHelp + "\n" + kIngestOptionsHelp + "\n" + kEncodeOptionsHelp;
  // Every option compress takes (the same library parser), plus --ranges.
  std::vector<std::string> options = ingest_cli_options(IngestOptionSet::kCompress);
  options.insert(options.end(), {"-o", "--ranges", "--input-list"});
  std::vector<std::string> flags = ingest_cli_flags(IngestOptionSet::kCompress);
  flags.insert(flags.end(), {"--help", "--quiet"});
  Args args(argc, argv, flags, options);
  if (args.has("--help")) {
    std::cout << usage;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  std::string input_error;
  const std::vector<std::string> inputs = command_inputs(args, 0, input_error);
  if (!input_error.empty()) return usage_error(kCommand, input_error);
  const auto out = args.get("-o");
  if (!out) return usage_error(kCommand, "missing -o PLAN");
  // The pyramid is built from the merged chunks, by merge.
  if (args.get("--pyramid")) {
    return usage_error(kCommand, "--pyramid is not part of the plan: give it to 'relief merge', which builds the "
                                 "pyramid from the merged chunks");
  }
  ShardPlanOptions po;
  IngestOptions& o = po.ingest;
  if (const std::string err = parse_ingest_options(args, IngestOptionSet::kCompress, o); !err.empty()) {
    return usage_error(kCommand, err);
  }
  po.ranges = static_cast<std::uint32_t>(args.get_int("--ranges", 0, 1, kMaxShardRanges));
  if (!args.ok()) return usage_error(kCommand, args.error());
  o.progress = progress_printer(args.has("--quiet"));
  o.cancel = install_interrupt_flag();
  auto plan = plan_shards(inputs, po);
  end_progress_line();
  if (!plan) {
    if (o.cancel->load()) return interrupted(kCommand, "; no plan written");
    return fail(kCommand, plan.status());
  }
  for (const std::string& w : plan->warnings) std::fprintf(stderr, "relief %s: warning: %s\n", kCommand, w.c_str());
  if (Status s = write_shard_plan(*plan, *out); !s) return fail(kCommand, s);
  if (!args.has("--quiet")) {
    std::printf("%s: %u inputs, %llu points, %u key ranges, chunk edge %.6g\n", out->c_str(), plan->input_count(),
                static_cast<unsigned long long>(plan->points), plan->range_count(), plan->grid.chunk_edge);
  }
  return kExitOk;
}

}  // namespace relief::cli
