// Live streaming into an archive (Golla & Klein 2015, III-A): incoming points
// are buffered per chunk until data stops falling into that chunk, or encoded
// batch by batch in immediate mode.
#include <sys/stat.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>

#include "core/parallel.h"
#include "ingest/chunk_pipeline.h"
#include "ingest/ingest_common.h"
#include "relief/crs.h"
#include "relief/ingest.h"
#include "relief/io.h"

namespace relief {

namespace {

using ingest::ChunkPipeline;
using ingest::ChunkTask;

// Encoder scratch per point, as in compress.cpp: bounds the size of one blob.
constexpr std::uint64_t kStreamPartPoints = 2'000'000;

class StreamIngestImpl final : public StreamIngest {
 public:
  StreamIngestImpl(std::unique_ptr<Archive> archive, const ArchiveGrid& grid, const EncodeParams& params,
                   const StreamOptions& options, std::int64_t scan_id, bool colors, bool intensity,
                   std::uint32_t las, std::uint32_t extra_size, bool created, std::string crs)
      : archive_(std::move(archive)),
        path_(archive_->path()),
        created_(created),
        grid_(grid),
        params_(params),
        options_(options),
        scan_id_(scan_id),
        colors_(colors),
        intensity_(intensity),
        las_(las),
        extra_size_(extra_size),
        crs_(std::move(crs)),
        pipeline_(*archive_, params, grid, scan_id, resolve_threads(options.ingest.threads), options.ingest.cancel,
                  options.ingest.verify_blobs),
        progress_(options.ingest.progress, 0),
        start_(std::chrono::steady_clock::now()) {}

  Status push(const PointCloud& incoming) override {
    if (finished_) return invalid_argument("stream already finished");
    RELIEF_RETURN_IF_ERROR(incoming.validate("stream batch"));
    // A batch of 0 points carries nothing (and still counts as a batch for
    // --idle); any other carries the stream's set.
    if (!incoming.empty() && (incoming.has_colors() != colors_ || incoming.has_intensity() != intensity_)) {
      return invalid_argument("stream batch has " +
                              ingest::attribute_list(incoming.has_colors(), incoming.has_intensity()) +
                              " but the stream was opened with " + ingest::attribute_list(colors_, intensity_));
    }
    if (!incoming.empty() && incoming.las.carried() != las_) {
      return invalid_argument("stream batch carries the LAS attributes '" + las_attribute_list(incoming.las.carried()) +
                              "' but the stream was opened with '" + las_attribute_list(las_) + "'");
    }
    if (!incoming.empty() && (las_ & kLasExtraBytes) != 0 && incoming.las.extra_bytes_size != extra_size_) {
      return invalid_argument("stream batch has " + std::to_string(incoming.las.extra_bytes_size) +
                              " extra bytes a point but the stream was opened with " + std::to_string(extra_size_));
    }
    PointCloud snapped;
    if (params_.bound) {
      snapped = incoming;
      RELIEF_RETURN_IF_ERROR(ingest::snap_to_grid(snapped, *params_.bound, "stream", points_read_));
    }
    const PointCloud& batch = params_.bound ? snapped : incoming;
    RELIEF_RETURN_IF_ERROR(ingest::check_coordinates(
        batch, max_coordinate_magnitude(params_.cell_size, grid_.chunk_edge), "stream", points_read_));
    points_read_ += batch.size();
    ++batch_index_;
    if (options_.immediate) {
      ingest::Grouping grouping;
      std::vector<ChunkTask> tasks = ingest::group_into_tasks(batch, grid_, kStreamPartPoints, grouping);
      return encode(tasks);
    }
    for (std::size_t i = 0; i < batch.size(); ++i) {
      Pending& p = buffered_[grid_.key_of(batch.positions[i])];
      p.points.push_back_from(batch, i);
      p.last_batch = batch_index_;
    }
    buffered_points_ += batch.size();
    // Chunks that this many batches left untouched are complete.
    std::vector<ChunkKey> ready;
    for (const auto& [key, p] : buffered_) {
      if (batch_index_ - p.last_batch >= options_.idle_batches) ready.push_back(key);
    }
    // Over the bound: the longest idle, then the largest, go early.
    if (buffered_points_ > options_.max_buffered_points) {
      std::vector<std::pair<std::pair<std::uint64_t, std::size_t>, ChunkKey>> rank;
      for (const auto& [key, p] : buffered_) {
        if (batch_index_ - p.last_batch >= options_.idle_batches) continue;
        rank.push_back({{p.last_batch, ~p.points.size()}, key});
      }
      std::sort(rank.begin(), rank.end());
      std::uint64_t freed = 0;
      for (const ChunkKey& k : ready) freed += buffered_[k].points.size();
      for (const auto& r : rank) {
        if (buffered_points_ - freed <= options_.max_buffered_points / 2) break;
        ready.push_back(r.second);
        freed += buffered_[r.second].points.size();
      }
    }
    return flush(ready);
  }

