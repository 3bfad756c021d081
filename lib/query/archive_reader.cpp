// Box queries over an archive: index lookup, blob reads with checksum, parallel
// decode at the requested level of detail, clipping, in-order delivery.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <set>

#include "core/parallel.h"
#include "relief/codec.h"
#include "relief/crs.h"
#include "relief/query.h"

namespace relief {

namespace {

// Chunks in flight (read, decoding or waiting to be delivered) per decoder
// thread: enough to keep every core busy, few enough that memory stays a
// handful of chunks whatever the box.
constexpr unsigned kChunksPerThreadPerWave = 2;

std::string chunk_name(const ChunkRef& r) {
  return "chunk (" + std::to_string(r.key.ix) + "," + std::to_string(r.key.iy) + "," + std::to_string(r.key.iz) +
         ") seq " + std::to_string(r.seq) + " (id " + std::to_string(r.id) + ")";
}

bool inside(const Vec3d& p, const Box3d& box) {
  return !(p.x < box.min.x || p.x > box.max.x || p.y < box.min.y || p.y > box.max.y || p.z < box.min.z ||
           p.z > box.max.z);
}

// The LAS filters of QueryOptions, checked against what the archive carries.
struct LasFilter {
  std::array<bool, 256> classes{};
  bool by_class = false;
  bool first = false;
  bool last = false;
  std::uint32_t bits = 0;  // the LAS attributes the filters read
  bool any() const { return by_class || first || last; }
  bool pass(const LasAttributes& a, std::size_t i) const {
    if (by_class && !classes[a.classification[i]]) return false;
    if (first && a.return_number[i] != 1) return false;
    if (last && a.return_number[i] != a.number_of_returns[i]) return false;
    return true;
  }
};

Result<LasFilter> make_filter(const QueryOptions& o, const ArchiveInfo& info, const std::string& path) {
  LasFilter f;
  const auto need = [&](std::uint32_t bits, const char* what, const char* filter) -> Status {
    f.bits |= bits;
    if ((info.las_attributes & bits) == bits) return Status::ok();
    return invalid_argument(path + ": " + filter + " needs " + what +
                            ", which this archive does not carry (it keeps LAS attributes only from LAS/LAZ "
                            "sources, in the error-bounded mode)");
  };
  if (!o.classes.empty()) {
    RELIEF_RETURN_IF_ERROR(need(kLasClassification, "the LAS classification", "--class"));
    f.by_class = true;
    for (const std::uint8_t c : o.classes) f.classes[c] = true;
  }
  if (o.first_returns) {
    RELIEF_RETURN_IF_ERROR(need(kLasReturnNumber, "return numbers", "--first-returns"));
    f.first = true;
  }
  if (o.last_returns) {
    RELIEF_RETURN_IF_ERROR(
        need(kLasReturnNumber | kLasNumberOfReturns, "return numbers and numbers of returns", "--last-returns"));
    f.last = true;
  }
  return f;
}

// Keeps the points inside `box` (and `polygon`, when given) that pass
// `filter`, then with `every` > 1 every every-th of them (a level of detail
// taken after filtering).
void select(PointCloud& cloud, const Box3d& box, bool clip_box, const LasFilter& filter, std::uint32_t every,
            const Polygon2D* polygon = nullptr) {
  std::vector<std::uint32_t> order;
  order.reserve(cloud.size());
  std::uint64_t matched = 0;
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (clip_box && !inside(cloud.positions[i], box)) continue;
    if (polygon != nullptr && !polygon->contains(cloud.positions[i].x, cloud.positions[i].y)) continue;
    if (!filter.pass(cloud.las, i)) continue;
    if (matched++ % every == 0) order.push_back(static_cast<std::uint32_t>(i));
  }
  if (order.size() != cloud.size()) cloud = cloud.gathered(order);
}

__extension__ typedef unsigned __int128 Uint128;

// Each row's share of a max_points query's limit `cap` when its rows hold
// `counts` points in the box, more than the limit in all: the limit split at
// the rows' running totals (row i keeps floor(cap * C_i / T) -
// floor(cap * C_(i-1) / T) of its c_i, C the running total, T the sum), so
// cap points in all and no row more than it holds. Empty when they fit (or
// when rows' counts claim 2^64 points or more in all: only a damaged row's
// could, and the query's cut at the limit stands in).
std::vector<std::uint64_t> quotas(const std::vector<std::uint64_t>& counts, std::uint64_t cap) {
  Uint128 total = 0;
  for (const std::uint64_t c : counts) total += c;
  if (total <= cap || (total >> 64) != 0) return {};
  std::vector<std::uint64_t> out(counts.size());
  Uint128 running = 0;
  std::uint64_t before = 0;
  for (std::size_t i = 0; i < counts.size(); ++i) {
    running += counts[i];
    const auto upto = static_cast<std::uint64_t>(running * cap / total);
    out[i] = upto - before;
    before = upto;
  }
  return out;
}

// quotas() when rows stand for different numbers of points each (`weights`:
// a row of a coarse pyramid level stands for the points of its scan's
// chunks), so that each row's share of `cap` is in proportion to the points
// it stands for, up to the points it holds (what a row cannot use goes to
// the others, in proportion again). The same as quotas() when the weights
// are all equal.
std::vector<std::uint64_t> weighted_quotas(const std::vector<std::uint64_t>& counts,
                                           const std::vector<double>& weights, std::uint64_t cap) {
  if (std::adjacent_find(weights.begin(), weights.end(), std::not_equal_to<>()) == weights.end()) {
    return quotas(counts, cap);
  }
  Uint128 total = 0;
  for (const std::uint64_t c : counts) total += c;
  if (total <= cap || (total >> 64) != 0) return {};
  const std::size_t n = counts.size();
  std::vector<std::uint64_t> out(n, 0);
  std::vector<bool> full(n, false);
  std::uint64_t remaining = cap;
  const auto weighted = [&] {
    long double w = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (!full[i]) w += static_cast<long double>(weights[i]) * static_cast<long double>(counts[i]);
    }
    return w;
  };
  // Rows whose share is all they hold take it; the rest is shared anew. A
  // row leaves per round: a few rounds are enough for the shares to settle,
  // and a bounded number keeps a hostile archive's rows from costing n^2.
  constexpr int kRounds = 64;
  for (int round = 0; round < kRounds; ++round) {
    const long double w = weighted();
    if (w <= 0) break;
    bool took = false;
    for (std::size_t i = 0; i < n; ++i) {
      const long double wc = static_cast<long double>(weights[i]) * static_cast<long double>(counts[i]);
      if (full[i] || counts[i] == 0 || static_cast<long double>(remaining) * wc / w < counts[i]) continue;
      out[i] = counts[i];
      full[i] = true;
      remaining -= std::min(remaining, counts[i]);
      took = true;
    }
    if (!took) break;
  }
  // The rest at the running totals of the weighted counts, as quotas(); the
  // last row's total is `remaining` itself (no rounding loses a point).
  const long double w = weighted();
  std::size_t last = n;
  for (std::size_t i = 0; i < n; ++i) {
    if (!full[i] && counts[i] > 0) last = i;
  }
  long double running = 0;
  std::uint64_t before = 0;
  for (std::size_t i = 0; i < n && w > 0; ++i) {
    if (full[i] || counts[i] == 0) continue;
    running += static_cast<long double>(weights[i]) * static_cast<long double>(counts[i]);
    const std::uint64_t upto = i == last
                                   ? remaining
                                   : static_cast<std::uint64_t>(std::min(
                                         static_cast<long double>(remaining),
                                         std::floor(static_cast<long double>(remaining) * running / w)));
    out[i] = std::min(counts[i], upto - std::min(upto, before));
    before = std::max(before, upto);
  }
  return out;
}

