// LAS attributes through the error-bounded codec (chunk formats 3, 5, 6): every
// LasAttributes vector comes back exactly, per point, for every combination
// of carried attributes; blobs depend only on the multiset of points; lying
// or truncated attribute sections are refused.
#include <catch2/catch.hpp>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <string>
#include <vector>

#include "codec/las_attribute_coder.h"
#include "core/grid_index.h"
#include "relief/codec.h"
#include "support/las_attributes.h"
#include "support/sanitized.h"
#include "support/synthetic.h"

using namespace relief;

namespace {

// Where the encoder puts v: the nearest grid index, or its neighbour where
// the nearest decodes beyond half a step (core/grid_index.h).
double snap(double v, double origin, double step) {
  return core::grid_value(origin, core::grid_index_within(v, origin, step).value(), step);
}

EncodeParams params_for(double tolerance, double cell) {
  EncodeParams p;
  p.cell_size = cell;
  p.bound = ErrorBound{};
  p.bound->step = {2 * tolerance, 2 * tolerance, 2 * tolerance};
  return p;
}

// The multiset of records the decoder must return: snapped positions, every
// other field as given.
std::vector<std::string> expected_records(PointCloud c, const ErrorBound& b) {
  for (Vec3d& p : c.positions) p = {snap(p.x, b.origin.x, b.step.x), snap(p.y, b.origin.y, b.step.y), snap(p.z, b.origin.z, b.step.z)};
  return test::sorted_records(c);
}

std::vector<std::string> records(const PointCloud& c) { return test::sorted_records(c); }

PointCloud scene(std::uint64_t seed, std::size_t points, bool colors) {
  test::SceneOptions o;
  o.seed = seed;
  o.points = points;
  o.colors = colors;
  o.intensity = true;
  return test::make_terrain(o, 6.0, 0.5);
}

// Header offsets of the version-3 fields (format-spec/chunk.md §2).
constexpr std::size_t kLasAttributesOffset = 168;
constexpr std::size_t kExtraBytesSizeOffset = 172;

void put_u32(std::vector<std::uint8_t>& b, std::size_t at, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) b[at + static_cast<std::size_t>(k)] = static_cast<std::uint8_t>(v >> (8 * k));
}

}  // namespace

TEST_CASE("LAS attributes: every combination of carried attributes round-trips exactly", "[codec][las]") {
  const PointCloud base = scene(3, 60, true);
  const EncodeParams p = params_for(0.002, 2.0);
  for (std::uint32_t bits = 1; bits < (1u << 12); ++bits) {
    // Under the sanitizers: every attribute alone, every pair, all but one,
    // and one combination in eight of the rest.
    const int carried = std::popcount(bits);
    if (test::kSanitized && carried > 2 && carried < 11 && bits % 8 != 1) continue;
    INFO("attributes " << bits);
    PointCloud in = base;
    test::add_las_attributes(in, bits, 1 + bits % 64, bits, (bits & 1) != 0);
    auto blob = encode_chunk(in, p);
    REQUIRE(blob.is_ok());
    auto info = inspect_chunk(*blob);
    REQUIRE(info.is_ok());
    // 16 for octree geometry; with GPS times in scan order, 13, or 15 where
    // the scan angles in time order code smaller by their successors.
    CHECK((info->format_version == kOctreeNearestFormatVersion ||
           (info->format_version == kOrderFreeFormatVersion && (bits & kLasGpsTime) != 0) ||
           (info->format_version == kLasCodingFormatVersion && (bits & kLasScanAngle) != 0 &&
            (bits & kLasGpsTime) != 0)));
    CHECK(info->las_attributes == bits);
    CHECK(info->extra_bytes_size == ((bits & kLasExtraBytes) ? 1 + bits % 64 : 0));
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    CHECK(out->las.carried() == bits);
    CHECK(records(*out) == expected_records(in, *p.bound));
  }
}

TEST_CASE("LAS attributes: survey-like and uniform values, every extra-bytes width", "[codec][las]") {
  const EncodeParams p = params_for(0.001, 1.5);
  for (std::uint32_t width = 1; width <= 64; ++width) {
    for (const bool uniform : {false, true}) {
      INFO("width " << width << " uniform " << uniform);
      PointCloud in = scene(100 + width, 700, width % 2 == 0);
      test::add_las_attributes(in, 0xFFF & ~(width % 2 == 0 ? 0u : kLasColorLow), width, width * 7 + uniform, uniform);
      auto blob = encode_chunk(in, p);
      REQUIRE(blob.is_ok());
      auto out = decode_chunk(*blob);
      REQUIRE(out.is_ok());
      CHECK(out->las.extra_bytes_size == width);
      CHECK(records(*out) == expected_records(in, *p.bound));
    }
  }
}

TEST_CASE("LAS attributes: 0 and 1 points, duplicates with differing attributes", "[codec][las]") {
  const EncodeParams p = params_for(0.01, 1.0);
  SECTION("an empty cloud is an empty blob without LAS attributes") {
    PointCloud empty;
    empty.las.extra_bytes_size = 8;
    auto blob = encode_chunk(empty, p);
    REQUIRE(blob.is_ok());
    auto info = inspect_chunk(*blob);
    REQUIRE(info.is_ok());
    CHECK(info->format_version == kOrderFreeFormatVersion);
    CHECK(info->las_attributes == 0);
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    CHECK(out->empty());
  }
  SECTION("one point") {
    PointCloud one;
    one.positions = {{1.234, -5.5, 7.0}};
    test::add_las_attributes(one, 0xFFF, 64, 5, true);
    auto blob = encode_chunk(one, p);
    REQUIRE(blob.is_ok());
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    CHECK(records(*out) == expected_records(one, *p.bound));
  }
  SECTION("duplicates that differ in one attribute each") {
    PointCloud dup;
    for (std::uint32_t b = 0; b < 12; ++b) {
      for (int k = 0; k < 3; ++k) dup.positions.push_back({0.5, 0.5, 0.5});
    }
    test::add_las_attributes(dup, 0xFFF, 3, 11, false);
    for (std::size_t i = 0; i < dup.size(); ++i) {
      dup.las.classification[i] = 2;
      dup.las.gps_time[i] = 1000.0;
      dup.las.extra_bytes[3 * i] = 0;
    }
    // Point i differs from the others of its position in attribute i / 3 only.
    for (std::size_t i = 0; i < dup.size(); ++i) {
      const auto v = static_cast<std::uint8_t>(i % 3);
      switch (i / 3) {
        case 0: dup.las.classification[i] = v; break;
        case 1: dup.las.class_flags[i] = v; break;
        case 2: dup.las.return_number[i] = v; break;
        case 3: dup.las.number_of_returns[i] = v; break;
        case 4: dup.las.scan_flags[i] = v; break;
        case 5: dup.las.scan_angle[i] = -v; break;
        case 6: dup.las.user_data[i] = v; break;
        case 7: dup.las.point_source_id[i] = v; break;
        case 8: dup.las.gps_time[i] = v == 0 ? 0.0 : (v == 1 ? -0.0 : 1e-310); break;
        case 9: dup.las.nir[i] = v; break;
        case 10: dup.las.color_low[i].g = v; break;
        default: dup.las.extra_bytes[3 * i] = v; break;
      }
    }
    auto blob = encode_chunk(dup, p);
    REQUIRE(blob.is_ok());
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    CHECK(records(*out) == expected_records(dup, *p.bound));
  }
}

