// Error-bounded chunk encoder (format 2). Mirror: bounded_decoder.cpp.
//
// The blob depends only on the multiset of input points and the parameters:
// points are put in a canonical order (Morton order of their grid cell, then
// by attributes within a cell) before anything is coded, and the base layer
// is encoded from the decoded (snapped) points in that order.
#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "codec/attribute_coder.h"
#include "codec/bounded.h"
#include "codec/geometry_coder.h"
#include "codec/las_attribute_coder.h"
#include "codec/octree.h"
#include "codec/scan_geometry_coder.h"
#include "core/grid_index.h"

namespace relief::codec {

namespace {

Status check_bound(const ErrorBound& b) {
  const Vec3d& s = b.step;
  const Vec3d& o = b.origin;
  if (!(std::isfinite(s.x) && std::isfinite(s.y) && std::isfinite(s.z) && s.x > 0 && s.y > 0 && s.z > 0)) {
    return invalid_argument("tolerance must be a finite positive number (the quantisation step is twice it)");
  }
  if (!(std::isfinite(o.x) && std::isfinite(o.y) && std::isfinite(o.z))) {
    return invalid_argument("quantisation origin must be finite");
  }
  if (b.color_tolerance < 0 || b.color_tolerance > kMaxColorTolerance) {
    return invalid_argument("colour tolerance must be between 0 and " + std::to_string(kMaxColorTolerance));
  }
  if (b.intensity_tolerance < 0 || b.intensity_tolerance > kMaxIntensityTolerance) {
    return invalid_argument("intensity tolerance must be between 0 and " + std::to_string(kMaxIntensityTolerance));
  }
  return Status::ok();
}

std::uint32_t float_bits(float v) {
  std::uint32_t u = 0;
  std::memcpy(&u, &v, sizeof u);
  return u;
}

std::vector<std::uint32_t> order_indices(const std::vector<KeyedIndex>& order) {
  std::vector<std::uint32_t> perm(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) perm[k] = order[k].index;
  return perm;
}

CellXyz cell_of(const std::vector<std::int64_t>& q, const std::int64_t lo[3], std::size_t i) {
  return {static_cast<std::uint32_t>(q[3 * i] - lo[0]), static_cast<std::uint32_t>(q[3 * i + 1] - lo[1]),
          static_cast<std::uint32_t>(q[3 * i + 2] - lo[2])};
}

std::vector<CellXyz> cells_in_order(const std::vector<std::int64_t>& q, const std::int64_t lo[3],
                                    const std::vector<KeyedIndex>& order) {
  std::vector<CellXyz> cells(order.size());
  for (std::size_t k = 0; k < order.size(); ++k) cells[k] = cell_of(q, lo, order[k].index);
  return cells;
}

// The layer in time order (format 8, §11.3.3): its geometry and GPS time
// sections, and the order (every section's).
struct ScanCoding {
  std::vector<std::uint8_t> geometry, gps;
  // The points in time order (key: the cell's Morton code, index: the input point).
  std::vector<KeyedIndex> order;
  // The identity: the time-ordered sections (§11.7.2) follow the layer.
  std::vector<std::uint32_t> time_order;
  // The times step back somewhere in the layer's order (only in a given
  // order): the GPS section needs format 14.
  bool times_step_back = false;
};

// The time order: GPS time (bit pattern), return number, cell, then
// `attr_less` (the attributes, as within a cell), so that it depends only on
// the multiset of points. Or, `given_order`, the order of `cloud` itself
// (ErrorBound::keep_order), GPS times or not.
template <typename Less>
ScanCoding encode_in_time_order(const PointCloud& cloud, const std::vector<std::int64_t>& q, const std::int64_t lo[3],
                                int depth, const Less& attr_less, bool given_order = false) {
  const std::size_t n = cloud.size();
  const LasAttributes& las = cloud.las;
  const bool has_rn = !las.return_number.empty(), has_nr = !las.number_of_returns.empty();
  const bool has_time = !las.gps_time.empty();
  std::vector<KeyedIndex> t(n);
  if (given_order) {
    for (std::size_t k = 0; k < n; ++k) {
      const CellXyz c = cell_of(q, lo, k);
      t[k] = {morton_encode(c[0], c[1], c[2]), static_cast<std::uint32_t>(k)};
    }
  } else {
    // By time first (a radix sort on the bit patterns), then each run of
    // equal times (a pulse's returns) by the rest.
    const std::vector<std::uint32_t> by_time = las_time_order(las.gps_time);
    for (std::size_t k = 0; k < n; ++k) {
      const CellXyz c = cell_of(q, lo, by_time[k]);
      t[k] = {morton_encode(c[0], c[1], c[2]), by_time[k]};
    }
    const auto rest_less = [&](const KeyedIndex& a, const KeyedIndex& b) {
      if (has_rn && las.return_number[a.index] != las.return_number[b.index]) {
        return las.return_number[a.index] < las.return_number[b.index];
      }
      if (a.key != b.key) return a.key < b.key;
      return attr_less(a, b);
    };
    const auto time_of = [&](const KeyedIndex& e) { return std::bit_cast<std::uint64_t>(las.gps_time[e.index]); };
    for (std::size_t i = 0; i < n;) {
      std::size_t j = i + 1;
      while (j < n && time_of(t[j]) == time_of(t[i])) ++j;
      if (j - i > 1) std::sort(t.begin() + static_cast<std::ptrdiff_t>(i), t.begin() + static_cast<std::ptrdiff_t>(j), rest_less);
      i = j;
    }
  }
  std::vector<CellXyz> cells(n);
  std::vector<double> times(has_time ? n : 0);
  std::vector<std::uint8_t> rn(has_rn ? n : 0), nr(has_nr ? n : 0);
  std::vector<std::uint32_t> identity(n);
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = t[k].index;
    cells[k] = cell_of(q, lo, i);
    if (has_time) times[k] = las.gps_time[i];
    if (has_rn) rn[k] = las.return_number[i];
    if (has_nr) nr[k] = las.number_of_returns[i];
    identity[k] = static_cast<std::uint32_t>(k);
  }
  // Without GPS times (format 14) the geometry has no pulse context.
  const std::vector<std::uint8_t> kinds = has_time ? las_pulse_kinds(times, identity) : std::vector<std::uint8_t>{};
  const std::vector<std::uint8_t> multiples = scan_pulse_multiples(times);
  ScanCoding out;
  out.geometry = encode_scan_geometry(cells, depth, ScanContext{kinds, multiples, rn, nr});
  for (std::size_t k = 1; k < times.size() && !out.times_step_back; ++k) {
    out.times_step_back = std::bit_cast<std::uint64_t>(times[k]) < std::bit_cast<std::uint64_t>(times[k - 1]);
  }
  if (has_time) out.gps = encode_gps_in_order(times, out.times_step_back);
  // The layer is in time order too.
  out.order = std::move(t);
  out.time_order = std::move(identity);
  return out;
}

}  // namespace

