// The error-bounded layer in time order (chunk format 8, geometry codec 9,
// format-spec/chunk.md §11.3.3): the coder alone (every cell back, hostile
// streams refused in bounded work) and through blobs (the encoder picks it
// for scans, every point and attribute comes back, the blob depends only on
// the multiset of points, older blobs still decode).
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "codec/chunk_format.h"
#include "codec/las_attribute_coder.h"
#include "codec/scan_geometry_coder.h"
#include "relief/codec.h"
#include "support/las_attributes.h"
#include "support/synthetic.h"

using namespace relief;
using codec::CellXyz;
using codec::ScanContext;

namespace {

// Cells of a zigzag scan with some jumps, and per-point contexts.
struct ScanCells {
  std::vector<CellXyz> cells;
  std::vector<std::uint8_t> kind, mult, rn, nr;
};

ScanCells scan_cells(std::uint64_t seed, std::size_t n, int depth) {
  test::Rng rng(seed);
  ScanCells s;
  const std::uint32_t top = (1u << depth) - 1;
  std::int64_t x = 0, y = 0, z = top / 2;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint64_t r = rng.next();
    if (r % 97 == 0) {  // a jump anywhere
      x = static_cast<std::int64_t>(rng.next() % (top + 1u));
      y = static_cast<std::int64_t>(rng.next() % (top + 1u));
    } else {
      x += 25 + static_cast<std::int64_t>(r % 5) - 2;
      y += static_cast<std::int64_t>((r >> 8) % 3) - 1;
    }
    z += static_cast<std::int64_t>((r >> 16) % 9) - 4;
    const auto clampv = [&](std::int64_t v) { return static_cast<std::uint32_t>(std::clamp<std::int64_t>(v, 0, top)); };
    s.cells.push_back({clampv(x), clampv(y), clampv(z)});
    x = s.cells.back()[0];
    y = s.cells.back()[1];
    z = s.cells.back()[2];
    s.kind.push_back(static_cast<std::uint8_t>((r >> 24) % 3));
    s.mult.push_back(static_cast<std::uint8_t>((r >> 32) % 8 == 0 ? (r >> 40) % 70 : 1));  // 0 and > 64 too
    s.rn.push_back(static_cast<std::uint8_t>(1 + (r >> 28) % 3));
    s.nr.push_back(static_cast<std::uint8_t>(3));
  }
  return s;
}

EncodeParams las_scale(double scale, double cell) {
  EncodeParams p;
  p.cell_size = cell;
  p.bound = ErrorBound{};
  p.bound->step = {scale, scale, scale};
  return p;
}

int geometry_codec(const std::vector<std::uint8_t>& blob) {
  auto info = inspect_chunk(blob);
  REQUIRE(info.is_ok());
  for (const ChunkSectionInfo& s : info->sections) {
    if (s.id == 7) return s.codec;
  }
  return -1;
}

std::vector<std::string> snapped_records(PointCloud c, double step) {
  for (Vec3d& p : c.positions) {
    p = {std::llround(p.x / step) * step, std::llround(p.y / step) * step, std::llround(p.z / step) * step};
  }
  return test::sorted_records(c);
}

std::vector<std::string> records(const PointCloud& c) { return test::sorted_records(c); }

PointCloud scan_scene(std::uint64_t seed, std::size_t points, std::uint32_t bits) {
  test::SceneOptions o;
  o.seed = seed;
  o.points = points;
  o.colors = true;
  o.intensity = true;
  return test::make_scan_with_las(o, 60.0, bits, 2);
}

// The points of `in` with their GPS times shuffled among them (times that no
// longer follow the geometry) code as an octree, and every point comes back.
void check_octree_with_shuffled_times(const PointCloud& in, const EncodeParams& p, std::uint64_t seed) {
  PointCloud shuffled = in;
  test::Rng rng(seed);
  for (std::size_t i = shuffled.size() - 1; i > 0; --i) {
    std::swap(shuffled.las.gps_time[i], shuffled.las.gps_time[rng.next() % (i + 1)]);
  }
  auto octree = encode_chunk(shuffled, p);
  REQUIRE(octree.is_ok());
  CHECK(geometry_codec(*octree) == 14);  // the octree (codec 14 from format 17)
  auto back = decode_chunk(*octree);
  REQUIRE(back.is_ok());
  CHECK(records(*back) == snapped_records(shuffled, 0.01));
}

}  // namespace

