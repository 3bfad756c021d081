#include "relief/render.h"

#include <png.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <csetjmp>
#include <cstdio>
#include <cstring>
#include <limits>
#include <new>

namespace relief {

namespace {

constexpr double kPi = 3.14159265358979323846;
constexpr float kEmpty = -std::numeric_limits<float>::infinity();
// Colour for points without RGB in a coloured preview (an archive whose
// scans disagree about colours): a light grey that the shading still models.
constexpr std::uint32_t kNoColor = 0xAAAAAA;
constexpr Rgb8 kWhite{255, 255, 255};
constexpr Rgb8 kDark{16, 16, 20};
// Coarsest pyramid level: 1/32 of the output resolution.
constexpr int kMaxLevel = 5;
// A point this many pixels behind most of its neighbours is hidden by them
// (oblique view): flat ground at 35 degrees steps about 1.4 pixels a row.
constexpr double kHiddenDepth = 4;
// Coarser levels that fill the holes left at the level drawn.
constexpr std::size_t kFillLevels = 2;
// Air around an oblique view, as a share of its larger extent.
constexpr double kObliqueMargin = 0.02;
// Points an oblique view keeps (20 bytes each) to fit the image to them: a
// lod-16 preview of a 60 M-point archive. Beyond, it streams into the frame.
constexpr std::size_t kMaxBufferedPoints = std::size_t{3} << 20;

double dot(const Vec3d& a, const Vec3d& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }

// ---- Height colour map --------------------------------------------------
// Nine stops of a perceptually ordered ramp from dark violet through blue,
// teal and green to yellow (close to matplotlib's viridis): lightness rises
// monotonically, so heights read correctly in greyscale and for most colour
// blind viewers.
constexpr std::array<Rgb8, 9> kRampStops = {{
    {68, 2, 86},
    {72, 40, 120},
    {62, 74, 137},
    {49, 104, 142},
    {38, 130, 142},
    {31, 158, 137},
    {53, 183, 121},
    {109, 205, 89},
    {180, 222, 44},
}};
// The top stop, kept apart so the ramp ends on a clear yellow.
constexpr Rgb8 kRampTop{250, 231, 35};

std::array<Rgb8, 256> build_ramp() {
  std::array<Rgb8, 256> lut{};
  constexpr int kSegments = static_cast<int>(kRampStops.size());  // 9 stops + the top = 9 segments
  for (int i = 0; i < 256; ++i) {
    const double t = i / 255.0 * kSegments;
    const int s = std::min(static_cast<int>(t), kSegments - 1);
    const double f = t - s;
    const Rgb8 a = kRampStops[static_cast<std::size_t>(s)];
    const Rgb8 b = s + 1 < kSegments ? kRampStops[static_cast<std::size_t>(s + 1)] : kRampTop;
    const auto mix = [f](std::uint8_t x, std::uint8_t y) {
      return static_cast<std::uint8_t>(std::lround(x + (y - x) * f));
    };
    lut[static_cast<std::size_t>(i)] = {mix(a.r, b.r), mix(a.g, b.g), mix(a.b, b.b)};
  }
  return lut;
}

// ---- A 5x7 bitmap font: each row is 5 bits, the leftmost pixel in bit 4. ----
struct Glyph {
  char c;
  std::uint8_t rows[7];
};

constexpr Glyph kFont[] = {
    {'0', {0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E}},
    {'1', {0x04, 0x0C, 0x04, 0x04, 0x04, 0x04, 0x0E}},
    {'2', {0x0E, 0x11, 0x01, 0x02, 0x04, 0x08, 0x1F}},
    {'3', {0x1F, 0x02, 0x04, 0x02, 0x01, 0x11, 0x0E}},
    {'4', {0x02, 0x06, 0x0A, 0x12, 0x1F, 0x02, 0x02}},
    {'5', {0x1F, 0x10, 0x1E, 0x01, 0x01, 0x11, 0x0E}},
    {'6', {0x06, 0x08, 0x10, 0x1E, 0x11, 0x11, 0x0E}},
    {'7', {0x1F, 0x01, 0x02, 0x04, 0x08, 0x08, 0x08}},
    {'8', {0x0E, 0x11, 0x11, 0x0E, 0x11, 0x11, 0x0E}},
    {'9', {0x0E, 0x11, 0x11, 0x0F, 0x01, 0x02, 0x0C}},
    {'.', {0x00, 0x00, 0x00, 0x00, 0x00, 0x0C, 0x0C}},
    {'-', {0x00, 0x00, 0x00, 0x0E, 0x00, 0x00, 0x00}},
    {'m', {0x00, 0x00, 0x1A, 0x15, 0x15, 0x15, 0x15}},
    {'k', {0x10, 0x10, 0x12, 0x14, 0x18, 0x14, 0x12}},
    {'N', {0x11, 0x19, 0x15, 0x13, 0x11, 0x11, 0x11}},
    // For the oblique view's "az 30 el 35".
    {'a', {0x00, 0x00, 0x0E, 0x01, 0x0F, 0x11, 0x0F}},
    {'z', {0x00, 0x00, 0x1F, 0x02, 0x04, 0x08, 0x1F}},
    {'e', {0x00, 0x00, 0x0E, 0x11, 0x1F, 0x10, 0x0E}},
    {'l', {0x0C, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E}},
};
constexpr int kGlyphW = 5;
constexpr int kGlyphH = 7;

const Glyph* find_glyph(char c) {
  for (const Glyph& g : kFont) {
    if (g.c == c) return &g;
  }
  return nullptr;  // space and anything unknown: blank
}

// ---- Drawing on the finished image (clipped) ----------------------------

void fill_rect(PreviewImage& img, int x0, int y0, int x1, int y1, Rgb8 c) {
  x0 = std::max(x0, 0);
  y0 = std::max(y0, 0);
  x1 = std::min(x1, img.width);
  y1 = std::min(y1, img.height);
  for (int y = y0; y < y1; ++y) {
    std::uint8_t* p = img.rgb.data() + (static_cast<std::size_t>(y) * img.width + x0) * 3;
    for (int x = x0; x < x1; ++x, p += 3) {
      p[0] = c.r;
      p[1] = c.g;
      p[2] = c.b;
    }
  }
}

int text_width(const std::string& text, int scale) {
  return text.empty() ? 0 : static_cast<int>(text.size()) * (kGlyphW + 1) * scale - scale;
}

// White text with a one-pixel dark outline, readable on any background.
void draw_text(PreviewImage& img, int x, int y, const std::string& text, int scale) {
  for (int pass = 0; pass < 2; ++pass) {
    const int grow = pass == 0 ? 1 : 0;
    const Rgb8 colour = pass == 0 ? kDark : kWhite;
    int cx = x;
    for (char ch : text) {
      if (const Glyph* g = find_glyph(ch)) {
        for (int row = 0; row < kGlyphH; ++row) {
          for (int col = 0; col < kGlyphW; ++col) {
            if (!((g->rows[row] >> (kGlyphW - 1 - col)) & 1)) continue;
            const int px = cx + col * scale, py = y + row * scale;
            fill_rect(img, px - grow, py - grow, px + scale + grow, py + scale + grow, colour);
          }
        }
      }
      cx += (kGlyphW + 1) * scale;
    }
  }
}

// A triangle pointing up, apex at (cx, top), `h` rows, base half-width `hw`.
void fill_up_triangle(PreviewImage& img, int cx, int top, int h, int hw, int grow, Rgb8 c) {
  for (int t = -grow; t < h + grow; ++t) {
    const int tt = std::clamp(t, 0, h - 1);
    const int half = static_cast<int>(std::lround(static_cast<double>(hw) * (tt + 1) / h)) + grow;
    fill_rect(img, cx - half, top + t, cx + half + 1, top + t + 1, c);
  }
}

std::string format_number(double v) {
  char buf[32];
  if (v == std::floor(v) && std::fabs(v) < 1e15) {
    std::snprintf(buf, sizeof buf, "%.0f", v);
  } else {
    std::snprintf(buf, sizeof buf, "%.1f", v);
  }
  return buf;
}

// ---- PNG output through libpng -------------------------------------------

struct PngSink {
  std::vector<std::uint8_t>* out = nullptr;
  char message[200] = "";
};

void png_on_error(png_structp png, png_const_charp message) {
  auto* sink = static_cast<PngSink*>(png_get_error_ptr(png));
  std::snprintf(sink->message, sizeof sink->message, "%s", message ? message : "unknown error");
  png_longjmp(png, 1);  // back to the setjmp in write_png_rows
}

void png_on_warning(png_structp, png_const_charp) {}  // previews do not care

void png_on_write(png_structp png, png_bytep data, png_size_t length) {
  auto* sink = static_cast<PngSink*>(png_get_io_ptr(png));
  bool failed = false;
  try {
    sink->out->insert(sink->out->end(), data, data + length);
  } catch (const std::bad_alloc&) {
    failed = true;
  }
  // Outside the catch block: png_error does not return (it longjmps).
  if (failed) png_error(png, "out of memory");
}

void png_on_flush(png_structp) {}

// libpng reports errors by longjmp, which skips C++ destructors: this
// function therefore holds only trivially destructible locals, and its
// pointers are not changed after setjmp.
bool write_png_rows(const PreviewImage* image, PngSink* sink, int level) {
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, sink, png_on_error, png_on_warning);
  if (png == nullptr) {
    std::snprintf(sink->message, sizeof sink->message, "cannot create the PNG writer");
    return false;
  }
  png_infop info = png_create_info_struct(png);
  if (info == nullptr) {
    png_destroy_write_struct(&png, nullptr);
    std::snprintf(sink->message, sizeof sink->message, "cannot create the PNG header");
    return false;
  }
  if (setjmp(png_jmpbuf(png))) {
    png_destroy_write_struct(&png, &info);
    return false;
  }
  png_set_write_fn(png, sink, png_on_write, png_on_flush);
  png_set_compression_level(png, level);
  // Sub and Up only: most of the gain of adaptive filtering on these
  // smooth images at a fraction of Paeth's cost.
  png_set_filter(png, PNG_FILTER_TYPE_BASE, PNG_FILTER_SUB | PNG_FILTER_UP);
  png_set_IHDR(png, info, static_cast<png_uint_32>(image->width), static_cast<png_uint_32>(image->height), 8,
               PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  const std::size_t stride = static_cast<std::size_t>(image->width) * 3;
  for (int y = 0; y < image->height; ++y) {
    png_write_row(png, image->rgb.data() + static_cast<std::size_t>(y) * stride);
  }
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return true;
}

}  // namespace

Rgb8 PreviewImage::at(int x, int y) const {
  const std::uint8_t* p = rgb.data() + (static_cast<std::size_t>(y) * width + x) * 3;
  return {p[0], p[1], p[2]};
}

Result<PreviewRenderer> PreviewRenderer::create(const Box3d& frame, const PreviewOptions& options) {
  if (frame.empty()) return invalid_argument("preview: the region to show is empty");
  if (options.width < 1 || options.width > kMaxPreviewSide) {
    return invalid_argument("preview: width must be from 1 to " + std::to_string(kMaxPreviewSide) + " pixels");
  }
  const bool oblique = options.view == PreviewView::kOblique;
  const bool xy_finite = std::isfinite(frame.min.x) && std::isfinite(frame.max.x) && std::isfinite(frame.min.y) &&
                         std::isfinite(frame.max.y);
  const bool z_finite = std::isfinite(frame.min.z) && std::isfinite(frame.max.z);
  if (!xy_finite || (oblique && !z_finite)) {
    return invalid_argument("preview: the region to show must be finite (x and y; z too for the oblique view)");
  }

  PreviewRenderer r;
  r.options_ = options;
  r.origin_ = {0.5 * (frame.min.x + frame.max.x), 0.5 * (frame.min.y + frame.max.y),
               z_finite ? 0.5 * (frame.min.z + frame.max.z) : 0.0};
  if (oblique) {
    if (!std::isfinite(options.azimuth_deg) || !(options.elevation_deg >= 0 && options.elevation_deg <= 90)) {
      return invalid_argument("preview: the elevation must be from 0 to 90 degrees and the azimuth finite");
    }
    // Rotation by the azimuth about z, then a tilt about the new x axis so
    // the viewer looks down at the elevation angle: these are the rows of
    // that rotation (elevation 90 gives the top view).
    const double a = options.azimuth_deg * kPi / 180.0, e = options.elevation_deg * kPi / 180.0;
    const double ca = std::cos(a), sa = std::sin(a), ce = std::cos(e), se = std::sin(e);
    r.right_ = {ca, -sa, 0};
    r.up_ = {sa * se, ca * se, ce};
    r.toward_ = {-sa * ce, -ca * ce, se};
  }

  r.separate_height_ = oblique && !options.use_colors;
  // Extent of the frame on the screen.
  double umin = +std::numeric_limits<double>::infinity(), umax = -umin, vmin = umin, vmax = -umin;
  if (!oblique) {
    umin = frame.min.x - r.origin_.x;
    umax = frame.max.x - r.origin_.x;
    vmin = frame.min.y - r.origin_.y;
    vmax = frame.max.y - r.origin_.y;
    r.set_geometry(umin, umax, vmin, vmax, 0);
    RELIEF_RETURN_IF_ERROR(r.allocate_levels());
  } else {
    for (int corner = 0; corner < 8; ++corner) {
      const Vec3d p{((corner & 1) ? frame.max.x : frame.min.x) - r.origin_.x,
                    ((corner & 2) ? frame.max.y : frame.min.y) - r.origin_.y,
                    ((corner & 4) ? frame.max.z : frame.min.z) - r.origin_.z};
      const double u = dot(p, r.right_), v = dot(p, r.up_);
      umin = std::min(umin, u);
      umax = std::max(umax, u);
      vmin = std::min(vmin, v);
      vmax = std::max(vmax, v);
    }
    r.frame_extent_ = {umin, umax, vmin, vmax};
    // The projected box is a loose fit (its corners are rarely all filled,
    // and scans are seldom box-shaped), so the points are kept, projected,
    // and the image is fitted to them at the end.
    r.set_geometry(umin, umax, vmin, vmax, kObliqueMargin);
    r.buffering_ = true;
  }
  return r;
}

void PreviewRenderer::set_geometry(double umin, double umax, double vmin, double vmax, double margin) {
  double eu = umax - umin, ev = vmax - vmin;
  // A little air around an oblique view: points on the silhouette look
  // cramped against the border.
  const double pad = margin * std::max(eu, ev);
  umin -= pad;
  umax += pad;
  vmin -= pad;
  vmax += pad;
  eu = umax - umin;
  ev = vmax - vmin;
  // A frame flat in one direction (points on a line, one point) still needs
  // a finite aspect ratio.
  const double floor_extent = std::max({eu, ev, 0.0}) / kMaxPreviewSide;
  if (floor_extent == 0) {
    eu = ev = 1;
  } else {
    eu = std::max(eu, floor_extent);
    ev = std::max(ev, floor_extent);
  }
  int w = options_.width;
  long long h = std::max(1LL, std::llround(static_cast<double>(w) * ev / eu));
  if (h > kMaxPreviewSide) {
    h = kMaxPreviewSide;
    w = static_cast<int>(std::max(1LL, std::llround(kMaxPreviewSide * eu / ev)));
  }
  width_ = w;
  height_ = static_cast<int>(h);
  pixel_size_ = std::max(eu / width_, ev / height_);
  u_left_ = 0.5 * (umin + umax) - 0.5 * width_ * pixel_size_;
  v_top_ = 0.5 * (vmin + vmax) + 0.5 * height_ * pixel_size_;
}

Status PreviewRenderer::allocate_levels() {
  levels_.clear();
  try {
    int lw = width_, lh = height_;
    // Halving down to 1/32 of the resolution (points 30 pixels apart, about
    // lod 1000 on dense data) while a level keeps a few pixels a side.
    for (int k = 0; k <= kMaxLevel; ++k) {
      Level level;
      level.width = lw;
      level.height = lh;
      const std::size_t pixels = static_cast<std::size_t>(lw) * static_cast<std::size_t>(lh);
      level.depth.assign(pixels, kEmpty);
      if (options_.use_colors) level.color.assign(pixels, 0);
      if (separate_height_) level.height_z.assign(pixels, 0.0f);
      levels_.push_back(std::move(level));
      if (std::min(lw, lh) < 16) break;
      lw = (lw + 1) / 2;
      lh = (lh + 1) / 2;
    }
  } catch (const std::bad_alloc&) {
    levels_.clear();
    return limit_exceeded("preview: not enough memory for a " + std::to_string(width_) + " x " +
                          std::to_string(height_) + " image");
  }
  return Status::ok();
}

Status PreviewRenderer::draw_buffer(bool fit) {
  if (fit && !buffer_.empty()) {
    float umin = buffer_[0].u, umax = umin, vmin = buffer_[0].v, vmax = vmin;
    for (const Projected& q : buffer_) {
      umin = std::min(umin, q.u);
      umax = std::max(umax, q.u);
      vmin = std::min(vmin, q.v);
      vmax = std::max(vmax, q.v);
    }
    set_geometry(umin, umax, vmin, vmax, kObliqueMargin);
  } else {
    set_geometry(frame_extent_[0], frame_extent_[1], frame_extent_[2], frame_extent_[3], kObliqueMargin);
  }
  RELIEF_RETURN_IF_ERROR(allocate_levels());
  for (const Projected& q : buffer_) draw(q.u, q.v, q.depth, q.z, q.color);
  buffer_.clear();
  buffer_.shrink_to_fit();
  buffering_ = false;
  return Status::ok();
}

void PreviewRenderer::draw(double u, double v, float depth, float z, std::uint32_t color) {
  const double fx = (u - u_left_) / pixel_size_;
  const double fy = (v_top_ - v) / pixel_size_;
  // Written so that NaN fails too. A point exactly on the frame's max edge
  // belongs to the last column or row.
  if (!(fx >= 0 && fx <= width_ && fy >= 0 && fy <= height_)) return;
  const int cx = std::min(static_cast<int>(fx), width_ - 1);
  const int cy = std::min(static_cast<int>(fy), height_ - 1);
  ++points_drawn_;
  const bool colors = options_.use_colors;
  for (std::size_t k = 0; k < levels_.size(); ++k) {
    Level& level = levels_[k];
    const std::size_t idx = static_cast<std::size_t>(cy >> k) * static_cast<std::size_t>(level.width) +
                            static_cast<std::size_t>(cx >> k);
    // Nearest to the viewer (the highest point, seen from above) wins.
    if (!(depth > level.depth[idx])) continue;
    level.depth[idx] = depth;
    if (colors) level.color[idx] = color;
    if (separate_height_) level.height_z[idx] = z;
  }
}

Status PreviewRenderer::add(const PointCloud& batch) {
  const bool batch_colors = options_.use_colors && batch.has_colors();
  const std::size_t n = batch.size();
  if (buffering_) {
    try {
      // Geometric growth: reserving just enough per batch would copy the
      // whole buffer on every batch.
      if (buffer_.capacity() < buffer_.size() + n) buffer_.reserve(std::max(2 * buffer_.capacity(), buffer_.size() + n));
    } catch (const std::bad_alloc&) {
      RELIEF_RETURN_IF_ERROR(draw_buffer(false));
    }
  }
  for (std::size_t i = 0; i < n; ++i) {
    const Vec3d& q = batch.positions[i];
    const Vec3d p{q.x - origin_.x, q.y - origin_.y, q.z - origin_.z};
    const double u = dot(p, right_), v = dot(p, up_);
    const auto depth = static_cast<float>(dot(p, toward_));
    std::uint32_t color = kNoColor;
    if (batch_colors) {
      const Rgb8 c = batch.colors[i];
      color = (std::uint32_t{c.r} << 16) | (std::uint32_t{c.g} << 8) | c.b;
    }
    if (buffering_) {
      // Only finite points can be fitted; others would fail the frame test
      // in draw() anyway.
      if (std::isfinite(u) && std::isfinite(v)) {
        buffer_.push_back({static_cast<float>(u), static_cast<float>(v), depth, static_cast<float>(p.z), color});
      }
    } else {
      draw(u, v, depth, static_cast<float>(p.z), color);
    }
  }
  // Beyond the cap, memory would grow with the archive: fall back to the
  // frame's extent and stream.
  if (buffering_ && buffer_.size() > kMaxBufferedPoints) RELIEF_RETURN_IF_ERROR(draw_buffer(false));
  return Status::ok();
}

void PreviewRenderer::cull_hidden(Level& level, double pixel) const {
  // Seen from the side, a sparse surface lets the points behind it show
  // through its gaps (dark speckles once shaded). A point well behind most
  // of its neighbours is such a leak: it is removed, and the hole filling
  // then closes the gap with the surface in front.
  const auto threshold = static_cast<float>(kHiddenDepth * pixel);
  const int lw = level.width, lh = level.height;
  const auto at = [lw](int x, int y) {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(lw) + static_cast<std::size_t>(x);
  };
  std::vector<std::size_t> hidden;
  for (int y = 1; y + 1 < lh; ++y) {
    for (int x = 1; x + 1 < lw; ++x) {
      const float d = level.depth[at(x, y)];
      if (d == kEmpty) continue;
      int nearer = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if (level.depth[at(x + dx, y + dy)] > d + threshold) ++nearer;  // empty (-inf) never counts
        }
      }
      if (nearer >= 5) hidden.push_back(at(x, y));
    }
  }
  for (const std::size_t k : hidden) level.depth[k] = kEmpty;
}

