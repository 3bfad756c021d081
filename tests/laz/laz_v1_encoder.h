// Test-side LAZ writers for what Relief only reads: LASzip 1.x's item
// version 1 (POINT10, GPSTIME11, RGB12, BYTE, and WAVEPACKET13 of the
// waveform formats 4 and 5, which LASzip still writes in version 1) and its
// unchunked pointwise compressor (1). The version-1 encoders here are written from LASzip's
// description of its version-1 compressors, apart from the library's
// decoders (items_v1.cpp): they share only the range coder and the integer
// coder, so a round trip checks the decoders' models against a second
// reading of the format. Version-2 items are encoded by the library's own
// item coders (items.h), as its writer does.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <memory>
#include <span>
#include <vector>

#include "laz/arithmetic_encoder.h"
#include "laz/integer_coder.h"
#include "laz/items.h"
#include "relief/laz.h"

namespace relief::laztest {

inline std::int32_t le_i32(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | p[i];
  return static_cast<std::int32_t>(v);
}
inline std::uint32_t le_u16(const std::uint8_t* p) { return static_cast<std::uint32_t>(p[0] | (p[1] << 8)); }
inline std::uint64_t le_u64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  return v;
}

// One item's encoder: init() with the first record's item (stored raw),
// then write() for each further record.
class ItemEncoder {
 public:
  virtual ~ItemEncoder() = default;
  virtual void init(const std::uint8_t* item) = 0;
  virtual void write(laz::ArithmeticEncoder& enc, const std::uint8_t* item) = 0;
};

// POINT10 version 1: x and y steps against the median of the previous three
// steps, y in a context of x's corrector bit length k (capped at 19), z
// against the previous z in a context of the mean of both k; then a 6-bit
// mask of the changed fields and each changed field: intensity and point
// source by 16-bit integer coders, the flag byte, classification and user
// data by 256-symbol models chosen by the previous value, the scan angle
// byte by an 8-bit integer coder in context "mean k below 3".
class Point10V1Encoder final : public ItemEncoder {
 public:
  void init(const std::uint8_t* item) override {
    std::memcpy(last_, item, 20);
    steps_x_.fill(0);
    steps_y_.fill(0);
    slot_ = 0;
    for (laz::IntegerCoder* ic : {&dx_, &dy_, &z_, &intensity_, &angle_, &source_}) ic->init();
    mask_.init();
    for (auto* table : {&flags_, &classes_, &users_}) {
      for (auto& m : *table) m.reset();
    }
  }

  void write(laz::ArithmeticEncoder& enc, const std::uint8_t* item) override {
    const auto sx = static_cast<std::int32_t>(static_cast<std::uint32_t>(le_i32(item)) -
                                              static_cast<std::uint32_t>(le_i32(last_)));
    const auto sy = static_cast<std::int32_t>(static_cast<std::uint32_t>(le_i32(item + 4)) -
                                              static_cast<std::uint32_t>(le_i32(last_ + 4)));
    dx_.compress(enc, middle(steps_x_), sx, 0);
    std::uint32_t k = dx_.k();
    dy_.compress(enc, middle(steps_y_), sy, std::min<std::uint32_t>(k, 19));
    k = (k + dy_.k()) / 2;
    z_.compress(enc, le_i32(last_ + 8), le_i32(item + 8), std::min<std::uint32_t>(k, 19));

    std::uint32_t mask = 0;
    if (le_u16(item + 12) != le_u16(last_ + 12)) mask |= 32;
    for (int b = 0; b < 4; ++b) {
      if (item[14 + b] != last_[14 + b]) mask |= 16u >> b;
    }
    if (le_u16(item + 18) != le_u16(last_ + 18)) mask |= 1;
    enc.encode_symbol(mask_, mask);
    if (mask & 32) intensity_.compress(enc, static_cast<std::int32_t>(le_u16(last_ + 12)),
                                       static_cast<std::int32_t>(le_u16(item + 12)), 0);
    if (mask & 16) enc.encode_symbol(model(flags_, last_[14]), item[14]);
    if (mask & 8) enc.encode_symbol(model(classes_, last_[15]), item[15]);
    if (mask & 4) angle_.compress(enc, last_[16], item[16], k < 3 ? 1 : 0);
    if (mask & 2) enc.encode_symbol(model(users_, last_[17]), item[17]);
    if (mask & 1) source_.compress(enc, static_cast<std::int32_t>(le_u16(last_ + 18)),
                                   static_cast<std::int32_t>(le_u16(item + 18)), 0);
    steps_x_[slot_] = sx;
    steps_y_[slot_] = sy;
    slot_ = (slot_ + 1) % 3;
    std::memcpy(last_, item, 20);
  }