TEST_CASE("LAS attributes: the blob depends only on the multiset of points", "[codec][las]") {
  PointCloud in = scene(8, 5000, true);
  // Duplicates whose positions, colours and intensities agree: only the LAS
  // attributes order them.
  for (std::size_t i = 0; i < 300; ++i) in.push_back_from(PointCloud(in), i % 20);
  test::add_las_attributes(in, 0xFFF, 5, 42, false);
  for (std::size_t i = 0; i < 300; ++i) in.las.extra_bytes[(5000 + i) * 5 + 4] = static_cast<std::uint8_t>(i);
  const EncodeParams p = params_for(0.002, 1.0);
  auto a = encode_chunk(in, p);
  REQUIRE(a.is_ok());
  test::Rng rng(77);
  for (int t = 0; t < 3; ++t) {
    const std::vector<std::uint32_t> perm = rng.permutation(in.size());
    auto b = encode_chunk(in.gathered(perm), p);
    REQUIRE(b.is_ok());
    CHECK(*a == *b);
  }
}

namespace {

// An aerial-like scan: pulses in zigzag lines 0.1 apart, 0.1 apart along a
// line, 1-3 returns each (the later ones lower, sharing the pulse's time), a
// pulse every 1e-5 s from 3e5 s.
PointCloud scan(std::uint64_t seed, int lines, int pulses) {
  test::Rng rng(seed);
  PointCloud c;
  std::size_t pulse = 0;
  for (int l = 0; l < lines; ++l) {
    for (int p = 0; p < pulses; ++p, ++pulse) {
      const double x = 0.1 * (l % 2 == 0 ? p : pulses - 1 - p) + 0.003 * static_cast<double>(rng.next() % 7);
      const double y = 0.1 * l + 0.003 * static_cast<double>(rng.next() % 7);
      const double ground = 0.2 * std::sin(x) + 0.1 * std::cos(y);
      const double t = 3.0e5 + 1e-5 * static_cast<double>(pulse);
      const int returns = 1 + static_cast<int>(rng.next() % 3);
      for (int r = 0; r < returns; ++r) {
        c.positions.push_back({x, y, ground + 1.5 * (returns - 1 - r) + 0.01 * static_cast<double>(rng.next() % 5)});
        c.las.gps_time.push_back(t);
      }
    }
  }
  return c;
}

// Where section `id` of a blob starts (format-spec/chunk.md §1, §3).
std::size_t section_offset(const std::vector<std::uint8_t>& blob, const ChunkInfo& info, int id) {
  std::size_t at = 176 + 12 * info.sections.size();
  for (const ChunkSectionInfo& s : info.sections) {
    if (s.id == id) return at;
    at += s.coded_size;
  }
  return blob.size();
}

std::uint32_t section_size(const ChunkInfo& info, int id) {
  for (const ChunkSectionInfo& s : info.sections) {
    if (s.id == id) return s.coded_size;
  }
  return 0;
}

// Damages section `id` of `blob` `trials` times, every `whole`-th time all
// its bytes at random, else one byte, and decodes each without the checksum:
// a refusal must be corrupt data, a decode goes to `check`. Returns how many
// were refused.
template <typename Check>
int damage_section(const std::vector<std::uint8_t>& blob, int id, int trials, int whole, test::Rng& rng,
                   Check&& check) {
  auto info = inspect_chunk(blob);
  REQUIRE(info.is_ok());
  const std::size_t at = section_offset(blob, *info, id);
  const std::uint32_t size = section_size(*info, id);
  REQUIRE(size > 0);
  REQUIRE(at + size <= blob.size());
  DecodeOptions nocrc;
  nocrc.verify_checksum = false;
  int refused = 0;
  for (int t = 0; t < trials; ++t) {
    std::vector<std::uint8_t> bad = blob;
    if (t % whole == 0) {
      for (std::size_t k = 0; k < size; ++k) bad[at + k] = static_cast<std::uint8_t>(rng.next());
    } else {
      const std::size_t k = at + rng.next() % size;
      bad[k] = static_cast<std::uint8_t>(bad[k] ^ (1u + rng.next() % 255));
    }
    auto r = decode_chunk(bad, nocrc);
    if (!r.is_ok()) {
      ++refused;
      CHECK(r.status().code() == StatusCode::kCorruptData);
    } else {
      check(*r);
    }
  }
  return refused;
}

}  // namespace

TEST_CASE("LAS attributes: GPS times in time order (formats 6 and 7) are exact and cheap for a scan", "[codec][las]") {
  const PointCloud in = scan(5, 40, 120);
  const EncodeParams p = params_for(0.005, 1.0);
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  auto info = inspect_chunk(*blob);
  REQUIRE(info.is_ok());
  CHECK(info->format_version >= 6);  // time order since format 6 (the encoder writes 7)
  auto out = decode_chunk(*blob);
  REQUIRE(out.is_ok());
  CHECK(records(*out) == expected_records(in, *p.bound));
  // Time order makes a scan's times cheap: a step that repeats, a pulse's
  // later returns at no step, and the next pulse next along the line.
  std::uint32_t gps_bytes = 0;
  for (const ChunkSectionInfo& s : info->sections) {
    if (s.id == 18) gps_bytes = s.coded_size;
  }
  const double bits = 8.0 * gps_bytes / static_cast<double>(in.size());
  INFO("GPS time bits per point: " << bits);
  CHECK(bits > 0);
  CHECK(bits < 3.0);
  // Any order of the input gives the same blob.
  test::Rng rng(9);
  const std::vector<std::uint32_t> perm = rng.permutation(in.size());
  auto shuffled = encode_chunk(in.gathered(perm), p);
  REQUIRE(shuffled.is_ok());
  CHECK(*shuffled == *blob);
}