void PreviewRenderer::fill_holes(Level& level) const {
  // One pass, decided on the unfilled image (fills do not feed each other),
  // so pinholes and thin cracks close while outlines stay put. A pixel takes
  // the mean of its filled neighbours when at least 5 of the 8 are filled,
  // or 4 of which two face each other across it. The second rule closes the
  // small cross-shaped holes where a missed row and a missed column of
  // regularly spaced samples meet (samples slightly further apart than the
  // pixels), and still never grows the data past a straight or convex edge
  // (at most 3 neighbours there).
  struct Fill {
    std::size_t index;
    float depth;
    float height;
    std::uint32_t color;
  };
  std::vector<Fill> fills;
  const bool colors = options_.use_colors;
  const int lw = level.width, lh = level.height;
  const auto at = [lw](int x, int y) {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(lw) + static_cast<std::size_t>(x);
  };
  const auto filled = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < lw && y < lh && level.depth[at(x, y)] != kEmpty;
  };
  for (int y = 0; y < lh; ++y) {
    for (int x = 0; x < lw; ++x) {
      const std::size_t k = at(x, y);
      if (level.depth[k] != kEmpty) continue;
      int count = 0;
      double sd = 0, sh = 0, sr = 0, sg = 0, sb = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if ((dx == 0 && dy == 0) || !filled(x + dx, y + dy)) continue;
          const std::size_t j = at(x + dx, y + dy);
          ++count;
          sd += level.depth[j];
          if (separate_height_) sh += level.height_z[j];
          if (colors) {
            sr += (level.color[j] >> 16) & 0xFF;
            sg += (level.color[j] >> 8) & 0xFF;
            sb += level.color[j] & 0xFF;
          }
        }
      }
      if (count < 4) continue;
      if (count == 4) {
        const int pairs = static_cast<int>(filled(x - 1, y) && filled(x + 1, y)) +
                          static_cast<int>(filled(x, y - 1) && filled(x, y + 1)) +
                          static_cast<int>(filled(x - 1, y - 1) && filled(x + 1, y + 1)) +
                          static_cast<int>(filled(x + 1, y - 1) && filled(x - 1, y + 1));
        if (pairs < 1) continue;
      }
      Fill f{k, static_cast<float>(sd / count), static_cast<float>(sh / count), 0};
      if (colors) {
        const auto channel = [count](double v) { return static_cast<std::uint32_t>(std::lround(v / count)); };
        f.color = (channel(sr) << 16) | (channel(sg) << 8) | channel(sb);
      }
      fills.push_back(f);
    }
  }
  for (const Fill& f : fills) {
    level.depth[f.index] = f.depth;
    if (separate_height_) level.height_z[f.index] = f.height;
    if (colors) level.color[f.index] = f.color;
  }
}