 private:
  static std::int32_t middle(std::array<std::int32_t, 3> v) {
    std::sort(v.begin(), v.end());
    return v[1];
  }
  static laz::SymbolModel& model(std::array<std::unique_ptr<laz::SymbolModel>, 256>& table, std::uint8_t at) {
    if (!table[at]) table[at] = std::make_unique<laz::SymbolModel>(256);
    return *table[at];
  }

  std::uint8_t last_[20] = {};
  std::array<std::int32_t, 3> steps_x_{}, steps_y_{};
  int slot_ = 0;
  laz::IntegerCoder dx_{32, 1}, dy_{32, 20}, z_{32, 20}, intensity_{16, 1}, angle_{8, 2}, source_{16, 1};
  laz::SymbolModel mask_{64};
  std::array<std::unique_ptr<laz::SymbolModel>, 256> flags_, classes_, users_;
};

// GPSTIME11 version 1: the double's bits as a 64-bit integer. With no
// reference step (the last one was 0): 0 = same time, 1 = a 32-bit step
// (which becomes the reference), 2 = the full 64 bits. Otherwise a 512-way
// multiplier symbol: m = round(step / reference) clamped to 0..509, the
// step coded against m * reference (reference / 4 for m = 0) in context 1
// for m = 1, 2 for 0, 3 below 10, 4 below 50, else 5; m = 1 makes the step
// the reference, and four extreme ones (0 or 509) in a row do too; 510 =
// the full 64 bits (step over 32 bits), 511 = same time.
class GpsTime11V1Encoder final : public ItemEncoder {
 public:
  void init(const std::uint8_t* item) override {
    last_ = le_u64(item);
    reference_ = 0;
    extremes_ = 0;
    multi_.init();
    zero_.init();
    ic_.init();
  }

  void write(laz::ArithmeticEncoder& enc, const std::uint8_t* item) override {
    const std::uint64_t t = le_u64(item);
    const auto step64 = static_cast<std::int64_t>(t - last_);
    const bool fits = step64 >= INT32_MIN && step64 <= INT32_MAX;
    const auto step = static_cast<std::int32_t>(step64);
    if (reference_ == 0) {
      if (t == last_) {
        enc.encode_symbol(zero_, 0);
      } else if (fits) {
        enc.encode_symbol(zero_, 1);
        ic_.compress(enc, 0, step, 0);
        reference_ = step;
      } else {
        enc.encode_symbol(zero_, 2);
        full(enc, t);
      }
    } else if (t == last_) {
      enc.encode_symbol(multi_, 511);
    } else if (!fits) {
      enc.encode_symbol(multi_, 510);
      full(enc, t);
    } else {
      const float ratio = static_cast<float>(step) / static_cast<float>(reference_) + 0.5f;
      const std::uint32_t m = ratio >= 509.0f ? 509u : (ratio < 1.0f ? 0u : static_cast<std::uint32_t>(ratio));
      enc.encode_symbol(multi_, m);
      if (m == 1) {
        ic_.compress(enc, reference_, step, 1);
        reference_ = step;
        extremes_ = 0;
      } else if (m == 0) {
        ic_.compress(enc, reference_ / 4, step, 2);
        extreme(step);
      } else {
        const auto pred = static_cast<std::int32_t>(m * static_cast<std::uint32_t>(reference_));
        ic_.compress(enc, pred, step, m < 10 ? 3 : (m < 50 ? 4 : 5));
        if (m == 509) extreme(step);
      }
    }
    last_ = t;
  }

