// The level-of-detail pyramid (format-spec/archive.md §9): built by ingest,
// append and build_pyramid, read by coarse queries and max_points queries,
// deterministic, removed with its scan, ignored until finished, and its
// unused rows removed by a rebuild or by the next writer that opens alone.
#include <catch2/catch.hpp>
#include <sqlite3.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <set>
#include <tuple>

#include "relief/archive.h"
#include "relief/ingest.h"
#include "relief/io.h"
#include "relief/query.h"
#include "support/sanitized.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"

using namespace relief;
using relief::test::TempDir;

namespace {

constexpr double kSize = 32.0;

PointCloud terrain(std::uint64_t seed, std::size_t points, Vec3d offset = {0, 0, 0}) {
  test::SceneOptions o;
  o.seed = seed;
  o.points = points;
  o.colors = true;
  o.intensity = true;
  o.offset = offset;
  return test::make_terrain(o, kSize, 0.5);
}

IngestOptions options(PyramidMode pyramid) {
  IngestOptions o;
  o.codec.cell_size = 0.25;
  o.chunk_edge = 2.0;
  o.pyramid = pyramid;
  return o;
}

// A 32 x 32 m terrain in 2 m chunks: 256 chunks, so levels 1, 2, 3 (4, 8,
// 16 m nodes; the last has at most 8).
std::string build(const TempDir& tmp, const std::string& name, const PointCloud& cloud,
                  IngestOptions o = options(PyramidMode::kOn)) {
  REQUIRE(write_ply(tmp.file(name + ".ply"), cloud).is_ok());
  auto r = compress_files({tmp.file(name + ".ply")}, tmp.file(name + ".relief"), o);
  REQUIRE(r.is_ok());
  return tmp.file(name + ".relief");
}

PointCloud run_query(ArchiveReader& r, const Box3d* box, QueryStats* stats, const QueryOptions& o) {
  PointCloud all;
  const PointSink sink = [&](const PointCloud& b) {
    REQUIRE(b.colors.size() == b.size());
    REQUIRE(b.intensities.size() == b.size());
    all.positions.insert(all.positions.end(), b.positions.begin(), b.positions.end());
    all.intensities.insert(all.intensities.end(), b.intensities.begin(), b.intensities.end());
    return Status::ok();
  };
  auto s = box ? r.query(*box, o, sink) : r.query_all(o, sink);
  REQUIRE(s.is_ok());
  if (stats) *stats = *s;
  return all;
}

bool inside(const Vec3d& p, const Box3d& b) {
  return p.x >= b.min.x && p.x <= b.max.x && p.y >= b.min.y && p.y <= b.max.y && p.z >= b.min.z && p.z <= b.max.z;
}

// Level blobs by (level, key): what a pyramid holds.
std::map<std::tuple<int, std::int64_t, std::int64_t, std::int64_t>, std::vector<std::uint8_t>> level_blobs(
    const std::string& path) {
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  const double inf = std::numeric_limits<double>::infinity();
  std::map<std::tuple<int, std::int64_t, std::int64_t, std::int64_t>, std::vector<std::uint8_t>> out;
  for (int level = 1; level <= 8; ++level) {
    auto refs = (*archive)->find_level_chunks(level, Box3d{{-inf, -inf, -inf}, {inf, inf, inf}});
    REQUIRE(refs.is_ok());
    for (const ChunkRef& ref : *refs) {
      auto row = (*archive)->read_level_chunk(ref.id);
      REQUIRE(row.is_ok());
      out[{level, ref.key.ix, ref.key.iy, ref.key.iz}] = row->blob;
    }
  }
  return out;
}

// Rows of relief_level_chunk per scan, used or not, read behind the
// archive's back (its API returns only the rows readers use).
std::map<std::int64_t, std::int64_t> level_rows(const std::string& path) {
  sqlite3* db = nullptr;
  REQUIRE(sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READONLY, nullptr) == SQLITE_OK);
  sqlite3_stmt* stmt = nullptr;
  REQUIRE(sqlite3_prepare_v2(db, "SELECT scan_id, COUNT(*) FROM relief_level_chunk GROUP BY scan_id", -1, &stmt,
                             nullptr) == SQLITE_OK);
  std::map<std::int64_t, std::int64_t> out;
  while (sqlite3_step(stmt) == SQLITE_ROW) out[sqlite3_column_int64(stmt, 0)] = sqlite3_column_int64(stmt, 1);
  sqlite3_finalize(stmt);
  sqlite3_close(db);
  return out;
}

// Stores a copy of the scan's first chunk as a node of `level` at `key`
// without recording the pyramid: what a build killed after it leaves.
void put_stray_node(Archive& archive, std::int64_t scan_id, int level, ChunkKey key) {
  auto refs = archive.scan_chunks(scan_id);
  REQUIRE(refs.is_ok());
  REQUIRE_FALSE(refs->empty());
  auto row = archive.read_chunk(refs->front().id);
  REQUIRE(row.is_ok());
  row->ref.key = key;
  std::vector<ChunkRow> batch = {*row};
  REQUIRE(archive.put_level_chunks(level, batch).is_ok());
}

