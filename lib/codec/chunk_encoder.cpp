// Chunk encoder (Golla & Klein 2015, section III-B..D). Mirror: chunk_decoder.cpp.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "codec/atlas.h"
#include "codec/bounded.h"
#include "codec/chunk_format.h"
#include "codec/coders.h"
#include "codec/fill.h"
#include "codec/jpeg_tables.h"
#include "codec/las_attribute_coder.h"
#include "codec/octree.h"
#include "codec/patch.h"
#include "codec/reconstruct.h"

namespace relief {

namespace {

using codec::KeyedIndex;
using codec::Leaf;
using codec::SectionCodec;
using codec::SectionEntry;
using codec::SectionId;

// The encoder refuses chunks above this; the archive splits data long before.
constexpr std::size_t kMaxChunkPoints = std::size_t{1} << 28;
// Normalised heights (height / cell edge) are quantised over [-kHeightRange,
// kHeightRange]: 8-bit steps of 0.0137 cell edges = 0.22 pixel pitch at r = 16.
// Measured against +-1.0 and +-0.6 (bench data, defaults): narrower ranges
// cost 9-16 % more geometry bytes for 4-6 % lower RMSE, a worse trade than a
// finer cell, and would clamp heights of strongly non-planar cells.
constexpr double kHeightRange = 1.75;
// JPEG codes 8x8 blocks.
constexpr int kLumaBlock = 8;
// Finest level of the density estimate in suggest_cell_size (extent / 2^20).
constexpr int kDensityLevels = 20;

Status check_params(const EncodeParams& p, std::size_t point_count, std::size_t normal_count) {
  RELIEF_RETURN_IF_ERROR(validate_encode_params(p));
  if (normal_count != 0 && normal_count != point_count) {
    return invalid_argument(std::to_string(normal_count) + " normals for " +
                            std::to_string(point_count) + " points");
  }
  return Status::ok();
}

}  // namespace

Status validate_encode_params(const EncodeParams& p) {
  const auto quality_ok = [](int q) { return q >= 1 && q <= 100; };
  if (p.map_resolution < codec::kMinMapResolution || p.map_resolution > codec::kMaxMapResolution ||
      p.map_resolution % 8 != 0) {
    return invalid_argument("map resolution " + std::to_string(p.map_resolution) +
                            " must be a multiple of 8 between 8 and 64");
  }
  if (!quality_ok(p.height_quality) || !quality_ok(p.color_quality) || !quality_ok(p.intensity_quality)) {
    return invalid_argument("qualities must be between 1 and 100");
  }
  if (p.height_bits != 8 && p.height_bits != 16) {
    return invalid_argument("height bits must be 8 or 16");
  }
  if (p.height_bits == 16 && p.image_codec != ImageCodec::kJpeg2000) {
    return invalid_argument("16-bit heights need the JPEG 2000 image codec (JPEG is 8-bit)");
  }
  if (p.image_codec != ImageCodec::kJpeg && p.image_codec != ImageCodec::kJpeg2000) {
    return invalid_argument("unknown image codec");
  }
  if (p.decomposition != Decomposition::kVoxelGrid && p.decomposition != Decomposition::kOctree) {
    return invalid_argument("unknown decomposition");
  }
  if (!std::isfinite(p.cell_size) || p.cell_size < 0) {
    return invalid_argument("cell size must be a finite non-negative number (0 = automatic)");
  }
  if (p.octree_max_points < 1) return invalid_argument("octree max points (n_l) must be at least 1");
  if (!std::isfinite(p.normal_cone_degrees) || p.normal_cone_degrees < 0 || p.normal_cone_degrees > 180) {
    return invalid_argument("normal cone angle must be between 0 and 180 degrees");
  }
  if (p.fill != FillMethod::kBlockProjection && p.fill != FillMethod::kPushPull && p.fill != FillMethod::kBoxFilter) {
    return invalid_argument("unknown fill method");
  }
  if (p.grid_origin) {
    const Vec3d& o = *p.grid_origin;
    if (!std::isfinite(o.x) || !std::isfinite(o.y) || !std::isfinite(o.z) ||
        !std::isfinite(p.grid_edge) || !(p.grid_edge > 0)) {
      return invalid_argument("grid origin must be finite and grid edge positive");
    }
  }
  return Status::ok();
}

namespace {

// Per-patch accumulation scratch, reused across patches. Only the pixels a
// patch touches are reset, so a patch costs O(points + r^2 / 8), not O(r^2 * 65 bytes).
struct PatchScratch {
  std::vector<double> u, v, h;
  std::vector<std::uint32_t> count;    // r*r, all zero between patches
  std::vector<std::uint32_t> touched;  // pixels with count > 0
  std::vector<double> sum_h;
  std::vector<double> sum_rgb;
  std::vector<double> sum_i;
  std::vector<std::uint8_t> occupied;
  std::vector<float> tile_h, tile_rgb, tile_i;
  // Classification: (pixel << 8 | class) per point, sorted for the
  // per-pixel majority; the tile's class per pixel.
  std::vector<std::uint32_t> class_votes;
  std::vector<std::uint8_t> tile_class;
  codec::FillScratch fill;
};

struct Encoder {
  Encoder(const PointCloud& c, const EncodeParams& p, std::span<const Vec3d> n)
      : cloud(c), count(c.size()), params(p), normals(n) {}

  const PointCloud& cloud;
  std::size_t count;
  const EncodeParams& params;
  std::span<const Vec3d> normals;

  Box3d input_bounds() const { return cloud.bounds(); }

