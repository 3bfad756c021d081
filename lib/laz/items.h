// Item coders of LASzip: version 1 (LASzip 1.x, pointwise), version 2
// (pointwise, one arithmetic stream per chunk) and version 3 (layered: each
// attribute has its own stream, and POINT14 keeps separate contexts per
// scanner channel that the other items follow). Each class holds one item's
// models and predictor state: read() (items_v1.cpp, items_v2.cpp,
// items_v3.cpp) matches LASzip's reader bit for bit; versions 2 and 3 also
// write() (items_v2_write.cpp, items_v3_write.cpp) LASzip's writer byte for
// byte, with the same state, so that every model is initialised and updated
// in one place (version 1 is read only: Relief writes the current versions).
// Internal to lib/laz.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "laz/arithmetic_decoder.h"
#include "laz/arithmetic_encoder.h"
#include "laz/integer_coder.h"

namespace relief::laz {

// LASzip item type codes (the VLR's item records).
enum ItemType : std::uint16_t {
  kItemByte = 0,
  kItemPoint10 = 6,
  kItemGpsTime11 = 7,
  kItemRgb12 = 8,
  kItemWavePacket13 = 9,
  kItemPoint14 = 10,
  kItemRgb14 = 11,
  kItemRgbNir14 = 12,
  kItemWavePacket14 = 13,
  kItemByte14 = 14,
};

inline constexpr std::size_t kPoint10Size = 20;
inline constexpr std::size_t kGpsTime11Size = 8;
inline constexpr std::size_t kRgb12Size = 6;
inline constexpr std::size_t kPoint14Size = 30;
inline constexpr std::size_t kRgbNir14Size = 8;
inline constexpr std::size_t kWavePacketSize = 29;

// The items of a point format before any extra bytes (empty for formats
// LAZ does not cover here) and their total size.
struct FormatItems {
  std::vector<std::uint16_t> types;
  std::size_t size = 0;
};
FormatItems items_for_format(int format);
// The size of a fixed-size item (0 for BYTE and BYTE14).
std::size_t fixed_item_size(std::uint16_t type);

// POINT10 byte offsets.
namespace p10 {
inline constexpr int kX = 0, kY = 4, kZ = 8, kIntensity = 12, kBits = 14, kClass = 15, kAngle = 16, kUser = 17,
                     kSource = 18;
}  // namespace p10

// A context's symbol model, created on first use (as LASzip does: most
// contexts of a 256-way table never occur).
inline SymbolModel& model_for(std::unique_ptr<SymbolModel>& m, std::uint32_t symbols) {
  if (!m) m = std::make_unique<SymbolModel>(symbols);
  return *m;
}
template <std::size_t N>
void init_existing(std::array<std::unique_ptr<SymbolModel>, N>& models) {
  for (auto& m : models) {
    if (m) m->init();
  }
}

// Running median of the last five values (LASzip's StreamingMedian5).
class Median5 {
 public:
  void init() {
    v_ = {0, 0, 0, 0, 0};
    high_ = true;
  }
  std::int32_t get() const { return v_[2]; }
  void add(std::int32_t x);

