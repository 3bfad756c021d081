// Error measures of Golla & Klein 2015, section IV-A, on nanoflann kd-trees.
//
// One kd-tree is built per cloud; every point of one cloud then asks the other
// cloud's tree for its spatial nearest neighbour. The work is split into fixed
// blocks of queries whose partial sums are combined in block order, so the
// result is bit-identical whatever the number of threads.
#include "relief/metrics.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <exception>
#include <limits>
#include <new>
#include <optional>
#include <string>
#include <system_error>
#include <thread>
#include <vector>

// nanoflann is a third-party header; keep our strict warning set away from it.
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wconversion"
#pragma GCC diagnostic ignored "-Wsign-conversion"
#pragma GCC diagnostic ignored "-Wshadow"
#pragma GCC diagnostic ignored "-Wpedantic"
#pragma GCC diagnostic ignored "-Wunused-parameter"
#include <nanoflann.hpp>
#pragma GCC diagnostic pop

#include "core/parallel.h"

namespace relief {
namespace {

// Queries per block. Small enough to balance two to a few dozen workers on
// clouds of some thousand points, large enough that the per-block bookkeeping
// is negligible next to the searches.
constexpr std::size_t kBlockSize = 1024;
// Points per kd-tree leaf: for 3-D single nearest-neighbour queries 10-16 is
// the usual sweet spot between tree depth and brute-force work in the leaves.
constexpr std::size_t kLeafSize = 12;

using Point3 = std::array<double, 3>;

// The view of a cloud that nanoflann indexes. Coordinates are re-centred on a
// common origin (the original's bounding-box minimum) on the fly rather than
// copied: georeferenced inputs keep full double precision in small numbers,
// and 100M-point clouds do not need a second copy of their positions.
class CentredCloud {
 public:
  CentredCloud(const std::vector<Vec3d>& positions, const Vec3d& origin)
      : positions_(positions), origin_(origin) {}

  // nanoflann's dataset interface (names fixed by nanoflann).
  std::size_t kdtree_get_point_count() const { return positions_.size(); }
  double kdtree_get_pt(std::size_t index, std::size_t dim) const {
    const Vec3d& p = positions_[index];
    // With the dimension fixed at compile time nanoflann unrolls its distance
    // loop, so this switch folds away on the hot path.
    switch (dim) {
      case 0:
        return p.x - origin_.x;
      case 1:
        return p.y - origin_.y;
      default:
        return p.z - origin_.z;
    }
  }
  template <class Box>
  bool kdtree_get_bbox(Box& /*box*/) const {
    return false;  // let nanoflann compute it from the centred coordinates
  }

  Point3 centred(std::size_t index) const {
    const Vec3d& p = positions_[index];
    return {p.x - origin_.x, p.y - origin_.y, p.z - origin_.z};
  }

 private:
  const std::vector<Vec3d>& positions_;
  Vec3d origin_;
};

template <typename Index>
using KdTree = nanoflann::KDTreeSingleIndexAdaptor<
    nanoflann::L2_Simple_Adaptor<double, CentredCloud, double, Index>, CentredCloud, 3, Index>;

// A result set for exactly one neighbour; cheaper than KNNResultSet(1) and it
// keeps its own best distance because nanoflann reads worstDist() only once
// per leaf. Ties keep the first candidate met, which is deterministic for a
// given tree.
template <typename Index>
class NearestResult {
 public:
  using DistanceType = double;
  using IndexType = Index;

  // nanoflann's result-set interface (names fixed by nanoflann).
  bool full() const { return found_; }
  std::size_t size() const { return found_ ? 1 : 0; }
  double worstDist() const { return best_sq_; }
  bool addPoint(double dist_sq, Index index) {
    if (dist_sq < best_sq_) {
      best_sq_ = dist_sq;
      index_ = index;
      found_ = true;
    }
    return true;  // keep searching: a closer point may still exist
  }

  double distance_sq() const { return best_sq_; }
  Index index() const { return index_; }

