// LAZ writing: LASzip's chunked pointwise compressor with the version 2
// items POINT10, GPSTIME11 and RGB12 (point formats 0-3), the chunk table
// and the LASzip VLR. Each item compressor mirrors its decompressor in items_v2.cpp.
#include <array>
#include <cstring>
#include <memory>

#include "laz/arithmetic_encoder.h"
#include "laz/items.h"
#include "laz/tables.h"
#include "relief/laz.h"

namespace relief::laz {

namespace {

constexpr std::uint16_t kCompressorPointwiseChunked = 2;
constexpr std::uint16_t kItemVersion2 = 2;
// What the VLR states as the LASzip version the stream follows (2.2.0: the
// version 2 items with chunks).
constexpr std::uint8_t kVersionMajor = 2;
constexpr std::uint8_t kVersionMinor = 2;
constexpr std::int64_t kNoSpecialEvlrs = -1;

std::int32_t get_i32(const std::uint8_t* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);
  return static_cast<std::int32_t>(v);
}
std::uint16_t get_u16(const std::uint8_t* p) { return static_cast<std::uint16_t>(p[0] | (p[1] << 8)); }
std::uint32_t zero_bit0(std::uint32_t k) { return k & ~1u; }

void ensure(std::unique_ptr<SymbolModel>& m) {
  if (!m) m = std::make_unique<SymbolModel>(256);
}

class Point10Writer {
 public:
  void init(const std::uint8_t* item) {
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
  }

  void write(ArithmeticEncoder& enc, const std::uint8_t* item) {
    const std::uint32_t r = item[14] & 0x7;
    const std::uint32_t n = (item[14] >> 3) & 0x7;
    const std::uint32_t m = kNumberReturnMap[n][r];
    const std::uint32_t l = kNumberReturnLevel[n][r];
    const std::uint16_t intensity = get_u16(item + 12);
    const std::uint16_t source = get_u16(item + 18);
    const std::uint32_t changed = (static_cast<std::uint32_t>(last_[14] != item[14]) << 5) |
                                  (static_cast<std::uint32_t>(last_intensity_[m] != intensity) << 4) |
                                  (static_cast<std::uint32_t>(last_[15] != item[15]) << 3) |
                                  (static_cast<std::uint32_t>(last_[16] != item[16]) << 2) |
                                  (static_cast<std::uint32_t>(last_[17] != item[17]) << 1) |
                                  static_cast<std::uint32_t>(get_u16(last_.data() + 18) != source);
    enc.encode_symbol(changed_values_, changed);
    if (changed & 32) {
      ensure(bit_byte_[last_[14]]);
      enc.encode_symbol(*bit_byte_[last_[14]], item[14]);
    }
    if (changed & 16) {
      ic_intensity_.compress(enc, last_intensity_[m], intensity, m < 3 ? m : 3);
      last_intensity_[m] = intensity;
    }
    if (changed & 8) {
      ensure(classification_[last_[15]]);
      enc.encode_symbol(*classification_[last_[15]], item[15]);
    }
    if (changed & 4) {
      enc.encode_symbol(scan_angle_[(item[14] >> 6) & 1], fold8(item[16] - last_[16]));
    }
    if (changed & 2) {
      ensure(user_data_[last_[17]]);
      enc.encode_symbol(*user_data_[last_[17]], item[17]);
    }
    if (changed & 1) ic_point_source_.compress(enc, get_u16(last_.data() + 18), source);

    std::int32_t diff = static_cast<std::int32_t>(static_cast<std::uint32_t>(get_i32(item)) -
                                                  static_cast<std::uint32_t>(get_i32(last_.data())));
    ic_dx_.compress(enc, last_x_diff_[m].get(), diff, n == 1);
    last_x_diff_[m].add(diff);
    std::uint32_t k_bits = ic_dx_.k();
    diff = static_cast<std::int32_t>(static_cast<std::uint32_t>(get_i32(item + 4)) -
                                     static_cast<std::uint32_t>(get_i32(last_.data() + 4)));
    ic_dy_.compress(enc, last_y_diff_[m].get(), diff, (n == 1) + (k_bits < 20 ? zero_bit0(k_bits) : 20));
    last_y_diff_[m].add(diff);
    k_bits = (ic_dx_.k() + ic_dy_.k()) / 2;
    const std::int32_t z = get_i32(item + 8);
    ic_z_.compress(enc, last_height_[l], z, (n == 1) + (k_bits < 18 ? zero_bit0(k_bits) : 18));
    last_height_[l] = z;
    std::memcpy(last_.data(), item, kPoint10Size);
  }

