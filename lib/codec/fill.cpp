#include "codec/fill.h"

#include <algorithm>
#include <cmath>

namespace relief::codec {

namespace {

struct Level {
  int w = 0, h = 0;
  std::size_t offset = 0;  // into the scratch arrays, in pixels
};

constexpr int kBoxRadius = 2;  // 5x5
constexpr int kBoxPasses = 3;

}  // namespace

void fill_push_pull(float* tile, const std::uint8_t* occupied, int r, int channels,
                    FillScratch& scratch) {
  // Level 0 is the tile itself; coarser levels halve (rounding up) down to 1x1.
  Level levels[16];
  int count = 0;
  std::size_t total = 0;
  for (int w = r, h = r;; w = (w + 1) / 2, h = (h + 1) / 2) {
    levels[count++] = {w, h, total};
    total += static_cast<std::size_t>(w) * static_cast<std::size_t>(h);
    if (w == 1 && h == 1) break;
  }
  const auto nch = static_cast<std::size_t>(channels);
  scratch.values.resize(total * nch);
  scratch.weights.resize(total);
  float* val = scratch.values.data();
  float* wt = scratch.weights.data();

  const std::size_t n0 = static_cast<std::size_t>(r) * static_cast<std::size_t>(r);
  for (std::size_t i = 0; i < n0; ++i) {
    wt[i] = occupied[i] ? 1.0f : 0.0f;
    for (std::size_t c = 0; c < nch; ++c) val[i * nch + c] = occupied[i] ? tile[i * nch + c] : 0.0f;
  }
  // Push: weighted means of 2x2 children, weight saturating at 1.
  for (int l = 1; l < count; ++l) {
    const Level& fine = levels[l - 1];
    const Level& coarse = levels[l];
    for (int y = 0; y < coarse.h; ++y) {
      for (int x = 0; x < coarse.w; ++x) {
        float wsum = 0;
        float vsum[4] = {0, 0, 0, 0};
        for (int dy = 0; dy < 2; ++dy) {
          for (int dx = 0; dx < 2; ++dx) {
            const int fx = 2 * x + dx, fy = 2 * y + dy;
            if (fx >= fine.w || fy >= fine.h) continue;
            const std::size_t fi = fine.offset + static_cast<std::size_t>(fy * fine.w + fx);
            wsum += wt[fi];
            for (std::size_t c = 0; c < nch; ++c) vsum[c] += wt[fi] * val[fi * nch + c];
          }
        }
        const std::size_t ci = coarse.offset + static_cast<std::size_t>(y * coarse.w + x);
        wt[ci] = std::min(1.0f, wsum);
        for (std::size_t c = 0; c < nch; ++c) val[ci * nch + c] = wsum > 0 ? vsum[c] / wsum : 0.0f;
      }
    }
  }
  // Pull: blend each pixel with the bilinear sample of the coarser level.
  for (int l = count - 2; l >= 0; --l) {
    const Level& fine = levels[l];
    const Level& coarse = levels[l + 1];
    for (int y = 0; y < fine.h; ++y) {
      const float sy = std::clamp((static_cast<float>(y) + 0.5f) * 0.5f - 0.5f, 0.0f,
                                  static_cast<float>(coarse.h - 1));
      const int y0 = static_cast<int>(sy);
      const int y1 = std::min(y0 + 1, coarse.h - 1);
      const float fy = sy - static_cast<float>(y0);
      for (int x = 0; x < fine.w; ++x) {
        const std::size_t fi = fine.offset + static_cast<std::size_t>(y * fine.w + x);
        const float w = wt[fi];
        if (w >= 1.0f) continue;
        const float sx = std::clamp((static_cast<float>(x) + 0.5f) * 0.5f - 0.5f, 0.0f,
                                    static_cast<float>(coarse.w - 1));
        const int x0 = static_cast<int>(sx);
        const int x1 = std::min(x0 + 1, coarse.w - 1);
        const float fx = sx - static_cast<float>(x0);
        const std::size_t i00 = coarse.offset + static_cast<std::size_t>(y0 * coarse.w + x0);
        const std::size_t i01 = coarse.offset + static_cast<std::size_t>(y0 * coarse.w + x1);
        const std::size_t i10 = coarse.offset + static_cast<std::size_t>(y1 * coarse.w + x0);
        const std::size_t i11 = coarse.offset + static_cast<std::size_t>(y1 * coarse.w + x1);
        for (std::size_t c = 0; c < nch; ++c) {
          const float top = val[i00 * nch + c] * (1 - fx) + val[i01 * nch + c] * fx;
          const float bottom = val[i10 * nch + c] * (1 - fx) + val[i11 * nch + c] * fx;
          const float coarse_v = top * (1 - fy) + bottom * fy;
          val[fi * nch + c] = w * val[fi * nch + c] + (1 - w) * coarse_v;
        }
        wt[fi] = 1.0f;
      }
    }
  }
  for (std::size_t i = 0; i < n0; ++i) {
    if (occupied[i]) continue;
    for (std::size_t c = 0; c < nch; ++c) tile[i * nch + c] = val[i * nch + c];
  }
}

void fill_box(float* tile, const std::uint8_t* occupied, int r, int channels) {
  const auto nch = static_cast<std::size_t>(channels);
  const std::size_t n = static_cast<std::size_t>(r) * static_cast<std::size_t>(r);
  double mean[4] = {0, 0, 0, 0};
  std::size_t occ = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (!occupied[i]) continue;
    ++occ;
    for (std::size_t c = 0; c < nch; ++c) mean[c] += tile[i * nch + c];
  }
  if (occ == 0) return;
  for (std::size_t i = 0; i < n; ++i) {
    if (occupied[i]) continue;
    for (std::size_t c = 0; c < nch; ++c) {
      tile[i * nch + c] = static_cast<float>(mean[c] / static_cast<double>(occ));
    }
  }
  std::vector<float> prev(tile, tile + n * nch);
  for (int pass = 0; pass < kBoxPasses; ++pass) {
    for (int y = 0; y < r; ++y) {
      for (int x = 0; x < r; ++x) {
        const std::size_t i = static_cast<std::size_t>(y * r + x);
        if (occupied[i]) continue;
        float sum[4] = {0, 0, 0, 0};
        int cnt = 0;
        for (int yy = std::max(0, y - kBoxRadius); yy <= std::min(r - 1, y + kBoxRadius); ++yy) {
          for (int xx = std::max(0, x - kBoxRadius); xx <= std::min(r - 1, x + kBoxRadius); ++xx) {
            const std::size_t j = static_cast<std::size_t>(yy * r + xx);
            for (std::size_t c = 0; c < nch; ++c) sum[c] += prev[j * nch + c];
            ++cnt;
          }
        }
        for (std::size_t c = 0; c < nch; ++c) tile[i * nch + c] = sum[c] / static_cast<float>(cnt);
      }
    }
    std::copy(tile, tile + n * nch, prev.begin());
  }
}

}  // namespace relief::codec
