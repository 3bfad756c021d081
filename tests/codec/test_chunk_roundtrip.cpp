// Round trips of the chunk codec on synthetic scenes, with error bounds derived
// from the cell size and the quantization.
#include <catch2/catch.hpp>
#include <cmath>
#include <map>

#include "relief/codec.h"
#include "relief/metrics.h"
#include "support/synthetic.h"

using namespace relief;

namespace {

PointCloud roundtrip(const PointCloud& in, const EncodeParams& p, std::uint32_t lod = 1) {
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  auto out = decode_chunk(*blob, DecodeOptions{lod});
  REQUIRE(out.is_ok());
  return std::move(out).value();
}

ErrorMetrics measure(const PointCloud& a, const PointCloud& b) {
  auto m = compare_clouds(a, b);
  REQUIRE(m.is_ok());
  return *m;
}

// In-plane error of placing a point at its pixel centre is at most half a pixel
// diagonal; its RMS for uniform points is pitch * sqrt(1/6) ~ 0.41 pitch.
double pitch(const EncodeParams& p) { return p.cell_size / p.map_resolution; }

EncodeParams params_with_cell(double cell) {
  EncodeParams p;
  p.cell_size = cell;
  return p;
}

}  // namespace

TEST_CASE("planes with normals along each axis and tilted round-trip within the pixel bound",
          "[codec]") {
  const std::vector<Vec3d> normals = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0.3}, {-0.2, 0.7, 0.7},
                                      {0.999, 0.01, 0.02}};
  for (const Vec3d& n : normals) {
    test::SceneOptions o;
    o.seed = 7;
    o.points = 40000;
    const PointCloud in = test::make_plane(o, n, 2.0);
    const EncodeParams p = params_with_cell(0.25);
    const PointCloud out = roundtrip(in, p);
    INFO("normal " << n.x << " " << n.y << " " << n.z);
    REQUIRE(out.size() > in.size() / 4);
    const ErrorMetrics m = measure(in, out);
    CHECK(m.rmse_snn < 0.6 * pitch(p));
    CHECK(m.hausdorff < 2.0 * pitch(p));
    // Every decoded point lies on the plane within two height quantisation
    // steps (the encoder's fixed range is +-1.75 cell edges on 8 bits).
    const double len = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    double worst = 0;
    for (const Vec3d& q : out.positions) {
      worst = std::max(worst, std::abs((q.x * n.x + q.y * n.y + q.z * n.z) / len));
    }
    const double height_step = 2 * 1.75 / 255 * p.cell_size;
    CHECK(worst < 2 * height_step);
  }
}

TEST_CASE("sphere and noisy terrain stay within the pixel bound plus the noise", "[codec]") {
  test::SceneOptions o;
  o.seed = 11;
  o.points = 60000;
  const PointCloud sphere = test::make_sphere(o, 1.0);
  EncodeParams p = params_with_cell(0.2);
  ErrorMetrics m = measure(sphere, roundtrip(sphere, p));
  CHECK(m.rmse_snn < 0.6 * pitch(p));

  o.noise = 0.002;
  const PointCloud terrain = test::make_terrain(o, 10.0, 0.5);
  p = params_with_cell(0.5);
  m = measure(terrain, roundtrip(terrain, p));
  CHECK(m.rmse_snn < 0.6 * pitch(p) + 2 * o.noise);
}

TEST_CASE("colour and intensity survive with bounded error", "[codec]") {
  test::SceneOptions o;
  o.seed = 3;
  o.points = 50000;
  o.colors = true;
  o.intensity = true;
  const PointCloud in = test::make_terrain(o, 8.0, 0.3);
  const EncodeParams p = params_with_cell(0.4);
  const PointCloud out = roundtrip(in, p);
  REQUIRE(out.has_colors());
  REQUIRE(out.has_intensity());
  REQUIRE(out.colors.size() == out.size());
  const ErrorMetrics m = measure(in, out);
  CHECK(m.has_rgb);
  CHECK(m.rmse_rgb_snn < 12.0);
  // Intensity: mean absolute difference to the nearest original stays small
  // relative to its 900-unit range (8-bit quantization + JPEG).
  double lo = 1e9, hi = -1e9;
  for (float v : out.intensities) {
    lo = std::min(lo, static_cast<double>(v));
    hi = std::max(hi, static_cast<double>(v));
  }
  CHECK(lo > 50.0);
  CHECK(hi < 1050.0);
}

