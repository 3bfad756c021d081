// Checks ingest makes before and while it works: the coordinate magnitude
// limit, the output directory, the sample's density against the cell size,
// and the attribute descriptions used in mismatch messages.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <system_error>

#include "ingest/ingest_common.h"
#include "relief/ingest.h"

namespace relief {

namespace {

// A point may lie at most 2^kMaxCellsFromOrigin cells (or chunk edges, if a
// chunk is smaller than a cell) from the origin. Chunk keys then stay below
// 2^36, far inside int64 and the fast key path (2^62), and one ulp of a
// coordinate is at most 2^(36-52) = 2^-16 cell, finer than the finest
// quantisation step the codec has (16-bit heights over 3.5 cells: ~2^-14 cell),
// so double arithmetic still resolves every map pixel and height step.
constexpr int kMaxCellsFromOrigin = 36;
// The density check (check_sample_density) needs a sample this large to say
// anything; smaller inputs cannot blow up far anyway.
constexpr std::uint64_t kDensityCheckMinPoints = 10'000;
// A cell holding a single point spends r x r map pixels (256 at r = 16) on
// it; the default cell (one point per pixel) puts tens to hundreds of points
// in a cell. Fewer than this on average means the cell is far too fine.
constexpr std::uint64_t kMinPointsPerCell = 2;
// Each chunk costs a row, an index entry and ~1 kB of headers and tables;
// below this many points per chunk that overhead dominates the archive.
constexpr std::uint64_t kMinPointsPerChunk = 16;

std::string format_number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

}  // namespace

double max_coordinate_magnitude(double cell_size, double chunk_edge) {
  const double unit = std::min(cell_size, chunk_edge);
  if (!(unit > 0) || !std::isfinite(unit)) return 0;
  return std::min(std::ldexp(unit, kMaxCellsFromOrigin), kMaxCoordinateMagnitude);
}

namespace ingest {

Status check_coordinates(const PointCloud& batch, double limit, const std::string& source,
                         std::uint64_t first_index) {
  const auto out_of_range = [limit](double v) { return !(std::abs(v) <= limit); };
  for (std::size_t i = 0; i < batch.size(); ++i) {
    const Vec3d& p = batch.positions[i];
    if (!out_of_range(p.x) && !out_of_range(p.y) && !out_of_range(p.z)) continue;
    const char axis = out_of_range(p.x) ? 'x' : out_of_range(p.y) ? 'y' : 'z';
    const double v = axis == 'x' ? p.x : axis == 'y' ? p.y : p.z;
    return invalid_argument(source + ": point " + std::to_string(first_index + i) + " has " + axis + " = " +
                            format_number(v) + ", beyond the limit of +-" + format_number(limit) +
                            " (2^36 cells, at most 2^50; README, \"Limits\")");
  }
  return Status::ok();
}

Status check_output_directory(const std::string& archive_path) {
  const std::filesystem::path parent = std::filesystem::path(archive_path).parent_path();
  if (parent.empty()) return Status::ok();
  std::error_code ec;
  const auto st = std::filesystem::status(parent, ec);
  if (st.type() == std::filesystem::file_type::not_found) {
    return io_error(archive_path + ": cannot create the archive: the directory " + parent.string() +
                    " does not exist");
  }
  if (!ec && st.type() != std::filesystem::file_type::directory) {
    return io_error(archive_path + ": cannot create the archive: " + parent.string() + " is not a directory");
  }
  return Status::ok();  // other failures (permissions) are reported by the create itself
}

Status check_sample_density(const PointCloud& sample, const ArchiveGrid& grid, double cell_size,
                            const std::string& source, double edge_capped_by_step) {
  if (sample.size() < kDensityCheckMinPoints) return Status::ok();
  const std::size_t n = std::min(sample.size(), kDensitySamplePoints);
  const auto distinct = [&](const ArchiveGrid& g) {
    std::vector<ChunkKey> keys(n);
    g.keys_of(sample.positions.data(), n, keys.data());
    std::sort(keys.begin(), keys.end());
    return static_cast<std::uint64_t>(std::unique(keys.begin(), keys.end()) - keys.begin());
  };
  ArchiveGrid cells = grid;
  cells.chunk_edge = cell_size;
  const std::uint64_t cell_count = distinct(cells);
  const std::uint64_t chunk_count = distinct(grid);
  const auto per = [n](std::uint64_t k) { return format_number(static_cast<double>(n) / static_cast<double>(k)); };
  const std::string what = source + ": the first " + std::to_string(n) + " points fall into ";
  // A chunk edge the tolerance capped cannot grow: say which knob moves it.
  const std::string remedy =
      edge_capped_by_step > 0
          ? "The chunk edge is at most 2^21 grid steps of " + format_number(edge_capped_by_step) +
                " (twice the tolerance): use a larger --tolerance"
          : std::string("Use a larger --cell (or leave it to the point density), a larger --chunk-edge");
  const std::string hint = "; the archive would be many times larger than the input. " + remedy +
                           ", or --allow-sparse (IngestOptions::allow_sparse) to go ahead";
  if (cell_count * kMinPointsPerCell > n) {
    return limit_exceeded(what + std::to_string(cell_count) + " cells of " + format_number(cell_size) + " (" +
                          per(cell_count) + " points per cell; at least " + std::to_string(kMinPointsPerCell) +
                          " expected)" + hint);
  }
  if (chunk_count * kMinPointsPerChunk > n) {
    return limit_exceeded(what + std::to_string(chunk_count) + " chunks of edge " + format_number(grid.chunk_edge) +
                          " (" + per(chunk_count) + " points per chunk; at least " +
                          std::to_string(kMinPointsPerChunk) + " expected)" + hint);
  }
  return Status::ok();
}

std::string attribute_list(bool colors, bool intensity) {
  if (colors && intensity) return "colours and intensity";
  if (colors) return "colours, no intensity";
  if (intensity) return "intensity, no colours";
  return "no colours or intensity";
}

}  // namespace ingest

}  // namespace relief