 private:
  void full(laz::ArithmeticEncoder& enc, std::uint64_t t) {
    enc.write_int(static_cast<std::uint32_t>(t));
    enc.write_int(static_cast<std::uint32_t>(t >> 32));
  }
  void extreme(std::int32_t step) {
    if (++extremes_ == 4) {
      reference_ = step;
      extremes_ = 0;
    }
  }

  std::uint64_t last_ = 0;
  std::int32_t reference_ = 0;
  int extremes_ = 0;
  laz::SymbolModel multi_{512}, zero_{3};
  laz::IntegerCoder ic_{32, 6};
};

// RGB12 version 1: a 6-bit mask of the bytes (low, high of red, green,
// blue) that differ from the previous colour, then each differing byte
// against its previous value, one 8-bit context per byte.
class Rgb12V1Encoder final : public ItemEncoder {
 public:
  void init(const std::uint8_t* item) override {
    std::memcpy(last_, item, 6);
    used_.init();
    ic_.init();
  }
  void write(laz::ArithmeticEncoder& enc, const std::uint8_t* item) override {
    std::uint32_t mask = 0;
    for (std::uint32_t b = 0; b < 6; ++b) {
      if (item[b] != last_[b]) mask |= 1u << b;
    }
    enc.encode_symbol(used_, mask);
    for (std::uint32_t b = 0; b < 6; ++b) {
      if (mask & (1u << b)) ic_.compress(enc, last_[b], item[b], b);
    }
    std::memcpy(last_, item, 6);
  }

 private:
  std::uint8_t last_[6] = {};
  laz::SymbolModel used_{64};
  laz::IntegerCoder ic_{8, 6};
};

// BYTE version 1: every byte against its previous value, context = its index.
class ByteV1Encoder final : public ItemEncoder {
 public:
  explicit ByteV1Encoder(std::size_t n) : last_(n), ic_(8, static_cast<std::uint32_t>(n)) {}
  void init(const std::uint8_t* item) override {
    std::memcpy(last_.data(), item, last_.size());
    ic_.init();
  }
  void write(laz::ArithmeticEncoder& enc, const std::uint8_t* item) override {
    for (std::size_t i = 0; i < last_.size(); ++i) ic_.compress(enc, last_[i], item[i], static_cast<std::uint32_t>(i));
    std::memcpy(last_.data(), item, last_.size());
  }

 private:
  std::vector<std::uint8_t> last_;
  laz::IntegerCoder ic_;
};

// WAVEPACKET13 version 1 (the only version; LASzip writes it so in every
// pointwise stream, formats 4 and 5), from LASzip's description of its
// writer: the descriptor index by a 256-symbol model; the waveform's byte
// offset against the previous descriptor's as 0 (the same), 1 (previous
// offset + previous packet size), 2 (a difference that fits 32 bits, by an
// integer coder against the previous such difference) or 3 (the 64 bits
// raw), in a 4-symbol model chosen by the previous choice; then the packet
// size, the return point and x, y, z (their 32-bit patterns; x y z in three
// contexts of one coder) against the previous descriptor's.
class WavePacket13V1Encoder final : public ItemEncoder {
 public:
  void init(const std::uint8_t* item) override {
    std::memcpy(last_, item + 1, 28);
    last_diff_ = 0;
    choice_ = 0;
    index_.init();
    for (auto& m : offset_) m.init();
    ic_offset_.init();
    ic_size_.init();
    ic_return_.init();
    ic_xyz_.init();
  }
  void write(laz::ArithmeticEncoder& enc, const std::uint8_t* item) override {
    enc.encode_symbol(index_, item[0]);
    const std::uint8_t* cur = item + 1;
    const std::uint64_t offset = le_u64(cur), last_offset = le_u64(last_);
    const auto size = static_cast<std::int32_t>(le_i32(cur + 8)), last_size = le_i32(last_ + 8);
    const auto diff64 = static_cast<std::int64_t>(offset - last_offset);
    const auto diff32 = static_cast<std::int32_t>(diff64);
    std::uint32_t choice = 3;
    if (diff64 == static_cast<std::int64_t>(diff32)) choice = diff32 == 0 ? 0 : (diff32 == last_size ? 1 : 2);
    enc.encode_symbol(offset_[choice_], choice);
    choice_ = choice;
    if (choice == 2) {
      ic_offset_.compress(enc, last_diff_, diff32);
      last_diff_ = diff32;
    } else if (choice == 3) {
      enc.write_int(static_cast<std::uint32_t>(offset));
      enc.write_int(static_cast<std::uint32_t>(offset >> 32));
    }
    ic_size_.compress(enc, last_size, size);
    ic_return_.compress(enc, le_i32(last_ + 12), le_i32(cur + 12));
    for (std::uint32_t a = 0; a < 3; ++a) ic_xyz_.compress(enc, le_i32(last_ + 16 + 4 * a), le_i32(cur + 16 + 4 * a), a);
    std::memcpy(last_, cur, 28);
  }

