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

}  // namespace relief::laz
