// The encoding side of LASzip's range coder and integer compressor, mirror
// of arithmetic_decoder.h: the same models, updated the same way, so that
// the decoder there (and LASzip's) reads back exactly what is written here.
// Internal to lib/laz.
#pragma once

#include <cstdint>
#include <vector>

#include "laz/arithmetic_decoder.h"

namespace relief::laz {

class ArithmeticEncoder {
 public:
  // Starts a stream appended to `out` (which must outlive the stream).
  void init(std::vector<std::uint8_t>& out) {
    out_ = &out;
    start_ = out.size();
    base_ = 0;
    length_ = kMaxLength;
  }

  void encode_bit(BitModel& m, std::uint32_t sym) {
    const std::uint32_t x = m.bit_0_prob_ * (length_ >> kBitLengthShift);
    if (sym == 0) {
      length_ = x;
      ++m.bit_0_count_;
    } else {
      add_base(x);
      length_ -= x;
    }
    if (length_ < kMinLength) renorm();
    if (--m.bits_until_update_ == 0) m.update();
  }

  void encode_symbol(SymbolModel& m, std::uint32_t sym) {
    const std::uint32_t* dist = m.distribution_.data();
    if (sym == m.symbols_ - 1) {
      const std::uint32_t x = dist[sym] * (length_ >> kSymbolLengthShift);
      add_base(x);
      length_ -= x;
    } else {
      length_ >>= kSymbolLengthShift;
      const std::uint32_t x = dist[sym] * length_;
      add_base(x);
      length_ = dist[sym + 1] * length_ - x;
    }
    if (length_ < kMinLength) renorm();
    ++m.counts_[sym];
    if (--m.symbols_until_update_ == 0) m.update();
  }

  void write_bits(std::uint32_t bits, std::uint32_t sym) {
    if (bits > 19) {
      write_short(sym & 0xFFFFu);
      sym >>= 16;
      bits -= 16;
    }
    length_ >>= bits;
    add_base(sym * length_);
    if (length_ < kMinLength) renorm();
  }
  void write_short(std::uint32_t sym) {
    length_ >>= 16;
    add_base(sym * length_);
    if (length_ < kMinLength) renorm();
  }
  void write_int(std::uint32_t sym) {
    write_short(sym & 0xFFFFu);
    write_short(sym >> 16);
  }

  // Ends the stream with the bytes the decoder will read ahead.
  void done() {
    bool another_byte = true;
    if (length_ > 2 * kMinLength) {
      add_base(kMinLength);
      length_ = kMinLength >> 1;
    } else {
      add_base(kMinLength >> 1);
      length_ = kMinLength >> 9;
      another_byte = false;
    }
    renorm();
    out_->push_back(0);
    out_->push_back(0);
    if (another_byte) out_->push_back(0);
    out_ = nullptr;
  }

 private:
  void add_base(std::uint32_t x) {
    const std::uint32_t before = base_;
    base_ += x;
    if (base_ < before) propagate_carry();
  }
  void propagate_carry() {
    // A carry ripples back through 0xFF bytes of this stream.
    std::size_t i = out_->size();
    while (i > start_) {
      --i;
      if ((*out_)[i] != 0xFF) {
        ++(*out_)[i];
        return;
      }
      (*out_)[i] = 0;
    }
  }
  void renorm() {
    do {
      out_->push_back(static_cast<std::uint8_t>(base_ >> 24));
      base_ <<= 8;
    } while ((length_ <<= 8) < kMinLength);
  }

  std::vector<std::uint8_t>* out_ = nullptr;
  std::size_t start_ = 0;
  std::uint32_t base_ = 0;
  std::uint32_t length_ = kMaxLength;
};

// IntegerCompressor, encoding side (same models as IntegerDecompressor).
class IntegerCompressor {
 public:
  explicit IntegerCompressor(std::uint32_t bits = 16, std::uint32_t contexts = 1, std::uint32_t bits_high = 8)
      : bits_high_(bits_high) {
    if (bits != 0 && bits < 32) {
      corr_bits_ = bits;
      corr_range_ = 1u << bits;
      corr_min_ = -static_cast<std::int32_t>(corr_range_ / 2);
      corr_max_ = corr_min_ + static_cast<std::int32_t>(corr_range_ - 1);
    } else {
      corr_bits_ = 32;
      corr_range_ = 0;
      corr_min_ = INT32_MIN;
      corr_max_ = INT32_MAX;
    }
    for (std::uint32_t i = 0; i < contexts; ++i) bits_models_.emplace_back(corr_bits_ + 1);
    for (std::uint32_t i = 1; i <= corr_bits_; ++i) {
      correctors_.emplace_back(i <= bits_high_ ? (1u << i) : (1u << bits_high_));
    }
  }
  void init() {
    for (auto& m : bits_models_) m.init();
    corrector0_.init();
    for (auto& m : correctors_) m.init();
  }
  std::uint32_t k() const { return k_; }

  void compress(ArithmeticEncoder& enc, std::int32_t pred, std::int32_t real, std::uint32_t context = 0) {
    std::int64_t corr = static_cast<std::int64_t>(real) - pred;
    if (corr_range_ != 0) {
      if (corr < corr_min_) {
        corr += corr_range_;
      } else if (corr > corr_max_) {
        corr -= corr_range_;
      }
    } else {
      corr = static_cast<std::int32_t>(static_cast<std::uint32_t>(real) - static_cast<std::uint32_t>(pred));
    }
    write_corrector(enc, static_cast<std::int32_t>(corr), bits_models_[context]);
  }

 private:
  void write_corrector(ArithmeticEncoder& enc, std::int32_t c, SymbolModel& bits_model) {
    // k: bits needed for |c| (c in [-(2^k - 1), -2^(k-1)] or [2^(k-1) + 1, 2^k]).
    std::uint32_t c1 = c <= 0 ? static_cast<std::uint32_t>(-static_cast<std::int64_t>(c))
                              : static_cast<std::uint32_t>(c) - 1;
    k_ = 0;
    while (c1 != 0) {
      c1 >>= 1;
      ++k_;
    }
    enc.encode_symbol(bits_model, k_);
    if (k_ == 0) {
      enc.encode_bit(corrector0_, static_cast<std::uint32_t>(c));
      return;
    }
    if (k_ >= 32) return;  // only corr_min needs 32 bits; the decoder knows it
    std::uint32_t v = c < 0 ? static_cast<std::uint32_t>(c + static_cast<std::int64_t>((1u << k_) - 1))
                            : static_cast<std::uint32_t>(c) - 1;
    if (k_ <= bits_high_) {
      enc.encode_symbol(correctors_[k_ - 1], v);
    } else {
      const std::uint32_t k1 = k_ - bits_high_;
      const std::uint32_t low = v & ((1u << k1) - 1);
      v >>= k1;
      enc.encode_symbol(correctors_[k_ - 1], v);
      enc.write_bits(k1, low);
    }
  }

  std::uint32_t bits_high_;
  std::uint32_t corr_bits_ = 0;
  std::uint32_t corr_range_ = 0;
  std::int32_t corr_min_ = 0;
  std::int32_t corr_max_ = 0;
  std::uint32_t k_ = 0;
  std::vector<SymbolModel> bits_models_;
  BitModel corrector0_;
  std::vector<SymbolModel> correctors_;
};

}  // namespace relief::laz
