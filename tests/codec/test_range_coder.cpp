// The binary range coder's models and integer codes (lib/codec/range_coder.h)
// against plain restatements of format-spec/chunk.md: the coder may be made
// faster, never different. Each restatement here is the slow, obvious form.

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <random>
#include <utility>
#include <vector>

#include "codec/range_coder.h"

namespace {

using relief::codec::BitModel;
using relief::codec::RangeDecoder;
using relief::codec::RangeEncoder;
using relief::codec::UIntModel;

// One estimate's update, as the format states it: the rate 2^-shift with
// shift = min(seen + 1, limit); a 1 moves p down by p >> shift, a 0 up by
// (2^16 - 1 - p) >> shift.
std::uint16_t spec_update(std::uint16_t p, int seen, int limit, int bit) {
  const int shift = seen < limit ? seen + 1 : limit;
  return bit ? static_cast<std::uint16_t>(p - (p >> shift))
             : static_cast<std::uint16_t>(p + ((relief::codec::kProbOne - 1 - p) >> shift));
}

// The Exp-Golomb code of v with the coder's own decisions, bit by bit in
// 128-bit arithmetic (v + 1 reaches 2^64).
void spec_encode_uint(RangeEncoder& enc, UIntModel& m, std::uint64_t v) {
  __extension__ typedef unsigned __int128 u128;
  const u128 w = static_cast<u128>(v) + 1;
  int n = -1;
  for (u128 t = w; t != 0; t >>= 1) ++n;
  for (int i = 0; i < n; ++i) enc.encode(m.prefix[i], 1);
  if (n < relief::codec::kMaxPrefix) enc.encode(m.prefix[n], 0);
  for (int b = n - 1; b >= 0; --b) {
    const int bit = static_cast<int>((w >> b) & 1);
    const int pos = n - 1 - b;
    if (pos < relief::codec::kModelledSuffixBits) {
      enc.encode(m.suffix[n][pos], bit);
    } else {
      enc.encode_raw(bit);
    }
  }
}

std::vector<std::uint64_t> edge_and_random_values() {
  std::vector<std::uint64_t> v = {0, 1, 2, 3, 7, 8, ~std::uint64_t{0}, ~std::uint64_t{0} - 1, std::uint64_t{1} << 63};
  for (int b = 1; b < 64; ++b) {
    v.push_back((std::uint64_t{1} << b) - 1);
    v.push_back(std::uint64_t{1} << b);
    v.push_back((std::uint64_t{1} << b) + 1);
  }
  std::mt19937_64 rng(4242);
  for (int i = 0; i < 2000; ++i) v.push_back(rng() >> (rng() % 64));
  return v;
}

}  // namespace

TEST_CASE("BitModel adapts as the format states, for every state and bit", "[coders][range]") {
  for (int seen = 0; seen <= relief::codec::kSlowShift; ++seen) {
    for (std::uint32_t p = 0; p < relief::codec::kProbOne; ++p) {
      for (const int bit : {0, 1}) {
        BitModel m;
        m.fast = static_cast<std::uint16_t>(p);
        m.slow = static_cast<std::uint16_t>(relief::codec::kProbOne - 1 - p);
        m.seen = static_cast<std::uint8_t>(seen);
        m.update(bit);
        const std::uint16_t fast = spec_update(static_cast<std::uint16_t>(p), seen, relief::codec::kFastShift, bit);
        const std::uint16_t slow = spec_update(static_cast<std::uint16_t>(relief::codec::kProbOne - 1 - p), seen,
                                               relief::codec::kSlowShift, bit);
        if (m.fast != fast || m.slow != slow || m.seen != std::min(seen + 1, relief::codec::kSlowShift)) {
          FAIL("seen " << seen << " p " << p << " bit " << bit << ": fast " << m.fast << " (spec " << fast
                       << "), slow " << m.slow << " (spec " << slow << "), seen " << int{m.seen});
        }
      }
    }
  }
}

TEST_CASE("no sequence of bits takes a BitModel's probability below kProbMin", "[coders][range]") {
  // p0() clamps only from above; this is why it may. Each estimate adapts on
  // its own, so explore the states (value, seen) each can reach from the
  // initial one and take the smallest values.
  const auto smallest_reachable = [](int limit) {
    std::vector<std::uint8_t> seen_state(std::size_t{relief::codec::kProbOne} * (relief::codec::kSlowShift + 1), 0);
    std::vector<std::pair<std::uint16_t, int>> stack = {{relief::codec::kProbOne / 2, 0}};
    std::uint32_t smallest = relief::codec::kProbOne;
    while (!stack.empty()) {
      const auto [p, seen] = stack.back();
      stack.pop_back();
      std::uint8_t& mark = seen_state[static_cast<std::size_t>(seen) * relief::codec::kProbOne + p];
      if (mark != 0) continue;
      mark = 1;
      smallest = std::min<std::uint32_t>(smallest, p);
      for (const int bit : {0, 1}) {
        stack.emplace_back(spec_update(p, seen, limit, bit), std::min(seen + 1, relief::codec::kSlowShift));
      }
    }
    return smallest;
  };
  const std::uint32_t fast = smallest_reachable(relief::codec::kFastShift);
  const std::uint32_t slow = smallest_reachable(relief::codec::kSlowShift);
  INFO("smallest fast " << fast << ", smallest slow " << slow);
  CHECK((fast + slow) / 2 >= relief::codec::kProbMin);
  // And the model agrees: p0() of the lowest state is the unclamped mean.
  BitModel m;
  for (int i = 0; i < 4000; ++i) m.update(1);
  CHECK(m.fast == fast);
  CHECK(m.slow == slow);
  CHECK(m.p0() == (fast + slow) / 2);
}

TEST_CASE("encode_uint writes the format's Exp-Golomb code and decode_uint reads it back", "[coders][range]") {
  const std::vector<std::uint64_t> values = edge_and_random_values();
  RangeEncoder fast, spec;
  auto m_fast = std::make_unique<UIntModel>();
  auto m_spec = std::make_unique<UIntModel>();
  for (const std::uint64_t v : values) {
    relief::codec::encode_uint(fast, *m_fast, v);
    spec_encode_uint(spec, *m_spec, v);
  }
  const std::vector<std::uint8_t> stream = fast.finish();
  CHECK(stream == spec.finish());
  RangeDecoder dec(stream);
  auto m = std::make_unique<UIntModel>();
  for (const std::uint64_t v : values) {
    std::uint64_t got = 0;
    REQUIRE(relief::codec::decode_uint(dec, *m, got));
    REQUIRE(got == v);
  }
  CHECK(dec.overrun() == 0);
}

TEST_CASE("decode_uint refuses a code wider than 64 bits", "[coders][range]") {
  // 64 prefix ones (no terminating zero), then suffix bits not all zero:
  // 2^64 + 1 + ... - 1 does not fit a u64.
  RangeEncoder enc;
  auto m = std::make_unique<UIntModel>();
  for (int i = 0; i < relief::codec::kMaxPrefix; ++i) enc.encode(m->prefix[i], 1);
  for (int pos = 0; pos < 64; ++pos) {
    if (pos < relief::codec::kModelledSuffixBits) {
      enc.encode(m->suffix[relief::codec::kMaxPrefix][pos], pos == 63 ? 1 : 0);
    } else {
      enc.encode_raw(pos == 63 ? 1 : 0);
    }
  }
  const std::vector<std::uint8_t> stream = enc.finish();
  RangeDecoder dec(stream);
  auto d = std::make_unique<UIntModel>();
  std::uint64_t v = 0;
  CHECK_FALSE(relief::codec::decode_uint(dec, *d, v));
}
