// libFuzzer target: the polygon readers of `query --polygon` (WKT or GeoJSON
// text a user or a file gives, or an ESRI shapefile: input starting with the
// shapefile file code goes to from_shapefile), and GeoJSON areas converted to
// another CRS. Any input must parse or be refused, naming the source,
// without a crash. A polygon that parses must answer contains() as the plain
// crossing test over all its edges does within its bounds (its strip index
// must not change the answer), at random points, its vertices and its edges'
// midpoints; no point
// outside its bounds may be inside; and a rectangle it calls inside or
// outside must hold only points that say so.
#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "relief/polygon.h"

namespace {

bool plain_contains(const relief::Polygon2D& p, double x, double y) {
  bool in = false;
  for (const relief::Polygon2D::Edge& e : p.edges()) {
    if (e.y0 <= y && y < e.y1 && x < e.x0 + (y - e.y0) * (e.x1 - e.x0) / (e.y1 - e.y0)) in = !in;
  }
  return in;
}

// Inside the bounds (outside them contains() is false by definition, and the
// plain test is left to rounding at their edges).
void same_as_plain(const relief::Polygon2D& p, double x, double y) {
  const relief::Box3d& b = p.bounds();
  if (!(x >= b.min.x && x <= b.max.x && y >= b.min.y && y <= b.max.y)) return;
  if (p.contains(x, y) != plain_contains(p, x, y)) {
    std::fprintf(stderr, "polygon: contains(%.17g, %.17g) differs from the plain test\n", x, y);
    std::abort();
  }
}

void check(const relief::Polygon2D& p, std::uint64_t seed) {
  const relief::Box3d& b = p.bounds();
  if (!(b.min.x <= b.max.x && b.min.y <= b.max.y)) std::abort();
  const auto next = [&seed] {
    seed = seed * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<double>(seed >> 11) / 9007199254740992.0;
  };
  const double w = b.max.x - b.min.x, h = b.max.y - b.min.y;
  for (int i = 0; i < 64; ++i) {
    // Points around the bounds (a margin outside them too).
    const double x = b.min.x - 0.1 * w + 1.2 * w * next(), y = b.min.y - 0.1 * h + 1.2 * h * next();
    same_as_plain(p, x, y);
    const bool in = p.contains(x, y);
    if (in && (x < b.min.x || x > b.max.x || y < b.min.y || y > b.max.y)) {
      std::fprintf(stderr, "polygon: a point outside the bounds is inside\n");
      std::abort();
    }
  }
  // Where rounding and the half-open rule bite (at most 256 edges' worth).
  const std::size_t step = std::max<std::size_t>(1, p.edges().size() / 256);
  for (std::size_t i = 0; i < p.edges().size(); i += step) {
    const relief::Polygon2D::Edge& e = p.edges()[i];
    same_as_plain(p, e.x0, e.y0);
    same_as_plain(p, 0.5 * (e.x0 + e.x1), 0.5 * (e.y0 + e.y1));
  }
  for (int i = 0; i < 16; ++i) {
    const double x0 = b.min.x - 0.1 * w + 1.2 * w * next(), y0 = b.min.y - 0.1 * h + 1.2 * h * next();
    const double x1 = x0 + 0.3 * w * next(), y1 = y0 + 0.3 * h * next();
    const relief::Box3d r{{x0, y0, 0}, {x1, y1, 0}};
    const relief::Polygon2D::Overlap o = p.classify(r);
    if (o == relief::Polygon2D::Overlap::kPartial) continue;
    const bool want = o == relief::Polygon2D::Overlap::kInside;
    for (int k = 0; k < 16; ++k) {
      const double u = k < 4 ? (k & 1) : next(), v = k < 4 ? (k >> 1) : next();
      const double x = x0 + u * (x1 - x0), y = y0 + v * (y1 - y0);
      if (x > x1 || y > y1) continue;  // rounding past the far corner
      if (p.contains(x, y) != want) {
        std::fprintf(stderr, "polygon: a rectangle called %s holds a point that is not\n", want ? "inside" : "outside");
        std::abort();
      }
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const std::span<const std::uint8_t> bytes(data, size);
  // from_arg: WKT, or GeoJSON by its '{' (never a file: no '@' reaches it).
  auto p = relief::Polygon2D::is_shapefile(bytes) ? relief::Polygon2D::from_shapefile(bytes, "fuzz.wkt")
           : text.empty() || text[0] != '@'       ? relief::Polygon2D::from_arg(std::string(text))
                                                  : relief::Polygon2D::from_wkt(text, "fuzz.wkt");
  if (!p.is_ok()) {
    // Errors name the source ("the polygon" for text from_arg reads).
    const std::string& m = p.status().message();
    if (m.rfind("fuzz.wkt: ", 0) != 0 && m.rfind("the polygon: ", 0) != 0) std::abort();
    return 0;
  }
  if (p->edge_count() < 3 || p->ring_count() == 0) std::abort();
  std::uint64_t seed = size;
  for (std::size_t i = 0; i < std::min<std::size_t>(size, 64); ++i) seed = seed * 131 + data[i];
  check(*p, seed);
  // A GeoJSON area (longitude/latitude, or the CRS it names) converted to
  // Web Mercator: refused naming where, or an area as sound as any.
  if (!p->crs().empty()) {
    auto q = p->converted_to("EPSG:3857", "fuzz");
    if (!q.is_ok()) {
      if (q.status().message().rfind("fuzz: ", 0) != 0) std::abort();
      return 0;
    }
    if (q->edge_count() < p->edge_count() || q->ring_count() != p->ring_count()) std::abort();
    check(*q, seed + 1);
  }
  return 0;
}
