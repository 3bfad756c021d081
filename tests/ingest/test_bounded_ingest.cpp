// The error-bounded mode end to end: every input point back within the
// tolerance, LAS integers exact, and archives that depend only on the set of
// input points and the parameters (not on --memory, --threads or point order).
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <map>
#include <string_view>
#include <tuple>

#include "relief/archive.h"
#include "relief/codec.h"
#include "relief/ingest.h"
#include "relief/io.h"
#include "support/decode_archive.h"
#include "support/dense_surface.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"

using namespace relief;
using relief::test::TempDir;

namespace {

PointCloud scene(std::uint64_t seed, std::size_t points) {
  test::SceneOptions o;
  o.seed = seed;
  o.points = points / 2;
  o.colors = true;
  o.intensity = true;
  o.noise = 0.003;
  PointCloud a = test::make_room(o, 8.0);
  o.seed = seed + 1;
  PointCloud b = test::make_terrain(o, 8.0, 0.4);
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  a.colors.insert(a.colors.end(), b.colors.begin(), b.colors.end());
  a.intensities.insert(a.intensities.end(), b.intensities.begin(), b.intensities.end());
  return a;
}

PointCloud shuffled(const PointCloud& in, std::uint64_t seed) {
  std::vector<std::size_t> perm(in.size());
  for (std::size_t i = 0; i < perm.size(); ++i) perm[i] = i;
  test::Rng rng(seed);
  for (std::size_t i = perm.size() - 1; i > 0; --i) std::swap(perm[i], perm[rng.next() % (i + 1)]);
  PointCloud out;
  for (std::size_t i : perm) {
    out.positions.push_back(in.positions[i]);
    if (in.has_colors()) out.colors.push_back(in.colors[i]);
    if (in.has_intensity()) out.intensities.push_back(in.intensities[i]);
  }
  return out;
}

PointCloud decode_all(const std::string& path) { return test::decode_archive(path); }

// XYZ text with colour and intensity: no point count in a header, so the
// ingest takes the external sort (bucket files) whatever the budget.
void write_xyz(const std::string& path, const PointCloud& c) {
  WriterOptions w;
  w.colors = true;
  w.intensity = true;
  auto writer = open_point_writer(path, w);
  REQUIRE(writer.is_ok());
  REQUIRE((*writer)->write(c).is_ok());
  REQUIRE((*writer)->finish().is_ok());
}

}  // namespace

TEST_CASE("bounded compress: every point back within the tolerance, attributes exact", "[ingest][bounded]") {
  TempDir dir;
  const PointCloud in = scene(3, 60000);
  REQUIRE(write_ply(dir.file("in.ply"), in).is_ok());
  IngestOptions o;
  o.tolerance = 0.002;
  o.threads = 2;
  auto r = compress_files({dir.file("in.ply")}, dir.file("a.relief"), o);
  REQUIRE(r.is_ok());
  CHECK(r->points_read == in.size());
  CHECK(r->points_decoded == in.size());
  const PointCloud out = decode_all(dir.file("a.relief"));
  REQUIRE(out.size() == in.size());
  // Snap the input the way the codec does and compare the multisets exactly.
  using Rec = std::tuple<double, double, double, int, int, int, float>;
  std::vector<Rec> want, got;
  double worst = 0;
  for (std::size_t i = 0; i < in.size(); ++i) {
    const Vec3d& p = in.positions[i];
    const auto snap = [](double v) { return static_cast<double>(std::llround(v / 0.004)) * 0.004; };
    const Vec3d q{snap(p.x), snap(p.y), snap(p.z)};
    worst = std::max({worst, std::fabs(q.x - p.x), std::fabs(q.y - p.y), std::fabs(q.z - p.z)});
    want.emplace_back(q.x, q.y, q.z, in.colors[i].r, in.colors[i].g, in.colors[i].b, in.intensities[i]);
  }
  for (std::size_t i = 0; i < out.size(); ++i) {
    const Vec3d& p = out.positions[i];
    got.emplace_back(p.x, p.y, p.z, out.colors[i].r, out.colors[i].g, out.colors[i].b, out.intensities[i]);
  }
  std::sort(want.begin(), want.end());
  std::sort(got.begin(), got.end());
  CHECK(worst <= 0.002 * (1 + 1e-9));
  CHECK(want == got);
  // A tolerance beyond 2^49 (a step beyond 2^50, as a cell) is refused before anything is
  // written: 8.9e307 overflowed the chunk keys.
  o.tolerance = 8.9e307;
  const auto huge = compress_files({dir.file("in.ply")}, dir.file("huge.relief"), o);
  CHECK(huge.status().code() == StatusCode::kInvalidArgument);
  CHECK_THAT(huge.status().message(), Catch::Contains("tolerance must be a positive number up to 2^49"));
  CHECK_FALSE(std::filesystem::exists(dir.file("huge.relief")));
}