// Keeps `keep` of the cloud's points (`expected` of them when the row's
// count held; otherwise as many as it has), evenly spaced in decoding order
// as a level of detail thins a chunk: point j of n stays when
// floor((j + 1) keep / n) > floor(j keep / n).
void thin(PointCloud& cloud, std::uint64_t keep, std::uint64_t expected) {
  const std::uint64_t n = cloud.size();
  if (n != expected) keep = std::min(keep, n);
  if (keep >= n) return;
  std::vector<std::uint32_t> order;
  order.reserve(static_cast<std::size_t>(keep));
  for (std::uint64_t j = 0; j < n; ++j) {
    const auto a = static_cast<Uint128>(j) * keep / n;
    const auto b = static_cast<Uint128>(j + 1) * keep / n;
    if (b > a) order.push_back(static_cast<std::uint32_t>(j));
  }
  cloud = cloud.gathered(order);
}

void clip(PointCloud& cloud, const Box3d& box) {
  if (!cloud.las.empty()) {
    select(cloud, box, true, LasFilter{}, 1);
    return;
  }
  std::size_t kept = 0;
  const bool colors = cloud.has_colors(), intensity = cloud.has_intensity();
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3d& p = cloud.positions[i];
    if (p.x < box.min.x || p.x > box.max.x || p.y < box.min.y || p.y > box.max.y || p.z < box.min.z ||
        p.z > box.max.z) {
      continue;
    }
    cloud.positions[kept] = p;
    if (colors) cloud.colors[kept] = cloud.colors[i];
    if (intensity) cloud.intensities[kept] = cloud.intensities[i];
    ++kept;
  }
  cloud.positions.resize(kept);
  if (colors) cloud.colors.resize(kept);
  if (intensity) cloud.intensities.resize(kept);
}

class Reader final : public ArchiveReader {
 public:
  Reader(std::unique_ptr<Archive> archive, ArchiveInfo info) : archive_(std::move(archive)), info_(std::move(info)) {
    // An archive of 8-bit colour levels with a colour tolerance: the low
    // bytes are the levels as read, which the decoded colours approximate;
    // the colours are what comes back (format-spec/archive.md §2.1,
    // las_colors_8bit), so each low byte becomes its colour.
    if (info_.las_colors_8bit) {
      const Result<EncodeParams> params = encode_params_from_string(info_.codec_params);
      lows_are_colors_ = params && params->bound && params->bound->color_tolerance > 0;
    }
  }

