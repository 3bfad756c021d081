// The error-bounded codec (chunk format 2): every point back, each coordinate
// within the tolerance, attributes exact (or within the colour tolerance),
// bytes that depend only on the multiset of points, and hostile blobs rejected.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <map>
#include <tuple>

#include "codec/chunk_format.h"
#include "core/grid_index.h"
#include "relief/codec.h"
#include "support/synthetic.h"

using namespace relief;

namespace {

struct Rec {
  double x, y, z;
  std::uint8_t r, g, b;
  std::uint32_t ibits;
  auto tie() const { return std::tie(x, y, z, r, g, b, ibits); }
  bool operator<(const Rec& o) const { return tie() < o.tie(); }
  bool operator==(const Rec& o) const { return tie() == o.tie(); }
};

std::uint32_t bits_of(float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

// Where the encoder puts v: the nearest grid index, or its neighbour where
// the nearest decodes beyond half a step (core/grid_index.h).
double snap(double v, double origin, double step) {
  return core::grid_value(origin, core::grid_index_within(v, origin, step).value(), step);
}

// The multiset the decoder must return: every input point snapped to the grid.
std::vector<Rec> snapped(const PointCloud& c, const ErrorBound& b) {
  std::vector<Rec> out;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Vec3d& p = c.positions[i];
    Rec r{snap(p.x, b.origin.x, b.step.x), snap(p.y, b.origin.y, b.step.y), snap(p.z, b.origin.z, b.step.z), 0, 0, 0, 0};
    if (c.has_colors()) r.r = c.colors[i].r, r.g = c.colors[i].g, r.b = c.colors[i].b;
    if (c.has_intensity()) r.ibits = bits_of(c.intensities[i]);
    out.push_back(r);
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<Rec> records(const PointCloud& c) {
  std::vector<Rec> out;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const Vec3d& p = c.positions[i];
    Rec r{p.x, p.y, p.z, 0, 0, 0, 0};
    if (c.has_colors()) r.r = c.colors[i].r, r.g = c.colors[i].g, r.b = c.colors[i].b;
    if (c.has_intensity()) r.ibits = bits_of(c.intensities[i]);
    out.push_back(r);
  }
  std::sort(out.begin(), out.end());
  return out;
}

EncodeParams bounded_params(double tolerance, double cell) {
  EncodeParams p;
  p.cell_size = cell;
  p.bound = ErrorBound{};
  p.bound->step = {2 * tolerance, 2 * tolerance, 2 * tolerance};
  return p;
}

}  // namespace

TEST_CASE("bounded: every point comes back within the tolerance, attributes exact", "[codec][bounded]") {
  for (double tol : {0.0005, 0.004, 0.05}) {
    test::SceneOptions o;
    o.seed = 7;
    o.points = 20000;
    o.colors = true;
    o.intensity = true;
    o.noise = 0.002;
    const PointCloud in = test::make_room(o, 4.0);
    const EncodeParams p = bounded_params(tol, 0.5);
    auto blob = encode_chunk(in, p);
    REQUIRE(blob.is_ok());
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    REQUIRE(out->size() == in.size());
    CHECK(records(*out) == snapped(in, *p.bound));
    // Each snapped coordinate is within the tolerance of its input.
    for (const Vec3d& q : in.positions) {
      CHECK(std::fabs(snap(q.x, 0, 2 * tol) - q.x) <= tol * (1 + 1e-9));
      CHECK(std::fabs(snap(q.z, 0, 2 * tol) - q.z) <= tol * (1 + 1e-9));
    }
    auto info = inspect_chunk(*blob);
    REQUIRE(info.is_ok());
    CHECK(info->format_version == kOctreeNearestFormatVersion);  // octree geometry: format 17
    CHECK(info->error_bounded);
    CHECK(info->decoded_points == in.size());
  }
}

TEST_CASE("bounded: every coordinate within the tolerance exactly, ties and large magnitudes included",
          "[codec][bounded]") {
  // 1.2345 on a 0.001 step is a tie: the nearest index by rounding, 1235,
  // decodes to 1.2350000000000001, 1.7e-16 beyond the tolerance; its
  // neighbour 1234 is within. A tolerance doubles do not resolve at the
  // coordinates (below 32 times their spacing) is refused where no index
  // decodes within it (1e-5 near 1e12 gave 1.2e-4; 1e-6 near 1e9, 1.07
  // times it).
  for (const double base : {0.0, 1.0, 6.4e6, 1.0e9}) {
    for (const double tol : {0.0005, 2e-6}) {
      // Near 1e9 doubles are 1.2e-7 apart: a tie on a 4e-6 step may decode
      // beyond 2e-6 on both sides (checked below).
      if (base == 1.0e9 && tol < 1e-5) continue;
      PointCloud in;
      std::uint64_t state = 3;
      for (int i = 0; i < 4000; ++i) {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        const double unit = static_cast<double>(state >> 11) / 9007199254740992.0;
        // Every other point a tie (an odd multiple of the tolerance), the rest anywhere.
        const double x =
            i % 2 == 0 ? base + (2 * static_cast<double>(i % 997) + 1) * tol : base + unit * 2000 * tol;
        in.positions.push_back({x, base - x * 0.5, static_cast<double>(i % 7) * tol});
      }
      const EncodeParams p = bounded_params(tol, 0.5);
      auto blob = encode_chunk(in, p);
      INFO("base " << base << ", tolerance " << tol << ": " << blob.status().to_string());
      REQUIRE(blob.is_ok());
      auto out = decode_chunk(*blob);
      REQUIRE(out.is_ok());
      REQUIRE(out->size() == in.size());
      // Snapping is monotone on each axis, so sorted inputs meet sorted outputs.
      for (int a = 0; a < 3; ++a) {
        std::vector<double> want, got;
        for (const Vec3d& q : in.positions) want.push_back(a == 0 ? q.x : a == 1 ? q.y : q.z);
        for (const Vec3d& q : out->positions) got.push_back(a == 0 ? q.x : a == 1 ? q.y : q.z);
        std::sort(want.begin(), want.end());
        std::sort(got.begin(), got.end());
        double worst = 0;
        for (std::size_t i = 0; i < want.size(); ++i) worst = std::max(worst, std::fabs(got[i] - want[i]));
        INFO("axis " << a);
        // Within the tolerance, plus at a tie the rounding of the decoded double.
        CHECK(worst <= tol + 4 * (std::nextafter(base + 1, 1e300) - (base + 1)));
      }
    }
  }
  // A tolerance finer than doubles resolve at the coordinates: refused, naming the point.
  PointCloud far;
  far.positions = {{1e12 + 0.123456, -1e12 - 0.5, 3.3}};
  const auto refused = encode_chunk(far, bounded_params(1e-5, 0.5));
  REQUIRE_FALSE(refused.is_ok());
  CHECK(refused.status().code() == StatusCode::kInvalidArgument);
  CHECK_THAT(refused.status().message(), Catch::Contains("cannot come back within the tolerance 1e-05"));
  CHECK_THAT(refused.status().message(), Catch::Contains("a tolerance of 32 times that (0.00390625) or more is always kept there"));
  PointCloud tie;
  tie.positions = {{1.0e9 + 13 * 2e-6, 0, 0}};  // 1000000000.000026, as above
  CHECK(encode_chunk(tie, bounded_params(2e-6, 0.5)).status().code() == StatusCode::kInvalidArgument);
  CHECK(encode_chunk(tie, bounded_params(4e-6, 0.5)).is_ok());
}

TEST_CASE("bounded: LAS integers come back exactly", "[codec][bounded]") {
  test::Rng rng(11);
  PointCloud in;
  const Vec3d offset{512000.0, 5400000.0, 0.0};
  const double scale = 0.01;
  std::vector<std::array<std::int64_t, 3>> ints;
  for (int i = 0; i < 5000; ++i) {
    const std::int64_t X = static_cast<std::int64_t>(rng.uniform(0, 20000));
    const std::int64_t Y = static_cast<std::int64_t>(rng.uniform(0, 20000));
    const std::int64_t Z = static_cast<std::int64_t>(rng.uniform(0, 3000));
    ints.push_back({X, Y, Z});
    in.positions.push_back({offset.x + static_cast<double>(X) * scale, offset.y + static_cast<double>(Y) * scale,
                            offset.z + static_cast<double>(Z) * scale});
    in.intensities.push_back(static_cast<float>(rng.next() % 65536));
  }
  EncodeParams p = bounded_params(scale / 2, 20.0);
  p.bound->origin = offset;
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  auto out = decode_chunk(*blob);
  REQUIRE(out.is_ok());
  REQUIRE(out->size() == in.size());
  std::vector<std::array<std::int64_t, 3>> back;
  for (const Vec3d& q : out->positions) {
    back.push_back({std::llround((q.x - offset.x) / scale), std::llround((q.y - offset.y) / scale),
                    std::llround((q.z - offset.z) / scale)});
  }
  std::sort(ints.begin(), ints.end());
  std::sort(back.begin(), back.end());
  CHECK(ints == back);
  CHECK(records(*out) == records(in));  // the LAS reader's doubles, bit for bit
}

TEST_CASE("bounded: duplicates, float intensities and degenerate clouds", "[codec][bounded]") {
  PointCloud in;
  for (int i = 0; i < 3000; ++i) {
    in.positions.push_back({1.0, 2.0, 3.0});  // one cell, many points
    in.intensities.push_back(0.001f * static_cast<float>(i % 7));
  }
  in.positions.push_back({1.5, 2.0, 3.0});
  in.intensities.push_back(-0.0f);
  auto blob = encode_chunk(in, bounded_params(0.001, 0.5));
  REQUIRE(blob.is_ok());
  auto out = decode_chunk(*blob);
  REQUIRE(out.is_ok());
  CHECK(records(*out) == snapped(in, *bounded_params(0.001, 0.5).bound));

  PointCloud one;
  one.positions.push_back({-7.25, 1e6, 0.5});
  auto b1 = encode_chunk(one, bounded_params(0.01, 1));
  REQUIRE(b1.is_ok());
  auto o1 = decode_chunk(*b1);
  REQUIRE(o1.is_ok());
  CHECK(o1->size() == 1);

  auto b0 = encode_chunk(PointCloud(), bounded_params(0.01, 1));
  REQUIRE(b0.is_ok());
  auto o0 = decode_chunk(*b0);
  REQUIRE(o0.is_ok());
  CHECK(o0->empty());
}

TEST_CASE("bounded: colour tolerance bounds every channel", "[codec][bounded]") {
  test::SceneOptions o;
  o.seed = 3;
  o.points = 15000;
  o.colors = true;
  const PointCloud in = test::make_terrain(o, 10.0, 1.0);
  std::size_t exact_bytes = 0;
  for (int c : {0, 2, 8, 30}) {
    EncodeParams p = bounded_params(0.005, 1.0);
    p.bound->color_tolerance = c;
    auto blob = encode_chunk(in, p);
    REQUIRE(blob.is_ok());
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    REQUIRE(out->size() == in.size());
    // Pair points: input sorted by (snapped position, colour); output sorted
    // stably by position keeps the encoder's within-cell order (by colour).
    std::vector<std::size_t> ia(in.size()), ib(in.size());
    for (std::size_t i = 0; i < ia.size(); ++i) ia[i] = ib[i] = i;
    const auto snapped_pos = [&](std::size_t i) {
      const Vec3d& q = in.positions[i];
      return std::make_tuple(snap(q.x, 0, 0.01), snap(q.y, 0, 0.01), snap(q.z, 0, 0.01));
    };
    std::sort(ia.begin(), ia.end(), [&](std::size_t a, std::size_t b) {
      const Rgb8 ca = in.colors[a], cb = in.colors[b];
      return std::tuple_cat(snapped_pos(a), std::make_tuple(ca.r, ca.g, ca.b)) <
             std::tuple_cat(snapped_pos(b), std::make_tuple(cb.r, cb.g, cb.b));
    });
    std::stable_sort(ib.begin(), ib.end(), [&](std::size_t a, std::size_t b) {
      const Vec3d &p = out->positions[a], &q = out->positions[b];
      return std::tie(p.x, p.y, p.z) < std::tie(q.x, q.y, q.z);
    });
    int worst = 0;
    for (std::size_t k = 0; k < ia.size(); ++k) {
      const Rgb8 a = in.colors[ia[k]], b = out->colors[ib[k]];
      worst = std::max({worst, std::abs(a.r - b.r), std::abs(a.g - b.g), std::abs(a.b - b.b)});
    }
    CHECK(worst <= c);
    if (c == 0) exact_bytes = blob->size();
    if (c == 30) CHECK(blob->size() < exact_bytes);
  }
}

TEST_CASE("bounded: an intensity tolerance bounds every 16-bit intensity, float ones stay exact",
          "[codec][bounded]") {
  // Points a cell apart (each alone in its cell, so input and output pair
  // by position), intensities a noisy field with runs at 0 and 65535.
  PointCloud in;
  std::uint64_t state = 7;
  const auto noise = [&state] {
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<int>((state >> 33) % 401) - 200;
  };
  for (int i = 0; i < 160; ++i) {
    for (int j = 0; j < 120; ++j) {
      in.positions.push_back({i * 0.05, j * 0.05, 0.3 * std::sin(i * 0.1) + 0.01 * (j % 7)});
      const int field = 30000 + static_cast<int>(30000 * std::sin(i * 0.05) * std::cos(j * 0.07)) + noise();
      const int v = i < 10 ? 0 : i > 150 ? 65535 : std::clamp(field, 0, 65535);
      in.intensities.push_back(static_cast<float>(v));
    }
  }
  const auto key = [](const Vec3d& p) {
    return std::make_tuple(std::llround(p.x / 0.01), std::llround(p.y / 0.01), std::llround(p.z / 0.01));
  };
  std::map<std::tuple<long long, long long, long long>, float> given;
  for (std::size_t k = 0; k < in.size(); ++k) given[key(in.positions[k])] = in.intensities[k];
  REQUIRE(given.size() == in.size());
  std::size_t previous = 0;
  for (const int t : {0, 1, 7, 300, kMaxIntensityTolerance}) {
    INFO("tolerance " << t);
    EncodeParams p = bounded_params(0.005, 1.0);
    p.bound->intensity_tolerance = t;
    auto blob = encode_chunk(in, p);
    REQUIRE(blob.is_ok());
    auto info = inspect_chunk(*blob);
    REQUIRE(info.is_ok());
    CHECK(info->format_version == kOctreeNearestFormatVersion);
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    REQUIRE(out->size() == in.size());
    float worst = 0;
    for (std::size_t k = 0; k < out->size(); ++k) {
      const float v = out->intensities[k];
      CHECK(v == std::floor(v));
      CHECK((v >= 0 && v <= 65535));
      worst = std::max(worst, std::abs(v - given.at(key(out->positions[k]))));
    }
    CHECK(worst <= static_cast<float>(t));
    if (t == 0) CHECK(worst == 0);
    if (t == 300) CHECK(worst > 0);  // the bound is used, not just kept
    if (t > 0) CHECK(blob->size() < previous);  // each tolerance cheaper than the one before
    previous = blob->size();
  }
  // Intensities that are not whole numbers keep their exact float values and
  // the header says tolerance 0.
  PointCloud floats = in;
  for (float& v : floats.intensities) v += 0.25f;
  EncodeParams p = bounded_params(0.005, 1.0);
  p.bound->intensity_tolerance = 50;
  auto blob = encode_chunk(floats, p);
  REQUIRE(blob.is_ok());
  auto parsed = codec::parse_blob(*blob, true);
  REQUIRE(parsed.is_ok());
  CHECK(parsed->header.intensity_tolerance == 0);
  auto out = decode_chunk(*blob);
  REQUIRE(out.is_ok());
  for (std::size_t k = 0; k < out->size(); ++k) CHECK(out->intensities[k] == given.at(key(out->positions[k])) + 0.25f);
  // Headers that claim a tolerance where none can be are corrupt: before
  // version 12, on float intensities, above 32767.
  p.bound->intensity_tolerance = 9;
  blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  parsed = codec::parse_blob(*blob, true);
  REQUIRE(parsed.is_ok());
  REQUIRE(parsed->header.intensity_tolerance == 9);
  const auto refused = [](const codec::ChunkHeader& h, const std::vector<codec::SectionEntry>& sections) {
    auto r = decode_chunk(codec::write_blob(h, sections));
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kCorruptData);
  };
  codec::ChunkHeader h = parsed->header;
  h.version = 11;
  refused(h, parsed->sections);
  h = parsed->header;
  h.intensity_coding = codec::IntensityCoding::kFloatBits;
  refused(h, parsed->sections);
  h = parsed->header;
  h.intensity_tolerance = 40000;
  refused(h, parsed->sections);
  p.bound->intensity_tolerance = kMaxIntensityTolerance + 1;
  CHECK(encode_chunk(in, p).status().code() == StatusCode::kInvalidArgument);
}