TEST_CASE("LAS attributes: a hostile format-6 GPS time section is refused or decodes, in bounded time", "[codec][las][reject]") {
  const PointCloud in = scan(6, 12, 40);
  auto blob = encode_chunk(in, params_for(0.005, 1.0));
  REQUIRE(blob.is_ok());
  auto info = inspect_chunk(*blob);
  REQUIRE(info.is_ok());
  REQUIRE(section_size(*info, 18) > 8);
  REQUIRE(section_offset(*blob, *info, 18) + section_size(*info, 18) + 4 <= blob->size());
  // Random bytes (every third time): any bucket shift, ranks and escapes.
  test::Rng rng(21);
  const int refused = damage_section(*blob, 18, 300, 3, rng, [&](const PointCloud& r) {
    CHECK(r.size() == in.size());
    for (const double g : r.las.gps_time) CHECK(std::isfinite(g));
  });
  CHECK(refused > 0);
}

namespace {

// The scan with the attributes that follow acquisition order: return number
// and count per pulse, scan direction (bit 6) and edge of line (bit 7), an
// angle that sweeps along each line in 0.006-degree steps (LasAttributes
// units: x 6), user data per line, a source ID per 10 lines.
PointCloud scan_with_pulses(std::uint64_t seed, int lines, int pulses) {
  PointCloud c = scan(seed, lines, pulses);
  const std::size_t n = c.size();
  LasAttributes& a = c.las;
  a.return_number.resize(n);
  a.number_of_returns.resize(n);
  a.scan_flags.resize(n);
  a.scan_angle.resize(n);
  a.user_data.resize(n);
  a.point_source_id.resize(n);
  std::size_t i = 0;
  const auto per_line = static_cast<std::size_t>(pulses);
  while (i < n) {
    std::size_t j = i;
    while (j < n && a.gps_time[j] == a.gps_time[i]) ++j;
    const auto pulse = static_cast<std::size_t>(std::llround((a.gps_time[i] - 3.0e5) / 1e-5));
    const std::size_t line = pulse / per_line, along = pulse % per_line;
    for (std::size_t k = i; k < j; ++k) {
      a.return_number[k] = static_cast<std::uint8_t>(k - i + 1);
      a.number_of_returns[k] = static_cast<std::uint8_t>(j - i);
      a.scan_flags[k] = static_cast<std::uint8_t>((line % 2) << 6 | (along == 0 || along + 1 == per_line ? 0x80 : 0));
      const auto sweep = static_cast<std::int32_t>(along * 3000 / per_line) - 1500;
      a.scan_angle[k] = 6 * (line % 2 == 0 ? sweep : -sweep);
      a.user_data[k] = static_cast<std::uint8_t>(line % 3);
      a.point_source_id[k] = static_cast<std::uint16_t>(100 + line / 10);
    }
    i = j;
  }
  return c;
}

}  // namespace

TEST_CASE("LAS attributes: acquisition-order attributes (format 6) are coded in time order, exactly and cheaper",
          "[codec][las]") {
  const PointCloud in = scan_with_pulses(12, 30, 150);
  const std::size_t n = in.size();
  // Through the chunk codec: exact, and any input order gives the same blob.
  const EncodeParams p = params_for(0.005, 1.0);
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  auto out = decode_chunk(*blob);
  REQUIRE(out.is_ok());
  CHECK(records(*out) == expected_records(in, *p.bound));
  test::Rng rng(31);
  const std::vector<std::uint32_t> perm = rng.permutation(n);
  auto shuffled = encode_chunk(in.gathered(perm), p);
  REQUIRE(shuffled.is_ok());
  CHECK(*shuffled == *blob);
  // Section by section, the points in a spatial order (rows of 0.5 across
  // the lines, as cells cut them): time order against cell order.
  std::vector<std::uint32_t> spatial(n);
  for (std::uint32_t i = 0; i < n; ++i) spatial[i] = i;
  std::stable_sort(spatial.begin(), spatial.end(), [&](std::uint32_t a, std::uint32_t b) {
    const auto ra = std::floor(in.positions[a].x / 0.5), rb = std::floor(in.positions[b].x / 0.5);
    return ra != rb ? ra < rb : in.positions[a].y < in.positions[b].y;
  });
  const PointCloud cells = in.gathered(spatial);
  const std::vector<std::uint32_t> order = codec::las_time_order(cells.las.gps_time);
  REQUIRE(order.size() == n);
  for (int b = 0; b < codec::kLasAttributeCount; ++b) {
    const std::uint32_t bit = 1u << b;
    if ((bit & codec::kLasTimeOrdered) == 0) continue;
    INFO(codec::las_attribute_name(bit));
    const std::vector<std::uint8_t> timed = codec::encode_las_attribute(bit, cells.las, n, 6, {}, order);
    const std::vector<std::uint8_t> plain = codec::encode_las_attribute(bit, cells.las, n, 6);
    INFO("time order " << timed.size() << " bytes, cell order " << plain.size());
    if (bit != kLasPointSourceId) CHECK(timed.size() < plain.size());
    CHECK(timed.size() <= plain.size() + 2);
    LasAttributes back;
    back.gps_time = cells.las.gps_time;
    if (bit == kLasNumberOfReturns) back.return_number = cells.las.return_number;
    REQUIRE(codec::decode_las_attribute(bit, timed, n, back, 6, {}, order).is_ok());
    const bool rn = bit == kLasReturnNumber || bit == kLasNumberOfReturns;
    CHECK(back.return_number == (rn ? cells.las.return_number : std::vector<std::uint8_t>{}));
    CHECK(back.number_of_returns == (bit == kLasNumberOfReturns ? cells.las.number_of_returns : std::vector<std::uint8_t>{}));
    CHECK(back.scan_flags == (bit == kLasScanFlags ? cells.las.scan_flags : std::vector<std::uint8_t>{}));
    CHECK(back.scan_angle == (bit == kLasScanAngle ? cells.las.scan_angle : std::vector<std::int32_t>{}));
    CHECK(back.user_data == (bit == kLasUserData ? cells.las.user_data : std::vector<std::uint8_t>{}));
    CHECK(back.point_source_id ==
          (bit == kLasPointSourceId ? cells.las.point_source_id : std::vector<std::uint16_t>{}));
    // A time order that does not cover the points is refused.
    LasAttributes short_order;
    short_order.gps_time = cells.las.gps_time;
    CHECK(codec::decode_las_attribute(bit, timed, n, short_order, 6, {}, std::span(order).first(n - 1)).code() ==
          StatusCode::kCorruptData);
  }
}

