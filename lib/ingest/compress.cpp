// compress_files / append_files: an external distribution sort into bucket
// files, then chunk-by-chunk parallel encoding into the archive.
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>

#include "core/parallel.h"
#include "ingest/bucket_files.h"
#include "ingest/chunk_pipeline.h"
#include "ingest/ingest_common.h"
#include "relief/archive.h"
#include "relief/ingest.h"

namespace relief {

namespace ingest {

namespace {

// Working memory per point while a bucket slice is grouped: the decoded
// record (positions, colour, intensity) plus its key and sort entry.
constexpr std::uint64_t kGroupBytesPerPoint = 24 + 3 + 4 + 24 + 16;
// Encoder scratch per point of a chunk being encoded (sorted keys, plane
// coordinates, the copy handed to the encoder, its decode check).
constexpr std::uint64_t kEncodeBytesPerPoint = 220;
constexpr std::uint32_t kMinBuckets = 4;
constexpr std::uint32_t kMaxBuckets = 4096;
// Points per read from an input.
constexpr std::size_t kReadBatch = 1u << 20;
// Bytes per point assumed for inputs whose header gives no count (ASCII).
constexpr std::uint64_t kUnknownBytesPerPoint = 12;

std::uint64_t file_size_or_zero(const std::string& path) {
  std::error_code ec;
  const auto s = std::filesystem::file_size(path, ec);
  return ec ? 0 : static_cast<std::uint64_t>(s);
}

}  // namespace

Result<InputSet> open_inputs(const std::vector<std::string>& inputs, const ReaderOptions& reader_options) {
  if (inputs.empty()) return invalid_argument("no input files");
  InputSet set;
  set.colors = true;
  set.intensity = true;
  for (const std::string& path : inputs) {
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> r, open_point_reader(path, reader_options));
    const PointStreamInfo& info = r->info();
    set.colors = set.colors && info.has_colors;
    set.intensity = set.intensity && info.has_intensity;
    if (info.point_count) {
      set.estimated_points += *info.point_count;
    } else {
      set.estimated_points += file_size_or_zero(path) / kUnknownBytesPerPoint;
    }
    if (info.point_count) set.known_total += *info.point_count;
    set.all_counts_known = set.all_counts_known && info.point_count.has_value();
    if (set.crs.empty()) set.crs = info.crs;
    ArchiveSource src;
    src.path = path;
    src.format = info.format;
    src.crs = info.crs;
    set.sources.push_back(src);
    set.readers.push_back(std::move(r));
  }
  return set;
}

void conform_attributes(PointCloud& batch, bool colors, bool intensity) {
  if (!colors) batch.colors.clear();
  if (!intensity) batch.intensities.clear();
}

Result<IngestResult> run_ingest(Archive& archive, const ArchiveGrid& grid, const EncodeParams& params,
                                InputSet& in, PointCloud pending, const IngestOptions& options,
                                const std::string& tmp_parent) {
  const auto t0 = std::chrono::steady_clock::now();
  const unsigned threads = resolve_threads(options.threads);
  const std::uint64_t budget = std::max<std::uint64_t>(options.memory_budget, 64u << 20);
  const std::size_t rec = record_size(in.colors, in.intensity);

  // Budget: 1/8 for bucket write buffers, 1/3 for one loaded bucket slice,
  // 1/3 for the encoders; the rest is headroom (reader blocks, SQLite cache).
  const std::uint64_t slice_points = std::max<std::uint64_t>(1, (budget / 3) / kGroupBytesPerPoint);
  const std::uint64_t part_points = std::max<std::uint64_t>(1024, (budget / 3) / (threads * kEncodeBytesPerPoint));
  const std::uint64_t read_batch =
      std::max<std::uint64_t>(1024, std::min<std::uint64_t>(kReadBatch, (budget / 16) / (kGroupBytesPerPoint + rec)));
  // Enough buckets that a bucket usually fits one slice (x2 for skew).
  const std::uint64_t want = (2 * std::max<std::uint64_t>(1, in.estimated_points)) / slice_points + 1;
  const auto buckets = static_cast<std::uint32_t>(std::clamp<std::uint64_t>(want, kMinBuckets, kMaxBuckets));
  const std::size_t write_buffer = static_cast<std::size_t>(std::min<std::uint64_t>(budget / 8, 256u << 20));

  RELIEF_ASSIGN_OR_RETURN(BucketFiles files,
                          BucketFiles::create(tmp_parent, buckets, write_buffer, in.colors, in.intensity));

  Progress progress(options.progress, in.all_counts_known ? in.known_total : 0);
  const auto cancelled = [&] { return options.cancel != nullptr && options.cancel->load(); };

  // ---- Pass 1: distribute every point into its chunk's bucket.
  std::vector<ChunkKey> keys;
  PointCloud batch = std::move(pending);
  std::uint64_t points_read = 0;
  for (std::size_t i = 0; i < in.readers.size(); ++i) {
    PointReader& reader = *in.readers[i];
    std::uint64_t from_this = 0;
    for (;;) {
      if (i > 0 || from_this > 0 || batch.empty()) {
        RELIEF_ASSIGN_OR_RETURN(std::size_t got, reader.read(batch, static_cast<std::size_t>(read_batch)));
        if (got == 0) break;
      }
      conform_attributes(batch, in.colors, in.intensity);
      keys.resize(batch.size());
      for (std::size_t k = 0; k < batch.size(); ++k) keys[k] = grid.key_of(batch.positions[k]);
      RELIEF_RETURN_IF_ERROR(files.append(batch, keys));
      from_this += batch.size();
      points_read += batch.size();
      batch.positions.clear();
      progress.update("reading", points_read, 0, 0);
      if (cancelled()) return io_error("interrupted");
    }
    in.sources[i].point_count = from_this;
  }
  RELIEF_RETURN_IF_ERROR(files.finish_writing());

  // ---- Pass 2: each bucket, slice by slice: group by chunk, encode, store.
  RELIEF_ASSIGN_OR_RETURN(std::int64_t scan_id, archive.begin_scan(in.sources));
  ChunkPipeline pipeline(archive, params, grid, scan_id, threads, options.cancel);
  PointCloud slice;
  std::vector<std::pair<ChunkKey, std::uint32_t>> order;
  for (std::uint32_t b = 0; b < files.bucket_count(); ++b) {
    const std::uint64_t n = files.bucket_points(b);
    for (std::uint64_t first = 0; first < n; first += slice_points) {
      const std::uint64_t count = std::min(slice_points, n - first);
      RELIEF_RETURN_IF_ERROR(files.read(b, first, count, slice));
      std::vector<ChunkTask> tasks = group_into_tasks(slice, grid, part_points, order);
      slice = PointCloud();
      RELIEF_RETURN_IF_ERROR(pipeline.run(tasks, [&] {
        progress.update("encoding", points_read, pipeline.totals().chunks, pipeline.totals().blob_bytes);
      }));
    }
    files.discard(b);
  }
  RELIEF_RETURN_IF_ERROR(archive.finish_scan(scan_id, in.colors, in.intensity, in.crs));

  IngestResult result;
  result.points_read = points_read;
  result.points_decoded = pipeline.totals().points_decoded;
  result.chunks_written = pipeline.totals().chunks;
  result.blob_bytes = pipeline.totals().blob_bytes;
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  result.cell_size = params.cell_size;
  result.chunk_edge = grid.chunk_edge;
  result.scan_id = scan_id;
  progress.finish("done", points_read, result.chunks_written, result.blob_bytes);
  return result;
}

std::vector<ChunkTask> group_into_tasks(const PointCloud& slice, const ArchiveGrid& grid, std::uint64_t part_points,
                                        std::vector<std::pair<ChunkKey, std::uint32_t>>& order) {
  order.resize(slice.size());
  for (std::size_t i = 0; i < slice.size(); ++i) {
    order[i] = {grid.key_of(slice.positions[i]), static_cast<std::uint32_t>(i)};
  }
  std::sort(order.begin(), order.end());
  std::vector<ChunkTask> tasks;
  const bool colors = slice.has_colors(), intensity = slice.has_intensity();
  std::size_t i = 0;
  while (i < order.size()) {
    std::size_t j = i;
    while (j < order.size() && order[j].first == order[i].first && j - i < part_points) ++j;
    ChunkTask t;
    t.key = order[i].first;
    t.points.reserve(j - i, colors, intensity);
    for (std::size_t k = i; k < j; ++k) {
      const std::uint32_t src = order[k].second;
      t.points.positions.push_back(slice.positions[src]);
      if (colors) t.points.colors.push_back(slice.colors[src]);
      if (intensity) t.points.intensities.push_back(slice.intensities[src]);
    }
    tasks.push_back(std::move(t));
    i = j;
  }
  return tasks;
}

void remove_archive_files(const std::string& path) {
  for (const char* suffix : {"", "-wal", "-shm", "-journal"}) ::unlink((path + suffix).c_str());
}

std::string default_tmp_parent(const std::string& archive_path, const IngestOptions& options) {
  if (!options.tmp_dir.empty()) return options.tmp_dir;
  const std::filesystem::path p(archive_path);
  const std::string parent = p.parent_path().string();
  return parent.empty() ? "." : parent;
}

}  // namespace ingest