  Status abort() override {
    if (finished_) return Status::ok();  // finish() cleaned up after itself
    finished_ = true;
    buffered_.clear();
    if (!created_) return archive_->abort_scan(scan_id_);
    // The archive is this stream's own: nothing of it may stay. The workers
    // only encode, so the archive can close before the pipeline stops.
    archive_.reset();
    ingest::remove_archive_files(path_);
    return Status::ok();
  }

  Result<IngestResult> finish() override {
    if (finished_) return invalid_argument("stream already finished");
    std::vector<ChunkKey> all;
    for (const auto& [key, p] : buffered_) all.push_back(key);
    RELIEF_RETURN_IF_ERROR(flush(all));
    // A stream that brought no point leaves an existing archive as it was:
    // no empty scan, no source of 0 points (a new archive stays, empty).
    const bool nothing = !created_ && points_read_ == 0;
    PyramidResult pyramid;
    if (nothing) {
      RELIEF_RETURN_IF_ERROR(archive_->abort_scan(scan_id_));
    } else {
      RELIEF_ASSIGN_OR_RETURN(
          pyramid, ingest::build_scan_pyramid(*archive_, scan_id_, points_read_, options_.ingest,
                                              ingest::default_tmp_parent(path_, options_.ingest), progress_));
      RELIEF_RETURN_IF_ERROR(archive_->set_source_points(scan_id_, points_read_));
      RELIEF_RETURN_IF_ERROR(archive_->finish_scan(scan_id_, colors_, intensity_, crs_));
    }
    finished_ = true;
    if (Status closed = archive_->close(); !closed) {
      if (!created_) return Status(closed.code(), closed.message() + kept_in_wal_note(path_));
      archive_.reset();
      ingest::remove_archive_files(path_);
      return Status(closed.code(), closed.message() + "; nothing of the new archive is kept");
    }
    IngestResult result = ingest::scan_result(pipeline_.totals(), points_read_, start_, params_.cell_size,
                                              grid_.chunk_edge, scan_id_, progress_);
    result.pyramid = pyramid;
    if (!pyramid.skipped.empty()) result.warnings.push_back(pyramid.skipped);
    if (nothing) {
      result.scan_id = 0;
      result.warnings.push_back(path_ + ": the stream brought no point; the archive is as it was");
    }
    return result;
  }

 private:
  struct Pending {
    PointCloud points;
    std::uint64_t last_batch = 0;
  };