  const std::string& path() const override { return archive_->path(); }
  const ArchiveInfo& info() const override { return info_; }

  Result<QueryStats> query(const Box3d& box, const QueryOptions& options, const PointSink& sink) override {
    const auto bad = [](double v) { return std::isnan(v); };
    if (bad(box.min.x) || bad(box.min.y) || bad(box.min.z) || bad(box.max.x) || bad(box.max.y) || bad(box.max.z)) {
      return invalid_argument("query box contains NaN");
    }
    if (box.min.x > box.max.x || box.min.y > box.max.y || box.min.z > box.max.z) {
      return invalid_argument("query box is empty or inverted (a min is above its max)");
    }
    return query_within(with_rounding_margin(box), options, sink);
  }

  Result<QueryStats> query_all(const QueryOptions& options, const PointSink& sink) override {
    const double inf = std::numeric_limits<double>::infinity();
    const Box3d all{{-inf, -inf, -inf}, {inf, inf, inf}};
    if (options.polygon) return query_within(all, options, sink);
    RELIEF_ASSIGN_OR_RETURN(std::vector<ChunkRef> refs, archive_->all_chunks());
    return run(refs, all, options, sink);
  }

 private:
  // The box grown by the rounding of decoded coordinates. A point is a grid
  // cell's centre (origin + index x step) or a decoded value computed in
  // double, so a point a user reads as 169.55 (and types as a face) may be
  // 169.54999999999998: each finite face moves out by 2^-46 of the largest
  // finite magnitude on its axis (the box's, the archive's bounds'), 64 to
  // 128 units in the last place, and never by more than an eighth of the
  // archive's grid step, so no point a step outside comes in.
  Box3d with_rounding_margin(Box3d box) const {
    double step[3] = {0, 0, 0};
    if (const Result<EncodeParams> params = encode_params_from_string(info_.codec_params);
        params && params->bound) {
      step[0] = params->bound->step.x;
      step[1] = params->bound->step.y;
      step[2] = params->bound->step.z;
    }
    const Box3d& a = info_.bounds;
    const auto grow = [&](double& lo, double& hi, double a_lo, double a_hi, double axis_step) {
      double m = 0;
      for (const double v : {lo, hi, a.empty() ? 0.0 : a_lo, a.empty() ? 0.0 : a_hi}) {
        if (std::isfinite(v)) m = std::max(m, std::abs(v));
      }
      double margin = std::ldexp(m, -46);
      if (axis_step > 0) margin = std::min(margin, axis_step / 8);
      lo -= margin;  // an infinite face stays infinite
      hi += margin;
    };
    grow(box.min.x, box.max.x, a.min.x, a.max.x, step[0]);
    grow(box.min.y, box.max.y, a.min.y, a.max.y, step[1]);
    grow(box.min.z, box.max.z, a.min.z, a.max.z, step[2]);
    return box;
  }

  // The polygon in the archive's CRS: converted when it names another one.
  Result<std::shared_ptr<const Polygon2D>> polygon_here(const QueryOptions& options) const {
    const std::string& from = options.polygon->crs();
    if (from.empty()) return options.polygon;
    if (info_.crs.empty()) {
      if (options.on_warning) {
        options.on_warning(archive_->path() + ": the archive names no CRS, so the polygon's coordinates (in " +
                           crs_label(from) + ") are taken as they are");
      }
      return options.polygon;
    }
    RELIEF_ASSIGN_OR_RETURN(const bool same, crs_equivalent(from, info_.crs));
    if (same) return options.polygon;
    RELIEF_ASSIGN_OR_RETURN(Polygon2D p, options.polygon->converted_to(info_.crs, "the polygon"));
    return std::make_shared<const Polygon2D>(std::move(p));
  }

  // A box query, within the polygon's bounds when there is one.
  Result<QueryStats> query_within(Box3d box, const QueryOptions& given, const PointSink& sink) {
    QueryOptions converted;
    const QueryOptions* use = &given;
    if (given.polygon) {
      RELIEF_ASSIGN_OR_RETURN(std::shared_ptr<const Polygon2D> here, polygon_here(given));
      if (here != given.polygon) {
        converted = given;
        converted.polygon = std::move(here);
        use = &converted;
      }
    }
    const QueryOptions& options = *use;
    if (options.polygon) {
      const Box3d& p = options.polygon->bounds();
      const Box3d& a = info_.bounds;
      if (options.on_warning && !a.empty() &&
          (p.max.x < a.min.x || p.min.x > a.max.x || p.max.y < a.min.y || p.min.y > a.max.y)) {
        // Most often a polygon in another CRS (longitude and latitude against
        // a projected archive): say so rather than return nothing silently.
        char text[512];
        std::snprintf(text, sizeof text,
                      "the polygon (x %.9g .. %.9g, y %.9g .. %.9g) lies outside the archive's bounds (x %.9g .. "
                      "%.9g, y %.9g .. %.9g): ",
                      p.min.x, p.max.x, p.min.y, p.max.y, a.min.x, a.max.x, a.min.y, a.max.y);
        const std::string why = given.polygon->crs().empty()
                                    ? "are its coordinates in the archive's CRS?"
                                    : "it was converted from " + crs_label(given.polygon->crs()) +
                                          " to the archive's CRS: is that the CRS its coordinates are in?";
        options.on_warning(archive_->path() + ": " + text + why);
      }
      box.min.x = std::max(box.min.x, p.min.x);
      box.min.y = std::max(box.min.y, p.min.y);
      box.max.x = std::min(box.max.x, p.max.x);
      box.max.y = std::min(box.max.y, p.max.y);
      if (box.min.x > box.max.x || box.min.y > box.max.y) return run({}, box, options, sink);
    }
    RELIEF_ASSIGN_OR_RETURN(std::vector<ChunkRef> refs, archive_->find_chunks(box));
    return run(refs, box, options, sink);
  }

