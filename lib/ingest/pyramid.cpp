// The level-of-detail pyramid of a scan (format-spec/archive.md §9), built
// from the scan's stored chunks: the map layer of every blob (the paper's
// coarse layer) thinned to one point per cube of the level's pixel pitch
// feeds level 1; each level's points thinned again feed the next. Points wait
// in bucket files between levels (ingest/bucket_files.h), so memory stays
// bounded by the budget whatever the size of the scan.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "core/parallel.h"
#include "ingest/bucket_files.h"
#include "relief/codec.h"
#include "relief/ingest.h"

namespace relief {

namespace {

using ingest::AlignedBuffer;
using ingest::BucketFiles;
using ingest::Grouping;

// Bytes a point takes in a bucket file at most (position 12, colour 3,
// intensity 4, classification 1) plus its share of block headers: sizes the
// bucket count so one bucket, read whole, stays within a quarter of the budget.
constexpr std::uint64_t kBucketBytesPerPoint = 32;
constexpr std::uint32_t kMaxBuckets = 1024;
// A stored level with at most this many nodes and points is the top of the
// pyramid: a whole-scan preview from it reads a few small blobs.
constexpr std::uint64_t kTopNodes = 8;
constexpr std::uint64_t kTopPoints = 8192;
constexpr std::uint64_t kMinBudget = std::uint64_t{64} << 20;
// Rows committed per transaction.
constexpr std::size_t kRowsPerCommit = 64;

// The node of `level` above a chunk (or above a node `shift` levels down):
// floor(k / 2^shift), which is what an arithmetic right shift gives.
ChunkKey parent(const ChunkKey& k, int shift) { return {k.ix >> shift, k.iy >> shift, k.iz >> shift}; }

// One level's grid and codec parameters.
struct Level {
  int level = 0;
  ArchiveGrid grid;       // the archive's origin, chunk edge * 2^level
  EncodeParams params;    // the resampling codec at the level's cell
  double pitch = 0;       // the level's pixel pitch: one point per cube of it
};

// Level L: nodes of chunk_edge * 2^L; cells of cell_size * 2^(L-1) for an
// error-bounded scan, whose map layer is the level-0 copy at cell_size, and of
// cell_size * 2^L for a resampling scan, whose chunks are themselves that copy.
Level make_level(int level, const ArchiveGrid& grid, const EncodeParams& base) {
  Level l;
  l.level = level;
  l.grid = grid;
  l.grid.chunk_edge = std::ldexp(grid.chunk_edge, level);
  l.params = base;
  const bool bounded = base.bound.has_value();
  l.params.bound.reset();
  l.params.cell_size = std::ldexp(base.cell_size, bounded ? level - 1 : level);
  l.params.grid_edge = l.grid.chunk_edge;
  l.pitch = l.params.cell_size / base.map_resolution;
  return l;
}

// Canonical order: coordinates, then colour, intensity, classification, so
// the points a level gets do not depend on the order they arrived in.
bool point_less(const PointCloud& c, std::uint32_t a, std::uint32_t b) {
  const Vec3d& p = c.positions[a];
  const Vec3d& q = c.positions[b];
  if (p.x != q.x) return p.x < q.x;
  if (p.y != q.y) return p.y < q.y;
  if (p.z != q.z) return p.z < q.z;
  if (!c.colors.empty()) {
    const Rgb8& s = c.colors[a];
    const Rgb8& t = c.colors[b];
    if (s.r != t.r) return s.r < t.r;
    if (s.g != t.g) return s.g < t.g;
    if (s.b != t.b) return s.b < t.b;
  }
  if (!c.intensities.empty() && c.intensities[a] != c.intensities[b]) return c.intensities[a] < c.intensities[b];
  if (!c.las.classification.empty()) return c.las.classification[a] < c.las.classification[b];
  return false;
}

// One point per cube of edge `pitch` (cubes anchored at `origin`): the one
// nearest the cube's centre, ties in canonical order. Output in cube order.
PointCloud thin(const PointCloud& cloud, const Vec3d& origin, double pitch) {
  struct Entry {
    std::int64_t c[3];
    double d2;
    std::uint32_t i;
  };
  std::vector<Entry> e(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3d& p = cloud.positions[i];
    const double t[3] = {(p.x - origin.x) / pitch, (p.y - origin.y) / pitch, (p.z - origin.z) / pitch};
    Entry& x = e[i];
    x.d2 = 0;
    for (int a = 0; a < 3; ++a) {
      const double f = std::floor(t[a]);
      x.c[a] = static_cast<std::int64_t>(f);
      const double d = t[a] - f - 0.5;
      x.d2 += d * d;
    }
    x.i = static_cast<std::uint32_t>(i);
  }
  std::sort(e.begin(), e.end(), [&](const Entry& a, const Entry& b) {
    for (int k = 0; k < 3; ++k) {
      if (a.c[k] != b.c[k]) return a.c[k] < b.c[k];
    }
    if (a.d2 != b.d2) return a.d2 < b.d2;
    return point_less(cloud, a.i, b.i);
  });
  std::vector<std::uint32_t> keep;
  for (std::size_t k = 0; k < e.size(); ++k) {
    if (k > 0 && std::equal(e[k].c, e[k].c + 3, e[k - 1].c)) continue;
    keep.push_back(e[k].i);
  }
  return cloud.gathered(keep);
}

// The attributes a pyramid carries: the scan's colours and intensity, and
// the classification when the archive has one (zero where a chunk has none).
struct Carried {
  bool colors = false;
  bool intensity = false;
  bool classification = false;
};

void conform(PointCloud& cloud, const Carried& carried) {
  const std::size_t n = cloud.size();
  if (!carried.colors) cloud.colors.clear();
  if (carried.colors && cloud.colors.size() != n) cloud.colors.assign(n, Rgb8{});
  if (!carried.intensity) cloud.intensities.clear();
  if (carried.intensity && cloud.intensities.size() != n) cloud.intensities.assign(n, 0.0f);
  conform_las_attributes(cloud, carried.classification ? std::uint32_t{kLasClassification} : 0u, 0);
}

class Builder {
 public:
  Builder(Archive& archive, std::int64_t scan_id, const PyramidOptions& options)
      : archive_(archive), scan_id_(scan_id), options_(options), threads_(resolve_threads(options.threads)) {
    budget_ = std::max(options.memory_budget, kMinBudget);
    tmp_parent_ = options.tmp_dir;
    if (tmp_parent_.empty()) {
      const std::string parent = std::filesystem::path(archive.path()).parent_path().string();
      tmp_parent_ = parent.empty() ? "." : parent;
    }
  }

