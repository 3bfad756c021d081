// The LASzip entropy decoder: a 32-bit range coder (after Amir Said's
// "FastAC") with adaptive bit and symbol models (shared with the encoder in
// arithmetic_encoder.h; the integer coder LASzip builds on them is in
// integer_coder.h). Bit-exact with LASzip's ArithmeticDecoder /
// ArithmeticModel, so every constant and update rule below is part of the
// format. Internal to lib/laz.
//
// Safety: the decoder reads only inside its span; past the end it feeds
// zeros and counts them, and callers reject a chunk whose decoders ran more
// than a few bytes past their input (a real stream never does). A first
// value that no encoder can produce (0xFFFFFFFF) is refused at init, which
// keeps value < length, so every table index and division below stays in
// range on any input.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace relief::laz {

// The rest of a stream that arrives in pieces.
class ByteFeed {
 public:
  // Sets [begin, end) to the next piece (non-empty); false at the end of the
  // stream or on a read error (which the feed keeps for its owner).
  virtual bool more(const std::uint8_t*& begin, const std::uint8_t*& end) = 0;
  // Bytes of the stream not handed out yet.
  virtual std::uint64_t remaining() const = 0;

 protected:
  ~ByteFeed() = default;
};

// Renormalise when the range falls below 2^24 (one byte of headroom).
inline constexpr std::uint32_t kMinLength = 0x01000000u;
inline constexpr std::uint32_t kMaxLength = 0xFFFFFFFFu;
// Bit models keep probabilities in 13 bits, symbol models in 15.
inline constexpr int kBitLengthShift = 13;
inline constexpr std::uint32_t kBitMaxCount = 1u << kBitLengthShift;
inline constexpr int kSymbolLengthShift = 15;
inline constexpr std::uint32_t kSymbolMaxCount = 1u << kSymbolLengthShift;
// Symbol models above this size get a lookup table for decoding.
inline constexpr std::uint32_t kTableThreshold = 16;

class BitModel {
 public:
  BitModel() { init(); }
  void init() {
    bit_0_count_ = 1;
    bit_count_ = 2;
    bit_0_prob_ = 1u << (kBitLengthShift - 1);
    update_cycle_ = bits_until_update_ = 4;
  }

 private:
  friend class ArithmeticDecoder;
  friend class ArithmeticEncoder;
  void update() {
    if ((bit_count_ += update_cycle_) > kBitMaxCount) {
      bit_count_ = (bit_count_ + 1) >> 1;
      bit_0_count_ = (bit_0_count_ + 1) >> 1;
      if (bit_0_count_ == bit_count_) ++bit_count_;
    }
    const std::uint32_t scale = 0x80000000u / bit_count_;
    bit_0_prob_ = (bit_0_count_ * scale) >> (31 - kBitLengthShift);
    update_cycle_ = std::min<std::uint32_t>((5 * update_cycle_) >> 2, 64);
    bits_until_update_ = update_cycle_;
  }
  std::uint32_t bit_0_count_, bit_count_, bit_0_prob_, update_cycle_, bits_until_update_;
};

class SymbolModel {
 public:
  explicit SymbolModel(std::uint32_t symbols) : symbols_(symbols) {
    if (symbols_ > kTableThreshold) {
      std::uint32_t table_bits = 3;
      while (symbols_ > (1u << (table_bits + 2))) ++table_bits;
      table_size_ = 1u << table_bits;
      table_shift_ = kSymbolLengthShift - static_cast<int>(table_bits);
      table_.assign(table_size_ + 2, 0);
    }
    distribution_.assign(symbols_, 0);
    counts_.assign(symbols_, 0);
    init();
  }
  void init() {
    total_count_ = 0;
    update_cycle_ = symbols_;
    std::fill(counts_.begin(), counts_.end(), 1u);
    update();
    symbols_until_update_ = update_cycle_ = (symbols_ + 6) >> 1;
  }
  std::uint32_t symbols() const { return symbols_; }

 private:
  friend class ArithmeticDecoder;
  friend class ArithmeticEncoder;
  void update() {
    if ((total_count_ += update_cycle_) > kSymbolMaxCount) {
      total_count_ = 0;
      for (auto& c : counts_) {
        c = (c + 1) >> 1;
        total_count_ += c;
      }
    }
    const std::uint32_t scale = 0x80000000u / total_count_;
    std::uint32_t sum = 0;
    if (table_size_ == 0) {
      for (std::uint32_t k = 0; k < symbols_; ++k) {
        distribution_[k] = (scale * sum) >> (31 - kSymbolLengthShift);
        sum += counts_[k];
      }
    } else {
      std::uint32_t s = 0;
      for (std::uint32_t k = 0; k < symbols_; ++k) {
        distribution_[k] = (scale * sum) >> (31 - kSymbolLengthShift);
        sum += counts_[k];
        const std::uint32_t w = distribution_[k] >> table_shift_;
        while (s < w) table_[++s] = k - 1;
      }
      table_[0] = 0;
      while (s <= table_size_) table_[++s] = symbols_ - 1;
    }
    update_cycle_ = std::min((5 * update_cycle_) >> 2, (symbols_ + 6) << 3);
    symbols_until_update_ = update_cycle_;
  }