 private:
  SymbolModel changed_values_{64};
  IntegerCompressor ic_intensity_{16, 4};
  std::array<SymbolModel, 2> scan_angle_{SymbolModel(256), SymbolModel(256)};
  IntegerCompressor ic_point_source_{16};
  std::array<std::unique_ptr<SymbolModel>, 256> bit_byte_, classification_, user_data_;
  IntegerCompressor ic_dx_{32, 2};
  IntegerCompressor ic_dy_{32, 22};
  IntegerCompressor ic_z_{32, 20};
  std::array<std::uint8_t, kPoint10Size> last_{};
  std::array<std::uint16_t, 16> last_intensity_{};
  std::array<Median5, 16> last_x_diff_, last_y_diff_;
  std::array<std::int32_t, 8> last_height_{};
};

class GpsTime11Writer {
 public:
  void init(const std::uint8_t* item) {
    std::uint64_t t;
    std::memcpy(&t, item, 8);
    s_.init(t);
  }

  void write(ArithmeticEncoder& enc, const std::uint8_t* item) {
    std::uint64_t t;
    std::memcpy(&t, item, 8);
    // At most one switch to another sequence, then the time is coded there.
    for (int hop = 0; hop < 2; ++hop) {
      if (write_in_sequence(enc, t, hop == 0)) return;
    }
  }

 private:
  static bool fits32(std::int64_t d) { return d == static_cast<std::int32_t>(d); }
  std::int64_t diff_to(std::uint32_t seq, std::uint64_t t) const {
    return static_cast<std::int64_t>(t - s_.time[seq]);
  }

  // Codes `t` against the current sequence; false after coding only a
  // switch to another sequence (the caller then codes `t` there).
  bool write_in_sequence(ArithmeticEncoder& enc, std::uint64_t t, bool may_switch) {
    State& s = s_;
    const bool zero = s.diff[s.last] == 0;
    if (t == s.time[s.last]) {
      enc.encode_symbol(zero ? s.zero_diff : s.multi, zero ? 0 : kGpsMultiUnchanged);
      return true;
    }
    const std::int64_t d64 = diff_to(s.last, t);
    if (fits32(d64)) {
      const auto d = static_cast<std::int32_t>(d64);
      if (zero) {
        enc.encode_symbol(s.zero_diff, 1);
        s.ic.compress(enc, 0, d, 0);
        s.diff[s.last] = d;
        s.extreme[s.last] = 0;
      } else {
        write_multiple(enc, d);
      }
      s.time[s.last] = t;
      return true;
    }
    if (may_switch) {
      for (std::uint32_t i = 1; i < 4; ++i) {
        if (fits32(diff_to((s.last + i) & 3, t))) {
          enc.encode_symbol(zero ? s.zero_diff : s.multi, zero ? i + 2 : kGpsMultiCodeFull + i);
          s.last = (s.last + i) & 3;
          return false;
        }
      }
    }
    enc.encode_symbol(zero ? s.zero_diff : s.multi, zero ? 2 : kGpsMultiCodeFull);
    s.ic.compress(enc, static_cast<std::int32_t>(s.time[s.last] >> 32), static_cast<std::int32_t>(t >> 32), 8);
    enc.write_int(static_cast<std::uint32_t>(t));
    s.next = (s.next + 1) & 3;
    s.last = s.next;
    s.diff[s.last] = 0;
    s.extreme[s.last] = 0;
    s.time[s.last] = t;
    return true;
  }

