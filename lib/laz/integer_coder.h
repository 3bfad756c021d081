// LASzip's IntegerCompressor: integers coded as a corrector against a
// prediction. The corrector's bit length k is a symbol (one model per
// context), then its value is a symbol (k <= bits_high) or a symbol for the
// high bits plus raw low bits. One class holds the models and codes both
// ways, so an item's reader and writer share their state type and cannot
// drift apart. Internal to lib/laz.
#pragma once

#include <cstdint>
#include <vector>

#include "laz/arithmetic_decoder.h"
#include "laz/arithmetic_encoder.h"

namespace relief::laz {

class IntegerCoder {
 public:
  explicit IntegerCoder(std::uint32_t bits = 16, std::uint32_t contexts = 1, std::uint32_t bits_high = 8)
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
    bits_models_.reserve(contexts);
    for (std::uint32_t i = 0; i < contexts; ++i) bits_models_.emplace_back(corr_bits_ + 1);
    correctors_.reserve(corr_bits_);
    for (std::uint32_t i = 1; i <= corr_bits_; ++i) {
      correctors_.emplace_back(i <= bits_high_ ? (1u << i) : (1u << bits_high_));
    }
  }
  void init() {
    for (auto& m : bits_models_) m.init();
    corrector0_.init();
    for (auto& m : correctors_) m.init();
  }
  // Bit length of the last corrector (LASzip's getK()), which other values
  // use as context.
  std::uint32_t k() const { return k_; }

  // Returns pred + corrector, wrapped into the corrector range (mod 2^32
  // for 32-bit values).
  std::int32_t decompress(ArithmeticDecoder& dec, std::int32_t pred, std::uint32_t context = 0) {
    const std::uint32_t c = read_corrector(dec, bits_models_[context]);
    std::uint32_t real = static_cast<std::uint32_t>(pred) + c;
    if (corr_range_ != 0) {
      if (static_cast<std::int32_t>(real) < 0) {
        real += corr_range_;
      } else if (real >= corr_range_) {
        real -= corr_range_;
      }
    }
    return static_cast<std::int32_t>(real);
  }

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
  std::uint32_t read_corrector(ArithmeticDecoder& dec, SymbolModel& bits_model) {
    k_ = dec.decode_symbol(bits_model);
    if (k_ == 0) return dec.decode_bit(corrector0_);
    if (k_ >= 32) return static_cast<std::uint32_t>(corr_min_);
    std::uint32_t c;
    if (k_ <= bits_high_) {
      c = dec.decode_symbol(correctors_[k_ - 1]);
    } else {
      const std::uint32_t k1 = k_ - bits_high_;
      c = dec.decode_symbol(correctors_[k_ - 1]);
      const std::uint32_t low = dec.read_bits(k1);
      c = (c << k1) | low;
    }
    // c in [0, 2^k) maps to [-(2^k - 1), -2^(k-1)] and [2^(k-1) + 1, 2^k].
    if (c >= (1u << (k_ - 1))) return c + 1;
    return c - ((1u << k_) - 1);
  }

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