TEST_CASE("format 15: scan angles that repeat line after line are coded by their successors, exactly and cheaper",
          "[codec][las]") {
  // A scanner's angles: the same irregular, quantised sequence on every
  // line (0.006 degree units), back and forth.
  PointCloud in = scan_with_pulses(41, 40, 150);
  const std::size_t n = in.size();
  for (std::size_t k = 0; k < n; ++k) {
    const auto pulse = static_cast<std::size_t>(std::llround((in.las.gps_time[k] - 3.0e5) / 1e-5));
    const std::size_t line = pulse / 150, along = pulse % 150;
    const double a = static_cast<double>(line % 2 == 0 ? along : 149 - along);
    in.las.scan_angle[k] = 6 * static_cast<std::int32_t>(std::lround(a * 19.7 + 7 * std::sin(a * 0.37))) - 9000;
  }
  const EncodeParams p = params_for(0.005, 1.0);
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  auto info = inspect_chunk(*blob);
  REQUIRE(info.is_ok());
  CHECK(info->format_version == kLasCodingFormatVersion);
  auto out = decode_chunk(*blob);
  REQUIRE(out.is_ok());
  CHECK(records(*out) == expected_records(in, *p.bound));
  // The section alone, in time order: format 15 against format 13's contexts.
  const std::vector<std::uint32_t> order = codec::las_time_order(in.las.gps_time);
  const std::vector<std::uint8_t> v13 = codec::encode_las_attribute(kLasScanAngle, in.las, n, 13, {}, order);
  const std::vector<std::uint8_t> v15 = codec::encode_las_attribute(kLasScanAngle, in.las, n, 15, {}, order);
  INFO("format 13: " << v13.size() << " bytes, format 15: " << v15.size());
  CHECK(10 * v15.size() < 6 * v13.size());  // measured: 2361 and 1175 bytes
  for (const int version : {13, 15}) {
    LasAttributes back;
    back.gps_time = in.las.gps_time;
    REQUIRE(codec::decode_las_attribute(kLasScanAngle, version == 15 ? v15 : v13, n, back, version, {}, order).is_ok());
    CHECK(back.scan_angle == in.las.scan_angle);
  }
  // Read as the other version's coding, the bytes mean something else (or
  // nothing): the version field decides.
  LasAttributes other;
  other.gps_time = in.las.gps_time;
  const Status misread = codec::decode_las_attribute(kLasScanAngle, v15, n, other, 13, {}, order);
  CHECK((!misread.is_ok() || other.scan_angle != in.las.scan_angle));
  // Damaged successor sections are refused as corrupt data or decode to as
  // many points, in bounded time.
  test::Rng rng(5);
  CHECK(damage_section(*blob, 15, 80, 4, rng, [&](const PointCloud& r) { CHECK(r.las.scan_angle.size() == n); }) > 0);
  // Constant angles code the same either way: the blob stays format 13.
  for (std::int32_t& a : in.las.scan_angle) a = 600;
  auto flat = encode_chunk(in, p);
  REQUIRE(flat.is_ok());
  CHECK(inspect_chunk(*flat)->format_version == kOrderFreeFormatVersion);
}

TEST_CASE("format 15: NIR that moves with the green band is coded against the colours, exactly and cheaper",
          "[codec][las]") {
  PointCloud in = scene(17, 4000, true);
  test::add_las_attributes(in, kLasNir, 0, 17, false);
  const std::size_t n = in.size();
  test::Rng rng(9);
  for (std::size_t i = 0; i < n; ++i) {
    const int nir = in.colors[i].g * 3 / 4 + 20 + static_cast<int>(rng.next() % 7);
    in.las.nir[i] = static_cast<std::uint16_t>(std::min(nir, 255) * 256);
  }
  const std::vector<std::uint8_t> v13 = codec::encode_las_attribute(kLasNir, in.las, n, 13, {}, {}, in.colors);
  const std::vector<std::uint8_t> v15 = codec::encode_las_attribute(kLasNir, in.las, n, 15, {}, {}, in.colors);
  INFO("format 13: " << v13.size() << " bytes, format 15: " << v15.size());
  CHECK(v15.size() < v13.size());
  LasAttributes back;
  REQUIRE(codec::decode_las_attribute(kLasNir, v15, n, back, 15, {}, {}, in.colors).is_ok());
  CHECK(back.nir == in.las.nir);
  // The colours it was coded against must all be there.
  LasAttributes short_colors;
  CHECK(codec::decode_las_attribute(kLasNir, v15, n, short_colors, 15, {}, {}, std::span(in.colors).first(n - 1))
            .code() == StatusCode::kCorruptData);
  // Through the chunk codec: format 15, exact, and NIR alone decodes (the
  // colours decoded for it, not returned).
  const EncodeParams p = params_for(0.002, 1.0);
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  // (An octree blob: format 17, which codes NIR so too.)
  CHECK(inspect_chunk(*blob)->format_version >= kLasCodingFormatVersion);
  auto out = decode_chunk(*blob);
  REQUIRE(out.is_ok());
  CHECK(records(*out) == expected_records(in, *p.bound));
  DecodeOptions nir_only;
  nir_only.attributes = AttributeSet::none();
  nir_only.attributes.las = kLasNir;
  auto alone = decode_chunk(*blob, nir_only);
  REQUIRE(alone.is_ok());
  CHECK(alone->colors.empty());
  CHECK(alone->las.nir == out->las.nir);
}

TEST_CASE("LAS attributes: time-ordered attributes with one time for all, and shared times, are exact", "[codec][las]") {
  PointCloud in = scene(14, 3000, false);
  test::add_las_attributes(in, 0xFFF, 3, 15, false);
  const EncodeParams p = params_for(0.002, 1.0);
  SECTION("one GPS time: time order is cell order") {
    for (double& t : in.las.gps_time) t = 123.25;
  }
  SECTION("few GPS times: many ties, broken by cell order") {
    for (std::size_t i = 0; i < in.size(); ++i) in.las.gps_time[i] = static_cast<double>(i % 7);
  }
  SECTION("negative and positive times") {
    for (std::size_t i = 0; i < in.size(); ++i) in.las.gps_time[i] = static_cast<double>(i % 11) - 5.5;
  }
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  auto out = decode_chunk(*blob);
  REQUIRE(out.is_ok());
  CHECK(records(*out) == expected_records(in, *p.bound));
}