 private:
  std::array<std::int32_t, 5> v_{};
  bool high_ = true;
};

// The RGB difference coder shared by RGB12 v2, RGB14 v3 and RGBNIR14 v3.
struct RgbModels {
  SymbolModel byte_used{128};
  std::array<SymbolModel, 6> diff{SymbolModel(256), SymbolModel(256), SymbolModel(256),
                                  SymbolModel(256), SymbolModel(256), SymbolModel(256)};
  void init() {
    byte_used.init();
    for (auto& m : diff) m.init();
  }
};
void decode_rgb(ArithmeticDecoder& dec, RgbModels& m, const std::uint16_t* last, std::uint16_t* out);
// Codes colour `c` against `last`; returns the symbol written first (bits
// 0-5: which bytes differ from `last`, bit 6: the channels differ), so 0
// means the colour added nothing.
std::uint32_t encode_rgb(ArithmeticEncoder& enc, RgbModels& m, const std::uint16_t* last, const std::uint16_t* c);

// GPS time state of one sequence set (GPSTIME11 v2 and POINT14 v3 differ
// only in the symbol numbering of the "zero difference" model).
struct GpsTimeState {
  explicit GpsTimeState(std::uint32_t zero_diff_symbols, std::uint32_t multi_symbols)
      : multi(multi_symbols), zero_diff(zero_diff_symbols) {}
  void init(std::uint64_t first);
  SymbolModel multi;
  SymbolModel zero_diff;
  IntegerCoder ic{32, 9};
  std::uint32_t last = 0, next = 0;
  std::array<std::uint64_t, 4> time{};
  std::array<std::int32_t, 4> diff{};
  std::array<std::int32_t, 4> extreme{};
};

// Multiplier codes of the GPS time predictor (LASZIP_GPSTIME_MULTI...).
inline constexpr std::int32_t kGpsMulti = 500;
inline constexpr std::int32_t kGpsMultiMinus = -10;
// A switch names another sequence; a valid stream chains at most a few, so
// more are taken as corrupt data and stop (bounded work on any input).
inline constexpr int kMaxSequenceSwitches = 4;
// The difference coded against multi * the sequence's last difference
// (codes 0 .. kGpsMulti - kGpsMultiMinus, except 1).
void gps_decode_multiple(ArithmeticDecoder& dec, GpsTimeState& s, std::uint32_t multi);
// A new sequence whose upper 32 bits are coded against the current one's.
void gps_decode_full(ArithmeticDecoder& dec, GpsTimeState& s);

// The symbols of the two GPS time coders (they differ by the "unchanged"
// code that only version 2 has: version 3 codes a time only when it changed).
struct GpsCodes {
  bool has_unchanged;              // v2: the time may repeat the sequence's last
  std::uint32_t zero_unchanged;    // zero-difference model: time repeats
  std::uint32_t zero_small;        // ... a 32-bit difference follows
  std::uint32_t zero_full;         // ... a new sequence starts
  std::uint32_t multi_unchanged;   // multiplier model: time repeats
  std::uint32_t multi_full;        // ... a new sequence starts; + i: switch by i
};
inline constexpr GpsCodes kGpsCodesV2{true, 0, 1, 2, kGpsMulti - kGpsMultiMinus + 1, kGpsMulti - kGpsMultiMinus + 2};
inline constexpr GpsCodes kGpsCodesV3{false, 0, 0, 1, 0, kGpsMulti - kGpsMultiMinus + 1};
// Codes time `t` (the double's bits) as LASzip's writer does.
void gps_encode(ArithmeticEncoder& enc, GpsTimeState& s, std::uint64_t t, const GpsCodes& codes);

// ---------------------------------------------------------------- version 1
//
// LASzip 1.x's items (items_v1.cpp): other models than version 2 (integer
// coders where version 2 has symbol tables, a median of three differences,
// no return-number contexts), read only. Files may mix versions 1 and 2
// item by item, as LASzip's reader allows.

class Point10V1 {
 public:
  void init(const std::uint8_t* item);
  void read(ArithmeticDecoder& dec, std::uint8_t* item);

 private:
  SymbolModel changed_values_{64};
  IntegerCoder ic_dx_{32, 1};
  IntegerCoder ic_dy_{32, 20};
  IntegerCoder ic_z_{32, 20};
  IntegerCoder ic_intensity_{16, 1};
  IntegerCoder ic_scan_angle_{8, 2};
  IntegerCoder ic_point_source_{16, 1};
  std::array<std::unique_ptr<SymbolModel>, 256> bit_byte_, classification_, user_data_;
  std::array<std::uint8_t, kPoint10Size> last_{};
  // The last three x and y differences, written round robin at next_.
  std::array<std::int32_t, 3> last_dx_{}, last_dy_{};
  int next_ = 0;
};

class GpsTime11V1 {
 public:
  void init(const std::uint8_t* item);
  void read(ArithmeticDecoder& dec, std::uint8_t* item);

  // Symbols of the multiplier model (512 of them): 0 .. kMultiMax - 3 are
  // multipliers of the last difference, then a full 64-bit time, then
  // "unchanged". The zero-difference model (3 symbols) codes unchanged,
  // a 32-bit difference, a full time.
  static constexpr std::uint32_t kMultiMax = 512;
  static constexpr std::uint32_t kMultiFull = kMultiMax - 2;
  static constexpr std::uint32_t kMultiUnchanged = kMultiMax - 1;

