// PCD reader (PCL point cloud data, header versions 0.6 and 0.7), DATA ascii,
// binary and binary_compressed. Field names match in any case (some exporters
// write X Y Z RGB). Fields x y z (F 4 or F 8) are required; colour comes from
// rgb or rgba (4 bytes packed as 0x00RRGGBB, whatever the TYPE says, as PCL
// does; an rgba field's top byte is its alpha) or else from separate r g b (or
// red green blue) fields, and intensity (any numeric type) is read when
// present. Every other field (normals, curvature, label, ...) is kept as LAS
// extra bytes (io/extra_fields.h), one field per value (COUNT n: <name>_0 ...
// <name>_<n-1>) of its TYPE and SIZE, and so is an rgba field's alpha (uint8
// "alpha", or "rgba_alpha" when a field is named alpha), unless
// ReaderOptions::extra_bytes is off; fields named "_" (PCL's padding) are
// skipped.
//
// Separate colour fields follow their declared type, so the rule does not
// depend on the values or their order: SIZE 2 integers are 16-bit levels
// (shifted right by 8, as the LAS and wide PLY colours that use the full
// range, with each level's low byte kept as LasAttributes::color_low when
// all three are); every other type holds 8-bit levels (0..255; floats are rounded and
// everything saturates at 0 and 255).
//
// binary_compressed (PCL's writer): after the header, u32 compressed size,
// u32 uncompressed size, then LZF data (liblzf) that expands to the fields in
// structure-of-arrays order: all values of field 1, then of field 2, ... The
// whole block is expanded at open (PCL does the same), after checking both
// sizes against the bytes present, POINTS x point size and LZF's largest
// expansion, and it must expand to exactly the declared size.
//
// Points with a NaN coordinate are skipped and counted in
// PointStreamInfo::skipped_points: organised clouds (WIDTH x HEIGHT images)
// mark pixels without depth that way, so they are not errors. An infinite
// coordinate has no such meaning and is reported.

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "io/byte_source.h"
#include "io/extra_fields.h"
#include "io/readers.h"
#include "io/stream_support.h"
#include "io/text_scan.h"
#include "relief/io.h"

#include <lzf.h>

namespace relief {

namespace {

// Limits on untrusted headers. Real PCD headers are ~10 lines; descriptors
// such as SHOT have COUNT in the hundreds. Keeping point_size <= 2^20 and the
// point count <= 2^40 keeps every byte count far below 2^64.
constexpr std::size_t kMaxHeaderLine = std::size_t{64} << 10;
constexpr std::size_t kMaxHeaderBytes = std::size_t{1} << 20;
constexpr std::size_t kMaxFields = 1024;
constexpr std::uint64_t kMaxFieldCount = std::uint64_t{1} << 16;
constexpr std::size_t kMaxPointSize = std::size_t{1} << 20;
constexpr std::uint64_t kMaxPoints = std::uint64_t{1} << 40;
// One ascii point per line.
constexpr std::size_t kMaxAsciiLine = std::size_t{4} << 20;
// binary_compressed: the two u32 sizes before the LZF data, and LZF's largest
// expansion: a 3-byte back reference copies at most 264 bytes, so no valid
// stream expands more than 88 times (checked before allocating).
constexpr std::size_t kCompressedHeader = 8;
constexpr std::uint64_t kMaxLzfExpansion = 88;

struct PcdField {
  std::string name;
  std::size_t size = 4;
  char type = 'F';
  std::size_t count = 1;
  std::size_t offset = 0;  // byte offset in a binary record
  std::size_t column = 0;  // first value in an ascii line
};

enum class PcdData { kAscii, kBinary, kBinaryCompressed };

struct PcdHeader {
  std::vector<PcdField> fields;
  PcdData data = PcdData::kAscii;
  std::uint64_t point_count = 0;
  std::size_t point_size = 0;  // bytes per binary record
  std::size_t columns = 0;     // values per ascii line
};

bool parse_u64(std::string_view tok, std::uint64_t& out) {
  const auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), out);
  return ec == std::errc{} && p == tok.data() + tok.size() && !tok.empty();
}

std::string upper(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return out;
}

