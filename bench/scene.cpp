#include "scene.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>

namespace relief::bench {

namespace {

constexpr double kTwoPi = 6.283185307179586;
constexpr double kBlock = 48;     // building plots, metres
constexpr double kTreeCell = 7;   // one possible tree per cell, metres
constexpr double kPulsesPerSecond = 100000;

// sin() by table and linear interpolation: the generator must stay far faster
// than the ingest it feeds (a few ns per call instead of tens).
class SineTable {
 public:
  static constexpr int kSize = 4096;
  SineTable() {
    for (int i = 0; i <= kSize; ++i) t_[static_cast<std::size_t>(i)] = std::sin(kTwoPi * i / kSize);
  }
  double operator()(double radians) const {
    const double u = radians * (kSize / kTwoPi);
    const double f = std::floor(u);
    const auto i = static_cast<std::size_t>(static_cast<std::int64_t>(f) & (kSize - 1));
    return t_[i] + (u - f) * (t_[i + 1] - t_[i]);
  }

 private:
  std::array<double, kSize + 1> t_{};
};

const SineTable& sine() {
  static const SineTable table;
  return table;
}

std::uint64_t mix(std::uint64_t z) {  // SplitMix64's finaliser
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

double unit(std::uint64_t bits) { return static_cast<double>(bits & 0xffff) * (1.0 / 65535.0); }

void put_u16(unsigned char* p, std::uint16_t v) {
  p[0] = static_cast<unsigned char>(v);
  p[1] = static_cast<unsigned char>(v >> 8);
}
void put_u32(unsigned char* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<unsigned char>(v >> (8 * i));
}
void put_f64(unsigned char* p, double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, 8);
  for (int i = 0; i < 8; ++i) p[i] = static_cast<unsigned char>(b >> (8 * i));
}
std::uint8_t clamp8(double v) { return static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0)); }

}  // namespace

AerialScene::AerialScene(std::uint64_t points, std::uint64_t seed) : points_(points), seed_(seed) {
  // At least one point per pulse, so side^2 x 16 pulses/m^2 >= points always
  // holds enough pulses; tree pulses (two returns) end the scene a little early.
  const double side = std::max(kSwath, std::sqrt(static_cast<double>(points)) * kPulseSpacing);
  strips_ = static_cast<std::uint64_t>(std::ceil(side / kSwath));
  strip_lines_ = static_cast<std::uint64_t>(std::ceil(side / kPulseSpacing));
  line_pulses_ = static_cast<std::uint64_t>(kSwath / kPulseSpacing);
  side_ = static_cast<double>(strips_) * kSwath;
  (void)sine();
  start_line();
}

std::uint64_t AerialScene::hash(std::uint64_t a, std::uint64_t b) const {
  return mix(seed_ ^ mix(a * 0x9e3779b97f4a7c15ULL + b));
}

double AerialScene::ground(double x, double y) const {
  const SineTable& s = sine();
  const double cy1 = y == line_y_ ? cy1_ : s(y / 770 + kTwoPi / 4);
  const double sy3 = y == line_y_ ? sy3_ : s(y / 53);
  return 100 + 20 * s(x / 610) * cy1 + 6 * s((x + 2 * y) / 230) + 1.5 * s(x / 37) * sy3;
}

void AerialScene::start_line() {
  line_y_ = static_cast<double>(line_) * kPulseSpacing;
  cy1_ = sine()(line_y_ / 770 + kTwoPi / 4);
  sy3_ = sine()(line_y_ / 53);
}