  // The share of `bounds` (a row's) that lies inside `box`, axis by axis; an
  // axis on which the row is flat counts 1 when it lies within the box.
  static double share_inside(const Box3d& bounds, const Box3d& box) {
    if (bounds.empty()) return 1;
    double share = 1;
    const double lo[3] = {bounds.min.x, bounds.min.y, bounds.min.z},
                 hi[3] = {bounds.max.x, bounds.max.y, bounds.max.z};
    const double blo[3] = {box.min.x, box.min.y, box.min.z}, bhi[3] = {box.max.x, box.max.y, box.max.z};
    for (int a = 0; a < 3; ++a) {
      const double extent = hi[a] - lo[a];
      const double inside = std::min(hi[a], bhi[a]) - std::max(lo[a], blo[a]);
      if (!(extent > 0)) {
        share *= lo[a] >= blo[a] && lo[a] <= bhi[a] ? 1.0 : 0.0;
      } else {
        share *= std::clamp(inside / extent, 0.0, 1.0);
      }
    }
    return share;
  }

  // A max_points query reads a level (or the top's rows whole) estimated at
  // up to this many times the limit, and thins it to the limit, before it
  // takes a coarser level or a level of detail from the base layer.
  static constexpr double kMaxPointsOverread = 4.0;

  // The points a row stands for per point it holds: 1 for a chunk, the
  // scan's chunks' points over its level's for a pyramid row (a level holds
  // about a quarter of the one below: such a row's points are a sample).
  double stands_for(const ChunkRef& ref) const {
    if (ref.level == 0) return 1.0;
    for (const ScanPyramid& scan : info_.pyramid) {
      if (scan.scan_id != ref.scan_id) continue;
      for (const PyramidLevel& l : scan.levels) {
        if (l.level == ref.level && l.points > 0) {
          return std::max(1.0, static_cast<double>(scan.base_points) / static_cast<double>(l.points));
        }
      }
    }
    return 1.0;
  }

  // What a query reads: chunk and pyramid rows, each with the level of
  // detail to decode it at, and a cut for a max_points query that even the
  // top of the pyramid cannot meet.
  struct Plan {
    std::vector<ChunkRef> refs;
    std::vector<std::uint32_t> lods;
    std::uint64_t cap = 0;  // 0 = none
    int level = 0;
    // A max_points plan: the points its rows are estimated to give the box
    // (at their levels of detail), and its finer levels, the next finer
    // first, for when its exact count falls short of both the limit and that
    // estimate by more than half (run).
    double expected = 0;
    std::vector<Plan> finer;
  };

  // The pyramid rows of `level` in the box, of the scans whose pyramid
  // reaches it, by scan (cached per level for one query).
  Result<const std::vector<ChunkRef>*> level_refs(int level, const Box3d& box,
                                                  std::map<int, std::vector<ChunkRef>>& cache) const {
    auto it = cache.find(level);
    if (it == cache.end()) {
      RELIEF_ASSIGN_OR_RETURN(std::vector<ChunkRef> refs, archive_->find_level_chunks(level, box));
      it = cache.emplace(level, std::move(refs)).first;
    }
    return &it->second;
  }

  // For each scan, the level it reads: `choose(scan)` (0 = its chunks).
  Result<Plan> gather(const std::vector<ChunkRef>& base, const Box3d& box,
                      const std::function<int(const ScanPyramid&)>& choose,
                      std::map<int, std::vector<ChunkRef>>& cache) const {
    Plan plan;
    std::map<std::int64_t, int> chosen;
    for (const ScanPyramid& scan : info_.pyramid) {
      const int level = scan.levels.empty() ? 0 : choose(scan);
      if (level > 0) chosen[scan.scan_id] = level;
      plan.level = std::max(plan.level, level);
    }
    for (const ChunkRef& ref : base) {
      if (chosen.count(ref.scan_id) == 0) plan.refs.push_back(ref);
    }
    std::set<int> levels;
    for (const auto& [scan, level] : chosen) levels.insert(level);
    for (const int level : levels) {
      RELIEF_ASSIGN_OR_RETURN(const std::vector<ChunkRef>* refs, level_refs(level, box, cache));
      for (const ChunkRef& ref : *refs) {
        const auto it = chosen.find(ref.scan_id);
        if (it != chosen.end() && it->second == level) plan.refs.push_back(ref);
      }
    }
    return plan;
  }

