// Box queries over an archive: index lookup, blob reads with checksum, parallel
// decode at the requested level of detail, clipping, in-order delivery.
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <thread>

#include "core/parallel.h"
#include "relief/codec.h"
#include "relief/query.h"

namespace relief {

namespace {

// Chunks decoded per wave per thread: enough to keep every core busy, few
// enough that memory stays a handful of chunks whatever the box.
constexpr unsigned kChunksPerThreadPerWave = 2;

bool contains(const Box3d& outer, const Box3d& inner) {
  return outer.min.x <= inner.min.x && outer.min.y <= inner.min.y && outer.min.z <= inner.min.z &&
         outer.max.x >= inner.max.x && outer.max.y >= inner.max.y && outer.max.z >= inner.max.z;
}

std::string chunk_name(const ChunkRef& r) {
  return "chunk (" + std::to_string(r.key.ix) + "," + std::to_string(r.key.iy) + "," + std::to_string(r.key.iz) +
         ") seq " + std::to_string(r.seq) + " (id " + std::to_string(r.id) + ")";
}

void clip(PointCloud& cloud, const Box3d& box) {
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
  Reader(std::unique_ptr<Archive> archive, ArchiveInfo info) : archive_(std::move(archive)), info_(std::move(info)) {}

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
    RELIEF_ASSIGN_OR_RETURN(std::vector<ChunkRef> refs, archive_->find_chunks(box));
    return run(refs, box, options, sink);
  }

  Result<QueryStats> query_all(const QueryOptions& options, const PointSink& sink) override {
    RELIEF_ASSIGN_OR_RETURN(std::vector<ChunkRef> refs, archive_->all_chunks());
    const double inf = std::numeric_limits<double>::infinity();
    return run(refs, Box3d{{-inf, -inf, -inf}, {inf, inf, inf}}, options, sink);
  }

 private:
  Result<QueryStats> run(const std::vector<ChunkRef>& refs, const Box3d& box, const QueryOptions& options,
                         const PointSink& sink) {
    if (options.lod < 1) return invalid_argument("level of detail must be at least 1");
    const auto t0 = std::chrono::steady_clock::now();
    const std::uint64_t bytes_before = archive_->blob_bytes_read();
    QueryStats stats;
    stats.chunks_in_index = refs.size();
    const unsigned threads = resolve_threads(options.threads);
    const std::size_t wave = static_cast<std::size_t>(threads) * kChunksPerThreadPerWave;
    DecodeOptions dec;
    dec.lod = options.lod;

    struct Slot {
      ChunkRef ref;
      std::vector<std::uint8_t> blob;
      PointCloud points;
      Status status;
    };
    std::vector<Slot> slots;
    for (std::size_t first = 0; first < refs.size(); first += wave) {
      const std::size_t count = std::min(wave, refs.size() - first);
      slots.assign(count, Slot{});
      // Blobs are read on this thread (one SQLite connection); checksum
      // failures surface here.
      for (std::size_t k = 0; k < count; ++k) {
        slots[k].ref = refs[first + k];
        auto row = archive_->read_chunk(slots[k].ref.id);
        if (row) {
          slots[k].blob = std::move(row->blob);
        } else {
          slots[k].status = row.status();
        }
      }
      std::atomic<std::size_t> next{0};
      const auto decode_worker = [&] {
        for (std::size_t k = next.fetch_add(1); k < count; k = next.fetch_add(1)) {
          Slot& s = slots[k];
          if (!s.status) continue;
          auto pts = decode_chunk(s.blob, dec);
          std::vector<std::uint8_t>().swap(s.blob);
          if (!pts) {
            s.status = pts.status().with_context(archive_->path() + ": " + chunk_name(s.ref));
            continue;
          }
          s.points = std::move(pts).value();
          if (!contains(box, s.ref.bounds)) clip(s.points, box);
        }
      };
      // This thread decodes too; the others join it for the wave.
      std::vector<std::thread> pool;
      const unsigned helpers = static_cast<unsigned>(std::min<std::size_t>(threads, count)) - 1;
      for (unsigned t = 0; t < helpers; ++t) pool.emplace_back(decode_worker);
      decode_worker();
      for (std::thread& t : pool) t.join();
      for (Slot& s : slots) {
        if (!s.status) {
          if (!options.skip_corrupt) return s.status;
          ++stats.chunks_skipped;
          if (options.on_warning) options.on_warning("skipped: " + s.status.message());
          continue;
        }
        ++stats.chunks_decoded;
        if (s.points.empty()) continue;
        stats.points += s.points.size();
        RELIEF_RETURN_IF_ERROR(sink(s.points));
        s.points = PointCloud();
      }
    }
    stats.blob_bytes_read = archive_->blob_bytes_read() - bytes_before;
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return stats;
  }

  std::unique_ptr<Archive> archive_;
  ArchiveInfo info_;
};

}  // namespace

Result<std::unique_ptr<ArchiveReader>> ArchiveReader::open(const std::string& path) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Archive> archive, Archive::open(path, Archive::Mode::kReadOnly));
  RELIEF_ASSIGN_OR_RETURN(ArchiveInfo info, archive->info());
  return std::unique_ptr<ArchiveReader>(new Reader(std::move(archive), std::move(info)));
}

Box3d box_2d(double xmin, double ymin, double xmax, double ymax) {
  const double inf = std::numeric_limits<double>::infinity();
  return Box3d{{xmin, ymin, -inf}, {xmax, ymax, inf}};
}

}  // namespace relief