TEST_CASE("LAS attributes: hostile time-ordered sections are refused or decode, in bounded time", "[codec][las][reject]") {
  const PointCloud in = scan_with_pulses(16, 10, 40);
  auto blob = encode_chunk(in, params_for(0.005, 1.0));
  REQUIRE(blob.is_ok());
  test::Rng rng(23);
  int refused = 0;
  for (const int id : {12, 13, 14, 15, 16, 17, 18}) {
    refused += damage_section(*blob, id, 60, 3, rng, [&](const PointCloud& r) {
      CHECK(r.size() == in.size());
      CHECK(r.las.scan_angle.size() == in.size());
    });
  }
  CHECK(refused > 0);
}

TEST_CASE("LAS attributes: subsets, and levels of detail from the point layer", "[codec][las]") {
  PointCloud in = scene(9, 4000, false);
  test::add_las_attributes(in, 0xFFF & ~kLasColorLow, 2, 9, false);
  const EncodeParams p = params_for(0.002, 1.0);
  std::vector<std::uint32_t> subset;
  for (std::uint32_t i = 0; i < in.size(); i += 3) subset.push_back(i);
  auto sub_blob = encode_chunk_subset(in, subset, p);
  REQUIRE(sub_blob.is_ok());
  auto direct = encode_chunk(in.gathered(subset), p);
  REQUIRE(direct.is_ok());
  CHECK(*sub_blob == *direct);
  // The whole cloud in its order is encoded in place: the same blob as
  // encode_chunk, as the gathered path would give.
  std::vector<std::uint32_t> identity(in.size());
  for (std::uint32_t i = 0; i < in.size(); ++i) identity[i] = i;
  auto whole = encode_chunk_subset(in, identity, p);
  REQUIRE(whole.is_ok());
  auto whole_direct = encode_chunk(in, p);
  REQUIRE(whole_direct.is_ok());
  CHECK(*whole == *whole_direct);
  std::vector<std::uint32_t> reversed(identity.rbegin(), identity.rend());
  auto whole_reversed = encode_chunk_subset(in, reversed, p);
  REQUIRE(whole_reversed.is_ok());
  CHECK(*whole_reversed == *encode_chunk(in.gathered(reversed), p));

  // A fine level (decoded from the point layer) keeps each kept point's attributes.
  auto blob = encode_chunk(in, params_for(0.002, 0.05));
  REQUIRE(blob.is_ok());
  auto info = inspect_chunk(*blob);
  REQUIRE(info.is_ok());
  auto all = decode_chunk(*blob);
  REQUIRE(all.is_ok());
  DecodeOptions d;
  d.lod = 2;
  auto half = decode_chunk(*blob, d);
  REQUIRE(half.is_ok());
  if (2ull * info->base_points < (in.size() + 1) / 2) {
    REQUIRE(half->size() == (all->size() + 1) / 2);
    for (std::size_t k = 0; k < half->size(); ++k) CHECK(test::point_record(*half, k) == test::point_record(*all, 2 * k));
  } else {
    // The base layer carries the majority class per pixel, nothing else.
    CHECK(half->las.carried() == kLasClassification);
  }
}

TEST_CASE("LAS attributes: encoder refuses inconsistent attributes", "[codec][las]") {
  PointCloud in = scene(10, 100, false);
  const EncodeParams p = params_for(0.01, 1.0);
  PointCloud short_class = in;
  short_class.las.classification.assign(99, 1);
  CHECK(encode_chunk(short_class, p).status().code() == StatusCode::kInvalidArgument);
  PointCloud nan_time = in;
  nan_time.las.gps_time.assign(100, 1.0);
  nan_time.las.gps_time[5] = std::nan("");
  CHECK(encode_chunk(nan_time, p).status().code() == StatusCode::kInvalidArgument);
  PointCloud low_without_rgb = in;
  low_without_rgb.las.color_low.assign(100, Rgb8{});
  CHECK(encode_chunk(low_without_rgb, p).status().code() == StatusCode::kInvalidArgument);
  std::vector<std::uint32_t> subset = {1, 2, 3};
  CHECK(encode_chunk_subset(nan_time, std::vector<std::uint32_t>{4, 5}, p).status().code() ==
        StatusCode::kInvalidArgument);
  CHECK(encode_chunk_subset(short_class, subset, p).status().code() == StatusCode::kInvalidArgument);
  // The whole cloud in order (encoded in place, not gathered) is checked alike.
  std::vector<std::uint32_t> identity(in.size());
  for (std::uint32_t i = 0; i < in.size(); ++i) identity[i] = i;
  CHECK(encode_chunk_subset(nan_time, identity, p).status().code() == StatusCode::kInvalidArgument);
  CHECK(encode_chunk_subset(short_class, identity, p).status().code() == StatusCode::kInvalidArgument);
  CHECK(encode_chunk_subset(low_without_rgb, identity, p).status().code() == StatusCode::kInvalidArgument);
}

TEST_CASE("LAS attributes: truncated and lying attribute sections are refused", "[codec][las][reject]") {
  PointCloud in = scene(11, 800, true);
  test::add_las_attributes(in, 0xFFF, 6, 11, false);
  auto blob = encode_chunk(in, params_for(0.002, 1.0));
  REQUIRE(blob.is_ok());
  for (std::size_t len = 0; len < blob->size(); len += 3) {
    std::vector<std::uint8_t> cut(blob->begin(), blob->begin() + static_cast<std::ptrdiff_t>(len));
    CHECK_FALSE(decode_chunk(cut).is_ok());
  }
  DecodeOptions nocrc;
  nocrc.verify_checksum = false;
  SECTION("header fields") {
    const auto refused = [&](std::size_t at, std::uint32_t v) {
      std::vector<std::uint8_t> bad = *blob;
      put_u32(bad, at, v);
      auto r = decode_chunk(bad, nocrc);
      return !r.is_ok() && r.status().code() == StatusCode::kCorruptData;
    };
    CHECK(refused(kLasAttributesOffset, 0));             // version 3 without attributes
    CHECK(refused(kLasAttributesOffset, 0xFFF | 1u << 12));  // a reserved bit
    CHECK(refused(kLasAttributesOffset, 0xFFE));         // one section fewer than the table
    CHECK(refused(kExtraBytesSizeOffset, 0));            // extra bytes of width 0
    CHECK(refused(kExtraBytesSizeOffset, 65536));        // wider than a LAS record
    // Extra bytes 65535 wide: the section cannot hold them, refused before allocating.
    CHECK(refused(kExtraBytesSizeOffset, 65535));
  }
  SECTION("every section payload byte flipped decodes or is refused, never crashes") {
    test::Rng rng(3);
    int refused = 0;
    for (int t = 0; t < 500; ++t) {
      std::vector<std::uint8_t> bad = *blob;
      // The LAS sections are at the end of the blob, before the CRC.
      const std::size_t at = bad.size() - 5 - rng.next() % std::min<std::size_t>(bad.size() / 3, 3000);
      bad[at] = static_cast<std::uint8_t>(bad[at] ^ (1u + rng.next() % 255));
      auto r = decode_chunk(bad, nocrc);
      if (!r.is_ok()) {
        ++refused;
      } else {
        CHECK(r->size() == in.size());
      }
    }
    CHECK(refused > 0);
  }
}