  std::uint32_t symbols_;
  std::uint32_t table_size_ = 0;
  int table_shift_ = 0;
  std::uint32_t total_count_ = 0, update_cycle_ = 0, symbols_until_update_ = 0;
  std::vector<std::uint32_t> distribution_, counts_, table_;
};

class ArithmeticDecoder {
 public:
  // Starts decoding `data`. False when the stream cannot be a LASzip stream.
  // With `feed`, `data` is the stream's first piece and the feed has the rest.
  bool init(std::span<const std::uint8_t> data, ByteFeed* feed = nullptr) {
    feed_ = feed;
    p_ = data.data();
    end_ = p_ + data.size();
    overrun_ = 0;
    length_ = kMaxLength;
    value_ = static_cast<std::uint32_t>(byte()) << 24;
    value_ |= static_cast<std::uint32_t>(byte()) << 16;
    value_ |= static_cast<std::uint32_t>(byte()) << 8;
    value_ |= byte();
    return value_ < length_;
  }
  // Bytes read past the end of the input (as zeros).
  std::size_t overrun() const { return overrun_; }
  // Input bytes not read yet (the feed's included).
  std::uint64_t unread() const {
    return static_cast<std::uint64_t>(end_ - p_) + (feed_ != nullptr ? feed_->remaining() : 0);
  }

  std::uint32_t decode_bit(BitModel& m) {
    const std::uint32_t x = m.bit_0_prob_ * (length_ >> kBitLengthShift);
    std::uint32_t sym;
    if (value_ < x) {
      sym = 0;
      length_ = x;
      ++m.bit_0_count_;
    } else {
      sym = 1;
      value_ -= x;
      length_ -= x;
    }
    if (length_ < kMinLength) renorm();
    if (--m.bits_until_update_ == 0) m.update();
    return sym;
  }

  std::uint32_t decode_symbol(SymbolModel& m) {
    std::uint32_t n, sym, x, y = length_;
    if (m.table_size_ != 0) {
      length_ >>= kSymbolLengthShift;
      const std::uint32_t dv = value_ / length_;
      // value < length keeps t <= table_size; the clamp is belt and braces.
      const std::uint32_t t = std::min(dv >> m.table_shift_, m.table_size_);
      sym = m.table_[t];
      n = m.table_[t + 1] + 1;
      while (n > sym + 1) {
        const std::uint32_t k = (sym + n) >> 1;
        if (m.distribution_[k] > dv) n = k; else sym = k;
      }
      x = m.distribution_[sym] * length_;
      if (sym != m.symbols_ - 1) y = m.distribution_[sym + 1] * length_;
    } else {
      x = sym = 0;
      length_ >>= kSymbolLengthShift;
      n = m.symbols_;
      std::uint32_t k = n >> 1;
      do {
        const std::uint32_t z = length_ * m.distribution_[k];
        if (z > value_) {
          n = k;
          y = z;
        } else {
          sym = k;
          x = z;
        }
      } while ((k = (sym + n) >> 1) != sym);
    }
    value_ -= x;
    length_ = y - x;
    if (length_ < kMinLength) renorm();
    ++m.counts_[sym];
    if (--m.symbols_until_update_ == 0) m.update();
    return sym;
  }

  // Raw bits, 1..32.
  std::uint32_t read_bits(std::uint32_t bits) {
    if (bits > 19) {
      const std::uint32_t low = read_short();
      const std::uint32_t high = read_bits(bits - 16);
      return (high << 16) | low;
    }
    length_ >>= bits;
    const std::uint32_t sym = value_ / length_;
    value_ -= length_ * sym;
    if (length_ < kMinLength) renorm();
    return sym;
  }
  std::uint32_t read_short() {
    length_ >>= 16;
    const std::uint32_t sym = value_ / length_;
    value_ -= length_ * sym;
    if (length_ < kMinLength) renorm();
    return sym & 0xFFFFu;
  }
  std::uint32_t read_int() {
    const std::uint32_t low = read_short();
    const std::uint32_t high = read_short();
    return (high << 16) | low;
  }

 private:
  std::uint32_t byte() {
    if (p_ < end_) return *p_++;
    if (feed_ != nullptr && feed_->more(p_, end_)) return *p_++;
    ++overrun_;
    return 0;
  }
  void renorm() {
    do {
      value_ = (value_ << 8) | byte();
    } while ((length_ <<= 8) < kMinLength);
  }

  ByteFeed* feed_ = nullptr;
  const std::uint8_t* p_ = nullptr;
  const std::uint8_t* end_ = nullptr;
  std::size_t overrun_ = 0;
  std::uint32_t value_ = 0;
  std::uint32_t length_ = 0;
};

}  // namespace relief::laz
