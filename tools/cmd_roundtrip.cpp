// The main job on one file: compress as a chunk, decompress, report size and error.
#include <cstdio>
#include <iostream>

#include "cli_common.h"
#include "commands.h"
#include "metrics_print.h"
#include "relief/codec.h"
#include "relief/io.h"
#include "relief/metrics.h"

namespace relief::cli {

namespace {
constexpr const char* kCommand = "roundtrip";
}  // namespace

int run_roundtrip(int argc, char** argv) {
  static const std::string usage = std::string(
      "usage: relief roundtrip IN.ply [-o RECONSTRUCTED.ply] [--blob OUT.rlfc] [--lod L] [options]\n"
      "Compresses IN as one chunk, decompresses it and prints size, bits per point, speed and the\n"
      "error measures (RMSE_SNN, PSNR, colour RMSE, Hausdorff) with points in and out.\n\n") +
      kEncodeOptionsHelp + kBoundOptionsHelp;
  std::vector<std::string> options = encode_option_names();
  options.insert(options.end(), {"-o", "--blob", "--lod", "--threads"});
  for (const std::string& name : bound_option_names()) options.push_back(name);
  Args args(argc, argv, {"--help", "--json", kKeepOrderFlag}, options);
  if (args.has("--help")) {
    std::cout << usage;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one input file");
  EncodeParams params;
  if (const std::string err = parse_encode_params(args, params); !err.empty()) {
    return usage_error(kCommand, err);
  }
  if (const std::string err = parse_bound_options(args, params); !err.empty()) return usage_error(kCommand, err);
  DecodeOptions dec;
  dec.lod = static_cast<std::uint32_t>(args.get_int("--lod", 1, 1, kMaxLod));
  MetricsOptions mopt;
  mopt.threads = static_cast<unsigned>(args.get_int("--threads", 0, 0, 1024));
  if (!args.ok()) return usage_error(kCommand, args.error());

  for (const char* name : {"-o", "--blob"}) {
    if (args.get(name) == "-") return usage_error(kCommand, std::string(name) + " - : standard output carries the report");
  }
  const std::string& in_path = args.positional()[0];
  auto cloud = read_point_file(in_path);
  if (!cloud) return fail(kCommand, cloud.status());
  if (Status s = check_chunk_coordinates(*cloud, in_path); !s) return fail(kCommand, s);
  if (params.cell_size == 0) params.cell_size = suggest_cell_size(*cloud, params.map_resolution);

  auto t0 = now_ns();
  auto blob = encode_chunk(*cloud, params);
  if (!blob) return fail(kCommand, blob.status().with_context(in_path));
  const double enc_s = seconds_since(t0);
  t0 = now_ns();
  auto recon = decode_chunk(*blob, dec);
  if (!recon) return fail(kCommand, recon.status().with_context(in_path));
  const double dec_s = seconds_since(t0);

  if (auto blob_path = args.get("--blob")) {
    if (Status s = write_file(*blob_path, *blob); !s) return fail(kCommand, s);
  }
  if (auto out = args.get("-o")) {
    if (Status s = write_decoded_cloud(kCommand, *out, *recon); !s) return fail(kCommand, s);
  }
  auto info = inspect_chunk(*blob);
  if (!info) return fail(kCommand, info.status());
  const double n = static_cast<double>(cloud->size());
  std::printf("input           %s\n", in_path.c_str());
  std::printf("decomposition   %s, cell %.6g, r %d, %s q%d/%d/%d, %d-bit heights\n",
              decomposition_name(params.decomposition), params.cell_size, params.map_resolution,
              image_codec_name(params.image_codec), params.height_quality, params.color_quality,
              params.intensity_quality, params.height_bits);
  std::printf("patches         %u (atlas %ux%u px)\n", info->patch_count, info->atlas_width, info->atlas_height);
  std::printf("size            %zu bytes = %.4f bits/point\n", blob->size(),
              n > 0 ? 8.0 * static_cast<double>(blob->size()) / n : 0.0);
  for (const ChunkSectionInfo& s : info->sections) {
    std::printf("  %-18s %9u bytes (%.4f bits/point)\n", chunk_section_label(s.id).c_str(), s.coded_size,
                n > 0 ? 8.0 * s.coded_size / n : 0.0);
  }
  std::printf("encode          %.3f s = %.2f M points/s (1 thread)\n", enc_s, n / enc_s * 1e-6);
  std::printf("decode          %.3f s = %.2f M points/s (1 thread, lod %u)\n", dec_s,
              static_cast<double>(recon->size()) / dec_s * 1e-6, dec.lod);
  if (recon->empty() || cloud->empty()) {
    std::printf("(no error measures: a cloud is empty)\n");
    return kExitOk;
  }
  auto m = compare_clouds(*cloud, *recon, mopt);
  if (!m) return fail(kCommand, m.status());
  print_metrics(*m, args.has("--json"));
  return kExitOk;
}

}  // namespace relief::cli