AerialScene::Hit AerialScene::surface(double x, double y, double g, bool* tree) const {
  const SineTable& s = sine();
  *tree = false;
  Hit h{};
  // Built-up districts and woodland alternate over kilometres.
  const double urban = s(x / 1500 + 0.3) + s(y / 1300 + 1.1);
  const auto bx = static_cast<std::int64_t>(std::floor(x / kBlock));
  const auto by = static_cast<std::int64_t>(std::floor(y / kBlock));
  const std::uint64_t hb = hash(static_cast<std::uint64_t>(bx), static_cast<std::uint64_t>(by) ^ 0xb1d9ULL);
  if (urban > -0.3 && (hb & 0xff) < 190) {
    const double w = 12 + unit(hb >> 8) * 18, d = 12 + unit(hb >> 16) * 18;
    const double x0 = static_cast<double>(bx) * kBlock + 4 + unit(hb >> 24) * (kBlock - 8 - w);
    const double y0 = static_cast<double>(by) * kBlock + 4 + unit(hb >> 32) * (kBlock - 8 - d);
    if (x >= x0 && x < x0 + w && y >= y0 && y < y0 + d) {
      const double base = ground(x0 + w / 2, y0 + d / 2);
      const double height = 6 + unit(hb >> 40) * 18;
      const bool gabled = ((hb >> 56) & 1) != 0;
      h.z = base + height + (gabled ? 0.6 * (d / 2 - std::fabs(y - y0 - d / 2)) : 0);
      static constexpr std::uint8_t kRoofs[4][3] = {{150, 70, 55}, {110, 110, 115}, {70, 72, 80}, {170, 160, 150}};
      const auto& c = kRoofs[(hb >> 57) & 3];
      h.rgb[0] = c[0], h.rgb[1] = c[1], h.rgb[2] = c[2];
      h.cls = 6;
      h.intensity = static_cast<std::uint16_t>(1500 + ((hb >> 59) & 0x1f) * 30);
      return h;
    }
  }
  const auto tx = static_cast<std::int64_t>(std::floor(x / kTreeCell));
  const auto ty = static_cast<std::int64_t>(std::floor(y / kTreeCell));
  const std::uint64_t ht = hash(static_cast<std::uint64_t>(tx), static_cast<std::uint64_t>(ty) ^ 0x7ee5ULL);
  if ((ht & 0xff) < (urban > -0.3 ? 40u : 150u)) {
    const double r = 1.8 + unit(ht >> 8) * 1.4;
    const double cx = (static_cast<double>(tx) + 0.5) * kTreeCell + (unit(ht >> 24) - 0.5) * 0.4;
    const double cy = (static_cast<double>(ty) + 0.5) * kTreeCell + (unit(ht >> 40) - 0.5) * 0.4;
    const double d2 = ((x - cx) * (x - cx) + (y - cy) * (y - cy)) / (r * r);
    if (d2 < 1) {
      const double height = 8 + unit(ht >> 48) * 12;
      h.z = g + height * (0.55 + 0.45 * std::sqrt(1 - d2));
      h.cls = 5;
      h.rgb[0] = clamp8(40 + 30 * d2), h.rgb[1] = clamp8(90 + 40 * d2), h.rgb[2] = 35;
      h.intensity = static_cast<std::uint16_t>(250 + 200 * d2);
      *tree = true;
      return h;
    }
  }
  const double grass = 0.5 + 0.25 * (s(x / 23) + s(y / 29 + 0.7));
  h.z = g;
  h.cls = 2;
  h.rgb[0] = clamp8(80 + 50 * grass), h.rgb[1] = clamp8(100 + 40 * grass), h.rgb[2] = clamp8(55 + 20 * grass);
  h.intensity = static_cast<std::uint16_t>(450 + 400 * grass);
  return h;
}

void AerialScene::put(unsigned char* p, double x, double y, const Hit& h, int ret, int returns, bool edge) const {
  // Scene coordinates are relative to the LAS offset already.
  const auto q = [](double v) {
    return static_cast<std::uint32_t>(static_cast<std::int32_t>(std::lround(v / kScale)));
  };
  put_u32(p, q(x));
  put_u32(p + 4, q(y));
  put_u32(p + 8, q(h.z));
  const std::uint64_t noise = hash(pulse_count_, static_cast<std::uint64_t>(ret));
  put_u16(p + 12, static_cast<std::uint16_t>(h.intensity + (noise & 0x3f)));
  const int direction = (line_ & 1) == 0 ? 1 : 0;
  p[14] = static_cast<unsigned char>(ret | (returns << 3) | (direction << 6) | ((edge ? 1 : 0) << 7));
  p[15] = h.cls;
  // Scan angle: -15 to +15 degrees across the swath.
  const double across = x - static_cast<double>(strip_) * kSwath;
  p[16] = static_cast<unsigned char>(static_cast<std::int8_t>(std::lround((across / kSwath - 0.5) * 30)));
  p[17] = 0;  // user data
  put_u16(p + 18, static_cast<std::uint16_t>(strip_ + 1));
  // One pulse every 10 us; a minute's turn between strips.
  put_f64(p + 20, 3.0e5 + static_cast<double>(pulse_count_) / kPulsesPerSecond + 60.0 * static_cast<double>(strip_));
  for (int c = 0; c < 3; ++c) {
    const int jitter = static_cast<int>((noise >> (8 + 8 * c)) & 0xf) - 8;
    put_u16(p + 28 + 2 * c, static_cast<std::uint16_t>(clamp8(h.rgb[c] + jitter) * 257));
  }
}