TEST_CASE("bounded: the blob depends only on the multiset of points", "[codec][bounded]") {
  test::SceneOptions o;
  o.seed = 5;
  o.points = 8000;
  o.colors = true;
  o.intensity = true;
  PointCloud in = test::make_sphere(o, 2.0);
  // Duplicates with different attributes, so their order matters.
  for (int i = 0; i < 200; ++i) {
    in.positions.push_back(in.positions[static_cast<std::size_t>(i)]);
    in.colors.push_back({static_cast<std::uint8_t>(i), 1, 2});
    in.intensities.push_back(static_cast<float>(i));
  }
  EncodeParams p = bounded_params(0.003, 0.5);
  p.grid_origin = Vec3d{-2.5, -2.5, -2.5};
  p.grid_edge = 5.0;
  auto a = encode_chunk(in, p);
  REQUIRE(a.is_ok());
  PointCloud shuffled;
  test::Rng rng(9);
  std::vector<std::size_t> perm(in.size());
  for (std::size_t i = 0; i < perm.size(); ++i) perm[i] = i;
  for (std::size_t i = perm.size() - 1; i > 0; --i) std::swap(perm[i], perm[rng.next() % (i + 1)]);
  for (std::size_t i : perm) {
    shuffled.positions.push_back(in.positions[i]);
    shuffled.colors.push_back(in.colors[i]);
    shuffled.intensities.push_back(in.intensities[i]);
  }
  auto b = encode_chunk(shuffled, p);
  REQUIRE(b.is_ok());
  CHECK(*a == *b);
}