double PreviewRenderer::hole_ratio(const Level& fine, const Level& coarse) {
  // Share of empty fine pixels under the interior of the coarse level's
  // footprint (coarse pixels whose 8 neighbours are filled too): at the edge
  // of the data fine pixels are legitimately empty and do not count.
  const auto filled = [&coarse](int x, int y) {
    return coarse.depth[static_cast<std::size_t>(y) * static_cast<std::size_t>(coarse.width) +
                        static_cast<std::size_t>(x)] != kEmpty;
  };
  std::size_t total = 0, empty = 0;
  for (int y = 1; y + 1 < coarse.height; ++y) {
    for (int x = 1; x + 1 < coarse.width; ++x) {
      bool interior = true;
      for (int dy = -1; dy <= 1 && interior; ++dy) {
        for (int dx = -1; dx <= 1 && interior; ++dx) interior = filled(x + dx, y + dy);
      }
      if (!interior) continue;
      for (int dy = 0; dy < 2; ++dy) {
        for (int dx = 0; dx < 2; ++dx) {
          const int fx = 2 * x + dx, fy = 2 * y + dy;
          if (fx >= fine.width || fy >= fine.height) continue;
          ++total;
          if (fine.depth[static_cast<std::size_t>(fy) * static_cast<std::size_t>(fine.width) +
                         static_cast<std::size_t>(fx)] == kEmpty) {
            ++empty;
          }
        }
      }
    }
  }
  // Too little interior to judge (a handful of points, thin data): keep the
  // finer level rather than blur on no evidence.
  if (total < 64) return 0;
  return static_cast<double>(empty) / static_cast<double>(total);
}

