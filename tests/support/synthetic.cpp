#include "support/synthetic.h"

#include <cmath>
#include <numbers>
#include <utility>

namespace relief::test {

std::uint64_t Rng::next() {
  std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

std::vector<std::uint32_t> Rng::permutation(std::size_t n) {
  std::vector<std::uint32_t> perm(n);
  for (std::size_t i = 0; i < n; ++i) perm[i] = static_cast<std::uint32_t>(i);
  for (std::size_t i = n; i > 1; --i) std::swap(perm[i - 1], perm[next() % i]);
  return perm;
}

double Rng::uniform() { return static_cast<double>(next() >> 11) * (1.0 / 9007199254740992.0); }
double Rng::uniform(double a, double b) { return a + (b - a) * uniform(); }
double Rng::normal() {
  double u1 = uniform();
  if (u1 < 1e-300) u1 = 1e-300;
  const double u2 = uniform();
  return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * std::numbers::pi * u2);
}

namespace {

Vec3d normalized(Vec3d v) {
  const double n = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  return {v.x / n, v.y / n, v.z / n};
}

Vec3d cross(Vec3d a, Vec3d b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

void add_point(PointCloud& c, const SceneOptions& o, Vec3d p) {
  const double f = 0.5 + 0.5 * std::sin(p.x * 3.1) * std::cos(p.y * 2.3 + p.z);
  c.positions.push_back({p.x + o.offset.x, p.y + o.offset.y, p.z + o.offset.z});
  if (o.colors) {
    c.colors.push_back({static_cast<std::uint8_t>(40 + 180 * f),
                        static_cast<std::uint8_t>(200 - 120 * f),
                        static_cast<std::uint8_t>(90 + 60 * std::cos(p.z * 4.0))});
  }
  if (o.intensity) c.intensities.push_back(static_cast<float>(100.0 + 900.0 * f));
}

}  // namespace

PointCloud make_plane(const SceneOptions& o, Vec3d normal, double size) {
  Rng rng(o.seed);
  const Vec3d n = normalized(normal);
  const Vec3d helper = std::abs(n.z) < 0.9 ? Vec3d{0, 0, 1} : Vec3d{1, 0, 0};
  const Vec3d a = normalized(cross(n, helper));
  const Vec3d b = cross(n, a);
  PointCloud c;
  c.reserve(o.points, o.colors, o.intensity);
  for (std::size_t i = 0; i < o.points; ++i) {
    const double s = rng.uniform(-0.5, 0.5) * size;
    const double t = rng.uniform(-0.5, 0.5) * size;
    const double h = o.noise > 0 ? o.noise * rng.normal() : 0.0;
    add_point(c, o, {s * a.x + t * b.x + h * n.x, s * a.y + t * b.y + h * n.y,
                     s * a.z + t * b.z + h * n.z});
  }
  return c;
}

PointCloud make_sphere(const SceneOptions& o, double radius) {
  Rng rng(o.seed);
  PointCloud c;
  c.reserve(o.points, o.colors, o.intensity);
  for (std::size_t i = 0; i < o.points; ++i) {
    const double z = rng.uniform(-1.0, 1.0);
    const double phi = rng.uniform(0.0, 2.0 * std::numbers::pi);
    const double r = std::sqrt(std::max(0.0, 1.0 - z * z));
    const double rr = radius + (o.noise > 0 ? o.noise * rng.normal() : 0.0);
    add_point(c, o, {rr * r * std::cos(phi), rr * r * std::sin(phi), rr * z});
  }
  return c;
}

PointCloud make_terrain(const SceneOptions& o, double size, double amplitude) {
  Rng rng(o.seed);
  PointCloud c;
  c.reserve(o.points, o.colors, o.intensity);
  for (std::size_t i = 0; i < o.points; ++i) {
    const double x = rng.uniform(0.0, size);
    const double y = rng.uniform(0.0, size);
    const double z = amplitude * std::sin(x * 0.7) * std::cos(y * 0.5) +
                     (o.noise > 0 ? o.noise * rng.normal() : 0.0);
    add_point(c, o, {x, y, z});
  }
  return c;
}

PointCloud make_airborne_scan(const SceneOptions& o, double size) {
  Rng rng(o.seed);
  PointCloud c;
  c.reserve(o.points, o.colors, o.intensity);
  const double pulse = 0.25, line = 0.5;
  const auto per_line = static_cast<std::size_t>(size / pulse);
  double t = 2.0e8 + static_cast<double>(o.seed % 97);
  LasAttributes& a = c.las;
  for (std::size_t p = 0; c.size() < o.points; ++p) {
    const std::size_t l = p / per_line, j = p % per_line;
    const double x = pulse * static_cast<double>(l % 2 == 0 ? j : per_line - 1 - j) + 0.02 * rng.normal();
    const double y = line * static_cast<double>(l) + 0.05 * std::sin(static_cast<double>(j) * 0.1);
    const double ground = 2.0 * std::sin(x * 0.11) * std::cos(y * 0.07) + 0.03 * rng.normal();
    t += (j == 0 ? 0.5 : 1.0e-5) + (rng.next() % 2 == 0 ? 0.0 : 1.0e-9);
    const std::uint8_t returns = rng.next() % 5 == 0 ? static_cast<std::uint8_t>(2 + rng.next() % 2) : 1;
    for (std::uint8_t r = 1; r <= returns && c.size() < o.points; ++r) {
      const double z = r == returns ? ground : ground + rng.uniform(2.0, 9.0) / r;
      add_point(c, o, {x + 0.01 * (r - 1), y, z});
      a.return_number.push_back(r);
      a.number_of_returns.push_back(returns);
      a.gps_time.push_back(t);
    }
  }
  return c;
}

PointCloud make_room(const SceneOptions& o, double size) {
  Rng rng(o.seed);
  PointCloud c;
  c.reserve(o.points, o.colors, o.intensity);
  const double h = size * 0.4;
  for (std::size_t i = 0; i < o.points; ++i) {
    const double u = rng.uniform(0.0, size);
    const double v = rng.uniform(0.0, h);
    const double noise = o.noise > 0 ? o.noise * rng.normal() : 0.0;
    Vec3d p;
    switch (rng.next() % 6) {
      case 0: p = {u, rng.uniform(0.0, size), noise}; break;         // floor
      case 1: p = {u, noise, v}; break;                              // wall y=0
      case 2: p = {noise, u, v}; break;                              // wall x=0
      case 3: p = {u, size + noise, v}; break;                       // wall y=size
      case 4: {                                                      // box top
        p = {size * 0.3 + u * 0.2, size * 0.4 + rng.uniform(0.0, size * 0.2), size * 0.15 + noise};
        break;
      }
      default: {                                                     // box side
        p = {size * 0.3 + u * 0.2, size * 0.4 + noise, rng.uniform(0.0, size * 0.15)};
        break;
      }
    }
    add_point(c, o, p);
  }
  return c;
}

}  // namespace relief::test
