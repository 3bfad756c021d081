// Decoded points as numpy structured arrays: one field per attribute a batch
// or the archive carries.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstdint>
#include <vector>

#include "relief/types.h"

namespace relief::python {

// Which fields an array has: x, y, z always; the rest when the archive or a
// batch carries them.
struct FieldSet {
  bool colors = false;
  bool intensity = false;
  std::uint32_t las = 0;  // LasAttributeBits
  std::uint32_t extra_bytes_size = 0;
  // The archive's colours are 8-bit levels stored in 16-bit LAS fields
  // (ArchiveInfo::las_colors_8bit): uint16 colour fields hold them as LAS
  // output writes them (las_color_level).
  bool levels_8bit = false;

  // The fields of `cloud` added to this set.
  void add(const PointCloud& cloud);
};

// The numpy dtype of `fields` (packed, field order as in the README).
pybind11::dtype make_dtype(const FieldSet& fields);

// One array of `fields` holding the points of `clouds` in order; a field a
// cloud does not carry is 0 for its points. The copy runs without the GIL.
pybind11::array to_array(const std::vector<PointCloud>& clouds, const FieldSet& fields);

}  // namespace relief::python
