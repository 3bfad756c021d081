// Constructors of the streaming readers, for the dispatch in point_file.cpp.
// Each takes the input (a path, or memory for tests and read_ply_memory) and
// returns a reader positioned at the first point. Internal to lib/io.
#pragma once

#include <memory>

#include "io/stream_support.h"
#include "relief/io.h"

namespace relief {

Result<std::unique_ptr<PointReader>> open_ply_reader(const InputSpec& input, const ReaderOptions& options);
Result<std::unique_ptr<PointReader>> open_las_reader(const InputSpec& input, bool positions_only = false,
                                                     unsigned decode_threads = 0);
Result<std::unique_ptr<PointReader>> open_xyz_reader(const InputSpec& input, const ReaderOptions& options);
Result<std::unique_ptr<PointReader>> open_pcd_reader(const InputSpec& input, const ReaderOptions& options);
Result<std::unique_ptr<PointReader>> open_ptx_reader(const InputSpec& input);
Result<std::unique_ptr<PointReader>> open_e57_reader(const InputSpec& input, const ReaderOptions& options);

}  // namespace relief