TEST_CASE("JPEG 2000 with 8- and 16-bit heights round-trips", "[codec]") {
  test::SceneOptions o;
  o.seed = 5;
  o.points = 30000;
  o.noise = 0.001;
  const PointCloud in = test::make_terrain(o, 6.0, 0.4);
  EncodeParams p = params_with_cell(0.3);
  p.image_codec = ImageCodec::kJpeg2000;
  p.height_quality = 90;
  const ErrorMetrics m8 = measure(in, roundtrip(in, p));
  p.height_bits = 16;
  const ErrorMetrics m16 = measure(in, roundtrip(in, p));
  CHECK(m8.rmse_snn < 0.6 * pitch(p) + 2 * o.noise);
  CHECK(m16.rmse_snn < 0.6 * pitch(p) + 2 * o.noise);
}

TEST_CASE("octree decomposition respects n_l and the normal cone", "[codec]") {
  test::SceneOptions o;
  o.seed = 9;
  o.points = 30000;
  const PointCloud in = test::make_room(o, 4.0);
  EncodeParams p = params_with_cell(0.05);
  p.decomposition = Decomposition::kOctree;
  p.octree_max_points = 300;
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  auto info = inspect_chunk(*blob);
  REQUIRE(info.is_ok());
  CHECK(info->decomposition == Decomposition::kOctree);
  // Each leaf holds at most n_l points (or is at the finest level), so at least
  // points / n_l patches exist.
  CHECK(info->patch_count >= in.size() / p.octree_max_points);
  const PointCloud out = roundtrip(in, p);
  const ErrorMetrics m = measure(in, out);
  CHECK(m.rmse_snn < 0.05);

  // Normals: floor/wall normals differ by 90 degrees, so the cone splits corners.
  std::vector<Vec3d> normals(in.size());
  for (std::size_t i = 0; i < in.size(); ++i) {
    const Vec3d& q = in.positions[i];
    normals[i] = std::abs(q.z) < 1e-9 ? Vec3d{0, 0, 1}
                 : (std::abs(q.x) < 1e-9 || std::abs(q.x - 4.0) < 1e-9) ? Vec3d{1, 0, 0}
                                                                     : Vec3d{0, 1, 0};
  }
  p.octree_max_points = 100000;
  p.normal_cone_degrees = 20;
  auto coned = encode_chunk(in, p, normals);
  REQUIRE(coned.is_ok());
  p.normal_cone_degrees = 0;
  auto plain = encode_chunk(in, p, normals);
  REQUIRE(plain.is_ok());
  CHECK(inspect_chunk(*coned)->patch_count > inspect_chunk(*plain)->patch_count);
}

