// Error-bounded chunk decoder (format 2). Mirror: bounded_encoder.cpp.
#include <cmath>
#include <cstring>
#include <string>
#include <type_traits>

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
// the GPS times (18; from format 14 possibly absent), return numbers (12) and
// numbers of returns (13), which the geometry uses as context, then the
// geometry. The layer is in time
// order: `out` gets the positions and those attributes, `time_order` the
// identity.
// `cell_pos` gets, when the order mask sets a bit of `slots` (those of the
// sections to be decoded), the layer position of each point in cell order
// (else it stays empty), `mask` the mask.
Status decode_time_ordered_layer(const ParsedBlob& blob, std::uint8_t slots, PointCloud& out,
                                 std::vector<std::uint32_t>& time_order, std::uint8_t& mask,
                                 std::vector<std::uint32_t>& cell_pos, std::vector<CellXyz>& layer_cells) {
  const ChunkHeader& h = blob.header;
  const std::size_t n = h.input_points;
  // Format 14: without GPS times the layer is in the order the encoder was
  // given (ErrorBound::keep_order), the geometry without pulse context.
  const SectionEntry* gps = find_section(blob, las_section_id(kLasGpsTime));
  if (gps == nullptr && h.version < 14) {
    return corrupt_data("chunk blob: geometry in time order without a GPS time section");
  }
  LasAttributes timed;
  // From format 14 the times may decrease in the layer's order.
  if (gps != nullptr) {
    RELIEF_RETURN_IF_ERROR(decode_gps_in_order(gps->payload, n, timed, h.version >= 14).with_context("chunk blob"));
  }
  std::vector<std::uint32_t> identity(n);
  for (std::size_t k = 0; k < n; ++k) identity[k] = static_cast<std::uint32_t>(k);
  // Without GPS times sections 12-17 have their plain coding in the layer's
  // order (§11.7.2 needs the times).
  const std::span<const std::uint32_t> timed_order =
      gps != nullptr ? std::span<const std::uint32_t>(identity) : std::span<const std::uint32_t>{};
  for (const std::uint32_t bit : {kLasReturnNumber, kLasNumberOfReturns}) {
    if (const SectionEntry* s = find_section(blob, las_section_id(bit))) {
      RELIEF_RETURN_IF_ERROR(
          decode_las_attribute(bit, s->payload, n, timed, h.version, {}, timed_order).with_context("chunk blob"));
    }
  }
  const std::vector<std::uint8_t> kinds =
      gps != nullptr ? las_pulse_kinds(timed.gps_time, identity) : std::vector<std::uint8_t>{};
  const std::vector<std::uint8_t> multiples = scan_pulse_multiples(timed.gps_time);
  const SectionEntry* geometry = find_section(blob, SectionId::kGeometry);
  if (geometry->payload.empty()) return corrupt_data("chunk blob: geometry section: no order mask");
  mask = geometry->payload[0];
  if ((mask & ~kKnownOrderMask) != 0) return corrupt_data("chunk blob: geometry section: reserved order mask bit set");
  auto cells = decode_scan_geometry(geometry->payload.subspan(1), h.geometry_depth, n,
                                    ScanContext{kinds, multiples, timed.return_number, timed.number_of_returns});
  if (!cells) return cells.status().with_context("chunk blob: geometry section");
  if ((mask & slots) != 0) {
    std::vector<KeyedIndex> by_cell(n);
    for (std::size_t k = 0; k < n; ++k) {
      const CellXyz& c = (*cells)[k];
      by_cell[k] = {morton_encode(c[0], c[1], c[2]), static_cast<std::uint32_t>(k)};
    }
    radix_sort(by_cell, 3 * h.geometry_depth);  // stable: a cell's points stay in time order
    cell_pos.resize(n);
    for (std::size_t j = 0; j < n; ++j) cell_pos[j] = by_cell[j].index;
  }
  // The layer is in time order.
  out.positions.resize(n);
  for (std::size_t k = 0; k < n; ++k) {
    const CellXyz& c = (*cells)[k];
    out.positions[k] = {dequantise(h.quant_origin.x, h.quant_base[0], c[0], h.quant_step.x),
                        dequantise(h.quant_origin.y, h.quant_base[1], c[1], h.quant_step.y),
                        dequantise(h.quant_origin.z, h.quant_base[2], c[2], h.quant_step.z)};
  }
  if (gps != nullptr) time_order = std::move(identity);
  layer_cells = std::move(cells).value();
  out.las.gps_time = std::move(timed.gps_time);
  out.las.return_number = std::move(timed.return_number);
  out.las.number_of_returns = std::move(timed.number_of_returns);
  return Status::ok();
}

}  // namespace

