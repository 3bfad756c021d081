// Quick-look images of point clouds (`relief preview`, and Archive.preview
// in Python): points arrive in batches and are drawn into z-buffers
// (O(points + pixels); memory bounded by the image, plus at most a few
// million projected points for the oblique view), then the image is shaded,
// overlaid with a scale bar or a view label and encoded as PNG.
// PreviewRenderer is independent of the archive (anything that yields
// PointCloud batches works); render_preview draws an archive or a box of it,
// reading as few points as the image needs.
#pragma once

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "relief/query.h"
#include "relief/status.h"
#include "relief/types.h"

namespace relief {

enum class PreviewView {
  kTop,      // orthographic, straight down, north up
  kOblique,  // orthographic, rotated by the azimuth about z, then tilted
};

// Neither side of a preview exceeds this many pixels.
inline constexpr int kMaxPreviewSide = 8192;

struct PreviewOptions {
  PreviewView view = PreviewView::kTop;
  int width = 1024;  // requested width; the height follows the aspect ratio
  double azimuth_deg = 30;
  double elevation_deg = 35;  // 90 = straight down (the top view)
  // true: colour by the points' RGB; false: a height colour map.
  bool use_colors = false;
  // Scale bar and north arrow (top view) or view label (oblique).
  bool overlays = true;
};

struct PreviewImage {
  int width = 0;
  int height = 0;
  std::vector<std::uint8_t> rgb;  // row-major from the top row, 3 bytes per pixel

  Rgb8 at(int x, int y) const;
};

// Background of pixels no point reached: a dark neutral grey, apart from
// every ramp colour and from the white overlays.
inline constexpr Rgb8 kPreviewBackground{48, 48, 52};

// Sparse points (a coarse level of detail, or a box zoomed in far) cannot
// fill an image pixel for pixel. The renderer therefore keeps a small pyramid
// of z-buffers (full, 1/2, 1/4, ... 1/32 resolution) and draws every point
// into each. At the end each level gets one pass of hole filling, the finest
// level whose interior is mostly covered is chosen, its remaining small holes
// take values from the two levels above it, and it is shaded and scaled up
// smoothly to the requested size. Dense data is drawn at full resolution;
// sparse data comes out softer instead of as noise.
class PreviewRenderer {
 public:
  // `frame` is the region to show, in point coordinates. The top view maps
  // its x/y extent onto the image (z may be infinite). The oblique view fits
  // the image to the points it is given, or, when there are too many to keep,
  // to the projection of the frame's eight corners (so its coordinates must
  // all be finite).
  static Result<PreviewRenderer> create(const Box3d& frame, const PreviewOptions& options);

  // Draws a batch; points outside the frame are ignored. Not thread-safe:
  // call from one thread at a time. Fails only when memory runs out.
  Status add(const PointCloud& batch);

  // Fills small holes, colours, shades and overlays. Call once, at the end.
  Result<PreviewImage> finish();

  // Image size. The oblique view fits the image to the points it was given
  // (when they fit in memory): its size is final only after finish().
  int width() const { return width_; }
  int height() const { return height_; }
  // Coordinate units per output pixel (on the ground for the top view).
  double pixel_size() const { return pixel_size_; }
  // Points that fell inside the image (for the oblique view: final after finish()).
  std::uint64_t points_drawn() const { return points_drawn_; }
  // After finish(): the pyramid level drawn (0 = full resolution, 1 = half...).
  int detail_level() const { return chosen_level_; }

 private:
  // One z-buffer of the pyramid.
  struct Level {
    int width = 0;
    int height = 0;
    std::vector<float> depth;           // toward the viewer; -inf = no point
    std::vector<float> height_z;        // z - origin.z, when separate_height_
    std::vector<std::uint32_t> color;   // 0xRRGGBB, when use_colors
  };

  // A point of an oblique view kept until the image is fitted to them.
  struct Projected {
    float u, v, depth, z;
    std::uint32_t color;
  };

  PreviewRenderer() = default;