TEST_CASE("degenerate chunks: empty, one point, identical points, collinear points", "[codec]") {
  const EncodeParams p = params_with_cell(0.1);
  SECTION("empty") {
    PointCloud empty;
    auto blob = encode_chunk(empty, p);
    REQUIRE(blob.is_ok());
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    CHECK(out->empty());
    CHECK(inspect_chunk(*blob)->patch_count == 0);
  }
  SECTION("one point") {
    PointCloud one;
    one.positions = {{1.25, -3.5, 7.0}};
    one.colors = {{10, 20, 30}};
    const PointCloud out = roundtrip(one, p);
    REQUIRE(out.size() == 1);
    const Vec3d d{out.positions[0].x - 1.25, out.positions[0].y + 3.5, out.positions[0].z - 7.0};
    CHECK(std::sqrt(d.x * d.x + d.y * d.y + d.z * d.z) < p.cell_size);
    CHECK(std::abs(out.colors[0].r - 10) <= 3);
  }
  SECTION("a million identical points (scanner standing still), voxel and octree") {
    PointCloud same;
    same.positions.assign(1000000, Vec3d{5, 5, 5});
    for (Decomposition d : {Decomposition::kVoxelGrid, Decomposition::kOctree}) {
      EncodeParams q = p;
      q.decomposition = d;
      q.octree_max_points = 16;
      const PointCloud out = roundtrip(same, q);
      REQUIRE(out.size() == 1);
      CHECK(std::abs(out.positions[0].x - 5) < p.cell_size);
    }
  }
  SECTION("collinear points") {
    PointCloud line;
    for (int i = 0; i < 500; ++i) line.positions.push_back({0.01 * i, 0.02 * i, -0.005 * i});
    const PointCloud out = roundtrip(line, p);
    REQUIRE(!out.empty());
    CHECK(measure(line, out).rmse_snn < p.cell_size / 4);
  }
}

TEST_CASE("non-finite input and bad parameters are rejected with a clear error", "[codec]") {
  test::SceneOptions o;
  o.points = 100;
  PointCloud in = test::make_plane(o, {0, 0, 1}, 1.0);
  EncodeParams p = params_with_cell(0.1);
  in.positions[17].y = std::nan("");
  auto r = encode_chunk(in, p);
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().code() == StatusCode::kInvalidArgument);
  CHECK(r.status().message().find("point 17") != std::string::npos);
  CHECK(r.status().message().find("non-finite") != std::string::npos);
  in.positions[17].y = 0;
  in.positions[3].x = INFINITY;
  CHECK_FALSE(encode_chunk(in, p).is_ok());
  in.positions[3].x = 0;

  EncodeParams bad = p;
  bad.map_resolution = 12;
  CHECK(encode_chunk(in, bad).status().code() == StatusCode::kInvalidArgument);
  bad = p;
  bad.height_bits = 16;  // needs JPEG 2000
  CHECK(encode_chunk(in, bad).status().code() == StatusCode::kInvalidArgument);
  bad = p;
  bad.height_quality = 0;
  CHECK(encode_chunk(in, bad).status().code() == StatusCode::kInvalidArgument);
  bad = p;
  bad.cell_size = 1e-12;  // > 2^21 cells per axis
  CHECK(encode_chunk(in, bad).status().code() == StatusCode::kInvalidArgument);
  bad = p;
  bad.grid_origin = Vec3d{10, 10, 10};
  bad.grid_edge = 1;  // points lie outside
  CHECK(encode_chunk(in, bad).status().code() == StatusCode::kInvalidArgument);
  CHECK(decode_chunk(*encode_chunk(in, p), DecodeOptions{0}).status().code() == StatusCode::kInvalidArgument);
}

TEST_CASE("georeferenced coordinates keep millimetres", "[codec]") {
  test::SceneOptions o;
  o.seed = 21;
  o.points = 20000;
  const PointCloud local = test::make_terrain(o, 20.0, 1.0);
  o.offset = {484649.36, 6632629.73, 99.65};
  const PointCloud geo = test::make_terrain(o, 20.0, 1.0);
  const EncodeParams p = params_with_cell(1.0);
  const ErrorMetrics a = measure(local, roundtrip(local, p));
  const ErrorMetrics b = measure(geo, roundtrip(geo, p));
  CHECK(std::abs(a.rmse_snn - b.rmse_snn) < 1e-4);
}

