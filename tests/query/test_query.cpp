// Spatial queries: exact box results, chunks touched, level of detail,
// corrupted chunks, readers during an append.
#include <catch2/catch.hpp>
#include <sqlite3.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <random>
#include <thread>

#include "relief/archive.h"
#include "relief/ingest.h"
#include "relief/io.h"
#include "relief/query.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"

using namespace relief;
namespace fs = std::filesystem;

using relief::test::TempDir;

namespace {


PointCloud scene(std::uint64_t seed, std::size_t points) {
  test::SceneOptions o;
  o.seed = seed;
  o.points = points;
  o.colors = true;
  return test::make_terrain(o, 16.0, 0.5);
}

// A 16 x 16 m terrain in 2 m chunks: 64 chunks.
std::string build(const TempDir& tmp, const std::string& name, std::uint64_t seed = 1, std::size_t points = 200000) {
  REQUIRE(write_ply(tmp.file(name + ".ply"), scene(seed, points)).is_ok());
  IngestOptions o;
  o.codec.cell_size = 0.25;
  o.chunk_edge = 2.0;
  REQUIRE(compress_files({tmp.file(name + ".ply")}, tmp.file(name + ".relief"), o).is_ok());
  return tmp.file(name + ".relief");
}

PointCloud run_query(ArchiveReader& r, const Box3d* box, QueryStats* stats = nullptr, QueryOptions o = {}) {
  PointCloud all;
  const PointSink sink = [&](const PointCloud& b) {
    all.positions.insert(all.positions.end(), b.positions.begin(), b.positions.end());
    all.colors.insert(all.colors.end(), b.colors.begin(), b.colors.end());
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

bool intersects(const Box3d& a, const Box3d& b) {
  return a.min.x <= b.max.x && a.max.x >= b.min.x && a.min.y <= b.max.y && a.max.y >= b.min.y &&
         a.min.z <= b.max.z && a.max.z >= b.min.z;
}

std::vector<std::tuple<double, double, double>> sorted_points(const PointCloud& c) {
  std::vector<std::tuple<double, double, double>> v;
  for (const Vec3d& p : c.positions) v.emplace_back(p.x, p.y, p.z);
  std::sort(v.begin(), v.end());
  return v;
}

}  // namespace

TEST_CASE("a box query returns exactly the full decompress's points inside the box", "[query]") {
  TempDir tmp;
  auto reader = ArchiveReader::open(build(tmp, "a"));
  REQUIRE(reader.is_ok());
  const PointCloud full = run_query(**reader, nullptr);
  CHECK(full.size() == (*reader)->info().decoded_points);
  const std::vector<Box3d> boxes = {
      {{3.1, 2.7, -10}, {7.9, 9.3, 10}},          // crosses chunk borders
      {{0.0, 0.0, -0.1}, {2.0, 2.0, 0.1}},        // one chunk, thin in z
      {{-5, -5, -5}, {30, 30, 30}},               // everything
      {{4.0, 4.0, -1}, {4.0, 6.0, 1}},            // zero width: a plane of points at most
      box_2d(10.25, 1.5, 13.75, 14.5),            // 2D: all heights
  };
  for (const Box3d& box : boxes) {
    QueryStats stats;
    const PointCloud got = run_query(**reader, &box, &stats);
    PointCloud want;
    for (std::size_t i = 0; i < full.size(); ++i) {
      if (inside(full.positions[i], box)) {
        want.positions.push_back(full.positions[i]);
        want.colors.push_back(full.colors[i]);
      }
    }
    INFO("box " << box.min.x << "," << box.min.y << " .. " << box.max.x << "," << box.max.y);
    CHECK(sorted_points(got) == sorted_points(want));
    CHECK(got.colors.size() == got.size());
    CHECK(stats.points == got.size());
  }
}

TEST_CASE("a box whose faces are coordinates as printed returns the points on them", "[query]") {
  // A LAS file at 1 cm with offsets 1000 and 2000: x = X * 0.01 + 1000 is
  // 169.54999999999995 in double for X = -83045, which prints, and is
  // typed, as 169.55. The faces are inclusive, so the points on them come back.
  TempDir tmp;
  std::mt19937_64 rng(11);
  PointCloud cloud;
  std::map<std::int32_t, std::size_t> per_x;
  for (int i = 0; i < 3000; ++i) {
    const auto ix = static_cast<std::int32_t>(-83100 + static_cast<int>(rng() % 200));
    const auto iy = static_cast<std::int32_t>(static_cast<int>(rng() % 5000));
    const auto iz = static_cast<std::int32_t>(static_cast<int>(rng() % 300));
    cloud.positions.push_back({ix * 0.01 + 1000.0, iy * 0.01 + 2000.0, iz * 0.01});
    ++per_x[ix];
  }
  WriterOptions w;
  w.grid_scale = Vec3d{0.01, 0.01, 0.01};
  w.grid_offset = Vec3d{1000.0, 2000.0, 0.0};
  auto writer = open_point_writer(tmp.file("edge.las"), w);
  REQUIRE(writer.is_ok());
  REQUIRE((*writer)->write(cloud).is_ok());
  REQUIRE((*writer)->finish().is_ok());
  REQUIRE(compress_files({tmp.file("edge.las")}, tmp.file("edge.relief"), IngestOptions{}).is_ok());
  auto reader = ArchiveReader::open(tmp.file("edge.relief"));
  REQUIRE(reader.is_ok());
  int checked = 0;
  for (const auto& [ix, count] : per_x) {
    if (checked++ % 7 != 0) continue;
    char text[64];
    std::snprintf(text, sizeof text, "%.2f", ix * 0.01 + 1000.0);
    const double face = std::strtod(text, nullptr);
    const Box3d plane{{face, 1900, -10}, {face, 2100, 10}};
    INFO("x = " << text << " (X = " << ix << ")");
    CHECK(run_query(**reader, &plane).size() == count);
    // Half a step beside it: none.
    const Box3d beside{{face + 0.005, 1900, -10}, {face + 0.005, 2100, 10}};
    CHECK(run_query(**reader, &beside).size() == 0);
  }
  CHECK(checked > 20);
}

TEST_CASE("check with the codec's row check reports a row whose point counts contradict its blob",
          "[query]") {
  // decoded_points of 2^62 passed as intact; info then said 4.6e18 points and
  // query --max-points 100 returned one point.
  TempDir tmp;
  const std::string path = build(tmp, "counts", 4, 20000);
  auto intact = check_archive(path, nullptr, chunk_row_check());
  REQUIRE(intact.is_ok());
  CHECK(intact->problems.empty());
  sqlite3* db = nullptr;
  REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
  REQUIRE(sqlite3_exec(db, "UPDATE relief_chunk SET decoded_points = 4611686018427387904 WHERE id = 2",
                       nullptr, nullptr, nullptr) == SQLITE_OK);
  sqlite3_close(db);
  auto damaged = check_archive(path, nullptr, chunk_row_check());
  REQUIRE(damaged.is_ok());
  REQUIRE(damaged->problems.size() == 1);
  CHECK_THAT(damaged->problems[0],
             Catch::Contains("(id 2): its row says 4611686018427387904 decoded points, its blob "));
}

TEST_CASE("chunks reach the sink in index order whatever the threads, and a failing sink stops the query",
          "[query][threads]") {
  TempDir tmp;
  auto reader = ArchiveReader::open(build(tmp, "order"));
  REQUIRE(reader.is_ok());
  // The batches in the order they arrive, one query per thread count.
  auto batches = [&](unsigned threads) {
    std::vector<std::vector<Vec3d>> got;
    QueryOptions o;
    o.threads = threads;
    auto s = (*reader)->query_all(o, [&](const PointCloud& b) {
      got.push_back(b.positions);
      return Status::ok();
    });
    REQUIRE(s.is_ok());
    CHECK(s->chunks_decoded == got.size());
    return got;
  };
  const auto one = batches(1);
  CHECK(one.size() > 32);  // enough chunks for several in flight per thread
  CHECK(batches(2) == one);
  CHECK(batches(7) == one);

  for (const unsigned threads : {1u, 3u}) {
    std::size_t calls = 0;
    QueryOptions o;
    o.threads = threads;
    auto s = (*reader)->query_all(o, [&](const PointCloud&) {
      ++calls;
      return calls == 5 ? io_error("the disk is full") : Status::ok();
    });
    REQUIRE_FALSE(s.is_ok());
    CHECK(s.status().message() == "the disk is full");
    CHECK(calls == 5);
  }
}

TEST_CASE("boxes outside the data return nothing and read nothing", "[query]") {
  TempDir tmp;
  auto reader = ArchiveReader::open(build(tmp, "b"));
  REQUIRE(reader.is_ok());
  for (const Box3d& box : {Box3d{{100, 100, -1}, {200, 200, 1}}, Box3d{{0, 0, 50}, {16, 16, 60}},
                           box_2d(-30, -30, -20, -20)}) {
    QueryStats stats;
    CHECK(run_query(**reader, &box, &stats).empty());
    CHECK(stats.chunks_decoded == 0);
    CHECK(stats.blob_bytes_read == 0);
  }
  const PointSink ignore = [](const PointCloud&) { return Status::ok(); };
  CHECK((*reader)->query(Box3d{{5, 5, 5}, {4, 6, 6}}, {}, ignore).status().code() == StatusCode::kInvalidArgument);
  CHECK((*reader)->query(Box3d{{std::nan(""), 0, 0}, {1, 1, 1}}, {}, ignore).status().code() ==
        StatusCode::kInvalidArgument);
}

TEST_CASE("a query reads only the chunks whose bounds intersect the box", "[query]") {
  TempDir tmp;
  const std::string path = build(tmp, "c");
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  auto refs = (*archive)->all_chunks();
  REQUIRE(refs.is_ok());
  std::uint64_t total_bytes = 0;
  for (const ChunkRef& r : *refs) total_bytes += r.blob_size;
  auto reader = ArchiveReader::open(path);
  const Box3d box{{4.5, 4.5, -10}, {5.5, 7.5, 10}};
  std::uint64_t want_chunks = 0, want_bytes = 0;
  for (const ChunkRef& r : *refs) {
    if (intersects(r.bounds, box)) {
      ++want_chunks;
      want_bytes += r.blob_size;
    }
  }
  QueryStats stats;
  run_query(**reader, &box, &stats);
  CHECK(stats.chunks_decoded == want_chunks);
  CHECK(stats.blob_bytes_read == want_bytes);
  CHECK(want_chunks < refs->size() / 4);
  CHECK(stats.blob_bytes_read < total_bytes / 4);
}

TEST_CASE("a polygon query returns the points inside it and reads only the chunks it touches", "[query][polygon]") {
  TempDir tmp;
  const std::string path = build(tmp, "p");
  auto reader = ArchiveReader::open(path);
  REQUIRE(reader.is_ok());
  const PointCloud full = run_query(**reader, nullptr);
  // An L-shaped area with a hole, a thin diagonal sliver, and two parts.
  const std::vector<std::string> areas = {
      "POLYGON ((1 1, 15 1, 15 5, 5 5, 5 15, 1 15, 1 1), (2 2, 4 2, 4 4, 2 4, 2 2))",
      "POLYGON ((0.5 0.5, 15.5 14.9, 15.5 15.5, 0.5 0.5))",
      "MULTIPOLYGON (((0 0, 3 0, 3 3, 0 3, 0 0)), ((10.3 10.1, 14.2 10.7, 12.9 15.8, 10.3 10.1)))",
  };
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  auto refs = (*archive)->all_chunks();
  REQUIRE(refs.is_ok());
  for (const std::string& wkt : areas) {
    auto polygon = Polygon2D::from_wkt(wkt, "area");
    REQUIRE(polygon.is_ok());
    QueryOptions o;
    o.polygon = std::make_shared<const Polygon2D>(*polygon);
    for (const bool with_box : {false, true}) {
      const Box3d box = box_2d(2.5, 0.5, 13.5, 12.5);
      QueryStats stats;
      const PointCloud got = run_query(**reader, with_box ? &box : nullptr, &stats, o);
      PointCloud want;
      for (const Vec3d& p : full.positions) {
        if (polygon->contains(p.x, p.y) && (!with_box || inside(p, box))) want.positions.push_back(p);
      }
      INFO(wkt << (with_box ? " within a box" : ""));
      CHECK(sorted_points(got) == sorted_points(want));
      CHECK(got.colors.size() == got.size());
      CHECK(!want.empty());
      // The chunks read: those whose bounds the area does not leave out.
      std::uint64_t touched = 0;
      for (const ChunkRef& r : *refs) {
        if (with_box && !intersects(r.bounds, box)) continue;
        if (polygon->classify(r.bounds) != Polygon2D::Overlap::kOutside) ++touched;
      }
      CHECK(stats.chunks_decoded == touched);
      CHECK(touched < refs->size());
    }
    // A coarse level of detail within the area: still from the base layer,
    // about 1/4 of the points, all inside.
    o.lod = 4;
    const PointCloud coarse = run_query(**reader, nullptr, nullptr, o);
    std::size_t inside_count = 0;
    for (const Vec3d& p : full.positions) inside_count += polygon->contains(p.x, p.y) ? 1 : 0;
    CHECK(std::abs(static_cast<double>(coarse.size()) - inside_count / 4.0) < 0.15 * inside_count / 4.0 + 64);
    bool all_inside = true;
    for (const Vec3d& p : coarse.positions) all_inside = all_inside && polygon->contains(p.x, p.y);
    CHECK(all_inside);
  }
  // An area beside the data reads nothing, and says why it may be so.
  QueryOptions far;
  far.polygon = std::make_shared<const Polygon2D>(*Polygon2D::from_wkt("POLYGON ((100 100, 110 100, 105 109))", "far"));
  std::vector<std::string> warnings;
  far.on_warning = [&](const std::string& w) { warnings.push_back(w); };
  QueryStats stats;
  CHECK(run_query(**reader, nullptr, &stats, far).empty());
  CHECK(stats.chunks_decoded == 0);
  CHECK(stats.blob_bytes_read == 0);
  REQUIRE(warnings.size() == 1);
  CHECK(warnings[0].find("p.relief: the polygon (x 100 .. 110, y 100 .. 109) lies outside the archive's bounds") !=
        std::string::npos);
  // One that overlaps the bounds says nothing.
  warnings.clear();
  far.polygon = std::make_shared<const Polygon2D>(*Polygon2D::from_wkt("POLYGON ((15 15, 30 15, 30 30, 15 15))", "c"));
  run_query(**reader, nullptr, nullptr, far);
  CHECK(warnings.empty());
}

TEST_CASE("level of detail L returns about 1/L of the points, spread uniformly", "[query][lod]") {
  TempDir tmp;
  auto reader = ArchiveReader::open(build(tmp, "d", 5, 400000));
  const PointCloud full = run_query(**reader, nullptr);
  for (std::uint32_t lod : {4u, 16u}) {
    QueryOptions o;
    o.lod = lod;
    const PointCloud sub = run_query(**reader, nullptr, nullptr, o);
    INFO("lod " << lod);
    const double expected = static_cast<double>(full.size()) / lod;
    CHECK(std::abs(static_cast<double>(sub.size()) - expected) < 0.05 * expected + 64);
    // Coarse 8 x 8 histogram over the 16 m square: every cell ~1/L of its full count.
    int a[8][8] = {}, b[8][8] = {};
    const auto cell = [](double v) { return std::clamp(static_cast<int>(v / 2.0), 0, 7); };
    for (const Vec3d& p : full.positions) a[cell(p.x)][cell(p.y)]++;
    for (const Vec3d& p : sub.positions) b[cell(p.x)][cell(p.y)]++;
    for (int i = 0; i < 8; ++i) {
      for (int j = 0; j < 8; ++j) {
        const double want = static_cast<double>(a[i][j]) / lod;
        CHECK(std::abs(b[i][j] - want) < 0.2 * want + 8);
      }
    }
  }
}

TEST_CASE("archive_sections says where every byte of the archive goes", "[query][sections]") {
  TempDir tmp;
  const std::string path = build(tmp, "s", 3, 60000);
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto info = (*archive)->info();
  REQUIRE(info.is_ok());
  std::uint64_t heard = 0;
  auto s = archive_sections(**archive, [&](std::uint64_t n) { heard += n; });
  INFO(s.status().to_string());
  REQUIRE(s.is_ok());
  CHECK(s->chunks == info->chunk_count);
  CHECK(s->input_points == info->input_points);
  CHECK(heard == info->input_points);
  CHECK(s->file_bytes == info->file_bytes);
  auto refs = (*archive)->all_chunks();
  REQUIRE(refs.is_ok());
  std::uint64_t blobs = 0;
  for (const ChunkRef& r : *refs) blobs += r.blob_size;
  CHECK(s->blob_bytes == blobs);
  // Every byte of every blob is a section's or the framing's.
  std::uint64_t sections = 0;
  std::map<std::string, const SectionTotal*> by_name;
  for (const SectionTotal& t : s->sections) {
    sections += t.bytes;
    by_name[t.name] = &t;
    CHECK(t.chunks > 0);
    CHECK(t.chunks <= s->chunks);
  }
  CHECK(sections + s->framing_bytes == s->blob_bytes);
  // Error-bounded chunks with colours: the points' geometry and colours, and
  // the paper's maps as their base layer.
  for (const char* name : {"geometry", "rgb", "occupancy map", "height map", "colour map"}) {
    INFO(name);
    REQUIRE(by_name.count(name) == 1);
    CHECK(by_name[name]->chunks == s->chunks);
    CHECK(by_name[name]->maps == (std::string(name).find("map") != std::string::npos));
  }
  CHECK(by_name["geometry"]->id == 7);
  CHECK(s->framing_bytes >= s->chunks * (176 + 4));
  CHECK(s->container_bytes() == s->file_bytes - s->blob_bytes - s->pyramid_bytes);
  const std::string json = archive_sections_json(*s);
  CHECK(json.find("{\"id\": 7, \"name\": \"geometry\", \"maps\": false, \"bytes\": " +
                  std::to_string(by_name["geometry"]->bytes)) != std::string::npos);
  CHECK(json.find("\"container_bytes\": " + std::to_string(s->container_bytes())) != std::string::npos);
  // Only the heads were read: a few hundred bytes of each blob.
  auto fresh = Archive::open(path, Archive::Mode::kReadOnly);
  REQUIRE(fresh.is_ok());
  REQUIRE(archive_sections(**fresh).is_ok());
  CHECK((*fresh)->blob_bytes_read() <= s->chunks * kChunkHeadBytes);
  CHECK((*fresh)->blob_bytes_read() < s->blob_bytes / 4);
  // A head is the blob's first bytes, and says what the whole blob says.
  const ChunkRef& first = refs->front();
  auto head = (*archive)->read_chunk_head(first.id, kChunkHeadBytes);
  REQUIRE(head.is_ok());
  auto row = (*archive)->read_chunk(first.id);
  REQUIRE(row.is_ok());
  REQUIRE(head->size() == std::min<std::size_t>(kChunkHeadBytes, row->blob.size()));
  CHECK(std::equal(head->begin(), head->end(), row->blob.begin()));
  auto from_head = inspect_chunk_head(*head, row->blob.size());
  auto from_blob = inspect_chunk(row->blob);
  REQUIRE(from_head.is_ok());
  REQUIRE(from_blob.is_ok());
  REQUIRE(from_head->sections.size() == from_blob->sections.size());
  for (std::size_t k = 0; k < from_head->sections.size(); ++k) {
    CHECK(from_head->sections[k].coded_size == from_blob->sections[k].coded_size);
  }
  CHECK_FALSE(inspect_chunk_head(*head, row->blob.size() + 1).is_ok());
  CHECK_FALSE(inspect_chunk_head(std::span<const std::uint8_t>(head->data(), 40), row->blob.size()).is_ok());
  CHECK_FALSE((*archive)->read_chunk_head(first.id + 1000000, 16).is_ok());
}

TEST_CASE("a corrupted chunk is reported by name, or skipped with a warning", "[query][corrupt]") {
  TempDir tmp;
  const std::string path = build(tmp, "e");
  {
    // Flip one byte in the middle of one blob, behind the archive's back.
    sqlite3* db = nullptr;
    REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
    sqlite3_stmt* get = nullptr;
    REQUIRE(sqlite3_prepare_v2(db, "SELECT id, blob FROM relief_chunk ORDER BY id LIMIT 1", -1, &get, nullptr) ==
            SQLITE_OK);
    REQUIRE(sqlite3_step(get) == SQLITE_ROW);
    const sqlite3_int64 id = sqlite3_column_int64(get, 0);
    const auto* data = static_cast<const unsigned char*>(sqlite3_column_blob(get, 1));
    std::vector<unsigned char> blob(data, data + sqlite3_column_bytes(get, 1));
    sqlite3_finalize(get);
    blob[blob.size() / 2] ^= 0x10;
    sqlite3_stmt* put = nullptr;
    REQUIRE(sqlite3_prepare_v2(db, "UPDATE relief_chunk SET blob = ?1 WHERE id = ?2", -1, &put, nullptr) == SQLITE_OK);
    sqlite3_bind_blob(put, 1, blob.data(), static_cast<int>(blob.size()), SQLITE_TRANSIENT);
    sqlite3_bind_int64(put, 2, id);
    REQUIRE(sqlite3_step(put) == SQLITE_DONE);
    sqlite3_finalize(put);
    sqlite3_close(db);
  }
  auto reader = ArchiveReader::open(path);
  REQUIRE(reader.is_ok());
  const PointSink ignore = [](const PointCloud&) { return Status::ok(); };
  auto failed = (*reader)->query_all({}, ignore);
  REQUIRE_FALSE(failed.is_ok());
  CHECK(failed.status().code() == StatusCode::kCorruptData);
  CHECK(failed.status().message().find(path) != std::string::npos);
  CHECK(failed.status().message().find("chunk (") != std::string::npos);
  QueryOptions o;
  o.skip_corrupt = true;
  std::vector<std::string> warnings;
  o.on_warning = [&](const std::string& w) { warnings.push_back(w); };
  QueryStats stats;
  const PointCloud rest = run_query(**reader, nullptr, &stats, o);
  CHECK(stats.chunks_skipped == 1);
  REQUIRE(warnings.size() == 1);
  CHECK(warnings[0].find("checksum") != std::string::npos);
  CHECK(rest.size() > 0);
  // Summing the sections reads each blob's header and section table only:
  // a byte damaged past them goes unseen (relief check finds it) ...
  {
    auto archive = Archive::open(path, Archive::Mode::kReadOnly);
    REQUIRE(archive.is_ok());
    CHECK(archive_sections(**archive).is_ok());
  }
  // ... a blob whose table disagrees with its size (cut short) is refused by name.
  {
    sqlite3* db = nullptr;
    REQUIRE(sqlite3_open(path.c_str(), &db) == SQLITE_OK);
    REQUIRE(sqlite3_exec(db, "UPDATE relief_chunk SET blob = substr(blob, 1, length(blob) - 9) WHERE id = "
                             "(SELECT max(id) FROM relief_chunk)",
                         nullptr, nullptr, nullptr) == SQLITE_OK);
    sqlite3_close(db);
  }
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto sections = archive_sections(**archive);
  REQUIRE_FALSE(sections.is_ok());
  CHECK(sections.status().code() == StatusCode::kCorruptData);
  CHECK(sections.status().message().find(path) != std::string::npos);
  CHECK(sections.status().message().find("chunk (") != std::string::npos);
  CHECK(sections.status().message().find("header and sections say") != std::string::npos);
}

TEST_CASE("readers during an append see a consistent archive", "[query][concurrency]") {
  TempDir tmp;
  const std::string path = build(tmp, "f", 7, 100000);
  REQUIRE(write_ply(tmp.file("more.ply"), scene(8, 300000)).is_ok());
  std::atomic<bool> done{false};
  std::atomic<int> errors{0};
  std::atomic<int> reads{0};
  std::thread reader_thread([&] {
    std::uint64_t last_chunks = 0;
    while (!done.load()) {
      auto r = ArchiveReader::open(path);
      if (!r) {
        ++errors;
        continue;
      }
      std::uint64_t points = 0, chunks = 0;
      const PointSink count = [&](const PointCloud& b) {
        points += b.size();
        return Status::ok();
      };
      auto s = (*r)->query_all({}, count);
      if (!s) {
        ++errors;
        continue;
      }
      chunks = s->chunks_decoded;
      // A snapshot never shrinks, and its points match its chunk count's info.
      if (chunks < last_chunks) ++errors;
      last_chunks = chunks;
      ++reads;
    }
  });
  IngestOptions o;
  o.threads = 1;
  auto appended = append_files(path, {tmp.file("more.ply")}, o);
  done = true;
  reader_thread.join();
  REQUIRE(appended.is_ok());
  CHECK(errors.load() == 0);
  CHECK(reads.load() > 0);
}