 private:
  SymbolModel multi_{kMultiMax};
  SymbolModel zero_diff_{3};
  IntegerCoder ic_{32, 6};
  std::uint64_t last_ = 0;
  std::int32_t last_diff_ = 0;
  int extreme_ = 0;
};

class Rgb12V1 {
 public:
  void init(const std::uint8_t* item);
  void read(ArithmeticDecoder& dec, std::uint8_t* item);

 private:
  SymbolModel byte_used_{64};
  IntegerCoder ic_{8, 6};
  std::array<std::uint16_t, 3> last_{};
};

// WAVEPACKET13 (point formats 4 and 5): the wave packet descriptor of a
// pulse. LASzip 2.x and 3.x still write it as version 1 in their pointwise
// streams. The descriptor index by a 256-symbol model; the byte offset of the
// waveform as the previous one, the previous one plus its size, a 32-bit
// difference (integer coder) or all 64 bits raw, the choice coded in a model
// picked by the previous choice; the packet size, the return point and the
// x y z step (floats, coded as their 32-bit patterns) by integer coders
// against the previous descriptor's.
class WavePacket13V1 {
 public:
  void init(const std::uint8_t* item);
  void read(ArithmeticDecoder& dec, std::uint8_t* item);

 private:
  SymbolModel packet_index_{256};
  std::array<SymbolModel, 4> offset_diff_{SymbolModel(4), SymbolModel(4), SymbolModel(4), SymbolModel(4)};
  IntegerCoder ic_offset_diff_{32};
  IntegerCoder ic_packet_size_{32};
  IntegerCoder ic_return_point_{32};
  IntegerCoder ic_xyz_{32, 3};
  std::array<std::uint8_t, kWavePacketSize - 1> last_{};  // the previous descriptor but its index
  std::int32_t last_diff_ = 0;
  std::uint32_t last_choice_ = 0;
};

class ByteV1 {
 public:
  explicit ByteV1(std::size_t n) : ic_(8, static_cast<std::uint32_t>(n)), last_(n) {}
  void init(const std::uint8_t* item);
  void read(ArithmeticDecoder& dec, std::uint8_t* item);

 private:
  IntegerCoder ic_;  // one context per byte
  std::vector<std::uint8_t> last_;
};

// ---------------------------------------------------------------- version 2

class Point10V2 {
 public:
  void init(const std::uint8_t* item);
  void read(ArithmeticDecoder& dec, std::uint8_t* item);
  void write(ArithmeticEncoder& enc, const std::uint8_t* item);

 private:
  SymbolModel changed_values_{64};
  IntegerCoder ic_intensity_{16, 4};
  std::array<SymbolModel, 2> scan_angle_{SymbolModel(256), SymbolModel(256)};
  IntegerCoder ic_point_source_{16};
  // Created on first use, as LASzip does (most of the 256 never are).
  std::array<std::unique_ptr<SymbolModel>, 256> bit_byte_, classification_, user_data_;
  IntegerCoder ic_dx_{32, 2};
  IntegerCoder ic_dy_{32, 22};
  IntegerCoder ic_z_{32, 20};
  std::array<std::uint8_t, kPoint10Size> last_{};
  std::array<std::uint16_t, 16> last_intensity_{};
  std::array<Median5, 16> last_x_diff_, last_y_diff_;
  std::array<std::int32_t, 8> last_height_{};
};

class GpsTime11V2 {
 public:
  void init(const std::uint8_t* item);
  void read(ArithmeticDecoder& dec, std::uint8_t* item);
  void write(ArithmeticEncoder& enc, const std::uint8_t* item);

 private:
  GpsTimeState s_{6, 516};
};

class Rgb12V2 {
 public:
  void init(const std::uint8_t* item);
  void read(ArithmeticDecoder& dec, std::uint8_t* item);
  void write(ArithmeticEncoder& enc, const std::uint8_t* item);

