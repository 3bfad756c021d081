#include <cmath>
#include <cstdio>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "metrics_print.h"
#include "relief/io.h"
#include "relief/metrics.h"

namespace relief::cli {

namespace {
constexpr const char* kCommand = "eval";
constexpr const char* kUsageText =
    "usage: relief eval ORIGINAL RECONSTRUCTED [--threads N] [--json]\n"
    "Prints the error measures of Golla & Klein 2015 (IV-A): RMSE_NN both ways, RMSE_SNN,\n"
    "Hausdorff, PSNR (peak = bounding-box diagonal of ORIGINAL), colour RMSE when both have RGB.\n";
}  // namespace

int run_eval(int argc, char** argv) {
  Args args(argc, argv, {"--help", "--json"}, {"--threads"});
  if (args.has("--help")) {
    std::cout << kUsageText;
    return kExitOk;
  }
  MetricsOptions options;
  options.threads = static_cast<unsigned>(args.get_int("--threads", 0, 0, 1024));
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 2) {
    return usage_error(kCommand, "expected ORIGINAL and RECONSTRUCTED");
  }
  auto original = read_point_file(args.positional()[0]);
  if (!original) return fail(kCommand, original.status());
  auto recon = read_point_file(args.positional()[1]);
  if (!recon) return fail(kCommand, recon.status());
  auto m = compare_clouds(*original, *recon, options);
  if (!m) return fail(kCommand, m.status());
  print_metrics(*m, args.has("--json"));
  return kExitOk;
}

}  // namespace relief::cli
