// Polygon areas of interest: WKT, shapefile and GeoJSON readers, conversion
// between CRSs, an even-odd point test through a strip index of the edges,
// and a rectangle test that lets a query skip the chunks outside and the
// point tests of the chunks inside.
#include "relief/polygon.h"

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <utility>

#include "geojson.h"
#include "relief/crs.h"

namespace relief {

namespace {

using Ring = std::vector<std::array<double, 2>>;

// Drops the closing vertex and repeated ones (they add nothing; three
// distinct vertices make an area) and returns how many are left.
std::size_t tidy(Ring& ring) {
  if (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
  ring.erase(std::unique(ring.begin(), ring.end()), ring.end());
  if (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
  return ring.size();
}

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
      if (tidy(ring) < 3) {
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
  return from_rings(rings, source);
}

namespace {

std::int32_t le_i32(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (int i = 3; i >= 0; --i) v = (v << 8) | p[i];
  return static_cast<std::int32_t>(v);
}
std::int32_t be_i32(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v = (v << 8) | p[i];
  return static_cast<std::int32_t>(v);
}
double le_f64(const std::uint8_t* p) {
  std::uint64_t v = 0;
  for (int i = 7; i >= 0; --i) v = (v << 8) | p[i];
  double d = 0;
  std::memcpy(&d, &v, sizeof d);
  return d;
}

constexpr std::int32_t kShapefileCode = 9994;
constexpr std::size_t kShapefileHeader = 100;

const char* shape_type_name(std::int32_t t) {
  switch (t) {
    case 1: case 11: case 21: return "a point";
    case 3: case 13: case 23: return "a polyline";
    case 8: case 18: case 28: return "a multipoint";
    case 31: return "a multipatch";
    default: return "an unknown shape";
  }
}

}  // namespace

bool Polygon2D::is_shapefile(std::span<const std::uint8_t> bytes) {
  return bytes.size() >= 4 && be_i32(bytes.data()) == kShapefileCode;
}

Result<Polygon2D> Polygon2D::from_shapefile(std::span<const std::uint8_t> bytes, const std::string& source) {
  const auto bad = [&](const std::string& what) { return format_error(source + ": not a polygon shapefile: " + what); };
  if (bytes.size() < kShapefileHeader || !is_shapefile(bytes)) return bad("no shapefile header (file code 9994)");
  if (le_i32(bytes.data() + 28) != 1000) return bad("version " + std::to_string(le_i32(bytes.data() + 28)) + ", not 1000");
  const std::int32_t type = le_i32(bytes.data() + 32);
  if (type != 5 && type != 15 && type != 25) {
    return bad("its shapes are " + std::string(shape_type_name(type)) + " (type " + std::to_string(type) +
               "), not polygons (5, 15 or 25)");
  }
  // The header's length (16-bit words) may not exceed the bytes present.
  const std::uint64_t declared = 2 * static_cast<std::uint64_t>(static_cast<std::uint32_t>(be_i32(bytes.data() + 24)));
  if (declared > bytes.size()) {
    return bad("truncated: the header declares " + std::to_string(declared) + " bytes, the file has " +
               std::to_string(bytes.size()));
  }
  if (declared < kShapefileHeader) return bad("the header declares " + std::to_string(declared) + " bytes");
  std::vector<Ring> rings;
  std::size_t at = kShapefileHeader;
  std::uint64_t record = 0;
  while (at < declared) {
    ++record;
    const std::string which = "record " + std::to_string(record) + " at byte " + std::to_string(at);
    if (declared - at < 8) return bad(which + ": its header is cut short");
    const std::uint64_t length = 2 * static_cast<std::uint64_t>(static_cast<std::uint32_t>(be_i32(bytes.data() + at + 4)));
    const std::size_t body = at + 8;
    if (length > declared - body) return bad(which + ": its " + std::to_string(length) + " bytes run past the end");
    at = body + static_cast<std::size_t>(length);
    if (length < 4) return bad(which + ": no shape type");
    const std::uint8_t* c = bytes.data() + body;
    const std::int32_t shape = le_i32(c);
    if (shape == 0) continue;  // a null shape
    if (shape != type) {
      return bad(which + ": shape type " + std::to_string(shape) + " in a file of type " + std::to_string(type));
    }
    if (length < 44) return bad(which + ": too short for a polygon");
    const std::int32_t parts = le_i32(c + 36), points = le_i32(c + 40);
    // Both counts bounded by the record's bytes before anything is allocated.
    if (parts < 1 || points < 0 ||
        44 + 4 * static_cast<std::uint64_t>(parts) + 16 * static_cast<std::uint64_t>(points) > length) {
      return bad(which + ": " + std::to_string(parts) + " parts and " + std::to_string(points) +
                 " points do not fit its " + std::to_string(length) + " bytes");
    }
    const std::uint8_t* part_at = c + 44;
    const std::uint8_t* xy = part_at + 4 * static_cast<std::size_t>(parts);
    for (std::int32_t k = 0; k < parts; ++k) {
      const std::int32_t first = le_i32(part_at + 4 * k);
      const std::int32_t end = k + 1 < parts ? le_i32(part_at + 4 * (k + 1)) : points;
      if (first < 0 || first > end || end > points || (k == 0 && first != 0)) {
        return bad(which + ": part " + std::to_string(k + 1) + " starts at point " + std::to_string(first) +
                   " (the parts must start at 0 and rise to the " + std::to_string(points) + " points)");
      }
      Ring ring;
      for (std::int32_t i = first; i < end; ++i) {
        const double x = le_f64(xy + 16 * static_cast<std::size_t>(i)), y = le_f64(xy + 16 * static_cast<std::size_t>(i) + 8);
        if (!std::isfinite(x) || !std::isfinite(y)) return bad(which + ": point " + std::to_string(i) + " is not finite");
        ring.push_back({x, y});
      }
      if (tidy(ring) < 3) {
        return invalid_argument(source + ": " + which + ": part " + std::to_string(k + 1) + " has " +
                                std::to_string(ring.size()) + " distinct vertices; a ring needs 3");
      }
      rings.push_back(std::move(ring));
    }
  }
  if (rings.empty()) return invalid_argument(source + ": the shapefile holds no polygon");
  return from_rings(rings, source);
}

namespace {

// The .prj beside a shapefile (same stem, either case of the extension):
// its path and text, or "" for both when there is none.
Result<std::pair<std::string, std::string>> read_prj(const std::string& shp) {
  for (const char* ext : {".prj", ".PRJ"}) {
    const std::filesystem::path prj = std::filesystem::path(shp).replace_extension(ext);
    std::error_code ec;
    if (!std::filesystem::is_regular_file(prj, ec)) continue;
    const auto size = std::filesystem::file_size(prj, ec);
    if (ec) return io_error(prj.string() + ": cannot read: " + ec.message());
    if (size > (std::uintmax_t{1} << 20)) {
      return invalid_argument(prj.string() + ": " + std::to_string(size) + " bytes; a .prj may hold at most 1 MiB");
    }
    std::ifstream in(prj, std::ios::binary);
    std::string text(static_cast<std::size_t>(size), '\0');
    if (!in || !in.read(text.data(), static_cast<std::streamsize>(text.size()))) return io_error(prj.string() + ": cannot read");
    while (!text.empty() && std::isspace(static_cast<unsigned char>(text.back())) != 0) text.pop_back();
    if (text.empty()) continue;
    return std::pair{prj.string(), text};
  }
  return std::pair<std::string, std::string>{};
}

}  // namespace

Result<Polygon2D> Polygon2D::from_file(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec)) return invalid_argument(path + ": is a directory, not a polygon file");
  const auto size = std::filesystem::file_size(path, ec);
  if (ec) return io_error(path + ": cannot read: " + ec.message());
  constexpr std::uintmax_t kMaxBytes = std::uintmax_t{256} << 20;
  if (size > kMaxBytes) {
    return invalid_argument(path + ": " + std::to_string(size) + " bytes; a polygon file may hold at most 256 MiB");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) return io_error(path + ": cannot open");
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(size));
  in.read(reinterpret_cast<char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) return io_error(path + ": read error");
  if (is_shapefile(bytes)) {
    RELIEF_ASSIGN_OR_RETURN(Polygon2D p, from_shapefile(bytes, path));
    RELIEF_ASSIGN_OR_RETURN(const auto prj, read_prj(path));
    if (!prj.second.empty()) RELIEF_RETURN_IF_ERROR(p.set_crs(prj.second, prj.first));
    return p;
  }
  const std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  if (geojson::looks_like(text)) return from_geojson(text, path);
  return from_wkt(text, path);
}

Result<Polygon2D> Polygon2D::from_arg(const std::string& text) {
  if (!text.empty() && text[0] == '@') return from_file(text.substr(1));
  if (geojson::looks_like(text)) return from_geojson(text, "the polygon");
  return from_wkt(text, "the polygon");
}

Result<Polygon2D> Polygon2D::from_geojson(std::string_view text, const std::string& source) {
  geojson::Area area;
  RELIEF_RETURN_IF_ERROR(geojson::read(text, source, area));
  std::vector<Ring> rings;
  rings.reserve(area.rings.size());
  for (geojson::Ring& r : area.rings) {
    if (tidy(r.vertices) < 3) {
      return invalid_argument(source + ": " + r.label + " has " + std::to_string(r.vertices.size()) +
                              " distinct vertices; a ring needs 3");
    }
    rings.push_back(std::move(r.vertices));
  }
  RELIEF_ASSIGN_OR_RETURN(Polygon2D p, from_rings(rings, source));
  RELIEF_RETURN_IF_ERROR(p.set_crs(area.crs, source));
  return p;
}

Status Polygon2D::set_crs(const std::string& crs, const std::string& where) {
  if (!crs.empty()) RELIEF_RETURN_IF_ERROR(crs_to_wkt2(crs, where).status());
  crs_ = crs;
  return Status::ok();
}

Result<Polygon2D> Polygon2D::converted_to(const std::string& target, const std::string& where) const {
  const std::string from = crs_.empty() ? target : crs_;
  RELIEF_ASSIGN_OR_RETURN(CrsTransform t, CrsTransform::create(from, target, where));
  const auto convert = [&](double x, double y) -> Result<std::array<double, 2>> {
    double cx = x, cy = y;
    if (!t.apply(cx, cy)) {
      char text[200];
      std::snprintf(text, sizeof text, ": the polygon's vertex (%.17g, %.17g) cannot be converted from ", x, y);
      return invalid_argument(where + text + crs_label(from) + " to " + crs_label(target) +
                              ": are its coordinates in that CRS, easting or longitude first?");
    }
    return std::array<double, 2>{cx, cy};
  };
  // Every vertex first (each edge's ends), for the converted area's extent.
  std::vector<std::array<double, 2>> ends;
  ends.reserve(2 * edges_.size());
  double x0 = std::numeric_limits<double>::infinity(), y0 = x0, x1 = -x0, y1 = -x0;
  for (const Edge& e : edges_) {
    for (const auto& [x, y] : {std::pair{e.x0, e.y0}, std::pair{e.x1, e.y1}}) {
      RELIEF_ASSIGN_OR_RETURN(const auto c, convert(x, y));
      ends.push_back(c);
      x0 = std::min(x0, c[0]);
      y0 = std::min(y0, c[1]);
      x1 = std::max(x1, c[0]);
      y1 = std::max(y1, c[1]);
    }
  }
  // Pieces of an edge: split where the converted midpoint of the source's
  // straight edge lies more than 10^-7 of the area's extent off the straight
  // piece, up to 10 levels deep, within a budget for the whole area.
  const double tolerance = 1e-7 * std::hypot(x1 - x0, y1 - y0);
  constexpr int kMaxLevels = 10;
  const std::size_t budget = std::max<std::size_t>(16 * edges_.size(), std::size_t{1} << 20);
  std::vector<Edge> out;
  out.reserve(edges_.size());
  struct Piece {
    double sx0, sy0, sx1, sy1;  // in the source
    std::array<double, 2> a, b;  // converted ends
    int level;
  };
  std::vector<Piece> stack;
  for (std::size_t i = 0; i < edges_.size(); ++i) {
    const Edge& e = edges_[i];
    stack.push_back({e.x0, e.y0, e.x1, e.y1, ends[2 * i], ends[2 * i + 1], 0});
    while (!stack.empty()) {
      const Piece p = stack.back();
      stack.pop_back();
      bool split = false;
      if (p.level < kMaxLevels && out.size() + stack.size() + 2 <= budget) {
        const double mx = 0.5 * (p.sx0 + p.sx1), my = 0.5 * (p.sy0 + p.sy1);
        RELIEF_ASSIGN_OR_RETURN(const auto m, convert(mx, my));
        split = std::hypot(m[0] - 0.5 * (p.a[0] + p.b[0]), m[1] - 0.5 * (p.a[1] + p.b[1])) > tolerance;
        if (split) {
          // Second half first on the stack, so pieces come out in order.
          stack.push_back({mx, my, p.sx1, p.sy1, m, p.b, p.level + 1});
          stack.push_back({p.sx0, p.sy0, mx, my, p.a, m, p.level + 1});
        }
      }
      if (!split) out.push_back({p.a[0], p.a[1], p.b[0], p.b[1]});
    }
  }
  RELIEF_ASSIGN_OR_RETURN(Polygon2D p, from_edges(std::move(out), ring_count_, where));
  p.crs_ = target;
  return p;
}

Result<Polygon2D> Polygon2D::from_rings(const std::vector<std::vector<std::array<double, 2>>>& rings,
                                        const std::string& source) {
  std::vector<Edge> edges;
  for (const Ring& ring : rings) {
    for (std::size_t i = 0; i < ring.size(); ++i) {
      const auto& a = ring[i];
      const auto& b = ring[(i + 1) % ring.size()];
      edges.push_back({a[0], a[1], b[0], b[1]});
    }
  }
  return from_edges(std::move(edges), rings.size(), source);
}

Result<Polygon2D> Polygon2D::from_edges(std::vector<Edge> edges, std::size_t rings, const std::string& source) {
  // Archives hold coordinates within 2^50 (README, Limits); so must an area,
  // which also keeps the crossing test's products far from overflow.
  constexpr double kLimit = 1125899906842624.0;  // 2^50
  for (const Edge& e : edges) {
    for (const auto& [x, y] : {std::pair{e.x0, e.y0}, std::pair{e.x1, e.y1}}) {
      if (std::abs(x) > kLimit || std::abs(y) > kLimit) {
        char text[160];
        std::snprintf(text, sizeof text, ": the polygon has the vertex (%.17g, %.17g), beyond the coordinate limit of 2^50",
                      x, y);
        return invalid_argument(source + text);
      }
    }
  }
  // The strip index holds at most 16 entries an edge (+ 4096) in 32-bit offsets.
  if (edges.size() > (std::numeric_limits<std::uint32_t>::max() - 4096) / 16) {
    return invalid_argument(source + ": the polygon has " + std::to_string(edges.size()) +
                            " vertices; at most 268,435,199 are taken");
  }
  Polygon2D p;
  p.ring_count_ = rings;
  const double inf = std::numeric_limits<double>::infinity();
  p.bounds_ = Box3d{{inf, inf, -inf}, {-inf, -inf, inf}};
  for (Edge& e : edges) {
    // Lower end first, so an edge two polygons share gives both the same
    // crossing whichever way each runs.
    if (!(e.y0 < e.y1 || (e.y0 == e.y1 && e.x0 <= e.x1))) e = Edge{e.x1, e.y1, e.x0, e.y0};
    p.bounds_.min.x = std::min({p.bounds_.min.x, e.x0, e.x1});
    p.bounds_.min.y = std::min(p.bounds_.min.y, e.y0);
    p.bounds_.max.x = std::max({p.bounds_.max.x, e.x0, e.x1});
    p.bounds_.max.y = std::max(p.bounds_.max.y, e.y1);
  }
  p.edges_ = std::move(edges);
  p.build_index();
  return p;
}

void Polygon2D::build_index() {
  const double height = bounds_.max.y - bounds_.min.y;
  // About two edges a strip, up to 2^16 strips (a detailed coastline of
  // 10^5-10^6 vertices still tests a handful of edges a point).
  std::size_t strips = std::clamp<std::size_t>(edges_.size() / 2, 1, std::size_t{1} << 16);
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