bool mentions_unused_rows(const ArchiveCheck& check) {
  return std::any_of(check.checked.begin(), check.checked.end(),
                     [](const std::string& line) { return line.find("no reader uses") != std::string::npos; });
}

}  // namespace

TEST_CASE("the pyramid's levels hold about a quarter of the points of the level below", "[pyramid]") {
  TempDir tmp;
  auto reader = ArchiveReader::open(build(tmp, "a", terrain(1, 300000)));
  REQUIRE(reader.is_ok());
  const ArchiveInfo& info = (*reader)->info();
  REQUIRE(info.pyramid.size() == 1);
  const ScanPyramid& p = info.pyramid[0];
  CHECK(p.base_points == 300000);
  CHECK(p.base_chunks == info.chunk_count);
  REQUIRE(p.levels.size() >= 2);
  std::uint64_t below = p.base_points, bytes = 0;
  int previous = 0;
  for (const PyramidLevel& l : p.levels) {
    INFO("level " << l.level << ": " << l.points << " points in " << l.chunks << " nodes");
    // A level is stored only when it keeps at most a third of the points
    // below; levels are numbered by node size (chunk edge * 2^level).
    CHECK(l.points * 3 <= below);
    CHECK(l.points > 0);
    CHECK(l.level > previous);
    below = l.points;
    previous = l.level;
    bytes += l.blob_bytes;
  }
  CHECK(p.levels.back().chunks <= 8);
  CHECK(p.levels.back().points <= 8192);
  CHECK(info.pyramid_bytes == bytes);
  CHECK(bytes * 10 < info.blob_bytes);

  TempDir tmp2;
  auto plain = ArchiveReader::open(build(tmp2, "b", terrain(1, 30000), options(PyramidMode::kAuto)));
  REQUIRE(plain.is_ok());
  REQUIRE((*plain)->info().pyramid.size() == 1);
  CHECK((*plain)->info().pyramid[0].levels.empty());  // auto: far below kPyramidAutoMinPoints
  CHECK((*plain)->info().pyramid_bytes == 0);
}

TEST_CASE("a coarse query reads the pyramid: far fewer bytes, about 1/L of the points, near the data", "[pyramid]") {
  TempDir tmp;
  const PointCloud cloud = terrain(2, 300000);
  auto reader = ArchiveReader::open(build(tmp, "a", cloud));
  REQUIRE(reader.is_ok());
  const Box3d box{{5.3, 7.1, -10}, {21.7, 19.9, 10}};
  std::size_t in_box = 0;
  for (const Vec3d& q : cloud.positions) in_box += inside(q, box) ? 1 : 0;

  QueryOptions full;
  QueryStats full_stats;
  run_query(**reader, &box, &full_stats, full);
  for (const std::uint32_t lod : {16u, 64u, 256u}) {
    QueryOptions o;
    o.lod = lod;
    QueryStats stats;
    const PointCloud got = run_query(**reader, &box, &stats, o);
    INFO("lod " << lod << ": " << got.size() << " points of " << in_box << ", level " << stats.pyramid_level
                << ", " << stats.blob_bytes_read << " of " << full_stats.blob_bytes_read << " bytes");
    CHECK(stats.pyramid_level >= 1);
    CHECK(stats.blob_bytes_read * 10 < full_stats.blob_bytes_read);
    const double want = static_cast<double>(in_box) / lod;
    CHECK(static_cast<double>(got.size()) > 0.4 * want);
    CHECK(static_cast<double>(got.size()) < 2.5 * want);
    // Every point inside the box and near the terrain: a resampled copy, a
    // plane per cell of 2-8 m here (levels 4-6), so on average within a few
    // centimetres, at worst within the terrain's slab.
    double sum = 0;
    for (const Vec3d& p : got.positions) {
      REQUIRE(inside(p, box));
      const double error = std::fabs(p.z - 0.5 * std::sin(p.x * 0.7) * std::cos(p.y * 0.5));
      REQUIRE(error < 0.6);  // within the terrain's slab (amplitude 0.5)
      sum += error;
    }
    CHECK(sum / static_cast<double>(got.size()) < 0.1);
    // Without the pyramid: the chunks' own levels of detail, every byte read.
    o.use_pyramid = false;
    QueryStats direct;
    run_query(**reader, &box, &direct, o);
    CHECK(direct.pyramid_level == 0);
    CHECK(direct.blob_bytes_read == full_stats.blob_bytes_read);
    CHECK(direct.lod_min == lod);
    CHECK(direct.lod_max == lod);
    CHECK_FALSE(direct.thinned);
  }
  // lod 1 never reads the pyramid.
  CHECK(full_stats.pyramid_level == 0);
  CHECK(full_stats.lod_min == 1);
  CHECK(full_stats.lod_max == 1);
}

