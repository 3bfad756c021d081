// Polygon areas of interest: a WKT reader, an even-odd point test through a
// strip index of the edges, and a rectangle test that lets a query skip the
// chunks outside and the point tests of the chunks inside.
#include "relief/polygon.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <limits>

namespace relief {

namespace {

using Ring = std::vector<std::array<double, 2>>;

class WktParser {
 public:
  WktParser(std::string_view text, const std::string& source) : s_(text), source_(source) {}

  Status parse(std::vector<Ring>& rings) {
    const std::string word = keyword();
    bool multi = false;
    if (word == "MULTIPOLYGON") {
      multi = true;
    } else if (word != "POLYGON") {
      return fail(word.empty() ? "expected POLYGON or MULTIPOLYGON" : "'" + word + "' is not POLYGON or MULTIPOLYGON");
    }
    const std::size_t at = pos_;
    const std::string dims = keyword();
    if (dims == "EMPTY") return fail("the polygon is EMPTY");
    if (!dims.empty() && dims != "Z" && dims != "M" && dims != "ZM") return fail("unexpected '" + dims + "'");
    if (dims.empty()) pos_ = at;
    RELIEF_RETURN_IF_ERROR(expect('('));
    if (multi) {
      do {
        RELIEF_RETURN_IF_ERROR(expect('('));
        RELIEF_RETURN_IF_ERROR(polygon(rings));
      } while (accept(','));
      RELIEF_RETURN_IF_ERROR(expect(')'));
    } else {
      RELIEF_RETURN_IF_ERROR(polygon(rings));
    }
    skip_space();
    if (pos_ != s_.size()) return fail("unexpected text after the polygon");
    return Status::ok();
  }

 private:
  // After a polygon's '(': rings up to its ')'.
  Status polygon(std::vector<Ring>& rings) {
    do {
      RELIEF_RETURN_IF_ERROR(expect('('));
      Ring ring;
      do {
        std::array<double, 4> v{};
        int n = 0;
        while (n < 5 && number_ahead()) {
          if (n == 4) return fail("a vertex has more than 4 numbers");
          RELIEF_RETURN_IF_ERROR(number(v[static_cast<std::size_t>(n)]));
          ++n;
        }
        if (n < 2) return fail("a vertex needs x and y");
        ring.push_back({v[0], v[1]});
      } while (accept(','));
      RELIEF_RETURN_IF_ERROR(expect(')'));
      const std::size_t index = rings.size() + 1;
      if (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
      // Repeated vertices add nothing; three distinct ones make an area.
      ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
      if (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
      if (ring.size() < 3) {
        return invalid_argument(source_ + ": ring " + std::to_string(index) + " of the polygon has " +
                                std::to_string(ring.size()) + " distinct vertices; a ring needs 3");
      }
      rings.push_back(std::move(ring));
    } while (accept(','));
    return expect(')');
  }

  void skip_space() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_])) != 0) ++pos_;
  }
  std::string keyword() {
    skip_space();
    std::string w;
    while (pos_ < s_.size() && std::isalpha(static_cast<unsigned char>(s_[pos_])) != 0) {
      w.push_back(static_cast<char>(std::toupper(static_cast<unsigned char>(s_[pos_]))));
      ++pos_;
    }
    return w;
  }
  bool accept(char c) {
    skip_space();
    if (pos_ < s_.size() && s_[pos_] == c) {
      ++pos_;
      return true;
    }
    return false;
  }
  Status expect(char c) {
    if (accept(c)) return Status::ok();
    return fail(std::string("expected '") + c + "'");
  }
  bool number_ahead() {
    skip_space();
    if (pos_ >= s_.size()) return false;
    const char c = s_[pos_];
    return (c >= '0' && c <= '9') || c == '-' || c == '+' || c == '.';
  }
  Status number(double& out) {
    skip_space();
    std::size_t p = pos_;
    if (p < s_.size() && s_[p] == '+') ++p;
    const char* begin = s_.data() + p;
    const auto [end, ec] = std::from_chars(begin, s_.data() + s_.size(), out);
    if (ec != std::errc() || !std::isfinite(out)) return fail("expected a finite number");
    pos_ = static_cast<std::size_t>(end - s_.data());
    return Status::ok();
  }
  Status fail(const std::string& what) const {
    return invalid_argument(source_ + ": not a WKT polygon: " + what + " at character " + std::to_string(pos_ + 1));
  }

  std::string_view s_;
  const std::string& source_;
  std::size_t pos_ = 0;
};

// Whether the segment meets the closed rectangle (Liang-Barsky clipping).
bool segment_meets(double x0, double y0, double x1, double y1, double rx0, double ry0, double rx1, double ry1) {
  const double dx = x1 - x0, dy = y1 - y0;
  double t0 = 0, t1 = 1;
  const double p[4] = {-dx, dx, -dy, dy};
  const double q[4] = {x0 - rx0, rx1 - x0, y0 - ry0, ry1 - y0};
  for (int i = 0; i < 4; ++i) {
    if (p[i] == 0) {
      if (q[i] < 0) return false;
      continue;
    }
    const double r = q[i] / p[i];
    if (p[i] < 0) {
      t0 = std::max(t0, r);
    } else {
      t1 = std::min(t1, r);
    }
    if (t0 > t1) return false;
  }
  return true;
}

}  // namespace