  Result<PyramidResult> run() {
    const auto t0 = std::chrono::steady_clock::now();
    RELIEF_ASSIGN_OR_RETURN(const ArchiveInfo info, archive_.info());
    RELIEF_ASSIGN_OR_RETURN(std::vector<ChunkRef> refs, archive_.scan_chunks(scan_id_));
    std::erase_if(refs, [](const ChunkRef& r) { return r.decoded_points == 0; });
    RELIEF_RETURN_IF_ERROR(archive_.remove_pyramid(scan_id_));
    PyramidResult result;
    if (refs.empty()) return result;
    grid_ = info.grid;
    carried_.classification = (info.las_attributes & kLasClassification) != 0;
    {
      RELIEF_ASSIGN_OR_RETURN(const ChunkRow first, archive_.read_chunk(refs.front().id));
      RELIEF_ASSIGN_OR_RETURN(base_, encode_params_from_string(first.codec_params));
      RELIEF_ASSIGN_OR_RETURN(const ChunkInfo chunk, inspect_chunk(first.blob));
      if (!(base_.cell_size > 0)) {
        return format_error(archive_.path() + ": chunk id " + std::to_string(first.ref.id) +
                            ": its codec parameters give no cell size to build a pyramid from");
      }
      carried_.colors = chunk.has_colors;
      carried_.intensity = chunk.has_intensity;
    }
    std::uint64_t upper = 0;
    for (const ChunkRef& r : refs) upper += r.decoded_points;
    Level level = make_level(1, grid_, base_);
    RELIEF_ASSIGN_OR_RETURN(BucketFiles files, make_files(level, upper));
    RELIEF_RETURN_IF_ERROR(feed_from_chunks(refs, level, files));
    // A level is stored when it keeps at most a third of the points of the
    // last stored one (the chunks at first); the top is the first stored
    // level of at most kTopNodes nodes and kTopPoints points.
    std::uint64_t last_stored = upper;
    std::uint64_t stored = 0;
    for (;;) {
      RELIEF_RETURN_IF_ERROR(files.finish_writing());
      const bool last_possible = level.level == kMaxPyramidLevel;
      RELIEF_ASSIGN_OR_RETURN(const LevelCount count, count_level(level, files));
      const bool store = count.points * 3 <= last_stored || last_possible;
      std::uint64_t in_files = 0;
      for (std::uint32_t b = 0; b < files.bucket_count(); ++b) in_files += files.bucket_points(b);
      const bool top = store && count.nodes <= kTopNodes && count.points <= kTopPoints;
      const Level next = last_possible || top ? level : make_level(level.level + 1, grid_, base_);
      std::optional<BucketFiles> next_files;
      if (!last_possible && !top) {
        RELIEF_ASSIGN_OR_RETURN(BucketFiles made, make_files(next, in_files));
        next_files.emplace(std::move(made));
      }
      RELIEF_RETURN_IF_ERROR(encode_level(level, files, store, next_files ? &*next_files : nullptr, result));
      if (store) {
        stored |= std::uint64_t{1} << level.level;
        last_stored = count.points;
        result.levels += 1;
        result.top_level = level.level;
      }
      if (top || last_possible) break;
      files = std::move(*next_files);
      level = next;
    }
    RELIEF_RETURN_IF_ERROR(archive_.finish_pyramid(scan_id_, stored));
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return result;
  }