  void write_multiple(ArithmeticEncoder& enc, std::int32_t d) {
    State& s = s_;
    std::int32_t& last_diff = s.diff[s.last];
    std::int32_t& extreme = s.extreme[s.last];
    // LASzip's I32_QUANTIZE of the float ratio.
    const float ratio = static_cast<float>(d) / static_cast<float>(last_diff);
    const auto multi = static_cast<std::int32_t>(ratio >= 0 ? ratio + 0.5f : ratio - 0.5f);
    const auto times = [](std::int32_t a, std::int32_t b) {
      return static_cast<std::int32_t>(static_cast<std::uint32_t>(a) * static_cast<std::uint32_t>(b));
    };
    auto extreme_step = [&] {
      if (++extreme > 3) {
        last_diff = d;
        extreme = 0;
      }
    };
    if (multi == 1) {
      enc.encode_symbol(s.multi, 1);
      s.ic.compress(enc, last_diff, d, 1);
      extreme = 0;
    } else if (multi > 0) {
      if (multi < kGpsMulti) {
        enc.encode_symbol(s.multi, static_cast<std::uint32_t>(multi));
        s.ic.compress(enc, times(multi, last_diff), d, multi < 10 ? 2 : 3);
      } else {
        enc.encode_symbol(s.multi, kGpsMulti);
        s.ic.compress(enc, times(kGpsMulti, last_diff), d, 4);
        extreme_step();
      }
    } else if (multi < 0) {
      if (multi > kGpsMultiMinus) {
        enc.encode_symbol(s.multi, static_cast<std::uint32_t>(kGpsMulti - multi));
        s.ic.compress(enc, times(multi, last_diff), d, 5);
      } else {
        enc.encode_symbol(s.multi, static_cast<std::uint32_t>(kGpsMulti - kGpsMultiMinus));
        s.ic.compress(enc, times(kGpsMultiMinus, last_diff), d, 6);
        extreme_step();
      }
    } else {
      enc.encode_symbol(s.multi, 0);
      s.ic.compress(enc, 0, d, 7);
      extreme_step();
    }
  }

  static constexpr std::uint32_t kGpsMultiUnchanged = kGpsMulti - kGpsMultiMinus + 1;
  static constexpr std::uint32_t kGpsMultiCodeFull = kGpsMulti - kGpsMultiMinus + 2;
  // GpsTimeState with the compressor in place of the decompressor.
  struct State {
    SymbolModel multi{516};
    SymbolModel zero_diff{6};
    IntegerCompressor ic{32, 9};
    std::uint32_t last = 0, next = 0;
    std::array<std::uint64_t, 4> time{};
    std::array<std::int32_t, 4> diff{};
    std::array<std::int32_t, 4> extreme{};
    void init(std::uint64_t first) {
      multi.init();
      zero_diff.init();
      ic.init();
      last = next = 0;
      diff = {0, 0, 0, 0};
      extreme = {0, 0, 0, 0};
      time = {first, 0, 0, 0};
    }
  };
  State s_;
};

class Rgb12Writer {
 public:
  void init(const std::uint8_t* item) {
    m_.init();
    for (int i = 0; i < 3; ++i) last_[i] = get_u16(item + 2 * i);
  }