Result<PcdHeader> parse_header(ByteSource& src, const std::string& name) {
  PcdHeader h;
  std::vector<std::string> sizes, types, counts;  // copies: lines do not outlive next_line
  std::optional<std::uint64_t> width, height, points;
  bool have_fields = false;
  bool have_data = false;
  std::size_t line_no = 0;
  while (!have_data) {
    std::string_view line;
    LineStatus state = LineStatus::kEnd;
    RELIEF_RETURN_IF_ERROR(next_line(src, kMaxHeaderLine, line, state));
    ++line_no;
    if (state == LineStatus::kEnd) {
      if (line_no == 1) return format_error(name + ": not a PCD file: it is empty");
      return format_error(name + ": the PCD header has no DATA line");
    }
    if (state == LineStatus::kTooLong || src.position() > kMaxHeaderBytes) {
      return format_error(name + ": the PCD header has no DATA line in its first " +
                          std::to_string(kMaxHeaderBytes) + " bytes");
    }
    const std::string where = name + ": header line " + std::to_string(line_no) + ": ";
    const std::vector<std::string_view> tok = split_tokens(line);
    if (tok.empty() || tok[0].starts_with('#')) continue;
    const std::string kw = upper(tok[0]);
    const std::vector<std::string_view> args(tok.begin() + 1, tok.end());
    auto one_number = [&](std::optional<std::uint64_t>& out) -> Status {
      std::uint64_t v = 0;
      if (args.size() != 1 || !parse_u64(args[0], v)) {
        return format_error(where + kw + " needs one non-negative integer");
      }
      if (v > kMaxPoints) return format_error(where + kw + " " + std::to_string(v) + " is absurdly large");
      out = v;
      return Status::ok();
    };
    auto copy = [&](std::vector<std::string>& out) { out.assign(args.begin(), args.end()); };
    if (kw == "VERSION" || kw == "VIEWPOINT") {
      // The viewpoint is the sensor pose; PCL does not apply it to the points either.
      continue;
    } else if (kw == "FIELDS" || kw == "COLUMNS") {  // COLUMNS: the 0.5 spelling
      if (args.empty()) return format_error(where + "FIELDS lists no field");
      if (args.size() > kMaxFields) {
        return format_error(where + "more than " + std::to_string(kMaxFields) + " fields");
      }
      h.fields.clear();
      for (std::string_view a : args) h.fields.push_back({std::string(a), 4, 'F', 1, 0, 0});
      have_fields = true;
    } else if (kw == "SIZE") {
      copy(sizes);
    } else if (kw == "TYPE") {
      copy(types);
    } else if (kw == "COUNT") {
      copy(counts);
    } else if (kw == "WIDTH") {
      RELIEF_RETURN_IF_ERROR(one_number(width));
    } else if (kw == "HEIGHT") {
      RELIEF_RETURN_IF_ERROR(one_number(height));
    } else if (kw == "POINTS") {
      RELIEF_RETURN_IF_ERROR(one_number(points));
    } else if (kw == "DATA") {
      if (args.size() != 1) {
        return format_error(where + "expected 'DATA ascii', 'DATA binary' or 'DATA binary_compressed'");
      }
      if (args[0] == "ascii") {
        h.data = PcdData::kAscii;
      } else if (args[0] == "binary") {
        h.data = PcdData::kBinary;
      } else if (args[0] == "binary_compressed") {
        h.data = PcdData::kBinaryCompressed;
      } else {
        return format_error(where + "unknown DATA kind " + quoted(args[0]));
      }
      have_data = true;
    } else {
      return format_error(where + "unknown header keyword " + quoted(tok[0]));
    }
  }
  if (!have_fields) return format_error(name + ": the PCD header has no FIELDS line");
  const std::size_t n = h.fields.size();
  auto matches = [&](const std::vector<std::string>& v, const char* what) -> Status {
    if (v.size() != n) {
      return format_error(name + ": the PCD header lists " + std::to_string(n) + " fields but " +
                          std::to_string(v.size()) + " " + what + " values");
    }
    return Status::ok();
  };
  RELIEF_RETURN_IF_ERROR(matches(sizes, "SIZE"));
  RELIEF_RETURN_IF_ERROR(matches(types, "TYPE"));
  if (!counts.empty()) RELIEF_RETURN_IF_ERROR(matches(counts, "COUNT"));
  for (std::size_t i = 0; i < n; ++i) {
    PcdField& f = h.fields[i];
    const std::string what = name + ": field " + quoted(f.name) + ": ";
    std::uint64_t size = 0;
    if (!parse_u64(sizes[i], size) || (size != 1 && size != 2 && size != 4 && size != 8)) {
      return format_error(what + "SIZE " + quoted(sizes[i]) + " is not 1, 2, 4 or 8");
    }
    if (types[i] != "F" && types[i] != "I" && types[i] != "U") {
      return format_error(what + "TYPE " + quoted(types[i]) + " is not F, I or U");
    }
    f.size = static_cast<std::size_t>(size);
    f.type = types[i][0];
    if (f.type == 'F' && f.size != 4 && f.size != 8) {
      return format_error(what + "a floating-point field must have SIZE 4 or 8, not " + sizes[i]);
    }
    std::uint64_t count = 1;
    if (!counts.empty() && (!parse_u64(counts[i], count) || count == 0 || count > kMaxFieldCount)) {
      return format_error(what + "COUNT " + quoted(counts[i]) + " is not between 1 and " +
                          std::to_string(kMaxFieldCount));
    }
    f.count = static_cast<std::size_t>(count);
    f.offset = h.point_size;
    f.column = h.columns;
    h.point_size += f.size * f.count;
    h.columns += f.count;
    if (h.point_size > kMaxPointSize) {
      return format_error(name + ": a PCD point of more than " + std::to_string(kMaxPointSize) +
                          " bytes is absurdly large");
    }
  }
  // WIDTH x HEIGHT is the image size of an organised cloud (HEIGHT 1 otherwise).
  std::optional<std::uint64_t> image;
  if (width) {
    const std::uint64_t rows = height.value_or(1);
    if (rows != 0 && *width > kMaxPoints / rows) {
      return format_error(name + ": WIDTH x HEIGHT is absurdly large");
    }
    image = *width * rows;
  }
  if (points) {
    // A mismatch means the header cannot be trusted.
    if (image && *image != *points) {
      return format_error(name + ": POINTS " + std::to_string(*points) + " differs from WIDTH x HEIGHT = " +
                          std::to_string(*width) + " x " + std::to_string(height.value_or(1)));
    }
    h.point_count = *points;
  } else {
    if (!image) return format_error(name + ": the PCD header has neither POINTS nor WIDTH");
    h.point_count = *image;
  }
  return h;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

// `field_name` is lower case; the file's names match in any case.
const PcdField* find_field(const PcdHeader& h, std::string_view field_name) {
  for (const PcdField& f : h.fields) {
    if (f.name.size() != field_name.size()) continue;
    bool same = true;
    for (std::size_t i = 0; i < f.name.size() && same; ++i) {
      same = std::tolower(static_cast<unsigned char>(f.name[i])) == field_name[i];
    }
    if (same) return &f;
  }
  return nullptr;
}

// A separate colour value as an 8-bit level, by its declared type (see the
// top of the file).
std::uint8_t color_level(double v, const PcdField& f) {
  constexpr int kWideShift = 8;
  if (f.type != 'F' && f.size == 2) v = std::floor(v / (1 << kWideShift));
  if (!(v > 0)) return 0;  // NaN too
  if (v >= 255) return 255;
  return static_cast<std::uint8_t>(std::lround(v));
}

// The low byte of a 16-bit level (a SIZE 2 integer colour value; negative
// ones, which color_level makes 0, give 0).
std::uint8_t low_byte16(double v) {
  if (!(v > 0)) return 0;
  return static_cast<std::uint8_t>(static_cast<std::uint32_t>(std::min(v, 65535.0)) & 0xFF);
}

// Any PCD scalar as a double (64-bit integers may round; they never hold
// coordinates here).
double load_value(const std::uint8_t* p, char type, std::size_t size) {
  if (type == 'F') return size == 4 ? static_cast<double>(load_le<float>(p)) : load_le<double>(p);
  if (type == 'I') {
    switch (size) {
      case 1:
        return static_cast<std::int8_t>(p[0]);
      case 2:
        return load_le<std::int16_t>(p);
      case 4:
        return load_le<std::int32_t>(p);
      default:
        return static_cast<double>(load_le<std::int64_t>(p));
    }
  }
  switch (size) {
    case 1:
      return p[0];
    case 2:
      return load_le<std::uint16_t>(p);
    case 4:
      return load_le<std::uint32_t>(p);
    default:
      return static_cast<double>(load_le<std::uint64_t>(p));
  }
}

// The LAS Extra Bytes data type of a PCD value (TYPE and SIZE already checked).
int extra_bytes_type(char type, std::size_t size) {
  if (type == 'F') return size == 4 ? 9 : 10;
  const int by_size = size == 1 ? 1 : size == 2 ? 3 : size == 4 ? 5 : 7;  // unsigned
  return type == 'I' ? by_size + 1 : by_size;
}

// An ascii value of a kept field as the little-endian bytes a binary PCD
// would hold; false when it is not a number of that type (or out of its range).
bool parse_value_bytes(std::string_view tok, char type, std::size_t size, std::uint8_t* out) {
  const char* first = tok.data();
  const char* const last = tok.data() + tok.size();
  if (last - first > 1 && *first == '+' && first[1] != '-' && first[1] != '+') ++first;
  if (first == last) return false;
  std::uint64_t bits = 0;
  bool ok = false;
  if (type == 'F' && size == 4) {
    float f = 0;  // parsed as a float, so a shortest float text comes back exactly
    const auto [p, ec] = std::from_chars(first, last, f);
    ok = ec == std::errc{} && p == last;
    bits = std::bit_cast<std::uint32_t>(f);
  } else if (type == 'F') {
    double d = 0;
    const auto [p, ec] = std::from_chars(first, last, d);
    ok = ec == std::errc{} && p == last;
    bits = std::bit_cast<std::uint64_t>(d);
  } else if (type == 'U') {
    const auto [p, ec] = std::from_chars(first, last, bits);
    ok = ec == std::errc{} && p == last && (size == 8 || bits >> (8 * size) == 0);
  } else {
    std::int64_t v = 0;
    const auto [p, ec] = std::from_chars(first, last, v);
    const std::int64_t hi = size == 8 ? INT64_MAX : (std::int64_t{1} << (8 * size - 1)) - 1;
    ok = ec == std::errc{} && p == last && v <= hi && v >= -hi - 1;
    bits = static_cast<std::uint64_t>(v);
  }
  for (std::size_t b = 0; b < size; ++b) out[b] = static_cast<std::uint8_t>(bits >> (8 * b));
  return ok;
}

// A packed colour in an ascii body. PCL writes it as the unsigned integer of
// its bits (since 1.x, because opaque colours are NaN as floats); older
// writers printed the float value, whose bits are the colour.
bool parse_packed_color(std::string_view tok, char type, std::uint32_t& bits) {
  std::int64_t whole = 0;
  const auto [p, ec] = std::from_chars(tok.data(), tok.data() + tok.size(), whole);
  if (ec == std::errc{} && p == tok.data() + tok.size() && !tok.empty()) {
    if (whole < std::numeric_limits<std::int32_t>::min() ||
        whole > std::numeric_limits<std::uint32_t>::max()) {
      return false;
    }
    bits = static_cast<std::uint32_t>(whole);  // I 4 values wrap to the same bits
    return true;
  }
  if (type != 'F') return false;
  float f = 0;
  const auto [q, ec2] = std::from_chars(tok.data(), tok.data() + tok.size(), f);
  if (ec2 != std::errc{} || q != tok.data() + tok.size()) return false;
  bits = std::bit_cast<std::uint32_t>(f);
  return true;
}

class PcdPointReader final : public PointReader {
 public:
  PcdPointReader(std::string name, ByteSource src, PcdHeader header)
      : src_(std::move(src)), header_(std::move(header)) {
    x_ = find_field(header_, "x");
    y_ = find_field(header_, "y");
    z_ = find_field(header_, "z");
    rgb_ = find_field(header_, "rgb");
    if (rgb_ == nullptr) rgb_ = find_field(header_, "rgba");
    if (rgb_ == nullptr) {
      for (const auto& names : {std::array<const char*, 3>{"r", "g", "b"},
                                std::array<const char*, 3>{"red", "green", "blue"}}) {
        const PcdField* r = find_field(header_, names[0]);
        const PcdField* g = find_field(header_, names[1]);
        const PcdField* b = find_field(header_, names[2]);
        if (r != nullptr && g != nullptr && b != nullptr) {
          split_ = {r, g, b};
          break;
        }
      }
    }
    // 16-bit levels (SIZE 2 integers, all three) keep their low bytes
    // (LasAttributes::color_low), so they come back exactly.
    wide_split_ = split_[0] != nullptr && std::all_of(split_.begin(), split_.end(), [](const PcdField* f) {
                    return f->type != 'F' && f->size == 2;
                  });
    intensity_ = find_field(header_, "intensity");
    info_.path = std::move(name);
    info_.format = "pcd";
    info_.text_body = header_.data == PcdData::kAscii;
    info_.point_count = header_.point_count;
    info_.has_colors = rgb_ != nullptr || split_[0] != nullptr;
    info_.has_intensity = intensity_ != nullptr;
    if (intensity_ != nullptr && intensity_->size >= 4 && !(intensity_->type == 'F' && intensity_->size == 4)) {
      // Intensities are 32-bit floats: say so when the field can hold more.
      info_.warnings.push_back(info_.path + ": field " + quoted(intensity_->name) + " is " + intensity_->type + " " +
                               std::to_string(intensity_->size) +
                               "; intensities are kept as 32-bit floats (about 7 significant digits, integers "
                               "exact up to 2^24)");
    }
    if (wide_split_) info_.las_attributes |= kLasColorLow;
    roles_.assign(header_.columns, kSkip);
    roles_[x_->column] = kX;
    roles_[y_->column] = kY;
    roles_[z_->column] = kZ;
    if (rgb_ != nullptr) roles_[rgb_->column] = kRgb;
    if (split_[0] != nullptr) {
      roles_[split_[0]->column] = kRed;
      roles_[split_[1]->column] = kGreen;
      roles_[split_[2]->column] = kBlue;
    }
    if (intensity_ != nullptr) roles_[intensity_->column] = kIntensity;
    extra_of_column_.assign(header_.columns, 0);
  }

  // Expands a binary_compressed body into records laid out as `binary` ones
  // and reads on from them.
  Status expand_compressed();

  // Keeps every other field's values as extra bytes (see the top of the file).
  Status plan_extras() {
    std::vector<KeptField> kept;
    for (const PcdField& f : header_.fields) {
      const bool used = &f == x_ || &f == y_ || &f == z_ || &f == rgb_ || &f == intensity_ ||
                        std::find(split_.begin(), split_.end(), &f) != split_.end();
      if (used || f.name == "_") continue;
      for (std::size_t k = 0; k < f.count; ++k) {
        roles_[f.column + k] = kExtra;
        extra_of_column_[f.column + k] = static_cast<std::uint32_t>(extras_.size());
        extras_.push_back({f.offset + k * f.size, f.size, extra_size_, f.type});
        extra_size_ += f.size;
        kept.push_back({f.count == 1 ? f.name : f.name + "_" + std::to_string(k), extra_bytes_type(f.type, f.size)});
      }
    }
    // PCL's PointXYZRGBA packs the alpha in rgba's top byte.
    if (rgb_ != nullptr && lower(rgb_->name) == "rgba") {
      const bool taken =
          std::any_of(kept.begin(), kept.end(), [](const KeptField& k) { return lower(k.name) == "alpha"; });
      alpha_at_ = extra_size_;
      extra_size_ += 1;
      kept.push_back({taken ? "rgba_alpha" : "alpha", 1});  // LAS data type 1: uint8
    }
    if (kept.empty()) return Status::ok();
    RELIEF_ASSIGN_OR_RETURN(info_.extra_bytes_vlr, kept_fields_vlr(kept, name(), "field", "PCD field", info_.warnings));
    info_.las_attributes |= kLasExtraBytes;
    info_.extra_bytes_size = static_cast<std::uint32_t>(extra_size_);
    scratch_.assign(extra_size_, 0);
    return Status::ok();
  }

  // Checks what the constructor relies on; call before using the reader.
  Status check() {
    for (const PcdField* f : {x_, y_, z_}) {
      if (f == nullptr) return format_error(name() + ": the PCD file has no x, y and z fields");
      if (f->type != 'F' || f->count != 1) {
        return format_error(name() + ": field " + quoted(f->name) + " must be a single F 4 or F 8 value");
      }
    }
    if (rgb_ != nullptr && (rgb_->size != 4 || rgb_->count != 1)) {
      return format_error(name() + ": field " + quoted(rgb_->name) + " must be one 4-byte packed colour");
    }
    if (intensity_ != nullptr && intensity_->count != 1) {
      return format_error(name() + ": field 'intensity' must have COUNT 1");
    }
    for (const PcdField* f : split_) {
      if (f != nullptr && f->count != 1) {
        return format_error(name() + ": colour field " + quoted(f->name) + " must have COUNT 1");
      }
    }
    if (header_.data == PcdData::kBinaryCompressed) RELIEF_RETURN_IF_ERROR(expand_compressed());
    if (header_.data == PcdData::kBinary) {
      if (const auto rem = src_.remaining()) {
        const std::uint64_t holds = *rem / header_.point_size;
        if (header_.point_count > holds) return truncated(holds);
      }
    }
    return Status::ok();
  }

  const PointStreamInfo& info() const override { return info_; }
  Result<std::size_t> read(PointCloud& batch, std::size_t max_points) override;

 private:
  // Column roles in an ascii line.
  enum : std::uint8_t { kSkip, kX, kY, kZ, kRgb, kRed, kGreen, kBlue, kIntensity, kExtra };

  // One value kept as extra bytes: where it is in a binary record, its size,
  // where it goes in the point's extra bytes, and its TYPE.
  struct Extra {
    std::size_t src = 0;
    std::size_t size = 0;
    std::size_t at = 0;
    char type = 'F';
  };

  struct Values {
    double x = 0, y = 0, z = 0, intensity = 0;
    std::uint32_t rgb = 0;
    std::array<double, 3> levels{};  // separate r g b fields
  };

  const std::string& name() const { return info_.path; }
  Status truncated(std::uint64_t got) const {
    return format_error(name() + ": truncated: header declares " + std::to_string(header_.point_count) +
                        " points but the data ends after " + std::to_string(got));
  }
  Status point_error(std::uint64_t index, const std::string& what) const {
    return format_error(name() + ": point " + std::to_string(index) + ": " + what);
  }
  void decode_binary(const std::uint8_t* rec, Values& v) {
    v.x = load_value(rec + x_->offset, 'F', x_->size);
    v.y = load_value(rec + y_->offset, 'F', y_->size);
    v.z = load_value(rec + z_->offset, 'F', z_->size);
    if (rgb_ != nullptr) v.rgb = load_le<std::uint32_t>(rec + rgb_->offset);
    if (split_[0] != nullptr) {
      for (std::size_t k = 0; k < 3; ++k) {
        v.levels[k] = load_value(rec + split_[k]->offset, split_[k]->type, split_[k]->size);
      }
    }
    if (intensity_ != nullptr)
      v.intensity = load_value(rec + intensity_->offset, intensity_->type, intensity_->size);
    // Binary PCD is little endian, as extra bytes are.
    for (const Extra& e : extras_) std::memcpy(scratch_.data() + e.at, rec + e.src, e.size);
  }
  Status parse_ascii(std::string_view line, std::uint64_t index, Values& v);
  // Appends the point unless it is a no-depth (NaN) point.
  Status accept(const Values& v, std::uint64_t index, PointCloud& batch, bool& kept);

  ByteSource src_;
  PcdHeader header_;
  PointStreamInfo info_;
  const PcdField* x_ = nullptr;
  const PcdField* y_ = nullptr;
  const PcdField* z_ = nullptr;
  const PcdField* rgb_ = nullptr;
  const PcdField* intensity_ = nullptr;
  std::array<const PcdField*, 3> split_{};  // separate r g b, when no packed rgb
  bool wide_split_ = false;                  // ... each a SIZE 2 integer: 16-bit levels
  std::vector<std::uint8_t> roles_;
  std::vector<Extra> extras_;
  std::vector<std::uint32_t> extra_of_column_;  // index into extras_ where roles_ is kExtra
  std::size_t extra_size_ = 0;
  std::vector<std::uint8_t> scratch_;  // the current point's extra bytes
  std::size_t alpha_at_ = kNoAlpha;     // where an rgba field's alpha goes in them
  static constexpr std::size_t kNoAlpha = ~std::size_t{0};
  std::vector<std::uint8_t> expanded_;  // binary_compressed records; src_ reads them
  std::uint64_t done_ = 0;  // records consumed, kept or skipped
  bool rest_checked_ = false;
  // Warns of records (or bytes) after the last point the header declares.
  Status note_extra_points();
};

Status PcdPointReader::parse_ascii(std::string_view line, std::uint64_t index, Values& v) {
  std::size_t pos = 0;
  for (std::size_t c = 0; c < header_.columns; ++c) {
    const std::string_view tok = next_token(line, pos);
    if (tok.empty()) {
      return point_error(index, "expected " + std::to_string(header_.columns) + " values but the line has " +
                                    std::to_string(c));
    }
    const std::uint8_t role = roles_[c];
    if (role == kSkip) continue;
    bool ok = true;
    switch (role) {
      case kX:
        ok = parse_number(tok, v.x);
        break;
      case kY:
        ok = parse_number(tok, v.y);
        break;
      case kZ:
        ok = parse_number(tok, v.z);
        break;
      case kRgb:
        ok = parse_packed_color(tok, rgb_->type, v.rgb);
        break;
      case kRed:
      case kGreen:
      case kBlue:
        ok = parse_number(tok, v.levels[role - kRed]);
        break;
      case kExtra: {
        const Extra& e = extras_[extra_of_column_[c]];
        ok = parse_value_bytes(tok, e.type, e.size, scratch_.data() + e.at);
        break;
      }
      default:
        ok = parse_number(tok, v.intensity);
        break;
    }
    if (!ok)
      return point_error(index,
                         quoted(tok) + " in column " + std::to_string(c + 1) + " is not a valid value");
  }
  if (!next_token(line, pos).empty()) {
    return point_error(index,
                       "more values than the " + std::to_string(header_.columns) + " the header declares");
  }
  return Status::ok();
}

Status PcdPointReader::accept(const Values& v, std::uint64_t index, PointCloud& batch, bool& kept) {
  kept = false;
  if (std::isnan(v.x) || std::isnan(v.y) || std::isnan(v.z)) {
    ++info_.skipped_points;
    return Status::ok();
  }
  if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z)) {
    return point_error(index, "non-finite coordinate (" + format_double(v.x) + ", " + format_double(v.y) +
                                  ", " + format_double(v.z) + ")");
  }
  float intensity = 0;
  if (intensity_ != nullptr) {
    if (!std::isfinite(v.intensity) || std::abs(v.intensity) > std::numeric_limits<float>::max()) {
      return point_error(index, "intensity " + format_double(v.intensity) + " is not a finite float");
    }
    intensity = static_cast<float>(v.intensity);
  }
  batch.positions.push_back({v.x, v.y, v.z});
  if (rgb_ != nullptr) {
    batch.colors.push_back({static_cast<std::uint8_t>(v.rgb >> 16), static_cast<std::uint8_t>(v.rgb >> 8),
                            static_cast<std::uint8_t>(v.rgb)});
  } else if (split_[0] != nullptr) {
    batch.colors.push_back({color_level(v.levels[0], *split_[0]), color_level(v.levels[1], *split_[1]),
                            color_level(v.levels[2], *split_[2])});
    if (wide_split_) {
      batch.las.color_low.push_back({low_byte16(v.levels[0]), low_byte16(v.levels[1]), low_byte16(v.levels[2])});
    }
  }
  if (intensity_ != nullptr) batch.intensities.push_back(intensity);
  if (alpha_at_ != kNoAlpha) scratch_[alpha_at_] = static_cast<std::uint8_t>(v.rgb >> 24);
  batch.las.extra_bytes.insert(batch.las.extra_bytes.end(), scratch_.begin(), scratch_.end());
  kept = true;
  return Status::ok();
}

