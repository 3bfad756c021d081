// Golden vectors for chunk format versions 1 to 17 (format-spec/vectors/). A decoder
// change that alters what an old blob means, or an encoder change that alters
// the bytes, fails here. Regenerate deliberately with
//   RELIEF_REGENERATE_GOLDEN=1 ./test_codec "[golden]"
// and bump the format version if the meaning of existing bytes changed.
// Vectors of a version the encoder no longer writes are frozen: regeneration
// leaves them alone and only their decoding is checked.
#include <catch2/catch.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>

#include "relief/codec.h"
#include "relief/io.h"
#include "support/las_attributes.h"
#include "support/synthetic.h"

using namespace relief;

namespace {

struct Vector {
  const char* name;
  EncodeParams params;
  PointCloud (*make)();
  int version;
  bool frozen = false;  // the encoder writes a newer version for these parameters
};

PointCloud voxel_scene() {
  test::SceneOptions o;
  o.seed = 2024;
  o.points = 1500;
  o.colors = true;
  o.intensity = true;
  return test::make_terrain(o, 4.0, 0.3);
}

// Every LAS attribute, survey-like, 5 extra bytes per point.
PointCloud las_scene() {
  PointCloud c = voxel_scene();
  test::add_las_attributes(c, 0xFFF, 5, 2026, false);
  return c;
}

// The same, as a source that stores 8-bit colour levels (or v * 257) in the
// LAS colour fields: each point's low bytes equal its colour.
PointCloud las_scene_8bit() {
  PointCloud c = las_scene();
  c.las.color_low = c.colors;
  return c;
}

// The same with whole-number intensities, as a LAS source's (16-bit):
// what an intensity tolerance applies to.
PointCloud las_scene_int() {
  PointCloud c = las_scene();
  for (float& v : c.intensities) v = std::round(v * 7.0f);  // 700..7000
  return c;
}

// An airborne scan in acquisition order with every LAS attribute: the
// geometry codes in time order (codec 9, format 8).
PointCloud las_scan_scene() {
  test::SceneOptions o;
  o.seed = 2027;
  o.points = 1500;
  o.colors = true;
  o.intensity = true;
  return test::make_scan_with_las(o, 40.0, 0xFFF, 5);
}

// Every LAS attribute but the GPS time, the points in the order a
// generator made them: with keep_order the geometry codes in that order
// without pulse context (codec 9, format 14).
PointCloud las_scene_untimed() {
  PointCloud c = voxel_scene();
  test::add_las_attributes(c, 0xFFF & ~kLasGpsTime, 5, 2028, false);
  return c;
}

// The scan's points in a shuffled order: with keep_order their GPS times
// step back in the layer's order (format 14).
PointCloud las_scan_shuffled() {
  const PointCloud scan = las_scan_scene();
  return scan.gathered(test::Rng(2029).permutation(scan.size()));
}

// The scan with a scanner's scan angles: the same irregular sequence of
// quantised angles (0.006 degree units) on every line of 50 pulses, back and
// forth, which format 15 codes by their successors (chunk.md §11.7.2), and a
// NIR band that follows the green one (§11.7).
PointCloud las_scan_repeating() {
  PointCloud scan = las_scan_scene();
  std::vector<double> times = scan.las.gps_time;
  std::sort(times.begin(), times.end());
  times.erase(std::unique(times.begin(), times.end()), times.end());
  for (std::size_t i = 0; i < scan.size(); ++i) {
    const auto pulse = static_cast<std::size_t>(
        std::lower_bound(times.begin(), times.end(), scan.las.gps_time[i]) - times.begin());
    const std::size_t line = pulse / 50, along = pulse % 50;
    const double a = static_cast<double>(line % 2 == 0 ? along : 49 - along);
    scan.las.scan_angle[i] = 6 * static_cast<std::int32_t>(std::lround(a * 19.7 + 7 * std::sin(a * 0.37))) - 3000;
    // An 8-bit NIR band (stored x 256) that moves with the green one, which
    // format 15 codes NIR against.
    const int nir = scan.colors[i].g / 2 + 60 + static_cast<int>(i * 7 % 5);
    scan.las.nir[i] = static_cast<std::uint16_t>(std::min(nir, 255) * 256);
  }
  return scan;
}

bool has_las(PointCloud (*make)()) {
  return make == las_scene || make == las_scene_8bit || make == las_scan_scene || make == las_scene_int ||
         make == las_scene_untimed || make == las_scan_shuffled || make == las_scan_repeating;
}

bool is_scan(PointCloud (*make)()) { return make == las_scan_scene || make == las_scan_repeating; }

bool keeps_order(const EncodeParams& p) { return p.bound && p.bound->keep_order; }

PointCloud octree_scene() {
  test::SceneOptions o;
  o.seed = 2025;
  o.points = 1500;
  return test::make_room(o, 3.0);
}

std::vector<Vector> vectors() {
  EncodeParams voxel;
  voxel.cell_size = 0.5;
  EncodeParams octree;
  octree.cell_size = 0.1;
  octree.decomposition = Decomposition::kOctree;
  octree.octree_max_points = 200;
  octree.image_codec = ImageCodec::kJpeg2000;
  octree.height_bits = 16;
  octree.height_quality = 80;
  // Format 2: the error-bounded layer over a base layer.
  EncodeParams bounded = voxel;
  bounded.cell_size = 2.0;
  bounded.bound = ErrorBound{};
  bounded.bound->step = {0.01, 0.01, 0.005};
  bounded.bound->origin = {0.003, -0.002, 0.0};
  EncodeParams bounded_lossy = bounded;
  bounded_lossy.bound->color_tolerance = 6;
  EncodeParams bounded_intensity = bounded;
  bounded_intensity.bound->intensity_tolerance = 20;
  EncodeParams bounded_keep_order = bounded;
  bounded_keep_order.bound->keep_order = true;
  EncodeParams bounded_geometry = octree;
  bounded_geometry.cell_size = 0.75;
  bounded_geometry.bound = ErrorBound{};
  bounded_geometry.bound->step = {0.002, 0.002, 0.002};
  return {{"voxel_jpeg_rgb_intensity_v1", voxel, voxel_scene, 1},
          {"octree_j2k16_v1", octree, octree_scene, 1},
          {"bounded_rgb_intensity_v2", bounded, voxel_scene, 2, true},
          {"bounded_rgb_tolerance6_v2", bounded_lossy, voxel_scene, 2, true},
          {"bounded_geometry_octree_v2", bounded_geometry, octree_scene, 2, true},
          {"bounded_las_attributes_v3", bounded, las_scene, 3, true},
          {"voxel_class_map_v4", voxel, las_scene, 4},
          // Format 5: single-child octree coding (geometry codec 7).
          {"bounded_rgb_intensity_v5", bounded, voxel_scene, 5, true},
          {"bounded_rgb_tolerance6_v5", bounded_lossy, voxel_scene, 5, true},
          {"bounded_geometry_octree_v5", bounded_geometry, octree_scene, 5, true},
          {"bounded_las_attributes_v5", bounded, las_scene, 5, true},
          // Format 6: GPS times in time order.
          {"bounded_rgb_intensity_v6", bounded, voxel_scene, 6, true},
          {"bounded_rgb_tolerance6_v6", bounded_lossy, voxel_scene, 6, true},
          {"bounded_geometry_octree_v6", bounded_geometry, octree_scene, 6, true},
          {"bounded_las_attributes_v6", bounded, las_scene, 6, true},
          // Format 7: mixed octree coding (geometry codec 8).
          {"bounded_rgb_intensity_v7", bounded, voxel_scene, 7, true},
          {"bounded_rgb_tolerance6_v7", bounded_lossy, voxel_scene, 7, true},
          {"bounded_geometry_octree_v7", bounded_geometry, octree_scene, 7, true},
          {"bounded_las_attributes_v7", bounded, las_scene, 7, true},
          // Format 7 also codes colour low bytes equal to the colours in one decision.
          {"bounded_las_colors8_v7", bounded, las_scene_8bit, 7, true},
          // Format 8: with GPS times, the geometry in time order when smaller
          // (codec 9: only the scan scene; the others as in format 7).
          {"bounded_rgb_intensity_v8", bounded, voxel_scene, 8, true},
          {"bounded_rgb_tolerance6_v8", bounded_lossy, voxel_scene, 8, true},
          {"bounded_geometry_octree_v8", bounded_geometry, octree_scene, 8, true},
          {"bounded_las_attributes_v8", bounded, las_scene, 8, true},
          {"bounded_las_colors8_v8", bounded, las_scene_8bit, 8, true},
          {"bounded_las_scan_v8", bounded, las_scan_scene, 8, true},
          // Format 9: point colours in cell order predicted from their
          // neighbours (codec 10; the scan scene keeps its time-ordered
          // colours with codec 6 unless cell order is smaller).
          {"bounded_rgb_intensity_v9", bounded, voxel_scene, 9, true},
          {"bounded_rgb_tolerance6_v9", bounded_lossy, voxel_scene, 9, true},
          {"bounded_geometry_octree_v9", bounded_geometry, octree_scene, 9, true},
          {"bounded_las_attributes_v9", bounded, las_scene, 9, true},
          {"bounded_las_colors8_v9", bounded, las_scene_8bit, 9, true},
          {"bounded_las_scan_v9", bounded, las_scan_scene, 9, true},
          // Format 10: the octree with chains (codec 11; the scan scene keeps
          // its geometry in time order).
          {"bounded_rgb_intensity_v10", bounded, voxel_scene, 10, true},
          {"bounded_rgb_tolerance6_v10", bounded_lossy, voxel_scene, 10, true},
          {"bounded_geometry_octree_v10", bounded_geometry, octree_scene, 10, true},
          {"bounded_las_attributes_v10", bounded, las_scene, 10, true},
          {"bounded_las_colors8_v10", bounded, las_scene_8bit, 10, true},
          {"bounded_las_scan_v10", bounded, las_scan_scene, 10, true},
          // Format 11: voted bytes in the LAS attribute sections (the scenes
          // without LAS attributes differ from format 10 in the version
          // field and checksum alone).
          {"bounded_rgb_intensity_v11", bounded, voxel_scene, 11, true},
          {"bounded_rgb_tolerance6_v11", bounded_lossy, voxel_scene, 11, true},
          {"bounded_geometry_octree_v11", bounded_geometry, octree_scene, 11, true},
          {"bounded_las_attributes_v11", bounded, las_scene, 11, true},
          {"bounded_las_colors8_v11", bounded, las_scene_8bit, 11, true},
          {"bounded_las_scan_v11", bounded, las_scan_scene, 11, true},
          // Format 12: an intensity tolerance (these differ from format 11
          // in the version field and checksum alone, but the last).
          {"bounded_rgb_intensity_v12", bounded, voxel_scene, 12, true},
          {"bounded_rgb_tolerance6_v12", bounded_lossy, voxel_scene, 12, true},
          {"bounded_geometry_octree_v12", bounded_geometry, octree_scene, 12, true},
          {"bounded_las_attributes_v12", bounded, las_scene, 12, true},
          {"bounded_las_colors8_v12", bounded, las_scene_8bit, 12, true},
          {"bounded_las_scan_v12", bounded, las_scan_scene, 12, true},
          {"bounded_intensity_tolerance20_v12", bounded_intensity, las_scene_int, 12, true},
          // Format 13: the octree with face patterns and APMs (codec 12; the
          // scan scene keeps its geometry in time order, so it differs from
          // format 12 in the version field and checksum alone). Since format
          // 16 only the scan scene is still written as format 13.
          {"bounded_rgb_intensity_v13", bounded, voxel_scene, 13, true},
          {"bounded_rgb_tolerance6_v13", bounded_lossy, voxel_scene, 13, true},
          {"bounded_geometry_octree_v13", bounded_geometry, octree_scene, 13, true},
          {"bounded_las_attributes_v13", bounded, las_scene, 13, true},
          {"bounded_las_colors8_v13", bounded, las_scene_8bit, 13, true},
          {"bounded_las_scan_v13", bounded, las_scan_scene, 13},
          {"bounded_intensity_tolerance20_v13", bounded_intensity, las_scene_int, 13, true},
          // Keeping the points' order (ErrorBound::keep_order): the geometry
          // in the given order (codec 9), with GPS times that never step back
          // format 13; without them (no pulse context), or with times that
          // step back, format 14.
          {"bounded_keep_order_las_scan_v13", bounded_keep_order, las_scan_scene, 13},
          {"bounded_keep_order_rgb_intensity_v14", bounded_keep_order, voxel_scene, 14},
          {"bounded_keep_order_las_untimed_v14", bounded_keep_order, las_scene_untimed, 14},
          {"bounded_keep_order_las_shuffled_v14", bounded_keep_order, las_scan_shuffled, 14},
          // Format 15: scan angles in time order coded by their successors
          // (§11.7.2), written where that is smaller: angles that repeat line
          // after line, as a scanner's do.
          {"bounded_las_scan_repeating_v15", bounded, las_scan_repeating, 15},
          {"bounded_keep_order_las_scan_repeating_v15", bounded_keep_order, las_scan_repeating, 15},
          // Format 16: the octree with plane classes (codec 13, §11.3.6), its
          // LAS sections coded as format 15's; every blob whose geometry was
          // the octree until format 17.
          {"bounded_rgb_intensity_v16", bounded, voxel_scene, 16, true},
          {"bounded_rgb_tolerance6_v16", bounded_lossy, voxel_scene, 16, true},
          {"bounded_geometry_octree_v16", bounded_geometry, octree_scene, 16, true},
          {"bounded_las_attributes_v16", bounded, las_scene, 16, true},
          {"bounded_las_colors8_v16", bounded, las_scene_8bit, 16, true},
          {"bounded_intensity_tolerance20_v16", bounded_intensity, las_scene_int, 16, true},
          // Format 17: the octree with plane and near classes (codec 14,
          // §11.3.7); every blob whose geometry is the octree.
          {"bounded_rgb_intensity_v17", bounded, voxel_scene, 17},
          {"bounded_rgb_tolerance6_v17", bounded_lossy, voxel_scene, 17},
          {"bounded_geometry_octree_v17", bounded_geometry, octree_scene, 17},
          {"bounded_las_attributes_v17", bounded, las_scene, 17},
          {"bounded_las_colors8_v17", bounded, las_scene_8bit, 17},
          {"bounded_intensity_tolerance20_v17", bounded_intensity, las_scene_int, 17}};
}

std::string vector_path(const std::string& name, const char* ext) {
  return std::string(RELIEF_SOURCE_DIR) + "/format-spec/vectors/" + name + ext;
}

// The LAS attributes of decoded points, one text line per point (the PLY
// beside a version-3 vector cannot hold them): classification, flags, return
// number, number of returns, scan flags, scan angle, user data, point source
// ID, GPS time bits (hex), NIR, colour low r g b, extra bytes (hex).
std::string las_text(const PointCloud& c) {
  std::string out;
  const LasAttributes& a = c.las;
  char buf[64];
  for (std::size_t i = 0; i < c.size(); ++i) {
    if (a.carried() == kLasClassification) {  // a classification map (version 4)
      out += std::to_string(a.classification[i]) + "\n";
      continue;
    }
    std::uint64_t g = 0;
    if (!a.gps_time.empty()) std::memcpy(&g, &a.gps_time[i], 8);
    std::snprintf(buf, sizeof buf, "%u %u %u %u %u %d %u %u %016llx %u %u %u %u ", a.classification[i],
                  a.class_flags[i], a.return_number[i], a.number_of_returns[i], a.scan_flags[i], a.scan_angle[i],
                  a.user_data[i], a.point_source_id[i], static_cast<unsigned long long>(g), a.nir[i],
                  a.color_low[i].r, a.color_low[i].g, a.color_low[i].b);
    out += buf;
    for (std::uint32_t j = 0; j < a.extra_bytes_size; ++j) {
      std::snprintf(buf, sizeof buf, "%02x", a.extra_bytes[i * a.extra_bytes_size + j]);
      out += buf;
    }
    out += '\n';
  }
  return out;
}

std::vector<std::uint8_t> slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST_CASE("golden chunk blobs of format versions 1 to 17 decode (and the current ones re-encode) identically",
          "[golden]") {
  const bool regenerate = std::getenv("RELIEF_REGENERATE_GOLDEN") != nullptr;
  for (const Vector& v : vectors()) {
    INFO(v.name);
    const PointCloud in = v.make();
    auto blob = encode_chunk(in, v.params);
    REQUIRE(blob.is_ok());
    const std::string blob_path = vector_path(v.name, ".rlfc");
    const std::string ply_path = vector_path(v.name, ".decoded.ply");
    if (regenerate && !v.frozen) {
      std::ofstream(blob_path, std::ios::binary)
          .write(reinterpret_cast<const char*>(blob->data()), static_cast<std::streamsize>(blob->size()));
      auto decoded = decode_chunk(*blob);
      REQUIRE(decoded.is_ok());
      REQUIRE(write_ply(ply_path, *decoded, {PlyEncoding::kAscii, PlyCoordinateType::kFloat64}).is_ok());
      if (has_las(v.make)) {
        std::ofstream(vector_path(v.name, ".decoded.las.txt"), std::ios::binary) << las_text(*decoded);
      }
    }
    const std::vector<std::uint8_t> golden = slurp(blob_path);
    REQUIRE(!golden.empty());
    auto info = inspect_chunk(golden);
    REQUIRE(info.is_ok());
    CHECK(info->format_version == v.version);
    // The geometry's codec: 9 (time order) for the scan, the octree for the others.
    for (const ChunkSectionInfo& s : info->sections) {
      if (s.id == 7 && v.version >= 8) {
        CHECK(s.codec == (is_scan(v.make) || keeps_order(v.params) ? 9
                          : v.version >= 17                        ? 14
                          : v.version >= 16                        ? 13
                          : v.version >= 13                        ? 12
                          : v.version >= 10                        ? 11
                                                                   : 8));
      }
      // Format 9: colours in cell order (every octree layer) are predicted from neighbours.
      if (s.id == 8 && v.version >= 9 && !is_scan(v.make) && !keeps_order(v.params)) CHECK(s.codec == 10);
    }
    // Encoder stability: the same input and parameters give the same bytes.
    if (!v.frozen) CHECK(*blob == golden);
    // Decoder stability: the golden blob means the same points as when it was made.
    auto decoded = decode_chunk(golden);
    REQUIRE(decoded.is_ok());
    auto expected = read_ply(ply_path);
    REQUIRE(expected.is_ok());
    REQUIRE(decoded->size() == expected->size());
    REQUIRE(decoded->has_colors() == expected->has_colors());
    REQUIRE(decoded->has_intensity() == expected->has_intensity());
    double worst = 0;
    for (std::size_t i = 0; i < decoded->size(); ++i) {
      const Vec3d a = decoded->positions[i], b = expected->positions[i];
      worst = std::max({worst, std::abs(a.x - b.x), std::abs(a.y - b.y), std::abs(a.z - b.z)});
    }
    CHECK(worst < 1e-9);
    if (keeps_order(v.params)) {
      // Point i is input point i, within half a step, with its own colour.
      const Vec3d step = v.params.bound->step;
      const auto within = [](double a, double b, double s) { return std::abs(a - b) <= s * 0.5 * (1 + 1e-9); };
      bool in_order = decoded->size() == in.size();
      for (std::size_t i = 0; in_order && i < in.size(); ++i) {
        const Vec3d a = decoded->positions[i], b = in.positions[i];
        in_order = within(a.x, b.x, step.x) && within(a.y, b.y, step.y) && within(a.z, b.z, step.z) &&
                   (!in.has_colors() || decoded->colors[i] == in.colors[i]);
      }
      CHECK(in_order);
    }
    if (decoded->has_colors()) CHECK(decoded->colors == expected->colors);
    if (decoded->has_intensity()) CHECK(decoded->intensities == expected->intensities);
    if (has_las(v.make)) {
      // Bounded blobs keep every LAS attribute; resampled ones the classification.
      REQUIRE(decoded->las.carried() == (!v.params.bound              ? kLasClassification
                                         : v.make == las_scene_untimed ? (0xFFFu & ~kLasGpsTime)
                                                                       : 0xFFFu));
      const std::vector<std::uint8_t> text = slurp(vector_path(v.name, ".decoded.las.txt"));
      CHECK(las_text(*decoded) == std::string(text.begin(), text.end()));
      if (v.make == las_scene_8bit) CHECK(decoded->las.color_low == decoded->colors);
    } else {
      CHECK(decoded->las.empty());
    }
  }
}

TEST_CASE("every golden blob decodes any attribute subset to the full decode's attributes", "[golden][attributes]") {
  // Each attribute alone, none, and pairs whose sections depend on each
  // other: what DecodeOptions::attributes skips must not change what it keeps.
  std::vector<AttributeSet> sets = {AttributeSet::none(), {true, false, 0}, {false, true, 0},
                                    {true, true, kLasNumberOfReturns | kLasExtraBytes}};
  for (std::uint32_t i = 0; i < kLasAttributeCount; ++i) sets.push_back({false, false, 1u << i});
  for (const Vector& v : vectors()) {
    INFO(v.name);
    const std::vector<std::uint8_t> golden = slurp(vector_path(v.name, ".rlfc"));
    REQUIRE(!golden.empty());
    for (const std::uint32_t lod : {1u, 16u}) {
      DecodeOptions all;
      all.lod = lod;
      auto full = decode_chunk(golden, all);
      REQUIRE(full.is_ok());
      for (const AttributeSet& set : sets) {
        INFO("lod " << lod << ", attributes '" << attribute_set_list(set) << "'");
        DecodeOptions some = all;
        some.attributes = set;
        auto part = decode_chunk(golden, some);
        REQUIRE(part.is_ok());
        PointCloud want = *full;
        keep_attributes(want, set);
        REQUIRE(part->size() == want.size());
        CHECK(part->positions == want.positions);
        CHECK(part->colors == want.colors);
        CHECK(part->intensities == want.intensities);
        CHECK(part->las.carried() == want.las.carried());
        bool same = true;
        LasAttributes::for_each_vector_pair(part->las, want.las,
                                            [&](const auto& a, const auto& b, std::uint32_t) { same = same && a == b; });
        CHECK(same);
        CHECK(part->las.extra_bytes == want.las.extra_bytes);
      }
    }
  }
}