TEST_CASE(
    "a tolerance that caps the chunk edge is named as the cause, a given edge beyond it refused up front",
    "[ingest][bounded]") {
  // A chunk spans at most 2^21 grid steps: at a 1e-6 tolerance, 4.19 units.
  // The density hint said "a larger --chunk-edge", which then failed after a
  // whole pass with "the points span 47746369 quantisation steps".
  TempDir dir;
  PointCloud sparse;
  std::uint64_t state = 5;
  for (int i = 0; i < 20000; ++i) {
    double c[3];
    for (double& v : c) {
      state = state * 6364136223846793005ull + 1442695040888963407ull;
      v = static_cast<double>(state >> 11) / 9007199254740992.0 * 1000;
    }
    sparse.positions.push_back({c[0], c[1], c[2]});
  }
  REQUIRE(write_ply(dir.file("sparse.ply"), sparse).is_ok());
  IngestOptions o;
  o.tolerance = 1e-6;
  const auto capped = compress_files({dir.file("sparse.ply")}, dir.file("a.relief"), o);
  CHECK(capped.status().code() == StatusCode::kLimitExceeded);
  CHECK_THAT(capped.status().message(), Catch::Contains("use a larger --tolerance"));
  o.chunk_edge = 100;
  const auto given = compress_files({dir.file("sparse.ply")}, dir.file("a.relief"), o);
  CHECK(given.status().code() == StatusCode::kInvalidArgument);
  CHECK_THAT(given.status().message(),
             Catch::Contains("use a chunk edge up to 4.194296 or a larger --tolerance"));
  CHECK_FALSE(std::filesystem::exists(dir.file("a.relief")));
}

