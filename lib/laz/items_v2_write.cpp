// LASzip item compressors, version 2, and the pieces version 3 shares: the
// mirror of items_v2.cpp, on the same state, writing what LASzip's writer
// writes byte for byte.
#include <cmath>
#include <cstring>

#include "laz/items.h"
#include "laz/tables.h"

namespace relief::laz {

using namespace p10;

std::uint32_t encode_rgb(ArithmeticEncoder& enc, RgbModels& m, const std::uint16_t* last, const std::uint16_t* c) {
  const auto lo = [](std::uint16_t v) { return static_cast<int>(v & 0xFF); };
  const auto hi = [](std::uint16_t v) { return static_cast<int>(v >> 8); };
  std::uint32_t sym = 0;
  sym |= static_cast<std::uint32_t>(lo(last[0]) != lo(c[0])) << 0;
  sym |= static_cast<std::uint32_t>(hi(last[0]) != hi(c[0])) << 1;
  sym |= static_cast<std::uint32_t>(lo(last[1]) != lo(c[1])) << 2;
  sym |= static_cast<std::uint32_t>(hi(last[1]) != hi(c[1])) << 3;
  sym |= static_cast<std::uint32_t>(lo(last[2]) != lo(c[2])) << 4;
  sym |= static_cast<std::uint32_t>(hi(last[2]) != hi(c[2])) << 5;
  // Bit 6: the channels differ (else green and blue repeat red).
  sym |= static_cast<std::uint32_t>(lo(c[0]) != lo(c[1]) || lo(c[0]) != lo(c[2]) || hi(c[0]) != hi(c[1]) ||
                                    hi(c[0]) != hi(c[2]))
         << 6;
  enc.encode_symbol(m.byte_used, sym);
  int diff_l = 0, diff_h = 0;
  if (sym & 1) {
    diff_l = lo(c[0]) - lo(last[0]);
    enc.encode_symbol(m.diff[0], fold8(diff_l));
  }
  if (sym & 2) {
    diff_h = hi(c[0]) - hi(last[0]);
    enc.encode_symbol(m.diff[1], fold8(diff_h));
  }
  if (sym & (1 << 6)) {
    if (sym & (1 << 2)) enc.encode_symbol(m.diff[2], fold8(lo(c[1]) - clamp8(diff_l + lo(last[1]))));
    if (sym & (1 << 4)) {
      diff_l = (diff_l + lo(c[1]) - lo(last[1])) / 2;  // truncates toward zero, as LASzip
      enc.encode_symbol(m.diff[4], fold8(lo(c[2]) - clamp8(diff_l + lo(last[2]))));
    }
    if (sym & (1 << 3)) enc.encode_symbol(m.diff[3], fold8(hi(c[1]) - clamp8(diff_h + hi(last[1]))));
    if (sym & (1 << 5)) {
      diff_h = (diff_h + hi(c[1]) - hi(last[1])) / 2;
      enc.encode_symbol(m.diff[5], fold8(hi(c[2]) - clamp8(diff_h + hi(last[2]))));
    }
  }
  return sym;
}

// ---------------------------------------------------------------- GPS time

namespace {

bool fits32(std::int64_t d) { return d == static_cast<std::int32_t>(d); }

// LASzip's I32_QUANTIZE of the float ratio of two time differences. A ratio
// outside the int32 range converts to INT32_MIN, what x86's conversion (and
// so LASzip there) gives, instead of undefined behaviour; any multiplier the
// writer picks decodes, this one keeps the bytes LASzip's.
std::int32_t quantize_ratio(float ratio) {
  const float r = ratio >= 0 ? ratio + 0.5f : ratio - 0.5f;
  if (!(r > -2147483648.0f && r < 2147483648.0f)) return INT32_MIN;
  return static_cast<std::int32_t>(r);
}

// Codes the 32-bit difference `d` of a sequence whose last difference is
// not zero, choosing the multiplier as LASzip does.
void gps_encode_multiple(ArithmeticEncoder& enc, GpsTimeState& s, std::int32_t d) {
  std::int32_t& last_diff = s.diff[s.last];
  std::int32_t& extreme = s.extreme[s.last];
  auto extreme_step = [&] {
    if (++extreme > 3) {
      last_diff = d;
      extreme = 0;
    }
  };
  const std::int32_t multi = quantize_ratio(static_cast<float>(d) / static_cast<float>(last_diff));
  if (multi == 1) {
    enc.encode_symbol(s.multi, 1);
    s.ic.compress(enc, last_diff, d, 1);
    extreme = 0;
  } else if (multi > 0) {
    if (multi < kGpsMulti) {
      enc.encode_symbol(s.multi, static_cast<std::uint32_t>(multi));
      s.ic.compress(enc, wrap_mul(multi, last_diff), d, multi < 10 ? 2 : 3);
    } else {
      enc.encode_symbol(s.multi, kGpsMulti);
      s.ic.compress(enc, wrap_mul(kGpsMulti, last_diff), d, 4);
      extreme_step();
    }
  } else if (multi < 0) {
    if (multi > kGpsMultiMinus) {
      enc.encode_symbol(s.multi, static_cast<std::uint32_t>(kGpsMulti - multi));
      s.ic.compress(enc, wrap_mul(multi, last_diff), d, 5);
    } else {
      enc.encode_symbol(s.multi, static_cast<std::uint32_t>(kGpsMulti - kGpsMultiMinus));
      s.ic.compress(enc, wrap_mul(kGpsMultiMinus, last_diff), d, 6);
      extreme_step();
    }
  } else {
    enc.encode_symbol(s.multi, 0);
    s.ic.compress(enc, 0, d, 7);
    extreme_step();
  }
}

}  // namespace

void gps_encode(ArithmeticEncoder& enc, GpsTimeState& s, std::uint64_t t, const GpsCodes& codes) {
  // At most one switch to another sequence, after which `t` fits there.
  for (int hop = 0; hop < 2; ++hop) {
    const bool zero = s.diff[s.last] == 0;
    SymbolModel& model = zero ? s.zero_diff : s.multi;
    if (codes.has_unchanged && t == s.time[s.last]) {
      enc.encode_symbol(model, zero ? codes.zero_unchanged : codes.multi_unchanged);
      return;
    }
    const auto d64 = static_cast<std::int64_t>(t - s.time[s.last]);
    if (fits32(d64)) {
      const auto d = static_cast<std::int32_t>(d64);
      if (zero) {
        enc.encode_symbol(model, codes.zero_small);
        s.ic.compress(enc, 0, d, 0);
        s.diff[s.last] = d;
        s.extreme[s.last] = 0;
      } else {
        gps_encode_multiple(enc, s, d);
      }
      s.time[s.last] = t;
      return;
    }
    if (hop == 0) {
      bool switched = false;
      for (std::uint32_t i = 1; i < 4 && !switched; ++i) {
        if (fits32(static_cast<std::int64_t>(t - s.time[(s.last + i) & 3]))) {
          enc.encode_symbol(model, (zero ? codes.zero_full : codes.multi_full) + i);
          s.last = (s.last + i) & 3;
          switched = true;
        }
      }
      if (switched) continue;
    }
    // A new sequence: its upper 32 bits against the current one's, then the
    // lower 32 raw.
    enc.encode_symbol(model, zero ? codes.zero_full : codes.multi_full);
    s.ic.compress(enc, static_cast<std::int32_t>(s.time[s.last] >> 32), static_cast<std::int32_t>(t >> 32), 8);
    enc.write_int(static_cast<std::uint32_t>(t));
    s.next = (s.next + 1) & 3;
    s.last = s.next;
    s.diff[s.last] = 0;
    s.extreme[s.last] = 0;
    s.time[s.last] = t;
    return;
  }
}

// ---------------------------------------------------------------- POINT10

void Point10V2::write(ArithmeticEncoder& enc, const std::uint8_t* item) {
  const std::uint32_t r = item[kBits] & 0x7;
  const std::uint32_t n = (item[kBits] >> 3) & 0x7;
  const std::uint32_t m = kNumberReturnMap[n][r];
  const std::uint32_t l = kNumberReturnLevel[n][r];
  const std::uint16_t intensity = get_u16(item + kIntensity);
  const std::uint16_t source = get_u16(item + kSource);
  const std::uint32_t changed = (static_cast<std::uint32_t>(last_[kBits] != item[kBits]) << 5) |
                                (static_cast<std::uint32_t>(last_intensity_[m] != intensity) << 4) |
                                (static_cast<std::uint32_t>(last_[kClass] != item[kClass]) << 3) |
                                (static_cast<std::uint32_t>(last_[kAngle] != item[kAngle]) << 2) |
                                (static_cast<std::uint32_t>(last_[kUser] != item[kUser]) << 1) |
                                static_cast<std::uint32_t>(get_u16(last_.data() + kSource) != source);
  enc.encode_symbol(changed_values_, changed);
  if (changed & 32) enc.encode_symbol(model_for(bit_byte_[last_[kBits]], 256), item[kBits]);
  if (changed & 16) {
    ic_intensity_.compress(enc, last_intensity_[m], intensity, m < 3 ? m : 3);
    last_intensity_[m] = intensity;
  }
  if (changed & 8) enc.encode_symbol(model_for(classification_[last_[kClass]], 256), item[kClass]);
  if (changed & 4) enc.encode_symbol(scan_angle_[(item[kBits] >> 6) & 1], fold8(item[kAngle] - last_[kAngle]));
  if (changed & 2) enc.encode_symbol(model_for(user_data_[last_[kUser]], 256), item[kUser]);
  if (changed & 1) ic_point_source_.compress(enc, get_u16(last_.data() + kSource), source);

  std::int32_t diff = wrap_sub(get_i32(item + kX), get_i32(last_.data() + kX));
  ic_dx_.compress(enc, last_x_diff_[m].get(), diff, n == 1);
  last_x_diff_[m].add(diff);
  std::uint32_t k_bits = ic_dx_.k();
  diff = wrap_sub(get_i32(item + kY), get_i32(last_.data() + kY));
  ic_dy_.compress(enc, last_y_diff_[m].get(), diff, (n == 1) + (k_bits < 20 ? zero_bit0(k_bits) : 20));
  last_y_diff_[m].add(diff);
  k_bits = (ic_dx_.k() + ic_dy_.k()) / 2;
  const std::int32_t z = get_i32(item + kZ);
  ic_z_.compress(enc, last_height_[l], z, (n == 1) + (k_bits < 18 ? zero_bit0(k_bits) : 18));
  last_height_[l] = z;
  std::memcpy(last_.data(), item, kPoint10Size);
}

// ---------------------------------------------------------------- GPSTIME11, RGB12, BYTE

void GpsTime11V2::write(ArithmeticEncoder& enc, const std::uint8_t* item) {
  gps_encode(enc, s_, get_u64(item), kGpsCodesV2);
}

void Rgb12V2::write(ArithmeticEncoder& enc, const std::uint8_t* item) {
  const std::uint16_t c[3] = {get_u16(item), get_u16(item + 2), get_u16(item + 4)};
  encode_rgb(enc, m_, last_.data(), c);
  for (int i = 0; i < 3; ++i) last_[i] = c[i];
}

void ByteV2::write(ArithmeticEncoder& enc, const std::uint8_t* item) {
  for (std::size_t i = 0; i < last_.size(); ++i) {
    enc.encode_symbol(models_[i], fold8(static_cast<int>(item[i]) - static_cast<int>(last_[i])));
    last_[i] = item[i];
  }
}

}  // namespace relief::laz