 private:
  Status cancelled() const {
    if (options_.cancel != nullptr && options_.cancel->load()) return io_error("interrupted");
    return Status::ok();
  }

  Result<BucketFiles> make_files(const Level& level, std::uint64_t points) const {
    const std::uint64_t per_bucket = budget_ / 4;
    const std::uint64_t buckets =
        std::clamp<std::uint64_t>((points * kBucketBytesPerPoint + per_bucket - 1) / per_bucket, 1, kMaxBuckets);
    return BucketFiles::create(tmp_parent_, static_cast<std::uint32_t>(buckets), level.grid, carried_.colors,
                               carried_.intensity, static_cast<std::size_t>(budget_ / 16),
                               carried_.classification ? std::uint32_t{kLasClassification} : 0u, 0);
  }

  // Level 1's points: the map layer of every chunk, thinned to the level's
  // pitch (read here, decoded by every thread, appended here in order;
  // core/parallel.h's ordered pipeline, 2 chunks per thread in flight).
  Status feed_from_chunks(const std::vector<ChunkRef>& refs, const Level& level, BucketFiles& files) {
    struct Slot {
      ChunkRow row;
      PointCloud points;
      Status status;
    };
    std::vector<ChunkKey> keys;
    const auto read = [&](std::size_t i, Slot& s) {
      auto row = archive_.read_chunk(refs[i].id);
      if (row) {
        s.row = std::move(*row);
      } else {
        s.status = row.status();
      }
    };
    const auto decode = [&](std::size_t, Slot& s) {
      if (!s.status) return;
      DecodeOptions dec;
      dec.base_layer = true;
      auto points = decode_chunk(s.row.blob, dec);
      std::vector<std::uint8_t>().swap(s.row.blob);
      if (!points) {
        s.status = points.status().with_context(archive_.path() + ": chunk id " + std::to_string(s.row.ref.id));
        return;
      }
      conform(*points, carried_);
      s.points = thin(*points, grid_.origin, level.pitch);
    };
    const auto append = [&](std::size_t, Slot& s, bool&) -> Status {
      RELIEF_RETURN_IF_ERROR(cancelled());
      RELIEF_RETURN_IF_ERROR(s.status);
      keys.assign(s.points.size(), parent(s.row.ref.key, level.level));
      return files.append(s.points, keys.data());
    };
    return ordered_pipeline<Slot>(refs.size(), threads_, static_cast<std::size_t>(threads_) * 2, read, decode, append);
  }

  struct LevelCount {
    std::uint64_t nodes = 0;
    std::uint64_t points = 0;
  };

  // Calls fn(keys, nodes) for the nodes of each bucket of `files`, a bucket
  // at a time, nodes[i] holding node keys[i]'s points thinned to the level's
  // pitch, in canonical order (thinned in parallel). The bucket is read
  // whole: a node's points may be spread over it (the bucket count keeps it
  // within the budget).
  template <typename Fn>
  Status for_each_bucket(const Level& level, BucketFiles& files, bool discard, Fn&& fn) {
    AlignedBuffer buffer;
    PointCloud slice;
    Grouping grouping;
    for (std::uint32_t b = 0; b < files.bucket_count(); ++b) {
      std::uint64_t offset = 0;
      while (offset < files.bucket_bytes(b)) {
        RELIEF_RETURN_IF_ERROR(cancelled());
        RELIEF_RETURN_IF_ERROR(files.read_slice(b, &offset, ~std::uint64_t{0}, slice, grouping, buffer));
        std::vector<std::uint64_t> start;
        const std::vector<std::uint32_t> by_key = grouping.sort_by_key(start);
        const std::vector<std::uint32_t>& order = grouping.order;
        std::vector<ChunkKey> keys(by_key.size());
        std::vector<PointCloud> nodes(by_key.size());
        for_each_parallel(by_key.size(), threads_, [&](std::size_t n) {
          const std::uint32_t k = by_key[n];
          keys[n] = grouping.keys[k];
          const std::vector<std::uint32_t> idx(order.begin() + static_cast<std::ptrdiff_t>(start[k]),
                                               order.begin() + static_cast<std::ptrdiff_t>(start[k + 1]));
          nodes[n] = thin(slice.gathered(idx), grid_.origin, level.pitch);
        });
        RELIEF_RETURN_IF_ERROR(fn(keys, nodes));
      }
      if (discard) files.discard(b);
    }
    return Status::ok();
  }