// Not run by default: writes the chunk fuzz target's seeds with LAS attributes,
//   RELIEF_FUZZ_SEED_DIR=tests/fuzz/corpus/chunk ./test_codec "[.seed]"
// The encoder writes format 13 for the error-bounded layer (14 with keep_order
// and no GPS times) and
// format 4 for resampling with a classification; the format-3 and format-6
// to format-12 seeds in the corpus (seed-v3-las-attributes.rlfc,
// seed-v6-las-*.rlfc, ...) were written by this test before later formats and
// are kept as they are. Seeds stay under the fuzz target's max_len
// (4096, scripts/fuzz.sh), else libFuzzer cuts them.
TEST_CASE("LAS attributes: write the fuzz seeds", "[.seed]") {
  const char* dir = std::getenv("RELIEF_FUZZ_SEED_DIR");
  if (dir == nullptr) return;
  const auto write = [&](const std::string& name, const std::vector<std::uint8_t>& blob, std::uint16_t version) {
    auto info = inspect_chunk(blob);
    REQUIRE(info.is_ok());
    CHECK(info->format_version == version);
    CHECK(blob.size() <= 4096);
    std::ofstream(std::string(dir) + "/" + name, std::ios::binary)
        .write(reinterpret_cast<const char*>(blob.data()), static_cast<std::streamsize>(blob.size()));
  };
  // Format 13, a scan: the geometry and GPS times in time order (codec 9),
  // pulses with their returns, scan flags, angles, user data and point
  // source IDs in acquisition order, plus a classification (and so the
  // classification map) and intensities.
  PointCloud timed = scan_with_pulses(14, 6, 30);
  test::Rng rng(15);
  for (std::size_t i = 0; i < timed.size(); ++i) {
    timed.las.classification.push_back(static_cast<std::uint8_t>(timed.las.return_number[i] == 1 ? 2 : 5));
    timed.intensities.push_back(static_cast<float>(rng.next() % 4096));
  }
  auto v13 = encode_chunk(timed, params_for(0.005, 1.0));
  REQUIRE(v13.is_ok());
  CHECK(inspect_chunk(*v13)->las_attributes ==
        (kLasClassification | kLasReturnNumber | kLasNumberOfReturns | kLasScanFlags | kLasScanAngle | kLasUserData |
         kLasPointSourceId | kLasGpsTime));
  for (const ChunkSectionInfo& s : inspect_chunk(*v13)->sections) {
    if (s.id == 7) CHECK(s.codec == 9);  // the geometry in time order
  }
  write("seed-v13-las-scan-time-order.rlfc", *v13, 13);
  // The same scan with an intensity tolerance (header bytes 164-165): the
  // intensities as quantised residuals (from format 12, §11.5).
  EncodeParams tolerant = params_for(0.005, 1.0);
  tolerant.bound->intensity_tolerance = 20;
  auto quantised = encode_chunk(timed, tolerant);
  REQUIRE(quantised.is_ok());
  REQUIRE(quantised->size() > 165);
  CHECK(((*quantised)[164] | (*quantised)[165] << 8) == 20);
  write("seed-v13-intensity-tolerance.rlfc", *quantised, 13);
  // Format 17 with every attribute (NIR, colour low bytes, extra bytes too),
  // the colours predicted from neighbours (codec 10), the octree with chains,
  // face patterns, APMs, plane and near classes (codec 14). (seed-v13-* and
  // seed-v16-* were written here before formats 16 and 17, with codecs 12
  // and 13.)
  PointCloud in = scene(12, 120, true);
  test::add_las_attributes(in, 0xFFF, 3, 12, false);
  EncodeParams p = params_for(0.005, 2.0);
  p.map_resolution = 8;
  auto all = encode_chunk(in, p);
  REQUIRE(all.is_ok());
  CHECK(inspect_chunk(*all)->las_attributes == 0xFFF);
  write("seed-v17-las-attributes.rlfc", *all, 17);
  // Format 17, geometry alone on a dense terrain: most of the octree's
  // decisions are codec 14's mixed ones (child bits, flags, index bits).
  PointCloud dense = scene(13, 900, false);
  dense.intensities.clear();
  auto octree = encode_chunk(dense, params_for(0.02, 2.0));
  REQUIRE(octree.is_ok());
  for (const ChunkSectionInfo& s : inspect_chunk(*octree)->sections) {
    if (s.id == 7) CHECK(s.codec == 14);
  }
  write("seed-v17-octree.rlfc", *octree, 17);
  // Format 17 on a sparse, noisy surface: chains and single children whose
  // index bits take plane and near classes of every kind.
  PointCloud sparse = scene(16, 400, false);
  sparse.intensities.clear();
  auto chains = encode_chunk(sparse, params_for(0.0005, 2.0));
  REQUIRE(chains.is_ok());
  write("seed-v17-chains.rlfc", *chains, 17);
  // Format 14: keep_order without GPS times, the geometry in the given order
  // with no pulse context (codec 9), the scan's returns, flags, angles, user
  // data and source IDs with their plain coding in that order; and colours
  // and intensities in it (or in cell order, as the order mask says).
  PointCloud untimed = timed;
  untimed.las.gps_time.clear();
  EncodeParams keep = params_for(0.005, 1.0);
  keep.bound->keep_order = true;
  auto v14 = encode_chunk(untimed, keep);
  REQUIRE(v14.is_ok());
  write("seed-v14-keep-order-untimed.rlfc", *v14, 14);
  // The scan shuffled: its GPS times step back in the given order (format
  // 14's GPS section without ranks).
  auto v14back = encode_chunk(timed.gathered(rng.permutation(timed.size() / 2)), keep);  // half: under max_len
  REQUIRE(v14back.is_ok());
  write("seed-v14-keep-order-times-back.rlfc", *v14back, 14);
  PointCloud colored = scene(14, 150, true);
  auto v14rgb = encode_chunk(colored, keep);
  REQUIRE(v14rgb.is_ok());
  write("seed-v14-keep-order-rgb.rlfc", *v14rgb, 14);
  EncodeParams resample;
  resample.cell_size = 0.5;
  resample.map_resolution = 8;
  auto v4 = encode_chunk(in, resample);
  REQUIRE(v4.is_ok());
  write("seed-v4-class-map.rlfc", *v4, 4);
}

