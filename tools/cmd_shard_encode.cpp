// relief shard-encode PLAN --range R --dir DIR -o SHARD: stage 2 of a sharded build.
#include <cstdio>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "ingest_options.h"
#include "relief/ingest.h"
#include "relief/shard.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "shard-encode";

}  // namespace

int run_shard_encode(int argc, char** argv) {
  static const std::string usage =
      "usage: relief shard-encode PLAN --range R --dir DIR -o SHARD.relief [--threads N] [--memory SIZE]\n"
      "                           [--tmp DIR] [--verify] [--quiet]\n"
      "Stage 2 of a sharded build: encodes key range R from every input's partition file in DIR\n"
      "(all stage-1 tasks must have finished) into the shard archive SHARD.relief, which is\n"
      "written under a temporary name and renamed when complete (replacing an earlier one: safe\n"
      "to retry). Join the shards with 'relief merge'.\n"
      "  --memory SIZE   working-memory budget, e.g. 512M, 2G (default 1G, minimum 64M; plain\n"
      "                  number = MiB): a range larger than half of it is sorted through temporary\n"
      "                  files, as 'relief compress' sorts its inputs; the blobs are the same\n"
      "  --tmp DIR       directory for those files (default: beside SHARD)\n";
  Args args(argc, argv, {"--help", "--quiet", "--verify"}, {"--range", "--dir", "-o", "--threads", "--memory", "--tmp"});
  if (args.has("--help")) {
    std::cout << usage;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one plan file");
  if (!args.has("--range") || !args.has("--dir") || !args.has("-o")) {
    return usage_error(kCommand, "missing --range R, --dir DIR or -o SHARD");
  }
  const auto range = static_cast<std::uint32_t>(args.get_int("--range", 0, 0, kMaxShardRanges - 1));
  EncodeShardOptions o;
  o.threads = static_cast<unsigned>(args.get_int("--threads", 0, 0, 1024));
  o.verify_blobs = args.has("--verify");
  if (const auto m = args.get("--memory")) {
    if (const std::string err = memory_option(*m, o.memory_budget); !err.empty())
      return usage_error(kCommand, err);
  }
  if (const auto t = args.get("--tmp")) o.tmp_dir = *t;
  if (!args.ok()) return usage_error(kCommand, args.error());
  auto plan = read_shard_plan(args.positional()[0]);
  if (!plan) return fail(kCommand, plan.status());
  const std::string out = *args.get("-o");
  o.cancel = install_interrupt_flag();
  o.progress = progress_printer(args.has("--quiet"));
  auto r = encode_shard(*plan, range, *args.get("--dir"), out, o);
  end_progress_line();
  if (!r) {
    if (o.cancel->load()) return interrupted(kCommand, "; no shard written (nothing of it is left)");
    return fail(kCommand, r.status());
  }
  if (!args.has("--quiet")) print_ingest_summary(out, *r);
  return kExitOk;
}

}  // namespace relief::cli