  codec::ChunkHeader header;
  int r = 16;
  std::vector<KeyedIndex> sorted;
  // The points in `sorted` order: patches read contiguous ranges instead of
  // chasing the permutation (which is cache-miss bound on large chunks).
  std::vector<Vec3d> pos;
  std::vector<Rgb8> col;
  std::vector<float> inten;
  std::vector<std::uint8_t> cls;  // classification, when the cloud carries it
  std::vector<std::uint8_t> tree_masks;
  std::vector<Leaf> leaves;

  // Atlas planes (float until the chunk-wide ranges are known).
  std::uint32_t atlas_w = 0, atlas_h = 0;
  std::vector<std::uint8_t> occupancy;
  std::vector<float> heights;    // normalised (height / cell edge), filled
  std::vector<std::uint8_t> rgb;
  std::vector<float> intensity;  // raw intensity, filled
  std::vector<std::uint8_t> class_plane;  // majority class of occupied pixels
  std::vector<std::uint8_t> patch_records;  // structure of arrays, 7 planes
  std::uint64_t decoded_points = 0;
  double h_lo = std::numeric_limits<double>::infinity();
  double h_hi = -std::numeric_limits<double>::infinity();
  float i_lo = std::numeric_limits<float>::infinity();
  float i_hi = -std::numeric_limits<float>::infinity();

  EncodeStats* stats = nullptr;
  std::vector<std::uint8_t> height_stream;      // the full coded height map, when stats are wanted
  std::vector<std::uint32_t> patch_occupied;    // occupied pixels per patch

  Status choose_grid();
  void build_decomposition();
  Status decoded_stats(const std::vector<std::uint8_t>& coded_heights, EncodeStats& out) const;
  void encode_patch(std::size_t index, const Leaf& leaf, PatchScratch& s);
  Result<std::vector<std::uint8_t>> finish();
};

Status Encoder::choose_grid() {
  r = params.map_resolution;
  const double cell = params.cell_size > 0 ? params.cell_size : suggest_cell_size(cloud, r);
  if (!(cell > 0) || !std::isfinite(cell)) {
    return invalid_argument("could not derive a cell size from the points; pass one explicitly");
  }
  Vec3d origin;
  double edge = 0;
  if (params.grid_origin) {
    origin = *params.grid_origin;
    edge = params.grid_edge;
    const Box3d b = input_bounds();
    const double tol = edge * 1e-9;
    if (b.min.x < origin.x - tol || b.min.y < origin.y - tol || b.min.z < origin.z - tol ||
        b.max.x > origin.x + edge + tol || b.max.y > origin.y + edge + tol ||
        b.max.z > origin.z + edge + tol) {
      return invalid_argument("points lie outside the chunk cube given by grid origin and edge");
    }
  } else {
    const Box3d b = input_bounds();
    origin = b.min;
    const Vec3d e = b.extent();
    edge = std::max({e.x, e.y, e.z});
  }
  int depth = 0;
  if (edge > cell) depth = static_cast<int>(std::ceil(std::log2(edge / cell) - 1e-12));
  if (depth > codec::kMaxTreeDepth) {
    return invalid_argument("cell size " + std::to_string(cell) + " is too small for a chunk " +
                            std::to_string(edge) + " across (more than 2^21 cells per axis)");
  }
  // Without a given cube, grow it so cells have exactly the requested edge.
  if (!params.grid_origin) edge = cell * std::ldexp(1.0, depth);
  header.grid_origin = origin;
  header.grid_edge = edge;
  header.tree_depth = static_cast<std::uint8_t>(depth);
  return Status::ok();
}

void Encoder::build_decomposition() {
  const int depth = header.tree_depth;
  const double cells = std::ldexp(1.0, depth);
  const double inv_fine = cells / header.grid_edge;
  const auto max_index = static_cast<std::uint32_t>(cells - 1);
  const Vec3d o = header.grid_origin;
  sorted.resize(count);
  const auto cell_of = [&](double v) {
    const double c = std::floor(v * inv_fine);
    return c <= 0 ? 0u : std::min(max_index, static_cast<std::uint32_t>(c));
  };
  for (std::size_t i = 0; i < count; ++i) {
    const Vec3d& p = cloud.positions[i];
    sorted[i] = {codec::morton_encode(cell_of(p.x - o.x), cell_of(p.y - o.y), cell_of(p.z - o.z)),
                 static_cast<std::uint32_t>(i)};
  }
  codec::radix_sort(sorted, 3 * depth);
  pos.resize(sorted.size());
  for (std::size_t i = 0; i < sorted.size(); ++i) pos[i] = cloud.positions[sorted[i].index];
  if (cloud.has_colors()) {
    col.resize(sorted.size());
    for (std::size_t i = 0; i < sorted.size(); ++i) col[i] = cloud.colors[sorted[i].index];
  }
  if (cloud.has_intensity()) {
    inten.resize(sorted.size());
    for (std::size_t i = 0; i < sorted.size(); ++i) inten[i] = cloud.intensities[sorted[i].index];
  }
  if (!cloud.las.classification.empty()) {
    cls.resize(sorted.size());
    for (std::size_t i = 0; i < sorted.size(); ++i) cls[i] = cloud.las.classification[sorted[i].index];
  }

  codec::LeafPredicate predicate;
  if (params.decomposition == Decomposition::kOctree) {
    const double cos_cone = std::cos(params.normal_cone_degrees * 3.14159265358979323846 / 180.0);
    const bool use_cone = !normals.empty() && params.normal_cone_degrees > 0;
    predicate = [this, cos_cone, use_cone](std::uint32_t b, std::uint32_t e) {
      if (e - b > params.octree_max_points) return false;
      if (!use_cone) return true;
      // Normals are unoriented: align each to the first before averaging.
      const Vec3d first = normals[sorted[b].index];
      Vec3d mean{0, 0, 0};
      for (std::uint32_t i = b; i < e; ++i) {
        const Vec3d n = normals[sorted[i].index];
        mean = mean + (dot(n, first) < 0 ? -1.0 : 1.0) * n;
      }
      const double len = norm(mean);
      if (!(len > 0)) return false;
      for (std::uint32_t i = b; i < e; ++i) {
        const Vec3d n = normals[sorted[i].index];
        if (std::abs(dot(n, mean)) / (len * norm(n)) < cos_cone) return false;
      }
      return true;
    };
  }
  leaves = codec::build_tree(sorted, depth, predicate, tree_masks);
}

void Encoder::encode_patch(std::size_t index, const Leaf& leaf, PatchScratch& s) {
  const std::uint32_t k = leaf.end - leaf.begin;
  const double edge = std::ldexp(header.grid_edge, -leaf.depth);
  const Vec3d o = header.grid_origin;
  const Vec3d center{o.x + (leaf.ix + 0.5) * edge, o.y + (leaf.iy + 0.5) * edge,
                     o.z + (leaf.iz + 0.5) * edge};

  // PCA relative to the cell centre (keeps georeferenced coordinates precise;
  // offsets are at most a cell edge, so one pass of raw moments is accurate).
  double sx = 0, sy = 0, sz = 0, sxx = 0, sxy = 0, sxz = 0, syy = 0, syz = 0, szz = 0;
  for (std::uint32_t i = leaf.begin; i < leaf.end; ++i) {
    const Vec3d d = pos[i] - center;
    sx += d.x;
    sy += d.y;
    sz += d.z;
    sxx += d.x * d.x;
    sxy += d.x * d.y;
    sxz += d.x * d.z;
    syy += d.y * d.y;
    syz += d.y * d.z;
    szz += d.z * d.z;
  }
  const double inv_k = 1.0 / k;
  const Vec3d mean{sx * inv_k, sy * inv_k, sz * inv_k};
  Eigen::Matrix3d cov;
  cov(0, 0) = sxx * inv_k - mean.x * mean.x;
  cov(0, 1) = sxy * inv_k - mean.x * mean.y;
  cov(0, 2) = sxz * inv_k - mean.x * mean.z;
  cov(1, 1) = syy * inv_k - mean.y * mean.y;
  cov(1, 2) = syz * inv_k - mean.y * mean.z;
  cov(2, 2) = szz * inv_k - mean.z * mean.z;
  cov(1, 0) = cov(0, 1);
  cov(2, 0) = cov(0, 2);
  cov(2, 1) = cov(1, 2);
  Vec3d normal{0, 0, 1};
  if (k >= 3) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
    solver.computeDirect(cov);
    const Eigen::Vector3d n = solver.eigenvectors().col(0);
    if (solver.info() == Eigen::Success && n.allFinite() && n.norm() > 0.5) {
      normal = {n.x(), n.y(), n.z()};
    }
  }
  // Canonical sign: largest component positive (heights keep one orientation).
  const double ax = std::abs(normal.x), ay = std::abs(normal.y), az = std::abs(normal.z);
  const double dominant = (az >= ax && az >= ay) ? normal.z : (ay >= ax ? normal.y : normal.x);
  if (dominant < 0) normal = -1.0 * normal;

