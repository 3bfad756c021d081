// relief.read: a point file's points as one numpy structured array, through
// the library's streaming readers.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <string>
#include <vector>

#include "relief/io.h"
#include "relief/status.h"

namespace relief::python {

struct ReadPoints {
  pybind11::array points;             // the fields Archive.query gives
  std::vector<std::string> warnings;  // the reader's (PointStreamInfo::warnings)
  std::vector<ExtraBytesField> extra;  // the extra bytes' fields, when described
};

// Every point of `path` (any format open_point_reader takes: LAS, LAZ, PLY,
// XYZ/CSV/PTS, PCD, PTX, E57) into `out`. `attributes` as
// parse_attribute_set takes it ("all", "none", "rgb,gps_time" ...);
// `columns`: ReaderOptions::xyz_columns when not empty; `extra_bytes`:
// ReaderOptions::extra_bytes. Reads without the GIL; call it with the GIL.
Status read_points(const std::string& path, const std::string& attributes, const std::string& columns,
                   bool extra_bytes, ReadPoints& out);

}  // namespace relief::python