Result<Polygon2D> Polygon2D::from_wkt(std::string_view wkt, const std::string& source) {
  std::vector<Ring> rings;
  RELIEF_RETURN_IF_ERROR(WktParser(wkt, source).parse(rings));
  Polygon2D p;
  p.ring_count_ = rings.size();
  const double inf = std::numeric_limits<double>::infinity();
  p.bounds_ = Box3d{{inf, inf, -inf}, {-inf, -inf, inf}};
  for (const Ring& ring : rings) {
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const auto& a = ring[i];
      const auto& b = ring[(i + 1) % ring.size()];
      // Lower end first, so an edge two polygons share gives both the same
      // crossing whichever way each runs.
      const bool up = a[1] < b[1] || (a[1] == b[1] && a[0] <= b[0]);
      p.edges_.push_back(up ? Edge{a[0], a[1], b[0], b[1]} : Edge{b[0], b[1], a[0], a[1]});
      p.bounds_.min.x = std::min(p.bounds_.min.x, a[0]);
      p.bounds_.min.y = std::min(p.bounds_.min.y, a[1]);
      p.bounds_.max.x = std::max(p.bounds_.max.x, a[0]);
      p.bounds_.max.y = std::max(p.bounds_.max.y, a[1]);
    }
  }
  if (p.edges_.size() > std::numeric_limits<std::uint32_t>::max() / 2) {
    return invalid_argument(source + ": the polygon has too many vertices");
  }
  p.build_index();
  return p;
}

void Polygon2D::build_index() {
  const double height = bounds_.max.y - bounds_.min.y;
  std::size_t strips = std::clamp<std::size_t>(edges_.size() / 2, 1, 4096);
  for (;;) {
    strip_height_ = height > 0 ? height / static_cast<double>(strips) : 1;
    strip_start_.assign(strips + 1, 0);
    std::size_t total = 0;
    for (const Edge& e : edges_) total += strip_of(e.y1) - strip_of(e.y0) + 1;
    // Long edges listed in many strips: fewer strips, so the index stays a
    // small multiple of the edges.
    if (strips == 1 || total <= 16 * edges_.size() + 4096) break;
    strips /= 2;
  }
  for (const Edge& e : edges_) {
    for (std::size_t s = strip_of(e.y0); s <= strip_of(e.y1); ++s) ++strip_start_[s + 1];
  }
  for (std::size_t s = 0; s + 1 < strip_start_.size(); ++s) strip_start_[s + 1] += strip_start_[s];
  strip_edges_.assign(strip_start_.back(), 0);
  std::vector<std::uint32_t> fill(strip_start_.begin(), strip_start_.end() - 1);
  for (std::size_t i = 0; i < edges_.size(); ++i) {
    for (std::size_t s = strip_of(edges_[i].y0); s <= strip_of(edges_[i].y1); ++s) {
      strip_edges_[fill[s]++] = static_cast<std::uint32_t>(i);
    }
  }
}

std::size_t Polygon2D::strip_of(double y) const {
  const std::size_t strips = strip_start_.size() - 1;
  if (!(y > bounds_.min.y)) return 0;
  const double s = (y - bounds_.min.y) / strip_height_;
  if (!(s < static_cast<double>(strips))) return strips - 1;
  return std::min(static_cast<std::size_t>(s), strips - 1);
}

bool Polygon2D::contains(double x, double y) const {
  if (!(x >= bounds_.min.x && x <= bounds_.max.x && y >= bounds_.min.y && y <= bounds_.max.y)) return false;
  const std::size_t s = strip_of(y);
  bool inside = false;
  for (std::uint32_t k = strip_start_[s]; k < strip_start_[s + 1]; ++k) {
    const Edge& e = edges_[strip_edges_[k]];
    // y0 <= y1: the edge crosses the line at y when y0 <= y < y1.
    if (e.y0 <= y && y < e.y1) {
      const double xi = e.x0 + (y - e.y0) * (e.x1 - e.x0) / (e.y1 - e.y0);
      if (x < xi) inside = !inside;
    }
  }
  return inside;
}

Polygon2D::Overlap Polygon2D::classify(const Box3d& box) const {
  const double rx0 = box.min.x, ry0 = box.min.y, rx1 = box.max.x, ry1 = box.max.y;
  if (!(std::isfinite(rx0) && std::isfinite(ry0) && std::isfinite(rx1) && std::isfinite(ry1))) {
    return Overlap::kPartial;
  }
  if (rx1 < bounds_.min.x || rx0 > bounds_.max.x || ry1 < bounds_.min.y || ry0 > bounds_.max.y) return Overlap::kOutside;
  // An edge within a hair of the rectangle makes it partial, so rounding in
  // the point test cannot put a point of an "inside" rectangle outside.
  const double eps = 1e-9 * (std::abs(rx0) + std::abs(rx1) + std::abs(ry0) + std::abs(ry1) + (rx1 - rx0) + (ry1 - ry0)) +
                     std::numeric_limits<double>::min();
  const double ex0 = rx0 - eps, ey0 = ry0 - eps, ex1 = rx1 + eps, ey1 = ry1 + eps;
  for (std::size_t s = strip_of(ey0); s <= strip_of(ey1); ++s) {
    for (std::uint32_t k = strip_start_[s]; k < strip_start_[s + 1]; ++k) {
      const Edge& e = edges_[strip_edges_[k]];
      if (segment_meets(e.x0, e.y0, e.x1, e.y1, ex0, ey0, ex1, ey1)) return Overlap::kPartial;
    }
  }
  return contains(0.5 * (rx0 + rx1), 0.5 * (ry0 + ry1)) ? Overlap::kInside : Overlap::kOutside;
}

}  // namespace relief
