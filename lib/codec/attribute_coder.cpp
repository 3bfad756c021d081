// Mirror pair in one file: each attribute's encoder and decoder share one
// coding routine parameterised by the bit coder, as geometry_coder.cpp does.
#include "codec/attribute_coder.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cstdlib>
#include <memory>
#include <string>

#include "codec/color_window.h"
#include "codec/range_coder.h"

namespace relief::codec {

namespace {

// Magnitude classes of a residual: 0, 1, 2–3, 4–7, 8+.
constexpr int kClasses = 5;
int magnitude_class(std::int64_t q) {
  const std::uint64_t m = q < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(q) : static_cast<std::uint64_t>(q);
  if (m == 0) return 0;
  if (m == 1) return 1;
  if (m <= 3) return 2;
  if (m <= 7) return 3;
  return 4;
}

struct ColorModels {
  SIntModel green[kClasses];
  SIntModel red[kClasses][kClasses];
  SIntModel blue[kClasses][kClasses];
};

int clamp255(int v) { return std::clamp(v, 0, 255); }

// Quantises a residual to the near-lossless step (2t + 1): |e - q*step| <= t.
int quantise(int e, int t) {
  const int step = 2 * t + 1;
  return e >= 0 ? (e + t) / step : -((-e + t) / step);
}

// A colour's prediction and the model sets (first index) of its three
// channels.
struct ColorPrediction {
  int r = 0, g = 0, b = 0;
  int ctx_g = 0, ctx_r = 0, ctx_b = 0;
};

// §11.4: the previous point's colour; contexts from the classes of the
// previous point's symbols.
class PreviousColor {
 public:
  ColorPrediction predict(std::size_t) const { return {prev_.r, prev_.g, prev_.b, cls_g_, cls_r_, cls_b_}; }
  void update(std::size_t, const Rgb8& rec, int qr, int qg, int qb) {
    prev_ = {rec.r, rec.g, rec.b};
    cls_g_ = magnitude_class(qg);
    cls_r_ = magnitude_class(qr);
    cls_b_ = magnitude_class(qb);
  }

 private:
  struct {
    int r = 0, g = 0, b = 0;
  } prev_;
  int cls_g_ = 0, cls_r_ = 0, cls_b_ = 0;
};

static_assert(kColorWindow == 32, "color_window.cpp's vector form assumes a window of 32");

// §11.4.1: the previous kColorWindow points, each weighted by its inverse
// squared cell distance relative to the nearest one's (with a colour
// tolerance) or its square (exact colours, where the nearest should
// dominate). It keeps the decoded colours by channel, for the sums.
class NeighbourColor {
 public:
  NeighbourColor(std::span<const CellXyz> cells, int tolerance)
      : activity_(cells.size(), 0), exact_(tolerance == 0) {
    // One array per axis and per channel: the window's sums then vectorise.
    for (auto& axis : axes_) axis.resize(cells.size());
    for (auto& channel : channels_) channel.resize(cells.size());
    for (std::size_t i = 0; i < cells.size(); ++i) {
      for (int a = 0; a < 3; ++a) axes_[a][i] = cells[i][a];
    }
  }

  ColorPrediction predict(std::size_t i) const {
    if (i == 0) return {};
    const std::size_t window = std::min(i, kColorWindow);
    const std::size_t first = i - window;
    const ColorWindowView view{axes_[0].data(),     axes_[1].data(),     axes_[2].data(),  channels_[0].data(),
                               channels_[1].data(), channels_[2].data(), activity_.data()};
    const WindowSums sums = window_sums(view, first, i, exact_ ? weights<2>().data() : weights<1>().data());
    const std::uint64_t w_sum = sums.w, r = sums.r, g = sums.g, b = sums.b, act = sums.act;
    const std::uint64_t half = w_sum / 2;
    const int ctx = static_cast<int>(std::min<std::uint64_t>(kClasses - 1, 2 * act / (3 * w_sum)));
    return {static_cast<int>((r + half) / w_sum), static_cast<int>((g + half) / w_sum),
            static_cast<int>((b + half) / w_sum), ctx, ctx, ctx};
  }
  void update(std::size_t i, const Rgb8& rec, int qr, int qg, int qb) {
    channels_[0][i] = rec.r;
    channels_[1][i] = rec.g;
    channels_[2][i] = rec.b;
    activity_[i] = static_cast<std::uint8_t>(std::min(255, std::abs(qr) + std::abs(qg) + std::abs(qb)));
  }

