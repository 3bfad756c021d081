// Optional: round trips of the real clouds in ../shared/data beside the checkout.
// Skipped with a message when the folder is absent (tests never download).
#include <catch2/catch.hpp>
#include <cmath>
#include <filesystem>
#include <optional>
#include <string>

#include "relief/codec.h"
#include "relief/io.h"
#include "relief/metrics.h"
#include "support/shared_data.h"

using namespace relief;

TEST_CASE("shared data files round-trip within the pixel bound", "[shared-data]") {
  const char* files[] = {"small/stanford_bunny.ply", "small/kinect_milk_scene_rgb.ply",
                         "small/kitti_000000.ply", "medium/lone_star_tls_519k.ply",
                         "medium/fr_aerial_rgb_698k.ply"};
  for (const char* name : files) {
    const std::optional<std::string> path = relief::test::shared_file(name);
    if (!path) continue;
    INFO(*path);
    auto cloud = read_ply(*path);
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