TEST_CASE("max_points picks the finest level that fits and never exceeds the limit", "[pyramid]") {
  TempDir tmp;
  auto reader = ArchiveReader::open(build(tmp, "a", terrain(3, 300000)));
  REQUIRE(reader.is_ok());
  const ScanPyramid& p = (*reader)->info().pyramid.at(0);
  REQUIRE(p.levels.size() >= 2);
  const auto count = [&](std::uint64_t max_points, QueryStats& stats) {
    QueryOptions o;
    o.max_points = max_points;
    return run_query(**reader, nullptr, &stats, o).size();
  };
  QueryStats stats;
  // Everything fits: every point, from the chunks.
  CHECK(count(1'000'000, stats) == 300000);
  CHECK(stats.pyramid_level == 0);
  // Exactly a level fits; one point less: the same level thinned evenly to
  // the limit (within 4 times it); below a quarter of the level: the next
  // level when that one fits.
  for (std::size_t i = 0; i + 1 < p.levels.size(); ++i) {
    CAPTURE(i, p.levels[i].points, p.levels[i + 1].points);
    CHECK(count(p.levels[i].points, stats) == p.levels[i].points);
    CHECK(stats.pyramid_level == p.levels[i].level);
    CHECK(count(p.levels[i].points - 1, stats) == p.levels[i].points - 1);
    CHECK(stats.pyramid_level == p.levels[i].level);
    const std::uint64_t quarter = p.levels[i].points / 4 - 1;
    if (p.levels[i + 1].points <= quarter) {
      CHECK(count(quarter, stats) == p.levels[i + 1].points);
      CHECK(stats.pyramid_level == p.levels[i + 1].level);
    }
  }
  // Below the top level: the top's rows whole and thinned to the limit, or
  // each at a level of detail that leaves it about its share, then thinned:
  // the limit exactly, one point too.
  for (const std::uint64_t limit : {std::uint64_t{1}, std::uint64_t{100}, p.levels.back().points - 1}) {
    CAPTURE(limit);
    CHECK(count(limit, stats) == limit);
    CHECK(stats.pyramid_level == p.levels.back().level);
  }
  QueryOptions both;
  both.max_points = 10;
  both.lod = 4;
  const auto r = (*reader)->query_all(both, [](const PointCloud&) { return Status::ok(); });
  CHECK(r.status().code() == StatusCode::kInvalidArgument);
}

TEST_CASE("max_points in a small box counts the rows' points inside it", "[pyramid]") {
  // The rows' whole counts chose levels far coarser than the box needed and
  // thinned below the top to a few points, or none (10 asked, 1 given).
  TempDir tmp;
  auto reader = ArchiveReader::open(build(tmp, "a", terrain(4, 300000)));
  REQUIRE(reader.is_ok());
  const double inf = std::numeric_limits<double>::infinity();
  const Box3d box{{10.0, 10.0, -inf}, {14.0, 14.0, inf}};  // 1/64 of the area
  QueryStats stats;
  const std::size_t inside = run_query(**reader, &box, &stats, QueryOptions{}).size();
  REQUIRE(inside > 2000);
  for (const std::uint64_t limit :
       {std::uint64_t{1}, std::uint64_t{10}, std::uint64_t{100}, std::uint64_t{1000}}) {
    CAPTURE(limit);
    QueryOptions o;
    o.max_points = limit;
    const std::size_t got = run_query(**reader, &box, &stats, o).size();
    CHECK(got <= limit);
    CHECK(got * 16 >= limit);
  }
  QueryOptions all;
  all.max_points = inside;
  CHECK(run_query(**reader, &box, &stats, all).size() == inside);
  CHECK(stats.pyramid_level == 0);
}

// 40,000 points at `at(i, unit)` (unit() a uniform draw in [0, 1), seeded),
// one colour, intensity i % 1000: the max_points tests' clouds.
template <typename At>
PointCloud sampled_cloud(std::uint64_t seed, At at) {
  std::mt19937_64 random(seed);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  const auto unit = [&] { return uniform(random); };
  PointCloud cloud;
  for (int i = 0; i < 40000; ++i) {
    cloud.positions.push_back(at(i, unit));
    cloud.colors.push_back({100, 150, 200});
    cloud.intensities.push_back(static_cast<float>(i % 1000));
  }
  return cloud;
}

// `cloud` in 2 m chunks of 0.02 m cells, with or without its pyramid.
std::unique_ptr<ArchiveReader> open_fine(const TempDir& tmp, const PointCloud& cloud, PyramidMode mode) {
  IngestOptions io = options(mode);
  io.codec.cell_size = 0.02;
  io.allow_sparse = true;
  auto reader = ArchiveReader::open(build(tmp, mode == PyramidMode::kOn ? "on" : "off", cloud, io));
  REQUIRE(reader.is_ok());
  return std::move(*reader);
}