void PreviewRenderer::fill_from_coarser(Level& fine, const Level& coarse) const {
  const int cw = coarse.width, ch = coarse.height;
  const auto at = [cw](int x, int y) {
    return static_cast<std::size_t>(y) * static_cast<std::size_t>(cw) + static_cast<std::size_t>(x);
  };
  const auto coarse_filled = [&](int x, int y) {
    return x >= 0 && y >= 0 && x < cw && y < ch && coarse.depth[at(x, y)] != kEmpty;
  };
  const bool colors = options_.use_colors;
  for (int y = 0; y < fine.height; ++y) {
    for (int x = 0; x < fine.width; ++x) {
      const std::size_t k = static_cast<std::size_t>(y) * static_cast<std::size_t>(fine.width) +
                            static_cast<std::size_t>(x);
      if (fine.depth[k] != kEmpty) continue;
      // Only under the interior of the coarse footprint (the coarse pixel and
      // its 8 neighbours filled), so the outline of the data stays where it
      // is; there all four bilinear neighbours below are filled.
      const int cx = x / 2, cy = y / 2;
      bool interior = true;
      for (int dy = -1; dy <= 1 && interior; ++dy) {
        for (int dx = -1; dx <= 1 && interior; ++dx) interior = coarse_filled(cx + dx, cy + dy);
      }
      if (!interior) continue;
      // Bilinear, so filled areas are smooth rather than 2^k-pixel blocks.
      const double sx = (x + 0.5) * 0.5 - 0.5, sy = (y + 0.5) * 0.5 - 0.5;
      const int x0 = static_cast<int>(std::floor(sx)), y0 = static_cast<int>(std::floor(sy));
      const double fx = sx - x0, fy = sy - y0;
      double d = 0, z = 0, r = 0, g = 0, b = 0;
      for (int j = 0; j < 2; ++j) {
        for (int i = 0; i < 2; ++i) {
          const std::size_t c = at(x0 + i, y0 + j);
          const double wgt = (i ? fx : 1 - fx) * (j ? fy : 1 - fy);
          d += wgt * coarse.depth[c];
          if (separate_height_) z += wgt * coarse.height_z[c];
          if (colors) {
            r += wgt * ((coarse.color[c] >> 16) & 0xFF);
            g += wgt * ((coarse.color[c] >> 8) & 0xFF);
            b += wgt * (coarse.color[c] & 0xFF);
          }
        }
      }
      fine.depth[k] = static_cast<float>(d);
      if (separate_height_) fine.height_z[k] = static_cast<float>(z);
      if (colors) {
        const auto channel = [](double v) { return static_cast<std::uint32_t>(std::lround(v)); };
        fine.color[k] = (channel(r) << 16) | (channel(g) << 8) | channel(b);
      }
    }
  }
}