  codec::QuantizedPatch q;
  codec::octahedral_encode(normal, q.oct_u, q.oct_v);
  const Vec3d n = codec::octahedral_decode(q.oct_u, q.oct_v);
  const double range = codec::kHalfDiagonal * edge;
  q.offset = codec::quantize_param(dot(mean, n), range, 0);
  // Provisional frame for the extents (the offset does not move u, v).
  Vec3d e1, e2;
  codec::axis_aligned_frame(n, e1, e2);
  const double offset = codec::dequantize_param(q.offset, range);
  s.u.resize(k);
  s.v.resize(k);
  s.h.resize(k);
  double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
  for (std::uint32_t i = 0; i < k; ++i) {
    const Vec3d d = pos[leaf.begin + i] - center;
    s.u[i] = dot(d, e1);
    s.v[i] = dot(d, e2);
    s.h[i] = dot(d, n) - offset;
    umin = std::min(umin, s.u[i]);
    umax = std::max(umax, s.u[i]);
    vmin = std::min(vmin, s.v[i]);
    vmax = std::max(vmax, s.v[i]);
  }
  q.umin = codec::quantize_param(umin, range, -1);
  q.umax = codec::quantize_param(umax, range, +1);
  q.vmin = codec::quantize_param(vmin, range, -1);
  q.vmax = codec::quantize_param(vmax, range, +1);
  // A zero-width extent (one point, or collinear along the other axis) still
  // needs a positive pixel pitch.
  if (q.umax <= q.umin) q.umax < 255 ? ++q.umax : --q.umin;
  if (q.vmax <= q.vmin) q.vmax < 255 ? ++q.vmax : --q.vmin;
  const codec::PatchFrame f = codec::make_frame(q, center, edge, r);

  const std::size_t np = patch_records.size() / codec::kPatchRecordSize;
  const std::uint8_t fields[codec::kPatchRecordSize] = {q.oct_u, q.oct_v, q.offset, q.umin,
                                                        q.umax,  q.vmin,  q.vmax};
  for (std::size_t fi = 0; fi < codec::kPatchRecordSize; ++fi) patch_records[fi * np + index] = fields[fi];