TEST_CASE("scan-order geometry: every cell comes back, with and without contexts", "[codec][scan]") {
  for (const int depth : {0, 1, 12, 21}) {
    const ScanCells s = scan_cells(static_cast<std::uint64_t>(depth) + 3, 3000, depth);
    for (int with_returns = 0; with_returns < 2; ++with_returns) {
      INFO("depth " << depth << ", returns " << with_returns);
      const ScanContext ctx{s.kind, s.mult, with_returns ? std::span<const std::uint8_t>(s.rn) : std::span<const std::uint8_t>(),
                            with_returns ? std::span<const std::uint8_t>(s.nr) : std::span<const std::uint8_t>()};
      const auto stream = codec::encode_scan_geometry(s.cells, depth, ctx);
      auto back = codec::decode_scan_geometry(stream, depth, s.cells.size(), ctx);
      REQUIRE(back.is_ok());
      CHECK(*back == s.cells);
    }
  }
  // One point, and none.
  const std::vector<CellXyz> one{{5, 6, 7}};
  auto back = codec::decode_scan_geometry(codec::encode_scan_geometry(one, 3, {}), 3, 1, {});
  REQUIRE(back.is_ok());
  CHECK(*back == one);
  auto none = codec::decode_scan_geometry(codec::encode_scan_geometry({}, 3, {}), 3, 0, {});
  REQUIRE(none.is_ok());
  CHECK(none->empty());
}

TEST_CASE("scan-order geometry: pulse multiples count the spacings a time step spans", "[codec][scan]") {
  const double t0 = 3.0e5, s = 1.0e-5;
  const std::vector<double> times{t0, t0 + s, t0 + 2 * s, t0 + 2 * s, t0 + 5 * s, t0 + 6 * s, t0 + 6.4 * s,
                                  t0 + 7.6 * s, t0 + 300 * s};
  const std::vector<std::uint8_t> u = codec::scan_pulse_multiples(times);
  // 1 first; 1, 1 steps of one spacing; 1 for a shared time; 3 spacings; 1;
  // 0.4 of a spacing rounds to 1; 1.2 / 0.4 = 3 spacings of the last step; a
  // jump of > 64 spacings is a new line, not missed pulses.
  CHECK(u == std::vector<std::uint8_t>{1, 1, 1, 1, 3, 1, 1, 3, 1});
  CHECK(codec::scan_pulse_multiples({}).empty());
}

TEST_CASE("scan-order geometry: a scan costs far fewer bits than random cells", "[codec][scan]") {
  const ScanCells s = scan_cells(9, 20000, 16);
  const auto stream = codec::encode_scan_geometry(s.cells, 16, ScanContext{s.kind, s.mult, s.rn, s.nr});
  test::Rng rng(10);
  std::vector<CellXyz> noise(s.cells.size());
  for (CellXyz& c : noise) c = {static_cast<std::uint32_t>(rng.next() % 65536), static_cast<std::uint32_t>(rng.next() % 65536),
                                static_cast<std::uint32_t>(rng.next() % 65536)};
  const auto random = codec::encode_scan_geometry(noise, 16, ScanContext{s.kind, s.mult, s.rn, s.nr});
  const double scan_bpp = 8.0 * static_cast<double>(stream.size()) / static_cast<double>(s.cells.size());
  const double random_bpp = 8.0 * static_cast<double>(random.size()) / static_cast<double>(noise.size());
  INFO(scan_bpp << " vs " << random_bpp << " bits a point");
  CHECK(scan_bpp < 14.0);     // steps of ±2 in x, ±1 in y, ±4 in z, a jump in 97
  CHECK(random_bpp > 46.0);   // 48 random bits, little to gain
}

