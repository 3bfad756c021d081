// Little-endian field-by-field serialisation. Internal to Relief (not installed).
// ByteWriter appends; ByteReader never reads past its span and reports every
// short read as corrupt data naming the field.
#pragma once

#include <cstdint>
#include <cstring>
#include <span>
#include <string>
#include <vector>

#include "relief/status.h"

namespace relief {

class ByteWriter {
 public:
  void u8(std::uint8_t v) { buf_.push_back(v); }
  void u16(std::uint16_t v) { put_le(v, 2); }
  void u32(std::uint32_t v) { put_le(v, 4); }
  void u64(std::uint64_t v) { put_le(v, 8); }
  void f32(float v) {
    std::uint32_t bits;
    std::memcpy(&bits, &v, 4);
    u32(bits);
  }
  void f64(double v) {
    std::uint64_t bits;
    std::memcpy(&bits, &v, 8);
    u64(bits);
  }
  // Unsigned LEB128.
  void varint(std::uint64_t v) {
    while (v >= 0x80) {
      buf_.push_back(static_cast<std::uint8_t>(v | 0x80));
      v >>= 7;
    }
    buf_.push_back(static_cast<std::uint8_t>(v));
  }
  void bytes(std::span<const std::uint8_t> b) { buf_.insert(buf_.end(), b.begin(), b.end()); }
  void bytes(const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    buf_.insert(buf_.end(), b, b + n);
  }
  // Overwrites 4 bytes at `offset` (for sizes known only later).
  void patch_u32(std::size_t offset, std::uint32_t v) {
    for (int i = 0; i < 4; ++i) buf_[offset + i] = static_cast<std::uint8_t>(v >> (8 * i));
  }

  std::size_t size() const { return buf_.size(); }
  std::vector<std::uint8_t>& buffer() { return buf_; }
  std::vector<std::uint8_t> take() { return std::move(buf_); }

 private:
  void put_le(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i) buf_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  std::vector<std::uint8_t> buf_;
};

class ByteReader {
 public:
  // `what` names the data in errors ("chunk blob", "PLY body of x.ply").
  ByteReader(std::span<const std::uint8_t> data, std::string what)
      : data_(data), what_(std::move(what)) {}

  std::size_t position() const { return pos_; }
  std::size_t remaining() const { return data_.size() - pos_; }
  bool at_end() const { return pos_ == data_.size(); }

  Status u8(std::uint8_t& v, const char* field) { return get_le(v, 1, field); }
  Status u16(std::uint16_t& v, const char* field) { return get_le(v, 2, field); }
  Status u32(std::uint32_t& v, const char* field) { return get_le(v, 4, field); }
  Status u64(std::uint64_t& v, const char* field) { return get_le(v, 8, field); }
  Status f32(float& v, const char* field) {
    std::uint32_t bits = 0;
    RELIEF_RETURN_IF_ERROR(u32(bits, field));
    std::memcpy(&v, &bits, 4);
    return Status::ok();
  }
  Status f64(double& v, const char* field) {
    std::uint64_t bits = 0;
    RELIEF_RETURN_IF_ERROR(u64(bits, field));
    std::memcpy(&v, &bits, 8);
    return Status::ok();
  }
  Status varint(std::uint64_t& v, const char* field) {
    v = 0;
    for (int shift = 0; shift < 64; shift += 7) {
      std::uint8_t b = 0;
      RELIEF_RETURN_IF_ERROR(u8(b, field));
      v |= static_cast<std::uint64_t>(b & 0x7f) << shift;
      if ((b & 0x80) == 0) return Status::ok();
    }
    return corrupt_data(what_ + ": varint '" + field + "' is longer than 10 bytes");
  }
  // A view of the next n bytes.
  Status span(std::span<const std::uint8_t>& out, std::size_t n, const char* field) {
    if (n > remaining()) return short_read(field, n);
    out = data_.subspan(pos_, n);
    pos_ += n;
    return Status::ok();
  }
  Status skip(std::size_t n, const char* field) {
    if (n > remaining()) return short_read(field, n);
    pos_ += n;
    return Status::ok();
  }

 private:
  template <typename T>
  Status get_le(T& v, int n, const char* field) {
    if (static_cast<std::size_t>(n) > remaining()) return short_read(field, n);
    std::uint64_t acc = 0;
    for (int i = 0; i < n; ++i) acc |= static_cast<std::uint64_t>(data_[pos_ + i]) << (8 * i);
    pos_ += n;
    v = static_cast<T>(acc);
    return Status::ok();
  }
  Status short_read(const char* field, std::size_t n) const {
    return corrupt_data(what_ + ": truncated at byte " + std::to_string(pos_) + " reading '" +
                        field + "' (" + std::to_string(n) + " bytes wanted, " +
                        std::to_string(remaining()) + " left)");
  }

  std::span<const std::uint8_t> data_;
  std::size_t pos_ = 0;
  std::string what_;
};

}  // namespace relief