  void write(ArithmeticEncoder& enc, const std::uint8_t* item) {
    const std::uint16_t c[3] = {get_u16(item), get_u16(item + 2), get_u16(item + 4)};
    const auto lo = [](std::uint16_t v) { return static_cast<int>(v & 0xFF); };
    const auto hi = [](std::uint16_t v) { return static_cast<int>(v >> 8); };
    std::uint32_t sym = 0;
    sym |= static_cast<std::uint32_t>(lo(last_[0]) != lo(c[0])) << 0;
    sym |= static_cast<std::uint32_t>(hi(last_[0]) != hi(c[0])) << 1;
    sym |= static_cast<std::uint32_t>(lo(last_[1]) != lo(c[1])) << 2;
    sym |= static_cast<std::uint32_t>(hi(last_[1]) != hi(c[1])) << 3;
    sym |= static_cast<std::uint32_t>(lo(last_[2]) != lo(c[2])) << 4;
    sym |= static_cast<std::uint32_t>(hi(last_[2]) != hi(c[2])) << 5;
    // Bit 6: the channels differ (else green and blue repeat red).
    sym |= static_cast<std::uint32_t>(lo(c[0]) != lo(c[1]) || lo(c[0]) != lo(c[2]) || hi(c[0]) != hi(c[1]) ||
                                      hi(c[0]) != hi(c[2]))
           << 6;
    enc.encode_symbol(m_.byte_used, sym);
    int diff_l = 0, diff_h = 0;
    if (sym & 1) {
      diff_l = lo(c[0]) - lo(last_[0]);
      enc.encode_symbol(m_.diff[0], fold8(diff_l));
    }
    if (sym & 2) {
      diff_h = hi(c[0]) - hi(last_[0]);
      enc.encode_symbol(m_.diff[1], fold8(diff_h));
    }
    if (sym & (1 << 6)) {
      if (sym & (1 << 2)) enc.encode_symbol(m_.diff[2], fold8(lo(c[1]) - clamp8(diff_l + lo(last_[1]))));
      if (sym & (1 << 4)) {
        diff_l = (diff_l + lo(c[1]) - lo(last_[1])) / 2;
        enc.encode_symbol(m_.diff[4], fold8(lo(c[2]) - clamp8(diff_l + lo(last_[2]))));
      }
      if (sym & (1 << 3)) enc.encode_symbol(m_.diff[3], fold8(hi(c[1]) - clamp8(diff_h + hi(last_[1]))));
      if (sym & (1 << 5)) {
        diff_h = (diff_h + hi(c[1]) - hi(last_[1])) / 2;
        enc.encode_symbol(m_.diff[5], fold8(hi(c[2]) - clamp8(diff_h + hi(last_[2]))));
      }
    }
    for (int i = 0; i < 3; ++i) last_[i] = c[i];
  }

 private:
  RgbModels m_;
  std::array<std::uint16_t, 3> last_{};
};

}  // namespace

struct PointCompressor::State {
  Point10Writer point;
  std::unique_ptr<GpsTime11Writer> gps;
  std::unique_ptr<Rgb12Writer> rgb;
  ArithmeticEncoder enc;
  std::vector<std::uint8_t> chunk;  // the chunk being written (a carry may still change it)
};

PointCompressor::PointCompressor() = default;
PointCompressor::~PointCompressor() = default;

Result<std::unique_ptr<PointCompressor>> PointCompressor::create(int point_format, std::size_t record_length,
                                                                 std::uint32_t chunk_size, const std::string& name) {
  if (point_format < 0 || point_format > 3) {
    return unsupported(name + ": LAZ output is written in point formats 0-3, not " + std::to_string(point_format));
  }
  const bool gps = point_format == 1 || point_format == 3;
  const bool rgb = point_format >= 2;
  const std::size_t need = kPoint10Size + (gps ? kGpsTime11Size : 0) + (rgb ? kRgb12Size : 0);
  if (record_length != need || chunk_size == 0 || chunk_size == kVariableChunks) {
    return invalid_argument(name + ": LAZ output needs " + std::to_string(need) + "-byte records and a fixed chunk size");
  }
  std::unique_ptr<PointCompressor> c(new PointCompressor());
  c->format_ = point_format;
  c->record_length_ = record_length;
  c->chunk_size_ = chunk_size;
  c->state_ = std::make_unique<State>();
  if (gps) c->state_->gps = std::make_unique<GpsTime11Writer>();
  if (rgb) c->state_->rgb = std::make_unique<Rgb12Writer>();
  c->rgb_offset_ = kPoint10Size + (gps ? kGpsTime11Size : 0);
  return c;
}