  Result<Plan> make_plan(const std::vector<ChunkRef>& base, const Box3d& box, const QueryOptions& options,
                         bool filtered) const {
    bool pyramid = false;
    for (const ScanPyramid& scan : info_.pyramid) pyramid = pyramid || !scan.levels.empty();
    std::map<int, std::vector<ChunkRef>> cache;
    Plan plan;
    if (options.max_points == 0) {
      if (!pyramid || !options.use_pyramid || filtered || options.lod == 1) {
        plan.refs = base;
        plan.lods.assign(base.size(), options.lod);
        return plan;
      }
      // The coarsest level that can supply at least half the points the
      // level of detail asks for (base_points / lod), thinned to them: the
      // rule by which a chunk's coarse level of detail is read from its base
      // layer (decode_chunk).
      const auto choose = [&](const ScanPyramid& scan) {
        int best = 0;
        for (const PyramidLevel& l : scan.levels) {
          if (2 * l.points * options.lod >= scan.base_points) best = l.level;
        }
        return best;
      };
      RELIEF_ASSIGN_OR_RETURN(plan, gather(base, box, choose, cache));
      std::map<std::int64_t, std::uint32_t> scan_lod;
      for (const ScanPyramid& scan : info_.pyramid) {
        const int level = scan.levels.empty() ? 0 : choose(scan);
        for (const PyramidLevel& l : scan.levels) {
          if (l.level != level) continue;
          scan_lod[scan.scan_id] = static_cast<std::uint32_t>(
              std::max<std::uint64_t>(1, l.points * options.lod / std::max<std::uint64_t>(1, scan.base_points)));
        }
      }
      for (const ChunkRef& ref : plan.refs) plan.lods.push_back(ref.level == 0 ? options.lod : scan_lod[ref.scan_id]);
      return plan;
    }
    // max_points: the finest level g (each scan at its coarsest stored level
    // up to g, or its chunks) whose rows in the box hold at most max_points.
    // Only when every scan with chunks in the box has a pyramid: the levels
    // of one with none would be its chunks, thinned by levels of detail to a
    // share of the limit that a coarse level of the others cannot meet.
    std::set<std::int64_t> without_pyramid;
    for (const ScanPyramid& scan : info_.pyramid) {
      if (scan.levels.empty()) without_pyramid.insert(scan.scan_id);
    }
    const bool every_scan = std::none_of(base.begin(), base.end(), [&](const ChunkRef& ref) {
      return without_pyramid.count(ref.scan_id) > 0;
    });
    std::set<int> candidates = {0};
    if (options.use_pyramid && !filtered && every_scan) {
      for (const ScanPyramid& scan : info_.pyramid) {
        for (const PyramidLevel& l : scan.levels) candidates.insert(l.level);
      }
    }
    // The points a level gives the box: each row's in proportion to the share
    // of its bounds inside the box (exact for a row wholly inside; the rows'
    // whole counts chose levels far coarser than a box needs). Rows a
    // polygon leaves out are not read: they do not count.
    const auto row_in_box = [&](const ChunkRef& ref) {
      return static_cast<double>(ref.decoded_points) * share_inside(ref.bounds, box);
    };
    const auto in_box = [&](const Plan& p) {
      double points = 0;
      for (const ChunkRef& ref : p.refs) {
        if (options.polygon &&
            (ref.bounds.empty() || options.polygon->classify(ref.bounds) == Polygon2D::Overlap::kOutside)) {
          continue;
        }
        points += row_in_box(ref);
      }
      return points;
    };
    // The finest level whose estimate fits; or, when that estimate is below
    // half the limit and the level just finer is estimated at no more than
    // kMaxPointsOverread times it, that finer one, thinned evenly to the
    // limit by the exact count (run): a level's estimate falls short or long
    // by its rows' bounds, and the levels differ by 3x or more, so the
    // coarser level alone could give the box a small fraction of the points
    // asked for.
    const auto cap = static_cast<double>(options.max_points);
    // A level's rows whole when the level is estimated at up to
    // kMaxPointsOverread times the limit (thinned evenly to the limit by the
    // exact count: their own points, attributes and all, rather than a level
    // of detail's). Far more: each row at the level of detail that leaves it
    // up to kMaxPointsOverread times its share of the limit, that share at
    // least one point (one level of detail for all left every row empty
    // under a small limit), the level 2 or more (read from the base layer, as
    // cheap for a row barely in the box as for any), then thinned to the
    // limit by the exact count.
    const auto set_lods = [&](Plan& p, double estimate) {
      p.cap = options.max_points;  // counted exactly and thinned by run: never more
      p.lods.clear();
      p.expected = estimate;
      if (estimate <= kMaxPointsOverread * cap) {
        p.lods.assign(p.refs.size(), 1);
        return;
      }
      p.expected = 0;
      // Each row's share of the limit by the points it stands for (rows of
      // scans read at different levels of the pyramid, or at none).
      std::vector<double> weight;
      double weighted = 0;
      for (const ChunkRef& ref : p.refs) {
        weight.push_back(stands_for(ref));
        weighted += row_in_box(ref) * weight.back();
      }
      const bool uniform =
          std::adjacent_find(weight.begin(), weight.end(), std::not_equal_to<>()) == weight.end();
      for (std::size_t i = 0; i < p.refs.size(); ++i) {
        const ChunkRef& ref = p.refs[i];
        const double points = row_in_box(ref);
        const double share =
            std::max(1.0, std::floor(uniform || weighted <= 0 ? cap * points / estimate
                                                              : cap * points * weight[i] / weighted));
        const double lod =
            std::clamp(std::floor(points / (kMaxPointsOverread * share)), 2.0, static_cast<double>(1u << 30));
        p.lods.push_back(static_cast<std::uint32_t>(lod));
        p.expected += points / lod;
      }
    };
    // The levels above the limit so far, finest first: each plan with its
    // estimate and its level's points (all scans'); the last is the one just
    // finer than the next candidate.
    struct Above {
      Plan plan;
      double estimate = 0;
      double total = 0;
    };
    std::vector<Above> above;
    double estimate = 0, total = 0;
    // What the next finer level's estimate says a plan read whole, of
    // `points` in all, should give the box, by the levels' sizes: a
    // level whose maps (one height per pixel) lost what lies above or below
    // a surface has no row in such a part of the box, an estimate of 0 there.
    // (set_lods reads a plan's rows all whole or all at levels of detail.)
    const auto expect_from = [](Plan& p, double points, const Above& finer) {
      const bool whole = p.lods.empty() || p.lods.front() == 1;
      if (whole && finer.total > 0) p.expected = std::max(p.expected, finer.estimate * points / finer.total);
    };
    const auto add_finer = [&](Plan& p) {
      for (auto it = above.rbegin(); it != above.rend(); ++it) {
        Plan& f = p.finer.emplace_back(std::move(it->plan));
        set_lods(f, it->estimate);
        if (std::next(it) != above.rend()) expect_from(f, it->total, *std::next(it));
      }
    };
    for (const int g : candidates) {
      const auto choose = [g](const ScanPyramid& scan) {
        int best = 0;
        for (const PyramidLevel& l : scan.levels) {
          if (l.level <= g) best = l.level;
        }
        return best;
      };
      RELIEF_ASSIGN_OR_RETURN(plan, gather(base, box, choose, cache));
      estimate = in_box(plan);
      total = 0;
      for (const ScanPyramid& scan : info_.pyramid) {
        const int level = scan.levels.empty() ? 0 : choose(scan);
        double points = static_cast<double>(scan.base_points);
        for (const PyramidLevel& l : scan.levels) {
          if (l.level == level) points = static_cast<double>(l.points);
        }
        total += points;
      }
      if (estimate <= cap) {
        // Also when the level reads scans at different levels (one whose
        // pyramid stops short of this level, read finer): counted whole, the
        // scans read coarser would give the box less than their share.
        const bool mixed =
            std::adjacent_find(plan.refs.begin(), plan.refs.end(), [&](const ChunkRef& a, const ChunkRef& b) {
              return stands_for(a) != stands_for(b);
            }) != plan.refs.end();
        if (!above.empty() && (2 * estimate < cap || mixed) &&
            above.back().estimate <= kMaxPointsOverread * cap) {
          plan = std::move(above.back().plan);
          estimate = above.back().estimate;
          total = above.back().total;
          above.pop_back();
        }
        set_lods(plan, estimate);
        if (!above.empty()) expect_from(plan, total, above.back());
        // The finer levels, next finer first, for when this one, counted
        // exactly, gives the box fewer than half the limit and half that
        // expectation: its rows' bounds overstated their share of the box,
        // a coarse level's maps lost part of it, or a level of detail left a
        // row fewer points than its share.
        add_finer(plan);
        return plan;
      }
      above.push_back({plan, estimate, total});
    }
    // Even the top holds more than the limit (the last of `above`); the
    // finer levels as above, should its levels of detail give too few.
    set_lods(plan, estimate);
    above.pop_back();
    add_finer(plan);
    return plan;
  }