TEST_CASE("scan-order geometry: hostile streams are refused in bounded work", "[codec][scan][reject]") {
  const ScanCells s = scan_cells(4, 2000, 14);
  const ScanContext ctx{s.kind, s.mult, s.rn, s.nr};
  const auto stream = codec::encode_scan_geometry(s.cells, 14, ctx);
  // Truncated anywhere: refused, never a crash.
  for (std::size_t cut = 0; cut + 1 < stream.size(); cut += std::max<std::size_t>(1, stream.size() / 97)) {
    auto r = codec::decode_scan_geometry(std::span(stream).first(cut), 14, s.cells.size(), ctx);
    CHECK(r.status().code() == StatusCode::kCorruptData);
  }
  // A count the bytes cannot hold is refused before anything is allocated.
  auto huge = codec::decode_scan_geometry(stream, 14, std::size_t{1} << 40, {});
  CHECK(huge.status().code() == StatusCode::kCorruptData);
  // Coordinates above the grid the header names are refused.
  auto small = codec::decode_scan_geometry(stream, 6, s.cells.size(), ctx);
  CHECK(small.status().code() == StatusCode::kCorruptData);
  auto deep = codec::decode_scan_geometry(stream, 22, s.cells.size(), ctx);
  CHECK(deep.status().code() == StatusCode::kCorruptData);
  // Contexts that do not cover the points.
  const ScanContext short_ctx{std::span(s.kind).first(10), {}, {}, {}};
  CHECK(codec::decode_scan_geometry(stream, 14, s.cells.size(), short_ctx).status().code() == StatusCode::kCorruptData);
  // Random bytes: refused or decoded within the grid.
  test::Rng rng(5);
  for (int t = 0; t < 200; ++t) {
    std::vector<std::uint8_t> junk(1 + rng.next() % 300);
    for (auto& b : junk) b = static_cast<std::uint8_t>(rng.next());
    auto r = codec::decode_scan_geometry(junk, 10, 50, {});
    if (r.is_ok()) {
      for (const CellXyz& c : *r) CHECK(std::max({c[0], c[1], c[2]}) < 1024u);
    }
  }
}

TEST_CASE("format 8: a scan with GPS times codes its geometry in time order, every point and attribute exact",
          "[codec][scan][las]") {
  for (const std::uint32_t bits : {0xFFFu, static_cast<std::uint32_t>(kLasGpsTime),
                                   static_cast<std::uint32_t>(kLasGpsTime | kLasReturnNumber),
                                   static_cast<std::uint32_t>(kLasGpsTime | kLasNumberOfReturns | kLasClassification)}) {
    INFO("attributes " << bits);
    const PointCloud in = scan_scene(21, 6000, bits);
    const EncodeParams p = las_scale(0.01, 4.0);
    auto blob = encode_chunk(in, p);
    REQUIRE(blob.is_ok());
    CHECK(inspect_chunk(*blob)->format_version == kOrderFreeFormatVersion);
    CHECK(geometry_codec(*blob) == 9);
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    REQUIRE(out->size() == in.size());
    CHECK(records(*out) == snapped_records(in, 0.01));
    // Smaller than the octree would be: the same points with their times
    // shuffled among them code as an octree.
    check_octree_with_shuffled_times(in, p, 3);
  }
}

TEST_CASE("format 8: the time-ordered blob depends only on the multiset of points", "[codec][scan][las]") {
  PointCloud in = scan_scene(22, 4000, 0xFFF);
  // Duplicates: same cell, same time and return, differing only in attributes.
  for (std::size_t i = 0; i < 50; ++i) {
    in.push_back_from(PointCloud(in), i * 7);
    in.las.extra_bytes[(in.size() - 1) * 2] = static_cast<std::uint8_t>(i);
  }
  const EncodeParams p = las_scale(0.01, 4.0);
  auto a = encode_chunk(in, p);
  REQUIRE(a.is_ok());
  CHECK(geometry_codec(*a) == 9);
  test::Rng rng(78);
  for (int t = 0; t < 3; ++t) {
    const std::vector<std::uint32_t> perm = rng.permutation(in.size());
    auto b = encode_chunk(in.gathered(perm), p);
    REQUIRE(b.is_ok());
    CHECK(*a == *b);
  }
  auto out = decode_chunk(*a);
  REQUIRE(out.is_ok());
  CHECK(records(*out) == snapped_records(in, 0.01));
}