void PreviewRenderer::height_range(const Level& level, float& lo, float& hi) const {
  // The 1st to 99th percentile of the visible heights rather than min..max:
  // a few outliers (birds, multipath returns) would otherwise squeeze the
  // whole scene into one colour.
  const std::vector<float>& heights = separate_height_ ? level.height_z : level.depth;
  float mn = std::numeric_limits<float>::infinity(), mx = -mn;
  std::size_t filled = 0;
  for (std::size_t k = 0; k < level.depth.size(); ++k) {
    if (level.depth[k] == kEmpty) continue;
    mn = std::min(mn, heights[k]);
    mx = std::max(mx, heights[k]);
    ++filled;
  }
  if (filled == 0) {
    lo = 0;
    hi = 1;
    return;
  }
  if (!(mx - mn > 1e-6f * std::max(1.0f, std::fabs(mx)))) {
    lo = mn - 0.5f;
    hi = mx + 0.5f;
    return;
  }
  constexpr std::size_t kBins = 4096;
  std::vector<std::size_t> hist(kBins, 0);
  const double scale = static_cast<double>(kBins - 1) / static_cast<double>(mx - mn);
  for (std::size_t k = 0; k < level.depth.size(); ++k) {
    if (level.depth[k] == kEmpty) continue;
    ++hist[static_cast<std::size_t>((heights[k] - mn) * scale)];
  }
  const std::size_t cut = filled / 100;
  std::size_t acc = 0;
  std::size_t b_lo = 0;
  while (b_lo + 1 < kBins && acc + hist[b_lo] <= cut) acc += hist[b_lo++];
  acc = 0;
  std::size_t b_hi = kBins - 1;
  while (b_hi > b_lo && acc + hist[b_hi] <= cut) acc += hist[b_hi--];
  lo = mn + static_cast<float>(static_cast<double>(b_lo) / scale);
  hi = mn + static_cast<float>(static_cast<double>(b_hi + 1) / scale);
  if (!(hi > lo)) hi = lo + 1;
}