Result<PointCloud> decode_bounded_points(const ParsedBlob& blob, const AttributeSet& want) {
  const ChunkHeader& h = blob.header;
  PointCloud out;
  const std::size_t n = h.input_points;
  if (n == 0) return out;
  // The LAS sections to decode: those wanted and those they are coded
  // against (number of returns against return numbers; from format 6, the
  // attributes in time order against the GPS times). The colour low bytes,
  // coded against the colours, come with them (AttributeSet::las_kept).
  std::uint32_t las = want.las_kept();
  if ((las & kLasNumberOfReturns) != 0) las |= kLasReturnNumber;
  if ((las & kLasTimeOrdered) != 0 && h.version >= 6) las |= kLasGpsTime;
  // From format 15 NIR is coded against the colours (§11.7): they are
  // decoded for it, and dropped again unless wanted.
  const bool nir_needs_colors = (las & kLasNir) != 0 && h.version >= kLasCodingFormatVersion &&
                                (h.flags & kFlagColors) != 0 && (h.las_attributes & kLasNir) != 0;
  const bool with_colors = want.colors || nir_needs_colors;
  // The order mask's slots (§11.3.3) of the sections decoded.
  std::uint8_t slots = 0;
  if (with_colors) slots |= 1u << kOrderSlotColors;
  if (want.intensity) slots |= 1u << kOrderSlotIntensity;
  for (std::uint32_t b = 0; b < kLasAttributeCount; ++b) {
    const int slot = order_slot(1u << b);
    if ((las & (1u << b)) != 0 && slot >= 0) slots |= static_cast<std::uint8_t>(1u << slot);
  }
  const SectionEntry* geometry = find_section(blob, SectionId::kGeometry);
  if (geometry == nullptr) return corrupt_data("chunk blob: no geometry section");  // parse_blob guarantees it
  // Decoded before the other sections: in time order, the geometry with
  // GPS times, return numbers and numbers of returns.
  const bool time_ordered_layer = geometry->codec == SectionCodec::kScanOrder;
  std::vector<std::uint32_t> time_order;
  OccupiedCells cells;
  std::uint8_t order_mask = 0;
  std::vector<std::uint32_t> cell_pos;  // layer position of each point in cell order
  std::vector<CellXyz> layer_cells;     // each point's cell, in the layer's order
  if (time_ordered_layer) {
    RELIEF_RETURN_IF_ERROR(decode_time_ordered_layer(blob, slots, out, time_order, order_mask, cell_pos, layer_cells));
  } else {
    const OctreeCoding coding = geometry->codec == SectionCodec::kOctreeNearest  ? OctreeCoding::kNearest
                                : geometry->codec == SectionCodec::kOctreePlanes ? OctreeCoding::kPlanes
                                : geometry->codec == SectionCodec::kOctreeFaces  ? OctreeCoding::kFacePatterns
                                : geometry->codec == SectionCodec::kOctreeChains ? OctreeCoding::kChains
                                : geometry->codec == SectionCodec::kOctreeMixed  ? OctreeCoding::kMixed
                                : geometry->codec == SectionCodec::kOctreeSingleChild
                                    ? OctreeCoding::kSingleChild
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
    const SectionEntry* colors = find_section(blob, SectionId::kPointColor);
    const bool near_colors = colors != nullptr && colors->codec == SectionCodec::kNeighbourColor;
    if ((near_colors && with_colors) || (h.version >= 6 && (h.las_attributes & kLasGpsTime & las) != 0)) {
      layer_cells.reserve(n);
      for (std::size_t c = 0; c < cells.keys.size(); ++c) {
        const std::uint64_t key = cells.keys[c];
        const CellXyz xyz{compact_bits3(key), compact_bits3(key >> 1), compact_bits3(key >> 2)};
        for (std::uint32_t j = 0; j < cells.counts[c]; ++j) layer_cells.push_back(xyz);
      }
    }
  }
  // Sections the order mask puts in cell order are moved to the layer's.
  const auto in_cells = [&](int slot) { return slot >= 0 && (order_mask & (1u << slot)) != 0; };
  const auto to_layer = [&](auto& v) {
    std::remove_reference_t<decltype(v)> moved(v.size());
    for (std::size_t j = 0; j < v.size(); ++j) moved[cell_pos[j]] = v[j];
    v = std::move(moved);
  };
  if (const SectionEntry* s = with_colors ? find_section(blob, SectionId::kPointColor) : nullptr) {
    std::vector<CellXyz> cells_by_cell;  // codec 10 in cell order under a time-ordered layer
    if (s->codec == SectionCodec::kNeighbourColor && in_cells(kOrderSlotColors)) {
      cells_by_cell.resize(n);
      for (std::size_t j = 0; j < n; ++j) cells_by_cell[j] = layer_cells[cell_pos[j]];
    }
    auto colors = s->codec != SectionCodec::kNeighbourColor
                      ? decode_colors(s->payload, n, h.color_tolerance)
                      : decode_colors_near(s->payload, cells_by_cell.empty() ? layer_cells : cells_by_cell,
                                           h.color_tolerance);
    if (!colors) return colors.status().with_context("chunk blob: point colour section");
    out.colors = std::move(colors).value();
    if (in_cells(kOrderSlotColors)) to_layer(out.colors);
  }
  if (const SectionEntry* s = want.intensity ? find_section(blob, SectionId::kPointIntensity) : nullptr) {
    auto values = decode_values(s->payload, n, h.intensity_tolerance);
    if (!values) return values.status().with_context("chunk blob: point intensity section");
    if (in_cells(kOrderSlotIntensity)) to_layer(*values);
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
  // Format 6 on: the octree layer's GPS times use every point's cell.
  const std::span<const CellXyz> point_cells =
      time_ordered_layer ? std::span<const CellXyz>{} : std::span<const CellXyz>{layer_cells};
  if (!time_ordered_layer && h.version >= 6 && (h.las_attributes & kLasGpsTime) != 0 && (las & kLasGpsTime) != 0) {
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
    if ((las & bit) == 0) continue;  // not wanted, and no wanted section is coded against it
    if (bit == kLasGpsTime && !time_order.empty()) continue;  // decoded above
    if (time_ordered_layer && (bit == kLasReturnNumber || bit == kLasNumberOfReturns)) continue;  // likewise
    if (in_cells(order_slot(bit))) {
      LasAttributes by_cell;
      by_cell.extra_bytes_size = h.extra_bytes_size;
      std::vector<Rgb8> colors;  // the colour low bytes' "equal" decision, and NIR, in cell order
      if (bit == kLasColorLow || bit == kLasNir) {
        colors.resize(out.colors.size());
        for (std::size_t j = 0; j < colors.size(); ++j) colors[j] = out.colors[cell_pos[j]];
      }
      RELIEF_RETURN_IF_ERROR(
          decode_las_attribute(bit, s.payload, n, by_cell, h.version, {}, {}, colors).with_context("chunk blob"));
      permute_las_attribute(bit, by_cell, out.las, cell_pos, Permute::kScatter);
      continue;
    }
    RELIEF_RETURN_IF_ERROR(
        decode_las_attribute(bit, s.payload, n, out.las, h.version, point_cells, time_order, out.colors)
            .with_context("chunk blob"));
  }
  if (!want.colors) out.colors.clear();
  return out;
}

}  // namespace relief::codec
