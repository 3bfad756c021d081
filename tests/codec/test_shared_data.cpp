// Optional: round trips of the real clouds in ../shared/data beside the checkout.
// Skipped with a message when the folder is absent (tests never download).
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>

#include "relief/codec.h"
#include "relief/io.h"
#include "relief/metrics.h"

using namespace relief;

TEST_CASE("shared data files round-trip within the pixel bound", "[shared-data]") {
  const std::filesystem::path root = RELIEF_SHARED_DATA_DIR;
  const char* files[] = {"small/stanford_bunny.ply", "small/kinect_milk_scene_rgb.ply",
                         "small/kitti_000000.ply", "medium/lone_star_tls_519k.ply",
                         "medium/fr_aerial_rgb_698k.ply"};
  if (!std::filesystem::exists(root)) {
    WARN("skipped: " << root.string() << " is absent (optional real-data tests)");
    return;
  }
  for (const char* name : files) {
    const std::filesystem::path path = root / name;
    if (!std::filesystem::exists(path)) {
      WARN("skipped: " << path.string() << " is absent");
      continue;
    }
    INFO(path.string());
    auto cloud = read_ply(path.string());
    REQUIRE(cloud.is_ok());
    EncodeParams p;
    p.cell_size = suggest_cell_size(*cloud, p.map_resolution);
    auto blob = encode_chunk(*cloud, p);
    REQUIRE(blob.is_ok());
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    CHECK(out->has_colors() == cloud->has_colors());
    CHECK(out->has_intensity() == cloud->has_intensity());
    CHECK(out->size() > cloud->size() / 10);
    auto m = compare_clouds(*cloud, *out);
    REQUIRE(m.is_ok());
    const double pitch = p.cell_size / p.map_resolution;
    // Real surfaces are rough within a pixel; allow the in-plane bound plus coding.
    CHECK(m->rmse_snn < 1.5 * pitch);
    CHECK(m->psnr > 40.0);
    const double bpp = 8.0 * static_cast<double>(blob->size()) / static_cast<double>(cloud->size());
    CHECK(bpp < 8.0);
    WARN(name << ": " << bpp << " bits/point, RMSE_SNN " << m->rmse_snn << ", points "
              << cloud->size() << " -> " << out->size());
  }
}