  Status flush(const std::vector<ChunkKey>& keys) {
    if (keys.empty()) return Status::ok();
    std::vector<ChunkTask> tasks;
    for (const ChunkKey& key : keys) {
      auto it = buffered_.find(key);
      if (it == buffered_.end()) continue;
      PointCloud& pts = it->second.points;
      buffered_points_ -= pts.size();
      // Cut very large chunks into several blobs of the same voxel.
      for (std::size_t first = 0; first < pts.size(); first += kStreamPartPoints) {
        const std::size_t last = std::min(pts.size(), first + static_cast<std::size_t>(kStreamPartPoints));
        ChunkTask t;
        t.key = key;
        if (first == 0 && last == pts.size()) {
          t.points = std::move(pts);
        } else {
          t.points.reserve(last - first, colors_, intensity_);
          for (std::size_t i = first; i < last; ++i) t.points.push_back_from(pts, i);
        }
        tasks.push_back(std::move(t));
      }
      buffered_.erase(it);
    }
    return encode(tasks);
  }

  Status encode(std::vector<ChunkTask>& tasks) {
    return pipeline_.run(std::move(tasks), [&] {
      const ingest::PipelineTotals t = pipeline_.encoded();
      progress_.update("streaming", points_read_, t.chunks, t.blob_bytes, t.points_in);
    });
  }