TEST_CASE("format 8: levels of detail and subsets of a time-ordered blob", "[codec][scan][las]") {
  const PointCloud in = scan_scene(23, 5000, 0xFFF);
  auto blob = encode_chunk(in, las_scale(0.01, 2.0));
  REQUIRE(blob.is_ok());
  REQUIRE(geometry_codec(*blob) == 9);
  DecodeOptions lod;
  lod.lod = 4;
  auto coarse = decode_chunk(*blob, lod);
  REQUIRE(coarse.is_ok());
  CHECK(coarse->size() > 0);
  CHECK(coarse->size() <= (in.size() + 3) / 4 + 1);
  auto full = decode_chunk(*blob);
  REQUIRE(full.is_ok());
  CHECK(full->size() == in.size());
}

namespace {

// Where section `id` of a blob starts (format-spec/chunk.md §1, §3).
std::size_t section_at(const std::vector<std::uint8_t>& blob, int id) {
  auto info = inspect_chunk(blob);
  REQUIRE(info.is_ok());
  std::size_t at = 176 + 12 * info->sections.size();
  for (const ChunkSectionInfo& s : info->sections) {
    if (s.id == id) return at;
    at += s.coded_size;
  }
  FAIL("no section " << id);
  return 0;
}

}  // namespace

namespace {

// A scan whose colours follow the height (canopy and ground returns
// alternate in time: cell order wins) and whose intensities are constant
// along each scan line (lines run along x at one y: time order wins).
PointCloud orders_scene(std::uint64_t seed, std::size_t points) {
  PointCloud in = scan_scene(seed, points, 0xFFF);
  for (std::size_t i = 0; i < in.size(); ++i) {
    const Vec3d p = in.positions[i];
    const auto level = static_cast<std::uint8_t>(std::clamp(128.0 + 40.0 * std::sin(p.x * 0.3) + 30.0 * p.z, 0.0, 255.0));
    in.colors[i] = {level, static_cast<std::uint8_t>(255 - level), 90};
    in.intensities[i] = static_cast<float>(std::floor(1000.0 + 200.0 * std::cos(p.y * 0.2)));
    in.las.classification[i] = static_cast<std::uint8_t>(in.las.return_number[i] == in.las.number_of_returns[i] ? 2 : 5);
  }
  return in;
}

}  // namespace

TEST_CASE("format 8: each attribute section of a time-ordered layer takes the smaller order", "[codec][scan][las]") {
  const PointCloud in = orders_scene(24, 6000);
  auto blob = encode_chunk(in, las_scale(0.01, 4.0));
  REQUIRE(blob.is_ok());
  REQUIRE(geometry_codec(*blob) == 9);
  const std::size_t at = section_at(*blob, 7);
  const std::uint8_t mask = (*blob)[at];
  INFO("order mask " << int{mask});
  CHECK((mask & 0x80) == 0);
  CHECK((mask & 0x01) != 0);  // colours in cell order
  CHECK((mask & 0x02) == 0);  // intensities in time order
  auto out = decode_chunk(*blob);
  REQUIRE(out.is_ok());
  CHECK(records(*out) == snapped_records(in, 0.01));
  // A reserved mask bit is refused; another mask decodes other orders, or
  // fails, but never crashes or returns another count.
  DecodeOptions unchecked;
  unchecked.verify_checksum = false;
  std::vector<std::uint8_t> bad = *blob;
  bad[at] = static_cast<std::uint8_t>(mask | 0x80);
  CHECK(decode_chunk(bad, unchecked).status().code() == StatusCode::kCorruptData);
  for (int bit = 0; bit < 7; ++bit) {
    bad[at] = static_cast<std::uint8_t>(mask ^ (1u << bit));
    auto r = decode_chunk(bad, unchecked);
    if (r.is_ok()) CHECK(r->size() == in.size());
  }
}