  // Bin points into pixels and average.
  const auto rr = static_cast<std::size_t>(r) * static_cast<std::size_t>(r);
  if (s.count.size() != rr) {
    s.count.assign(rr, 0);
    s.sum_h.assign(rr, 0.0);
    s.sum_rgb.assign(rr * 3, 0.0);
    s.sum_i.assign(rr, 0.0);
    s.occupied.assign(rr, 0);
    s.tile_h.assign(rr, 0.0f);
    s.tile_rgb.assign(rr * 3, 0.0f);
    s.tile_i.assign(rr, 0.0f);
    s.tile_class.assign(rr, 0);
  }
  s.touched.clear();
  s.class_votes.clear();
  const bool has_class = !cls.empty();
  const bool has_rgb = cloud.has_colors(), has_i = cloud.has_intensity();
  const double inv_pu = 1.0 / f.pixel_u, inv_pv = 1.0 / f.pixel_v;
  const double rmax = r - 1;
  for (std::uint32_t i = 0; i < k; ++i) {
    // Clamped to [0, r-1] before truncation, so truncation is floor.
    const auto px = static_cast<std::size_t>(std::clamp((s.u[i] - f.umin) * inv_pu, 0.0, rmax));
    const auto py = static_cast<std::size_t>(std::clamp((s.v[i] - f.vmin) * inv_pv, 0.0, rmax));
    const std::size_t pi = py * static_cast<std::size_t>(r) + px;
    if (s.count[pi]++ == 0) {
      s.touched.push_back(static_cast<std::uint32_t>(pi));
      s.sum_h[pi] = 0;
      if (has_rgb) s.sum_rgb[pi * 3] = s.sum_rgb[pi * 3 + 1] = s.sum_rgb[pi * 3 + 2] = 0;
      if (has_i) s.sum_i[pi] = 0;
    }
    s.sum_h[pi] += s.h[i];
    const std::size_t src = leaf.begin + i;
    if (has_rgb) {
      const Rgb8 c = col[src];
      s.sum_rgb[pi * 3] += c.r;
      s.sum_rgb[pi * 3 + 1] += c.g;
      s.sum_rgb[pi * 3 + 2] += c.b;
    }
    if (has_i) s.sum_i[pi] += inten[src];
    if (has_class) s.class_votes.push_back(static_cast<std::uint32_t>(pi << 8 | cls[src]));
  }
  if (has_class) {
    // Majority class per pixel; ties go to the lowest class value.
    std::sort(s.class_votes.begin(), s.class_votes.end());
    std::size_t best_run = 0;
    for (std::size_t a = 0; a < s.class_votes.size();) {
      std::size_t b = a + 1;
      while (b < s.class_votes.size() && s.class_votes[b] == s.class_votes[a]) ++b;
      const std::uint32_t pixel = s.class_votes[a] >> 8;
      if (a == 0 || (s.class_votes[a - 1] >> 8) != pixel) best_run = 0;
      if (b - a > best_run) {
        best_run = b - a;
        s.tile_class[pixel] = static_cast<std::uint8_t>(s.class_votes[a] & 0xFF);
      }
      a = b;
    }
  }
  std::fill(s.occupied.begin(), s.occupied.end(), std::uint8_t{0});
  const double inv_edge = 1.0 / edge;
  for (const std::uint32_t pi : s.touched) {
    s.occupied[pi] = 1;
    const double inv = 1.0 / s.count[pi];
    s.count[pi] = 0;
    const double hn = s.sum_h[pi] * inv * inv_edge;
    s.tile_h[pi] = static_cast<float>(hn);
    h_lo = std::min(h_lo, static_cast<double>(s.tile_h[pi]));
    h_hi = std::max(h_hi, static_cast<double>(s.tile_h[pi]));
    if (has_rgb) {
      for (int c = 0; c < 3; ++c) s.tile_rgb[pi * 3 + c] = static_cast<float>(s.sum_rgb[pi * 3 + c] * inv);
    }
    if (has_i) {
      s.tile_i[pi] = static_cast<float>(s.sum_i[pi] * inv);
      i_lo = std::min(i_lo, s.tile_i[pi]);
      i_hi = std::max(i_hi, s.tile_i[pi]);
    }
  }
  decoded_points += s.touched.size();
  patch_occupied[index] = static_cast<std::uint32_t>(s.touched.size());
  // A fully occupied tile has nothing to fill.
  if (s.touched.size() < rr) {
    const auto fill = [&](std::vector<float>& tile, int channels, int block) {
      if (params.fill == FillMethod::kBoxFilter) {
        codec::fill_box(tile.data(), s.occupied.data(), r, channels, s.fill);
        return;
      }
      codec::fill_push_pull(tile.data(), s.occupied.data(), r, channels, s.fill);
      if (params.fill == FillMethod::kBlockProjection) {
        codec::project_blocks_low_frequency(tile.data(), s.occupied.data(), r, channels, block);
      }
    };
    fill(s.tile_h, 1, kLumaBlock);
    if (has_rgb) {
      // Colour: the paper's box filter measured smallest at equal colour error
      // (bench/codec fill rows), better than projecting 8x8 or 16x16 blocks.
      if (params.fill == FillMethod::kBlockProjection) {
        codec::fill_box(s.tile_rgb.data(), s.occupied.data(), r, 3, s.fill);
      } else {
        fill(s.tile_rgb, 3, kLumaBlock);
      }
    }
    if (has_i) fill(s.tile_i, 1, kLumaBlock);
  }