 private:
  using WeightTable = std::array<std::uint32_t, kFarRatio + 1>;
  // w(r) = floor(2^30 / max(r, 1)^E): E = 1 with a colour tolerance, 2 for
  // exact colours.
  template <int E>
  static const WeightTable& weights() {
    static const WeightTable table = [] {
      WeightTable t{};
      for (std::uint32_t r = 0; r <= kFarRatio; ++r) {
        const std::uint64_t v = std::max<std::uint32_t>(r, 1);
        t[r] = static_cast<std::uint32_t>((std::uint64_t{1} << 30) / (E == 1 ? v : v * v));
      }
      return t;
    }();
    return table;
  }

  std::vector<std::uint32_t> axes_[3];      // the cells' x, y and z
  std::vector<std::uint8_t> channels_[3];   // the decoded colours' r, g and b
  std::vector<std::uint8_t> activity_;  // min(255, |qr| + |qg| + |qb|) of each coded point
  bool exact_;
};

// Codes n colours; `sym(model, q)` encodes q (encoder) or returns the decoded
// value (decoder, which passes 0), false on a bad stream. `truth(i)` is the
// input colour (encoder) and unused by the decoder. Writes the reconstruction.
template <typename Sym, typename Truth, typename Predictor>
bool code_colors(std::size_t n, int t, Sym&& sym, Truth&& truth, Predictor& predictor, std::vector<Rgb8>& out) {
  auto models = std::make_unique<ColorModels>();
  const int step = 2 * t + 1;
  out.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Rgb8 c = truth(i);
    const ColorPrediction p = predictor.predict(i);
    int qg = quantise(static_cast<int>(c.g) - p.g, t);
    if (!sym(models->green[p.ctx_g], qg)) return false;
    const int g = clamp255(p.g + qg * step);
    const int shift = g - p.g;
    const int cur_g = magnitude_class(qg);
    const int pr = clamp255(p.r + shift);
    int qr = quantise(static_cast<int>(c.r) - pr, t);
    if (!sym(models->red[p.ctx_r][cur_g], qr)) return false;
    const int pb = clamp255(p.b + shift);
    int qb = quantise(static_cast<int>(c.b) - pb, t);
    if (!sym(models->blue[p.ctx_b][cur_g], qb)) return false;
    const Rgb8 rec{static_cast<std::uint8_t>(clamp255(pr + qr * step)), static_cast<std::uint8_t>(g),
                   static_cast<std::uint8_t>(clamp255(pb + qb * step))};
    out[i] = rec;
    predictor.update(i, rec, qr, qg, qb);
  }
  return true;
}

// The encoder's and decoder's symbol functions.
auto encoder_symbol(RangeEncoder& enc) {
  return [&enc](SIntModel& m, int& q) {
    encode_sint(enc, m, q);
    return true;
  };
}
// The decoder's truth is never read: with it, each quantise() sees the
// negated prediction and the decoded symbol then replaces q.
auto decoder_symbol(RangeDecoder& dec) {
  return [&dec](SIntModel& m, int& q) {
    std::int64_t v = 0;
    if (!decode_sint(dec, m, v) || v < -255 || v > 255) return false;
    q = static_cast<int>(v);
    return true;
  };
}
Rgb8 no_truth(std::size_t) { return Rgb8{}; }

constexpr int kValueClasses = 12;
int value_class(std::int64_t r) {
  const std::uint64_t m = r < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(r) : static_cast<std::uint64_t>(r);
  int c = 0;
  for (std::uint64_t v = m; v != 0 && c < kValueClasses - 1; v >>= 2) ++c;
  return c;
}

}  // namespace

void encode_colors_into(RangeEncoder& enc, std::span<const Rgb8> colors, int tolerance, std::vector<Rgb8>* reconstructed) {
  std::vector<Rgb8> rec;
  PreviousColor predictor;
  code_colors(colors.size(), tolerance, encoder_symbol(enc), [&](std::size_t i) { return colors[i]; }, predictor, rec);
  if (reconstructed != nullptr) *reconstructed = std::move(rec);
}

bool decode_colors_from(RangeDecoder& dec, std::size_t count, int tolerance, std::vector<Rgb8>& out) {
  PreviousColor predictor;
  return code_colors(count, tolerance, decoder_symbol(dec), no_truth, predictor, out);
}

std::vector<std::uint8_t> encode_colors(std::span<const Rgb8> colors, int tolerance, std::vector<Rgb8>* reconstructed) {
  RangeEncoder enc;
  encode_colors_into(enc, colors, tolerance, reconstructed);
  return enc.finish();
}