  void set_geometry(double umin, double umax, double vmin, double vmax, double margin);
  Status allocate_levels();
  // Sizes the image (fitted to the kept points, or to the frame) and draws
  // the kept points; from then on points are drawn as they come.
  Status draw_buffer(bool fit);
  void draw(double u, double v, float depth, float z, std::uint32_t color);

  void cull_hidden(Level& level, double pixel) const;
  void fill_holes(Level& level) const;
  static double hole_ratio(const Level& fine, const Level& coarse);
  void fill_from_coarser(Level& fine, const Level& coarse) const;
  void height_range(const Level& level, float& lo, float& hi) const;
  // Colours and shades `level`; `mask` marks the pixels that hold a point.
  void shade(const Level& level, double pixel, std::vector<std::uint8_t>& rgb, std::vector<std::uint8_t>& mask) const;
  void draw_overlays(PreviewImage& image) const;

  PreviewOptions options_;
  int width_ = 0;
  int height_ = 0;
  double pixel_size_ = 1;
  // Points are made relative to the frame's centre before projection so the
  // float buffers keep their precision with georeferenced coordinates.
  Vec3d origin_;
  // Rows of the view rotation: screen right, screen up, toward the viewer.
  Vec3d right_{1, 0, 0};
  Vec3d up_{0, 1, 0};
  Vec3d toward_{0, 0, 1};
  double u_left_ = 0;  // screen coordinate of the image's left edge
  double v_top_ = 0;   // screen coordinate of the image's top edge
  bool separate_height_ = false;  // height_z in use (oblique without colours)

  bool buffering_ = false;
  std::vector<Projected> buffer_;
  std::array<double, 4> frame_extent_{};  // umin, umax, vmin, vmax of the oblique frame

  std::vector<Level> levels_;
  std::uint64_t points_drawn_ = 0;
  int chosen_level_ = 0;
};

// ---- An archive's preview: what `relief preview` draws.

struct PreviewRequest {
  // The region to show (closed); unset: the archive's bounds. A box with
  // infinite heights shows every height. Its x and y extents must be
  // positive.
  std::optional<Box3d> box;
  // Level of detail (1..kMaxQueryLod). Unset: an archive with a level-of-detail
  // pyramid reads the finest level that gives at most
  // kPreviewPointsPerPixel points per pixel of the image; one without, lod 16,
  // or the finer lod that gives about that many when the box holds fewer
  // than 16 times as many points.
  std::optional<std::uint32_t> lod;
  PreviewOptions options;  // use_colors is set from the archive
  unsigned threads = 0;    // decoder threads (0 = all cores)
};

inline constexpr double kPreviewPointsPerPixel = 2;
inline constexpr std::uint32_t kDefaultPreviewLod = 16;

struct PreviewResult {
  PreviewImage image;
  QueryStats stats;
  std::uint32_t lod = 1;            // the level of detail read
  std::uint64_t max_points = 0;     // the point budget read from the pyramid (0: lod)
  std::uint64_t points_drawn = 0;   // points that fell inside the image
  int detail_level = 0;             // PreviewRenderer::detail_level()
  double pixel_size = 1;            // coordinate units per pixel
};

// Draws `request`'s region of the archive. The top view shows the box's x/y
// extent as asked (a box beside the data gives an all-background image); the
// oblique view frames the part of the box that holds data. kInvalidArgument
// for an archive without points or a box without x/y extent.
Result<PreviewResult> render_preview(ArchiveReader& reader, const PreviewRequest& request);

// A "nice" length (1, 2 or 5 x 10^k) close to `target` (> 0).
double nice_length(double target);
// "200 m", "0.5 m", "2 km": the scale bar label.
std::string format_length(double metres);

// Encodes 8-bit RGB as PNG (zlib `level` 0..9: low levels are much faster and
// previews compress well anyway).
Result<std::vector<std::uint8_t>> encode_png(const PreviewImage& image, int level = 3);

}  // namespace relief
