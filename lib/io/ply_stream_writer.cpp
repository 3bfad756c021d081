// Streaming PLY writer. The vertex count is not known until finish(), so the
// header carries a fixed-width placeholder, "element vertex" followed by 20
// zero-padded digits (enough for any 64-bit count), which finish() overwrites
// in place. A zero-padded decimal is still a plain decimal integer, so every
// PLY reader accepts it. Properties: double x y z, then uchar red green blue
// (ushort when the points carry 16-bit colours: kLasColorLow, not
// las_colors_8bit) and float intensity when the options ask for them, then one property per
// LAS dimension the points carry, under LAS's names, which
// the PLY reader maps back (io/text_columns.h): uchar classification,
// synthetic, key_point, withheld, overlap, return_number, number_of_returns,
// scan_direction_flag, edge_of_flight_line, scanner_channel, user_data;
// float scan_angle (degrees); ushort point_source_id, nir; double gps_time.
// Then the LAS extra bytes
// (WriterOptions::las_attributes has kLasExtraBytes) as one property per
// value: each Extra Bytes field of a PLY scalar type as that type under its
// name (an array field as <name>_0, <name>_1, ...), 64-bit integers and
// undocumented bytes as uchar properties <name>_0 ... (PLY has no 64-bit
// integers, and bytes keep them exact). Names are made PLY tokens (blanks
// become '_') and unique (a clash gets _2, _3 ...); a name the reader would
// take for a coordinate, colour, intensity or LAS dimension gets "_extra".

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "io/output_file.h"
#include "io/ply_format.h"
#include "io/point_writers.h"
#include "io/text_columns.h"

#ifndef RELIEF_VERSION
#define RELIEF_VERSION "unknown"
#endif