 private:
  RgbModels m_;
  std::array<std::uint16_t, 3> last_{};
};

class ByteV2 {
 public:
  explicit ByteV2(std::size_t n);
  void init(const std::uint8_t* item);
  void read(ArithmeticDecoder& dec, std::uint8_t* item);
  void write(ArithmeticEncoder& enc, const std::uint8_t* item);

 private:
  std::vector<SymbolModel> models_;
  std::vector<std::uint8_t> last_;
};

// ---------------------------------------------------------------- version 3

// A layer being read: its bytes in the chunk, its decoder, and whether it is
// present (a layer of zero bytes means the attribute never changes in the
// chunk).
struct Layer {
  std::uint32_t size = 0;
  bool changed = false;
  ArithmeticDecoder dec;
};

// Starts the decoders of `layers` on consecutive slices of `data`. False
// when a stream is not decodable.
bool start_layers(std::span<Layer> layers, std::span<const std::uint8_t> data);

// A layer being written: its own stream, stored only if `changed` (some
// point of the chunk differs from its predecessor in it) or `always`.
struct OutLayer {
  std::vector<std::uint8_t> bytes;
  ArithmeticEncoder enc;
  bool changed = false;
  bool always = false;
  void start() {
    bytes.clear();
    enc.init(bytes);
    changed = always;
  }
};

inline constexpr int kScannerChannels = 4;

class Point14V3 {
 public:
  static constexpr std::size_t kLayers = 9;
  Point14V3();
  ~Point14V3();
  std::span<Layer> layers() { return layers_; }
  std::span<OutLayer> out_layers() { return out_layers_; }
  // Starts a chunk at its first item (stored raw); returns the item's
  // scanner channel: the context the other items follow. (A writer starts
  // the out_layers() itself.)
  std::uint32_t init(const std::uint8_t* item);
  std::uint32_t read(std::uint8_t* item);
  std::uint32_t write(const std::uint8_t* item);

  struct Context;
  struct Fields;

 private:
  void init_context(std::uint32_t c, const Fields& from);
  void read_gps_time(Context& ctx);

  std::array<Layer, kLayers> layers_;
  std::array<OutLayer, kLayers> out_layers_;
  std::array<std::unique_ptr<Context>, kScannerChannels> contexts_;
  std::uint32_t current_ = 0;
};

class Rgb14V3 {
 public:
  explicit Rgb14V3(bool nir);
  std::span<Layer> layers() { return layers_; }
  std::span<OutLayer> out_layers() { return out_layers_; }
  void init(const std::uint8_t* item, std::uint32_t context);
  void read(std::uint8_t* item, std::uint32_t context);
  void write(const std::uint8_t* item, std::uint32_t context);

 private:
  struct Context {
    bool unused = true;
    RgbModels rgb;
    SymbolModel nir_used{4};
    std::array<SymbolModel, 2> nir_diff{SymbolModel(256), SymbolModel(256)};
    std::array<std::uint16_t, 4> last{};
  };
  void init_context(std::uint32_t c, const std::uint16_t* from);
  std::uint16_t* switch_context(std::uint32_t context);

  bool nir_;
  std::vector<Layer> layers_;
  std::vector<OutLayer> out_layers_;
  std::array<std::unique_ptr<Context>, kScannerChannels> contexts_;
  std::uint32_t current_ = 0;
};

class Byte14V3 {
 public:
  explicit Byte14V3(std::size_t n) : n_(n), layers_(n), out_layers_(n) {}
  std::span<Layer> layers() { return layers_; }
  std::span<OutLayer> out_layers() { return out_layers_; }
  void init(const std::uint8_t* item, std::uint32_t context);
  void read(std::uint8_t* item, std::uint32_t context);
  void write(const std::uint8_t* item, std::uint32_t context);

 private:
  struct Context {
    bool unused = true;
    std::vector<SymbolModel> models;
    std::vector<std::uint8_t> last;
  };
  void init_context(std::uint32_t c, const std::uint8_t* from);
  std::uint8_t* switch_context(std::uint32_t context);

  std::size_t n_;
  std::vector<Layer> layers_;
  std::vector<OutLayer> out_layers_;
  std::array<std::unique_ptr<Context>, kScannerChannels> contexts_;
  std::uint32_t current_ = 0;
};

}  // namespace relief::laz
