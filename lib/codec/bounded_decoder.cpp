// Error-bounded chunk decoder (format 2). Mirror: bounded_encoder.cpp.
#include <cmath>
#include <cstring>
#include <string>

#include "codec/attribute_coder.h"
#include "codec/bounded.h"
#include "codec/geometry_coder.h"
#include "codec/las_attribute_coder.h"
#include "codec/octree.h"
#include "codec/scan_geometry_coder.h"

namespace relief::codec {

namespace {

const SectionEntry* find_section(const ParsedBlob& blob, SectionId id) {
  for (const SectionEntry& s : blob.sections) {
    if (s.id == id) return &s;
  }
  return nullptr;
}

// The sections of a format-8 blob whose geometry is in time order (§11.3.3):
// the GPS times (18), return numbers (12) and numbers of returns (13), which
// the geometry uses as context, then the geometry. The layer is in time
// order: `out` gets the positions and those attributes, `time_order` the
// identity.
Status decode_time_ordered_layer(const ParsedBlob& blob, PointCloud& out, std::vector<std::uint32_t>& time_order) {
  const ChunkHeader& h = blob.header;
  const std::size_t n = h.input_points;
  const SectionEntry* gps = find_section(blob, las_section_id(kLasGpsTime));
  if (gps == nullptr) return corrupt_data("chunk blob: geometry in time order without a GPS time section");
  LasAttributes timed;
  RELIEF_RETURN_IF_ERROR(decode_gps_in_order(gps->payload, n, timed).with_context("chunk blob"));
  std::vector<std::uint32_t> identity(n);
  for (std::size_t k = 0; k < n; ++k) identity[k] = static_cast<std::uint32_t>(k);
  for (const std::uint32_t bit : {kLasReturnNumber, kLasNumberOfReturns}) {
    if (const SectionEntry* s = find_section(blob, las_section_id(bit))) {
      RELIEF_RETURN_IF_ERROR(
          decode_las_attribute(bit, s->payload, n, timed, h.version, {}, identity).with_context("chunk blob"));
    }
  }
  const std::vector<std::uint8_t> kinds = las_pulse_kinds(timed.gps_time, identity);
  const std::vector<std::uint8_t> multiples = scan_pulse_multiples(timed.gps_time);
  const SectionEntry* geometry = find_section(blob, SectionId::kGeometry);
  auto cells = decode_scan_geometry(geometry->payload, h.geometry_depth, n,
                                    ScanContext{kinds, multiples, timed.return_number, timed.number_of_returns});
  if (!cells) return cells.status().with_context("chunk blob: geometry section");
  // The layer is in time order.
  out.positions.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const CellXyz& c = (*cells)[k];
    out.positions[k] = {dequantise(h.quant_origin.x, h.quant_base[0], c[0], h.quant_step.x),
                        dequantise(h.quant_origin.y, h.quant_base[1], c[1], h.quant_step.y),
                        dequantise(h.quant_origin.z, h.quant_base[2], c[2], h.quant_step.z)};
  }
  time_order = std::move(identity);
  out.las.gps_time = std::move(timed.gps_time);
  out.las.return_number = std::move(timed.return_number);
  out.las.number_of_returns = std::move(timed.number_of_returns);
  return Status::ok();
}

}  // namespace