TEST_CASE("level of detail returns a uniform subset of about 1/L of the points", "[codec][lod]") {
  test::SceneOptions o;
  o.seed = 4;
  o.points = 200000;
  o.colors = true;
  const PointCloud in = test::make_terrain(o, 10.0, 0.5);
  const EncodeParams p = params_with_cell(0.25);
  const PointCloud full = roundtrip(in, p, 1);
  std::map<std::tuple<double, double, double>, int> all;
  for (const Vec3d& q : full.positions) all[{q.x, q.y, q.z}]++;
  for (std::uint32_t lod : {2u, 4u, 16u}) {
    const PointCloud sub = roundtrip(in, p, lod);
    INFO("lod " << lod);
    const double expected = static_cast<double>(full.size()) / lod;
    CHECK(std::abs(static_cast<double>(sub.size()) - expected) < 0.02 * expected + 2);
    // A subset of the full decode.
    std::size_t missing = 0;
    for (const Vec3d& q : sub.positions) missing += all.count({q.x, q.y, q.z}) == 0;
    CHECK(missing == 0);
    // Uniform: on a coarse 10x10 histogram every bin holds ~1/lod of its full count.
    int full_bins[10][10] = {}, sub_bins[10][10] = {};
    const auto bin = [](double v) { return std::clamp(static_cast<int>(v), 0, 9); };
    for (const Vec3d& q : full.positions) full_bins[bin(q.x)][bin(q.y)]++;
    for (const Vec3d& q : sub.positions) sub_bins[bin(q.x)][bin(q.y)]++;
    for (int i = 0; i < 10; ++i) {
      for (int j = 0; j < 10; ++j) {
        const double want = static_cast<double>(full_bins[i][j]) / lod;
        CHECK(std::abs(sub_bins[i][j] - want) < 0.15 * want + 3);
      }
    }
  }
}

TEST_CASE("encoding is deterministic and every fill decodes", "[codec]") {
  test::SceneOptions o;
  o.seed = 8;
  o.points = 20000;
  o.colors = true;
  const PointCloud in = test::make_sphere(o, 1.0);
  EncodeParams p = params_with_cell(0.25);
  auto a = encode_chunk(in, p);
  auto b = encode_chunk(in, p);
  REQUIRE(a.is_ok());
  REQUIRE(b.is_ok());
  CHECK(*a == *b);
  for (FillMethod f : {FillMethod::kBoxFilter, FillMethod::kPushPull, FillMethod::kBlockProjection}) {
    p.fill = f;
    const ErrorMetrics m = measure(in, roundtrip(in, p));
    CHECK(m.rmse_snn < 0.6 * pitch(p));
  }
}

TEST_CASE("a given chunk cube aligns the patch grid", "[codec]") {
  test::SceneOptions o;
  o.points = 5000;
  o.offset = {100.5, 200.5, 0.5};
  const PointCloud in = test::make_plane(o, {0, 0, 1}, 0.9);
  EncodeParams p = params_with_cell(0.125);
  p.grid_origin = Vec3d{100, 200, 0};
  p.grid_edge = 1.0;
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  auto info = inspect_chunk(*blob);
  REQUIRE(info.is_ok());
  CHECK(info->grid_origin == Vec3d{100, 200, 0});
  CHECK(info->grid_edge == 1.0);
  CHECK(info->tree_depth == 3);
  CHECK(measure(in, *decode_chunk(*blob)).rmse_snn < 0.6 * pitch(p));
}

TEST_CASE("fills leave occupied pixels alone and make empty 8x8 blocks flat", "[codec][fill]") {
  // Exercised through the public encoder: a plane with a hole decodes the same
  // points whatever the fill, because fills only touch unoccupied pixels.
  test::SceneOptions o;
  o.seed = 12;
  o.points = 30000;
  PointCloud in = test::make_plane(o, {0, 0, 1}, 2.0);
  PointCloud holed;
  for (const Vec3d& q : in.positions) {
    if (std::hypot(q.x - 0.3, q.y + 0.2) > 0.35) holed.positions.push_back(q);
  }
  EncodeParams p = params_with_cell(0.5);
  std::vector<std::size_t> counts;
  for (FillMethod f : {FillMethod::kBoxFilter, FillMethod::kPushPull, FillMethod::kBlockProjection}) {
    p.fill = f;
    counts.push_back(roundtrip(holed, p).size());
  }
  CHECK(counts[0] == counts[1]);
  CHECK(counts[1] == counts[2]);
}

