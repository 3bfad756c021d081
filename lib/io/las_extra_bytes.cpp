// The LAS Extra Bytes VLR (LASF_Spec, record 4): 192-byte descriptors, one
// per field, after ASPRS LAS 1.4 R15 section 2.5. Only what Relief needs is
// read: type, size, name, description, scale and offset.

#include <array>
#include <bit>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "io/stream_support.h"
#include "relief/io.h"

namespace relief {

namespace {

constexpr std::size_t kDescriptorSize = 192;
constexpr std::size_t kNameOffset = 4;
constexpr std::size_t kNameSize = 32;
constexpr std::size_t kScaleOffset = 112;
constexpr std::size_t kOffsetOffset = 136;
constexpr std::size_t kDescriptionOffset = 160;
constexpr std::uint8_t kOptionScale = 1u << 3;
constexpr std::uint8_t kOptionOffset = 1u << 4;
// Data types 1-10: u8 i8 u16 i16 u32 i32 u64 i64 f32 f64; 11-20 two of
// each, 21-30 three of each (deprecated but defined). 31 and up are reserved.
constexpr int kScalarTypes = 10;
constexpr int kLastDefinedType = 30;
constexpr std::array<std::size_t, kScalarTypes> kScalarSizes = {1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
constexpr std::array<const char*, kScalarTypes> kScalarNames = {"uint8",  "int8",  "uint16", "int16",   "uint32",
                                                               "int32",  "uint64", "int64", "float32", "float64"};

void store_double_le(char* p, double v) {
  const auto u = std::bit_cast<std::uint64_t>(v);
  for (int b = 0; b < 8; ++b) p[b] = static_cast<char>((u >> (8 * b)) & 0xFF);
}

std::string fixed_text(const std::uint8_t* p, std::size_t width) {
  const auto* chars = reinterpret_cast<const char*>(p);
  return std::string(chars, ::strnlen(chars, width));
}

}  // namespace

std::size_t extra_bytes_type_size(int data_type) {
  if (data_type < 1 || data_type > kLastDefinedType) return 0;
  const int base = (data_type - 1) % kScalarTypes;
  const int count = (data_type - 1) / kScalarTypes + 1;
  return kScalarSizes[static_cast<std::size_t>(base)] * static_cast<std::size_t>(count);
}

int extra_bytes_base_type(int data_type) {
  if (data_type < 1 || data_type > kLastDefinedType) return 0;
  return (data_type - 1) % kScalarTypes + 1;
}

Result<std::string> make_extra_bytes_vlr(const std::vector<ExtraBytesField>& fields) {
  constexpr std::size_t kMaxFields = 65535 / kDescriptorSize;
  if (fields.size() > kMaxFields) {
    return invalid_argument(std::to_string(fields.size()) + " extra bytes fields: one Extra Bytes VLR holds at most " +
                            std::to_string(kMaxFields));
  }
  std::string out(fields.size() * kDescriptorSize, '\0');
  for (std::size_t i = 0; i < fields.size(); ++i) {
    const ExtraBytesField& f = fields[i];
    if (f.name.size() > kNameSize || f.description.size() > kNameSize) {
      return invalid_argument("extra bytes field '" + f.name + "': a name or description longer than 32 bytes");
    }
    if (f.data_type < 0 || f.data_type > kLastDefinedType) {
      return invalid_argument("extra bytes field '" + f.name + "': data type " + std::to_string(f.data_type) +
                              " is reserved");
    }
    char* d = out.data() + i * kDescriptorSize;
    d[2] = static_cast<char>(f.data_type);
    d[3] = static_cast<char>(f.options);
    std::memcpy(d + kNameOffset, f.name.data(), f.name.size());
    std::memcpy(d + kDescriptionOffset, f.description.data(), f.description.size());
    if ((f.options & kOptionScale) != 0) store_double_le(d + kScaleOffset, f.scale);
    if ((f.options & kOptionOffset) != 0) store_double_le(d + kOffsetOffset, f.value_offset);
  }
  return out;
}

Result<std::vector<ExtraBytesField>> parse_extra_bytes_vlr(std::span<const std::uint8_t> payload,
                                                           std::size_t record_extra, const std::string& what) {
  if (payload.size() % kDescriptorSize != 0) {
    return format_error(what + ": the Extra Bytes VLR has " + std::to_string(payload.size()) +
                        " bytes, not a whole number of 192-byte field descriptors");
  }
  std::vector<ExtraBytesField> fields;
  std::size_t at = 0;
  for (std::size_t i = 0; i < payload.size() / kDescriptorSize; ++i) {
    const std::uint8_t* d = payload.data() + i * kDescriptorSize;
    ExtraBytesField f;
    f.data_type = d[2];
    f.options = d[3];
    f.name = fixed_text(d + kNameOffset, kNameSize);
    f.description = fixed_text(d + kDescriptionOffset, kNameSize);
    const std::string which = what + ": Extra Bytes field " + std::to_string(i + 1) + " ('" + f.name + "')";
    if (f.data_type == 0) {
      f.size = f.options;  // undocumented bytes: the options byte holds the count
      f.type_name = "bytes[" + std::to_string(f.size) + "]";
      if (f.size == 0) return format_error(which + " has 0 undocumented bytes");
    } else if (f.data_type <= kLastDefinedType) {
      const int base = (f.data_type - 1) % kScalarTypes;
      const int count = (f.data_type - 1) / kScalarTypes + 1;
      f.size = extra_bytes_type_size(f.data_type);
      f.type_name = kScalarNames[static_cast<std::size_t>(base)];
      if (count > 1) f.type_name += "[" + std::to_string(count) + "]";
      if ((f.options & kOptionScale) != 0) f.scale = load_le<double>(d + kScaleOffset);
      if ((f.options & kOptionOffset) != 0) f.value_offset = load_le<double>(d + kOffsetOffset);
    } else {
      return format_error(which + " has the reserved data type " + std::to_string(f.data_type));
    }
    f.offset = at;
    at += f.size;
    if (at > record_extra) {
      return format_error(what + ": the Extra Bytes VLR describes at least " + std::to_string(at) +
                          " bytes per point but the point records have " + std::to_string(record_extra) +
                          " extra bytes");
    }
    fields.push_back(std::move(f));
  }
  return fields;
}

}  // namespace relief