TEST_CASE("classification map: resampled points get their pixel's majority class", "[codec][las][classmap]") {
  EncodeParams p;
  p.cell_size = 0.5;
  SECTION("two regions") {
    test::SceneOptions o;
    o.seed = 31;
    o.points = 20000;
    PointCloud in = test::make_terrain(o, 4.0, 0.2);
    for (const Vec3d& q : in.positions) in.las.classification.push_back(q.x < 0 ? 2 : 6);
    in.las.user_data.assign(in.size(), 9);  // other attributes are not kept by the maps
    auto blob = encode_chunk(in, p);
    REQUIRE(blob.is_ok());
    auto info = inspect_chunk(*blob);
    REQUIRE(info.is_ok());
    CHECK(info->format_version == 4);
    CHECK(info->las_attributes == kLasClassification);
    auto out = decode_chunk(*blob);
    REQUIRE(out.is_ok());
    REQUIRE(out->las.carried() == kLasClassification);
    std::size_t checked = 0;
    for (std::size_t i = 0; i < out->size(); ++i) {
      const double x = out->positions[i].x;
      if (std::fabs(x) < 0.1) continue;  // pixels straddling the border may vote either way
      CHECK(out->las.classification[i] == (x < 0 ? 2 : 6));
      ++checked;
    }
    CHECK(checked > out->size() / 2);
    // Without classification the blob stays version 1.
    in.las = LasAttributes{};
    auto plain = encode_chunk(in, p);
    REQUIRE(plain.is_ok());
    CHECK(inspect_chunk(*plain)->format_version == 1);
  }
  SECTION("majority and ties within one pixel") {
    for (const auto& [classes, want] : std::vector<std::pair<std::vector<std::uint8_t>, std::uint8_t>>{
             {{3, 5, 3, 5, 3}, 3}, {{7, 4, 7, 4}, 4}, {{200}, 200}, {{9, 1, 9, 9, 1, 1, 1}, 1}}) {
      PointCloud in;
      for (const std::uint8_t c : classes) {
        in.positions.push_back({0.25, 0.25, 0.25});
        in.las.classification.push_back(c);
      }
      auto blob = encode_chunk(in, p);
      REQUIRE(blob.is_ok());
      auto out = decode_chunk(*blob);
      REQUIRE(out.is_ok());
      REQUIRE(out->size() == 1);
      CHECK(out->las.classification[0] == want);
    }
  }
}

TEST_CASE("classification map: lying flags and sections are refused", "[codec][las][classmap][reject]") {
  test::SceneOptions o;
  o.seed = 32;
  o.points = 3000;
  PointCloud in = test::make_terrain(o, 4.0, 0.2);
  for (const Vec3d& q : in.positions) in.las.classification.push_back(q.y < 0 ? 1 : 2);
  EncodeParams resample;
  resample.cell_size = 0.5;
  auto v4 = encode_chunk(in, resample);
  REQUIRE(v4.is_ok());
  EncodeParams bounded = params_for(0.002, 0.5);
  auto v3 = encode_chunk(in, bounded);
  REQUIRE(v3.is_ok());
  REQUIRE(inspect_chunk(*v3)->format_version == kOctreeNearestFormatVersion);
  DecodeOptions nocrc;
  nocrc.verify_checksum = false;
  const auto corrupt = [&](std::vector<std::uint8_t> b) {
    auto r = decode_chunk(b, nocrc);
    return !r.is_ok() && r.status().code() == StatusCode::kCorruptData;
  };
  constexpr std::size_t kFlags = 8, kVersion = 4;
  std::vector<std::uint8_t> bad = *v4;
  bad[kFlags] = 0;  // version 4 without its map
  CHECK(corrupt(bad));
  bad = *v4;
  bad[kVersion] = 1;  // version 1 with the flag
  CHECK(corrupt(bad));
  bad = *v3;
  bad[kFlags] = static_cast<std::uint8_t>(bad[kFlags] & ~4u);  // classes without the map
  CHECK(corrupt(bad));
  for (std::size_t len = 0; len < v4->size(); len += 5) {
    CHECK_FALSE(decode_chunk(std::span<const std::uint8_t>(v4->data(), len)).is_ok());
  }
  // The map section is the last: every flip in it decodes or is refused.
  test::Rng rng(5);
  for (int t = 0; t < 300; ++t) {
    bad = *v4;
    const std::size_t at = bad.size() - 5 - rng.next() % 40;
    bad[at] = static_cast<std::uint8_t>(bad[at] ^ (1u + rng.next() % 255));
    auto r = decode_chunk(bad, nocrc);
    if (r.is_ok()) CHECK(r->las.classification.size() == r->size());
  }
}

TEST_CASE("classification map: coarse levels from the base layer keep the classes", "[codec][las][classmap]") {
  test::SceneOptions o;
  o.seed = 33;
  o.points = 40000;
  PointCloud in = test::make_terrain(o, 20.0, 1.0);
  for (const Vec3d& q : in.positions) in.las.classification.push_back(q.x < 0 ? 2 : 5);
  in.las.gps_time.assign(in.size(), 7.0);
  auto blob = encode_chunk(in, params_for(0.002, 4.0));
  REQUIRE(blob.is_ok());
  DecodeOptions d;
  d.lod = 64;
  auto out = decode_chunk(*blob, d);
  REQUIRE(out.is_ok());
  REQUIRE(!out->empty());
  CHECK(out->las.carried() == kLasClassification);  // GPS time needs the point layer
  for (std::size_t i = 0; i < out->size(); ++i) {
    if (std::fabs(out->positions[i].x) > 1.0) CHECK(out->las.classification[i] == (out->positions[i].x < 0 ? 2 : 5));
  }
}

