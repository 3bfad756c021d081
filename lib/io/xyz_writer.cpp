// Streaming XYZ/CSV writer: one line "x y z [r g b] [i]" per point, with
// shortest round-trip doubles, so the XYZ reader gets every coordinate back
// bit for bit. Standard output ("-") is written through the same buffer and
// flushed by finish(); nothing there can be taken back after an error.
//
// Points with LAS attributes (WriterOptions::las_attributes) get a header
// line naming every column, as PDAL's writers.text does, and after the
// colours and intensity one column per LAS dimension they carry, under
// PDAL's names (io/text_columns.h: Classification, the four class flags,
// ReturnNumber ... ScanAngleRank in degrees, GpsTime, Infrared), then one per
// value of their extra bytes: a scalar field under its name, an array's
// components as <name>_0 ..., undocumented bytes as integers extra_<k>;
// scaled fields (Extra Bytes options bits 3 and 4) as raw * scale + offset.
// The XYZ reader maps those names back (the LAS dimensions exactly, the extra
// bytes as float64 fields). Colours are 8-bit levels, so 16-bit colours' low
// bytes (kLasColorLow) are the one attribute text leaves out. CSV (',')
// always has the header; space-separated text without LAS attributes has
// none, as before.

#include <algorithm>
#include <bit>
#include <charconv>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "io/output_file.h"
#include "io/point_writers.h"
#include "io/text_columns.h"

namespace relief {

namespace {

// One text column after x y z, colours and intensity.
struct TailColumn {
  TextColumn column = TextColumn::kExtra;
  std::uint32_t bit = 0;    // LAS dimensions: the LasAttributeBits of its vector
  int base_type = 0;        // extra bytes: LAS data type 1..10, or 0 for a raw byte
  std::size_t offset = 0;   // extra bytes: of the value within a point's extra bytes
  bool scaled = false;
  double scale = 1;
  double value_offset = 0;
};

// A name the text reader keeps as extra bytes under the same name: no
// separator, quote or blank in it, not starting as a comment does.
std::string column_name(std::string base, std::vector<std::string>& taken) {
  if (!base.empty() && (base[0] == '#' || base[0] == '/')) base = "_" + base;
  return unique_field_name(std::move(base), ",;\"'", "_", taken);
}

class XyzStreamWriter final : public StreamPointWriter {
 public:
  XyzStreamWriter(std::unique_ptr<OutputFile> out, const WriterOptions& options, char separator)
      : StreamPointWriter(std::move(out), options), separator_(separator) {}

  // Plans the columns and writes the header when there is one.
  Status start() {
    const std::uint32_t bits = options_.las_attributes;
    // CSV always names its columns (a spreadsheet or a reader such as
    // Relief's then needs no column list); space-separated text only when
    // it has LAS dimensions beyond x y z [r g b] [i].
    if ((bits & ~std::uint32_t{kLasColorLow}) == 0 && separator_ != ',') return Status::ok();
    std::vector<std::string> header = {"X", "Y", "Z"};
    if (options_.colors) header.insert(header.end(), {"Red", "Green", "Blue"});
    if (options_.intensity) header.emplace_back("Intensity");
    for (const LasTextColumn& c : las_text_columns()) {
      if ((bits & c.bit) == 0) continue;
      tail_.push_back({c.column, c.bit});
      las_bits_ |= c.bit;
      header.emplace_back(c.header);
    }
    if ((bits & kLasExtraBytes) != 0 && options_.extra_bytes_size > 0) plan_extras(header);
    std::string line;
    for (const std::string& h : header) line += (line.empty() ? "" : std::string(1, separator_)) + h;
    line += '\n';
    return out_->append(line.data(), line.size());
  }

 protected:
  Status write_points(const PointCloud& batch) override {
    if (tail_.empty()) return write_text_points(*out_, batch, options_, separator_);
    RELIEF_RETURN_IF_ERROR(check_batch_columns(batch.las, las_bits_, extra_size_, batch.size(), out_->path()));
    const auto sep = static_cast<std::uint8_t>(separator_);
    return write_text_lines(*out_, batch, options_, separator_, kMaxColumnText * tail_.size(),
                            [&](std::uint8_t* p, std::size_t i) {
                              for (const TailColumn& c : tail_) {
                                *p++ = sep;
                                p = put_tail(p, batch.las, i, c);
                              }
                              return p;
                            });
  }
  Status complete() override { return Status::ok(); }

