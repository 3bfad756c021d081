#include "ingest/bucket_encode.h"

#include <algorithm>
#include <memory>
#include <utility>
#include <vector>

#include "core/memory.h"
#include "ingest/bucket_split.h"
#include "relief/ingest.h"

namespace relief::ingest {

namespace {

// Working memory per point while a bucket slice is grouped: the decoded
// record (positions, colour, intensity) plus its key and sort entry.
constexpr std::uint64_t kGroupBytesPerPoint = 24 + 3 + 4 + 4 + 4;
// Memory per point of a chunk being encoded: the worker's gathered copy (31)
// plus encoder scratch and the decode check. Error-bounded blobs of x y z
// measured ~125 bytes a point at 400 k points (heaptrack, 2026-11-29) and
// ~100 at 1 M; sparse data adds atlas pixels. Also the estimate by which
// ChunkPipeline admits tasks (plus the LAS record).
constexpr std::uint64_t kEncodeBytesPerPoint = 128;
constexpr std::uint32_t kMinBuckets = 4;
constexpr std::uint32_t kMaxBuckets = 4096;
// Write buffers of a bucket split into loads (bucket_split.h): its records
// are written in blocks of 64 KiB or more, which direct I/O takes as fast.
constexpr std::size_t kSplitStagingBytes = std::size_t{4} << 20;
// Memory per point of a batch on its way from a reader: the decoded points
// (31) and their chunk keys (24); the bucket writer's scratch (4). Up to three
// batches are alive (being read, queued, consumed).
constexpr std::uint64_t kBatchBytesPerPoint = 31 + 24 + 4;
// Resident memory (in thirds of the budget: the slices' and the encoders'
// shares) above which the allocator's free memory is given back between
// slices.
constexpr std::uint64_t kTrimAboveThirds = 2;
// An encoding thread's own high-water mark beside its share of the points:
// its allocator arena, coder models, maps and images (14-18 MiB measured per
// extra thread on 14 k-point chunks, 2026-11-29). The threads that encode are
// as many as the encoders' third of the budget holds (one at the 64 MiB
// minimum; two from 96 MiB; every core at the 1 GiB default).
constexpr std::uint64_t kEncoderThreadBytes = std::uint64_t{16} << 20;

}  // namespace

IngestBudget plan_ingest_budget(std::uint64_t memory_budget, unsigned threads, std::uint64_t las_bytes,
                                std::uint64_t estimated_points, bool whole_chunks) {
  IngestBudget b;
  b.budget = std::max<std::uint64_t>(memory_budget, kMinMemoryBudget);
  b.encode_threads = static_cast<unsigned>(std::clamp<std::uint64_t>((b.budget / 3) / kEncoderThreadBytes, 1, threads));
  // The LAS attributes travel with every point (up to 25 bytes, plus extra
  // bytes; 23 for LAS 1.2 format 3) beside the constants' x y z,
  // colour and intensity: left out, slices of LAS input overran their share.
  b.group_bytes = kGroupBytesPerPoint + las_bytes;
  b.slice_points = std::max<std::uint64_t>(1, (b.budget / 6) / b.group_bytes);
  b.part_points = std::max<std::uint64_t>(1024, (b.budget / 3) / (threads * kEncodeBytesPerPoint));
  // Without bucket files their buffers' share is free: the whole input may
  // take half the budget, the encoders keep their third.
  b.in_memory_points = (b.budget / 2) / b.group_bytes;
  b.read_batch = std::max<std::uint64_t>(
      1024, std::min<std::uint64_t>(kReadBatchPoints, (b.budget / 16) / (kBatchBytesPerPoint + las_bytes)));
  // Enough buckets that a bucket usually fits one slice (x2 for skew; x4 when
  // buckets are read whole).
  const std::uint64_t want = ((whole_chunks ? 4 : 2) * std::max<std::uint64_t>(1, estimated_points)) / b.slice_points + 1;
  b.buckets = static_cast<std::uint32_t>(std::clamp<std::uint64_t>(want, kMinBuckets, kMaxBuckets));
  b.staging_bytes = static_cast<std::size_t>(std::min<std::uint64_t>(b.budget / 8, 256u << 20));
  b.trim_above = kTrimAboveThirds * (b.budget / 3);
  // Tasks start while their estimates fit the encoders' third and half the
  // headroom (a larger task alone), so dense chunks do not encode side by
  // side past the budget.
  b.encode_memory = EncodeMemory{b.budget / 2, kEncodeBytesPerPoint + las_bytes, b.trim_above};
  return b;
}

Status encode_bucket_files(BucketFiles& files, const ArchiveGrid& grid, ChunkPipeline& pipeline, SlicePool& slices,
                           const IngestBudget& budget, const BucketEncodeOptions& options,
                           const std::function<void()>& tick) {
  const std::uint64_t slice_points = budget.slice_points;
  const bool whole = options.whole_chunks;
  // The next slice loads while the workers encode the current one; each
  // slice goes back to the pool (or, larger than its share, is freed) as
  // soon as its last chunk is encoded.
  AlignedBuffer read_buffer;          // only this thread reads the bucket files
  std::uint64_t encoding_points = 0;  // points of the slice still encoding
  // The next slice's tasks go to the workers; at most one slice stays
  // encoding while the next one loads.
  // `alone`: nothing loads beside it while it encodes (its points count as
  // both slices).
  const auto encode_slice = [&](std::vector<ChunkTask> tasks, std::shared_ptr<Slice> slice,
                                bool alone = false) -> Status {
    encoding_points = alone ? 2 * slice_points : slice->points.size();
    pipeline.submit(std::move(tasks), std::move(slice));
    RELIEF_RETURN_IF_ERROR(pipeline.wait(1, tick));
    // The encoders' scratch follows the chunks' sizes, and the threads'
    // malloc arenas keep what they freed: resident memory would climb to
    // the largest chunks' high-water mark and stay there. Given back
    // whenever the process holds more than the slices' and encoders'
    // shares (so it costs nothing while memory is plentiful).
    if (core::resident_bytes() > budget.trim_above) core::release_free_memory();
    return Status::ok();
  };
  // A slice of `points` loads alone when it would not fit beside the one
  // still encoding: that one finishes first, and the pool's idle slices go.
  const auto make_room = [&](std::uint64_t points) -> Status {
    if (encoding_points + points <= 2 * slice_points) return Status::ok();
    RELIEF_RETURN_IF_ERROR(pipeline.wait(0, tick));
    encoding_points = 0;
    slices.clear();
    return Status::ok();
  };
  for (std::uint32_t b = 0; b < files.bucket_count(); ++b) {
    if (whole && files.bucket_points(b) > 2 * slice_points) {
      // Too large to read whole (slices hold whole buckets here): its points
      // go to loads of at most a slice, each holding whole parts of the
      // chunks' octant split (bucket_split.h).
      // It starts once the slices before it are encoded, as a bucket that
      // loads alone does: its passes' buffers do not stack on their encoders.
      RELIEF_RETURN_IF_ERROR(make_room(2 * slice_points + 1));
      BucketSplitOptions split_options;
      split_options.split_points = options.task_points;
      split_options.load_points = slice_points;
      split_options.tmp_parent = options.tmp_parent;
      split_options.staging_bytes = std::min<std::size_t>(budget.staging_bytes, kSplitStagingBytes);
      RELIEF_ASSIGN_OR_RETURN(BucketSplit split,
                              BucketSplit::create(files, b, grid, split_options, read_buffer, tick, options.cancel));
      files.discard(b);
      for (std::uint32_t load = 0; load < split.load_count(); ++load) {
        RELIEF_RETURN_IF_ERROR(make_room(split.load_points(load)));
        std::shared_ptr<Slice> slice = slices.acquire();
        RELIEF_ASSIGN_OR_RETURN(std::vector<ChunkTask> tasks,
                                split.read_load(load, slice->points, slice->grouping, read_buffer));
        split.discard(load);
        // A part larger than a slice is a load of its own, and its
        // encoder runs alone (EncodeMemory): so does its load, as a bucket
        // of that size would.
        const bool alone = split.load_points(load) > slice_points;
        RELIEF_RETURN_IF_ERROR(encode_slice(std::move(tasks), std::move(slice), alone));
      }
      continue;
    }
    if (whole) RELIEF_RETURN_IF_ERROR(make_room(files.bucket_points(b)));
    std::uint64_t offset = 0;
    while (offset < files.bucket_bytes(b)) {
      std::shared_ptr<Slice> slice = slices.acquire();
      RELIEF_RETURN_IF_ERROR(files.read_slice(b, &offset, whole ? ~std::uint64_t{0} : slice_points, slice->points,
                                              slice->grouping, read_buffer));
      std::vector<ChunkTask> tasks = make_tasks(slice->points, options.task_points, slice->grouping, options.split_grid);
      RELIEF_RETURN_IF_ERROR(encode_slice(std::move(tasks), std::move(slice)));
    }
    files.discard(b);
  }
  return pipeline.wait(0, tick);
}

}  // namespace relief::ingest