TEST_CASE("bounded compress: the same blobs whatever --memory, --threads and point order", "[ingest][bounded]") {
  TempDir dir;
  const PointCloud in = scene(8, 120000);
  REQUIRE(write_ply(dir.file("in.ply"), in).is_ok());
  // The shuffled copy as XYZ text: no point count in a header, so the ingest
  // takes the external sort (bucket files) whatever the budget.
  write_xyz(dir.file("shuffled.xyz"), shuffled(in, 77));
  IngestOptions o;
  o.threads = 1;
  o.split_points = 20000;  // some chunks split into octants
  auto a = compress_files({dir.file("in.ply")}, dir.file("a.relief"), o);
  REQUIRE(a.is_ok());
  IngestOptions small = o;
  small.threads = 2;
  small.memory_budget = 64u << 20;
  small.reader.xyz_columns = "x,y,z,r,g,b,i";
  auto b = compress_files({dir.file("shuffled.xyz")}, dir.file("b.relief"), small);
  REQUIRE(b.is_ok());
  CHECK(a->cell_size == b->cell_size);
  CHECK(a->chunk_edge == b->chunk_edge);
  const auto ba = test::archive_blobs(dir.file("a.relief"));
  const auto bb = test::archive_blobs(dir.file("b.relief"));
  CHECK(ba.size() > 8);
  CHECK(ba == bb);
  // Parts of split chunks are each below the split size.
  auto archive = Archive::open(dir.file("a.relief"), Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto refs = (*archive)->all_chunks();
  REQUIRE(refs.is_ok());
  for (const ChunkRef& ref : *refs) CHECK(ref.input_points <= 20000);
}

TEST_CASE("bounded compress: a chunk larger than the budget's slices is read in loads, with the same blobs",
          "[ingest][bounded][split]") {
  TempDir dir;
  // 800 k points on a 2 x 2 m surface, all in one 4 m chunk. As XYZ text (no
  // count in a header: the external sort) at the 64 MiB budget, a slice holds
  // ~286 k points (64 MiB / 6 over 39 bytes a point), so the chunk's bucket
  // is more than the two slices may hold and is routed to loads of whole
  // octant parts (ingest/bucket_split.h) instead of being read whole. The
  // PLY at 1 GiB is split in memory.
  const PointCloud dense = test::dense_surface(800000, 4, true);
  REQUIRE(write_ply(dir.file("in.ply"), dense).is_ok());
  {
    auto writer = open_point_writer(dir.file("dense.xyz"), WriterOptions{});
    REQUIRE(writer.is_ok());
    REQUIRE((*writer)->write(shuffled(dense, 5)).is_ok());
    REQUIRE((*writer)->finish().is_ok());
  }
  IngestOptions o;
  o.tolerance = 0.001;
  o.chunk_edge = 4;
  o.split_points = 1u << 16;  // parts at several depths
  o.threads = 2;
  REQUIRE(compress_files({dir.file("in.ply")}, dir.file("a.relief"), o).is_ok());
  IngestOptions small = o;
  small.memory_budget = 64u << 20;
  auto b = compress_files({dir.file("dense.xyz")}, dir.file("b.relief"), small);
  INFO((b ? std::string() : b.status().to_string()));
  REQUIRE(b.is_ok());
  CHECK(b->points_read == 800000);
  const auto blobs = test::archive_blobs(dir.file("a.relief"));
  CHECK(blobs.size() > 12);
  CHECK(blobs == test::archive_blobs(dir.file("b.relief")));
  auto archive = Archive::open(dir.file("b.relief"), Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto refs = (*archive)->all_chunks();
  REQUIRE(refs.is_ok());
  std::uint64_t points = 0;
  for (const ChunkRef& ref : *refs) {
    CHECK(ref.input_points <= (1u << 16));
    points += ref.input_points;
  }
  CHECK(points == 800000);
}

TEST_CASE("compress: small inputs get small pages, and every chunk's base layer serves lod 16", "[ingest][bounded]") {
  CHECK(ingest_page_size(0) == kSmallArchivePageSize);
  CHECK(ingest_page_size(kSmallArchiveMaxPoints) == kSmallArchivePageSize);
  CHECK(ingest_page_size(kSmallArchiveMaxPoints + 1) == kArchivePageSize);
  CHECK(ingest_page_size(kMediumArchiveMaxPoints) == kArchivePageSize);
  CHECK(ingest_page_size(kMediumArchiveMaxPoints + 1) == kLargeArchivePageSize);
  TempDir dir;
  const PointCloud in = scene(5, 40000);
  REQUIRE(write_ply(dir.file("in.ply"), in).is_ok());
  IngestOptions o;
  o.tolerance = 0.002;
  o.threads = 1;
  REQUIRE(compress_files({dir.file("in.ply")}, dir.file("a.relief"), o).is_ok());
  // The SQLite header: the page size, big-endian, at offset 16.
  std::ifstream f(dir.file("a.relief"), std::ios::binary);
  std::array<unsigned char, 18> header{};
  REQUIRE(f.read(reinterpret_cast<char*>(header.data()), header.size()));
  CHECK(((header[16] << 8) | header[17]) == static_cast<int>(kSmallArchivePageSize));
  auto archive = Archive::open(dir.file("a.relief"), Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto refs = (*archive)->all_chunks();
  REQUIRE(refs.is_ok());
  REQUIRE(!refs->empty());
  for (const ChunkRef& ref : *refs) {
    auto row = (*archive)->read_chunk(ref.id);
    REQUIRE(row.is_ok());
    auto info = inspect_chunk(row->blob);
    REQUIRE(info.is_ok());
    CHECK(2 * info->base_points >= (ref.input_points + kBaseLayerLod - 1) / kBaseLayerLod);
    // Not much more either: about 24 points per map pixel is the aim
    // (the cell snaps to the chunk's power-of-two grid, so within a factor 4).
    CHECK(info->base_points * 4 <= ref.input_points);
  }
}

TEST_CASE("compress: a small compact input is one chunk, a scattered one keeps the default edge", "[ingest][bounded]") {
  TempDir dir;
  // A long strip (24 x 1.5 m): the default edge (32 density cells) is shorter.
  test::SceneOptions so;
  so.seed = 9;
  so.points = 5000;
  PointCloud strip = test::make_terrain(so, 1.5, 0.2);
  for (int k = 1; k < 16; ++k) {
    so.seed = 9 + static_cast<std::uint64_t>(k);
    const PointCloud tile = test::make_terrain(so, 1.5, 0.2);
    for (const Vec3d& p : tile.positions) strip.positions.push_back({p.x + 1.5 * k, p.y, p.z});
  }
  REQUIRE(write_ply(dir.file("strip.ply"), strip).is_ok());
  IngestOptions o;
  o.tolerance = 0.002;
  o.threads = 1;
  auto one = compress_files({dir.file("strip.ply")}, dir.file("one.relief"), o);
  REQUIRE(one.is_ok());
  CHECK(one->chunks_written == 1);
  // The same strip given a chunk edge of a quarter of that: several chunks,
  // so the automatic edge did grow.
  IngestOptions quarter = o;
  quarter.chunk_edge = one->chunk_edge / 4;
  auto several = compress_files({dir.file("strip.ply")}, dir.file("several.relief"), quarter);
  REQUIRE(several.is_ok());
  CHECK(several->chunks_written > 1);
  // Two copies far apart (100 strips' length): scattered, not one chunk.
  PointCloud apart = strip;
  for (const Vec3d& p : strip.positions) apart.positions.push_back({p.x + 2400, p.y, p.z});
  REQUIRE(write_ply(dir.file("apart.ply"), apart).is_ok());
  auto two = compress_files({dir.file("apart.ply")}, dir.file("apart.relief"), o);
  REQUIRE(two.is_ok());
  CHECK(two->chunks_written > 1);
  CHECK(two->chunk_edge < one->chunk_edge);
}

TEST_CASE("bounded compress: LAS input comes back as the same LAS integers", "[ingest][bounded]") {
  TempDir dir;
  test::Rng rng(5);
  PointCloud in;
  const Vec3d offset{431000.0, 5200000.0, 10.0};
  for (int i = 0; i < 40000; ++i) {
    const double X = std::floor(rng.uniform(0, 30000)), Y = std::floor(rng.uniform(0, 30000)),
                 Z = std::floor(rng.uniform(0, 500));
    in.positions.push_back({X * 0.01 + offset.x, Y * 0.01 + offset.y, Z * 0.01 + offset.z});
    in.intensities.push_back(static_cast<float>(rng.next() % 65536));
  }
  WriterOptions w;
  w.intensity = true;
  w.grid_scale = Vec3d{0.01, 0.01, 0.01};
  w.grid_offset = offset;
  {
    auto writer = open_point_writer(dir.file("in.las"), w);
    REQUIRE(writer.is_ok());
    REQUIRE((*writer)->write(in).is_ok());
    REQUIRE((*writer)->finish().is_ok());
  }
  IngestOptions o;  // automatic tolerance: half the LAS scale
  auto r = compress_files({dir.file("in.las")}, dir.file("a.relief"), o);
  REQUIRE(r.is_ok());
  auto archive = Archive::open(dir.file("a.relief"), Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto info = (*archive)->info();
  REQUIRE(info.is_ok());
  auto params = encode_params_from_string(info->codec_params);
  REQUIRE(params.is_ok());
  REQUIRE(params->bound.has_value());
  CHECK(params->bound->step.x == 0.01);
  CHECK(params->bound->origin.x == offset.x);
  const PointCloud out = decode_all(dir.file("a.relief"));
  REQUIRE(out.size() == in.size());
  // The archive's bounds are its points' own, exactly: the input's, since
  // they are the same LAS integers (the base layer's overhang is in the
  // bounds of what any level of detail returns only).
  CHECK(info->point_bounds.min == out.bounds().min);
  CHECK(info->point_bounds.max == out.bounds().max);
  CHECK(info->point_bounds.min == in.bounds().min);
  CHECK(info->point_bounds.max == in.bounds().max);
  CHECK(info->bounds.contains(info->point_bounds));
  // (Here the base layer does reach beyond the points: the test shows the difference.)
  CHECK_FALSE((info->bounds.min == info->point_bounds.min && info->bounds.max == info->point_bounds.max));
  const auto ints = [&](const PointCloud& c) {
    std::vector<std::array<long long, 4>> v;
    for (std::size_t i = 0; i < c.size(); ++i) {
      const Vec3d& p = c.positions[i];
      v.push_back({std::llround((p.x - offset.x) / 0.01), std::llround((p.y - offset.y) / 0.01),
                   std::llround((p.z - offset.z) / 0.01), static_cast<long long>(c.intensities[i])});
    }
    std::sort(v.begin(), v.end());
    return v;
  };
  CHECK(ints(out) == ints(in));
  // And through a LAS writer with the archive's grid, the file's integers.
  WriterOptions back = w;
  back.grid_scale = params->bound->step;
  back.grid_offset = params->bound->origin;
  back.las_attributes = out.las.carried();  // what the archive gives every point
  auto writer = open_point_writer(dir.file("out.las"), back);
  REQUIRE(writer.is_ok());
  REQUIRE((*writer)->write(out).is_ok());
  REQUIRE((*writer)->finish().is_ok());
  auto reread = read_point_file(dir.file("out.las"));
  REQUIRE(reread.is_ok());
  CHECK(ints(*reread) == ints(in));
}

TEST_CASE("append of a LAS file off the archive's grid says its integers will not come back",
          "[ingest][bounded]") {
  TempDir dir;
  test::Rng rng(9);
  const auto las = [&](const std::string& name, double scale, double offset) {
    PointCloud c;
    for (int i = 0; i < 2000; ++i) {
      c.positions.push_back({offset + std::floor(rng.uniform(0, 1000)) * scale,
                             offset + std::floor(rng.uniform(0, 1000)) * scale,
                             std::floor(rng.uniform(0, 100)) * scale});
    }
    WriterOptions w;
    w.grid_scale = Vec3d{scale, scale, scale};
    w.grid_offset = Vec3d{offset, offset, 0};
    w.grid_offset_exact = true;
    auto writer = open_point_writer(dir.file(name), w);
    REQUIRE(writer.is_ok());
    REQUIRE((*writer)->write(c).is_ok());
    REQUIRE((*writer)->finish().is_ok());
  };
  las("cm.las", 0.01, 1000);
  las("cm_again.las", 0.01, 1000);
  las("cm_shifted.las", 0.02, 1000.01);  // a scale of two steps: on the grid
  las("mm.las", 0.001, 1000);            // a finer scale
  las("half.las", 0.01, 1000.005);       // an offset between two steps
  REQUIRE(compress_files({dir.file("cm.las")}, dir.file("a.relief"), IngestOptions{}).is_ok());
  const auto warned = [&](const std::string& name) {
    auto r = append_files(dir.file("a.relief"), {dir.file(name)}, IngestOptions{});
    REQUIRE(r.is_ok());
    return std::any_of(r->warnings.begin(), r->warnings.end(), [&](const std::string& w) {
      return w.find(dir.file(name) + ": its LAS grid") != std::string::npos &&
             w.find("not as its own integers") != std::string::npos;
    });
  };
  CHECK_FALSE(warned("cm_again.las"));
  CHECK_FALSE(warned("cm_shifted.las"));
  CHECK(warned("mm.las"));
  CHECK(warned("half.las"));
}

TEST_CASE("bounded compress of an organised PCD: no-depth pixels skipped, fields kept, the blobs of the same PLY",
          "[ingest][bounded][extra]") {
  TempDir dir;
  // A 160 x 120 depth image: every 7th pixel has no depth (NaN), the others
  // carry a packed colour, a normal component and a label.
  const int w = 160, h = 120;
  std::string pcd = "VERSION 0.7\nFIELDS x y z rgb normal_x label\nSIZE 4 4 4 4 4 4\nTYPE F F F U F U\n"
                    "COUNT 1 1 1 1 1 1\nWIDTH " + std::to_string(w) + "\nHEIGHT " + std::to_string(h) +
                    "\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + std::to_string(w * h) + "\nDATA binary\n";
  std::string ply_body;
  int kept = 0;
  auto put = [](std::string& out, const auto& v) { out.append(reinterpret_cast<const char*>(&v), sizeof(v)); };
  for (int i = 0; i < w * h; ++i) {
    const bool hole = i % 7 == 3;
    const float x = hole ? std::nanf("") : 0.01f * static_cast<float>(i % w);
    const float y = 0.01f * static_cast<float>(i / w);
    const float z = 1.0f + 0.002f * static_cast<float>((i * 37) % 11);
    const std::uint32_t rgb = (static_cast<std::uint32_t>(i % 251) << 16) | (static_cast<std::uint32_t>(i % 13) << 8) | 7u;
    const float nx = static_cast<float>(i % 101) / 100.0f;
    const std::uint32_t label = static_cast<std::uint32_t>(i) * 2654435761u;
    put(pcd, x), put(pcd, y), put(pcd, z), put(pcd, rgb), put(pcd, nx), put(pcd, label);
    if (hole) continue;
    ++kept;
    put(ply_body, x), put(ply_body, y), put(ply_body, z);
    const std::uint8_t c[3] = {static_cast<std::uint8_t>(rgb >> 16), static_cast<std::uint8_t>(rgb >> 8),
                               static_cast<std::uint8_t>(rgb)};
    ply_body.append(reinterpret_cast<const char*>(c), 3);
    put(ply_body, nx), put(ply_body, label);
  }
  const std::string ply = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(kept) +
                          "\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\n"
                          "property uchar green\nproperty uchar blue\nproperty float normal_x\nproperty uint label\n"
                          "end_header\n" + ply_body;
  std::ofstream(dir.file("depth.pcd"), std::ios::binary) << pcd;
  std::ofstream(dir.file("same.ply"), std::ios::binary) << ply;

  IngestOptions o;
  o.tolerance = 0.0005;
  auto a = compress_files({dir.file("depth.pcd")}, dir.file("pcd.relief"), o);
  REQUIRE(a.is_ok());
  CHECK(a->points_read == static_cast<std::uint64_t>(kept));
  auto b = compress_files({dir.file("same.ply")}, dir.file("ply.relief"), o);
  REQUIRE(b.is_ok());
  // The values, not the file they came from, make the blobs.
  CHECK(test::archive_blobs(dir.file("pcd.relief")) == test::archive_blobs(dir.file("ply.relief")));

  // Every kept pixel comes back once, with its colour and fields exactly.
  auto source = read_point_file(dir.file("same.ply"));
  REQUIRE(source.is_ok());
  REQUIRE(source->las.extra_bytes_size == 8);
  const PointCloud out = decode_all(dir.file("pcd.relief"));
  REQUIRE(out.size() == source->size());
  REQUIRE(out.las.extra_bytes.size() == 8 * out.size());
  using Key = std::tuple<std::uint64_t, std::uint8_t, std::uint8_t, std::uint8_t>;  // fields, colour
  auto keyed = [](const PointCloud& c) {
    std::vector<std::pair<Key, Vec3d>> v;
    for (std::size_t i = 0; i < c.size(); ++i) {
      std::uint64_t f = 0;
      std::memcpy(&f, c.las.extra_bytes.data() + 8 * i, 8);
      v.push_back({{f, c.colors[i].r, c.colors[i].g, c.colors[i].b}, c.positions[i]});
    }
    std::sort(v.begin(), v.end(), [](const auto& p, const auto& q) { return p.first < q.first; });
    return v;
  };
  const auto want = keyed(*source);
  const auto got = keyed(out);
  double worst = 0;
  bool same_keys = true;
  for (std::size_t i = 0; i < want.size(); ++i) {
    same_keys = same_keys && want[i].first == got[i].first;
    worst = std::max({worst, std::abs(want[i].second.x - got[i].second.x), std::abs(want[i].second.y - got[i].second.y),
                      std::abs(want[i].second.z - got[i].second.z)});
  }
  CHECK(same_keys);
  CHECK(worst <= 0.0005 * (1 + 1e-9));
}

TEST_CASE("bounded compress --keep-order: each chunk gives its points back in input order, whatever --memory",
          "[ingest][bounded]") {
  TempDir dir;
  PointCloud in = scene(12, 60000);
  // Each point's intensity is its input index (exact as a float).
  for (std::size_t i = 0; i < in.size(); ++i) in.intensities[i] = static_cast<float>(i);
  REQUIRE(write_ply(dir.file("in.ply"), in).is_ok());
  write_xyz(dir.file("in.xyz"), in);
  IngestOptions o;
  o.tolerance = 0.002;
  o.threads = 2;
  o.split_points = 20000;
  o.keep_order = true;
  auto a = compress_files({dir.file("in.ply")}, dir.file("a.relief"), o);
  REQUIRE(a.is_ok());
  // Text input takes the external sort (bucket files): the same blobs.
  IngestOptions text = o;
  text.memory_budget = 64u << 20;
  text.reader.xyz_columns = "x,y,z,r,g,b,i";
  auto b = compress_files({dir.file("in.xyz")}, dir.file("b.relief"), text);
  REQUIRE(b.is_ok());
  const auto blobs = test::archive_blobs(dir.file("a.relief"));
  CHECK(blobs.size() > 4);
  CHECK(blobs == test::archive_blobs(dir.file("b.relief")));
  auto archive = Archive::open(dir.file("a.relief"), Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto info = (*archive)->info();
  REQUIRE(info.is_ok());
  CHECK(info->codec_params.find("order=input") != std::string::npos);
  // The points of each chunk are a run of increasing input indices, each
  // within the tolerance of its input point with its colour.
  const auto runs = [](const PointCloud& c) {
    std::size_t r = c.empty() ? 0 : 1;
    for (std::size_t i = 1; i < c.size(); ++i) r += c.intensities[i] < c.intensities[i - 1] ? 1 : 0;
    return r;
  };
  const PointCloud out = decode_all(dir.file("a.relief"));
  REQUIRE(out.size() == in.size());
  bool exact = true;
  for (std::size_t k = 0; k < out.size(); ++k) {
    const auto i = static_cast<std::size_t>(out.intensities[k]);
    const Vec3d p = out.positions[k], q = in.positions[i];
    exact = exact && std::fabs(p.x - q.x) <= 0.002 * (1 + 1e-9) && std::fabs(p.y - q.y) <= 0.002 * (1 + 1e-9) &&
            std::fabs(p.z - q.z) <= 0.002 * (1 + 1e-9) && out.colors[k] == in.colors[i];
  }
  CHECK(exact);
  CHECK(runs(out) <= blobs.size());
  // Without it the points come back in cell order.
  IngestOptions any = o;
  any.keep_order = false;
  REQUIRE(compress_files({dir.file("in.ply")}, dir.file("c.relief"), any).is_ok());
  CHECK(runs(decode_all(dir.file("c.relief"))) > 100 * blobs.size());
}

TEST_CASE(
    "bounded compress --fast-geometry: octree chunks in format 13 (codec 12), appends follow the archive",
    "[ingest][bounded]") {
  TempDir dir;
  const PointCloud in = scene(14, 20000);
  REQUIRE(write_ply(dir.file("in.ply"), in).is_ok());
  IngestOptions o;
  o.tolerance = 0.002;
  o.threads = 2;
  IngestOptions fast = o;
  fast.fast_geometry = true;
  REQUIRE(compress_files({dir.file("in.ply")}, dir.file("planes.relief"), o).is_ok());
  REQUIRE(compress_files({dir.file("in.ply")}, dir.file("fast.relief"), fast).is_ok());
  // The format of each chunk, and the points: the same either way.
  const auto versions = [&](const std::string& path) {
    std::map<int, std::size_t> out;
    for (const auto& [key, blob] : test::archive_blobs(path)) {
      auto info = inspect_chunk(blob);
      REQUIRE(info.is_ok());
      ++out[info->format_version];
      for (const ChunkSectionInfo& s : info->sections) {
        if (s.id == 7) CHECK(s.codec == (info->format_version == kOctreeNearestFormatVersion ? 14 : 12));
      }
    }
    return out;
  };
  CHECK(versions(dir.file("planes.relief")) ==
        std::map<int, std::size_t>{
            {kOctreeNearestFormatVersion, test::archive_blobs(dir.file("planes.relief")).size()}});
  CHECK(versions(dir.file("fast.relief")) ==
        std::map<int, std::size_t>{
            {kOrderFreeFormatVersion, test::archive_blobs(dir.file("fast.relief")).size()}});
  const auto sorted_records = [](const PointCloud& c) {
    std::vector<std::tuple<double, double, double, float>> r;
    for (std::size_t i = 0; i < c.size(); ++i) {
      r.emplace_back(c.positions[i].x, c.positions[i].y, c.positions[i].z, c.intensities[i]);
    }
    std::sort(r.begin(), r.end());
    return r;
  };
  CHECK(sorted_records(decode_all(dir.file("fast.relief"))) ==
        sorted_records(decode_all(dir.file("planes.relief"))));
  auto archive = Archive::open(dir.file("fast.relief"), Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto info = (*archive)->info();
  REQUIRE(info.is_ok());
  CHECK(info->codec_params.find("geometry=fast") != std::string::npos);
  archive->reset();
  // The archive without it keeps the parameter text of before (no key in
  // the stored, compact form; the full form says "planes").
  auto planes = Archive::open(dir.file("planes.relief"), Archive::Mode::kReadOnly);
  REQUIRE(planes.is_ok());
  CHECK((*planes)->info()->codec_params.find("geometry") == std::string::npos);
  planes->reset();
  // An append takes the archive's parameters: format 13 again.
  PointCloud more = scene(15, 5000);
  for (Vec3d& p : more.positions) p.x += 100;
  REQUIRE(write_ply(dir.file("more.ply"), more).is_ok());
  IngestOptions append;
  append.threads = 2;
  REQUIRE(append_files(dir.file("fast.relief"), {dir.file("more.ply")}, append).is_ok());
  const auto after = versions(dir.file("fast.relief"));
  CHECK(after.size() == 1);
  CHECK(after.begin()->first == kOrderFreeFormatVersion);
}