 private:
  laz::SymbolModel index_{256};
  std::array<laz::SymbolModel, 4> offset_{laz::SymbolModel(4), laz::SymbolModel(4), laz::SymbolModel(4),
                                          laz::SymbolModel(4)};
  laz::IntegerCoder ic_offset_{32}, ic_size_{32}, ic_return_{32}, ic_xyz_{32, 3};
  std::uint8_t last_[28] = {};
  std::int32_t last_diff_ = 0;
  std::uint32_t choice_ = 0;
};

// A version-2 item through the library's item coder.
template <typename T>
class V2Encoder final : public ItemEncoder {
 public:
  template <typename... A>
  explicit V2Encoder(A... a) : item_(a...) {}
  void init(const std::uint8_t* item) override { item_.init(item); }
  void write(laz::ArithmeticEncoder& enc, const std::uint8_t* item) override { item_.write(enc, item); }

 private:
  T item_;
};

// The items of point format 0-5 with `extra` bytes, each in `version`
// (bit i of `v1_mask` makes item i version 1, the others version 2;
// WAVEPACKET13 is always version 1).
inline std::vector<laz::Item> pointwise_items(int format, std::size_t extra, unsigned v1_mask) {
  std::vector<laz::Item> items;
  const laz::FormatItems need = laz::items_for_format(format);
  for (const std::uint16_t type : need.types) {
    items.push_back({type, static_cast<std::uint16_t>(laz::fixed_item_size(type)), 2});
  }
  if (extra > 0) items.push_back({laz::kItemByte, static_cast<std::uint16_t>(extra), 2});
  for (std::size_t i = 0; i < items.size(); ++i) {
    if ((v1_mask & (1u << i)) || items[i].type == laz::kItemWavePacket13) items[i].version = 1;
  }
  return items;
}

