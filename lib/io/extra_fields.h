// Per-point fields of non-LAS inputs kept as LAS extra bytes: the PLY vertex
// properties and PCD fields other than x y z, colour and intensity (normals,
// labels, curvature, alpha, scalar fields ...). Each becomes one field of a
// synthesised Extra Bytes VLR with its type, so the archive carries it exactly
// and LAS output describes it. Internal to lib/io.
#pragma once

#include <cstddef>
#include <string>
#include <vector>

#include "relief/status.h"

namespace relief {

struct KeptField {
  std::string name;   // as the file names it
  int data_type = 0;  // LAS Extra Bytes data type, 1..10
};

// The Extra Bytes VLR payload describing `fields` in order. A name longer than
// the 32 bytes a descriptor holds is cut, with a warning appended to
// `warnings`; two names that agree in their first 32 bytes, or more fields than
// one VLR holds (341), are refused with an error naming `file`. `kind` names a
// field in messages ("vertex property", "field"); `description` is written
// into each descriptor.
Result<std::string> kept_fields_vlr(const std::vector<KeptField>& fields, const std::string& file,
                                    const std::string& kind, const std::string& description,
                                    std::vector<std::string>& warnings);

}  // namespace relief
