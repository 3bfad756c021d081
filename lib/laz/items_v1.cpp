// LASzip item decompressors, version 1 (what LASzip 1.x wrote). Each read()
// takes the same decisions in the same order as LASzip's
// LASreadItemCompressed_*_v1; 32-bit arithmetic wraps as LASzip's does on
// every platform it runs on (done here in unsigned types).
#include <algorithm>
#include <cstring>

#include "laz/items.h"
#include "laz/tables.h"

namespace relief::laz {

using namespace p10;

namespace {

std::int32_t median3(const std::array<std::int32_t, 3>& v) {
  return std::max(std::min(v[0], v[1]), std::min(std::max(v[0], v[1]), v[2]));
}

std::uint32_t min19(std::uint32_t k) { return k < 19 ? k : 19; }

}  // namespace

// ---------------------------------------------------------------- POINT10

void Point10V1::init(const std::uint8_t* item) {
  last_dx_ = {0, 0, 0};
  last_dy_ = {0, 0, 0};
  next_ = 0;
  ic_dx_.init();
  ic_dy_.init();
  ic_z_.init();
  ic_intensity_.init();
  ic_scan_angle_.init();
  ic_point_source_.init();
  changed_values_.init();
  init_existing(bit_byte_);
  init_existing(classification_);
  init_existing(user_data_);
  // Unlike version 2, the first point's intensity is the prediction.
  std::memcpy(last_.data(), item, kPoint10Size);
}

void Point10V1::read(ArithmeticDecoder& dec, std::uint8_t* item) {
  std::uint8_t* last = last_.data();
  // Coordinates first: x against the median of the last three x steps, y
  // likewise in a context of x's corrector size, z against the last z in a
  // context of the mean of both sizes.
  const std::int32_t dx = ic_dx_.decompress(dec, median3(last_dx_));
  put_i32(last + kX, wrap_add(get_i32(last + kX), dx));
  std::uint32_t k = ic_dx_.k();
  const std::int32_t dy = ic_dy_.decompress(dec, median3(last_dy_), min19(k));
  put_i32(last + kY, wrap_add(get_i32(last + kY), dy));
  k = (k + ic_dy_.k()) / 2;
  put_i32(last + kZ, ic_z_.decompress(dec, get_i32(last + kZ), min19(k)));

  // Then which other fields changed (bit 5 intensity, 4 the flag byte,
  // 3 classification, 2 scan angle, 1 user data, 0 point source).
  const std::uint32_t changed = dec.decode_symbol(changed_values_);
  if (changed & 32) {
    put_u16(last + kIntensity, static_cast<std::uint32_t>(ic_intensity_.decompress(dec, get_u16(last + kIntensity))));
  }
  if (changed & 16) {
    last[kBits] = static_cast<std::uint8_t>(dec.decode_symbol(model_for(bit_byte_[last[kBits]], 256)));
  }
  if (changed & 8) {
    last[kClass] = static_cast<std::uint8_t>(dec.decode_symbol(model_for(classification_[last[kClass]], 256)));
  }
  if (changed & 4) {
    // The scan angle's byte, unsigned, in a context of "coordinates barely moved".
    last[kAngle] = static_cast<std::uint8_t>(ic_scan_angle_.decompress(dec, last[kAngle], k < 3 ? 1 : 0));
  }
  if (changed & 2) {
    last[kUser] = static_cast<std::uint8_t>(dec.decode_symbol(model_for(user_data_[last[kUser]], 256)));
  }
  if (changed & 1) {
    put_u16(last + kSource,
            static_cast<std::uint32_t>(ic_point_source_.decompress(dec, get_u16(last + kSource))));
  }
  last_dx_[next_] = dx;
  last_dy_[next_] = dy;
  next_ = next_ == 2 ? 0 : next_ + 1;
  std::memcpy(item, last, kPoint10Size);
}

// ---------------------------------------------------------------- GPSTIME11

void GpsTime11V1::init(const std::uint8_t* item) {
  multi_.init();
  zero_diff_.init();
  ic_.init();
  last_ = get_u64(item);
  last_diff_ = 0;
  extreme_ = 0;
}

// The time's bits as a 64-bit integer, stepped by 32-bit differences: after
// a zero difference one of the zero-difference model's three cases, else a
// multiple of the last difference (LASzip's writer picks the rounded ratio,
// clamped to 0 .. kMultiMax - 3) with contexts by the multiplier's size. A
// multiplier of 0 (a much smaller step) or the largest one counts as
// extreme: four in a row make the step the new reference.
void GpsTime11V1::read(ArithmeticDecoder& dec, std::uint8_t* item) {
  auto step = [&](std::int32_t diff) {
    last_ += static_cast<std::uint64_t>(static_cast<std::int64_t>(diff));
  };
  auto extreme = [&](std::int32_t diff) {
    if (++extreme_ > 3) {
      last_diff_ = diff;
      extreme_ = 0;
    }
  };
  auto full = [&] {
    const std::uint64_t low = dec.read_int();
    const std::uint64_t high = dec.read_int();
    last_ = (high << 32) | low;
  };
  if (last_diff_ == 0) {
    const std::uint32_t sym = dec.decode_symbol(zero_diff_);
    if (sym == 1) {
      last_diff_ = ic_.decompress(dec, 0, 0);
      step(last_diff_);
    } else if (sym == 2) {
      full();
    }
  } else {
    const std::uint32_t multi = dec.decode_symbol(multi_);
    if (multi == 1) {
      const std::int32_t diff = ic_.decompress(dec, last_diff_, 1);
      last_diff_ = diff;
      extreme_ = 0;
      step(diff);
    } else if (multi == 0) {
      const std::int32_t diff = ic_.decompress(dec, last_diff_ / 4, 2);  // truncates toward zero, as LASzip
      extreme(diff);
      step(diff);
    } else if (multi < kMultiFull) {
      const std::uint32_t context = multi < 10 ? 3 : (multi < 50 ? 4 : 5);
      const std::int32_t diff =
          ic_.decompress(dec, wrap_mul(static_cast<std::int32_t>(multi), last_diff_), context);
      if (multi == kMultiFull - 1) extreme(diff);
      step(diff);
    } else if (multi == kMultiFull) {
      full();
    }
    // kMultiUnchanged: the time repeats.
  }
  put_u64(item, last_);
}

// ---------------------------------------------------------------- RGB12, BYTE

void Rgb12V1::init(const std::uint8_t* item) {
  byte_used_.init();
  ic_.init();
  for (int i = 0; i < 3; ++i) last_[i] = get_u16(item + 2 * i);
}

// Bits 0-5 of the first symbol say which of the six bytes (low then high of
// red, green, blue) changed; each changed byte is coded against its old
// value in its own context.
void Rgb12V1::read(ArithmeticDecoder& dec, std::uint8_t* item) {
  const std::uint32_t sym = dec.decode_symbol(byte_used_);
  for (std::uint32_t c = 0; c < 3; ++c) {
    std::uint32_t low = last_[c] & 0xFFu, high = last_[c] >> 8;
    if (sym & (1u << (2 * c))) low = static_cast<std::uint32_t>(ic_.decompress(dec, static_cast<std::int32_t>(low), 2 * c));
    if (sym & (1u << (2 * c + 1))) {
      high = static_cast<std::uint32_t>(ic_.decompress(dec, static_cast<std::int32_t>(high), 2 * c + 1));
    }
    last_[c] = static_cast<std::uint16_t>(low | (high << 8));
    put_u16(item + 2 * c, last_[c]);
  }
}

void ByteV1::init(const std::uint8_t* item) {
  ic_.init();
  std::memcpy(last_.data(), item, last_.size());
}

void ByteV1::read(ArithmeticDecoder& dec, std::uint8_t* item) {
  for (std::size_t i = 0; i < last_.size(); ++i) {
    last_[i] = static_cast<std::uint8_t>(
        ic_.decompress(dec, last_[i], static_cast<std::uint32_t>(i)));
  }
  std::memcpy(item, last_.data(), last_.size());
}

// ---------------------------------------------------------------- WAVEPACKET13

void WavePacket13V1::init(const std::uint8_t* item) {
  last_diff_ = 0;
  last_choice_ = 0;
  packet_index_.init();
  for (auto& m : offset_diff_) m.init();
  ic_offset_diff_.init();
  ic_packet_size_.init();
  ic_return_point_.init();
  ic_xyz_.init();
  std::memcpy(last_.data(), item + 1, last_.size());
}

void WavePacket13V1::read(ArithmeticDecoder& dec, std::uint8_t* item) {
  item[0] = static_cast<std::uint8_t>(dec.decode_symbol(packet_index_));
  std::uint8_t* out = item + 1;
  const std::uint8_t* last = last_.data();
  // Byte 0 the offset (64 bits), 8 the packet size, 12 the return point,
  // 16, 20, 24 the x, y, z step.
  const std::uint64_t last_offset = get_u64(last);
  const std::uint32_t last_size = get_u32(last + 8);
  last_choice_ = dec.decode_symbol(offset_diff_[last_choice_]);
  std::uint64_t offset = last_offset;
  if (last_choice_ == 1) {
    offset = last_offset + last_size;
  } else if (last_choice_ == 2) {
    last_diff_ = ic_offset_diff_.decompress(dec, last_diff_);
    offset = last_offset + static_cast<std::uint64_t>(static_cast<std::int64_t>(last_diff_));
  } else if (last_choice_ == 3) {
    const std::uint64_t low = dec.read_int();
    offset = (static_cast<std::uint64_t>(dec.read_int()) << 32) | low;
  }
  put_u64(out, offset);
  put_i32(out + 8, ic_packet_size_.decompress(dec, static_cast<std::int32_t>(last_size)));
  put_i32(out + 12, ic_return_point_.decompress(dec, get_i32(last + 12)));
  for (std::uint32_t a = 0; a < 3; ++a) {
    put_i32(out + 16 + 4 * a, ic_xyz_.decompress(dec, get_i32(last + 16 + 4 * a), a));
  }
  std::memcpy(last_.data(), out, last_.size());
}

}  // namespace relief::laz