void PreviewRenderer::shade(const Level& level, double pixel, std::vector<std::uint8_t>& rgb,
                            std::vector<std::uint8_t>& mask) const {
  static const std::array<Rgb8, 256> ramp = build_ramp();
  const int lw = level.width, lh = level.height;
  rgb.assign(static_cast<std::size_t>(lw) * static_cast<std::size_t>(lh) * 3, 0);
  mask.assign(static_cast<std::size_t>(lw) * static_cast<std::size_t>(lh), 0);
  float lo = 0, hi = 1;
  if (!options_.use_colors) height_range(level, lo, hi);
  const float to_ramp = 255.0f / (hi - lo);
  const std::vector<float>& heights = separate_height_ ? level.height_z : level.depth;
  const std::vector<float>& depth = level.depth;

  // Light from the upper left of the screen, 45 degrees up: north-west in the
  // top view, the cartographic convention that makes relief read as raised.
  const double lx = -0.5, ly = 0.5, lz = std::sqrt(0.5);
  // Flat ground keeps its colour: the shade is relative to a horizontal
  // surface's (its normal in view coordinates is the world z axis).
  const double flat = right_.z * lx + up_.z * ly + toward_.z * lz;
  const double ref = flat > 0.1 ? flat : 0.1;
  // RGB already carries the scene's own shading: shade it lightly.
  const double strength = options_.use_colors ? 0.35 : 0.7;
  const double inv_2px = 0.5 / pixel, inv_px = 1.0 / pixel;
  const auto row_step = static_cast<std::size_t>(lw);

  for (int y = 0; y < lh; ++y) {
    for (int x = 0; x < lw; ++x) {
      const std::size_t k = static_cast<std::size_t>(y) * row_step + static_cast<std::size_t>(x);
      const float d = depth[k];
      if (d == kEmpty) continue;
      mask[k] = 1;
      Rgb8 base;
      if (options_.use_colors) {
        base = {static_cast<std::uint8_t>(level.color[k] >> 16), static_cast<std::uint8_t>(level.color[k] >> 8),
                static_cast<std::uint8_t>(level.color[k])};
      } else {
        const float t = std::clamp((heights[k] - lo) * to_ramp, 0.0f, 255.0f);
        base = ramp[static_cast<std::size_t>(t)];
      }
      // Depth gradient by central differences, one-sided beside a hole.
      const float left = x > 0 ? depth[k - 1] : kEmpty;
      const float right = x + 1 < lw ? depth[k + 1] : kEmpty;
      const float above = y > 0 ? depth[k - row_step] : kEmpty;
      const float below = y + 1 < lh ? depth[k + row_step] : kEmpty;
      double gu = 0, gv = 0;
      if (left != kEmpty && right != kEmpty) {
        gu = (right - left) * inv_2px;
      } else if (right != kEmpty) {
        gu = (right - d) * inv_px;
      } else if (left != kEmpty) {
        gu = (d - left) * inv_px;
      }
      // Screen "up" is the row above.
      if (above != kEmpty && below != kEmpty) {
        gv = (above - below) * inv_2px;
      } else if (above != kEmpty) {
        gv = (above - d) * inv_px;
      } else if (below != kEmpty) {
        gv = (d - below) * inv_px;
      }
      // Surface normal (-gu, -gv, 1) against the light.
      const double lambert = (-gu * lx - gv * ly + lz) / std::sqrt(gu * gu + gv * gv + 1.0);
      const double factor = std::clamp(1.0 - strength + strength * lambert / ref, 0.3, 1.3);
      const auto lit = [factor](std::uint8_t c) {
        return static_cast<std::uint8_t>(std::min(255.0, c * factor + 0.5));
      };
      std::uint8_t* out = rgb.data() + k * 3;
      out[0] = lit(base.r);
      out[1] = lit(base.g);
      out[2] = lit(base.b);
    }
  }
}

