// Partition files of a sharded build (format-spec/shard.md): the snapped
// points one input contributes to one key range, as exact doubles. Internal
// to lib/shard.
//
//   offset size
//   0      8    magic "RLFPART\0"
//   8      4    u32 format version (kPartitionFormatVersion)
//   12     8    u64 plan id (shard_plan_id)
//   20     4    u32 input index
//   24     4    u32 range index
//   28     4    u32 attribute flags: bit 0 rgb, bit 1 intensity; others 0
//   32     8    u64 point count
//   40          point_count records: f64 x, y, z; u8 r, g, b (if rgb);
//               f32 intensity (if intensity)
#pragma once

#include <cstdint>
#include <string>

#include "relief/shard.h"
#include "relief/types.h"

namespace relief::shard {

inline constexpr char kPartitionMagic[8] = {'R', 'L', 'F', 'P', 'A', 'R', 'T', '\0'};
inline constexpr std::size_t kPartitionHeaderBytes = 40;
inline constexpr std::uint32_t kFlagRgb = 1;
inline constexpr std::uint32_t kFlagIntensity = 2;
inline constexpr char kManifestMagic[] = "relief-partition";

std::size_t partition_record_bytes(bool colors, bool intensity);

// Appends the points of partition file `path` to `out` (which carries the
// plan's attributes), after checking its header against the plan, input and
// range and its size against the header's count before reading any point.
// Returns the number of points appended.
Result<std::uint64_t> read_partition_file(const std::string& path, std::uint64_t plan_id, std::uint32_t input,
                                          std::uint32_t range, bool colors, bool intensity, PointCloud& out);
// The header's point count alone (checked like read_partition_file).
Result<std::uint64_t> partition_file_points(const std::string& path, std::uint64_t plan_id, std::uint32_t input,
                                            std::uint32_t range, bool colors, bool intensity);

struct Manifest {
  std::uint64_t points = 0;
  std::vector<std::string> warnings;
};
Result<Manifest> read_manifest(const std::string& path, std::uint64_t plan_id, std::uint32_t input);

}  // namespace relief::shard
