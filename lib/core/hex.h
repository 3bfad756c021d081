// Bytes as lower-case hexadecimal text and back (binary values in text
// metadata: the Extra Bytes VLR in relief_meta and in shard plans). Internal
// to Relief (not installed).
#pragma once

#include <cstddef>
#include <optional>
#include <string>

namespace relief {

inline std::string hex_lower(const std::string& bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  out.reserve(2 * bytes.size());
  for (const char c : bytes) {
    const auto b = static_cast<unsigned char>(c);
    out += kDigits[b >> 4];
    out += kDigits[b & 15];
  }
  return out;
}

// hex_lower's inverse; nullopt on an odd length or a character that is not a
// hexadecimal digit (upper-case digits only with `accept_upper`).
inline std::optional<std::string> bytes_from_hex(const std::string& hex, bool accept_upper) {
  if (hex.size() % 2 != 0) return std::nullopt;
  const auto digit = [accept_upper](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (accept_upper && c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  std::string out;
  out.reserve(hex.size() / 2);
  for (std::size_t i = 0; i < hex.size(); i += 2) {
    const int hi = digit(hex[i]);
    const int lo = digit(hex[i + 1]);
    if (hi < 0 || lo < 0) return std::nullopt;
    out += static_cast<char>((hi << 4) | lo);
  }
  return out;
}

}  // namespace relief