  std::unique_ptr<Archive> archive_;
  std::string path_;
  bool created_;  // this stream created the archive (abort removes it)
  ArchiveGrid grid_;
  EncodeParams params_;
  StreamOptions options_;
  std::int64_t scan_id_;
  bool colors_;
  bool intensity_;
  std::uint32_t las_;  // LasAttributeBits of every batch
  std::uint32_t extra_size_;  // extra bytes a point (kLasExtraBytes)
  std::string crs_;           // WKT2 of --crs, or empty
  ChunkPipeline pipeline_;
  ingest::Progress progress_;
  std::chrono::steady_clock::time_point start_;
  std::map<ChunkKey, Pending> buffered_;
  std::uint64_t buffered_points_ = 0;
  std::uint64_t batch_index_ = 0;
  std::uint64_t points_read_ = 0;
  bool finished_ = false;
};

}  // namespace

Result<std::unique_ptr<StreamIngest>> StreamIngest::open(const std::string& archive_path,
                                                         const StreamOptions& options, bool has_colors,
                                                         bool has_intensity, std::uint32_t las_attributes,
                                                         const std::string& extra_bytes_vlr,
                                                         std::uint32_t extra_bytes_size) {
  if (((las_attributes & kLasExtraBytes) != 0) != (extra_bytes_size > 0)) {
    return invalid_argument(archive_path + ": a stream carries extra bytes exactly when it gives their size");
  }
  if (extra_bytes_size > 0) {
    RELIEF_RETURN_IF_ERROR(parse_extra_bytes_vlr({reinterpret_cast<const std::uint8_t*>(extra_bytes_vlr.data()),
                                                  extra_bytes_vlr.size()},
                                                 extra_bytes_size, archive_path + ": the stream's Extra Bytes VLR")
                               .status());
  }
  if ((las_attributes & ~(kLasTextAttributes | kLasExtraBytes)) != 0) {
    return invalid_argument(archive_path + ": a stream carries the LAS dimensions of text columns (" +
                            las_attribute_list(kLasTextAttributes) + "), not '" +
                            las_attribute_list(las_attributes & ~kLasTextAttributes) + "'");
  }
  std::string crs;  // WKT2 of --crs
  if (!options.ingest.crs.empty()) {
    RELIEF_ASSIGN_OR_RETURN(crs, crs_to_wkt2(options.ingest.crs, "--crs"));
  }
  struct stat st {};
  std::unique_ptr<Archive> archive;
  ArchiveGrid grid;
  EncodeParams params = options.ingest.codec;
  RELIEF_RETURN_IF_ERROR(validate_encode_params(params));
  const bool created = ::stat(archive_path.c_str(), &st) != 0;
  if (!created) {
    RELIEF_ASSIGN_OR_RETURN(archive, Archive::open(archive_path, Archive::Mode::kReadWrite));
    RELIEF_ASSIGN_OR_RETURN(ArchiveInfo info, archive->info());
    RELIEF_ASSIGN_OR_RETURN(params, encode_params_from_string(info.codec_params));
    grid = info.grid;
    if (!crs.empty() && !info.crs.empty() && !ingest::same_crs(crs, info.crs)) {
      return invalid_argument(archive_path + " has the CRS " + crs_label(info.crs) + " but --crs has " +
                              crs_label(crs) + "; one archive holds one CRS");
    }
    if (info.chunk_count > 0 && (info.extra_bytes_size != extra_bytes_size || info.extra_bytes_vlr != extra_bytes_vlr)) {
      return invalid_argument(archive_path + ": the archive's points carry other extra bytes fields (" +
                              std::to_string(info.extra_bytes_size) + " bytes a point) than the stream's (" +
                              std::to_string(extra_bytes_size) + ")");
    }
    if (info.chunk_count > 0 && (info.has_colors != has_colors || info.has_intensity != has_intensity)) {
      // Every chunk of an archive carries the same attributes.
      return invalid_argument(archive_path + ": the archive has " +
                              ingest::attribute_list(info.has_colors, info.has_intensity) + " but the stream has " +
                              ingest::attribute_list(has_colors, has_intensity));
    }
  } else {
    if (!(params.cell_size > 0)) {
      return invalid_argument("a new archive needs a cell size for streaming (--cell)");
    }
    const bool bounded = options.ingest.mode == IngestMode::kBounded;
    if (bounded) {
      params.bound = ingest::resolve_error_bound(options.ingest, ingest::InputSet{});
    } else {
      params.bound.reset();
    }
    const double cells_per_chunk = bounded ? kDefaultCellsPerChunk / kBaseCellFactor : kDefaultCellsPerChunk;
    grid.chunk_edge = options.ingest.chunk_edge > 0 ? options.ingest.chunk_edge : params.cell_size * cells_per_chunk;
    if (bounded && options.ingest.chunk_edge == 0) {
      const double finest = std::min({params.bound->step.x, params.bound->step.y, params.bound->step.z});
      while (grid.chunk_edge / finest > std::ldexp(1.0, 21) - 4) grid.chunk_edge /= 2;
    }
    if (!(grid.chunk_edge > 0) || !std::isfinite(grid.chunk_edge) || grid.chunk_edge > kMaxCoordinateMagnitude ||
        params.cell_size > kMaxCoordinateMagnitude) {
      return invalid_argument("cell size and chunk edge must be positive numbers up to 2^50");
    }
    if (grid.chunk_edge / params.cell_size > std::ldexp(1.0, 21)) {
      return invalid_argument("chunk edge " + std::to_string(grid.chunk_edge) + " is more than 2^21 cells of " +
                              std::to_string(params.cell_size));
    }
    RELIEF_RETURN_IF_ERROR(ingest::check_output_directory(archive_path));
    RELIEF_ASSIGN_OR_RETURN(archive, Archive::create(archive_path, grid, encode_params_to_string(params, ParamsText::kCompact),
                                                     options.ingest.creator));
  }
  ArchiveSource src;
  src.path = "-";
  src.format = "stream";
  src.crs = options.ingest.crs;
  ScanAttributes attributes;
  attributes.crs = crs;
  attributes.has_colors = has_colors;
  attributes.has_intensity = has_intensity;
  // As a CSV's LAS columns: LAS 1.4 point format 6 for LAS output (classes
  // above 31), GPS times of an unknown kind.
  attributes.las_attributes = las_attributes;
  attributes.extra_bytes_vlr = extra_bytes_vlr;
  attributes.extra_bytes_size = extra_bytes_size;
  if (las_attributes != 0) attributes.las_point_format = 6;
  Result<std::int64_t> scan_id = archive->begin_scan({src}, attributes);
  if (!scan_id) {
    if (created) {
      archive.reset();
      ingest::remove_archive_files(archive_path);
    }
    return scan_id.status();
  }
  return std::unique_ptr<StreamIngest>(
      new StreamIngestImpl(std::move(archive), grid, params, options, *scan_id, has_colors, has_intensity,
                           las_attributes, extra_bytes_size, created, crs));
}

}  // namespace relief