TEST_CASE("encode parameters round-trip through their text form", "[codec]") {
  EncodeParams p;
  p.decomposition = Decomposition::kOctree;
  p.cell_size = 0.1 + 0.2;  // not exactly representable in short decimal
  p.octree_max_points = 333;
  p.normal_cone_degrees = 12.5;
  p.map_resolution = 24;
  p.image_codec = ImageCodec::kJpeg2000;
  p.height_quality = 61;
  p.color_quality = 42;
  p.intensity_quality = 17;
  p.height_bits = 16;
  p.fill = FillMethod::kBoxFilter;
  const std::string text = encode_params_to_string(p);
  auto back = encode_params_from_string(text);
  REQUIRE(back.is_ok());
  CHECK(encode_params_to_string(*back) == text);
  CHECK(back->cell_size == p.cell_size);
  CHECK_FALSE(encode_params_from_string("cell=abc").is_ok());
  CHECK_FALSE(encode_params_from_string("colour=1").is_ok());
  CHECK_FALSE(encode_params_from_string("decomposition=kd").is_ok());
  // The compact form names only what differs from the text defaults, which
  // are frozen (format-spec/archive.md §2.1.1), and reads back the same.
  const std::string compact = encode_params_to_string(p, ParamsText::kCompact);
  CHECK(compact == text);  // every key of p is off its default
  CHECK(full_params_text(compact) == text);
}

TEST_CASE("archives store encode parameters without the keys at their defaults", "[codec]") {
  EncodeParams p;
  p.cell_size = 0.25;
  CHECK(encode_params_to_string(p, ParamsText::kCompact) == "cell=0.25");
  CHECK(encode_params_to_string(p) ==
        "decomposition=voxel;cell=0.25;max_points=1024;cone=0;r=16;image=jpeg;q=75;color_q=70;intensity_q=70;"
        "height_bits=8;fill=project");
  p.bound = ErrorBound{};
  p.bound->step = {0.01, 0.01, 0.02};
  CHECK(encode_params_to_string(p, ParamsText::kCompact) == "cell=0.25;step=0.01,0.01,0.02");
  p.bound->origin = {-0.0, 0, 0.5};
  p.bound->color_tolerance = 3;
  p.map_resolution = 32;
  const std::string compact = encode_params_to_string(p, ParamsText::kCompact);
  CHECK(compact == "cell=0.25;r=32;step=0.01,0.01,0.02;origin=-0,0,0.5;color_tol=3");
  auto back = encode_params_from_string(compact);
  REQUIRE(back.is_ok());
  CHECK(encode_params_to_string(*back) == encode_params_to_string(p));
  CHECK(std::signbit(back->bound->origin.x));
  // The full form ends with every bound key; --fast-geometry appears in the
  // compact form only when set, and reads back.
  CHECK(encode_params_to_string(p).ends_with(";color_tol=3;intensity_tol=0;order=any;geometry=planes"));
  p.bound->fast_geometry = true;
  const std::string fast = encode_params_to_string(p, ParamsText::kCompact);
  CHECK(fast == "cell=0.25;r=32;step=0.01,0.01,0.02;origin=-0,0,0.5;color_tol=3;geometry=fast");
  auto fast_back = encode_params_from_string(fast);
  REQUIRE(fast_back.is_ok());
  CHECK(fast_back->bound->fast_geometry);
  CHECK_FALSE(encode_params_from_string("cell=1;step=1,1,1;geometry=slow").is_ok());
  // The defaults of the text, not EncodeParams' own, fill what is left out.
  auto bare = encode_params_from_string("cell=2");
  REQUIRE(bare.is_ok());
  CHECK(bare->map_resolution == 16);
  CHECK(bare->height_quality == 75);
  CHECK_FALSE(bare->bound.has_value());
  CHECK(full_params_text("not params") == "not params");
}