 private:
  double best_sq_ = std::numeric_limits<double>::infinity();
  Index index_ = 0;
  bool found_ = false;
};

// Sums for one direction (queries from one cloud into the other).
struct DirectionSums {
  // long double: 100M squared distances of very different magnitudes must
  // still add up to a correct RMSE; blocks keep each sum short as well.
  long double sum_sq = 0;
  double max_sq = 0;
  // Per point dr^2 + dg^2 + db^2 <= 3 * 255^2, so an integer sum is exact for
  // any cloud that fits in memory.
  std::uint64_t sum_rgb_sq = 0;
};

inline std::uint64_t rgb_error_sq(const Rgb8& a, const Rgb8& b) {
  const int dr = int{a.r} - int{b.r};
  const int dg = int{a.g} - int{b.g};
  const int db = int{a.b} - int{b.b};
  return static_cast<std::uint64_t>(dr * dr + dg * dg + db * db);
}

// For every point of `from`, finds its nearest neighbour in `to_tree`.
// Queries run in the leaf order of `from_tree` so that consecutive queries
// are spatial neighbours and walk the same part of the target tree (much
// better cache behaviour than the input order of a scan).
template <typename Index>
DirectionSums measure_direction(const PointCloud& from, const CentredCloud& from_view,
                                const KdTree<Index>& from_tree, const PointCloud& to,
                                const KdTree<Index>& to_tree, bool with_rgb, unsigned threads) {
  const std::vector<Index>& order = from_tree.vAcc;
  const std::size_t n = order.size();
  const std::size_t blocks = (n + kBlockSize - 1) / kBlockSize;
  std::vector<DirectionSums> partial(blocks);
  const nanoflann::SearchParams search_params;

  parallel_for_ranges(blocks, threads, [&](std::size_t first_block, std::size_t last_block,
                                           unsigned /*worker*/) {
    for (std::size_t b = first_block; b < last_block; ++b) {
      DirectionSums sums;
      const std::size_t end = std::min(n, (b + 1) * kBlockSize);
      for (std::size_t k = b * kBlockSize; k < end; ++k) {
        const std::size_t i = order[k];
        const Point3 query = from_view.centred(i);
        NearestResult<Index> nearest;
        to_tree.findNeighbors(nearest, query.data(), search_params);
        const double d2 = nearest.distance_sq();
        sums.sum_sq += d2;
        sums.max_sq = std::max(sums.max_sq, d2);
        if (with_rgb) sums.sum_rgb_sq += rgb_error_sq(from.colors[i], to.colors[nearest.index()]);
      }
      partial[b] = sums;
    }
  });

  // Fixed combination order: the same answer for any thread count.
  DirectionSums total;
  for (const DirectionSums& s : partial) {
    total.sum_sq += s.sum_sq;
    total.max_sq = std::max(total.max_sq, s.max_sq);
    total.sum_rgb_sq += s.sum_rgb_sq;
  }
  return total;
}

// Builds the kd-trees of both clouds, the second one on a helper thread when
// more than one thread is allowed (nanoflann builds a single tree serially).
template <typename Index>
void build_trees(const CentredCloud& view_p, const CentredCloud& view_q, unsigned threads,
                 std::optional<KdTree<Index>>& tree_p, std::optional<KdTree<Index>>& tree_q) {
  const nanoflann::KDTreeSingleIndexAdaptorParams params(kLeafSize);
  std::exception_ptr helper_error;
  std::thread helper;
  if (threads >= 2) {
    try {
      helper = std::thread([&] {
        try {
          tree_q.emplace(3, view_q, params);
        } catch (...) {
          helper_error = std::current_exception();
        }
      });
    } catch (const std::system_error&) {
      // No thread available: fall through to the serial build below.
    }
  }
  std::exception_ptr main_error;
  try {
    tree_p.emplace(3, view_p, params);
    if (!helper.joinable()) tree_q.emplace(3, view_q, params);
  } catch (...) {
    main_error = std::current_exception();
  }
  if (helper.joinable()) helper.join();
  if (main_error) std::rethrow_exception(main_error);
  if (helper_error) std::rethrow_exception(helper_error);
}

double mean(long double sum, std::size_t count) {
  return static_cast<double>(sum / static_cast<long double>(count));
}

template <typename Index>
ErrorMetrics compare_with_index(const PointCloud& original, const PointCloud& reconstructed,
                                unsigned threads) {
  ErrorMetrics m;
  m.points_original = original.size();
  m.points_reconstructed = reconstructed.size();

  const Box3d box = original.bounds();
  m.peak = box.diagonal();

  const CentredCloud view_p(original.positions, box.min);
  const CentredCloud view_q(reconstructed.positions, box.min);
  std::optional<KdTree<Index>> tree_p;
  std::optional<KdTree<Index>> tree_q;
  build_trees<Index>(view_p, view_q, threads, tree_p, tree_q);

  m.has_rgb = original.has_colors() && reconstructed.has_colors();
  const DirectionSums pq =
      measure_direction<Index>(original, view_p, *tree_p, reconstructed, *tree_q, m.has_rgb, threads);
  const DirectionSums qp =
      measure_direction<Index>(reconstructed, view_q, *tree_q, original, *tree_p, m.has_rgb, threads);

  const double mse_pq = mean(pq.sum_sq, m.points_original);
  const double mse_qp = mean(qp.sum_sq, m.points_reconstructed);
  m.rmse_nn_pq = std::sqrt(mse_pq);
  m.rmse_nn_qp = std::sqrt(mse_qp);
  m.rmse_snn = std::sqrt(0.5 * mse_pq + 0.5 * mse_qp);
  m.hausdorff = std::sqrt(std::max(pq.max_sq, qp.max_sq));

  const double worst_rmse = std::max(m.rmse_nn_pq, m.rmse_nn_qp);
  // A single-point original has peak 0 and then, if inexact, psnr = -inf:
  // the formula's own limit, left as is rather than invented.
  m.psnr = worst_rmse == 0 ? std::numeric_limits<double>::infinity()
                           : 20.0 * std::log10(m.peak / worst_rmse);

  if (m.has_rgb) {
    // MSE_RGB averages the three channels, hence the extra factor 3.
    const double mse_rgb_pq = mean(static_cast<long double>(pq.sum_rgb_sq), 3 * m.points_original);
    const double mse_rgb_qp =
        mean(static_cast<long double>(qp.sum_rgb_sq), 3 * m.points_reconstructed);
    m.rmse_rgb_nn_pq = std::sqrt(mse_rgb_pq);
    m.rmse_rgb_nn_qp = std::sqrt(mse_rgb_qp);
    m.rmse_rgb_snn = std::sqrt(0.5 * mse_rgb_pq + 0.5 * mse_rgb_qp);
    m.psnr_rgb = m.rmse_rgb_snn == 0 ? std::numeric_limits<double>::infinity()
                                     : 20.0 * std::log10(255.0 / m.rmse_rgb_snn);
  }
  return m;
}

}  // namespace

Result<ErrorMetrics> compare_clouds(const PointCloud& original, const PointCloud& reconstructed,
                                    const MetricsOptions& options) {
  if (original.empty()) {
    return invalid_argument("compare_clouds: the original cloud is empty");
  }
  if (reconstructed.empty()) {
    return invalid_argument("compare_clouds: the reconstructed cloud is empty");
  }
  RELIEF_RETURN_IF_ERROR(original.validate("original"));
  RELIEF_RETURN_IF_ERROR(reconstructed.validate("reconstructed"));

  const unsigned threads = resolve_threads(options.threads);
  try {
    // 32-bit indices halve the trees' index arrays; wider ones only when needed.
    const std::size_t largest = std::max(original.size(), reconstructed.size());
    if (largest <= std::numeric_limits<std::uint32_t>::max()) {
      return compare_with_index<std::uint32_t>(original, reconstructed, threads);
    }
    return compare_with_index<std::uint64_t>(original, reconstructed, threads);
  } catch (const std::bad_alloc&) {
    return limit_exceeded("compare_clouds: out of memory while building the kd-trees (" +
                          std::to_string(original.size()) + " and " +
                          std::to_string(reconstructed.size()) + " points)");
  } catch (const std::exception& e) {
    return internal_error(std::string("compare_clouds: nearest-neighbour search failed: ") +
                          e.what());
  }
}

}  // namespace relief
