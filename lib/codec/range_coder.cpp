#include "codec/range_coder.h"

#include <bit>

namespace relief::codec {


void RangeEncoder::flush_cache() {
  const auto carry = static_cast<std::uint8_t>(low_ >> 32);
  std::uint8_t temp = cache_;
  do {
    out_.push_back(static_cast<std::uint8_t>(temp + carry));
    temp = 0xFF;
  } while (--cache_size_ != 0);
  cache_ = static_cast<std::uint8_t>(low_ >> 24);
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
  // w = v + 1 has n + 1 bits (n = 0..64); the leading one is implicit. For
  // v = 2^64 - 1, w = 2^64: n = 64 and every bit below the leading one is 0.
  const bool top = v == ~std::uint64_t{0};
  const std::uint64_t w = top ? 0 : v + 1;  // the bits below the leading one
  const int n = top ? kMaxPrefix : static_cast<int>(std::bit_width(w)) - 1;
  for (int i = 0; i < n; ++i) enc.encode(m.prefix[i], 1);
  if (n < kMaxPrefix) enc.encode(m.prefix[n], 0);
  const int modelled = n < kModelledSuffixBits ? n : kModelledSuffixBits;
  for (int pos = 0; pos < modelled; ++pos) enc.encode(m.suffix[n][pos], static_cast<int>((w >> (n - 1 - pos)) & 1));
  for (int b = n - 1 - modelled; b >= 0; --b) enc.encode_raw(static_cast<int>((w >> b) & 1));
}

bool decode_uint(RangeDecoder& dec, UIntModel& m, std::uint64_t& v) {
  // Exhaustion only grows, so one check after the (at most 128) decisions
  // gives the answer checks after each would.
  int n = 0;
  while (n < kMaxPrefix && dec.decode(m.prefix[n])) ++n;
  // The n bits below the leading one.
  std::uint64_t low = 0;
  const int modelled = n < kModelledSuffixBits ? n : kModelledSuffixBits;
  for (int pos = 0; pos < modelled; ++pos) low = (low << 1) | static_cast<std::uint64_t>(dec.decode(m.suffix[n][pos]));
  for (int pos = modelled; pos < n; ++pos) low = (low << 1) | static_cast<std::uint64_t>(dec.decode_raw());
  if (dec.exhausted()) return false;
  if (n == kMaxPrefix) {
    // w = 2^64 + low: only low = 0 (v = 2^64 - 1) fits 64 bits.
    if (low != 0) return false;
    v = ~std::uint64_t{0};
    return true;
  }
  v = ((std::uint64_t{1} << n) | low) - 1;
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