  // Copy the tile into the atlas planes.
  std::uint32_t tx = 0, ty = 0;
  codec::tile_position(static_cast<std::uint32_t>(index), tx, ty);
  for (int y = 0; y < r; ++y) {
    const std::size_t row = (static_cast<std::size_t>(ty) * r + y) * atlas_w + static_cast<std::size_t>(tx) * r;
    const std::size_t src = static_cast<std::size_t>(y) * r;
    for (int x = 0; x < r; ++x) {
      occupancy[row + x] = s.occupied[src + x];
      heights[row + x] = s.tile_h[src + x];
      if (has_rgb) {
        for (int c = 0; c < 3; ++c) {
          // Clamped to [0, 255], so adding 0.5 and truncating rounds to nearest.
          const float val = std::clamp(s.tile_rgb[(src + x) * 3 + c], 0.0f, 255.0f);
          rgb[(row + x) * 3 + c] = static_cast<std::uint8_t>(val + 0.5f);
        }
      }
      if (has_i) intensity[row + x] = s.tile_i[src + x];
      if (has_class) class_plane[row + x] = s.occupied[src + x] ? s.tile_class[src + x] : 0;
    }
  }
}

// Compresses with LZMA unless that does not shrink the data.
Result<SectionEntry> lzma_section(SectionId id, std::vector<std::uint8_t>& raw,
                                  std::vector<std::vector<std::uint8_t>>& storage) {
  SectionEntry e;
  e.id = id;
  e.raw_size = static_cast<std::uint32_t>(raw.size());
  RELIEF_ASSIGN_OR_RETURN(std::vector<std::uint8_t> packed, codec::lzma_compress(raw));
  if (packed.size() < raw.size()) {
    e.codec = SectionCodec::kLzma2;
    storage.push_back(std::move(packed));
  } else {
    e.codec = SectionCodec::kStored;
    storage.push_back(raw);
  }
  return e;
}

// Quantizes a float plane to `levels` over [lo, hi]; NaN (unused tiles) maps
// to mid-range so those tiles are flat.
template <typename Sample>
std::vector<Sample> quantize_plane(const std::vector<float>& plane, double lo, double hi, double levels) {
  std::vector<Sample> out(plane.size());
  const double scale = hi > lo ? levels / (hi - lo) : 0.0;
  const auto mid = static_cast<Sample>(levels / 2);
  for (std::size_t i = 0; i < plane.size(); ++i) {
    const float v = plane[i];
    if (std::isnan(v)) {
      out[i] = mid;
      continue;
    }
    // Clamped to [0, levels] first, so +0.5 and truncation round to nearest.
    const double q = std::clamp((static_cast<double>(v) - lo) * scale, 0.0, levels);
    out[i] = static_cast<Sample>(q + 0.5);
  }
  return out;
}

// A JPEG section: abbreviated (tables implied by the quality) when the stream
// carries exactly the standard tables, else the full stream.
Result<SectionEntry> jpeg_section(SectionId id, const codec::Image8& img, int quality, bool subsample,
                                  std::vector<std::vector<std::uint8_t>>& storage,
                                  std::vector<std::uint8_t>* full_copy = nullptr) {
  RELIEF_ASSIGN_OR_RETURN(std::vector<std::uint8_t> coded, codec::jpeg_encode(img, quality, subsample));
  if (full_copy) *full_copy = coded;
  SectionEntry e{id, SectionCodec::kJpeg, static_cast<std::uint32_t>(img.pixels.size()), 0, {}};
  if (auto brief = codec::jpeg_abbreviate(coded, quality, img.channels)) {
    brief->insert(brief->begin(), static_cast<std::uint8_t>(quality));
    e.codec = SectionCodec::kJpegAbbreviated;
    storage.push_back(std::move(*brief));
  } else {
    storage.push_back(std::move(coded));
  }
  return e;
}

Result<std::vector<std::uint8_t>> Encoder::finish() {
  const bool has_rgb = cloud.has_colors(), has_i = cloud.has_intensity();
  header.decoded_points = static_cast<std::uint32_t>(decoded_points);
  // One height step for every chunk: a range fixed in cell edges, wide enough
  // for any height a patch can have (|h| <= sqrt(3) cell edges). A range taken
  // from each chunk's data made small chunks quantise finer and cost several
  // times more (bench/ingest chunk sweep); with a fixed step the archive size
  // no longer depends on the chunk size.
  h_lo = -kHeightRange;
  h_hi = kHeightRange;
  header.height_min = h_lo;
  header.height_max = h_hi;
  if (has_i) {
    if (params.intensity_range) {
      i_lo = std::min(params.intensity_range->first, i_lo);
      i_hi = std::max(params.intensity_range->second, i_hi);
    }
    header.intensity_min = i_lo;
    header.intensity_max = i_hi;
  }
  std::vector<std::vector<std::uint8_t>> storage;
  storage.reserve(6);
  std::vector<SectionEntry> sections;

  RELIEF_ASSIGN_OR_RETURN(SectionEntry tree, lzma_section(SectionId::kTree, tree_masks, storage));
  sections.push_back(tree);
  RELIEF_ASSIGN_OR_RETURN(SectionEntry patches, lzma_section(SectionId::kPatches, patch_records, storage));
  sections.push_back(patches);

  RELIEF_ASSIGN_OR_RETURN(std::vector<std::uint8_t> occ, codec::bilevel_encode(occupancy, atlas_w, atlas_h));
  sections.push_back({SectionId::kOccupancy, SectionCodec::kJbig85,
                      static_cast<std::uint32_t>(occupancy.size()), 0, {}});
  storage.push_back(std::move(occ));

  const bool jpeg = params.image_codec == ImageCodec::kJpeg;
  const SectionCodec image_codec = jpeg ? SectionCodec::kJpeg : SectionCodec::kJpeg2000;
  const std::uint32_t pixels = atlas_w * atlas_h;
  if (params.height_bits == 16) {
    codec::Image16 img{atlas_w, atlas_h, quantize_plane<std::uint16_t>(heights, h_lo, h_hi, 65535.0)};
    RELIEF_ASSIGN_OR_RETURN(std::vector<std::uint8_t> coded, codec::j2k_encode16(img, params.height_quality));
    if (stats) height_stream = coded;
    storage.push_back(std::move(coded));
    sections.push_back({SectionId::kHeight, image_codec, pixels * 2, 0, {}});
  } else {
    codec::Image8 img{atlas_w, atlas_h, 1, quantize_plane<std::uint8_t>(heights, h_lo, h_hi, 255.0)};
    if (jpeg) {
      RELIEF_ASSIGN_OR_RETURN(SectionEntry s, jpeg_section(SectionId::kHeight, img, params.height_quality, false,
                                                           storage, stats ? &height_stream : nullptr));
      sections.push_back(s);
    } else {
      RELIEF_ASSIGN_OR_RETURN(std::vector<std::uint8_t> coded, codec::j2k_encode8(img, params.height_quality));
      if (stats) height_stream = coded;
      storage.push_back(std::move(coded));
      sections.push_back({SectionId::kHeight, image_codec, pixels, 0, {}});
    }
  }
  if (has_rgb) {
    codec::Image8 img{atlas_w, atlas_h, 3, std::move(rgb)};
    if (jpeg) {
      RELIEF_ASSIGN_OR_RETURN(SectionEntry s, jpeg_section(SectionId::kColor, img, params.color_quality, true, storage));
      sections.push_back(s);
    } else {
      RELIEF_ASSIGN_OR_RETURN(std::vector<std::uint8_t> coded, codec::j2k_encode8(img, params.color_quality));
      storage.push_back(std::move(coded));
      sections.push_back({SectionId::kColor, image_codec, pixels * 3, 0, {}});
    }
  }
  if (has_i) {
    codec::Image8 img{atlas_w, atlas_h, 1, quantize_plane<std::uint8_t>(intensity, i_lo, i_hi, 255.0)};
    if (jpeg) {
      RELIEF_ASSIGN_OR_RETURN(SectionEntry s,
                              jpeg_section(SectionId::kIntensity, img, params.intensity_quality, false, storage));
      sections.push_back(s);
    } else {
      RELIEF_ASSIGN_OR_RETURN(std::vector<std::uint8_t> coded, codec::j2k_encode8(img, params.intensity_quality));
      storage.push_back(std::move(coded));
      sections.push_back({SectionId::kIntensity, image_codec, pixels, 0, {}});
    }
  }
  if (!cls.empty()) {
    // The occupied pixels' classes in atlas raster order (format-spec/chunk.md §7).
    LasAttributes map;
    map.classification.reserve(header.decoded_points);
    for (std::size_t a = 0; a < occupancy.size(); ++a) {
      if (occupancy[a]) map.classification.push_back(class_plane[a]);
    }
    storage.push_back(codec::encode_las_attribute(kLasClassification, map, map.classification.size()));
    sections.push_back({SectionId::kClassMap, SectionCodec::kArithmetic,
                        static_cast<std::uint32_t>(map.classification.size()), 0, {}});
    header.flags |= codec::kFlagClassMap;
    header.version = 4;  // the bounded encoder moves these sections into its own version-3 blob
  }
  for (std::size_t i = 0; i < sections.size(); ++i) {
    sections[i].payload = storage[i];
    sections[i].coded_size = static_cast<std::uint32_t>(storage[i].size());
  }
  if (stats) RELIEF_RETURN_IF_ERROR(decoded_stats(height_stream, *stats));
  return codec::write_blob(header, sections);
}

// The decoded points' count and exact bounds, from this encoder's occupancy
// and patch records and the decoded height map: the same reconstruction a
// decoder runs (reconstruct.h), without decoding occupancy or attributes.
Status Encoder::decoded_stats(const std::vector<std::uint8_t>& coded_heights, EncodeStats& out) const {
  codec::Image8 h8;
  codec::Image16 h16;
  codec::MapsView maps;
  if (params.height_bits == 16) {
    RELIEF_ASSIGN_OR_RETURN(h16, codec::j2k_decode16(coded_heights, atlas_w, atlas_h));
    maps.height16 = h16.pixels.data();
  } else if (params.image_codec == ImageCodec::kJpeg) {
    RELIEF_ASSIGN_OR_RETURN(h8, codec::jpeg_decode(coded_heights, atlas_w, atlas_h, 1));
    maps.height8 = h8.pixels.data();
  } else {
    RELIEF_ASSIGN_OR_RETURN(h8, codec::j2k_decode8(coded_heights, atlas_w, atlas_h, 1));
    maps.height8 = h8.pixels.data();
  }
  maps.header = &header;
  maps.leaves = &leaves;
  maps.records = patch_records.data();
  maps.occupancy = occupancy.data();
  maps.atlas_width = atlas_w;
  Box3d bounds;
  for (std::uint32_t p = 0; p < header.patch_count; ++p) {
    codec::reconstruct_patch(maps, p, patch_occupied[p], patch_occupied[p],
                             [&](std::size_t, const Vec3d& point) { bounds.add(point); });
  }
  out.decoded_points = header.decoded_points;
  out.decoded_bounds = bounds;
  out.point_bounds = bounds;
  return Status::ok();
}

}  // namespace