Result<IngestResult> compress_files(const std::vector<std::string>& inputs, const std::string& archive_path,
                                    const IngestOptions& options) {
  using namespace ingest;
  struct stat st {};
  if (::stat(archive_path.c_str(), &st) == 0) {
    return io_error(archive_path + ": already exists (use 'relief append' to add to an archive)");
  }
  RELIEF_ASSIGN_OR_RETURN(InputSet in, open_inputs(inputs, options.reader));

  EncodeParams params = options.codec;
  PointCloud first;
  if (params.cell_size == 0 || options.error_target > 0) {
    // The first points set the cell size (from their density, or by trial
    // encodes for an error target); they are then ingested like every batch.
    RELIEF_ASSIGN_OR_RETURN(std::size_t got, in.readers[0]->read(first, kReadBatch));
    if (got == 0) return invalid_argument(inputs[0] + ": no points to derive a cell size from");
    conform_attributes(first, in.colors, in.intensity);
    if (options.error_target > 0) {
      RELIEF_ASSIGN_OR_RETURN(params.cell_size, choose_cell_for_error(first, params, options.error_target));
    } else {
      params.cell_size = suggest_cell_size(first, params.map_resolution);
    }
  }
  ArchiveGrid grid;
  grid.chunk_edge = options.chunk_edge > 0 ? options.chunk_edge : params.cell_size * kDefaultCellsPerChunk;
  if (!(grid.chunk_edge > 0) || !std::isfinite(grid.chunk_edge)) {
    return invalid_argument("chunk edge must be a positive number");
  }
  if (grid.chunk_edge / params.cell_size > std::ldexp(1.0, 21)) {
    return invalid_argument("chunk edge " + std::to_string(grid.chunk_edge) + " is more than 2^21 cells of " +
                            std::to_string(params.cell_size));
  }
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Archive> archive,
                          Archive::create(archive_path, grid, encode_params_to_string(params), options.creator));
  auto result = run_ingest(*archive, grid, params, in, std::move(first), options,
                           default_tmp_parent(archive_path, options));
  if (!result) {
    const bool interrupted = options.cancel != nullptr && options.cancel->load();
    archive.reset();
    // A clean failure leaves no archive; an interruption keeps what is committed.
    if (!interrupted) remove_archive_files(archive_path);
    return result.status();
  }
  return result;
}

