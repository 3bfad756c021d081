// Adaptive binary range coder for the error-bounded layer of chunk format v2
// (format-spec/chunk.md, "Binary arithmetic coding"). Carry-less in the style
// of LZMA's range coder: 32-bit range, 16-bit probabilities, a byte cache for
// carry propagation. Every model is a pair of probabilities adapting at two
// speeds; the coder uses their mean.
//
// The decoder never reads outside its input: past the end it reads zero bytes
// and counts them, so a caller can reject a stream that was over-read
// (`overrun()`), and it counts decisions so callers can bound the work a
// hostile stream can cause by the bytes actually present.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace relief::codec {

// Probabilities are of the bit being 0, in units of 2^-16.
inline constexpr int kProbBits = 16;
inline constexpr std::uint32_t kProbOne = 1u << kProbBits;
// Clamp so no decision costs less than ~0.0007 bits: a decoder's work is then
// bounded by ~11,000 decisions per byte of input (see max_decisions()).
inline constexpr std::uint32_t kProbMin = 32;
inline constexpr std::uint32_t kProbMax = kProbOne - kProbMin;
inline constexpr int kFastShift = 4;
// A decision costs at least -log2(1 - kProbMin / 2^16) ~ 0.000705 bits, so
// one byte carries at most ~11,350 of them; the constant leaves headroom for
// the coder's 4-byte window. A decoder given `bytes` of input stops after
// max_decisions(bytes) decisions.
inline constexpr std::uint64_t kMaxDecisionsPerByte = 12000;
inline constexpr std::uint64_t kDecisionSlackBytes = 8;
inline constexpr std::uint64_t max_decisions(std::size_t bytes) {
  return kMaxDecisionsPerByte * (bytes + kDecisionSlackBytes);
}
inline constexpr int kSlowShift = 7;

// The adaptation shifts of a model seen `seen` times (0..kSlowShift): the
// rate starts at 1/2 and falls by half per bit seen down to the floor.
inline constexpr std::uint8_t kFastShiftBySeen[kSlowShift + 1] = {1, 2, 3, 4, 4, 4, 4, 4};
inline constexpr std::uint8_t kSlowShiftBySeen[kSlowShift + 1] = {1, 2, 3, 4, 5, 6, 7, 7};
static_assert(kFastShiftBySeen[kSlowShift] == kFastShift && kSlowShiftBySeen[kSlowShift] == kSlowShift);

struct BitModel {
  // Two estimates of P(0): `fast` adapts with a rate that starts at 1/2 and
  // falls to 2^-kFastShift as the context is seen (a young context learns
  // from its first few bits), `slow` at 2^-kSlowShift once mature.
  std::uint16_t fast = kProbOne / 2;
  std::uint16_t slow = kProbOne / 2;
  std::uint8_t seen = 0;

  // Clamped to [kProbMin, kProbMax]. Only the upper bound can bind: from the
  // initial state no sequence of bits takes `fast` below 15 or `slow` below
  // 127 (test_range_coder.cpp explores every reachable state), so p >= 71.
  std::uint32_t p0() const {
    const std::uint32_t p = (static_cast<std::uint32_t>(fast) + slow) >> 1;
    return p > kProbMax ? kProbMax : p;
  }
  // A 1 moves each estimate down by p >> shift, a 0 up by (2^16 - 1 - p) >>
  // shift (without branching on the bit, which the coder cannot predict).
  // A mature model (most decisions) takes the constant shifts.
  void update(int bit) {
    if (seen == kSlowShift) return move(bit, kFastShift, kSlowShift);
    const int fs = kFastShiftBySeen[seen];
    const int ss = kSlowShiftBySeen[seen];
    ++seen;
    move(bit, fs, ss);
  }

 private:
  void move(int bit, int fs, int ss) {
    const std::uint32_t f = fast, s = slow;
    const std::uint32_t df = (bit ? f : kProbOne - 1 - f) >> fs;
    const std::uint32_t ds = (bit ? s : kProbOne - 1 - s) >> ss;
    fast = static_cast<std::uint16_t>(bit ? f - df : f + df);
    slow = static_cast<std::uint16_t>(bit ? s - ds : s + ds);
  }
};

class RangeEncoder {
 public:
  void encode(BitModel& m, int bit) {
    const std::uint32_t bound = (range_ >> kProbBits) * m.p0();
    low_ += bit ? bound : 0;
    range_ = bit ? range_ - bound : bound;
    m.update(bit);
    while (range_ < kTop) {
      range_ <<= 8;
      shift_low();
    }
  }
  // A bit with the given P(0) in [kProbMin, kProbMax], no model (the caller
  // computed the probability and updates its own state).
  void encode_prob(std::uint32_t p0, int bit) {
    const std::uint32_t bound = (range_ >> kProbBits) * p0;
    low_ += bit ? bound : 0;
    range_ = bit ? range_ - bound : bound;
    while (range_ < kTop) {
      range_ <<= 8;
      shift_low();
    }
  }
  // A bit with probability 1/2, no model.
  void encode_raw(int bit) {
    range_ >>= 1;
    low_ += bit ? range_ : 0;
    while (range_ < kTop) {
      range_ <<= 8;
      shift_low();
    }
  }
  // Flushes and returns the stream.
  std::vector<std::uint8_t> finish();
  // Bytes the stream holds so far, pending ones included. It grows by one
  // per byte shifted out, and finish() shifts five more and drops the
  // first, so the finished stream is always longer than any value seen.
  std::size_t bytes() const { return out_.size() + static_cast<std::size_t>(cache_size_); }