Result<std::vector<Rgb8>> decode_colors(std::span<const std::uint8_t> data, std::size_t count, int tolerance) {
  RangeDecoder dec(data);
  std::vector<Rgb8> out;
  if (!decode_colors_from(dec, count, tolerance, out) || dec.overrun() > 0) {
    return corrupt_data("colour section: invalid or truncated stream");
  }
  return out;
}

std::vector<std::uint8_t> encode_colors_near(std::span<const Rgb8> colors, std::span<const CellXyz> cells,
                                             int tolerance, std::vector<Rgb8>* reconstructed) {
  RangeEncoder enc;
  std::vector<Rgb8> rec;
  NeighbourColor predictor(cells, tolerance);
  code_colors(colors.size(), tolerance, encoder_symbol(enc), [&](std::size_t i) { return colors[i]; }, predictor, rec);
  if (reconstructed != nullptr) *reconstructed = std::move(rec);
  return enc.finish();
}

Result<std::vector<Rgb8>> decode_colors_near(std::span<const std::uint8_t> data, std::span<const CellXyz> cells,
                                             int tolerance) {
  RangeDecoder dec(data);
  std::vector<Rgb8> out;
  NeighbourColor predictor(cells, tolerance);
  if (!code_colors(cells.size(), tolerance, decoder_symbol(dec), no_truth, predictor, out) || dec.overrun() > 0) {
    return corrupt_data("colour section: invalid or truncated stream");
  }
  return out;
}

std::vector<std::uint8_t> encode_values(std::span<const std::int64_t> values, int tolerance,
                                        std::vector<std::int64_t>* reconstructed) {
  RangeEncoder enc;
  auto models = std::make_unique<SIntModel[]>(kValueClasses);
  std::uint64_t prev = 0;
  int cls = 0;
  if (reconstructed) reconstructed->assign(values.begin(), values.end());
  if (tolerance == 0) {
    for (const std::int64_t v : values) {
      const auto r = static_cast<std::int64_t>(static_cast<std::uint64_t>(v) - prev);
      encode_sint(enc, models[cls], r);
      cls = value_class(r);
      prev = static_cast<std::uint64_t>(v);
    }
    return enc.finish();
  }
  // 16-bit values within the tolerance (format 12, §11.5): each residual
  // from the previous *decoded* value in steps of s = 2t + 1, the decoded
  // value clamped to 0..65535 (toward the input, so still within t).
  const std::int64_t s = 2 * std::int64_t{tolerance} + 1;
  std::int64_t last = 0;
  for (std::size_t i = 0; i < values.size(); ++i) {
    const std::int64_t e = values[i] - last;
    const std::int64_t q = e >= 0 ? (e + tolerance) / s : -((-e + tolerance) / s);
    encode_sint(enc, models[cls], q);
    cls = value_class(q);
    last = std::clamp<std::int64_t>(last + q * s, 0, kMaxUInt16Value);
    if (reconstructed) (*reconstructed)[i] = last;
  }
  return enc.finish();
}

Result<std::vector<std::int64_t>> decode_values(std::span<const std::uint8_t> data, std::size_t count, int tolerance) {
  RangeDecoder dec(data);
  auto models = std::make_unique<SIntModel[]>(kValueClasses);
  std::vector<std::int64_t> out(count);
  std::uint64_t prev = 0;
  int cls = 0;
  if (tolerance != 0) {
    const std::int64_t s = 2 * std::int64_t{tolerance} + 1;
    std::int64_t last = 0;
    for (std::size_t i = 0; i < count; ++i) {
      std::int64_t q = 0;
      if (!decode_sint(dec, models[cls], q) || q < -kMaxUInt16Value || q > kMaxUInt16Value) {
        return corrupt_data("attribute section: invalid or truncated stream");
      }
      last = std::clamp<std::int64_t>(last + q * s, 0, kMaxUInt16Value);
      out[i] = last;
      cls = value_class(q);
    }
    if (dec.overrun() > 0) return corrupt_data("attribute section: truncated stream");
    return out;
  }
  for (std::size_t i = 0; i < count; ++i) {
    std::int64_t r = 0;
    if (!decode_sint(dec, models[cls], r)) return corrupt_data("attribute section: invalid or truncated stream");
    prev += static_cast<std::uint64_t>(r);
    out[i] = static_cast<std::int64_t>(prev);
    cls = value_class(r);
  }
  if (dec.overrun() > 0) return corrupt_data("attribute section: truncated stream");
  return out;
}

}  // namespace relief::codec