TEST_CASE("format 8: a large time-ordered blob picks each section's order from a sample, exactly",
          "[codec][scan][las]") {
  // 2^18 points and more: the encoder codes the first eighth of the cell
  // order both ways and codes each section in the order that wins there
  // (by more than 1/32) alone. Colours win in cell order and intensities in
  // time order by far.
  const PointCloud in = orders_scene(26, 300000);
  auto blob = encode_chunk(in, las_scale(0.01, 4.0));
  REQUIRE(blob.is_ok());
  REQUIRE(geometry_codec(*blob) == 9);
  REQUIRE(inspect_chunk(*blob)->input_points == in.size());
  const std::uint8_t mask = (*blob)[section_at(*blob, 7)];
  INFO("order mask " << int{mask});
  CHECK((mask & 0x01) != 0);  // colours in cell order
  CHECK((mask & 0x02) == 0);  // intensities in time order
  auto out = decode_chunk(*blob);
  REQUIRE(out.is_ok());
  CHECK(records(*out) == snapped_records(in, 0.01));
}

TEST_CASE("format 8: a time-ordered geometry needs GPS times and version 8", "[codec][scan][reject]") {
  const PointCloud in = scan_scene(25, 2000, 0xFFF);
  auto blob = encode_chunk(in, las_scale(0.01, 4.0));
  REQUIRE(blob.is_ok());
  REQUIRE(geometry_codec(*blob) == 9);
  auto parsed = codec::parse_blob(*blob, true);
  REQUIRE(parsed.is_ok());
  // Without its GPS time section (and bit), with a valid checksum: refused.
  codec::ChunkHeader h = parsed->header;
  h.las_attributes &= ~static_cast<std::uint32_t>(kLasGpsTime);
  std::vector<codec::SectionEntry> kept;
  for (const codec::SectionEntry& s : parsed->sections) {
    if (s.id != codec::las_section_id(kLasGpsTime)) kept.push_back(s);
  }
  const std::vector<std::uint8_t> no_times = codec::write_blob(h, kept);
  auto r = decode_chunk(no_times);
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().code() == StatusCode::kCorruptData);
  CHECK(r.status().message().find("without a GPS time section") != std::string::npos);
  // Codec 9 in a version-7 blob: refused when the blob is parsed.
  codec::ChunkHeader v7 = parsed->header;
  v7.version = 7;
  auto old = decode_chunk(codec::write_blob(v7, parsed->sections));
  REQUIRE_FALSE(old.is_ok());
  CHECK(old.status().code() == StatusCode::kCorruptData);
}

TEST_CASE("format 8: in a blob of 2^16 points or more the octree is tried only when a trial on the first eighth "
          "could win", "[codec][scan][las]") {
  // Above the trial's threshold (bounded_encoder.cpp, kOctreeTrialPoints):
  // the scan keeps the time order, and the same points with their times
  // shuffled (times that do not follow the geometry) still get the octree,
  // which the trial must not skip.
  const PointCloud in = scan_scene(26, 70000, kLasGpsTime | kLasReturnNumber | kLasNumberOfReturns);
  const EncodeParams p = las_scale(0.01, 8.0);
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  CHECK(geometry_codec(*blob) == 9);
  check_octree_with_shuffled_times(in, p, 4);
}

TEST_CASE("median_of_five equals sorting, for every ordering with ties", "[codec][scan]") {
  // Every 5-tuple of values 0..4 covers every ordering of five values, ties
  // included; large magnitudes check nothing overflows.
  for (int code = 0; code < 5 * 5 * 5 * 5 * 5; ++code) {
    std::array<std::int64_t, 5> v{};
    for (int k = 0, c = code; k < 5; ++k, c /= 5) v[static_cast<std::size_t>(k)] = (c % 5 - 2) * (std::int64_t{1} << 40);
    std::array<std::int64_t, 5> sorted = v;
    std::sort(sorted.begin(), sorted.end());
    REQUIRE(codec::median_of_five(v) == sorted[2]);
  }
}