Result<std::size_t> PcdPointReader::read(PointCloud& batch, std::size_t max_points) {
  size_batch(batch, 0, info_.has_colors, intensity_ != nullptr);  // keeps the capacity
  batch.las.extra_bytes.clear();
  batch.las.color_low.clear();
  if (extra_size_ > 0) batch.las.extra_bytes_size = static_cast<std::uint32_t>(extra_size_);
  std::size_t got = 0;
  const std::size_t stride = header_.point_size;
  while (got < max_points && done_ < header_.point_count) {
    if (header_.data == PcdData::kBinary) {
      std::span<const std::uint8_t> view;
      RELIEF_RETURN_IF_ERROR(src_.fill(stride, view));
      const std::uint64_t avail = std::min<std::uint64_t>(view.size() / stride, header_.point_count - done_);
      if (avail == 0) return truncated(done_);
      std::size_t used = 0;
      while (used < avail && got < max_points) {
        Values v;
        decode_binary(view.data() + used * stride, v);
        bool kept = false;
        RELIEF_RETURN_IF_ERROR(accept(v, done_ + used, batch, kept));
        got += kept ? 1 : 0;
        ++used;
      }
      src_.consume(used * stride);
      done_ += used;
    } else {
      std::string_view line;
      LineStatus state = LineStatus::kEnd;
      RELIEF_RETURN_IF_ERROR(next_line(src_, kMaxAsciiLine, line, state));
      if (state == LineStatus::kEnd) return truncated(done_);
      if (state == LineStatus::kTooLong) {
        return point_error(done_, "line longer than " + std::to_string(kMaxAsciiLine) + " bytes");
      }
      std::size_t pos = 0;
      if (next_token(line, pos).empty()) continue;  // blank line
      Values v;
      RELIEF_RETURN_IF_ERROR(parse_ascii(line, done_, v));
      bool kept = false;
      RELIEF_RETURN_IF_ERROR(accept(v, done_, batch, kept));
      got += kept ? 1 : 0;
      ++done_;
    }
  }
  if (done_ == header_.point_count && !rest_checked_) {
    rest_checked_ = true;
    RELIEF_RETURN_IF_ERROR(note_extra_points());
  }
  return got;
}