 private:
  void plan_extras(std::vector<std::string>& header) {
    const std::size_t size = options_.extra_bytes_size;
    extra_size_ = size;
    std::vector<ExtraBytesField> fields;
    if (!options_.extra_bytes_vlr.empty()) {
      const std::span<const std::uint8_t> payload(reinterpret_cast<const std::uint8_t*>(options_.extra_bytes_vlr.data()),
                                                  options_.extra_bytes_vlr.size());
      // The archive checked this VLR when it took it; a failure leaves the bytes undescribed.
      if (auto parsed = parse_extra_bytes_vlr(payload, size, "extra bytes")) fields = std::move(*parsed);
    }
    std::vector<std::string> taken = header;
    std::size_t described = 0;
    for (const ExtraBytesField& f : fields) {
      const int base = extra_bytes_base_type(f.data_type);
      const std::size_t value_size = base == 0 ? 1 : extra_bytes_type_size(base);
      const std::size_t count = f.size / value_size;
      for (std::size_t k = 0; k < count; ++k) {
        TailColumn c;
        c.base_type = base;
        c.offset = f.offset + k * value_size;
        c.scaled = base != 0 && (f.options & 0x18) != 0;
        c.scale = (f.options & 0x08) != 0 ? f.scale : 1;
        c.value_offset = (f.options & 0x10) != 0 ? f.value_offset : 0;
        tail_.push_back(c);
        header.push_back(column_name(count == 1 && base != 0 ? f.name : f.name + "_" + std::to_string(k), taken));
      }
      described = std::max(described, f.offset + f.size);
    }
    for (std::size_t k = described; k < size; ++k) {
      TailColumn c;
      c.offset = k;
      tail_.push_back(c);
      header.push_back(column_name("extra_" + std::to_string(k), taken));
    }
  }

  std::uint8_t* put_tail(std::uint8_t* p, const LasAttributes& a, std::size_t i, const TailColumn& c) const {
    // A LAS dimension: its integers print as integers.
    if (c.bit != 0) return put_shortest(p, las_column_value(a, c.column, i));
    const std::uint8_t* v = a.extra_bytes.data() + i * a.extra_bytes_size + c.offset;
    double value = 0;
    switch (c.base_type) {
      case 1: value = load_le_value<std::uint8_t>(v); break;
      case 2: value = load_le_value<std::int8_t>(v); break;
      case 3: value = load_le_value<std::uint16_t>(v); break;
      case 4: value = load_le_value<std::int16_t>(v); break;
      case 5: value = load_le_value<std::uint32_t>(v); break;
      case 6: value = load_le_value<std::int32_t>(v); break;
      case 7:
        if (!c.scaled) return put_integer(p, load_le_value<std::uint64_t>(v));
        value = static_cast<double>(load_le_value<std::uint64_t>(v));
        break;
      case 8:
        if (!c.scaled) return put_integer(p, load_le_value<std::int64_t>(v));
        value = static_cast<double>(load_le_value<std::int64_t>(v));
        break;
      case 9:
        if (!c.scaled) return put_shortest(p, load_le_value<float>(v));
        value = load_le_value<float>(v);
        break;
      case 10: value = load_le_value<double>(v); break;
      default: return put_integer(p, v[0]);  // an undocumented byte
    }
    if (c.scaled) value = value * c.scale + c.value_offset;
    return put_shortest(p, value);  // integers below 2^32 print as integers
  }

  char separator_;
  std::vector<TailColumn> tail_;
  std::uint32_t las_bits_ = 0;    // the LasAttributeBits of the LAS dimension columns
  std::size_t extra_size_ = 0;    // extra bytes per point the columns read (0: none)
};

}  // namespace

Result<std::unique_ptr<PointWriter>> open_xyz_writer(const std::string& path, const WriterOptions& options,
                                                     char separator) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<OutputFile> out, OutputFile::create(path));
  auto writer = std::make_unique<XyzStreamWriter>(std::move(out), options, separator);
  RELIEF_RETURN_IF_ERROR(writer->start());
  return std::unique_ptr<PointWriter>(std::move(writer));
}

}  // namespace relief
