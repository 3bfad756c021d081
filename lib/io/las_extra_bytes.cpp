// The LAS Extra Bytes VLR (LASF_Spec, record 4): 192-byte descriptors, one
// per field, after ASPRS LAS 1.4 R15 section 2.5. Only what Relief needs is
// read: type, size, name, description, scale and offset.

#include <array>
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

std::string fixed_text(const std::uint8_t* p, std::size_t width) {
  const auto* chars = reinterpret_cast<const char*>(p);
  return std::string(chars, ::strnlen(chars, width));
}

}  // namespace

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
      f.size = kScalarSizes[static_cast<std::size_t>(base)] * static_cast<std::size_t>(count);
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