TEST_CASE("JPEG sections are stored abbreviated at every quality", "[codec][jpeg]") {
  // If the canonical tables ever stopped matching what TurboJPEG writes, the
  // encoder would silently fall back to full streams; this pins that down.
  test::SceneOptions o;
  o.seed = 31;
  o.points = 20000;
  o.colors = true;
  o.intensity = true;
  const PointCloud in = test::make_terrain(o, 6.0, 0.3);
  for (int q : {1, 10, 49, 50, 51, 75, 95, 100}) {
    EncodeParams p = params_with_cell(0.4);
    p.height_quality = p.color_quality = p.intensity_quality = q;
    auto blob = encode_chunk(in, p);
    REQUIRE(blob.is_ok());
    auto info = inspect_chunk(*blob);
    REQUIRE(info.is_ok());
    INFO("quality " << q);
    for (const ChunkSectionInfo& s : info->sections) {
      if (s.id >= 4) CHECK(static_cast<int>(s.codec) == 5);
    }
    CHECK(decode_chunk(*blob).is_ok());
  }
}

TEST_CASE("the encoder's decoded count and bounds equal a real decode exactly", "[codec]") {
  test::SceneOptions o;
  o.seed = 41;
  o.points = 30000;
  o.colors = true;
  o.noise = 0.003;
  const PointCloud in = test::make_room(o, 3.0);
  for (int variant = 0; variant < 4; ++variant) {
    EncodeParams p = params_with_cell(0.2);
    if (variant == 1) p.image_codec = ImageCodec::kJpeg2000;
    if (variant == 2) {
      p.image_codec = ImageCodec::kJpeg2000;
      p.height_bits = 16;
    }
    if (variant == 3) {
      p.decomposition = Decomposition::kOctree;
      p.octree_max_points = 200;
      p.cell_size = 0.05;
    }
    EncodeStats stats;
    auto blob = encode_chunk(in, p, {}, &stats);
    REQUIRE(blob.is_ok());
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    INFO("variant " << variant);
    CHECK(stats.decoded_points == out->size());
    const Box3d b = out->bounds();
    CHECK(stats.decoded_bounds.min == b.min);
    CHECK(stats.decoded_bounds.max == b.max);
  }
}

TEST_CASE("encoding a subset in place equals encoding the gathered points", "[codec]") {
  test::SceneOptions o;
  o.seed = 51;
  o.points = 40000;
  o.colors = true;
  o.intensity = true;
  const PointCloud all = test::make_room(o, 4.0);
  std::vector<std::uint32_t> subset;
  PointCloud gathered;
  for (std::uint32_t i = 0; i < all.size(); i += 3) {
    subset.push_back(i);
    gathered.positions.push_back(all.positions[i]);
    gathered.colors.push_back(all.colors[i]);
    gathered.intensities.push_back(all.intensities[i]);
  }
  const EncodeParams p = params_with_cell(0.25);
  EncodeStats a_stats, b_stats;
  auto a = encode_chunk(gathered, p, {}, &a_stats);
  auto b = encode_chunk_subset(all, subset, p, &b_stats);
  REQUIRE(a.is_ok());
  REQUIRE(b.is_ok());
  CHECK(*a == *b);
  CHECK(a_stats.decoded_points == b_stats.decoded_points);
  // The whole cloud in order is encoded where it lies: encode_chunk's blob.
  std::vector<std::uint32_t> identity(all.size());
  for (std::uint32_t i = 0; i < all.size(); ++i) identity[i] = i;
  auto whole = encode_chunk_subset(all, identity, p);
  auto direct = encode_chunk(all, p);
  REQUIRE(whole.is_ok());
  REQUIRE(direct.is_ok());
  CHECK(*whole == *direct);
  subset.push_back(static_cast<std::uint32_t>(all.size()));  // out of range
  CHECK(encode_chunk_subset(all, subset, p).status().code() == StatusCode::kInvalidArgument);
  EncodeParams automatic;
  CHECK(encode_chunk_subset(all, {subset.data(), 10}, automatic).status().code() == StatusCode::kInvalidArgument);
}
