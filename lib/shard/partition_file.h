// Partition files of a sharded build (format-spec/shard.md): the snapped
// points one input contributes to one key range, as exact doubles, with
// every attribute of the plan. Internal to lib/shard.
//
// Version 2 (written):              Version 1 (read; no LAS attributes):
//   offset size                       offset size
//   0      8    magic "RLFPART\0"     0      8    magic
//   8      4    u32 version (2)       8      4    u32 version (1)
//   12     8    u64 plan id           12     8    u64 plan id
//   20     4    u32 input index       20     4    u32 input index
//   24     4    u32 range index       24     4    u32 range index
//   28     4    u32 flags             28     4    u32 flags
//   32     4    u32 LAS attributes    32     8    u64 point count
//   36     4    u32 extra bytes size  40          records
//   40     8    u64 point count
//   48          records
// flags: bit 0 rgb, bit 1 intensity, others 0. A record: f64 x, y, z; u8 r,
// g, b (rgb); f32 intensity (intensity); each LAS attribute of the set in
// LasAttributeBits order in its own width (scan angle i32, point source id
// and NIR u16, GPS time f64, colour low bytes u8 r, g, b, the others u8);
// then the extra bytes. All little-endian.
#pragma once

#include <cstdint>
#include <functional>
#include <string>

#include "relief/shard.h"
#include "relief/types.h"

namespace relief::shard {

inline constexpr char kPartitionMagic[8] = {'R', 'L', 'F', 'P', 'A', 'R', 'T', '\0'};
inline constexpr std::size_t kPartitionHeaderBytesV1 = 40;
inline constexpr std::size_t kPartitionHeaderBytes = 48;  // version 2
inline constexpr std::uint32_t kFlagRgb = 1;
inline constexpr std::uint32_t kFlagIntensity = 2;
inline constexpr char kManifestMagic[] = "relief-partition";

// What every record of a plan's partition files carries.
struct PartitionLayout {
  bool colors = false;
  bool intensity = false;
  std::uint32_t las = 0;         // LasAttributeBits
  std::uint32_t extra_size = 0;  // extra bytes per point (las has kLasExtraBytes), else 0

  static PartitionLayout of(const ShardPlan& plan);
  std::uint32_t flags() const;
  std::size_t record_bytes() const;
};

// Appends the points of partition file `path` to `out` (which carries the
// plan's attributes), after checking its header against the plan, input and
// range and its size against the header's count before reading any point.
// Returns the number of points appended.
Result<std::uint64_t> read_partition_file(const std::string& path, std::uint64_t plan_id, std::uint32_t input,
                                          std::uint32_t range, const PartitionLayout& layout, PointCloud& out);
// The same points in batches: take(batch) for each run of at most
// `batch_points` of them in file order (the batch is reused: take moves or
// copies what it keeps). The header and size are checked before any point is
// read, so a batch never holds more than the file does.
Result<std::uint64_t> read_partition_batches(const std::string& path, std::uint64_t plan_id, std::uint32_t input,
                                             std::uint32_t range, const PartitionLayout& layout,
                                             std::uint64_t batch_points,
                                             const std::function<Status(PointCloud&)>& take);
// The header's point count alone (checked like read_partition_file).
Result<std::uint64_t> partition_file_points(const std::string& path, std::uint64_t plan_id, std::uint32_t input,
                                            std::uint32_t range, const PartitionLayout& layout);

struct Manifest {
  std::uint64_t points = 0;
  std::vector<std::string> warnings;
};
Result<Manifest> read_manifest(const std::string& path, std::uint64_t plan_id, std::uint32_t input);

}  // namespace relief::shard