  Result<LevelCount> count_level(const Level& level, BucketFiles& files) {
    LevelCount count;
    RELIEF_RETURN_IF_ERROR(for_each_bucket(level, files, false,
                                           [&](const std::vector<ChunkKey>& keys, const std::vector<PointCloud>& nodes) {
                                             count.nodes += keys.size();
                                             for (const PointCloud& n : nodes) count.points += n.size();
                                             return Status::ok();
                                           }));
    return count;
  }

  // Encodes every node of `level` (when `store`) from its bucket files; the
  // nodes' points thinned to the next level's pitch go to `next`.
  Status encode_level(const Level& level, BucketFiles& files, bool store, BucketFiles* next, PyramidResult& result) {
    std::vector<ChunkKey> up_keys;
    std::uint64_t done = 0;
    const double next_pitch = next != nullptr ? make_level(level.level + 1, grid_, base_).pitch : 0;
    return for_each_bucket(level, files, true, [&](const std::vector<ChunkKey>& keys, std::vector<PointCloud>& nodes) {
      struct Node {
        ChunkRow row;
        PointCloud up;  // the node's points thinned for the next level
        Status status;
      };
      std::vector<Node> out(keys.size());
      for_each_parallel(keys.size(), threads_, [&](std::size_t n) {
        Node& node = out[n];
        if (next != nullptr) node.up = thin(nodes[n], grid_.origin, next_pitch);
        if (!store) return;
        EncodeParams params = level.params;
        params.grid_origin = level.grid.chunk_box(keys[n]).min;
        EncodeStats stats;
        auto blob = encode_chunk(nodes[n], params, {}, &stats);
        if (!blob) {
          node.status =
              blob.status().with_context(archive_.path() + ": pyramid level " + std::to_string(level.level) + " node");
          return;
        }
        node.row.ref.key = keys[n];
        node.row.ref.scan_id = scan_id_;
        node.row.ref.input_points = nodes[n].size();
        node.row.ref.decoded_points = stats.decoded_points;
        node.row.ref.bounds = stats.decoded_bounds;
        node.row.codec = 1;
        node.row.codec_params = encode_params_to_string(params, ParamsText::kCompact);
        node.row.blob = std::move(blob).value();
        nodes[n] = PointCloud();
      });
      std::vector<ChunkRow> rows;
      for (Node& node : out) {
        RELIEF_RETURN_IF_ERROR(node.status);
        if (next != nullptr && !node.up.empty()) {
          up_keys.assign(node.up.size(), parent(keys[static_cast<std::size_t>(&node - out.data())], 1));
          RELIEF_RETURN_IF_ERROR(next->append(node.up, up_keys.data()));
        }
        node.up = PointCloud();
        if (!store) continue;
        result.chunks += 1;
        result.points += node.row.ref.decoded_points;
        result.blob_bytes += node.row.blob.size();
        rows.push_back(std::move(node.row));
        if (rows.size() == kRowsPerCommit) {
          RELIEF_RETURN_IF_ERROR(archive_.put_level_chunks(level.level, rows));
          rows.clear();
        }
      }
      RELIEF_RETURN_IF_ERROR(archive_.put_level_chunks(level.level, rows));
      done += keys.size();
      if (options_.progress) options_.progress(level.level, done);
      return Status::ok();
    });
  }

  Archive& archive_;
  std::int64_t scan_id_;
  const PyramidOptions& options_;
  unsigned threads_;
  std::uint64_t budget_ = 0;
  std::string tmp_parent_;
  ArchiveGrid grid_;
  EncodeParams base_;
  Carried carried_;
};

}  // namespace

Result<PyramidResult> build_pyramid(Archive& archive, std::int64_t scan_id, const PyramidOptions& options) {
  Builder builder(archive, scan_id, options);
  Result<PyramidResult> result = builder.run();
  if (!result) {
    // Nothing half-built stays behind: the scan reads from its chunks.
    (void)archive.remove_pyramid(scan_id);
  }
  return result;
}

}  // namespace relief