TEST_CASE("bounded: coarse levels of detail come from the base layer", "[codec][bounded]") {
  test::SceneOptions o;
  o.seed = 21;
  o.points = 40000;
  o.colors = true;
  const PointCloud in = test::make_terrain(o, 20.0, 1.0);
  EncodeParams p = bounded_params(0.002, 4.0);  // 4 m cells: ~1 base pixel per ~10 points
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  auto info = inspect_chunk(*blob);
  REQUIRE(info.is_ok());
  REQUIRE(info->base_points > 0);
  REQUIRE(info->base_points < in.size());
  for (std::uint32_t lod : {2u, 16u, 64u}) {
    DecodeOptions d;
    d.lod = lod;
    auto out = decode_chunk(*blob, d);
    REQUIRE(out.is_ok());
    const double want = static_cast<double>(in.size()) / lod;
    if (info->base_points >= static_cast<std::uint64_t>(std::ceil(want))) {
      CHECK(std::fabs(static_cast<double>(out->size()) - want) <= want * 0.02 + 2);
    } else if (2.0 * info->base_points >= std::ceil(want)) {
      CHECK(out->size() == info->base_points);  // the whole base layer
    } else {
      CHECK(out->size() == (in.size() + lod - 1) / lod);
    }
    CHECK(out->has_colors());
  }
}