std::size_t AerialScene::next(unsigned char* out, std::size_t n) {
  std::size_t written = 0;
  while (written < n && emitted_ < points_ && strip_ < strips_) {
    // Zigzag: even lines run left to right across the strip.
    const std::uint64_t k = (line_ & 1) == 0 ? pulse_ : line_pulses_ - 1 - pulse_;
    const std::uint64_t jit = hash(pulse_count_, 0x9e37ULL);
    const double x = static_cast<double>(strip_) * kSwath + (static_cast<double>(k) + 0.5) * kPulseSpacing +
                     (unit(jit) - 0.5) * 0.1;
    const double y = line_y_ + (unit(jit >> 16) - 0.5) * 0.1;
    const double g = ground(x, y);
    bool tree = false;
    const Hit h = surface(x, y, g, &tree);
    const bool edge = pulse_ + 1 == line_pulses_;
    // A tree gives its canopy and the ground beneath, when both fit.
    const bool two = tree && points_ - emitted_ >= 2;
    if (two && n - written < 2) break;
    put(out + written * kRecordBytes, x, y, h, 1, two ? 2 : 1, edge);
    ++written;
    if (two) {
      Hit under{};
      under.z = g;
      under.cls = 2;
      under.rgb[0] = 95, under.rgb[1] = 85, under.rgb[2] = 60;
      under.intensity = 150;
      put(out + written * kRecordBytes, x, y, under, 2, 2, edge);
      ++written;
    }
    emitted_ += two ? 2 : 1;
    ++pulse_count_;
    if (++pulse_ == line_pulses_) {
      pulse_ = 0;
      if (++line_ == strip_lines_) {
        line_ = 0;
        ++strip_;
      }
      start_line();
    }
  }
  return written;
}

std::vector<unsigned char> AerialScene::header() const {
  std::vector<unsigned char> h(kHeaderBytes, 0);
  std::memcpy(h.data(), "LASF", 4);
  h[24] = 1, h[25] = 2;  // LAS 1.2
  std::memcpy(h.data() + 26, "relief bench", 12);
  std::memcpy(h.data() + 58, "bench/ingest --billion", 22);
  put_u16(h.data() + 90, 1);
  put_u16(h.data() + 92, 2026);
  put_u16(h.data() + 94, static_cast<std::uint16_t>(kHeaderBytes));
  put_u32(h.data() + 96, static_cast<std::uint32_t>(kHeaderBytes));
  put_u32(h.data() + 100, 0);  // no VLRs
  h[104] = 3;
  put_u16(h.data() + 105, static_cast<std::uint16_t>(kRecordBytes));
  // The legacy 32-bit count: enough up to 4.29 billion points.
  put_u32(h.data() + 107, static_cast<std::uint32_t>(points_));
  for (int i = 0; i < 3; ++i) put_f64(h.data() + 131 + 8 * i, kScale);
  put_f64(h.data() + 155, kOffsetX);
  put_f64(h.data() + 163, kOffsetY);
  put_f64(h.data() + 171, kOffsetZ);
  // Bounds: the whole scene (its last strip may end early); z from the
  // terrain's range and the tallest roof or tree.
  const double length = static_cast<double>(strip_lines_) * kPulseSpacing;
  put_f64(h.data() + 179, kOffsetX + side_);
  put_f64(h.data() + 187, kOffsetX);
  put_f64(h.data() + 195, kOffsetY + length);
  put_f64(h.data() + 203, kOffsetY);
  put_f64(h.data() + 211, kOffsetZ + 200);
  put_f64(h.data() + 219, kOffsetZ + 60);
  return h;
}

}  // namespace relief::bench
