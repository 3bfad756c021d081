// PLY vocabulary shared by the reader and the writer: scalar types, their
// names and sizes, and the parsed header. Internal to lib/io.
#pragma once

#include <algorithm>
#include <cctype>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "relief/io.h"

namespace relief::ply {

enum class ScalarType : std::uint8_t { kInt8, kUint8, kInt16, kUint16, kInt32, kUint32, kFloat32, kFloat64 };

inline constexpr std::size_t scalar_size(ScalarType t) {
  switch (t) {
    case ScalarType::kInt8:
    case ScalarType::kUint8: return 1;
    case ScalarType::kInt16:
    case ScalarType::kUint16: return 2;
    case ScalarType::kInt32:
    case ScalarType::kUint32:
    case ScalarType::kFloat32: return 4;
    case ScalarType::kFloat64: return 8;
  }
  return 0;
}

inline constexpr bool is_integer(ScalarType t) {
  return t != ScalarType::kFloat32 && t != ScalarType::kFloat64;
}

// The classic names; the writer emits these because every PLY reader knows them.
inline constexpr const char* scalar_name(ScalarType t) {
  switch (t) {
    case ScalarType::kInt8: return "char";
    case ScalarType::kUint8: return "uchar";
    case ScalarType::kInt16: return "short";
    case ScalarType::kUint16: return "ushort";
    case ScalarType::kInt32: return "int";
    case ScalarType::kUint32: return "uint";
    case ScalarType::kFloat32: return "float";
    case ScalarType::kFloat64: return "double";
  }
  return "?";
}

// LAS Extra Bytes data types (ASPRS LAS 1.4 R15, table 24) of the PLY scalar
// types: every PLY scalar has one, so a vertex property kept as LAS extra
// bytes keeps its type. The inverse is partial: 64-bit integers (7, 8) have
// no PLY type.
inline constexpr int extra_bytes_type(ScalarType t) {
  switch (t) {
    case ScalarType::kUint8: return 1;
    case ScalarType::kInt8: return 2;
    case ScalarType::kUint16: return 3;
    case ScalarType::kInt16: return 4;
    case ScalarType::kUint32: return 5;
    case ScalarType::kInt32: return 6;
    case ScalarType::kFloat32: return 9;
    case ScalarType::kFloat64: return 10;
  }
  return 0;
}

inline std::optional<ScalarType> scalar_type_of_extra_bytes(int base_type) {
  for (ScalarType t : {ScalarType::kUint8, ScalarType::kInt8, ScalarType::kUint16, ScalarType::kInt16,
                       ScalarType::kUint32, ScalarType::kInt32, ScalarType::kFloat32, ScalarType::kFloat64}) {
    if (extra_bytes_type(t) == base_type) return t;
  }
  return std::nullopt;
}

// Accepts both the classic names and the sized aliases (int8 ... float64).
inline std::optional<ScalarType> parse_scalar_type(std::string_view name) {
  struct Alias {
    std::string_view name;
    ScalarType type;
  };
  static constexpr Alias kAliases[] = {
      {"char", ScalarType::kInt8},      {"int8", ScalarType::kInt8},
      {"uchar", ScalarType::kUint8},    {"uint8", ScalarType::kUint8},
      {"short", ScalarType::kInt16},    {"int16", ScalarType::kInt16},
      {"ushort", ScalarType::kUint16},  {"uint16", ScalarType::kUint16},
      {"int", ScalarType::kInt32},      {"int32", ScalarType::kInt32},
      {"uint", ScalarType::kUint32},    {"uint32", ScalarType::kUint32},
      {"float", ScalarType::kFloat32},  {"float32", ScalarType::kFloat32},
      {"double", ScalarType::kFloat64}, {"float64", ScalarType::kFloat64},
  };
  for (const Alias& a : kAliases) {
    if (a.name == name) return a.type;
  }
  return std::nullopt;
}

inline constexpr const char* encoding_name(PlyEncoding e) {
  switch (e) {
    case PlyEncoding::kAscii: return "ascii";
    case PlyEncoding::kBinaryLittleEndian: return "binary_little_endian";
    case PlyEncoding::kBinaryBigEndian: return "binary_big_endian";
  }
  return "?";
}

inline std::optional<PlyEncoding> parse_encoding(std::string_view name) {
  for (PlyEncoding e : {PlyEncoding::kAscii, PlyEncoding::kBinaryLittleEndian,
                        PlyEncoding::kBinaryBigEndian}) {
    if (name == encoding_name(e)) return e;
  }
  return std::nullopt;
}

struct Property {
  std::string name;
  ScalarType type = ScalarType::kFloat32;  // the item type for a list
  bool is_list = false;
  ScalarType count_type = ScalarType::kUint8;  // only for a list
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  std::vector<Property> properties;

  // Byte size of one record when no property is a list.
  bool fixed_size() const {
    for (const Property& p : properties) {
      if (p.is_list) return false;
    }
    return true;
  }
  // Smallest possible binary record: every list empty.
  std::size_t min_record_size() const {
    std::size_t n = 0;
    for (const Property& p : properties) n += scalar_size(p.is_list ? p.count_type : p.type);
    return n;
  }
  // Index of the property called `name`, if any.
  std::optional<std::size_t> find(std::string_view prop_name) const {
    for (std::size_t i = 0; i < properties.size(); ++i) {
      if (properties[i].name == prop_name) return i;
    }
    return std::nullopt;
  }
  // The same name in any case when no property has it exactly (writers
  // spell them X, Red, Intensity, CloudCompare's scalar_Intensity ...).
  std::optional<std::size_t> find_any_case(std::string_view prop_name) const {
    if (const auto exact = find(prop_name)) return exact;
    const auto lower = [](char c) { return static_cast<char>(std::tolower(static_cast<unsigned char>(c))); };
    for (std::size_t i = 0; i < properties.size(); ++i) {
      const std::string& n = properties[i].name;
      if (n.size() == prop_name.size() &&
          std::equal(n.begin(), n.end(), prop_name.begin(), [&](char a, char b) { return lower(a) == lower(b); })) {
        return i;
      }
    }
    return std::nullopt;
  }
};

struct Header {
  PlyEncoding encoding = PlyEncoding::kAscii;
  std::vector<Element> elements;
};

// Limits on untrusted headers. Real headers are a few hundred bytes with a
// handful of properties; the limits keep garbage from being scanned or
// allocated for, and keep every size product far from overflowing 64 bits
// (kMaxElementCount * kMaxProperties * 8 < 2^56).
inline constexpr std::size_t kMaxHeaderBytes = std::size_t{1} << 20;
inline constexpr std::size_t kMaxHeaderLine = std::size_t{64} << 10;
inline constexpr std::size_t kMaxElements = 1024;
inline constexpr std::size_t kMaxProperties = 1024;
inline constexpr std::uint64_t kMaxElementCount = std::uint64_t{1} << 40;

}  // namespace relief::ply