TEST_CASE("max_points thins every part of the box alike when the rows' bounds overstate their share of it",
          "[pyramid]") {
  // 8 x 8 m in 2 m chunks, points uniform in x and y and in z 0..1 but for
  // 2 % at z 1.9: the box (z up to 1) takes about half of each row's bounds,
  // so the estimate is about half its points. The level chosen held more
  // than the limit and was cut at it: the last chunks' corner of the box
  // came back empty.
  TempDir tmp;
  const PointCloud cloud = sampled_cloud(11, [](int i, const auto& unit) {
    const double x = 8 * unit(), y = 8 * unit();
    return Vec3d{x, y, i % 50 == 0 ? 1.9 : unit()};
  });
  const double inf = std::numeric_limits<double>::infinity();
  const Box3d box{{-inf, -inf, -1.0}, {inf, inf, 1.0}};
  for (const PyramidMode mode : {PyramidMode::kOff, PyramidMode::kOn}) {
    const std::unique_ptr<ArchiveReader> reader = open_fine(tmp, cloud, mode);
    const PointCloud all = run_query(*reader, &box, nullptr, QueryOptions{});
    REQUIRE(all.size() > 35000);
    // Points by 2 x 2 m cell (a chunk's area) and by quadrant of the box.
    const auto cells = [](const PointCloud& c) {
      std::map<std::pair<int, int>, double> out;
      for (const Vec3d& p : c.positions)
        out[{std::clamp(int(p.x / 2), 0, 3), std::clamp(int(p.y / 2), 0, 3)}] += 1;
      return out;
    };
    const auto quadrants = [](const PointCloud& c) {
      std::map<std::pair<int, int>, double> out;
      for (const Vec3d& p : c.positions) out[{p.x < 4 ? 0 : 1, p.y < 4 ? 0 : 1}] += 1;
      return out;
    };
    const auto in_cells = cells(all), in_quadrants = quadrants(all);
    REQUIRE(in_cells.size() == 16);
    // Just below the count (the finest level fits by its estimate), and far
    // below it (thinned below the top level, or the chunks without pyramid).
    for (const double fraction : {0.9, 0.2, 0.01}) {
      CAPTURE(mode, fraction);
      QueryOptions o;
      o.max_points = static_cast<std::uint64_t>(fraction * static_cast<double>(all.size()));
      QueryStats stats;
      const PointCloud got = run_query(*reader, &box, &stats, o);
      CHECK(got.size() <= o.max_points);
      // (A pyramid level may hold far fewer: levels differ by a factor.)
      if (stats.pyramid_level == 0) CHECK(got.size() * 2 >= o.max_points);
      const double rate = static_cast<double>(got.size()) / static_cast<double>(all.size());
      const auto got_quadrants = quadrants(got);
      for (const auto& [q, n] : in_quadrants) {
        CAPTURE(q.first, q.second, n);
        const auto it = got_quadrants.find(q);
        const double kept = it == got_quadrants.end() ? 0.0 : it->second;
        CHECK(kept >= 0.8 * rate * n);
        CHECK(kept <= 1.2 * rate * n);
      }
      if (fraction > 0.5) {
        const auto got_cells = cells(got);
        for (const auto& [c, n] : in_cells) {
          CAPTURE(c.first, c.second, n);
          const auto it = got_cells.find(c);
          const double kept = it == got_cells.end() ? 0.0 : it->second;
          CHECK(kept >= 0.8 * rate * n);
        }
      }
      // The same points whatever the threads.
      for (const unsigned threads : {1u, 3u}) {
        o.threads = threads;
        const PointCloud again = run_query(*reader, &box, nullptr, o);
        CHECK(again.positions == got.positions);
      }
    }
  }
}