namespace {

// Copies cloud[subset[i]] into `out` in subset order, checking each index and
// each point on the way: one pass of (cache-missing) reads from the shared
// cloud, after which the encoder works on contiguous memory.
Status gather_subset(const PointCloud& cloud, std::span<const std::uint32_t> subset, PointCloud& out) {
  if ((!cloud.colors.empty() && cloud.colors.size() != cloud.size()) ||
      (!cloud.intensities.empty() && cloud.intensities.size() != cloud.size())) {
    return invalid_argument("chunk: attribute arrays do not match the positions");
  }
  const std::size_t n = subset.size();
  if (!cloud.las.empty()) {
    // The LAS attributes travel with their points. Only the subset is copied
    // (an ingest encodes many subsets of one large cloud); the sizes are
    // checked against the whole cloud and the copy by validate() below.
    LasAttributes& dst = out.las;
    const LasAttributes& src = cloud.las;
    dst.extra_bytes_size = src.extra_bytes_size;
    bool sizes_ok = true;
    const auto gather = [&](const auto& from, auto& to) {
      if (from.empty()) return;
      if (from.size() != cloud.size()) {
        sizes_ok = false;
        return;
      }
      to.resize(n);
      for (std::size_t k = 0; k < n; ++k) to[k] = subset[k] < from.size() ? from[subset[k]] : to[k];
    };
    LasAttributes::for_each_vector_pair(src, dst, [&](const auto& from, auto& to, std::uint32_t) { gather(from, to); });
    if (!src.extra_bytes.empty()) {
      const std::size_t w = src.extra_bytes_size;
      if (w == 0 || src.extra_bytes.size() != cloud.size() * w) {
        sizes_ok = false;
      } else {
        dst.extra_bytes.resize(n * w);
        for (std::size_t k = 0; k < n; ++k) {
          if (subset[k] >= cloud.size()) continue;  // refused below
          std::copy_n(src.extra_bytes.begin() + static_cast<std::ptrdiff_t>(subset[k] * w), w,
                      dst.extra_bytes.begin() + static_cast<std::ptrdiff_t>(k * w));
        }
      }
    }
    if (!sizes_ok) return invalid_argument("chunk: LAS attribute arrays do not match the positions");
  }
  out.positions.resize(n);
  out.colors.resize(cloud.has_colors() ? n : 0);
  out.intensities.resize(cloud.has_intensity() ? n : 0);
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t i = subset[k];
    if (i >= cloud.size()) return invalid_argument("chunk: subset index " + std::to_string(i) + " out of range");
    const Vec3d& p = cloud.positions[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      return invalid_argument("chunk: point " + std::to_string(i) + " has a non-finite coordinate");
    }
    out.positions[k] = p;
  }
  if (cloud.has_colors()) {
    for (std::size_t k = 0; k < n; ++k) out.colors[k] = cloud.colors[subset[k]];
  }
  if (cloud.has_intensity()) {
    for (std::size_t k = 0; k < n; ++k) {
      const float v = cloud.intensities[subset[k]];
      if (!std::isfinite(v)) {
        return invalid_argument("chunk: point " + std::to_string(subset[k]) + " has a non-finite intensity");
      }
      out.intensities[k] = v;
    }
  }
  // GPS times finite, colour low bytes only with colours.
  if (!out.las.empty()) RELIEF_RETURN_IF_ERROR(out.validate("chunk"));
  return Status::ok();
}

