// render_preview (relief/render.h): an archive's region through the
// PreviewRenderer, reading as few points as the image needs.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <mutex>

#include "relief/render.h"

namespace relief {

namespace {

bool finite_box(const Box3d& b) {
  return std::isfinite(b.min.x) && std::isfinite(b.min.y) && std::isfinite(b.min.z) && std::isfinite(b.max.x) &&
         std::isfinite(b.max.y) && std::isfinite(b.max.z);
}

Box3d intersect(const Box3d& a, const Box3d& b) {
  Box3d r;
  r.min = {std::max(a.min.x, b.min.x), std::max(a.min.y, b.min.y), std::max(a.min.z, b.min.z)};
  r.max = {std::min(a.max.x, b.max.x), std::min(a.max.y, b.max.y), std::min(a.max.z, b.max.z)};
  return r;
}

// The region the image shows. The top view shows the box's x/y extent as
// asked (so a box beside the data still gives an image of that box). The
// oblique view needs finite heights and looks better framed tightly: it fits
// the part of the box that holds data, with the heights of the data.
Box3d choose_frame(const Box3d& box, const Box3d& bounds, PreviewView view) {
  Box3d frame = box;
  const Box3d common = intersect(box, bounds);
  if (view == PreviewView::kOblique && !common.empty()) frame = common;
  if (!std::isfinite(frame.min.z) || !std::isfinite(frame.max.z) || common.empty()) {
    frame.min.z = bounds.min.z;
    frame.max.z = bounds.max.z;
  }
  return frame;
}

}  // namespace

Result<PreviewResult> render_preview(ArchiveReader& reader, const PreviewRequest& request) {
  const ArchiveInfo& info = reader.info();
  if (info.bounds.empty() || !finite_box(info.bounds)) {
    return invalid_argument(reader.path() + " holds no points: nothing to preview");
  }
  const Box3d box = request.box.value_or(info.bounds);
  if (!(box.max.x > box.min.x) || !(box.max.y > box.min.y)) {
    return invalid_argument("a preview box must have xmax > xmin and ymax > ymin to make an image");
  }
  if (request.lod && (*request.lod < 1 || *request.lod > kMaxQueryLod)) {
    return invalid_argument("preview level of detail " + std::to_string(*request.lod) + " is outside 1.." +
                            std::to_string(kMaxQueryLod));
  }
  PreviewOptions options = request.options;
  options.use_colors = info.has_colors;
  const Box3d frame = choose_frame(box, info.bounds, options.view);
  RELIEF_ASSIGN_OR_RETURN(PreviewRenderer renderer, PreviewRenderer::create(frame, options));

  QueryOptions q;
  q.lod = request.lod.value_or(kDefaultPreviewLod);
  q.threads = request.threads;
  bool pyramid = false;
  for (const ScanPyramid& scan : info.pyramid) pyramid = pyramid || !scan.levels.empty();
  const double dx = frame.max.x - frame.min.x, dy = frame.max.y - frame.min.y;
  if (!std::isfinite(dx) || !std::isfinite(dy) || !std::isfinite(frame.max.z - frame.min.z)) {
    char text[200];
    std::snprintf(text, sizeof text, "x %.9g .. %.9g, y %.9g .. %.9g, z %.9g .. %.9g", frame.min.x,
                  frame.max.x, frame.min.y, frame.max.y, frame.min.z, frame.max.z);
    return invalid_argument(std::string("the preview's box is wider than doubles can measure (") + text +
                            "): give a smaller box");
  }
  const double rows = options.view == PreviewView::kTop && dx > 0
                          ? std::clamp(options.width * dy / dx, 1.0, static_cast<double>(kMaxPreviewSide))
                          : static_cast<double>(options.width);
  const double budget = kPreviewPointsPerPixel * options.width * rows;
  if (!request.lod && pyramid) {
    // A point budget instead of a fraction: the time then stays the same
    // whatever the size of the archive (the pyramid's coarse levels).
    q.lod = 1;
    q.max_points = static_cast<std::uint64_t>(budget);
  } else if (!request.lod) {
    // Without a pyramid, lod 16 unless the box holds fewer than 16 budgets
    // of points (its share of the archive's x-y bounds): then the lod that
    // fills the budget, so a small archive is not drawn as scattered dots.
    const Box3d& all = info.bounds;
    const double area = (all.max.x - all.min.x) * (all.max.y - all.min.y);
    const double inside = std::max(0.0, std::min(all.max.x, box.max.x) - std::max(all.min.x, box.min.x)) *
                          std::max(0.0, std::min(all.max.y, box.max.y) - std::max(all.min.y, box.min.y));
    const double share = area > 0 ? std::clamp(inside / area, 0.0, 1.0) : 1.0;
    const double points = static_cast<double>(info.decoded_points) * share;
    q.lod = static_cast<std::uint32_t>(
        std::clamp(std::ceil(points / budget), 1.0, static_cast<double>(kDefaultPreviewLod)));
  }
  std::mutex draw_mutex;  // the reader promises batches in order, not on which thread
  const PointSink sink = [&](const PointCloud& batch) {
    const std::lock_guard<std::mutex> lock(draw_mutex);
    return renderer.add(batch);
  };
  PreviewResult out;
  RELIEF_ASSIGN_OR_RETURN(out.stats, request.box ? reader.query(box, q, sink) : reader.query_all(q, sink));
  RELIEF_ASSIGN_OR_RETURN(out.image, renderer.finish());
  out.lod = q.lod;
  out.max_points = q.max_points;
  out.points_drawn = renderer.points_drawn();
  out.detail_level = renderer.detail_level();
  out.pixel_size = renderer.pixel_size();
  return out;
}

}  // namespace relief