TEST_CASE("max_points near the box's count reads the points themselves, and a small limit is met too",
          "[pyramid]") {
  // 8 x 8 m in 2 m chunks; in every chunk 40 % of the points lie in its
  // first 0.2 m along x, the rest uniform, so a box from 0.3 to 1.9 m along
  // x overstates the chunks' share of it (0.8 of their bounds, 0.48 of their
  // points). A limit at or just below the box's count was met from a
  // coarser level or the base layer's level of detail: a fraction of the
  // points, not the points (LAS attributes zero); a limit of 1 came back
  // empty.
  TempDir tmp;
  const PointCloud cloud = sampled_cloud(17, [](int i, const auto& unit) {
    const double cx = 2.0 * static_cast<double>(i % 4), cy = 2.0 * static_cast<double>((i / 4) % 4);
    const double lx = i % 5 < 2 ? 0.2 * unit() : 2.0 * unit();
    const double y = cy + 2.0 * unit();
    return Vec3d{cx + lx, y, unit()};
  });
  const double inf = std::numeric_limits<double>::infinity();
  const Box3d box{{0.3, -inf, -inf}, {1.9, inf, inf}};
  for (const PyramidMode mode : {PyramidMode::kOff, PyramidMode::kOn}) {
    CAPTURE(mode);
    const std::unique_ptr<ArchiveReader> reader = open_fine(tmp, cloud, mode);
    const PointCloud all = run_query(*reader, &box, nullptr, QueryOptions{});
    REQUIRE(all.size() > 3000);
    std::set<std::pair<std::tuple<double, double, double>, float>> points;
    for (std::size_t i = 0; i < all.size(); ++i) {
      points.insert({{all.positions[i].x, all.positions[i].y, all.positions[i].z}, all.intensities[i]});
    }
    for (const std::uint64_t limit : {std::uint64_t{all.size()}, std::uint64_t{all.size() - 1}}) {
      CAPTURE(limit);
      QueryOptions o;
      o.max_points = limit;
      QueryStats stats;
      const PointCloud got = run_query(*reader, &box, &stats, o);
      CHECK(got.size() == limit);
      CHECK(stats.pyramid_level == 0);
      // Read whole, and thinned only below the box's count (what the CLI's
      // summary line says).
      CHECK(stats.lod_min == 1);
      CHECK(stats.lod_max == 1);
      CHECK(stats.thinned == (limit < all.size()));
      // The box's own points, intensities and all.
      std::size_t own = 0;
      for (std::size_t i = 0; i < got.size(); ++i) {
        own +=
            points.count({{got.positions[i].x, got.positions[i].y, got.positions[i].z}, got.intensities[i]});
      }
      CHECK(own == got.size());
    }
    for (const std::uint64_t limit : {1, 2, 7}) {
      CAPTURE(limit);
      QueryOptions o;
      o.max_points = limit;
      CHECK(run_query(*reader, &box, nullptr, o).size() == limit);
    }
  }
}

TEST_CASE("max_points reads a finer level when the level it chose, counted, gives the box too few points",
          "[pyramid]") {
  // 32 x 32 m in 2 m chunks of 0.25 m cells, 90 % of the points in a 0.1 m
  // slab at the bottom, the rest up to 8 m. The top level's maps (one height
  // per pixel of 16 m cells) keep little but the slab, so a box over the top
  // half gets a point or none from it at the level of detail its estimate
  // (half its node's points) asks for: limits of 1, 20 and 60 gave 0, 1
  // and 1 points, with 30,000 in the box.
  TempDir tmp;
  std::mt19937_64 random(23);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  PointCloud cloud;
  for (int i = 0; i < 300000; ++i) {
    const double x = 32 * unit(random), y = 32 * unit(random);
    cloud.positions.push_back({x, y, i % 10 == 0 ? 8 * unit(random) : 0.1 * unit(random)});
    cloud.colors.push_back({100, 150, 200});
    cloud.intensities.push_back(static_cast<float>(i % 1000));
  }
  auto opened = ArchiveReader::open(build(tmp, "a", cloud));
  REQUIRE(opened.is_ok());
  const std::unique_ptr<ArchiveReader> reader = std::move(*opened);
  REQUIRE(reader->info().pyramid.at(0).levels.size() >= 3);
  const double inf = std::numeric_limits<double>::infinity();
  const Box3d box{{-inf, -inf, 4.0}, {inf, inf, inf}};
  for (const std::uint64_t limit : {1, 20, 60, 250, 700}) {
    CAPTURE(limit);
    QueryOptions o;
    o.max_points = limit;
    QueryStats stats;
    const PointCloud got = run_query(*reader, &box, &stats, o);
    INFO("level " << stats.pyramid_level << ", lod " << stats.lod_min << "-" << stats.lod_max << ", "
                  << stats.chunks_decoded << " rows, " << stats.blob_bytes_read << " bytes");
    CHECK(got.size() == limit);
    CHECK(stats.thinned);
    CHECK(stats.pyramid_level > 0);  // not the chunks: a few kB read
    CHECK(stats.blob_bytes_read < 200000);
    for (const Vec3d& p : got.positions) CHECK(p.z >= 4.0);
    // The same points whatever the threads.
    o.threads = 3;
    CHECK(run_query(*reader, &box, nullptr, o).positions == got.positions);
  }
  // A level that gives what it was estimated to stands, however far below
  // the limit: a whole-archive query (a preview's) of a limit more than
  // twice a level that the next finer one exceeds 4 times reads that level
  // alone, not the finer one.
  const ScanPyramid& p = reader->info().pyramid.at(0);
  bool tried = false;
  for (std::size_t i = 0; i + 1 < p.levels.size(); ++i) {
    const std::uint64_t coarse = p.levels[i + 1].points, limit = 2 * coarse + 2;
    if (p.levels[i].points <= 4 * limit) continue;
    CAPTURE(i, p.levels[i].points, coarse);
    tried = true;
    QueryOptions o;
    o.max_points = limit;
    QueryStats stats;
    CHECK(run_query(*reader, nullptr, &stats, o).size() == coarse);
    CHECK(stats.pyramid_level == p.levels[i + 1].level);
    CHECK(stats.blob_bytes_read == p.levels[i + 1].blob_bytes);
    CHECK_FALSE(stats.thinned);
  }
  CHECK(tried);
}