Status PcdPointReader::note_extra_points() {
  // After binary_compressed records nothing is left to see (their size is
  // checked against POINTS); after binary ones the bytes, after ascii ones
  // the lines that are not blank.
  if (header_.data == PcdData::kBinaryCompressed) return Status::ok();
  RELIEF_ASSIGN_OR_RETURN(const ByteSource::Rest rest, src_.read_rest());
  const bool ascii = header_.data == PcdData::kAscii;
  const std::uint64_t extra = ascii ? rest.lines : rest.bytes / header_.point_size;
  if (extra > 0) {
    info_.warnings.push_back(name() + ": the header declares " + std::to_string(header_.point_count) +
                             " points but " + std::to_string(header_.point_count + extra) +
                             " follow; the last " + std::to_string(extra) + " were ignored");
  } else if (!ascii && rest.bytes > 0) {
    info_.warnings.push_back(name() + ": " + std::to_string(rest.bytes) + " bytes follow the last of the " +
                             std::to_string(header_.point_count) +
                             " points the header declares; they were ignored");
  }
  return Status::ok();
}

Status PcdPointReader::expand_compressed() {
  std::span<const std::uint8_t> view;
  RELIEF_RETURN_IF_ERROR(src_.fill(kCompressedHeader, view));
  if (view.size() < kCompressedHeader) {
    return format_error(name() + ": truncated: binary_compressed data has no size fields");
  }
  const std::uint32_t packed = load_le<std::uint32_t>(view.data());
  const std::uint32_t unpacked = load_le<std::uint32_t>(view.data() + 4);
  src_.consume(kCompressedHeader);
  // point_size <= 2^20 and point_count <= 2^40: the product cannot overflow.
  const std::uint64_t expected = header_.point_count * header_.point_size;
  const std::string where = name() + ": binary_compressed: ";
  if (unpacked != expected) {
    return format_error(where + "uncompressed size " + std::to_string(unpacked) + " is not POINTS x point size = " +
                        std::to_string(header_.point_count) + " x " + std::to_string(header_.point_size));
  }
  if (expected == 0) return Status::ok();
  if (const auto rem = src_.remaining(); rem && packed > *rem) {
    return format_error(where + "compressed size " + std::to_string(packed) + " but only " + std::to_string(*rem) +
                        " bytes follow");
  }
  if (std::uint64_t{unpacked} > std::uint64_t{packed} * kMaxLzfExpansion) {
    return format_error(where + std::to_string(packed) + " compressed bytes cannot expand to " +
                        std::to_string(unpacked));
  }
  // Grown as bytes arrive: from a pipe the size cannot be checked in advance.
  std::vector<std::uint8_t> packed_bytes;
  while (packed_bytes.size() < packed) {
    RELIEF_RETURN_IF_ERROR(src_.fill(1, view));
    if (view.empty()) {
      return format_error(where + "truncated: compressed size " + std::to_string(packed) + " but the file ends after " +
                          std::to_string(packed_bytes.size()));
    }
    const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(view.size(), packed - packed_bytes.size()));
    packed_bytes.insert(packed_bytes.end(), view.data(), view.data() + n);
    src_.consume(n);
  }
  std::vector<std::uint8_t> fields(unpacked);
  const unsigned got = lzf_decompress(packed_bytes.data(), packed, fields.data(), unpacked);
  if (got != unpacked) {
    return format_error(where + "the LZF data is corrupt (it expands to " + std::to_string(got) + " of " +
                        std::to_string(unpacked) + " bytes)");
  }
  packed_bytes = {};
  // Structure of arrays to records: field f of point i moves from
  // soa(f) + i * width(f) to i * point_size + offset(f).
  const auto n = static_cast<std::size_t>(header_.point_count);
  expanded_.resize(fields.size());
  std::size_t soa = 0;
  for (const PcdField& f : header_.fields) {
    const std::size_t width = f.size * f.count;
    for (std::size_t i = 0; i < n; ++i) {
      std::memcpy(expanded_.data() + i * header_.point_size + f.offset, fields.data() + soa + i * width, width);
    }
    soa += width * n;
  }
  src_ = ByteSource::from_memory(expanded_);
  header_.data = PcdData::kBinary;
  return Status::ok();
}

}  // namespace

Result<std::unique_ptr<PointReader>> open_pcd_reader(const InputSpec& input, const ReaderOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(ByteSource src, input.open());
  RELIEF_ASSIGN_OR_RETURN(PcdHeader header, parse_header(src, input.name));
  for (const char* axis : {"x", "y", "z"}) {
    if (find_field(header, axis) == nullptr) {
      return format_error(input.name + ": the PCD header has no '" + axis + "' field");
    }
  }
  std::unique_ptr<PcdPointReader> reader(new PcdPointReader(input.name, std::move(src), std::move(header)));
  RELIEF_RETURN_IF_ERROR(reader->check());
  if (options.extra_bytes) RELIEF_RETURN_IF_ERROR(reader->plan_extras());
  return std::unique_ptr<PointReader>(std::move(reader));
}

}  // namespace relief