Result<IngestResult> append_files(const std::string& archive_path, const std::vector<std::string>& inputs,
                                  const IngestOptions& options) {
  using namespace ingest;
  RELIEF_ASSIGN_OR_RETURN(InputSet in, open_inputs(inputs, options.reader));
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Archive> archive, Archive::open(archive_path, Archive::Mode::kReadWrite));
  RELIEF_ASSIGN_OR_RETURN(ArchiveInfo info, archive->info());
  RELIEF_ASSIGN_OR_RETURN(EncodeParams params, encode_params_from_string(info.codec_params));
  if (info.chunk_count > 0) {
    // Keep one attribute set per archive so every chunk decodes alike.
    if (info.has_colors && !in.colors) {
      return invalid_argument(archive_path + " has colours but the new input has none");
    }
    if (info.has_intensity && !in.intensity) {
      return invalid_argument(archive_path + " has intensity but the new input has none");
    }
    in.colors = info.has_colors;
    in.intensity = info.has_intensity;
  }
  auto result = run_ingest(*archive, info.grid, params, in, PointCloud(), options,
                           default_tmp_parent(archive_path, options));
  if (!result) {
    const bool interrupted = options.cancel != nullptr && options.cancel->load();
    if (!interrupted) {
      // Remove whatever this append committed: the archive is as before.
      auto scans = archive->info();
      if (scans) {
        for (const ArchiveScan& s : scans->scans) {
          bool existed = false;
          for (const ArchiveScan& old : info.scans) existed = existed || old.id == s.id;
          if (!existed) (void)archive->abort_scan(s.id);
        }
      }
    }
    return result.status();
  }
  return result;
}

}  // namespace relief
