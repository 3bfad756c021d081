// The README's example, compiled and run as written (keep them identical).
#include <catch2/catch.hpp>

#include <filesystem>
#include <unistd.h>

#include "relief/codec.h"
#include "relief/io.h"
#include "support/synthetic.h"

namespace {

std::size_t readme_example() {
  relief::Result<relief::PointCloud> cloud = relief::read_ply("scan.ply");
  relief::EncodeParams params;                          // voxel grid, r = 16, JPEG
  params.cell_size = 4 * relief::suggest_cell_size(*cloud, params.map_resolution);  // base layer
  params.bound = relief::ErrorBound{{0.002, 0.002, 0.002}};  // every point within 1 mm
  relief::Result<std::vector<std::uint8_t>> blob = relief::encode_chunk(*cloud, params);
  relief::Result<relief::PointCloud> all = relief::decode_chunk(*blob);              // every point
  relief::Result<relief::PointCloud> preview = relief::decode_chunk(*blob, {.lod = 16});  // base layer
  return all->size() + preview->size();
}

}  // namespace

TEST_CASE("the README example compiles and runs", "[codec][readme]") {
  const auto dir = std::filesystem::temp_directory_path() / ("relief-readme-" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const auto old = std::filesystem::current_path();
  std::filesystem::current_path(dir);
  relief::test::SceneOptions o;
  o.points = 20000;
  REQUIRE(relief::write_ply("scan.ply", relief::test::make_sphere(o, 1.0)).is_ok());
  const std::size_t n = readme_example();
  std::filesystem::current_path(old);
  std::filesystem::remove_all(dir);
  // Every point, plus 1/32 to 1/16 of them from the base layer (format-spec/chunk.md §11.6).
  CHECK(n >= 20000 + 20000 / 32);
  CHECK(n <= 20000 + 20000 / 16 + 1);
}