std::vector<std::uint8_t> PointCompressor::vlr_payload() const {
  std::vector<std::uint8_t> p;
  auto u8 = [&](std::uint8_t v) { p.push_back(v); };
  auto u16 = [&](std::uint16_t v) {
    u8(static_cast<std::uint8_t>(v));
    u8(static_cast<std::uint8_t>(v >> 8));
  };
  auto u32 = [&](std::uint32_t v) {
    u16(static_cast<std::uint16_t>(v));
    u16(static_cast<std::uint16_t>(v >> 16));
  };
  auto u64 = [&](std::uint64_t v) {
    u32(static_cast<std::uint32_t>(v));
    u32(static_cast<std::uint32_t>(v >> 32));
  };
  u16(kCompressorPointwiseChunked);
  u16(0);  // arithmetic coder
  u8(kVersionMajor);
  u8(kVersionMinor);
  u16(0);  // revision
  u32(0);  // options
  u32(chunk_size_);
  u64(static_cast<std::uint64_t>(kNoSpecialEvlrs));
  u64(static_cast<std::uint64_t>(kNoSpecialEvlrs));
  const bool gps = format_ == 1 || format_ == 3;
  const bool rgb = format_ >= 2;
  u16(static_cast<std::uint16_t>(1 + (gps ? 1 : 0) + (rgb ? 1 : 0)));
  u16(kItemPoint10);
  u16(kPoint10Size);
  u16(kItemVersion2);
  if (gps) {
    u16(kItemGpsTime11);
    u16(kGpsTime11Size);
    u16(kItemVersion2);
  }
  if (rgb) {
    u16(kItemRgb12);
    u16(kRgb12Size);
    u16(kItemVersion2);
  }
  return p;
}

void PointCompressor::end_chunk(std::vector<std::uint8_t>& out) {
  State& s = *state_;
  s.enc.done();
  chunk_bytes_.push_back(static_cast<std::uint32_t>(s.chunk.size()));
  out.insert(out.end(), s.chunk.begin(), s.chunk.end());
  s.chunk.clear();
  in_chunk_ = 0;
}

void PointCompressor::add(const std::uint8_t* records, std::size_t n, std::vector<std::uint8_t>& out) {
  State& s = *state_;
  for (std::size_t i = 0; i < n; ++i, records += record_length_) {
    if (in_chunk_ == chunk_size_) end_chunk(out);
    if (in_chunk_ == 0) {
      // A chunk starts with its first point raw; the stream follows it.
      s.chunk.insert(s.chunk.end(), records, records + record_length_);
      s.point.init(records);
      if (s.gps) s.gps->init(records + kPoint10Size);
      if (s.rgb) s.rgb->init(records + rgb_offset_);
      s.enc.init(s.chunk);
    } else {
      s.point.write(s.enc, records);
      if (s.gps) s.gps->write(s.enc, records + kPoint10Size);
      if (s.rgb) s.rgb->write(s.enc, records + rgb_offset_);
    }
    ++in_chunk_;
  }
}

std::vector<std::uint8_t> PointCompressor::finish(std::vector<std::uint8_t>& out) {
  if (in_chunk_ > 0) end_chunk(out);
  std::vector<std::uint8_t> table;
  auto u32 = [&](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) table.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  };
  u32(0);  // version
  u32(static_cast<std::uint32_t>(chunk_bytes_.size()));
  if (!chunk_bytes_.empty()) {
    ArithmeticEncoder enc;
    enc.init(table);
    IntegerCompressor ic(32, 2);
    ic.init();
    for (std::size_t i = 0; i < chunk_bytes_.size(); ++i) {
      ic.compress(enc, static_cast<std::int32_t>(i ? chunk_bytes_[i - 1] : 0),
                  static_cast<std::int32_t>(chunk_bytes_[i]), 1);
    }
    enc.done();
  }
  return table;
}

}  // namespace relief::laz
