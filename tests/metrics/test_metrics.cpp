// Tests of the Golla & Klein error measures (lib/metrics).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include <catch2/catch.hpp>

#include "relief/metrics.h"
#include "support/synthetic.h"

namespace relief {
namespace {

using test::SceneOptions;

constexpr double kInf = std::numeric_limits<double>::infinity();

ErrorMetrics compare_ok(const PointCloud& p, const PointCloud& q, unsigned threads = 0) {
  MetricsOptions options;
  options.threads = threads;
  Result<ErrorMetrics> r = compare_clouds(p, q, options);
  INFO(r.status().to_string());
  REQUIRE(r.is_ok());
  return *r;
}

PointCloud cloud_of(const std::vector<Vec3d>& points, const std::vector<Rgb8>& colors = {}) {
  PointCloud c;
  c.positions = points;
  c.colors = colors;
  return c;
}

double squared_distance(const Vec3d& a, const Vec3d& b) {
  const double dx = a.x - b.x;
  const double dy = a.y - b.y;
  const double dz = a.z - b.z;
  return dx * dx + dy * dy + dz * dz;
}

// Reference answers by exhaustive search, written independently of the kd-tree code.
struct BruteDirection {
  double mse = 0;
  double max_sq = 0;
  double mse_rgb = 0;
};

BruteDirection brute_direction(const PointCloud& from, const PointCloud& to) {
  long double sum = 0;
  long double sum_rgb = 0;
  BruteDirection out;
  for (std::size_t i = 0; i < from.size(); ++i) {
    std::size_t best = 0;
    double best_sq = kInf;
    for (std::size_t j = 0; j < to.size(); ++j) {
      const double d2 = squared_distance(from.positions[i], to.positions[j]);
      if (d2 < best_sq) {
        best_sq = d2;
        best = j;
      }
    }
    sum += best_sq;
    out.max_sq = std::max(out.max_sq, best_sq);
    if (from.has_colors() && to.has_colors()) {
      const Rgb8 a = from.colors[i];
      const Rgb8 b = to.colors[best];
      const double dr = static_cast<double>(a.r) - static_cast<double>(b.r);
      const double dg = static_cast<double>(a.g) - static_cast<double>(b.g);
      const double db = static_cast<double>(a.b) - static_cast<double>(b.b);
      sum_rgb += (dr * dr + dg * dg + db * db) / 3.0;
    }
  }
  out.mse = static_cast<double>(sum / static_cast<long double>(from.size()));
  out.mse_rgb = static_cast<double>(sum_rgb / static_cast<long double>(from.size()));
  return out;
}

void check_relative(double actual, double expected, double rel) {
  INFO("actual " << actual << " expected " << expected);
  CHECK(std::abs(actual - expected) <= rel * std::max(std::abs(expected), 1e-300));
}

void check_all_relative(const ErrorMetrics& a, const ErrorMetrics& b, double rel) {
  CHECK(a.points_original == b.points_original);
  CHECK(a.points_reconstructed == b.points_reconstructed);
  CHECK(a.has_rgb == b.has_rgb);
  check_relative(a.rmse_nn_pq, b.rmse_nn_pq, rel);
  check_relative(a.rmse_nn_qp, b.rmse_nn_qp, rel);
  check_relative(a.rmse_snn, b.rmse_snn, rel);
  check_relative(a.hausdorff, b.hausdorff, rel);
  check_relative(a.peak, b.peak, rel);
  check_relative(a.psnr, b.psnr, rel);
  check_relative(a.rmse_rgb_nn_pq, b.rmse_rgb_nn_pq, rel);
  check_relative(a.rmse_rgb_nn_qp, b.rmse_rgb_nn_qp, rel);
  check_relative(a.rmse_rgb_snn, b.rmse_rgb_snn, rel);
  check_relative(a.psnr_rgb, b.psnr_rgb, rel);
}

PointCloud flat_plane(std::size_t points, std::uint64_t seed, bool colors = false) {
  SceneOptions o;
  o.seed = seed;
  o.points = points;
  o.colors = colors;
  return test::make_plane(o, {0, 0, 1}, 100.0);
}

}  // namespace

TEST_CASE("identical clouds have zero error and infinite PSNR", "[metrics]") {
  SceneOptions o;
  o.seed = 7;
  o.points = 5000;
  o.noise = 0.02;
  o.colors = true;
  const PointCloud p = test::make_room(o, 8.0);
  const ErrorMetrics m = compare_ok(p, p);
  CHECK(m.points_original == p.size());
  CHECK(m.points_reconstructed == p.size());
  CHECK(m.rmse_nn_pq == 0);
  CHECK(m.rmse_nn_qp == 0);
  CHECK(m.rmse_snn == 0);
  CHECK(m.hausdorff == 0);
  CHECK(m.peak == Approx(p.bounds().diagonal()).epsilon(1e-15));
  CHECK(m.psnr == kInf);
  CHECK(m.has_rgb);
  CHECK(m.rmse_rgb_nn_pq == 0);
  CHECK(m.rmse_rgb_nn_qp == 0);
  CHECK(m.rmse_rgb_snn == 0);
  CHECK(m.psnr_rgb == kInf);
}

TEST_CASE("a shift of every point along the plane normal gives rmse = shift", "[metrics]") {
  // A shift orthogonal to the plane keeps every point's nearest neighbour its
  // own shifted copy: |p - p' + d n|^2 = |p - p'|^2 + d^2 > d^2 for p' != p.
  const double d = 0.01;
  const PointCloud p = flat_plane(400, 3);
  PointCloud q = p;
  for (Vec3d& v : q.positions) v.z += d;
  const ErrorMetrics m = compare_ok(p, q);
  CHECK(m.rmse_nn_pq == Approx(d).epsilon(1e-12));
  CHECK(m.rmse_nn_qp == Approx(d).epsilon(1e-12));
  CHECK(m.rmse_snn == Approx(d).epsilon(1e-12));
  CHECK(m.hausdorff == Approx(d).epsilon(1e-12));
  CHECK_FALSE(m.has_rgb);
  CHECK(m.rmse_rgb_snn == 0);
  CHECK(m.psnr_rgb == 0);
}

TEST_CASE("PSNR uses the original's bounding-box diagonal and the worse direction", "[metrics]") {
  const double d = 0.05;
  const PointCloud p = flat_plane(300, 11);
  PointCloud q = p;
  for (Vec3d& v : q.positions) v.z -= d;
  const ErrorMetrics m = compare_ok(p, q);
  const double peak = p.bounds().diagonal();
  CHECK(m.peak == Approx(peak).epsilon(1e-15));
  CHECK(m.psnr == Approx(20.0 * std::log10(peak / d)).epsilon(1e-12));

  // Asymmetric case: the worse of the two RMSEs drives the PSNR, and swapping
  // the arguments changes the peak because only the original's box counts.
  const PointCloud a = cloud_of({{0, 0, 0}, {4, 0, 0}, {4, 3, 0}});
  const PointCloud b = cloud_of({{0, 0, 0}, {4, 0, 0}, {4, 3, 0}, {0, 0, 12}});
  const ErrorMetrics ab = compare_ok(a, b);
  CHECK(ab.peak == Approx(5.0).epsilon(1e-15));
  CHECK(ab.rmse_nn_pq == 0);
  CHECK(ab.rmse_nn_qp == Approx(6.0).epsilon(1e-15));  // sqrt(144 / 4)
  CHECK(ab.psnr == Approx(20.0 * std::log10(5.0 / 6.0)).epsilon(1e-12));
  const ErrorMetrics ba = compare_ok(b, a);
  CHECK(ba.peak == Approx(13.0).epsilon(1e-15));
  CHECK(ba.rmse_nn_pq == Approx(6.0).epsilon(1e-15));
  CHECK(ba.rmse_nn_qp == 0);
  CHECK(ba.psnr == Approx(20.0 * std::log10(13.0 / 6.0)).epsilon(1e-12));
}

TEST_CASE("asymmetric case: a subset matches a brute-force search", "[metrics]") {
  SceneOptions o;
  o.seed = 5;
  o.points = 360;
  o.noise = 0.01;
  o.colors = true;
  const PointCloud p = test::make_sphere(o, 2.0);
  PointCloud q;
  for (std::size_t i = 0; i < p.size(); i += 3) {
    q.positions.push_back(p.positions[i]);
    q.colors.push_back(p.colors[i]);
  }
  const ErrorMetrics m = compare_ok(p, q);
  const BruteDirection pq = brute_direction(p, q);
  const BruteDirection qp = brute_direction(q, p);
  REQUIRE(pq.mse > 0);
  CHECK(qp.mse == 0);
  CHECK(m.rmse_nn_qp == 0);
  CHECK(m.rmse_nn_pq > 0);
  check_relative(m.rmse_nn_pq, std::sqrt(pq.mse), 1e-12);
  check_relative(m.rmse_snn, std::sqrt(0.5 * pq.mse), 1e-12);
  check_relative(m.hausdorff, std::sqrt(pq.max_sq), 1e-12);
  check_relative(m.psnr, 20.0 * std::log10(p.bounds().diagonal() / std::sqrt(pq.mse)), 1e-12);
  REQUIRE(m.has_rgb);
  CHECK(m.rmse_rgb_nn_qp == 0);
  check_relative(m.rmse_rgb_nn_pq, std::sqrt(pq.mse_rgb), 1e-12);
  check_relative(m.rmse_rgb_snn, std::sqrt(0.5 * pq.mse_rgb), 1e-12);
}

TEST_CASE("two unrelated noisy clouds match a brute-force search both ways", "[metrics]") {
  SceneOptions o;
  o.points = 1500;
  o.noise = 0.03;
  o.colors = true;
  o.seed = 21;
  const PointCloud p = test::make_terrain(o, 10.0, 0.7);
  o.points = 1100;
  o.seed = 22;
  o.noise = 0.08;
  const PointCloud q = test::make_terrain(o, 10.0, 0.7);
  const ErrorMetrics m = compare_ok(p, q);
  const BruteDirection pq = brute_direction(p, q);
  const BruteDirection qp = brute_direction(q, p);
  check_relative(m.rmse_nn_pq, std::sqrt(pq.mse), 1e-12);
  check_relative(m.rmse_nn_qp, std::sqrt(qp.mse), 1e-12);
  check_relative(m.rmse_snn, std::sqrt(0.5 * pq.mse + 0.5 * qp.mse), 1e-12);
  check_relative(m.hausdorff, std::sqrt(std::max(pq.max_sq, qp.max_sq)), 1e-12);
  check_relative(m.rmse_rgb_nn_pq, std::sqrt(pq.mse_rgb), 1e-12);
  check_relative(m.rmse_rgb_nn_qp, std::sqrt(qp.mse_rgb), 1e-12);
}

TEST_CASE("colour error on a hand-made example", "[metrics]") {
  // P -> Q: p0 -> q0 differs by (3, 4, 0): 25/3; p1 -> q1 by (0, 0, 10): 100/3.
  // Q -> P: q0 -> p0: 25/3; q1 -> p1: 100/3; q2 (20,0,0) is nearest to p1
  // (distance 10 vs 20) and differs by (100, 100, 100): 10000.
  const PointCloud p = cloud_of({{0, 0, 0}, {10, 0, 0}}, {{10, 20, 30}, {100, 100, 100}});
  const PointCloud q = cloud_of({{0.1, 0, 0}, {10, 0, 0.2}, {20, 0, 0}},
                                {{13, 24, 30}, {100, 100, 90}, {0, 0, 0}});
  const ErrorMetrics m = compare_ok(p, q);
  const double mse_pq = (25.0 / 3.0 + 100.0 / 3.0) / 2.0;
  const double mse_qp = (25.0 / 3.0 + 100.0 / 3.0 + 10000.0) / 3.0;
  REQUIRE(m.has_rgb);
  CHECK(m.rmse_rgb_nn_pq == Approx(std::sqrt(mse_pq)).epsilon(1e-14));
  CHECK(m.rmse_rgb_nn_qp == Approx(std::sqrt(mse_qp)).epsilon(1e-14));
  const double snn = std::sqrt(0.5 * mse_pq + 0.5 * mse_qp);
  CHECK(m.rmse_rgb_snn == Approx(snn).epsilon(1e-14));
  CHECK(m.psnr_rgb == Approx(20.0 * std::log10(255.0 / snn)).epsilon(1e-13));

  SECTION("colour is only measured when both clouds carry it") {
    const PointCloud bare = cloud_of(q.positions);
    const ErrorMetrics n1 = compare_ok(p, bare);
    const ErrorMetrics n2 = compare_ok(bare, p);
    for (const ErrorMetrics& n : {n1, n2}) {
      CHECK_FALSE(n.has_rgb);
      CHECK(n.rmse_rgb_nn_pq == 0);
      CHECK(n.rmse_rgb_nn_qp == 0);
      CHECK(n.rmse_rgb_snn == 0);
      CHECK(n.psnr_rgb == 0);
    }
    // Geometry does not depend on colour. n2 has the roles swapped and so is
    // re-centred on another origin, which may change the last bit.
    CHECK(n1.rmse_nn_pq == m.rmse_nn_pq);
    CHECK(n1.rmse_nn_qp == m.rmse_nn_qp);
    CHECK(n2.rmse_nn_pq == Approx(m.rmse_nn_qp).epsilon(1e-14));
    CHECK(n2.rmse_nn_qp == Approx(m.rmse_nn_pq).epsilon(1e-14));
  }
}

TEST_CASE("Hausdorff distance on a hand-made example", "[metrics]") {
  // P -> Q: the farthest point of P is (5,0,0), 2 from (3,0,0).
  // Q -> P: (0,3,4) is 5 from (0,0,0). Hausdorff = max(2, 5) = 5.
  const PointCloud p = cloud_of({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {5, 0, 0}});
  const PointCloud q = cloud_of({{0, 0, 0}, {1, 0, 0}, {3, 0, 0}, {0, 3, 4}});
  const ErrorMetrics m = compare_ok(p, q);
  CHECK(m.hausdorff == Approx(5.0).epsilon(1e-15));
  // P -> Q squared distances 0, 0, 1, 4; Q -> P: 0, 0, 1, 25.
  CHECK(m.rmse_nn_pq == Approx(std::sqrt(5.0 / 4.0)).epsilon(1e-15));
  CHECK(m.rmse_nn_qp == Approx(std::sqrt(26.0 / 4.0)).epsilon(1e-15));
  CHECK(m.rmse_snn == Approx(std::sqrt(0.5 * 5.0 / 4.0 + 0.5 * 26.0 / 4.0)).epsilon(1e-15));
  // The direction does not matter for the Hausdorff distance.
  CHECK(compare_ok(q, p).hausdorff == Approx(5.0).epsilon(1e-15));
}

TEST_CASE("single points on both sides", "[metrics]") {
  const ErrorMetrics m = compare_ok(cloud_of({{1, 2, 3}}), cloud_of({{1, 2, 5}}));
  CHECK(m.points_original == 1);
  CHECK(m.points_reconstructed == 1);
  CHECK(m.rmse_nn_pq == 2);
  CHECK(m.rmse_nn_qp == 2);
  CHECK(m.hausdorff == 2);
  CHECK(m.peak == 0);
  CHECK(m.psnr == -kInf);  // 20 log10(0 / 2): the original has no extent
}

TEST_CASE("georeferenced offsets do not change the result", "[metrics]") {
  SceneOptions o;
  o.points = 20000;
  o.noise = 0.005;
  o.colors = true;
  o.seed = 31;
  const PointCloud p = test::make_room(o, 20.0);
  o.seed = 32;
  o.noise = 0.02;
  o.points = 15000;
  const PointCloud q = test::make_room(o, 20.0);

  const Vec3d offset{5e5, 6e6, 0};
  auto shifted = [&](PointCloud c) {
    for (Vec3d& v : c.positions) {
      v.x += offset.x;
      v.y += offset.y;
      v.z += offset.z;
    }
    return c;
  };
  const ErrorMetrics local = compare_ok(p, q);
  const ErrorMetrics geo = compare_ok(shifted(p), shifted(q));
  // Adding 6e6 rounds each coordinate by up to ulp(6e6) / 2 ~ 4.7e-10 m,
  // so distances of some centimetres agree to about 1e-9 m.
  CHECK(std::abs(geo.rmse_nn_pq - local.rmse_nn_pq) <= 1e-9);
  CHECK(std::abs(geo.rmse_nn_qp - local.rmse_nn_qp) <= 1e-9);
  CHECK(std::abs(geo.rmse_snn - local.rmse_snn) <= 1e-9);
  CHECK(std::abs(geo.hausdorff - local.hausdorff) <= 1e-9);
  CHECK(std::abs(geo.peak - local.peak) <= 1e-9);
  CHECK(std::abs(geo.psnr - local.psnr) <= 1e-6);
  CHECK(geo.rmse_rgb_snn == Approx(local.rmse_rgb_snn).epsilon(1e-12));
  CHECK(local.rmse_nn_pq > 0.001);  // a meaningful, non-trivial error
}

TEST_CASE("empty clouds are rejected and the message names the empty one", "[metrics]") {
  const PointCloud full = flat_plane(10, 1);
  const PointCloud empty;
  SECTION("original") {
    const Result<ErrorMetrics> r = compare_clouds(empty, full);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kInvalidArgument);
    CHECK(r.status().message().find("original") != std::string::npos);
  }
  SECTION("reconstructed") {
    const Result<ErrorMetrics> r = compare_clouds(full, empty);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kInvalidArgument);
    CHECK(r.status().message().find("reconstructed") != std::string::npos);
  }
  SECTION("both") {
    const Result<ErrorMetrics> r = compare_clouds(empty, empty);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kInvalidArgument);
  }
}