TEST_CASE("bounded: the base layer serves kBaseLayerLod even when the cell is too coarse for it", "[codec][bounded]") {
  test::SceneOptions o;
  o.seed = 23;
  o.points = 60000;
  const PointCloud in = test::make_terrain(o, 20.0, 1.0);
  // Cells as wide as the terrain: one patch, one r x r map (256 pixels), far
  // fewer than n / 32; the encoder halves the cell until the maps hold enough.
  for (const double cell : {20.0, 40.0, 5.0}) {
    INFO("cell " << cell);
    auto blob = encode_chunk(in, bounded_params(0.002, cell));
    REQUIRE(blob.is_ok());
    auto info = inspect_chunk(*blob);
    REQUIRE(info.is_ok());
    const std::uint64_t wanted = (in.size() + kBaseLayerLod - 1) / kBaseLayerLod;
    CHECK(2 * info->base_points >= wanted);
    DecodeOptions d;
    d.lod = kBaseLayerLod;
    auto out = decode_chunk(*blob, d);
    REQUIRE(out.is_ok());
    // From the maps alone: about min(wanted, base points), not every 16th point.
    const auto w = static_cast<double>(std::min<std::uint64_t>(wanted, info->base_points));
    CHECK(std::fabs(static_cast<double>(out->size()) - w) <= w * 0.02 + 2);
    auto all = decode_chunk(*blob);
    REQUIRE(all.is_ok());
    CHECK(all->size() == in.size());
  }
  // A cell already fine enough is kept: the maps hold more than n / 16 / 2.
  auto fine = encode_chunk(in, bounded_params(0.002, 2.0));
  REQUIRE(fine.is_ok());
  auto fine_info = inspect_chunk(*fine);
  REQUIRE(fine_info.is_ok());
  auto coarse = encode_chunk(in, bounded_params(0.002, 20.0));
  REQUIRE(coarse.is_ok());
  CHECK(inspect_chunk(*coarse)->base_points <= fine_info->base_points);
}