  Result<QueryStats> run(const std::vector<ChunkRef>& base, const Box3d& box, const QueryOptions& options,
                         const PointSink& sink) {
    if (options.lod < 1) return invalid_argument("level of detail must be at least 1");
    if (options.max_points > 0 && options.lod != 1) {
      return invalid_argument("give a level of detail or a maximum number of points, not both");
    }
    const auto t0 = std::chrono::steady_clock::now();
    const std::uint64_t bytes_before = archive_->blob_bytes_read();
    QueryStats stats;
    const unsigned threads = resolve_threads(options.threads);
    const std::size_t wave = static_cast<std::size_t>(threads) * kChunksPerThreadPerWave;
    RELIEF_RETURN_IF_ERROR(check_attributes(info_, options.attributes, archive_->path()));
    RELIEF_ASSIGN_OR_RETURN(const LasFilter filter, make_filter(options, info_, archive_->path()));
    RELIEF_ASSIGN_OR_RETURN(Plan plan, make_plan(base, box, options, filter.any()));
    // With a polygon: rows wholly outside it are dropped unread, and only
    // those it crosses are tested point by point.
    std::vector<bool> crossed;
    const auto restrict_to_polygon = [&] {
      crossed.assign(plan.refs.size(), false);
      if (!options.polygon) return;
      std::vector<ChunkRef> refs;
      std::vector<std::uint32_t> lods;
      crossed.clear();
      for (std::size_t i = 0; i < plan.refs.size(); ++i) {
        const Polygon2D::Overlap o = plan.refs[i].bounds.empty() ? Polygon2D::Overlap::kOutside
                                                                 : options.polygon->classify(plan.refs[i].bounds);
        if (o == Polygon2D::Overlap::kOutside) continue;
        refs.push_back(plan.refs[i]);
        lods.push_back(plan.lods[i]);
        crossed.push_back(o == Polygon2D::Overlap::kPartial);
      }
      plan.refs = std::move(refs);
      plan.lods = std::move(lods);
    };
    restrict_to_polygon();
    const std::vector<ChunkRef>& refs = plan.refs;  // plan may yet become a finer one (below)
    // A filter needs every point's LAS attributes: the full layer, with the
    // level of detail applied to the matching points here.
    const std::uint32_t every = filter.any() ? options.lod : 1;
    // What the chunks decode: the attributes asked for and those the filters read.
    // (The colour low bytes go with the colours.)
    AttributeSet decoded = options.attributes;
    decoded.las = decoded.las_kept() | filter.bits;

    // core/parallel.h's ordered pipeline: this thread reads blobs (one
    // SQLite connection; checksum failures surface here) a few chunks ahead,
    // the decoders take them as they come, and this thread hands each to the
    // sink in index order: reading, decoding and the sink (often a file
    // writer) overlap, and at most `wave` chunks are in memory.
    struct Slot {
      std::size_t index = 0;  // in refs
      ChunkRef ref;
      std::uint32_t lod = 1;
      bool crossed = false;  // by the polygon's edges
      std::vector<std::uint8_t> blob;
      PointCloud points;
      Status status;
    };
    const auto read = [&](std::size_t i, Slot& s) {
      s.index = i;
      s.ref = refs[i];
      s.lod = filter.any() ? 1 : plan.lods[i];
      s.crossed = crossed[i];
      auto row = s.ref.level == 0 ? archive_->read_chunk(s.ref.id) : archive_->read_level_chunk(s.ref.id);
      if (row) {
        s.blob = std::move(row->blob);
      } else {
        s.status = row.status();
      }
    };
    // The counting pass of a max_points query needs only how many points
    // each row has in the box: x y z and what the filters read.
    AttributeSet counted = AttributeSet::none();
    counted.las = filter.bits;
    const auto decode_as = [&](Slot& s, const AttributeSet& attributes) {
      if (!s.status) return;
      DecodeOptions dec;
      dec.lod = s.lod;
      dec.attributes = attributes;
      auto pts = decode_chunk(s.blob, dec);
      std::vector<std::uint8_t>().swap(s.blob);
      if (!pts) {
        s.status = pts.status().with_context(archive_->path() + ": " + chunk_name(s.ref) +
                                             (s.ref.level > 0 ? " of pyramid level " + std::to_string(s.ref.level) : ""));
        return;
      }
      s.points = std::move(pts).value();
      // Every batch carries the archive's LAS attributes, whatever the
      // chunk's scan or layer had.
      conform_las_attributes(s.points, info_.las_attributes & attributes.las, info_.extra_bytes_size);
      if (lows_are_colors_ && !s.points.las.color_low.empty()) s.points.las.color_low = s.points.colors;
      if (filter.any() || s.crossed) {
        select(s.points, box, !box.contains(s.ref.bounds), filter, every,
               s.crossed ? options.polygon.get() : nullptr);
      } else if (!box.contains(s.ref.bounds)) {
        clip(s.points, box);
      }
      keep_attributes(s.points, options.attributes);
    };
    const auto decode = [&](std::size_t, Slot& s) { decode_as(s, decoded); };
    const auto count = [&](std::size_t, Slot& s) { decode_as(s, counted); };
    // A max_points query whose rows hold more points in the box than the
    // limit: each row keeps its quota, evenly spread over its points.
    std::vector<std::uint64_t> in_box, quota;
    // The finer levels to fall back on, in turn (see make_plan).
    std::vector<Plan> finer = std::move(plan.finer);
    std::size_t next_finer = 0;
    while (plan.cap > 0) {
      // A row's points in the box: its decoded_points when it lies wholly
      // inside the box (and polygon), is decoded whole and filtered by
      // nothing; otherwise counted by decoding it (a first pass over the rows
      // that cross the box's faces or the polygon's edges, as many chunks in
      // memory at once as the query's), unless even every row's whole count
      // fits the limit and either there is no finer level to fall back on or
      // the rows known to lie inside hold half the limit already.
      in_box.assign(refs.size(), 0);
      std::vector<std::size_t> uncertain;
      Uint128 most = 0, least = 0;
      bool bounded = true;
      for (std::size_t i = 0; i < refs.size(); ++i) {
        const bool whole = plan.lods[i] == 1;
        if (whole && !filter.any() && !crossed[i] && box.contains(refs[i].bounds)) {
          in_box[i] = refs[i].decoded_points;
          least += in_box[i];
        } else {
          uncertain.push_back(i);
        }
        bounded = bounded && whole;
        most += refs[i].decoded_points;
      }
      // A fallback to a finer level needs fewer than half of the limit and
      // of the level's own estimate (a level that gives what it was
      // estimated to, as a whole archive's levels do, stands).
      const double shortfall = std::min(static_cast<double>(plan.cap), plan.expected);
      if (!bounded || most > plan.cap ||
          (next_finer < finer.size() && 2 * static_cast<double>(least) < shortfall)) {
        RELIEF_RETURN_IF_ERROR(ordered_pipeline<Slot>(
            uncertain.size(), threads, wave, [&](std::size_t k, Slot& s) { read(uncertain[k], s); }, count,
            [&](std::size_t, Slot& s, bool&) -> Status {
              if (!s.status && !options.skip_corrupt) return s.status;
              in_box[s.index] = s.status ? s.points.size() : 0;  // skipped (and reported) by the second pass
              return Status::ok();
            }));
        Uint128 total = 0;
        for (const std::uint64_t c : in_box) total += c;
        // Fewer than half the limit and half the estimate (see make_plan):
        // the next finer level, counted in turn. (Between half and all of the
        // limit the level stands: a preview's budget is met from the level
        // that fits it, not from one 3 to 4 times larger.)
        if (2 * static_cast<double>(total) < shortfall && next_finer < finer.size()) {
          plan = std::move(finer[next_finer++]);
          restrict_to_polygon();
          continue;
        }
        // A row stands for its level's sample of its scan, and a point
        // decoded at level of detail L for L of the row's.
        std::vector<double> weights;
        for (std::size_t i = 0; i < refs.size(); ++i) weights.push_back(stands_for(refs[i]) * plan.lods[i]);
        quota = weighted_quotas(in_box, weights, plan.cap);
        stats.thinned = !quota.empty();
      }
      break;
    }
    stats.chunks_in_index = refs.size();
    stats.pyramid_level = plan.level;
    for (std::size_t i = 0; i < refs.size(); ++i) {
      const std::uint32_t lod = filter.any() ? every : plan.lods[i];
      stats.lod_min = i == 0 ? lod : std::min(stats.lod_min, lod);
      stats.lod_max = std::max(stats.lod_max, lod);
    }
    const auto decode_and_thin = [&](std::size_t i, Slot& s) {
      decode(i, s);
      if (s.status && !quota.empty()) thin(s.points, quota[s.index], in_box[s.index]);
    };
    const auto deliver = [&](std::size_t, Slot& s, bool& stop) -> Status {
      if (!s.status) {
        if (!options.skip_corrupt) return s.status;
        ++stats.chunks_skipped;
        if (options.on_warning) options.on_warning("skipped: " + s.status.message());
        return Status::ok();
      }
      ++stats.chunks_decoded;
      if (plan.cap > 0 && stats.points + s.points.size() > plan.cap) {
        s.points.resize_points(static_cast<std::size_t>(plan.cap - stats.points));
      }
      if (!s.points.empty()) {
        stats.points += s.points.size();
        RELIEF_RETURN_IF_ERROR(sink(s.points));
        s.points = PointCloud();
      }
      stop = plan.cap > 0 && stats.points >= plan.cap;
      return Status::ok();
    };
    RELIEF_RETURN_IF_ERROR(
        ordered_pipeline<Slot>(refs.size(), threads, wave, read, decode_and_thin, deliver));
    stats.blob_bytes_read = archive_->blob_bytes_read() - bytes_before;
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return stats;
  }

