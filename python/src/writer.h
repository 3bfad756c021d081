// relief.write: numpy columns into a point file through the library's writers.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <string>

#include "relief/status.h"

namespace relief::python {

// Writes the points of `columns` (field name -> 1-D C-contiguous array of the
// field's type, as relief/__init__.py casts and checks them: x y z float64,
// red green blue uint8 or uint16, intensity float32, the LAS attributes as
// Archive.query gives them) and, when `extra` is an (n, extra_size) uint8
// array, each point's extra bytes, described by `extra_vlr` (an Extra Bytes
// VLR payload; empty: undocumented). `crs`: WKT or "EPSG:<code>" for LAS/LAZ
// (empty: none); `scale`: the LAS coordinate resolution (0: automatic).
// Runs without the GIL; sets `written` to the points written and `warnings`
// to what the format could not hold as given (PointWriter::take_warnings).
Status write_points(const std::string& path, const pybind11::dict& columns, const pybind11::object& extra,
                    const pybind11::bytes& extra_vlr, const std::string& crs, double scale, std::uint64_t& written,
                    std::vector<std::string>& warnings);

}  // namespace relief::python