TEST_CASE("format 7: colour low bytes equal to the colours cost one decision, others code as before",
          "[codec][las]") {
  test::SceneOptions o;
  o.seed = 77;
  o.points = 3000;
  o.colors = true;
  const PointCloud scene = test::make_terrain(o, 4.0, 0.3);
  const std::size_t n = scene.size();
  std::vector<Rgb8> low(n);
  for (std::size_t i = 0; i < n; ++i) {
    low[i] = Rgb8{static_cast<std::uint8_t>(i * 7), static_cast<std::uint8_t>(i * 13), static_cast<std::uint8_t>(i >> 3)};
  }
  SECTION("equal: one decision, and the decoder takes the colours it is given") {
    LasAttributes las;
    las.color_low = scene.colors;
    const auto coded = codec::encode_las_attribute(kLasColorLow, las, n, 7, {}, {}, scene.colors);
    CHECK(coded.size() <= 4);
    LasAttributes back;
    REQUIRE(codec::decode_las_attribute(kLasColorLow, coded, n, back, 7, {}, {}, scene.colors).is_ok());
    CHECK(back.color_low == scene.colors);
    // The same stream without the colours is corrupt, not a crash or a guess.
    LasAttributes none;
    CHECK(codec::decode_las_attribute(kLasColorLow, coded, n, none, 7).code() == StatusCode::kCorruptData);
    // Format 6 has no such decision: the triplets are coded whatever they are.
    CHECK(codec::encode_las_attribute(kLasColorLow, las, n, 6, {}, {}, scene.colors).size() > 100);
  }
  SECTION("different: the triplets follow the decision, exactly") {
    LasAttributes las;
    las.color_low = low;
    const auto v7 = codec::encode_las_attribute(kLasColorLow, las, n, 7, {}, {}, scene.colors);
    const auto v6 = codec::encode_las_attribute(kLasColorLow, las, n, 6, {}, {}, scene.colors);
    CHECK(v7.size() <= v6.size() + 1);
    LasAttributes back;
    REQUIRE(codec::decode_las_attribute(kLasColorLow, v7, n, back, 7, {}, {}, scene.colors).is_ok());
    CHECK(back.color_low == low);
    LasAttributes back6;
    REQUIRE(codec::decode_las_attribute(kLasColorLow, v6, n, back6, 6).is_ok());
    CHECK(back6.color_low == low);
    // Every truncation of the stream is refused.
    for (std::size_t cut = 0; cut + 1 < v7.size(); cut += std::max<std::size_t>(1, v7.size() / 64)) {
      LasAttributes t;
      CHECK(codec::decode_las_attribute(kLasColorLow, std::span(v7).first(cut), n, t, 7, {}, {}, scene.colors).code() ==
            StatusCode::kCorruptData);
    }
  }
}

TEST_CASE("format 11: voted bytes code every byte attribute exactly, in cell and in time order", "[codec][las]") {
  // Survey-like attributes (runs of classes, pulses of returns) and an
  // extra byte column that mostly repeats.
  PointCloud in = scene(21, 6000, false);
  test::add_las_attributes(in, 0xFFF, 3, 21, false);
  const std::size_t n = in.size();
  const std::vector<std::uint32_t> order = codec::las_time_order(in.las.gps_time);
  for (const std::uint32_t bit : {kLasClassification, kLasClassFlags, kLasReturnNumber, kLasNumberOfReturns,
                                  kLasScanFlags, kLasUserData, kLasExtraBytes}) {
    for (const bool timed : {false, true}) {
      if (timed && (bit & codec::kLasTimeOrdered) == 0) continue;
      INFO(codec::las_attribute_name(bit) << (timed ? " in time order" : " in cell order"));
      const std::span<const std::uint32_t> t = timed ? std::span<const std::uint32_t>(order) : std::span<const std::uint32_t>();
      const auto v10 = codec::encode_las_attribute(bit, in.las, n, 10, {}, t);
      const auto v11 = codec::encode_las_attribute(bit, in.las, n, 11, {}, t);
      INFO("format 10: " << v10.size() << " bytes, format 11: " << v11.size());
      // The vote saves where a byte repeats and costs little where it does
      // not: at worst +12 % here, the extra byte column whose differences
      // are spread evenly over five values (the spec's worst case).
      CHECK(v11.size() <= v10.size() + v10.size() * 15 / 100 + 4);
      for (const auto& [coded, version] : {std::pair{v10, 10}, std::pair{v11, 11}}) {
        LasAttributes back;
        back.extra_bytes_size = in.las.extra_bytes_size;
        back.gps_time = in.las.gps_time;
        if (bit == kLasNumberOfReturns) back.return_number = in.las.return_number;
        REQUIRE(codec::decode_las_attribute(bit, coded, n, back, version, {}, t).is_ok());
        CHECK(back.classification == (bit == kLasClassification ? in.las.classification : std::vector<std::uint8_t>{}));
        CHECK(back.class_flags == (bit == kLasClassFlags ? in.las.class_flags : std::vector<std::uint8_t>{}));
        CHECK(back.number_of_returns ==
              (bit == kLasNumberOfReturns ? in.las.number_of_returns : std::vector<std::uint8_t>{}));
        if (bit == kLasReturnNumber) CHECK(back.return_number == in.las.return_number);
        CHECK(back.scan_flags == (bit == kLasScanFlags ? in.las.scan_flags : std::vector<std::uint8_t>{}));
        CHECK(back.user_data == (bit == kLasUserData ? in.las.user_data : std::vector<std::uint8_t>{}));
        CHECK(back.extra_bytes == (bit == kLasExtraBytes ? in.las.extra_bytes : std::vector<std::uint8_t>{}));
      }
      // A format-11 stream read as format 10 does not give the points back.
      LasAttributes wrong;
      wrong.extra_bytes_size = in.las.extra_bytes_size;
      wrong.gps_time = in.las.gps_time;
      if (bit == kLasNumberOfReturns) wrong.return_number = in.las.return_number;
      const Status s = codec::decode_las_attribute(bit, v11, n, wrong, 10, {}, t);
      const bool same = s.is_ok() && wrong.classification == in.las.classification &&
                        wrong.class_flags == in.las.class_flags && wrong.scan_flags == in.las.scan_flags &&
                        wrong.user_data == in.las.user_data && wrong.extra_bytes == in.las.extra_bytes &&
                        wrong.number_of_returns == in.las.number_of_returns;
      CHECK_FALSE(same);
      // Every truncation of the format-11 stream is refused.
      for (std::size_t cut = 0; cut + 1 < v11.size(); cut += std::max<std::size_t>(1, v11.size() / 32)) {
        LasAttributes c;
        c.extra_bytes_size = in.las.extra_bytes_size;
        c.gps_time = in.las.gps_time;
        if (bit == kLasNumberOfReturns) c.return_number = in.las.return_number;
        CHECK(codec::decode_las_attribute(bit, std::span(v11).first(cut), n, c, 11, {}, t).code() ==
              StatusCode::kCorruptData);
      }
    }
  }
}