  std::unique_ptr<Archive> archive_;
  ArchiveInfo info_;
  bool lows_are_colors_ = false;
};

}  // namespace

Result<std::unique_ptr<ArchiveReader>> ArchiveReader::open(const std::string& path) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Archive> archive, Archive::open(path, Archive::Mode::kReadOnly));
  RELIEF_ASSIGN_OR_RETURN(ArchiveInfo info, archive->info());
  return std::unique_ptr<ArchiveReader>(new Reader(std::move(archive), std::move(info)));
}

Status check_attributes(const ArchiveInfo& info, const AttributeSet& set, const std::string& path) {
  if (set.everything()) return Status::ok();
  AttributeSet missing = set;
  missing.colors = set.colors && !info.has_colors;
  missing.intensity = set.intensity && !info.has_intensity;
  missing.las = set.las & ~info.las_attributes & ((1u << kLasAttributeCount) - 1);
  if (missing == AttributeSet::none()) return Status::ok();
  const std::string has = attribute_set_list({info.has_colors, info.has_intensity, info.las_attributes});
  return invalid_argument(path + ": the attributes asked for include " + attribute_set_list(missing) +
                          ", which this archive does not carry (it has " + (has.empty() ? "none" : has) + ")");
}

Box3d box_2d(double xmin, double ymin, double xmax, double ymax) {
  const double inf = std::numeric_limits<double>::infinity();
  return Box3d{{xmin, ymin, -inf}, {xmax, ymax, inf}};
}

}  // namespace relief