namespace relief {

namespace {

constexpr std::size_t kCountDigits = 20;
constexpr std::string_view kCountLine = "element vertex ";

static_assert(sizeof(Vec3d) == 3 * sizeof(double) && std::is_standard_layout_v<Vec3d>,
              "binary PLY output copies Vec3d arrays as x y z doubles");

template <typename T>
T byte_swapped(T v) {
  if constexpr (sizeof(T) == 8) {
    std::uint64_t u;
    std::memcpy(&u, &v, 8);
    u = __builtin_bswap64(u);
    std::memcpy(&v, &u, 8);
  } else if constexpr (sizeof(T) == 2) {
    v = static_cast<T>(__builtin_bswap16(static_cast<std::uint16_t>(v)));
  } else {
    static_assert(sizeof(T) == 4);
    std::uint32_t u;
    std::memcpy(&u, &v, 4);
    u = __builtin_bswap32(u);
    std::memcpy(&v, &u, 4);
  }
  return v;
}

template <bool kSwap, typename T>
std::uint8_t* put(std::uint8_t* p, T v) {
  if constexpr (kSwap) v = byte_swapped(v);
  std::memcpy(p, &v, sizeof(T));
  return p + sizeof(T);
}

// Encodes points [first, first + n) of `batch` as binary records at `dst`,
// `stride` bytes apart (the core properties; extra bytes follow them).
template <bool kSwap, bool kColors, bool kIntensity, bool kColors16>
void encode_binary(const PointCloud& batch, std::size_t first, std::size_t n, std::size_t stride,
                   std::uint8_t* records) {
  const Vec3d* pos = batch.positions.data() + first;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* dst = records + i * stride;
    dst = put<kSwap>(dst, pos[i].x);
    dst = put<kSwap>(dst, pos[i].y);
    dst = put<kSwap>(dst, pos[i].z);
    if constexpr (kColors && kColors16) {
      const Rgb8& c = batch.colors[first + i];
      const Rgb8& low = batch.las.color_low[first + i];
      dst = put<kSwap>(dst, static_cast<std::uint16_t>(c.r << 8 | low.r));
      dst = put<kSwap>(dst, static_cast<std::uint16_t>(c.g << 8 | low.g));
      dst = put<kSwap>(dst, static_cast<std::uint16_t>(c.b << 8 | low.b));
    } else if constexpr (kColors) {
      const Rgb8& c = batch.colors[first + i];
      dst[0] = c.r;
      dst[1] = c.g;
      dst[2] = c.b;
      dst += 3;
    }
    if constexpr (kIntensity) dst = put<kSwap>(dst, batch.intensities[first + i]);
  }
}

using EncodeFn = void (*)(const PointCloud&, std::size_t, std::size_t, std::size_t, std::uint8_t*);

// One PLY property per value of the extra bytes, in order.
struct ExtraProperty {
  std::string name;
  ply::ScalarType type = ply::ScalarType::kUint8;
};

// Makes `base` a PLY token not in `taken`, and takes it.
std::string unique_name(std::string base, std::vector<std::string>& taken) {
  return unique_field_name(std::move(base), "", "extra", taken);
}

// The PLY properties of `size` extra bytes per point described by `vlr`
// (bytes the VLR leaves undescribed become uchar properties "extra_<i>").
std::vector<ExtraProperty> extra_properties(const std::string& vlr, std::size_t size,
                                            std::vector<std::string> taken) {
  std::vector<ExtraBytesField> fields;
  if (!vlr.empty()) {
    const std::span<const std::uint8_t> payload(reinterpret_cast<const std::uint8_t*>(vlr.data()), vlr.size());
    // The archive checked this VLR when it took it; a failure leaves the bytes undescribed.
    if (auto parsed = parse_extra_bytes_vlr(payload, size, "extra bytes")) fields = std::move(*parsed);
  }
  std::vector<ExtraProperty> props;
  std::size_t described = 0;
  for (const ExtraBytesField& f : fields) {
    const int base = extra_bytes_base_type(f.data_type);
    const std::optional<ply::ScalarType> t = ply::scalar_type_of_extra_bytes(base);
    const std::size_t count = t ? f.size / ply::scalar_size(*t) : f.size;
    if (t && count == 1) {
      props.push_back({unique_name(f.name, taken), *t});
    } else {
      for (std::size_t k = 0; k < count; ++k) {
        props.push_back({unique_name(f.name + "_" + std::to_string(k), taken), t.value_or(ply::ScalarType::kUint8)});
      }
    }
    described += f.size;
  }
  for (std::size_t k = described; k < size; ++k) {
    props.push_back({unique_name("extra_" + std::to_string(k), taken), ply::ScalarType::kUint8});
  }
  return props;
}

// The PLY type of a LAS dimension's property.
ply::ScalarType las_property_type(TextColumn c) {
  switch (c) {
    case TextColumn::kScanAngle: return ply::ScalarType::kFloat32;
    case TextColumn::kGpsTime: return ply::ScalarType::kFloat64;
    case TextColumn::kPointSourceId:
    case TextColumn::kNir: return ply::ScalarType::kUint16;
    default: return ply::ScalarType::kUint8;
  }
}

// Stores `v` as PLY type `t` at `dst`, little endian, or big when `big`.
std::uint8_t* put_las_value(std::uint8_t* dst, double v, ply::ScalarType t, bool big) {
  std::size_t size = 0;
  switch (t) {
    case ply::ScalarType::kFloat32: {
      const auto f = static_cast<float>(v);
      std::memcpy(dst, &f, size = sizeof f);
      break;
    }
    case ply::ScalarType::kFloat64:
      std::memcpy(dst, &v, size = sizeof v);
      break;
    case ply::ScalarType::kUint16: {
      const auto u = static_cast<std::uint16_t>(v);
      std::memcpy(dst, &u, size = sizeof u);
      break;
    }
    default:
      *dst = static_cast<std::uint8_t>(v);
      size = 1;
      break;
  }
  if (big != (std::endian::native == std::endian::big)) std::reverse(dst, dst + size);
  return dst + size;
}

template <bool kSwap>
EncodeFn pick_encoder(bool colors, bool intensity, bool colors16) {
  if (colors && colors16) {
    return intensity ? &encode_binary<kSwap, true, true, true> : &encode_binary<kSwap, true, false, true>;
  }
  if (colors) {
    return intensity ? &encode_binary<kSwap, true, true, false> : &encode_binary<kSwap, true, false, false>;
  }
  return intensity ? &encode_binary<kSwap, false, true, false> : &encode_binary<kSwap, false, false, false>;
}

class PlyStreamWriter final : public StreamPointWriter {
 public:
  PlyStreamWriter(std::unique_ptr<OutputFile> out, const WriterOptions& options)
      : StreamPointWriter(std::move(out), options) {
    // 16-bit colours (the points carry the levels' low bytes, and they are
    // not 8-bit levels stored in 16-bit fields) are written as ushort.
    colors16_ = options.colors && (options.las_attributes & kLasColorLow) != 0 && !options.las_colors_8bit;
    core_size_ = 3 * sizeof(double) + (options.colors ? (colors16_ ? 6 : 3) : 0) +
                 (options.intensity ? sizeof(float) : 0);
    std::vector<std::string> taken = {"x", "y", "z"};
    if (options.colors) taken.insert(taken.end(), {"red", "green", "blue"});
    if (options.intensity) taken.emplace_back("intensity");
    for (const LasTextColumn& c : las_text_columns()) {
      if ((options.las_attributes & c.bit) == 0) continue;
      las_.push_back(&c);
      las_bits_ |= c.bit;
      las_size_ += ply::scalar_size(las_property_type(c.column));
      taken.emplace_back(c.snake);
    }
    if ((options.las_attributes & kLasExtraBytes) != 0 && options.extra_bytes_size > 0) {
      extra_size_ = options.extra_bytes_size;
      extras_ = extra_properties(options.extra_bytes_vlr, extra_size_, std::move(taken));
    }
    record_size_ = core_size_ + las_size_ + extra_size_;
    const bool little = options.ply_encoding == PlyEncoding::kBinaryLittleEndian;
    const bool swap = little != (std::endian::native == std::endian::little);
    big_endian_ = !little;
    encode_ = swap ? pick_encoder<true>(options.colors, options.intensity, colors16_)
                   : pick_encoder<false>(options.colors, options.intensity, colors16_);
    // The positions array is already the record layout.
    copy_positions_ = !swap && !options.colors && !options.intensity && las_size_ == 0 && extra_size_ == 0;
  }

