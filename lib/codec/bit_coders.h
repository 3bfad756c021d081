// Bit coders with one interface, so that a section's encoder and decoder run
// the same routine (a template over the coder) and cannot drift apart: the
// encoder passes the true value and gets it back, the decoder ignores what it
// is given and returns what it read. Internal to the codec.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "codec/range_coder.h"

namespace relief::codec {

class EncCoder {
 public:
  static constexpr bool kEncoding = true;
  explicit EncCoder(RangeEncoder& e) : e_(e) {}
  int bit(BitModel& m, int b) {
    e_.encode(m, b);
    return b;
  }
  bool sint(SIntModel& m, std::int64_t& v) {
    encode_sint(e_, m, v);
    return true;
  }
  bool uint(UIntModel& m, std::uint64_t& v) {
    encode_uint(e_, m, v);
    return true;
  }
  bool ok() const { return true; }

 private:
  RangeEncoder& e_;
};

class DecCoder {
 public:
  static constexpr bool kEncoding = false;
  explicit DecCoder(RangeDecoder& d) : d_(d) {}
  int bit(BitModel& m, int) { return d_.decode(m); }
  bool sint(SIntModel& m, std::int64_t& v) { return decode_sint(d_, m, v); }
  bool uint(UIntModel& m, std::uint64_t& v) { return decode_uint(d_, m, v); }
  bool ok() const { return !d_.exhausted(); }

 private:
  RangeDecoder& d_;
};

// Model sets of type M per context, each made when its context is first
// used: a small chunk touches few of them, and none costs its size until then.
template <typename M>
class LazyModels {
 public:
  explicit LazyModels(std::size_t count) : models_(count) {}
  M& operator[](std::size_t i) {
    std::unique_ptr<M>& p = models_[i];
    if (!p) p = std::make_unique<M>();
    return *p;
  }

 private:
  std::vector<std::unique_ptr<M>> models_;
};

}  // namespace relief::codec