// Whether the octree could beat the time order (format 8 on, §11.3.3): for
// a large blob, a trial codes the octree of the first 1/kOctreeTrialShare of
// the points in time order (a few scan lines) within that share of the
// time-ordered geometry and GPS sections. The trial leaves out the ranked
// GPS times the octree would also need, so it errs towards trying; it saves
// coding most of a losing octree (a quarter of the encoder's time on
// airborne scans). When the two are close the trial runs nearly to its end,
// so it codes a thirty-second of the points (an eighth until codec 13) with
// codec 12 whatever the blob's octree codec (codec 13 takes twice its time
// for 1-3 % fewer bytes on such samples). Small blobs always try.
constexpr std::size_t kOctreeTrialPoints = std::size_t{1} << 16;
constexpr std::size_t kOctreeTrialShare = 32;

// Sections that may follow either order are tried on a sample first from
// this many points on (encode_bounded).
constexpr std::size_t kOrderTrialPoints = std::size_t{1} << 18;
// What the sample says: code the section in both orders and keep the
// smaller, or in one order alone.
enum class OrderChoice { kTry, kLayer, kCells };
// One order wins the trial when it is smaller by more than 1/kOrderTrialMargin.
constexpr std::size_t kOrderTrialMargin = 32;
bool octree_may_win(const std::vector<KeyedIndex>& time_order, int depth, std::size_t scan_bytes) {
  const std::size_t n = time_order.size();
  if (n < kOctreeTrialPoints) return true;
  const std::size_t m = n / kOctreeTrialShare;
  std::vector<std::uint64_t> keys(m);
  for (std::size_t k = 0; k < m; ++k) keys[k] = time_order[k].key;
  std::sort(keys.begin(), keys.end());
  OccupiedCells trial;
  for (std::size_t i = 0; i < m;) {
    std::size_t j = i + 1;
    while (j < m && keys[j] == keys[i]) ++j;
    trial.keys.push_back(keys[i]);
    trial.counts.push_back(static_cast<std::uint32_t>(j - i));
    i = j;
  }
  const std::uint64_t share = std::uint64_t{scan_bytes} * m / n;  // both below 2^32: no overflow
  return encode_geometry_within(trial, depth, OctreeCoding::kFacePatterns, share).has_value();
}