// `validated`: the caller has already checked the points (gather_subset).
Result<std::vector<std::uint8_t>> encode_impl(const PointCloud& cloud, const EncodeParams& params,
                                              std::span<const Vec3d> normals, EncodeStats* stats, bool validated) {
  const std::size_t count = cloud.size();
  RELIEF_RETURN_IF_ERROR(check_params(params, count, normals.size()));
  if (!validated) RELIEF_RETURN_IF_ERROR(cloud.validate("chunk"));
  for (std::size_t i = 0; i < normals.size(); ++i) {
    const Vec3d& n = normals[i];
    if (!std::isfinite(n.x) || !std::isfinite(n.y) || !std::isfinite(n.z) || norm(n) < 1e-12) {
      return invalid_argument("chunk: normal " + std::to_string(i) + " is not a finite non-zero vector");
    }
  }
  if (count > kMaxChunkPoints) {
    return limit_exceeded("chunk: " + std::to_string(count) + " points exceed the limit of " +
                          std::to_string(kMaxChunkPoints) + " per chunk");
  }
  if (params.bound) return codec::encode_bounded(cloud, params, stats);
  Encoder enc{cloud, params, normals};
  codec::ChunkHeader& h = enc.header;
  h.flags = static_cast<std::uint8_t>((cloud.has_colors() ? codec::kFlagColors : 0) |
                                      (cloud.has_intensity() ? codec::kFlagIntensity : 0));
  h.decomposition = params.decomposition;
  h.image_codec = params.image_codec;
  h.map_resolution = static_cast<std::uint8_t>(params.map_resolution);
  h.height_bits = static_cast<std::uint8_t>(params.height_bits);
  h.input_points = static_cast<std::uint32_t>(count);
  if (count == 0) {
    h.grid_edge = 1;
    if (stats) *stats = EncodeStats{};
    return codec::write_blob(h, {});
  }
  RELIEF_RETURN_IF_ERROR(enc.choose_grid());
  enc.build_decomposition();
  h.patch_count = static_cast<std::uint32_t>(enc.leaves.size());
  const codec::AtlasLayout layout = codec::atlas_layout(h.patch_count);
  const auto r = static_cast<std::uint32_t>(params.map_resolution);
  if (static_cast<std::uint64_t>(layout.tiles_x) * r > codec::kMaxImageSide ||
      static_cast<std::uint64_t>(layout.tiles_x) * layout.tiles_y * r * r > kMaxAtlasPixels) {
    return limit_exceeded("chunk: " + std::to_string(h.patch_count) +
                          " patches do not fit one atlas image; use a larger cell size or smaller chunks");
  }
  h.tiles_x = static_cast<std::uint16_t>(layout.tiles_x);
  h.tiles_y = static_cast<std::uint16_t>(layout.tiles_y);
  enc.atlas_w = layout.tiles_x * r;
  enc.atlas_h = layout.tiles_y * r;
  const std::size_t pixels = static_cast<std::size_t>(enc.atlas_w) * enc.atlas_h;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  enc.occupancy.assign(pixels, 0);
  enc.heights.assign(pixels, nan);
  if (cloud.has_colors()) enc.rgb.assign(pixels * 3, 128);
  if (cloud.has_intensity()) enc.intensity.assign(pixels, nan);
  if (!cloud.las.classification.empty()) enc.class_plane.assign(pixels, 0);
  enc.patch_records.assign(enc.leaves.size() * codec::kPatchRecordSize, 0);
  enc.patch_occupied.assign(enc.leaves.size(), 0);
  enc.stats = stats;
  PatchScratch scratch;
  for (std::size_t i = 0; i < enc.leaves.size(); ++i) enc.encode_patch(i, enc.leaves[i], scratch);
  return enc.finish();
}

}  // namespace