// One pointwise stream (a chunk's, or compressor 1's whole point data):
// the first record raw, the others arithmetic-coded item by item.
inline std::vector<std::uint8_t> encode_pointwise(std::span<const std::uint8_t> records, std::size_t rl,
                                                  const std::vector<laz::Item>& items) {
  std::vector<std::unique_ptr<ItemEncoder>> coders;
  std::vector<std::size_t> offsets;
  std::size_t offset = 0;
  for (const laz::Item& it : items) {
    const bool v1 = it.version == 1;
    switch (it.type) {
      case laz::kItemPoint10:
        coders.push_back(v1 ? std::unique_ptr<ItemEncoder>(std::make_unique<Point10V1Encoder>())
                            : std::make_unique<V2Encoder<laz::Point10V2>>());
        break;
      case laz::kItemGpsTime11:
        coders.push_back(v1 ? std::unique_ptr<ItemEncoder>(std::make_unique<GpsTime11V1Encoder>())
                            : std::make_unique<V2Encoder<laz::GpsTime11V2>>());
        break;
      case laz::kItemRgb12:
        coders.push_back(v1 ? std::unique_ptr<ItemEncoder>(std::make_unique<Rgb12V1Encoder>())
                            : std::make_unique<V2Encoder<laz::Rgb12V2>>());
        break;
      case laz::kItemWavePacket13:
        coders.push_back(std::make_unique<WavePacket13V1Encoder>());
        break;
      default:
        coders.push_back(v1 ? std::unique_ptr<ItemEncoder>(std::make_unique<ByteV1Encoder>(it.size))
                            : std::make_unique<V2Encoder<laz::ByteV2>>(std::size_t{it.size}));
        break;
    }
    offsets.push_back(offset);
    offset += it.size;
  }
  std::vector<std::uint8_t> out;
  const std::size_t n = records.size() / rl;
  if (n == 0) return out;
  out.assign(records.begin(), records.begin() + static_cast<std::ptrdiff_t>(rl));
  for (std::size_t i = 0; i < coders.size(); ++i) coders[i]->init(records.data() + offsets[i]);
  laz::ArithmeticEncoder enc;
  enc.init(out);
  for (std::size_t p = 1; p < n; ++p) {
    for (std::size_t i = 0; i < coders.size(); ++i) coders[i]->write(enc, records.data() + p * rl + offsets[i]);
  }
  enc.done();
  return out;
}

// The LASzip VLR payload for `items` under `compressor` (LASzip 1.x's
// version numbers; nothing reads them).
inline std::vector<std::uint8_t> pointwise_vlr(std::uint16_t compressor, std::uint32_t chunk_size,
                                               const std::vector<laz::Item>& items) {
  std::vector<std::uint8_t> p;
  auto put = [&](std::uint64_t v, int bytes) {
    for (int i = 0; i < bytes; ++i) p.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  };
  put(compressor, 2);
  put(0, 2);  // arithmetic coder
  put(1, 1);  // LASzip 1.4 r0
  put(4, 1);
  put(0, 2);
  put(0, 4);  // options
  put(chunk_size, 4);
  put(~std::uint64_t{0}, 8);  // no special EVLRs
  put(~std::uint64_t{0}, 8);
  put(items.size(), 2);
  for (const laz::Item& it : items) {
    put(it.type, 2);
    put(it.size, 2);
    put(it.version, 2);
  }
  return p;
}

// A compressor-2 point region with fixed chunks of `chunk_size` points:
// the 8-byte table offset (relative to the region's start at `base`), the
// chunks, the chunk table (byte counts against the previous one, context 1).
inline std::vector<std::uint8_t> chunked_region(std::span<const std::uint8_t> records, std::size_t rl,
                                                const std::vector<laz::Item>& items, std::uint32_t chunk_size,
                                                std::uint64_t base) {
  std::vector<std::uint8_t> out(8, 0);
  std::vector<std::uint32_t> sizes;
  const std::size_t n = records.size() / rl;
  for (std::size_t at = 0; at < n; at += chunk_size) {
    const std::size_t m = std::min<std::size_t>(chunk_size, n - at);
    const auto chunk = encode_pointwise(records.subspan(at * rl, m * rl), rl, items);
    out.insert(out.end(), chunk.begin(), chunk.end());
    sizes.push_back(static_cast<std::uint32_t>(chunk.size()));
  }
  const std::uint64_t table_at = base + out.size();
  for (int i = 0; i < 8; ++i) out[i] = static_cast<std::uint8_t>(table_at >> (8 * i));
  for (int i = 0; i < 4; ++i) out.push_back(0);  // table version 0
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(sizes.size() >> (8 * i)));
  if (!sizes.empty()) {
    std::vector<std::uint8_t> coded;
    laz::ArithmeticEncoder enc;
    enc.init(coded);
    laz::IntegerCoder ic(32, 2);
    ic.init();
    std::uint32_t prev = 0;
    for (const std::uint32_t s : sizes) {
      ic.compress(enc, static_cast<std::int32_t>(prev), static_cast<std::int32_t>(s), 1);
      prev = s;
    }
    enc.done();
    out.insert(out.end(), coded.begin(), coded.end());
  }
  return out;
}

}  // namespace relief::laztest