TEST_CASE("max_points within a polygon counts only the rows the polygon reaches", "[pyramid][polygon]") {
  TempDir tmp;
  auto reader = ArchiveReader::open(build(tmp, "a", terrain(3, 300000)));
  REQUIRE(reader.is_ok());
  const Box3d& b = (*reader)->info().bounds;
  // A sliver along the diagonal: its bounds hold every row, it reaches few.
  const double w = b.max.x - b.min.x;
  char wkt[256];
  std::snprintf(wkt, sizeof wkt, "POLYGON ((%.9f %.9f, %.9f %.9f, %.9f %.9f))", b.min.x, b.min.y, b.max.x, b.max.y,
                b.max.x - 0.05 * w, b.max.y);
  auto area = Polygon2D::from_wkt(wkt, "sliver");
  REQUIRE(area.is_ok());
  auto archive = Archive::open(tmp.file("a.relief"), Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto refs = (*archive)->all_chunks();
  REQUIRE(refs.is_ok());
  std::uint64_t reached = 0;
  for (const ChunkRef& r : *refs) {
    if (area->classify(r.bounds) != Polygon2D::Overlap::kOutside) reached += r.decoded_points;
  }
  REQUIRE(reached < 150000);
  QueryOptions all;
  all.polygon = std::make_shared<const Polygon2D>(*area);
  const std::size_t inside = run_query(**reader, nullptr, nullptr, all).size();
  // A limit the reached rows meet: every point inside, from the chunks
  // (counting the rows of the polygon's bounds it went to a coarser level).
  QueryOptions o = all;
  o.max_points = reached;
  QueryStats stats;
  CHECK(run_query(**reader, nullptr, &stats, o).size() == inside);
  CHECK(stats.pyramid_level == 0);
}

TEST_CASE("the pyramid's blobs depend only on the points, not their order, threads or budget", "[pyramid]") {
  TempDir tmp;
  PointCloud cloud = terrain(4, 120000);
  const std::string a = build(tmp, "a", cloud);
  // Reversed order, one thread, the smallest budget.
  std::vector<std::uint32_t> order(cloud.size());
  for (std::uint32_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::uint32_t>(order.size() - 1 - i);
  IngestOptions o = options(PyramidMode::kOn);
  o.threads = 1;
  o.memory_budget = std::uint64_t{64} << 20;
  const std::string b = build(tmp, "b", cloud.gathered(order), o);
  const auto blobs_a = level_blobs(a);
  const auto blobs_b = level_blobs(b);
  CHECK(blobs_a.size() >= 3);
  CHECK(blobs_a == blobs_b);

  // Rebuilt from the stored chunks: the same blobs again.
  auto archive = Archive::open(b, Archive::Mode::kReadWrite);
  REQUIRE(archive.is_ok());
  auto rebuilt = build_pyramid(**archive, 1, PyramidOptions{});
  REQUIRE(rebuilt.is_ok());
  CHECK(rebuilt->levels >= 2);
  archive->reset();
  CHECK(level_blobs(b) == blobs_a);
}

TEST_CASE("an append brings its own pyramid, removing the scan removes it", "[pyramid]") {
  TempDir tmp;
  const std::string path = build(tmp, "a", terrain(5, 100000));
  REQUIRE(write_ply(tmp.file("more.ply"), terrain(6, 100000, {kSize, 0, 0})).is_ok());
  IngestOptions o = options(PyramidMode::kOn);
  auto appended = append_files(path, {tmp.file("more.ply")}, o);
  REQUIRE(appended.is_ok());
  CHECK(appended->pyramid.levels >= 2);
  {
    auto reader = ArchiveReader::open(path);
    REQUIRE(reader.is_ok());
    const ArchiveInfo& info = (*reader)->info();
    REQUIRE(info.pyramid.size() == 2);
    CHECK_FALSE(info.pyramid[0].levels.empty());
    CHECK_FALSE(info.pyramid[1].levels.empty());
    // A coarse query of both scans' area returns points of both.
    QueryOptions q;
    q.lod = 32;
    QueryStats stats;
    const PointCloud got = run_query(**reader, nullptr, &stats, q);
    CHECK(stats.pyramid_level >= 1);
    std::size_t left = 0, right = 0;
    for (const Vec3d& p : got.positions) (p.x < kSize ? left : right) += 1;
    CHECK(left > 1000);
    CHECK(right > 1000);
  }
  {
    auto archive = Archive::open(path, Archive::Mode::kReadWrite);
    REQUIRE(archive.is_ok());
    REQUIRE((*archive)->abort_scan(appended->scan_id).is_ok());
  }
  auto reader = ArchiveReader::open(path);
  REQUIRE(reader.is_ok());
  REQUIRE((*reader)->info().pyramid.size() == 1);
  QueryOptions q;
  q.lod = 32;
  QueryStats stats;
  for (const Vec3d& p : run_query(**reader, nullptr, &stats, q).positions) REQUIRE(p.x <= kSize);
  CHECK(stats.pyramid_level >= 1);
}

TEST_CASE("max_points gives each scan its share of the limit, whatever level of the pyramid it is read at",
          "[pyramid]") {
  // Scan A (100 k points) has a pyramid; scan B lies over the same area 100 m
  // higher, without one (appended with --pyramid off) or with a shallower one
  // (20 k points). A row of a coarse level stands for the points of the
  // level below it: its share of the limit counts them, or A's rows (a
  // level's few hundred points) got 28 of 2,000 points and B 1,972.
  TempDir tmp;
  const std::string path = build(tmp, "a", terrain(5, 100000));
  for (const bool b_pyramid : {false, true}) {
    DYNAMIC_SECTION("scan B " << (b_pyramid ? "with a shallower pyramid" : "without a pyramid")) {
      const std::size_t b_points = b_pyramid ? 20000 : 100000;
      REQUIRE(write_ply(tmp.file("b.ply"), terrain(6, b_points, {0, 0, 100})).is_ok());
      const std::string copy = tmp.file(b_pyramid ? "ab2.relief" : "ab1.relief");
      std::filesystem::copy_file(path, copy);
      auto appended =
          append_files(copy, {tmp.file("b.ply")}, options(b_pyramid ? PyramidMode::kOn : PyramidMode::kOff));
      REQUIRE(appended.is_ok());
      auto reader = ArchiveReader::open(copy);
      REQUIRE(reader.is_ok());
      REQUIRE((*reader)->info().pyramid.size() == 2);
      CHECK((*reader)->info().pyramid[1].levels.empty() == !b_pyramid);
      const double want_a = 100000.0 / static_cast<double>(100000 + b_points);
      // (One limit under the sanitizers: the rest repeat the same paths.)
      const std::vector<std::uint64_t> limits =
          test::kSanitized ? std::vector<std::uint64_t>{20000} : std::vector<std::uint64_t>{200, 2000, 20000};
      for (const std::uint64_t limit : limits) {
        for (const bool whole : {true, false}) {
          INFO("limit " << limit << (whole ? ", whole archive" : ", a box over half of it"));
          QueryOptions q;
          q.max_points = limit;
          QueryStats stats;
          const Box3d half{{0, 0, -1000}, {kSize / 2, kSize, 1000}};
          const PointCloud got = run_query(**reader, whole ? nullptr : &half, &stats, q);
          REQUIRE(got.size() <= limit);
          CHECK(got.size() >= limit / 2);
          std::size_t a = 0;
          for (const Vec3d& p : got.positions) a += p.z < 50 ? 1 : 0;
          const double share =
              static_cast<double>(a) / static_cast<double>(std::max<std::size_t>(1, got.size()));
          CHECK(share > 0.75 * want_a);
          CHECK(share < 1.25 * want_a);
        }
      }
    }
  }
}

TEST_CASE("pyramid rows are ignored until the scan's pyramid is recorded finished", "[pyramid]") {
  TempDir tmp;
  const std::string path = build(tmp, "a", terrain(7, 60000), options(PyramidMode::kOff));
  ChunkRow node;
  {
    auto archive = Archive::open(path, Archive::Mode::kReadWrite);
    REQUIRE(archive.is_ok());
    auto rows = (*archive)->scan_chunks(1);
    REQUIRE(rows.is_ok());
    REQUIRE_FALSE(rows->empty());
    auto first = (*archive)->read_chunk(rows->front().id);
    REQUIRE(first.is_ok());
    node = *first;
    node.ref.key = ChunkKey{0, 0, 0};
    std::vector<ChunkRow> batch = {node};
    REQUIRE((*archive)->put_level_chunks(1, batch).is_ok());
    std::vector<ChunkRow> bad = {node};
    CHECK((*archive)->put_level_chunks(0, bad).code() == StatusCode::kInvalidArgument);
    CHECK((*archive)->finish_pyramid(99, 0b10).code() == StatusCode::kInvalidArgument);
    CHECK((*archive)->finish_pyramid(1, 1).code() == StatusCode::kInvalidArgument);  // level 0 is the chunks
  }
  {
    auto reader = ArchiveReader::open(path);
    REQUIRE(reader.is_ok());
    CHECK((*reader)->info().pyramid.at(0).levels.empty());
    QueryOptions q;
    q.lod = 64;
    QueryStats stats;
    run_query(**reader, nullptr, &stats, q);
    CHECK(stats.pyramid_level == 0);
  }
  {
    auto archive = Archive::open(path, Archive::Mode::kReadWrite);
    REQUIRE(archive.is_ok());
    // Recorded with a level it lacks: still not used.
    REQUIRE((*archive)->finish_pyramid(1, 0b110).is_ok());
  }
  auto reader = ArchiveReader::open(path);
  REQUIRE(reader.is_ok());
  CHECK((*reader)->info().pyramid.at(0).levels.empty());
  auto check = check_archive(path);
  REQUIRE(check.is_ok());
  CHECK(check->problems.empty());
}

TEST_CASE("rebuilding a scan's pyramid first removes the rows an unfinished build left", "[pyramid]") {
  TempDir tmp;
  const PointCloud cloud = terrain(10, 60000);
  const std::string path = build(tmp, "a", cloud, options(PyramidMode::kOff));
  auto writer = Archive::open(path, Archive::Mode::kReadWrite);
  REQUIRE(writer.is_ok());
  // Left by a build killed mid-way: a node far from the data at level 1
  // (a level the rebuild stores) and one at level 7 (a level it does not).
  put_stray_node(**writer, 1, 1, ChunkKey{99, 99, 99});
  put_stray_node(**writer, 1, 7, ChunkKey{0, 0, 0});
  REQUIRE(level_rows(path).at(1) == 2);
  PyramidOptions p;
  p.threads = 1;
  auto built = build_pyramid(**writer, 1, p);
  REQUIRE(built.is_ok());
  REQUIRE(built->levels >= 2);
  // The same rows as a pyramid built by compress, read while this writer is
  // still open (so not removed by any later open).
  const std::string fresh = build(tmp, "b", cloud);
  CHECK(level_rows(path) == level_rows(fresh));
  CHECK(level_blobs(path) == level_blobs(fresh));
}

TEST_CASE("pyramid rows no reader uses are removed by the next writer that opens the archive alone", "[pyramid]") {
  TempDir tmp;
  const std::string path = build(tmp, "a", terrain(8, 60000));
  REQUIRE(write_ply(tmp.file("more.ply"), terrain(9, 60000, {kSize, 0, 0})).is_ok());
  auto appended = append_files(path, {tmp.file("more.ply")}, options(PyramidMode::kOff));
  REQUIRE(appended.is_ok());
  const std::int64_t second = appended->scan_id;
  const auto finished = level_blobs(path);
  const auto rows = level_rows(path);
  REQUIRE(rows.size() == 1);
  REQUIRE(rows.at(1) > 0);
  {
    auto writer = Archive::open(path, Archive::Mode::kReadWrite);
    REQUIRE(writer.is_ok());
    // The second scan's pyramid, never finished (a run killed while building
    // it), and a node of the first scan at a level its record does not name.
    put_stray_node(**writer, second, 1, ChunkKey{8, 0, 0});
    put_stray_node(**writer, second, 2, ChunkKey{4, 0, 0});
    put_stray_node(**writer, 1, 12, ChunkKey{0, 0, 0});
    // Another writer opening meanwhile removes nothing: this one may be
    // building that pyramid.
    {
      auto other = Archive::open(path, Archive::Mode::kReadWrite);
      REQUIRE(other.is_ok());
    }
    const auto during = level_rows(path);
    CHECK(during.at(second) == 2);
    CHECK(during.at(1) == rows.at(1) + 1);
  }
  // Readers ignore the rows; check counts them but finds no damage.
  CHECK(level_blobs(path) == finished);
  auto listed = check_archive(path);
  REQUIRE(listed.is_ok());
  CHECK(listed->problems.empty());
  CHECK(mentions_unused_rows(*listed));
  {
    auto writer = Archive::open(path, Archive::Mode::kReadWrite);
    REQUIRE(writer.is_ok());
  }
  CHECK(level_rows(path) == rows);
  CHECK(level_blobs(path) == finished);
  auto clean = check_archive(path);
  REQUIRE(clean.is_ok());
  CHECK(clean->problems.empty());
  CHECK_FALSE(mentions_unused_rows(*clean));
  // A record and rows of a scan that is gone (removed by a writer that does
  // not know the pyramid) go too, whoever else is connected.
  {
    sqlite3* db = nullptr;
    REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
    REQUIRE(sqlite3_exec(db,
                         "PRAGMA foreign_keys = OFF; INSERT INTO relief_level_scan(scan_id, levels) VALUES(77, 2); "
                         "INSERT INTO relief_level_chunk(level, ix, iy, iz, seq, scan_id, input_points, "
                         "decoded_points, codec, crc32, blob) VALUES(1, 50, 50, 50, 0, 77, 0, 0, 1, 0, x'00')",
                         nullptr, nullptr, nullptr) == SQLITE_OK);
    sqlite3_close(db);
  }
  REQUIRE(level_rows(path).at(77) == 1);
  auto reader = ArchiveReader::open(path);  // another connection stays open
  REQUIRE(reader.is_ok());
  {
    auto writer = Archive::open(path, Archive::Mode::kReadWrite);
    REQUIRE(writer.is_ok());
  }
  CHECK(level_rows(path) == rows);
}