TEST_CASE("format 14: keep_order gives the points back in the given order, GPS times stepping back or not",
          "[codec][scan][las]") {
  const PointCloud scan = scan_scene(27, 4000, 0xFFF);
  // The scan in time order, the same points in a shuffled order (times
  // stepping back), and without GPS times.
  const PointCloud shuffled = scan.gathered(test::Rng(28).permutation(scan.size()));
  PointCloud untimed = shuffled;
  untimed.las.gps_time.clear();
  EncodeParams p = las_scale(0.01, 4.0);
  p.bound->keep_order = true;
  const struct {
    const PointCloud* in;
    int version;
  } cases[] = {{&scan, 13}, {&shuffled, 14}, {&untimed, 14}};
  for (const auto& c : cases) {
    INFO("version " << c.version << ", " << (c.in->las.gps_time.empty() ? "no times" : "times"));
    auto blob = encode_chunk(*c.in, p);
    REQUIRE(blob.is_ok());
    CHECK(inspect_chunk(*blob)->format_version == c.version);
    CHECK(geometry_codec(*blob) == 9);
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    REQUIRE(out->size() == c.in->size());
    // Point by point: the input's, snapped, with every attribute.
    PointCloud want = *c.in;
    for (Vec3d& q : want.positions) {
      q = {std::llround(q.x / 0.01) * 0.01, std::llround(q.y / 0.01) * 0.01, std::llround(q.z / 0.01) * 0.01};
    }
    bool same = out->colors == want.colors && out->intensities == want.intensities;
    for (std::size_t i = 0; i < want.size(); ++i) {
      const Vec3d d{out->positions[i].x - want.positions[i].x, out->positions[i].y - want.positions[i].y,
                    out->positions[i].z - want.positions[i].z};
      same = same && std::fabs(d.x) < 1e-9 && std::fabs(d.y) < 1e-9 && std::fabs(d.z) < 1e-9;
    }
    LasAttributes::for_each_vector_pair(out->las, want.las,
                                        [&](const auto& a, const auto& b, std::uint32_t) { same = same && a == b; });
    CHECK(same);
    // A version-13 reader's rule (times never step back) refuses the shuffled one.
    if (c.in == &shuffled) {
      auto parsed = codec::parse_blob(*blob, true);
      REQUIRE(parsed.is_ok());
      codec::ChunkHeader v13 = parsed->header;
      v13.version = 13;
      auto r = decode_chunk(codec::write_blob(v13, parsed->sections));
      REQUIRE_FALSE(r.is_ok());
      CHECK(r.status().code() == StatusCode::kCorruptData);
    }
  }
}

TEST_CASE("coders refuse input that breaks their preconditions with an empty section, never a cut stream",
          "[codec][scan]") {
  // A cell of 2^depth or more; a context of another size.
  const std::vector<CellXyz> cells = {{1, 2, 3}, {9, 2, 3}};
  CHECK_FALSE(codec::encode_scan_geometry(cells, 4, ScanContext{}).empty());
  CHECK(codec::encode_scan_geometry(cells, 3, ScanContext{}).empty());
  const std::vector<std::uint8_t> one_kind = {0};
  CHECK(codec::encode_scan_geometry(cells, 4, ScanContext{one_kind, {}, {}, {}}).empty());
  // Times in the layer's order that step back: only format 14 codes them.
  const std::vector<double> times = {10.0, 12.0, 11.0};
  CHECK(codec::encode_gps_in_order(times).empty());
  const std::vector<std::uint8_t> back = codec::encode_gps_in_order(times, true);
  REQUIRE_FALSE(back.empty());
  LasAttributes las;
  REQUIRE(codec::decode_gps_in_order(back, times.size(), las, true).is_ok());
  CHECK(las.gps_time == times);
  CHECK_FALSE(codec::decode_gps_in_order(back, times.size(), las, false).is_ok());
}
