#include "codec/range_coder.h"

namespace relief::codec {

namespace {

__extension__ typedef unsigned __int128 u128;

int bit_width128(u128 w) {
  int n = 0;
  while (w != 0) {
    ++n;
    w >>= 1;
  }
  return n;
}

}  // namespace

void RangeEncoder::shift_low() {
  if (low_ < 0xFF000000ull || low_ >= (1ull << 32)) {
    const auto carry = static_cast<std::uint8_t>(low_ >> 32);
    std::uint8_t temp = cache_;
    do {
      out_.push_back(static_cast<std::uint8_t>(temp + carry));
      temp = 0xFF;
    } while (--cache_size_ != 0);
    cache_ = static_cast<std::uint8_t>(low_ >> 24);
  }
  ++cache_size_;
  low_ = (low_ & 0x00FFFFFFull) << 8;
}

std::vector<std::uint8_t> RangeEncoder::finish() {
  for (int i = 0; i < 5; ++i) shift_low();
  // The first byte is always the initial cache (0): drop it, the decoder
  // starts as if it had read it.
  std::vector<std::uint8_t> out(out_.begin() + 1, out_.end());
  return out;
}

RangeDecoder::RangeDecoder(std::span<const std::uint8_t> data)
    : data_(data), max_decisions_(max_decisions(data.size())) {
  for (int i = 0; i < 4; ++i) code_ = (code_ << 8) | next_byte();
}

void encode_uint(RangeEncoder& enc, UIntModel& m, std::uint64_t v) {
  const u128 w = static_cast<u128>(v) + 1;
  const int n = bit_width128(w) - 1;  // 0..64 bits below the leading one
  for (int i = 0; i < n; ++i) enc.encode(m.prefix[i], 1);
  if (n < kMaxPrefix) enc.encode(m.prefix[n], 0);
  for (int b = n - 1; b >= 0; --b) {
    const int bit = static_cast<int>((w >> b) & 1);
    const int pos = n - 1 - b;
    if (pos < kModelledSuffixBits) {
      enc.encode(m.suffix[n][pos], bit);
    } else {
      enc.encode_raw(bit);
    }
  }
}

bool decode_uint(RangeDecoder& dec, UIntModel& m, std::uint64_t& v) {
  int n = 0;
  while (n < kMaxPrefix && dec.decode(m.prefix[n])) {
    ++n;
    if (dec.exhausted()) return false;
  }
  u128 w = 1;
  for (int pos = 0; pos < n; ++pos) {
    const int bit = pos < kModelledSuffixBits ? dec.decode(m.suffix[n][pos]) : dec.decode_raw();
    w = (w << 1) | static_cast<u128>(bit);
  }
  if (dec.exhausted()) return false;
  const u128 value = w - 1;
  if (value > static_cast<u128>(~std::uint64_t{0})) return false;
  v = static_cast<std::uint64_t>(value);
  return true;
}

void encode_sint(RangeEncoder& enc, SIntModel& m, std::int64_t v) {
  if (v == 0) {
    enc.encode(m.zero, 1);
    return;
  }
  enc.encode(m.zero, 0);
  enc.encode(m.sign, v < 0 ? 1 : 0);
  const std::uint64_t mag = v < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(v) : static_cast<std::uint64_t>(v);
  encode_uint(enc, m.magnitude, mag - 1);
}

bool decode_sint(RangeDecoder& dec, SIntModel& m, std::int64_t& v) {
  if (dec.decode(m.zero)) {
    v = 0;
    return !dec.exhausted();
  }
  const int negative = dec.decode(m.sign);
  std::uint64_t mag1 = 0;
  if (!decode_uint(dec, m.magnitude, mag1)) return false;
  if (mag1 == ~std::uint64_t{0}) return false;  // magnitude 2^64 does not fit
  const std::uint64_t mag = mag1 + 1;
  if (negative) {
    if (mag > (std::uint64_t{1} << 63)) return false;
    v = static_cast<std::int64_t>(std::uint64_t{0} - mag);
  } else {
    if (mag > static_cast<std::uint64_t>(INT64_MAX)) return false;
    v = static_cast<std::int64_t>(mag);
  }
  return true;
}

}  // namespace relief::codec