Result<std::vector<std::uint8_t>> encode_bounded(const PointCloud& cloud, const EncodeParams& params,
                                                 EncodeStats* stats) {
  const ErrorBound& bound = *params.bound;
  RELIEF_RETURN_IF_ERROR(check_bound(bound));
  const std::size_t n = cloud.size();
  const bool has_rgb = cloud.has_colors();
  const bool has_i = cloud.has_intensity();

  ChunkHeader h;
  // 13: geometry codec 9 (time order; 17 below for the octree, codec 14), colour codec 6 or 10, voted LAS
  // bytes, an intensity tolerance; 14 (below) for keep_order's scan order
  // without GPS times or with times that step back.
  h.version = kOrderFreeFormatVersion;
  h.flags = static_cast<std::uint8_t>((has_rgb ? kFlagColors : 0) | (has_i ? kFlagIntensity : 0));
  h.decomposition = params.decomposition;
  h.image_codec = params.image_codec;
  h.map_resolution = static_cast<std::uint8_t>(params.map_resolution);
  h.height_bits = static_cast<std::uint8_t>(params.height_bits);
  h.quant_step = bound.step;
  h.quant_origin = bound.origin;
  h.color_tolerance = static_cast<std::uint8_t>(has_rgb ? bound.color_tolerance : 0);
  // The LAS attributes the points carry (sections 10-21), possibly none.
  const std::uint32_t las_bits = cloud.las.carried();
  if (las_bits != 0) {
    if (cloud.las.extra_bytes_size > kMaxExtraBytesSize) {
      return invalid_argument("chunk: " + std::to_string(cloud.las.extra_bytes_size) +
                              " extra bytes per point, more than a LAS record holds");
    }
    h.las_attributes = las_bits;
    h.extra_bytes_size = (las_bits & kLasExtraBytes) != 0 ? cloud.las.extra_bytes_size : 0;
  }
  if (n == 0) {
    h.grid_edge = 1;
    h.intensity_coding = has_i ? IntensityCoding::kUInt16 : IntensityCoding::kNone;
    if (stats) *stats = EncodeStats{};
    return write_blob(h, {});
  }

  // ---- Snap every point to the grid.
  const double steps[3] = {bound.step.x, bound.step.y, bound.step.z};
  const double origins[3] = {bound.origin.x, bound.origin.y, bound.origin.z};
  std::vector<std::int64_t> q(3 * n);
  std::int64_t lo[3] = {INT64_MAX, INT64_MAX, INT64_MAX};
  std::int64_t hi[3] = {INT64_MIN, INT64_MIN, INT64_MIN};
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3d& p = cloud.positions[i];
    const double c[3] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; ++a) {
      // The nearest index, or its neighbour where the nearest decodes (in
      // double) beyond half a step from the point: within it, always.
      const std::optional<std::int64_t> k = core::grid_index_within(c[a], origins[a], steps[a]);
      if (!k && !core::grid_index_in_range(c[a], origins[a], steps[a])) {
        return invalid_argument("chunk: point " + std::to_string(i) + " lies " + std::to_string(c[a]) +
                                " from the quantisation origin, more than 4e18 steps of " +
                                std::to_string(steps[a]));
      }
      if (!k) {
        return invalid_argument("chunk: point " + std::to_string(i) + ": " +
                                core::grid_too_fine_text(c[a], steps[a]));
      }
      const std::int64_t v = *k;
      q[3 * i + a] = v;
      lo[a] = std::min(lo[a], v);
      hi[a] = std::max(hi[a], v);
    }
  }
  std::uint64_t span = 0;
  for (int a = 0; a < 3; ++a) span = std::max(span, static_cast<std::uint64_t>(hi[a] - lo[a]));
  const int depth = static_cast<int>(std::bit_width(span));
  if (depth > kMaxGeometryDepth) {
    return limit_exceeded("chunk: the points span " + std::to_string(span + 1) +
                          " quantisation steps on one axis, more than 2^21; use smaller chunks or a larger tolerance");
  }
  for (int a = 0; a < 3; ++a) h.quant_base[a] = lo[a];
  h.geometry_depth = static_cast<std::uint8_t>(depth);

  // ---- Canonical order: Morton order of the cells, then attributes.
  std::vector<KeyedIndex> order(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto lx = static_cast<std::uint32_t>(q[3 * i] - lo[0]);
    const auto ly = static_cast<std::uint32_t>(q[3 * i + 1] - lo[1]);
    const auto lz = static_cast<std::uint32_t>(q[3 * i + 2] - lo[2]);
    order[i] = {morton_encode(lx, ly, lz), static_cast<std::uint32_t>(i)};
  }
  radix_sort(order, 3 * depth);
  const auto attr_less = [&](const KeyedIndex& a, const KeyedIndex& b) {
    if (has_rgb) {
      const Rgb8 ca = cloud.colors[a.index], cb = cloud.colors[b.index];
      if (ca.r != cb.r) return ca.r < cb.r;
      if (ca.g != cb.g) return ca.g < cb.g;
      if (ca.b != cb.b) return ca.b < cb.b;
    }
    if (has_i) {
      const std::uint32_t ia = float_bits(cloud.intensities[a.index]), ib = float_bits(cloud.intensities[b.index]);
      if (ia != ib) return ia < ib;
    }
    return las_bits != 0 && compare_las_points(cloud.las, a.index, b.index) < 0;
  };
  OccupiedCells cells;
  for (std::size_t i = 0; i < n;) {
    std::size_t j = i + 1;
    while (j < n && order[j].key == order[i].key) ++j;
    if (j - i > 1) std::sort(order.begin() + static_cast<std::ptrdiff_t>(i), order.begin() + static_cast<std::ptrdiff_t>(j), attr_less);
    cells.keys.push_back(order[i].key);
    cells.counts.push_back(static_cast<std::uint32_t>(j - i));
    i = j;
  }

  // Format 8: with GPS times, the geometry may instead be coded in time
  // order (§11.3.3), the times then without ranks; the encoder keeps the
  // smaller of the two codings of geometry and times (the octree when they
  // tie), and stops coding the octree once it is sure to lose.
  std::vector<std::uint8_t> geometry;
  // The octree: codec 14 (format 17), or codec 12 (format 13) with
  // ErrorBound::fast_geometry.
  const OctreeCoding octree_coding =
      bound.fast_geometry ? OctreeCoding::kFacePatterns : OctreeCoding::kNearest;
  const SectionCodec octree_codec =
      bound.fast_geometry ? SectionCodec::kOctreeFaces : SectionCodec::kOctreeNearest;
  const std::uint16_t octree_version =
      bound.fast_geometry ? kOrderFreeFormatVersion : kOctreeNearestFormatVersion;
  SectionCodec geometry_codec = octree_codec;
  // The cell order above, kept when a scan order replaces it as the layer's.
  std::vector<KeyedIndex> cell_order;
  std::vector<std::uint32_t> time_order;  // layer index of each time-order position
  std::vector<std::uint8_t> gps_payload;
  if (bound.keep_order && n > 1) {
    // The points' own order (ErrorBound::keep_order): the geometry in scan
    // order whatever it costs, GPS times (if any) in that order too. Without
    // GPS times, or with times that step back, the blob is format 14.
    ScanCoding scan = encode_in_time_order(cloud, q, lo, depth, attr_less, true);
    geometry = std::move(scan.geometry);
    geometry_codec = SectionCodec::kScanOrder;
    cell_order = std::move(order);
    order = std::move(scan.order);
    time_order = std::move(scan.time_order);
    gps_payload = std::move(scan.gps);
    if ((las_bits & kLasGpsTime) == 0) {
      // Sections 12-17 then follow the layer's order with their plain
      // coding (§11.7.2 needs the times).
      h.version = kKeptOrderFormatVersion;
      time_order.clear();
    } else if (scan.times_step_back) {
      h.version = kKeptOrderFormatVersion;  // times that decrease in the layer's order
    }
  } else if ((las_bits & kLasGpsTime) != 0 && n > 1) {
    LasAttributes cell_las;  // the times in cell order
    cell_las.gps_time.resize(n);
    for (std::size_t k = 0; k < n; ++k) cell_las.gps_time[k] = cloud.las.gps_time[order[k].index];
    const auto first = std::bit_cast<std::uint64_t>(cell_las.gps_time[0]);
    if (!std::all_of(cell_las.gps_time.begin(), cell_las.gps_time.end(),
                     [&](double t) { return std::bit_cast<std::uint64_t>(t) == first; })) {
      ScanCoding scan = encode_in_time_order(cloud, q, lo, depth, attr_less);
      // (+ 1: the order mask, §11.3.3)
      const std::size_t scan_bytes = scan.geometry.size() + 1 + scan.gps.size();
      std::optional<std::vector<std::uint8_t>> octree;
      std::vector<std::uint8_t> gps_ranked;
      if (octree_may_win(scan.order, depth, scan_bytes)) {
        time_order = las_time_order(cell_las.gps_time);
        gps_ranked = encode_las_attribute(kLasGpsTime, cell_las, n, octree_version,
                                          cells_in_order(q, lo, order), time_order);
        if (gps_ranked.size() <= scan_bytes) {
          octree = encode_geometry_within(cells, depth, octree_coding, scan_bytes - gps_ranked.size());
        }
      }
      if (octree) {
        geometry = std::move(*octree);
        gps_payload = std::move(gps_ranked);
      } else {
        geometry = std::move(scan.geometry);
        geometry_codec = SectionCodec::kScanOrder;
        cell_order = std::move(order);
        order = std::move(scan.order);
        time_order = std::move(scan.time_order);
        gps_payload = std::move(scan.gps);
      }
    }
  }
  if (geometry_codec == octree_codec && geometry.empty()) {
    geometry = encode_geometry(cells, depth, octree_coding);
  }
  // Format 17 for octree geometry (codec 14), its LAS sections with format
  // 15's codings (format 13 with codec 12 and fast_geometry, 15 below where
  // its sections are smaller); 13, 14 or 15 for geometry in scan order.
  if (geometry_codec == octree_codec) h.version = octree_version;
  std::vector<SectionEntry> refined;
  std::vector<std::vector<std::uint8_t>> payloads;
  payloads.push_back(std::move(geometry));
  refined.push_back({SectionId::kGeometry, geometry_codec, static_cast<std::uint32_t>(n), 0, {}});
  // A time-ordered layer (§11.3.3) codes each attribute section that does
  // not follow acquisition order in time order or in cell order, whichever
  // is smaller, and says which in the order mask that starts the geometry.
  // cell_pos[j]: the layer position of the j-th point in cell order.
  std::vector<std::uint32_t> cell_pos;
  std::uint8_t order_mask = 0;
  if (geometry_codec == SectionCodec::kScanOrder) {
    // The layer's points in cell order, a cell's in layer order: the cell
    // order made above, each cell's points (most cells hold one) put in
    // layer order, as a stable sort of the layer by cell would give them.
    std::vector<std::uint32_t> layer_pos(n);
    for (std::size_t k = 0; k < n; ++k) layer_pos[order[k].index] = static_cast<std::uint32_t>(k);
    cell_pos.resize(n);
    for (std::size_t i = 0; i < n;) {
      std::size_t j = i + 1;
      while (j < n && cell_order[j].key == cell_order[i].key) ++j;
      for (std::size_t t = i; t < j; ++t) cell_pos[t] = layer_pos[cell_order[t].index];
      if (j - i > 1)
        std::sort(cell_pos.begin() + static_cast<std::ptrdiff_t>(i),
                  cell_pos.begin() + static_cast<std::ptrdiff_t>(j));
      i = j;
    }
    cell_order = {};
  }
  // Each section that may follow either order (its slot's bit in the mask)
  // is coded in the layer's order and in cell order and the smaller kept.
  // A large blob first codes a sample both ways, the points of the first
  // eighth of the cell order (a region of the chunk, with every pass over
  // it): when one order is smaller there by more than 1/kOrderTrialMargin,
  // the section is coded in that order alone. An encoder's choice (the format
  // allows either); it saves coding most sections twice, whose losing
  // order cost a sixth of a time-ordered survey's encoding.
  // sample_layer: the sample's layer positions in layer order; sample_cells:
  // the same in cell order.
  std::vector<std::uint32_t> sample_layer, sample_cells;
  if (!cell_pos.empty() && n >= kOrderTrialPoints) {
    sample_cells.assign(cell_pos.begin(), cell_pos.begin() + static_cast<std::ptrdiff_t>(n / 8));
    sample_layer = sample_cells;
    std::sort(sample_layer.begin(), sample_layer.end());
  }
  // `code(positions, in_cells)` codes the section's values at those layer
  // positions, in that order, with the layer's coder or the cell order's.
  const auto choose_order = [&](auto&& code) {
    if (sample_cells.empty()) return OrderChoice::kTry;
    const std::size_t in_layer = code(std::span<const std::uint32_t>(sample_layer), false).size();
    const std::size_t in_cells = code(std::span<const std::uint32_t>(sample_cells), true).size();
    if (kOrderTrialMargin * in_cells < (kOrderTrialMargin - 1) * in_layer) return OrderChoice::kCells;
    if (kOrderTrialMargin * in_layer < (kOrderTrialMargin - 1) * in_cells) return OrderChoice::kLayer;
    return OrderChoice::kTry;
  };
  // The section as `choice` says: `in_layer` and `in_cells` are its codings
  // (empty when not made). Sets the slot's bit when cell order is kept.
  const auto keep = [&](int slot, OrderChoice choice, std::vector<std::uint8_t> in_layer,
                        std::vector<std::uint8_t> in_cells) {
    const bool keep_cells =
        choice == OrderChoice::kCells ||
        (choice == OrderChoice::kTry && !cell_pos.empty() && in_cells.size() < in_layer.size());
    if (keep_cells) {
      order_mask = static_cast<std::uint8_t>(order_mask | (1u << slot));
      return in_cells;
    }
    return in_layer;
  };

  // ---- The base layer is built from what the decoder will return.
  PointCloud base;
  base.reserve(n, has_rgb, has_i);
  base.positions.resize(n);
  Box3d refined_bounds;
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = order[k].index;
    Vec3d p{dequantise(origins[0], lo[0], static_cast<std::uint32_t>(q[3 * i] - lo[0]), steps[0]),
            dequantise(origins[1], lo[1], static_cast<std::uint32_t>(q[3 * i + 1] - lo[1]), steps[1]),
            dequantise(origins[2], lo[2], static_cast<std::uint32_t>(q[3 * i + 2] - lo[2]), steps[2])};
    refined_bounds.add(p);
    base.positions[k] = p;
  }
  if (has_rgb) {
    std::vector<Rgb8> ordered(n);
    for (std::size_t k = 0; k < n; ++k) ordered[k] = cloud.colors[order[k].index];
    // Colours in cell order are predicted from the previous points, the
    // nearest weighing most (codec 10, §11.4.1), colours in time order from
    // the previous point (codec 6, §11.4), which the scan line makes the
    // nearest.
    SectionCodec color_codec = SectionCodec::kNeighbourColor;
    std::vector<std::uint8_t> coded;
    if (cell_pos.empty()) {
      coded = encode_colors_near(ordered, cells_in_order(q, lo, order), h.color_tolerance, &base.colors);
    } else {
      const auto colors_at = [&](std::span<const std::uint32_t> at) {
        std::vector<Rgb8> v(at.size());
        for (std::size_t j = 0; j < at.size(); ++j) v[j] = ordered[at[j]];
        return v;
      };
      const auto cells_at = [&](std::span<const std::uint32_t> at) {
        std::vector<CellXyz> v(at.size());
        for (std::size_t j = 0; j < at.size(); ++j) v[j] = cell_of(q, lo, order[at[j]].index);
        return v;
      };
      const OrderChoice choice = choose_order([&](std::span<const std::uint32_t> at, bool in_cells) {
        return in_cells ? encode_colors_near(colors_at(at), cells_at(at), h.color_tolerance, nullptr)
                        : encode_colors(colors_at(at), h.color_tolerance, nullptr);
      });
      // With a colour tolerance the decoded colours depend on the order.
      std::vector<std::uint8_t> in_layer, in_cells;
      std::vector<Rgb8> decoded;
      if (choice != OrderChoice::kCells) in_layer = encode_colors(ordered, h.color_tolerance, &base.colors);
      if (choice != OrderChoice::kLayer) {
        in_cells = encode_colors_near(colors_at(cell_pos), cells_at(cell_pos), h.color_tolerance, &decoded);
      }
      color_codec = SectionCodec::kArithmetic;
      coded = keep(kOrderSlotColors, choice, std::move(in_layer), std::move(in_cells));
      if (order_mask & (1u << kOrderSlotColors)) {
        color_codec = SectionCodec::kNeighbourColor;
        base.colors.resize(n);
        for (std::size_t j = 0; j < n; ++j) base.colors[cell_pos[j]] = decoded[j];
      }
    }
    payloads.push_back(std::move(coded));
    refined.push_back({SectionId::kPointColor, color_codec, static_cast<std::uint32_t>(n), 0, {}});
  }
  if (has_i) {
    bool integral = true;
    for (const float v : cloud.intensities) {
      integral = integral && v >= 0 && v <= 65535 && v == std::floor(v) && !(v == 0 && std::signbit(v));
    }
    h.intensity_coding = integral ? IntensityCoding::kUInt16 : IntensityCoding::kFloatBits;
    // A tolerance applies to 16-bit intensities only: float ones stay exact.
    const int tolerance = integral ? bound.intensity_tolerance : 0;
    h.intensity_tolerance = static_cast<std::uint16_t>(tolerance);
    if (stats) stats->intensities_kept_exact = !integral && bound.intensity_tolerance > 0;
    std::vector<std::int64_t> values(n);
    base.intensities.resize(n);
    for (std::size_t k = 0; k < n; ++k) {
      const float v = cloud.intensities[order[k].index];
      values[k] = integral ? static_cast<std::int64_t>(v) : static_cast<std::int64_t>(float_bits(v));
      base.intensities[k] = v;
    }
    // With a tolerance the base layer's map is made of what a full decode
    // returns, as for colours.
    std::vector<std::int64_t> decoded_layer, decoded_cells;
    std::vector<std::int64_t>* const want_layer = tolerance != 0 ? &decoded_layer : nullptr;
    std::vector<std::int64_t>* const want_cells = tolerance != 0 ? &decoded_cells : nullptr;
    std::vector<std::uint8_t> coded;
    bool cells_kept = false;
    if (cell_pos.empty()) {
      coded = encode_values(values, tolerance, want_layer);
    } else {
      // One coder, either order: the values at the positions, in turn.
      const auto code = [&](std::span<const std::uint32_t> at, bool, std::vector<std::int64_t>* decoded) {
        std::vector<std::int64_t> v(at.size());
        for (std::size_t j = 0; j < at.size(); ++j) v[j] = values[at[j]];
        return encode_values(v, tolerance, decoded);
      };
      const OrderChoice choice =
          choose_order([&](std::span<const std::uint32_t> at, bool full) { return code(at, full, nullptr); });
      std::vector<std::uint8_t> in_layer, in_cells;
      if (choice != OrderChoice::kCells) in_layer = encode_values(values, tolerance, want_layer);
      if (choice != OrderChoice::kLayer) in_cells = code(cell_pos, true, want_cells);
      coded = keep(kOrderSlotIntensity, choice, std::move(in_layer), std::move(in_cells));
      cells_kept = (order_mask & (1u << kOrderSlotIntensity)) != 0;
    }
    if (tolerance != 0) {
      if (cells_kept) {
        for (std::size_t j = 0; j < n; ++j) base.intensities[cell_pos[j]] = static_cast<float>(decoded_cells[j]);
      } else {
        for (std::size_t k = 0; k < n; ++k) base.intensities[k] = static_cast<float>(decoded_layer[k]);
      }
    }
    payloads.push_back(std::move(coded));
    refined.push_back({SectionId::kPointIntensity, SectionCodec::kArithmetic, static_cast<std::uint32_t>(n), 0, {}});
  }
  // Format 15's codings of the sections it codes otherwise (§11.7: NIR
  // against the colours, the scan angle in time order by successors), by
  // index in payloads: the blob is format 15 when together they are smaller.
  struct Format15Coding {
    std::size_t index;
    std::vector<std::uint8_t> payload;
  };
  std::vector<Format15Coding> format15;
  if (las_bits != 0) {
    // The coded attributes alone, in the layer's order (gathering the whole
    // cloud would copy its positions, colours and intensities too: ~30 bytes
    // a point more at the encoder's peak). Kept as a PointCloud, which the
    // order trials' samples are gathered from.
    PointCloud gathered;
    {
      const std::vector<std::uint32_t> at = order_indices(order);
      gathered.las.extra_bytes_size = cloud.las.extra_bytes_size;
      for (int b = 0; b < kLasAttributeCount; ++b) {
        if ((las_bits & (1u << b)) != 0) permute_las_attribute(1u << b, cloud.las, gathered.las, at, Permute::kGather);
      }
    }
    // With a colour tolerance, a low byte equal to its channel's input colour
    // (a source of 8-bit levels, whose low bytes repeat them, or a 16-bit
    // level v * 257) becomes the decoded colour: the level then comes back
    // as the decoded colour says (c' * 257, or c'), within the tolerance,
    // and a section of such bytes is one decision rather than the exact
    // levels over again (format-spec/chunk.md §11.7, colour low bytes).
    if (h.color_tolerance > 0 && gathered.las.color_low.size() == n && base.colors.size() == n) {
      for (std::size_t k = 0; k < n; ++k) {
        const Rgb8& in = cloud.colors[order[k].index];
        const Rgb8& out = base.colors[k];
        Rgb8& low = gathered.las.color_low[k];
        if (low.r == in.r) low.r = out.r;
        if (low.g == in.g) low.g = out.g;
        if (low.b == in.b) low.b = out.b;
      }
    }
    const LasAttributes& ordered = gathered.las;
    // The order trials' sample in the layer's order (made when first needed).
    struct LayerSample {
      LasAttributes las;
      std::vector<std::uint32_t> identity;
      std::vector<Rgb8> colors;
    };
    std::unique_ptr<LayerSample> layer_sample;
    // With GPS times, the attributes that follow acquisition order are coded
    // in time order (§11.7.2): the geometry's order (§11.3.3) or the times'
    // (§11.7.1), whose section gps_payload already holds.
    if ((las_bits & kLasGpsTime) && time_order.empty()) time_order = las_time_order(ordered.gps_time);
    for (int b = 0; b < kLasAttributeCount; ++b) {
      const std::uint32_t bit = 1u << b;
      if ((las_bits & bit) == 0) continue;
      if (bit == kLasGpsTime && !gps_payload.empty()) {
        payloads.push_back(std::move(gps_payload));
      } else {
        const int slot = order_slot(bit);
        // The section's format-15 coding, where it differs (§11.7, §11.7.2):
        // the scan angle in time order, NIR with colours.
        // (Formats 16 and 17 code them so already.)
        const bool v15_differs =
            h.version < kLasCodingFormatVersion &&
            ((bit == kLasScanAngle && !time_order.empty()) || (bit == kLasNir && !base.colors.empty()));
        if (cell_pos.empty() || slot < 0) {
          payloads.push_back(encode_las_attribute(bit, ordered, n, h.version, {}, time_order, base.colors));
          if (v15_differs) {
            format15.push_back({payloads.size() - 1, encode_las_attribute(bit, ordered, n, kLasCodingFormatVersion, {},
                                                                          time_order, base.colors)});
          }
        } else {
          // In cell order: this attribute alone (no context from the others).
          const auto in_cell_order = [&](std::span<const std::uint32_t> at, int version) {
            LasAttributes by_cell;
            by_cell.extra_bytes_size = ordered.extra_bytes_size;
            permute_las_attribute(bit, ordered, by_cell, at, Permute::kGather);
            std::vector<Rgb8> colors;  // the decoded colours, in that order
            if (bit == kLasColorLow || bit == kLasNir) {
              colors.resize(base.colors.empty() ? 0 : at.size());
              for (std::size_t j = 0; j < colors.size(); ++j) colors[j] = base.colors[at[j]];
            }
            return encode_las_attribute(bit, by_cell, at.size(), version, {}, {}, colors);
          };
          const OrderChoice choice = choose_order([&](std::span<const std::uint32_t> at, bool in_cells) {
            if (in_cells) return in_cell_order(at, h.version);
            // In the layer's (time) order: every attribute at those points
            // (`at` is sample_layer), the lower bits being context, gathered
            // once for every section.
            if (!layer_sample) {
              layer_sample = std::make_unique<LayerSample>();
              layer_sample->las = gathered.gathered(sample_layer).las;
              layer_sample->identity.resize(sample_layer.size());
              for (std::size_t j = 0; j < sample_layer.size(); ++j) layer_sample->identity[j] = static_cast<std::uint32_t>(j);
              if (!base.colors.empty()) {
                layer_sample->colors.resize(sample_layer.size());
                for (std::size_t j = 0; j < sample_layer.size(); ++j) layer_sample->colors[j] = base.colors[sample_layer[j]];
              }
            }
            return encode_las_attribute(bit, layer_sample->las, at.size(), h.version, {}, layer_sample->identity,
                                        layer_sample->colors);
          });
          std::vector<std::uint8_t> in_layer, in_cells;
          if (choice != OrderChoice::kCells) {
            in_layer = encode_las_attribute(bit, ordered, n, h.version, {}, time_order, base.colors);
          }
          if (choice != OrderChoice::kLayer) in_cells = in_cell_order(cell_pos, h.version);
          payloads.push_back(keep(slot, choice, std::move(in_layer), std::move(in_cells)));
          if (v15_differs) {
            // In the order kept (the order trial's codings are format 13's).
            const bool cells_kept = (order_mask & (1u << slot)) != 0;
            format15.push_back({payloads.size() - 1,
                                cells_kept ? in_cell_order(cell_pos, kLasCodingFormatVersion)
                                           : encode_las_attribute(bit, ordered, n, kLasCodingFormatVersion, {},
                                                                  time_order, base.colors)});
          }
        }
      }
      refined.push_back({static_cast<SectionId>(kFirstLasSection + b), SectionCodec::kArithmetic,
                         static_cast<std::uint32_t>(n), 0, {}});
    }
  }
  if (!format15.empty()) {
    std::int64_t saved = 0;  // bytes format 15 saves over the codings above
    bool coded = true;
    for (const Format15Coding& f : format15) {
      coded = coded && !f.payload.empty();
      saved += static_cast<std::int64_t>(payloads[f.index].size()) - static_cast<std::int64_t>(f.payload.size());
    }
    if (coded && saved > 0) {
      for (Format15Coding& f : format15) payloads[f.index] = std::move(f.payload);
      h.version = std::max(h.version, kLasCodingFormatVersion);
    }
  }
  // A coder that refused its input (a broken precondition: never for valid
  // points) left its section empty; a range-coded section of n > 0 points
  // never is. Report it rather than store a stream that cannot decode.
  for (std::size_t k = 0; k < payloads.size(); ++k) {
    if (payloads[k].empty()) {
      return internal_error("chunk: the " + chunk_section_label(static_cast<int>(refined[k].id)) +
                            " section could not be coded (" + std::to_string(n) + " points)");
    }
  }
  if (geometry_codec == SectionCodec::kScanOrder) payloads[0].insert(payloads[0].begin(), order_mask);
  if (las_bits & kLasClassification) {
    // The base layer's classification map: the majority class per pixel.
    base.las.classification.resize(n);
    for (std::size_t k = 0; k < n; ++k) base.las.classification[k] = cloud.las.classification[order[k].index];
  }
  EncodeParams base_params = params;
  base_params.bound.reset();
  if (base_params.grid_origin) {
    // Snapping may move a point up to half a step out of the chunk cube; the
    // base layer only approximates, so pull such points onto the cube.
    const Vec3d o = *base_params.grid_origin;
    const double e = base_params.grid_edge;
    for (Vec3d& p : base.positions) {
      p.x = std::clamp(p.x, o.x, o.x + e);
      p.y = std::clamp(p.y, o.y, o.y + e);
      p.z = std::clamp(p.z, o.z, o.z + e);
    }
  }
  EncodeStats base_stats;
  auto base_blob = encode_chunk(base, base_params, {}, &base_stats);
  if (!base_blob) return base_blob.status().with_context("chunk: base layer");
  // The archive's base cell comes from a sample of all points; a chunk whose
  // maps hold too few pixels for kBaseLayerLod (sparser or more line-like
  // than the sample) gets them again with half the cell, about 4 times the
  // pixels on a surface. A finer cell the encoder refuses (depth or atlas
  // limit) keeps the coarser maps, which stay valid.
  const std::uint64_t wanted = (static_cast<std::uint64_t>(n) + kBaseLayerLod - 1) / kBaseLayerLod;
  for (int k = 0; k < kMaxBaseRefinements && base_params.cell_size > 0 &&
                  2 * static_cast<std::uint64_t>(base_stats.decoded_points) < wanted;
       ++k) {
    EncodeParams finer = base_params;
    finer.cell_size = base_params.cell_size / 2;
    EncodeStats finer_stats;
    auto finer_blob = encode_chunk(base, finer, {}, &finer_stats);
    if (!finer_blob) break;
    base_params = finer;
    base_blob = std::move(finer_blob);
    base_stats = finer_stats;
  }
  RELIEF_ASSIGN_OR_RETURN(ParsedBlob parsed, parse_blob(*base_blob, false));
  const ChunkHeader& bh = parsed.header;
  h.decomposition = bh.decomposition;
  h.tree_depth = bh.tree_depth;
  h.input_points = static_cast<std::uint32_t>(n);
  h.decoded_points = bh.decoded_points;
  h.patch_count = bh.patch_count;
  h.tiles_x = bh.tiles_x;
  h.tiles_y = bh.tiles_y;
  h.grid_origin = bh.grid_origin;
  h.grid_edge = bh.grid_edge;
  h.height_min = bh.height_min;
  h.height_max = bh.height_max;
  h.intensity_min = bh.intensity_min;
  h.intensity_max = bh.intensity_max;
  // Sections in id order: the maps, the error-bounded layer, then the base
  // layer's classification map.
  h.flags |= static_cast<std::uint8_t>(bh.flags & kFlagClassMap);
  std::vector<SectionEntry> sections;
  for (const SectionEntry& s : parsed.sections) {
    if (s.id != SectionId::kClassMap) sections.push_back(s);
  }
  for (std::size_t s = 0; s < refined.size(); ++s) {
    refined[s].payload = payloads[s];
    refined[s].coded_size = static_cast<std::uint32_t>(payloads[s].size());
    sections.push_back(refined[s]);
  }
  for (const SectionEntry& s : parsed.sections) {
    if (s.id == SectionId::kClassMap) sections.push_back(s);
  }
  if (stats) {
    stats->decoded_points = static_cast<std::uint32_t>(n);
    Box3d b = refined_bounds;
    if (!base_stats.decoded_bounds.empty()) {
      b.add(base_stats.decoded_bounds.min);
      b.add(base_stats.decoded_bounds.max);
    }
    stats->decoded_bounds = b;
    stats->point_bounds = refined_bounds;
  }
  return write_blob(h, sections);
}

}  // namespace relief::codec
