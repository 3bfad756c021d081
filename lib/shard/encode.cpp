// Stage 2 of a sharded build: one key range's points from every input's
// partition file -> a shard archive, encoded exactly as compress_files
// encodes those chunks (same grouping, split rule, parameters, pipeline).
#include <sys/stat.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <memory>

#include "core/host.h"
#include "core/parallel.h"
#include "ingest/bucket_encode.h"
#include "ingest/bucket_files.h"
#include "ingest/chunk_pipeline.h"
#include "ingest/ingest_common.h"
#include "ingest/las_columns.h"
#include "ingest/slice_pool.h"
#include "relief/codec.h"
#include "relief/shard.h"
#include "shard/partition_file.h"
#include "shard/shard_files.h"

namespace relief {

Result<IngestResult> encode_shard(const ShardPlan& plan, std::uint32_t range, const std::string& dir,
                                  const std::string& out, const EncodeShardOptions& options) {
  using namespace ingest;
  const auto t0 = std::chrono::steady_clock::now();
  if (range >= plan.range_count()) {
    return invalid_argument("range " + std::to_string(range) + " of a plan of " + std::to_string(plan.range_count()) +
                            " ranges");
  }
  // A retried task replaces its earlier shard; any other file is left alone.
  if (struct stat st {}; ::stat(out.c_str(), &st) == 0) {
    if (!S_ISREG(st.st_mode) || !Archive::open(out, Archive::Mode::kReadOnly)) {
      return io_error(out + ": already exists and is not a Relief archive (shard-encode replaces only an earlier "
                            "shard, never another file)");
    }
  }
  RELIEF_ASSIGN_OR_RETURN(const EncodeParams params, encode_params_from_string(plan.archive_params));
  EncodeParams chunk_params = params;
  if (plan.has_intensity_range) chunk_params.intensity_range = std::make_pair(plan.intensity_lo, plan.intensity_hi);
  const std::uint64_t plan_id = shard_plan_id(plan);
  const shard::PartitionLayout layout = shard::PartitionLayout::of(plan);
  const std::string base = dir.empty() ? std::string(".") : dir;
  // Every input's manifest (its point count) and the size of its range file,
  // all checked before any point is read or memory reserved.
  std::vector<ArchiveSource> sources = plan.sources;
  std::vector<std::string> warnings = plan.warnings;
  std::uint64_t total = 0;
  for (std::uint32_t i = 0; i < plan.input_count(); ++i) {
    RELIEF_ASSIGN_OR_RETURN(const shard::Manifest m,
                            shard::read_manifest(base + "/" + partition_manifest_name(i), plan_id, i));
    sources[i].point_count = m.points;
    warnings.insert(warnings.end(), m.warnings.begin(), m.warnings.end());
    RELIEF_ASSIGN_OR_RETURN(const std::uint64_t n,
                            shard::partition_file_points(base + "/" + partition_file_name(i, range), plan_id, i, range,
                                                         layout));
    if (n > m.points) {
      return corrupt_data(base + "/" + partition_file_name(i, range) + ": more points than its input's manifest says");
    }
    total += n;
  }
  std::uint64_t read = 0;
  for (const ArchiveSource& src : sources) read += src.point_count;
  if (read != plan.points) {
    return invalid_argument(base + ": stage 1 read " + std::to_string(read) + " points where the plan read " +
                            std::to_string(plan.points) + ": the inputs changed since the plan (make a new plan)");
  }
  const std::string where = base + "/" + "range " + std::to_string(range);
  const double coordinate_limit = max_coordinate_magnitude(params.cell_size, plan.grid.chunk_edge);
  // A point outside the range is a damaged or foreign partition file.
  const auto outside = [&](const ChunkKey& k) {
    std::string chunk = where;
    chunk += ": holds a point of chunk ";
    chunk += std::to_string(k.ix) + "," + std::to_string(k.iy) + "," + std::to_string(k.iz);
    return corrupt_data(chunk + ", which belongs to range " + std::to_string(plan.range_of(k)));
  };
  // The budget as compress shares it, over this range's points.
  const std::uint64_t las_bytes = las_record_bytes(layout.las, layout.extra_size);
  const IngestBudget budget =
      plan_ingest_budget(options.memory_budget, resolve_threads(options.threads), las_bytes, total, true);
  const std::string tmp_parent = default_tmp_parent(out, options.tmp_dir);
  const auto interrupted = [&]() -> Status {
    if (options.cancel != nullptr && options.cancel->load()) return io_error(out + ": interrupted");
    return Status::ok();
  };

  core::remove_stale_temps_beside(out);  // left by killed tasks of this host writing `out`
  const std::string tmp = core::temp_path_beside(out);
  remove_archive_files(tmp);
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Archive> archive,
                          Archive::create(tmp, plan.grid, plan.archive_params, plan.creator,
                                          ingest_page_size(plan.points)));
  const auto failed = [&](Status s) -> Result<IngestResult> {
    archive.reset();
    remove_archive_files(tmp);
    return s;
  };
  // The scan's attributes as compress records them, LAS metadata included.
  auto scan_id = archive->begin_scan(sources, plan.attributes);
  if (!scan_id) return failed(scan_id.status());
  PipelineTotals totals;
  Progress progress(options.progress, total);
  // Both ways give the same blobs, as compress's two ways do: chunks whole,
  // cut by the plan's octant rule.
  const auto encode = [&]() -> Status {
    // Before the pipeline: its workers hand slices back to the pool until
    // they stop, so the pool must outlive them.
    SlicePool slices(budget.slice_points);
    // A range read whole: also before the pipeline, whose tasks point into them.
    PointCloud points;
    Grouping grouping;
    ChunkPipeline pipeline(*archive, chunk_params, plan.grid, *scan_id, budget.encode_threads, options.cancel,
                           options.verify_blobs, budget.encode_memory);
    const std::function<void()> tick = [&] {
      const PipelineTotals t = pipeline.encoded();
      progress.update("encoding", total, t.chunks, t.blob_bytes, t.points_in);
    };
    if (total <= budget.in_memory_points) {
      // In input order, each file in read order: the order compress_files sees.
      points.reserve(static_cast<std::size_t>(total), layout.colors, layout.intensity);
      reserve_las(points.las, static_cast<std::size_t>(total), layout.las, layout.extra_size);
      for (std::uint32_t i = 0; i < plan.input_count(); ++i) {
        RELIEF_RETURN_IF_ERROR(interrupted());
        RELIEF_RETURN_IF_ERROR(shard::read_partition_file(base + "/" + partition_file_name(i, range), plan_id, i,
                                                          range, layout, points)
                                   .status());
        progress.update("reading", points.size(), 0, 0);
      }
      RELIEF_RETURN_IF_ERROR(check_coordinates(points, coordinate_limit, where, 0));
      grouping.add(points.positions.data(), points.size(), plan.grid);
      for (const ChunkKey& k : grouping.keys) {
        if (plan.range_of(k) != range) return outside(k);
      }
      RELIEF_RETURN_IF_ERROR(pipeline.run(make_tasks(points, plan.split_points, grouping, &plan.grid), tick));
    } else {
      // Larger than half the budget: the external sort of compress, its
      // bucket files beside the shard (or in --tmp), read back in slices.
      RELIEF_ASSIGN_OR_RETURN(BucketFiles files,
                              BucketFiles::create(tmp_parent, budget.buckets, plan.grid, layout.colors,
                                                  layout.intensity, budget.staging_bytes, layout.las,
                                                  layout.extra_size));
      std::vector<ChunkKey> keys;
      std::uint64_t first = 0;
      for (std::uint32_t i = 0; i < plan.input_count(); ++i) {
        const Result<std::uint64_t> got = shard::read_partition_batches(
            base + "/" + partition_file_name(i, range), plan_id, i, range, layout, budget.read_batch,
            [&](PointCloud& batch) -> Status {
              RELIEF_RETURN_IF_ERROR(interrupted());
              RELIEF_RETURN_IF_ERROR(check_coordinates(batch, coordinate_limit, where, first));
              first += batch.size();
              progress.update("reading", first, 0, 0);
              keys.resize(batch.size());
              plan.grid.keys_of(batch.positions.data(), batch.size(), keys.data());
              for (std::size_t j = 0; j < keys.size(); ++j) {
                if ((j == 0 || !(keys[j] == keys[j - 1])) && plan.range_of(keys[j]) != range) return outside(keys[j]);
              }
              return files.append(batch, keys.data());
            });
        if (!got) return got.status();
      }
      RELIEF_RETURN_IF_ERROR(files.finish_writing());
      BucketEncodeOptions how;
      how.whole_chunks = true;
      how.task_points = plan.split_points;
      how.split_grid = &plan.grid;
      how.tmp_parent = tmp_parent;
      how.cancel = options.cancel;
      RELIEF_RETURN_IF_ERROR(encode_bucket_files(files, plan.grid, pipeline, slices, budget, how, tick));
    }
    totals = pipeline.totals();
    return Status::ok();
  };
  if (Status s = encode(); !s) {
    // The pipeline reports a cancellation as its own error: say it plainly.
    if (Status stopped = interrupted(); !stopped) return failed(stopped);
    return failed(s);
  }
  const ScanAttributes& attributes = plan.attributes;
  if (Status s = finish_scan(*archive, *scan_id, attributes.has_colors, attributes.has_intensity, attributes.crs);
      !s) {
    return failed(s);
  }
  if (Status s = archive->close(); !s) {  // one file before it moves
    return failed(Status(s.code(), s.message() + "; nothing of the shard is kept"));
  }
  archive.reset();
  // No journal of an earlier file of that name may be replayed into this one.
  for (const char* suffix : {"-wal", "-journal"}) ::unlink((out + suffix).c_str());
  if (std::rename(tmp.c_str(), out.c_str()) != 0) {
    remove_archive_files(tmp);
    return io_error(out + ": cannot rename the finished shard into place");
  }
  progress.finish("done", total, totals.chunks, totals.blob_bytes, totals.points_in);
  IngestResult r;
  r.points_read = total;
  r.points_decoded = totals.points_decoded;
  r.chunks_written = totals.chunks;
  r.blob_bytes = totals.blob_bytes;
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.cell_size = params.cell_size;
  r.chunk_edge = plan.grid.chunk_edge;
  r.scan_id = *scan_id;
  r.warnings = std::move(warnings);
  return r;
}

}  // namespace relief
