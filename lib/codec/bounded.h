// The error-bounded layer of chunk format 2 (format-spec/chunk.md): every
// input point, snapped to a per-axis grid, coded as an octree of occupied
// cells with point counts plus per-point attributes, beside the paper's maps
// as a base layer. Mirror pair: bounded_encoder.cpp / bounded_decoder.cpp.
// Internal to the codec.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "codec/chunk_format.h"
#include "core/grid_index.h"
#include "relief/codec.h"

namespace relief::codec {

// Coordinate of local cell `local` on one axis. Encoder (for the index
// bounds) and decoder compute it with this one expression, so both get the
// same doubles; with origin = a LAS offset and step = its scale it is the LAS
// reader's own formula.
inline double dequantise(double origin, std::int64_t base, std::uint32_t local, double step) {
  return core::grid_value(origin, base + static_cast<std::int64_t>(local), step);
}

// `cloud` has been validated (finite coordinates and intensities, matching
// attribute arrays); params.bound is set.
Result<std::vector<std::uint8_t>> encode_bounded(const PointCloud& cloud, const EncodeParams& params,
                                                 EncodeStats* stats);

// Every point of the error-bounded layer, in the blob's canonical order.
// Sections of attributes `want` leaves out are skipped unless a wanted one is
// coded against them (the result may then carry them: the caller keeps what
// it asked for).
Result<PointCloud> decode_bounded_points(const ParsedBlob& blob, const AttributeSet& want = {});

}  // namespace relief::codec
