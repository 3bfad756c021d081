// relief shard-partition PLAN --input I --dir DIR: stage 1 of a sharded build.
#include <cstdio>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "relief/shard.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "shard-partition";

}  // namespace

int run_shard_partition(int argc, char** argv) {
  static const std::string usage =
      "usage: relief shard-partition PLAN --input I --dir DIR [--quiet]\n"
      "Stage 1 of a sharded build: reads input I (0-based, in the plan's order), snaps its points\n"
      "to the plan's grid and writes them into DIR, one file per key range, then the input's\n"
      "manifest. Files appear under their final names only when complete; a re-run writes the\n"
      "same bytes (safe to retry).\n";
  Args args(argc, argv, {"--help", "--quiet"}, {"--input", "--dir"});
  if (args.has("--help")) {
    std::cout << usage;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one plan file");
  if (!args.has("--input") || !args.has("--dir")) return usage_error(kCommand, "missing --input I or --dir DIR");
  const auto input = static_cast<std::uint32_t>(args.get_int("--input", 0, 0, 0xFFFFFFFFLL));
  if (!args.ok()) return usage_error(kCommand, args.error());
  auto plan = read_shard_plan(args.positional()[0]);
  if (!plan) return fail(kCommand, plan.status());
  const std::atomic<bool>* cancel = install_interrupt_flag();
  auto r = partition_input(*plan, input, *args.get("--dir"), cancel);
  if (!r) {
    if (cancel->load()) return interrupted(kCommand, "; nothing of input " + std::to_string(input) + " is left");
    return fail(kCommand, r.status());
  }
  for (const std::string& w : r->warnings) std::fprintf(stderr, "relief %s: warning: %s\n", kCommand, w.c_str());
  if (!args.has("--quiet")) {
    std::printf("input %u (%s): %llu points into %u ranges\n", input, plan->sources[input].path.c_str(),
                static_cast<unsigned long long>(r->points), plan->range_count());
  }
  return kExitOk;
}

}  // namespace relief::cli
