// LASzip item decompressors, version 2, and the pieces version 3 shares
// (the compressors are in items_v2_write.cpp).
#include <cstring>

#include "laz/items.h"
#include "laz/tables.h"

namespace relief::laz {

void Median5::add(std::int32_t x) {
  auto& v = v_;
  if (high_) {
    if (x < v[2]) {
      v[4] = v[3];
      v[3] = v[2];
      if (x < v[0]) {
        v[2] = v[1];
        v[1] = v[0];
        v[0] = x;
      } else if (x < v[1]) {
        v[2] = v[1];
        v[1] = x;
      } else {
        v[2] = x;
      }
    } else {
      if (x < v[3]) {
        v[4] = v[3];
        v[3] = x;
      } else {
        v[4] = x;
      }
      high_ = false;
    }
  } else {
    if (v[2] < x) {
      v[0] = v[1];
      v[1] = v[2];
      if (v[4] < x) {
        v[2] = v[3];
        v[3] = v[4];
        v[4] = x;
      } else if (v[3] < x) {
        v[2] = v[3];
        v[3] = x;
      } else {
        v[2] = x;
      }
    } else {
      if (v[1] < x) {
        v[0] = v[1];
        v[1] = x;
      } else {
        v[0] = x;
      }
      high_ = true;
    }
  }
}

void decode_rgb(ArithmeticDecoder& dec, RgbModels& m, const std::uint16_t* last, std::uint16_t* out) {
  const std::uint32_t sym = dec.decode_symbol(m.byte_used);
  std::uint16_t r, g, b;
  if (sym & 1) {
    r = fold8(static_cast<int>(dec.decode_symbol(m.diff[0])) + (last[0] & 0xFF));
  } else {
    r = last[0] & 0xFF;
  }
  if (sym & 2) {
    r |= static_cast<std::uint16_t>(fold8(static_cast<int>(dec.decode_symbol(m.diff[1])) + (last[0] >> 8)) << 8);
  } else {
    r |= last[0] & 0xFF00;
  }
  if (sym & (1 << 6)) {
    int diff = (r & 0xFF) - (last[0] & 0xFF);
    if (sym & (1 << 2)) {
      g = fold8(static_cast<int>(dec.decode_symbol(m.diff[2])) + clamp8(diff + (last[1] & 0xFF)));
    } else {
      g = last[1] & 0xFF;
    }
    if (sym & (1 << 4)) {
      const int corr = static_cast<int>(dec.decode_symbol(m.diff[4]));
      diff = (diff + ((g & 0xFF) - (last[1] & 0xFF))) / 2;  // truncates toward zero, as LASzip
      b = fold8(corr + clamp8(diff + (last[2] & 0xFF)));
    } else {
      b = last[2] & 0xFF;
    }
    diff = (r >> 8) - (last[0] >> 8);
    if (sym & (1 << 3)) {
      g |= static_cast<std::uint16_t>(
          fold8(static_cast<int>(dec.decode_symbol(m.diff[3])) + clamp8(diff + (last[1] >> 8))) << 8);
    } else {
      g |= last[1] & 0xFF00;
    }
    if (sym & (1 << 5)) {
      const int corr = static_cast<int>(dec.decode_symbol(m.diff[5]));
      diff = (diff + ((g >> 8) - (last[1] >> 8))) / 2;
      b |= static_cast<std::uint16_t>(fold8(corr + clamp8(diff + (last[2] >> 8))) << 8);
    } else {
      b |= last[2] & 0xFF00;
    }
  } else {
    g = r;
    b = r;
  }
  out[0] = r;
  out[1] = g;
  out[2] = b;
}

void GpsTimeState::init(std::uint64_t first) {
  multi.init();
  zero_diff.init();
  ic.init();
  last = next = 0;
  diff = {0, 0, 0, 0};
  extreme = {0, 0, 0, 0};
  time = {first, 0, 0, 0};
}

// ---------------------------------------------------------------- POINT10

using namespace p10;

void Point10V2::init(const std::uint8_t* item) {
  for (int i = 0; i < 16; ++i) {
    last_x_diff_[i].init();
    last_y_diff_[i].init();
    last_intensity_[i] = 0;
    last_height_[i / 2] = 0;
  }
  changed_values_.init();
  ic_intensity_.init();
  scan_angle_[0].init();
  scan_angle_[1].init();
  ic_point_source_.init();
  for (int i = 0; i < 256; ++i) {
    if (bit_byte_[i]) bit_byte_[i]->init();
    if (classification_[i]) classification_[i]->init();
    if (user_data_[i]) user_data_[i]->init();
  }
  ic_dx_.init();
  ic_dy_.init();
  ic_z_.init();
  std::memcpy(last_.data(), item, kPoint10Size);
  // LASzip starts the intensity prediction from zero, not from the first point.
  last_[kIntensity] = 0;
  last_[kIntensity + 1] = 0;
}

void Point10V2::read(ArithmeticDecoder& dec, std::uint8_t* item) {
  std::uint8_t* last = last_.data();
  const std::uint32_t changed = dec.decode_symbol(changed_values_);
  std::uint32_t r, n, m, l;
  auto returns = [&] {
    r = last[kBits] & 0x7;
    n = (last[kBits] >> 3) & 0x7;
    m = kNumberReturnMap[n][r];
    l = kNumberReturnLevel[n][r];
  };
  if (changed != 0) {
    if (changed & 32) {
      SymbolModel& model = model_for(bit_byte_[last[kBits]], 256);
      last[kBits] = static_cast<std::uint8_t>(dec.decode_symbol(model));
    }
    returns();
    if (changed & 16) {
      const auto v = ic_intensity_.decompress(dec, last_intensity_[m], m < 3 ? m : 3);
      put_u16(last + kIntensity, static_cast<std::uint32_t>(v));
      last_intensity_[m] = static_cast<std::uint16_t>(v);
    } else {
      put_u16(last + kIntensity, last_intensity_[m]);
    }
    if (changed & 8) {
      SymbolModel& model = model_for(classification_[last[kClass]], 256);
      last[kClass] = static_cast<std::uint8_t>(dec.decode_symbol(model));
    }
    if (changed & 4) {
      const int v = static_cast<int>(dec.decode_symbol(scan_angle_[(last[kBits] >> 6) & 1]));
      last[kAngle] = fold8(v + last[kAngle]);
    }
    if (changed & 2) {
      SymbolModel& model = model_for(user_data_[last[kUser]], 256);
      last[kUser] = static_cast<std::uint8_t>(dec.decode_symbol(model));
    }
    if (changed & 1) {
      const auto v = ic_point_source_.decompress(dec, get_u16(last + kSource));
      put_u16(last + kSource, static_cast<std::uint32_t>(v));
    }
  } else {
    returns();
  }

  std::int32_t median = last_x_diff_[m].get();
  std::int32_t diff = ic_dx_.decompress(dec, median, n == 1);
  put_i32(last + kX, wrap_add(get_i32(last + kX), diff));
  last_x_diff_[m].add(diff);

  median = last_y_diff_[m].get();
  std::uint32_t k_bits = ic_dx_.k();
  diff = ic_dy_.decompress(dec, median, (n == 1) + (k_bits < 20 ? zero_bit0(k_bits) : 20));
  put_i32(last + kY, wrap_add(get_i32(last + kY), diff));
  last_y_diff_[m].add(diff);

  k_bits = (ic_dx_.k() + ic_dy_.k()) / 2;
  const std::int32_t z = ic_z_.decompress(dec, last_height_[l], (n == 1) + (k_bits < 18 ? zero_bit0(k_bits) : 18));
  put_i32(last + kZ, z);
  last_height_[l] = z;

  std::memcpy(item, last, kPoint10Size);
}

// ---------------------------------------------------------------- GPSTIME11

namespace {
constexpr std::uint32_t kGpsMultiUnchangedV2 = kGpsCodesV2.multi_unchanged;  // 511
constexpr std::uint32_t kGpsMultiCodeFullV2 = kGpsCodesV2.multi_full;         // 512
}  // namespace

void gps_decode_multiple(ArithmeticDecoder& dec, GpsTimeState& s, std::uint32_t multi_u) {
  const auto multi = static_cast<std::int32_t>(multi_u);
  std::int32_t& last_diff = s.diff[s.last];
  std::int32_t& extreme = s.extreme[s.last];
  std::int32_t d;
  if (multi == 0) {
    d = s.ic.decompress(dec, 0, 7);
    if (++extreme > 3) {
      last_diff = d;
      extreme = 0;
    }
  } else if (multi < kGpsMulti) {
    d = s.ic.decompress(dec, wrap_mul(multi, last_diff), multi < 10 ? 2 : 3);
  } else if (multi == kGpsMulti) {
    d = s.ic.decompress(dec, wrap_mul(kGpsMulti, last_diff), 4);
    if (++extreme > 3) {
      last_diff = d;
      extreme = 0;
    }
  } else {
    const std::int32_t back = kGpsMulti - multi;
    if (back > kGpsMultiMinus) {
      d = s.ic.decompress(dec, wrap_mul(back, last_diff), 5);
    } else {
      d = s.ic.decompress(dec, wrap_mul(kGpsMultiMinus, last_diff), 6);
      if (++extreme > 3) {
        last_diff = d;
        extreme = 0;
      }
    }
  }
  s.time[s.last] += static_cast<std::uint64_t>(static_cast<std::int64_t>(d));
}

void gps_decode_full(ArithmeticDecoder& dec, GpsTimeState& s) {
  s.next = (s.next + 1) & 3;
  const auto high = s.ic.decompress(dec, static_cast<std::int32_t>(s.time[s.last] >> 32), 8);
  std::uint64_t t = static_cast<std::uint64_t>(static_cast<std::int64_t>(high)) << 32;
  t |= dec.read_int();
  s.time[s.next] = t;
  s.last = s.next;
  s.diff[s.last] = 0;
  s.extreme[s.last] = 0;
}

void GpsTime11V2::init(const std::uint8_t* item) { s_.init(get_u64(item)); }

void GpsTime11V2::read(ArithmeticDecoder& dec, std::uint8_t* item) {
  for (int hop = 0; hop <= kMaxSequenceSwitches; ++hop) {
    if (s_.diff[s_.last] == 0) {
      const std::uint32_t multi = dec.decode_symbol(s_.zero_diff);
      if (multi == 1) {
        s_.diff[s_.last] = s_.ic.decompress(dec, 0, 0);
        s_.time[s_.last] += static_cast<std::uint64_t>(static_cast<std::int64_t>(s_.diff[s_.last]));
        s_.extreme[s_.last] = 0;
      } else if (multi == 2) {
        gps_decode_full(dec, s_);
      } else if (multi > 2) {
        s_.last = (s_.last + multi - 2) & 3;
        continue;
      }
    } else {
      const std::uint32_t multi = dec.decode_symbol(s_.multi);
      if (multi == 1) {
        s_.time[s_.last] +=
            static_cast<std::uint64_t>(static_cast<std::int64_t>(s_.ic.decompress(dec, s_.diff[s_.last], 1)));
        s_.extreme[s_.last] = 0;
      } else if (multi < kGpsMultiUnchangedV2) {
        gps_decode_multiple(dec, s_, multi);
      } else if (multi == kGpsMultiCodeFullV2) {
        gps_decode_full(dec, s_);
      } else if (multi > kGpsMultiCodeFullV2) {
        s_.last = (s_.last + multi - kGpsMultiCodeFullV2) & 3;
        continue;
      }
    }
    break;
  }
  put_u64(item, s_.time[s_.last]);
}

// ---------------------------------------------------------------- RGB12, BYTE

void Rgb12V2::init(const std::uint8_t* item) {
  m_.init();
  for (int i = 0; i < 3; ++i) last_[i] = get_u16(item + 2 * i);
}

void Rgb12V2::read(ArithmeticDecoder& dec, std::uint8_t* item) {
  std::uint16_t out[3];
  decode_rgb(dec, m_, last_.data(), out);
  for (int i = 0; i < 3; ++i) {
    put_u16(item + 2 * i, out[i]);
    last_[i] = out[i];
  }
}

ByteV2::ByteV2(std::size_t n) : last_(n) {
  models_.reserve(n);
  for (std::size_t i = 0; i < n; ++i) models_.emplace_back(256);
}

void ByteV2::init(const std::uint8_t* item) {
  for (auto& m : models_) m.init();
  std::memcpy(last_.data(), item, last_.size());
}

void ByteV2::read(ArithmeticDecoder& dec, std::uint8_t* item) {
  for (std::size_t i = 0; i < last_.size(); ++i) {
    item[i] = fold8(static_cast<int>(last_[i]) + static_cast<int>(dec.decode_symbol(models_[i])));
    last_[i] = item[i];
  }
}

}  // namespace relief::laz
