// Mirror pair in one file: each attribute's encoder and decoder share one
// coding routine parameterised by the bit coder, as geometry_coder.cpp does.
#include "codec/attribute_coder.h"

#include <algorithm>
#include <memory>
#include <string>

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

// Codes n colours; `sym(model, q)` encodes q (encoder) or returns the decoded
// value (decoder, which passes 0), false on a bad stream. `truth(i)` is the
// input colour (encoder) and unused by the decoder. Writes the reconstruction.
template <typename Sym, typename Truth>
bool code_colors(std::size_t n, int t, Sym&& sym, Truth&& truth, std::vector<Rgb8>& out) {
  auto models = std::make_unique<ColorModels>();
  const int step = 2 * t + 1;
  out.resize(n);
  Rgb8 prev{0, 0, 0};
  int cls_r = 0, cls_g = 0, cls_b = 0;
  for (std::size_t i = 0; i < n; ++i) {
    const Rgb8 c = truth(i);
    int qg = quantise(static_cast<int>(c.g) - prev.g, t);
    if (!sym(models->green[cls_g], qg)) return false;
    const int g = clamp255(prev.g + qg * step);
    const int shift = g - prev.g;
    const int cur_g = magnitude_class(qg);
    const int pr = clamp255(prev.r + shift);
    int qr = quantise(static_cast<int>(c.r) - pr, t);
    if (!sym(models->red[cls_r][cur_g], qr)) return false;
    const int pb = clamp255(prev.b + shift);
    int qb = quantise(static_cast<int>(c.b) - pb, t);
    if (!sym(models->blue[cls_b][cur_g], qb)) return false;
    const Rgb8 rec{static_cast<std::uint8_t>(clamp255(pr + qr * step)), static_cast<std::uint8_t>(g),
                   static_cast<std::uint8_t>(clamp255(pb + qb * step))};
    out[i] = rec;
    prev = rec;
    cls_g = cur_g;
    cls_r = magnitude_class(qr);
    cls_b = magnitude_class(qb);
  }
  return true;
}

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
  code_colors(
      colors.size(), tolerance,
      [&](SIntModel& m, int& q) {
        encode_sint(enc, m, q);
        return true;
      },
      [&](std::size_t i) { return colors[i]; }, rec);
  if (reconstructed != nullptr) *reconstructed = std::move(rec);
}

bool decode_colors_from(RangeDecoder& dec, std::size_t count, int tolerance, std::vector<Rgb8>& out) {
  // The decoder's truth is never read: with it, each quantise() sees 0 and
  // the decoded symbol then replaces q.
  return code_colors(
      count, tolerance,
      [&](SIntModel& m, int& q) {
        std::int64_t v = 0;
        if (!decode_sint(dec, m, v) || v < -255 || v > 255) return false;
        q = static_cast<int>(v);
        return true;
      },
      [](std::size_t) { return Rgb8{}; }, out);
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

std::vector<std::uint8_t> encode_values(std::span<const std::int64_t> values) {
  RangeEncoder enc;
  auto models = std::make_unique<SIntModel[]>(kValueClasses);
  std::uint64_t prev = 0;
  int cls = 0;
  for (const std::int64_t v : values) {
    const auto r = static_cast<std::int64_t>(static_cast<std::uint64_t>(v) - prev);
    encode_sint(enc, models[cls], r);
    cls = value_class(r);
    prev = static_cast<std::uint64_t>(v);
  }
  return enc.finish();
}

Result<std::vector<std::int64_t>> decode_values(std::span<const std::uint8_t> data, std::size_t count) {
  RangeDecoder dec(data);
  auto models = std::make_unique<SIntModel[]>(kValueClasses);
  std::vector<std::int64_t> out(count);
  std::uint64_t prev = 0;
  int cls = 0;
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