Result<PointCloud> decode_bounded_points(const ParsedBlob& blob) {
  const ChunkHeader& h = blob.header;
  PointCloud out;
  const std::size_t n = h.input_points;
  if (n == 0) return out;
  const SectionEntry* geometry = find_section(blob, SectionId::kGeometry);
  if (geometry == nullptr) return corrupt_data("chunk blob: no geometry section");  // parse_blob guarantees it
  // Decoded before the other sections: in time order, the geometry with
  // GPS times, return numbers and numbers of returns.
  const bool time_ordered_layer = geometry->codec == SectionCodec::kScanOrder;
  std::vector<std::uint32_t> time_order;
  OccupiedCells cells;
  if (time_ordered_layer) {
    RELIEF_RETURN_IF_ERROR(decode_time_ordered_layer(blob, out, time_order));
  } else {
    const OctreeCoding coding = geometry->codec == SectionCodec::kOctreeMixed         ? OctreeCoding::kMixed
                                : geometry->codec == SectionCodec::kOctreeSingleChild ? OctreeCoding::kSingleChild
                                                                                      : OctreeCoding::kBitwise;
    auto decoded = decode_geometry(geometry->payload, h.geometry_depth, n, coding);
    if (!decoded) return decoded.status().with_context("chunk blob: geometry section");
    cells = std::move(decoded).value();
    out.positions.resize(n);
    std::size_t k = 0;
    for (std::size_t c = 0; c < cells.keys.size(); ++c) {
      const std::uint64_t key = cells.keys[c];
      const Vec3d p{dequantise(h.quant_origin.x, h.quant_base[0], compact_bits3(key), h.quant_step.x),
                    dequantise(h.quant_origin.y, h.quant_base[1], compact_bits3(key >> 1), h.quant_step.y),
                    dequantise(h.quant_origin.z, h.quant_base[2], compact_bits3(key >> 2), h.quant_step.z)};
      for (std::uint32_t j = 0; j < cells.counts[c]; ++j) out.positions[k++] = p;
    }
  }
  if (const SectionEntry* s = find_section(blob, SectionId::kPointColor)) {
    auto colors = decode_colors(s->payload, n, h.color_tolerance);
    if (!colors) return colors.status().with_context("chunk blob: point colour section");
    out.colors = std::move(colors).value();
  }
  if (const SectionEntry* s = find_section(blob, SectionId::kPointIntensity)) {
    auto values = decode_values(s->payload, n);
    if (!values) return values.status().with_context("chunk blob: point intensity section");
    out.intensities.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::int64_t v = (*values)[i];
      if (h.intensity_coding == IntensityCoding::kUInt16) {
        if (v < 0 || v > 65535) return corrupt_data("chunk blob: intensity " + std::to_string(v) + " out of 0..65535");
        out.intensities[i] = static_cast<float>(v);
      } else {
        if (v < 0 || v > 0xFFFFFFFFll) return corrupt_data("chunk blob: intensity bit pattern out of range");
        const auto bits = static_cast<std::uint32_t>(v);
        float f = 0;
        std::memcpy(&f, &bits, sizeof f);
        if (!std::isfinite(f)) return corrupt_data("chunk blob: non-finite intensity");
        out.intensities[i] = f;
      }
    }
  }
  // LAS attribute sections, in table (= bit) order: a section may use the
  // attributes of lower bits as context. Format 6 codes GPS times in time
  // order, which needs every point's cell, and decodes them first: the
  // attributes that follow acquisition order are then coded in time order.
  out.las.extra_bytes_size = h.extra_bytes_size;
  std::vector<CellXyz> point_cells;
  if (!time_ordered_layer && h.version >= 6 && (h.las_attributes & kLasGpsTime) != 0) {
    point_cells.reserve(n);
    for (std::size_t c = 0; c < cells.keys.size(); ++c) {
      const std::uint64_t key = cells.keys[c];
      const CellXyz xyz{compact_bits3(key), compact_bits3(key >> 1), compact_bits3(key >> 2)};
      for (std::uint32_t j = 0; j < cells.counts[c]; ++j) point_cells.push_back(xyz);
    }
  }
  if (!time_ordered_layer && h.version >= 6 && (h.las_attributes & kLasGpsTime) != 0) {
    for (const SectionEntry& s : blob.sections) {
      if (!is_las_section(s.id) || las_section_bit(s.id) != kLasGpsTime) continue;
      RELIEF_RETURN_IF_ERROR(
          decode_las_attribute(kLasGpsTime, s.payload, n, out.las, h.version, point_cells).with_context("chunk blob"));
      time_order = las_time_order(out.las.gps_time);
    }
  }
  for (const SectionEntry& s : blob.sections) {
    if (!is_las_section(s.id)) continue;
    const std::uint32_t bit = las_section_bit(s.id);
    if (bit == kLasGpsTime && !time_order.empty()) continue;  // decoded above
    if (time_ordered_layer && (bit == kLasReturnNumber || bit == kLasNumberOfReturns)) continue;  // likewise
    RELIEF_RETURN_IF_ERROR(
        decode_las_attribute(bit, s.payload, n, out.las, h.version, point_cells, time_order, out.colors)
            .with_context("chunk blob"));
  }
  return out;
}

}  // namespace relief::codec