TEST_CASE("bounded: truncated and corrupted blobs are rejected without crashing", "[codec][bounded][reject]") {
  test::SceneOptions o;
  o.seed = 4;
  o.points = 2000;
  o.colors = true;
  o.intensity = true;
  const PointCloud in = test::make_sphere(o, 1.0);
  auto blob = encode_chunk(in, bounded_params(0.001, 0.5));
  REQUIRE(blob.is_ok());
  for (std::size_t len = 0; len < blob->size(); len += 7) {
    std::vector<std::uint8_t> cut(blob->begin(), blob->begin() + static_cast<std::ptrdiff_t>(len));
    CHECK_FALSE(decode_chunk(cut).is_ok());
  }
  DecodeOptions nocrc;
  nocrc.verify_checksum = false;
  test::Rng rng(17);
  int rejected = 0;
  for (int t = 0; t < 400; ++t) {
    std::vector<std::uint8_t> bad = *blob;
    // Flip bytes in the error-bounded layer and its header fields.
    const std::size_t at = 88 + rng.next() % (bad.size() - 92);
    bad[at] = static_cast<std::uint8_t>(bad[at] ^ (1u + rng.next() % 255));
    auto r = decode_chunk(bad, nocrc);
    if (!r.is_ok()) {
      ++rejected;
    } else {
      CHECK(r->size() <= in.size());
    }
    CHECK_FALSE(decode_chunk(bad).is_ok());  // the checksum catches every flip
  }
  CHECK(rejected > 0);
}