TEST_CASE("non-finite coordinates and inconsistent attributes are rejected", "[metrics]") {
  const PointCloud good = flat_plane(50, 2);
  PointCloud nan_cloud = good;
  nan_cloud.positions[17].y = std::numeric_limits<double>::quiet_NaN();
  PointCloud inf_cloud = good;
  inf_cloud.positions[3].z = kInf;

  const Result<ErrorMetrics> a = compare_clouds(nan_cloud, good);
  REQUIRE_FALSE(a.is_ok());
  CHECK(a.status().code() == StatusCode::kInvalidArgument);
  CHECK(a.status().message().find("original") != std::string::npos);

  const Result<ErrorMetrics> b = compare_clouds(good, nan_cloud);
  REQUIRE_FALSE(b.is_ok());
  CHECK(b.status().code() == StatusCode::kInvalidArgument);
  CHECK(b.status().message().find("reconstructed") != std::string::npos);

  const Result<ErrorMetrics> c = compare_clouds(good, inf_cloud);
  REQUIRE_FALSE(c.is_ok());
  CHECK(c.status().code() == StatusCode::kInvalidArgument);

  PointCloud short_colors = good;
  short_colors.colors.resize(good.size() - 1);
  const Result<ErrorMetrics> d = compare_clouds(good, short_colors);
  REQUIRE_FALSE(d.is_ok());
  CHECK(d.status().code() == StatusCode::kInvalidArgument);
}

TEST_CASE("the thread count does not change the result", "[metrics]") {
  SceneOptions o;
  o.points = 30000;
  o.noise = 0.01;
  o.colors = true;
  o.seed = 41;
  const PointCloud p = test::make_terrain(o, 30.0, 2.0);
  o.points = 25000;
  o.noise = 0.03;
  o.seed = 42;
  const PointCloud q = test::make_terrain(o, 30.0, 2.0);
  const ErrorMetrics one = compare_ok(p, q, 1);
  const ErrorMetrics two = compare_ok(p, q, 2);
  const ErrorMetrics three = compare_ok(p, q, 3);
  const ErrorMetrics all = compare_ok(p, q, 0);
  check_all_relative(two, one, 1e-12);
  check_all_relative(three, one, 1e-12);
  check_all_relative(all, one, 1e-12);
  CHECK(one.rmse_nn_pq > 0);
  CHECK(one.rmse_rgb_snn > 0);
}

}  // namespace relief
