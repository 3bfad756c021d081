// POINT14 v3 state shared by its reader (items_v3.cpp) and writer
// (items_v3_write.cpp): the layer order, the fields the coder works on and the
// models and predictors of one scanner channel. Internal to lib/laz.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "laz/items.h"
#include "laz/tables.h"

namespace relief::laz {

inline constexpr std::uint32_t kGpsMultiCodeFullV3 = kGpsCodesV3.multi_full;  // 511
inline constexpr std::uint32_t kGpsMultiTotalV3 = kGpsMulti - kGpsMultiMinus + 5;     // 515
inline constexpr std::uint32_t kGpsZeroDiffSymbolsV3 = 5;

// Layer order in the chunk (and of the byte counts before the layers).
enum Point14Layer : std::size_t {
  kXY = 0,
  kZ,
  kClassification,
  kFlags,
  kIntensity,
  kScanAngle,
  kUserData,
  kPointSource,
  kGpsTime,
};

// A return pair's contexts: the 6-way map m, the level l that picks the z
// predictor, and cpr: 1 first, 2 last, 3 single, 0 intermediate return.
struct ReturnContexts {
  std::uint32_t m, l, cpr;
};
inline ReturnContexts return_contexts(std::uint32_t n, std::uint32_t r) {
  return {kNumberReturnMap6[n][r], number_return_level8(n, r), (r == 1 ? 1u : 0u) + (r >= n ? 2u : 0u)};
}

// The POINT14 fields the coder works on (LASzip's LASpoint14 minus legacy copies).
struct Point14V3::Fields {
  std::int32_t x = 0, y = 0, z = 0;
  std::uint16_t intensity = 0;
  std::uint32_t return_number = 0, number_of_returns = 0;
  std::uint32_t classification_flags = 0, scanner_channel = 0, scan_direction = 0, edge = 0;
  std::uint32_t classification = 0, user_data = 0;
  std::int16_t scan_angle = 0;
  std::uint16_t point_source = 0;
  std::uint64_t gps_time = 0;
  bool gps_time_change = false;

  void load(const std::uint8_t* p) {
    x = get_i32(p);
    y = get_i32(p + 4);
    z = get_i32(p + 8);
    intensity = get_u16(p + 12);
    return_number = p[14] & 0xF;
    number_of_returns = p[14] >> 4;
    classification_flags = p[15] & 0xF;
    scanner_channel = (p[15] >> 4) & 0x3;
    scan_direction = (p[15] >> 6) & 1;
    edge = p[15] >> 7;
    classification = p[16];
    user_data = p[17];
    scan_angle = static_cast<std::int16_t>(get_u16(p + 18));
    point_source = get_u16(p + 20);
    gps_time = get_u64(p + 22);
  }
  void store(std::uint8_t* p) const {
    put_i32(p, x);
    put_i32(p + 4, y);
    put_i32(p + 8, z);
    put_u16(p + 12, intensity);
    p[14] = static_cast<std::uint8_t>(return_number | (number_of_returns << 4));
    p[15] = static_cast<std::uint8_t>(classification_flags | (scanner_channel << 4) | (scan_direction << 6) |
                                      (edge << 7));
    p[16] = static_cast<std::uint8_t>(classification);
    p[17] = static_cast<std::uint8_t>(user_data);
    put_u16(p + 18, static_cast<std::uint16_t>(scan_angle));
    put_u16(p + 20, point_source);
    put_u64(p + 22, gps_time);
  }
};

// Models and predictor state of one scanner channel.
struct Point14V3::Context {
  bool unused = true;
  Fields last;
  std::vector<SymbolModel> changed_values = std::vector<SymbolModel>(8, SymbolModel(128));
  SymbolModel scanner_channel{3};
  std::array<std::unique_ptr<SymbolModel>, 16> number_of_returns, return_number;
  SymbolModel return_number_gps_same{13};
  IntegerCoder ic_dx{32, 2};
  IntegerCoder ic_dy{32, 22};
  IntegerCoder ic_z{32, 20};
  std::array<std::unique_ptr<SymbolModel>, 64> classification, flags, user_data;
  IntegerCoder ic_intensity{16, 4};
  IntegerCoder ic_scan_angle{16, 2};
  IntegerCoder ic_point_source{16};
  GpsTimeState gps{kGpsZeroDiffSymbolsV3, kGpsMultiTotalV3};
  std::array<std::uint16_t, 8> last_intensity{};
  std::array<Median5, 12> last_x_diff, last_y_diff;
  std::array<std::int32_t, 8> last_z{};
};

}  // namespace relief::laz