TEST_CASE(
    "bounded: colour codec 10 only for point colours from version 9, octree codec 12 only in 13-15, 13 in "
    "16, "
    "14 from 17",
    "[codec][bounded][reject]") {
  test::SceneOptions o;
  o.seed = 5;
  o.points = 3000;
  o.colors = true;
  o.intensity = true;
  const PointCloud in = test::make_terrain(o, 10.0, 1.0);
  auto blob = encode_chunk(in, bounded_params(0.005, 1.0));
  REQUIRE(blob.is_ok());
  auto parsed = codec::parse_blob(*blob, true);
  REQUIRE(parsed.is_ok());
  REQUIRE(parsed->header.version == kOctreeNearestFormatVersion);
  bool found = false;
  bool chains = false;
  for (const codec::SectionEntry& s : parsed->sections) {
    if (s.id == codec::SectionId::kPointColor) found = s.codec == codec::SectionCodec::kNeighbourColor;
    if (s.id == codec::SectionId::kGeometry) chains = s.codec == codec::SectionCodec::kOctreeNearest;
  }
  REQUIRE(found);  // octree layers code their colours in cell order, with codec 10
  REQUIRE(chains);  // and their octree with codec 14
  const auto refused = [](const std::vector<std::uint8_t>& b) {
    auto r = decode_chunk(b);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kCorruptData);
  };
  // The same sections in a version-16, 15, 12 or 9 header (valid checksum):
  // refused, for codec 14; the octree said to be codec 13, 12 or 11 in a
  // version-17 header: refused; with the octree said to be codec 8, in a
  // version-8 header: refused, for codec 10.
  codec::ChunkHeader older = parsed->header;
  older.version = 16;
  refused(codec::write_blob(older, parsed->sections));
  older.version = 15;
  refused(codec::write_blob(older, parsed->sections));
  older.version = 12;
  refused(codec::write_blob(older, parsed->sections));
  older.version = 9;
  refused(codec::write_blob(older, parsed->sections));
  std::vector<codec::SectionEntry> as_codec13 = parsed->sections;
  for (codec::SectionEntry& s : as_codec13) {
    if (s.id == codec::SectionId::kGeometry) s.codec = codec::SectionCodec::kOctreePlanes;
  }
  refused(codec::write_blob(parsed->header, as_codec13));
  std::vector<codec::SectionEntry> as_codec12 = parsed->sections;
  for (codec::SectionEntry& s : as_codec12) {
    if (s.id == codec::SectionId::kGeometry) s.codec = codec::SectionCodec::kOctreeFaces;
  }
  refused(codec::write_blob(parsed->header, as_codec12));
  std::vector<codec::SectionEntry> as_codec11 = parsed->sections;
  for (codec::SectionEntry& s : as_codec11) {
    if (s.id == codec::SectionId::kGeometry) s.codec = codec::SectionCodec::kOctreeChains;
  }
  refused(codec::write_blob(parsed->header, as_codec11));
  std::vector<codec::SectionEntry> as_codec8 = parsed->sections;
  for (codec::SectionEntry& s : as_codec8) {
    if (s.id == codec::SectionId::kGeometry) s.codec = codec::SectionCodec::kOctreeMixed;
  }
  older.version = 8;
  refused(codec::write_blob(older, as_codec8));
  // Codec 11 on a version-11 colour section: refused.
  std::vector<codec::SectionEntry> misplaced = parsed->sections;
  for (codec::SectionEntry& s : misplaced) {
    if (s.id == codec::SectionId::kPointColor) s.codec = codec::SectionCodec::kOctreeChains;
  }
  refused(codec::write_blob(parsed->header, misplaced));
  // Codec 10 on the intensity section: refused.
  std::vector<codec::SectionEntry> sections = parsed->sections;
  for (codec::SectionEntry& s : sections) {
    if (s.id == codec::SectionId::kPointIntensity) s.codec = codec::SectionCodec::kNeighbourColor;
  }
  refused(codec::write_blob(parsed->header, sections));
  // Codec 6 in place of 10 decodes (both are valid from version 9), to other
  // colours or to an error, never past the stream's end.
  sections = parsed->sections;
  for (codec::SectionEntry& s : sections) {
    if (s.id == codec::SectionId::kPointColor) s.codec = codec::SectionCodec::kArithmetic;
  }
  auto other = decode_chunk(codec::write_blob(parsed->header, sections));
  if (other.is_ok()) CHECK(other->size() == in.size());
}