  Status start() {
    std::string h = "ply\nformat ";
    h += ply::encoding_name(options_.ply_encoding);
    h += " 1.0\ncomment generated by relief " RELIEF_VERSION "\n";
    count_offset_ = h.size() + kCountLine.size();
    h += kCountLine;
    h += std::string(kCountDigits, '0');
    h += "\nproperty double x\nproperty double y\nproperty double z\n";
    if (options_.colors) {
      h += colors16_ ? "property ushort red\nproperty ushort green\nproperty ushort blue\n"
                     : "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    }
    if (options_.intensity) h += "property float intensity\n";
    for (const LasTextColumn* c : las_) {
      h += std::string("property ") + ply::scalar_name(las_property_type(c->column)) + " " + c->snake + "\n";
    }
    for (const ExtraProperty& p : extras_) h += std::string("property ") + ply::scalar_name(p.type) + " " + p.name + "\n";
    h += "end_header\n";
    return out_->append(h.data(), h.size());
  }

 protected:
  Status write_points(const PointCloud& batch) override {
    const std::size_t n = batch.size();
    RELIEF_RETURN_IF_ERROR(check_batch_columns(batch.las, las_bits_, extra_size_, n, out_->path()));
    if (colors16_ && batch.las.color_low.size() != n) {
      return invalid_argument(out_->path() + ": a batch of " + std::to_string(n) + " points has " +
                              std::to_string(batch.las.color_low.size()) + " colour low bytes");
    }
    if (options_.ply_encoding == PlyEncoding::kAscii) return write_ascii(batch);
    if (copy_positions_) return out_->append(batch.positions.data(), batch.size() * sizeof(Vec3d));
    std::size_t i = 0;
    while (i < n) {
      std::span<std::uint8_t> room;
      RELIEF_RETURN_IF_ERROR(out_->room(record_size_, room));
      const std::size_t k = std::min(n - i, room.size() / record_size_);
      encode_(batch, i, k, record_size_, room.data());
      if (las_size_ > 0) put_las(batch, i, k, room.data() + core_size_);
      if (extra_size_ > 0) put_extras(batch, i, k, room.data() + core_size_ + las_size_);
      out_->advance(k * record_size_);
      i += k;
    }
    return Status::ok();
  }

  Status complete() override {
    const std::string digits = std::to_string(points_written());
    std::string field(kCountDigits - digits.size(), '0');
    field += digits;
    return out_->patch(count_offset_, field.data(), field.size());
  }

 private:
  // The extra bytes of points [first, first + n) after each record's core
  // properties (`dst` points past the first record's core).
  void put_extras(const PointCloud& batch, std::size_t first, std::size_t n, std::uint8_t* dst) const {
    const std::uint8_t* src = batch.las.extra_bytes.data() + first * extra_size_;
    for (std::size_t i = 0; i < n; ++i, src += extra_size_, dst += record_size_) {
      std::memcpy(dst, src, extra_size_);  // little endian, as LAS stores them
      if (!big_endian_) continue;
      std::uint8_t* v = dst;
      for (const ExtraProperty& p : extras_) {
        const std::size_t size = ply::scalar_size(p.type);
        std::reverse(v, v + size);
        v += size;
      }
    }
  }

  // ASCII records: the core properties as text output writes them, then the
  // LAS dimensions and the extra bytes' values, each as its PLY type prints
  // (integers whole, floats and doubles in the shortest text that reads back
  // to the same value; a NaN reads back as a NaN, without its payload).
  Status write_ascii(const PointCloud& batch) const {
    const std::size_t tail_room = kMaxColumnText * (las_.size() + extras_.size());
    return write_text_lines(*out_, batch, options_, ' ', tail_room, [&](std::uint8_t* p, std::size_t i) {
      for (const LasTextColumn* c : las_) {
        *p++ = ' ';
        const double v = las_column_value(batch.las, c->column, i);
        switch (las_property_type(c->column)) {
          case ply::ScalarType::kFloat32: p = put_shortest(p, static_cast<float>(v)); break;
          case ply::ScalarType::kFloat64: p = put_shortest(p, v); break;
          default: p = put_integer(p, static_cast<std::uint32_t>(v)); break;  // uchar, ushort
        }
      }
      const std::uint8_t* v = batch.las.extra_bytes.data() + i * extra_size_;
      for (const ExtraProperty& e : extras_) {
        *p++ = ' ';
        p = put_scalar_text(p, v, e.type);
        v += ply::scalar_size(e.type);
      }
      return p;
    }, colors16_);
  }

  // The little-endian value of PLY type `t` at `v` as ASCII PLY text.
  static std::uint8_t* put_scalar_text(std::uint8_t* p, const std::uint8_t* v, ply::ScalarType t) {
    switch (t) {
      case ply::ScalarType::kInt8: return put_integer(p, static_cast<int>(load_le_value<std::int8_t>(v)));
      case ply::ScalarType::kUint8: return put_integer(p, static_cast<unsigned>(v[0]));
      case ply::ScalarType::kInt16: return put_integer(p, load_le_value<std::int16_t>(v));
      case ply::ScalarType::kUint16: return put_integer(p, load_le_value<std::uint16_t>(v));
      case ply::ScalarType::kInt32: return put_integer(p, load_le_value<std::int32_t>(v));
      case ply::ScalarType::kUint32: return put_integer(p, load_le_value<std::uint32_t>(v));
      case ply::ScalarType::kFloat32: return put_shortest(p, load_le_value<float>(v));
      case ply::ScalarType::kFloat64: return put_shortest(p, load_le_value<double>(v));
    }
    return p;
  }

  // The LAS dimensions of points [first, first + n) after each record's core
  // properties.
  void put_las(const PointCloud& batch, std::size_t first, std::size_t n, std::uint8_t* dst) const {
    for (std::size_t i = 0; i < n; ++i, dst += record_size_) {
      std::uint8_t* v = dst;
      for (const LasTextColumn* c : las_) {
        v = put_las_value(v, las_column_value(batch.las, c->column, first + i), las_property_type(c->column),
                          big_endian_);
      }
    }
  }

  std::size_t core_size_ = 0;
  std::vector<const LasTextColumn*> las_;
  std::uint32_t las_bits_ = 0;  // the LasAttributeBits of las_
  std::size_t las_size_ = 0;
  std::size_t extra_size_ = 0;
  std::vector<ExtraProperty> extras_;
  std::size_t record_size_ = 0;
  bool big_endian_ = false;
  bool colors16_ = false;  // colours as ushort levels (see the constructor)
  EncodeFn encode_ = nullptr;
  bool copy_positions_ = false;
  std::uint64_t count_offset_ = 0;
};

}  // namespace

Result<std::unique_ptr<PointWriter>> open_ply_writer(const std::string& path, const WriterOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<OutputFile> out, OutputFile::create(path));
  if (out->is_stdout()) {
    return invalid_argument("PLY cannot be written to standard output (its header is completed last)");
  }
  auto writer = std::make_unique<PlyStreamWriter>(std::move(out), options);
  RELIEF_RETURN_IF_ERROR(writer->start());
  return std::unique_ptr<PointWriter>(std::move(writer));
}

}  // namespace relief