Result<PreviewImage> PreviewRenderer::finish() {
  if (buffering_) RELIEF_RETURN_IF_ERROR(draw_buffer(true));
  // Hidden points out, then one pass of hole filling; only on the levels the
  // choice below looks at (the finest ones are big and often not needed).
  const auto prepare = [this](std::size_t k) {
    if (options_.view == PreviewView::kOblique) cull_hidden(levels_[k], pixel_size_ * static_cast<double>(1 << k));
    fill_holes(levels_[k]);
  };
  // The level to draw: the finest whose interior is mostly covered after the
  // fill, judged from the coarsest level down (a level is only trusted when
  // the next coarser one was, so a sparse level, too fragmented to have an
  // interior to judge, is never picked for lack of evidence). Uniformly
  // sampled data passes with hardly any holes; scans whose density varies a
  // lot (terrestrial scanners) pass where their dense parts are sharp.
  constexpr double kMaxHoles = 0.2;
  chosen_level_ = static_cast<int>(levels_.size()) - 1;
  prepare(levels_.size() - 1);
  while (chosen_level_ > 0) {
    const auto k = static_cast<std::size_t>(chosen_level_);
    prepare(k - 1);
    if (hole_ratio(levels_[k - 1], levels_[k]) > kMaxHoles) break;
    --chosen_level_;
  }
  // The holes left inside the data (its sparser parts; cracks where patch
  // grids meet) are filled from the next coarser level, itself filled from
  // the one above it, so every hole gets the finest value there is. Two
  // levels at most: gaps up to about four pixels are holes, wider ones are
  // places without data (bays between scans) and stay background.
  const std::size_t top = std::min(levels_.size() - 1, static_cast<std::size_t>(chosen_level_) + kFillLevels);
  for (std::size_t k = top; k > static_cast<std::size_t>(chosen_level_); --k) {
    fill_from_coarser(levels_[k - 1], levels_[k]);
  }
  const Level& level = levels_[static_cast<std::size_t>(chosen_level_)];
  const int factor = 1 << chosen_level_;
  std::vector<std::uint8_t> rgb, mask;
  shade(level, pixel_size_ * factor, rgb, mask);

  PreviewImage img;
  img.width = width_;
  img.height = height_;
  img.rgb.resize(static_cast<std::size_t>(width_) * static_cast<std::size_t>(height_) * 3);
  const auto put = [&img](std::size_t pixel, std::uint8_t r, std::uint8_t g, std::uint8_t b) {
    std::uint8_t* out = img.rgb.data() + pixel * 3;
    out[0] = r;
    out[1] = g;
    out[2] = b;
  };
  if (chosen_level_ == 0) {
    for (std::size_t k = 0; k < mask.size(); ++k) {
      if (mask[k]) {
        put(k, rgb[k * 3], rgb[k * 3 + 1], rgb[k * 3 + 2]);
      } else {
        put(k, kPreviewBackground.r, kPreviewBackground.g, kPreviewBackground.b);
      }
    }
  } else {
    // Bilinear scale-up over the filled pixels only: the colour is the
    // weighted mean of the filled neighbours, and a pixel is background when
    // less than half of the weight lies on filled ones (the data's edge
    // stays where it is instead of bleeding into the background).
    const int lw = level.width, lh = level.height;
    const double inv = 1.0 / factor;
    for (int y = 0; y < height_; ++y) {
      const double sy = (y + 0.5) * inv - 0.5;
      const int y0 = static_cast<int>(std::floor(sy));
      const double fy = sy - y0;
      for (int x = 0; x < width_; ++x) {
        const double sx = (x + 0.5) * inv - 0.5;
        const int x0 = static_cast<int>(std::floor(sx));
        const double fx = sx - x0;
        double wsum = 0, r = 0, g = 0, b = 0;
        for (int j = 0; j < 2; ++j) {
          const int yy = y0 + j;
          if (yy < 0 || yy >= lh) continue;
          const double wy = j ? fy : 1 - fy;
          for (int i = 0; i < 2; ++i) {
            const int xx = x0 + i;
            if (xx < 0 || xx >= lw) continue;
            const std::size_t k =
                static_cast<std::size_t>(yy) * static_cast<std::size_t>(lw) + static_cast<std::size_t>(xx);
            if (!mask[k]) continue;
            const double wgt = wy * (i ? fx : 1 - fx);
            wsum += wgt;
            r += wgt * rgb[k * 3];
            g += wgt * rgb[k * 3 + 1];
            b += wgt * rgb[k * 3 + 2];
          }
        }
        const std::size_t pixel =
            static_cast<std::size_t>(y) * static_cast<std::size_t>(width_) + static_cast<std::size_t>(x);
        if (wsum < 0.5) {
          put(pixel, kPreviewBackground.r, kPreviewBackground.g, kPreviewBackground.b);
        } else {
          const auto channel = [wsum](double v) { return static_cast<std::uint8_t>(std::lround(v / wsum)); };
          put(pixel, channel(r), channel(g), channel(b));
        }
      }
    }
  }
  draw_overlays(img);
  return img;
}

