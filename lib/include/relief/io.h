// Point-file readers and writers.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "relief/status.h"
#include "relief/types.h"

namespace relief {

enum class PlyEncoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };
enum class PlyCoordinateType { kFloat32, kFloat64 };

struct PlyWriteOptions {
  PlyEncoding encoding = PlyEncoding::kBinaryLittleEndian;
  PlyCoordinateType coordinate_type = PlyCoordinateType::kFloat64;
};

// Reads the `vertex` element of a PLY file (ascii, binary little or big endian):
// x y z as any numeric type, optional red green blue (uchar, or ushort which is
// shifted to 8 bits when any value exceeds 255), optional intensity (any numeric
// type, stored as float). Other properties and elements, including list
// properties such as faces, are skipped. Errors name `path` and the problem.
Result<PointCloud> read_ply(const std::string& path);
// The same from memory; `name` is used in error messages.
Result<PointCloud> read_ply_memory(std::span<const std::uint8_t> data, const std::string& name);

// Writes `cloud` as PLY. The file appears atomically: it is written beside the
// target and renamed, and nothing is left behind on failure.
Status write_ply(const std::string& path, const PointCloud& cloud, const PlyWriteOptions& options = {});

// Reads any supported point file, chosen by extension (.ply).
Result<PointCloud> read_point_file(const std::string& path);

}  // namespace relief