 private:
  static constexpr std::uint32_t kTop = 1u << 24;
  // Moves the top byte of low_ out: into the cache, and the cache (plus any
  // run of 0xFF bytes waiting for a carry) into the stream once the carry
  // into it is settled.
  void shift_low() {
    if (low_ < 0xFF000000ull || low_ >= (1ull << 32)) {
      flush_cache();
    }
    ++cache_size_;
    low_ = (low_ & 0x00FFFFFFull) << 8;
  }
  void flush_cache();

  std::uint64_t low_ = 0;
  std::uint32_t range_ = 0xFFFFFFFFu;
  std::uint8_t cache_ = 0;
  std::uint64_t cache_size_ = 1;
  std::vector<std::uint8_t> out_;
};

class RangeDecoder {
 public:
  explicit RangeDecoder(std::span<const std::uint8_t> data);

  int decode(BitModel& m) {
    ++decisions_;
    const std::uint32_t bound = (range_ >> kProbBits) * m.p0();
    const int bit = code_ >= bound ? 1 : 0;
    code_ -= bit ? bound : 0;
    range_ = bit ? range_ - bound : bound;
    m.update(bit);
    while (range_ < kTop) {
      range_ <<= 8;
      code_ = (code_ << 8) | next_byte();
    }
    return bit;
  }
  // The mirror of RangeEncoder::encode_prob.
  int decode_prob(std::uint32_t p0) {
    ++decisions_;
    const std::uint32_t bound = (range_ >> kProbBits) * p0;
    const int bit = code_ >= bound ? 1 : 0;
    code_ -= bit ? bound : 0;
    range_ = bit ? range_ - bound : bound;
    while (range_ < kTop) {
      range_ <<= 8;
      code_ = (code_ << 8) | next_byte();
    }
    return bit;
  }
  int decode_raw() {
    ++decisions_;
    range_ >>= 1;
    const int bit = code_ >= range_ ? 1 : 0;
    code_ -= bit ? range_ : 0;
    while (range_ < kTop) {
      range_ <<= 8;
      code_ = (code_ << 8) | next_byte();
    }
    return bit;
  }
  // Bytes read past the end of the input (a valid stream reads none: the
  // encoder's flush supplies every byte the decoder's window needs).
  std::size_t overrun() const { return overrun_; }
  // True when the stream has been read past its end or has made more
  // decisions than its size can honestly encode: the caller must stop.
  bool exhausted() const { return overrun_ > 0 || decisions_ > max_decisions_; }
  std::uint64_t decisions() const { return decisions_; }

 private:
  static constexpr std::uint32_t kTop = 1u << 24;
  std::uint8_t next_byte() {
    if (pos_ < data_.size()) return data_[pos_++];
    ++overrun_;
    return 0;
  }

  std::span<const std::uint8_t> data_;
  std::size_t pos_ = 0;
  std::size_t overrun_ = 0;
  std::uint32_t range_ = 0xFFFFFFFFu;
  std::uint32_t code_ = 0;
  std::uint64_t decisions_ = 0;
  std::uint64_t max_decisions_ = 0;
};

// ---- Integers on top of the binary coder.
//
// An adaptive Exp-Golomb code for unsigned values: the number of bits of
// (v + 1) as a unary prefix with one model per position, then the bits below
// the leading one, the top `kModelledSuffixBits` of them with a model per
// (prefix length, bit position), the rest raw.
inline constexpr int kMaxPrefix = 64;
inline constexpr int kModelledSuffixBits = 3;

struct UIntModel {
  BitModel prefix[kMaxPrefix + 1];
  BitModel suffix[kMaxPrefix + 1][kModelledSuffixBits];
};

void encode_uint(RangeEncoder& enc, UIntModel& m, std::uint64_t v);
// Returns false on a stream that is exhausted or encodes a value wider than 64 bits.
bool decode_uint(RangeDecoder& dec, UIntModel& m, std::uint64_t& v);

// Signed values: a zero flag, a sign and the magnitude − 1.
struct SIntModel {
  BitModel zero;
  BitModel sign;
  UIntModel magnitude;
};

void encode_sint(RangeEncoder& enc, SIntModel& m, std::int64_t v);
bool decode_sint(RangeDecoder& dec, SIntModel& m, std::int64_t& v);

}  // namespace relief::codec