void PreviewRenderer::draw_overlays(PreviewImage& img) const {
  if (!options_.overlays || img.width < 100 || img.height < 48) return;  // no room for legible marks
  const int scale = img.width >= 320 && img.height >= 160 ? 2 : 1;
  const int margin = 6 * scale;
  if (options_.view == PreviewView::kTop) {
    const double length = nice_length(0.2 * img.width * pixel_size_);
    const int bar = std::max(1, static_cast<int>(std::lround(length / pixel_size_)));
    const int bar_h = 3 * scale;
    const int x0 = margin, y1 = img.height - margin, y0 = y1 - bar_h;
    fill_rect(img, x0 - 1, y0 - 1, x0 + bar + 1, y1 + 1, kDark);
    fill_rect(img, x0, y0, x0 + bar, y1, kWhite);
    // End ticks make the bar's extent unambiguous on a bright background.
    fill_rect(img, x0 - 1, y0 - 2 * scale - 1, x0 + scale + 1, y0, kDark);
    fill_rect(img, x0 + bar - scale - 1, y0 - 2 * scale - 1, x0 + bar + 1, y0, kDark);
    fill_rect(img, x0, y0 - 2 * scale, x0 + scale, y0, kWhite);
    fill_rect(img, x0 + bar - scale, y0 - 2 * scale, x0 + bar, y0, kWhite);
    draw_text(img, x0 + 2 * scale + 2, y0 - 2 * scale - 2 - kGlyphH * scale, format_length(length), scale);

    // North arrow in the top-right corner: a triangle above an "N".
    const int tri_h = 9 * scale, tri_hw = 4 * scale;
    const int cx = img.width - margin - tri_hw - 1, top = margin;
    fill_up_triangle(img, cx, top, tri_h, tri_hw, 1, kDark);
    fill_up_triangle(img, cx, top, tri_h, tri_hw, 0, kWhite);
    draw_text(img, cx - (kGlyphW * scale) / 2, top + tri_h + 2 * scale, "N", scale);
  } else {
    const std::string label =
        "az " + format_number(options_.azimuth_deg) + " el " + format_number(options_.elevation_deg);
    if (text_width(label, scale) + 2 * margin > img.width) return;
    draw_text(img, margin, img.height - margin - kGlyphH * scale, label, scale);
  }
}

double nice_length(double target) {
  if (!(target > 0) || !std::isfinite(target)) return 1;
  const double base = std::pow(10.0, std::floor(std::log10(target)));
  double best = base;
  for (const double m : {1.0, 2.0, 5.0, 10.0}) {
    if (std::fabs(std::log(m * base / target)) < std::fabs(std::log(best / target))) best = m * base;
  }
  return best;
}

std::string format_length(double metres) {
  double v = metres;
  const char* unit = "m";
  if (metres >= 1000) {
    v = metres / 1000;
    unit = "km";
  }
  char buf[48];
  if (v >= 1) {
    std::snprintf(buf, sizeof buf, "%.0f %s", v, unit);
  } else {
    // 0.5 -> one decimal, 0.02 -> two: exactly the digits a 1-2-5 value needs.
    const int decimals = std::clamp(static_cast<int>(-std::floor(std::log10(v) + 1e-9)), 1, 12);
    std::snprintf(buf, sizeof buf, "%.*f %s", decimals, v, unit);
  }
  return buf;
}

Result<std::vector<std::uint8_t>> encode_png(const PreviewImage& image, int level) {
  if (image.width < 1 || image.height < 1 ||
      image.rgb.size() != static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height) * 3) {
    return invalid_argument("PNG: the image is empty or its pixel buffer has the wrong size");
  }
  std::vector<std::uint8_t> out;
  // Previews compress to roughly a third of the raw size; reserving avoids
  // most of the regrowth copies.
  out.reserve(image.rgb.size() / 3 + 1024);
  PngSink sink;
  sink.out = &out;
  if (!write_png_rows(&image, &sink, std::clamp(level, 0, 9))) {
    return internal_error(std::string("PNG encoding failed: ") + sink.message);
  }
  return out;
}

}  // namespace relief
