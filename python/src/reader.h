// relief.read: a point file's points as numpy structured arrays, whole or a
// batch at a time, through the library's streaming readers.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "arrays.h"
#include "relief/io.h"
#include "relief/status.h"

namespace relief::python {

// A point file (any format open_point_reader takes: LAS, LAZ, PLY,
// XYZ/CSV/PTS, PCD, PTX, E57) read a batch at a time. Not thread-safe; call
// next() without the GIL.
class PointFileBatches {
 public:
  // `attributes` as parse_attribute_set takes it ("all", "none",
  // "rgb,gps_time" ...); `columns`: ReaderOptions::xyz_columns when not
  // empty; `extra_bytes`: ReaderOptions::extra_bytes; `batch_points` > 0.
  static Result<std::unique_ptr<PointFileBatches>> open(const std::string& path, const std::string& attributes,
                                                        const std::string& columns, bool extra_bytes,
                                                        std::size_t batch_points);

  // The next batch into `batch` (empty at the end), `fields` the array
  // fields of the file for it, and in `said` the reader's warnings noticed
  // since the last call.
  Status next(PointCloud& batch, FieldSet& fields, std::vector<std::string>& said);

  // The extra bytes' fields, when the file describes them.
  const std::vector<ExtraBytesField>& extra() const { return extra_; }

 private:
  std::unique_ptr<PointReader> reader_;
  std::size_t batch_points_ = 0;
  std::size_t said_ = 0;  // warnings handed out so far
  std::vector<ExtraBytesField> extra_;
};

struct ReadPoints {
  pybind11::array points;             // the fields Archive.query gives
  std::vector<std::string> warnings;  // the reader's (PointStreamInfo::warnings)
  std::vector<ExtraBytesField> extra;  // the extra bytes' fields, when described
};

// Every point of `path` into `out`, as PointFileBatches reads them, as one
// array. Reads without the GIL; call it with the GIL.
Status read_points(const std::string& path, const std::string& attributes, const std::string& columns,
                   bool extra_bytes, ReadPoints& out);

}  // namespace relief::python