Result<std::vector<std::uint8_t>> encode_chunk(const PointCloud& cloud, const EncodeParams& params,
                                               std::span<const Vec3d> normals, EncodeStats* stats) {
  return encode_impl(cloud, params, normals, stats, false);
}

Result<std::vector<std::uint8_t>> encode_chunk_subset(const PointCloud& cloud, std::span<const std::uint32_t> subset,
                                                      const EncodeParams& params, EncodeStats* stats) {
  if (subset.empty()) return encode_impl(PointCloud(), params, {}, stats, true);
  if (params.cell_size == 0) return invalid_argument("chunk: encoding a subset needs an explicit cell size");
  // A subset that is the whole cloud in its order (a load holding one chunk,
  // the largest an encoder sees) is encoded in place: a copy would add ~50
  // bytes a point to the encoder's peak.
  bool whole = subset.size() == cloud.size();
  for (std::size_t k = 0; whole && k < subset.size(); ++k) whole = subset[k] == k;
  if (whole) return encode_impl(cloud, params, {}, stats, false);
  PointCloud gathered;
  RELIEF_RETURN_IF_ERROR(gather_subset(cloud, subset, gathered));
  return encode_impl(gathered, params, {}, stats, true);
}

double suggest_cell_size(const PointCloud& cloud, int map_resolution) {
  return cell_size_for_density(cloud, static_cast<double>(map_resolution) * map_resolution);
}

double cell_size_for_density(const PointCloud& cloud, double points_per_cell) {
  const Box3d b = cloud.bounds();
  if (b.empty()) return 1.0;
  const Vec3d e = b.extent();
  const double extent = std::max({e.x, e.y, e.z});
  if (!(extent > 0)) return 1.0;
  // One sort of the finest Morton keys gives the number of occupied cells at
  // every power-of-two cell size (distinct key prefixes). Pick the level whose
  // cells hold about r^2 points -- one point per map pixel on a locally flat
  // surface -- and refine between levels with the surface model
  // points-per-cell ~ cell^2.
  constexpr int kLevels = kDensityLevels;
  const double finest = extent / std::ldexp(1.0, kLevels);
  const double inv = 1.0 / finest;
  const double max_index = std::ldexp(1.0, kLevels) - 1;
  // Morton keys of the finest cells, shifted down to their top `levels` levels.
  std::vector<codec::KeyedIndex> keys(cloud.size());
  const auto make_keys = [&](int levels) {
    const int shift = 3 * (kLevels - levels);
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      const Vec3d& p = cloud.positions[i];
      const auto cx = static_cast<std::uint32_t>(std::min(max_index, (p.x - b.min.x) * inv));
      const auto cy = static_cast<std::uint32_t>(std::min(max_index, (p.y - b.min.y) * inv));
      const auto cz = static_cast<std::uint32_t>(std::min(max_index, (p.z - b.min.z) * inv));
      keys[i] = {codec::morton_encode(cx, cy, cz) >> shift, 0};
    }
  };
  const double n = static_cast<double>(cloud.size());
  const double target = std::max(points_per_cell, 1e-9);
  // Sorts keys by their top `levels` levels and walks those levels; returns 0
  // when none of them reaches the target.
  const auto pick = [&](std::vector<codec::KeyedIndex>& sorted, int levels) -> double {
    codec::radix_sort(sorted, 3 * levels);
    // first_diff[L]: adjacent keys whose prefixes first differ at level L, so
    // occupied(L) = 1 + sum of first_diff[0..L].
    std::vector<std::uint64_t> first_diff(static_cast<std::size_t>(levels) + 1, 0);
    for (std::size_t i = 1; i < sorted.size(); ++i) {
      const std::uint64_t x = sorted[i].key ^ sorted[i - 1].key;
      if (x == 0) continue;
      const int top_bit = 63 - __builtin_clzll(x);
      // Bits [3(k-L-1), 3(k-L)) hold level L's digit (level 1 = the top triple).
      const int level = levels - top_bit / 3;
      ++first_diff[static_cast<std::size_t>(level)];
    }
    double occupied = 1;
    double prev_cell = extent, prev_per_cell = n;
    for (int level = 1; level <= levels; ++level) {
      occupied += static_cast<double>(first_diff[static_cast<std::size_t>(level)]);
      const double cell = extent / std::ldexp(1.0, level);
      const double per_cell = n / occupied;
      if (per_cell <= target) {
        // Between prev (>= target) and this level: per_cell ~ cell^2.
        const double c = prev_cell * std::sqrt(target / prev_per_cell);
        return std::clamp(c, cell, prev_cell);
      }
      prev_cell = cell;
      prev_per_cell = per_cell;
    }
    return 0;
  };
  // Most clouds reach the target within the top levels. Their prefixes are the
  // top bits of the keys, and sorting by those alone (half the radix passes)
  // gives exactly the same counts for those levels; the full sort is needed
  // only when no coarse level gets there.
  constexpr int kCoarseLevels = 8;
  make_keys(kCoarseLevels);
  if (const double c = pick(keys, kCoarseLevels); c > 0) return c;
  make_keys(kLevels);
  if (const double c = pick(keys, kLevels); c > 0) return c;
  return finest;
}

}  // namespace relief
