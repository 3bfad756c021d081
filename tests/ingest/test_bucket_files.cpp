// The external sort's bucket files (internal to lib/ingest): fixed-point
// blocks round-trip every point into the right chunk, slices respect their
// bound, and a damaged file is an error, not a crash.
#include <catch2/catch.hpp>
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <tuple>
#include <vector>

#include "core/host.h"
#include "ingest/bucket_files.h"
#include "ingest/bucket_split.h"
#include "ingest/ingest_common.h"
#include "relief/archive.h"
#include "support/dead_pid.h"
#include "support/temp_dir.h"

using namespace relief;
using relief::ingest::AlignedBuffer;
using relief::ingest::BucketFiles;
using relief::ingest::Grouping;
using relief::test::TempDir;
namespace fs = std::filesystem;

namespace {

// Points over a few chunks on both sides of the origin, some exactly on a
// chunk face and some an ulp beside one; intensity = point index (exact in
// float below 2^24) identifies each point after the round trip.
PointCloud points_over_chunks(const ArchiveGrid& grid, std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-2.5, 2.5);
  PointCloud c;
  for (std::size_t i = 0; i < n; ++i) {
    Vec3d p{grid.origin.x + u(rng) * grid.chunk_edge, grid.origin.y + u(rng) * grid.chunk_edge,
            grid.origin.z + u(rng) * grid.chunk_edge};
    if (i % 97 == 0) p.x = grid.origin.x + std::round(u(rng)) * grid.chunk_edge;  // on a face
    if (i % 89 == 0) p.y = std::nextafter(grid.origin.y + std::round(u(rng)) * grid.chunk_edge, -1e300);
    c.positions.push_back(p);
    c.colors.push_back({static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(i >> 8),
                        static_cast<std::uint8_t>(i >> 16)});
    c.intensities.push_back(static_cast<float>(i));
  }
  return c;
}

}  // namespace

TEST_CASE("bucket files return every point to its chunk within the fixed-point step", "[ingest][buckets]") {
  TempDir tmp;
  ArchiveGrid grid;
  grid.origin = {484000.25, 6632000.5, -12.0};  // georeferenced: large coordinates
  grid.chunk_edge = 7.5;
  const std::size_t n = 60000;
  const PointCloud pts = points_over_chunks(grid, n, 7);
  std::vector<ChunkKey> keys(n);
  grid.keys_of(pts.positions.data(), n, keys.data());
  for (std::size_t i = 0; i < n; i += 101) CHECK(keys[i] == grid.key_of(pts.positions[i]));

  // A tiny staging share: every bucket flushes many times.
  auto files = BucketFiles::create(tmp.path(), 5, grid, true, true, 5 * 8192);
  REQUIRE(files.is_ok());
  // Several batches, as the reader delivers them.
  for (std::size_t first = 0; first < n; first += 7000) {
    const std::size_t m = std::min<std::size_t>(7000, n - first);
    PointCloud batch;
    batch.positions.assign(pts.positions.begin() + first, pts.positions.begin() + first + m);
    batch.colors.assign(pts.colors.begin() + first, pts.colors.begin() + first + m);
    batch.intensities.assign(pts.intensities.begin() + first, pts.intensities.begin() + first + m);
    REQUIRE(files->append(batch, keys.data() + first).is_ok());
  }
  REQUIRE(files->finish_writing().is_ok());

  const double step = grid.chunk_edge / 4294967296.0;
  std::vector<int> seen(n, 0);
  std::uint64_t total = 0;
  PointCloud slice;
  Grouping g;
  AlignedBuffer buf;
  for (std::uint32_t b = 0; b < files->bucket_count(); ++b) {
    total += files->bucket_points(b);
    std::uint64_t offset = 0;
    while (offset < files->bucket_bytes(b)) {
      const std::uint64_t before = offset;
      REQUIRE(files->read_slice(b, &offset, 9000, slice, g, buf).is_ok());
      REQUIRE(offset > before);
      REQUIRE(g.ids.size() == slice.size());
      // A slice holds whole blocks (at most one batch each) within the bound.
      CHECK(slice.size() <= 9000);
      for (std::size_t k = 0; k < slice.size(); ++k) {
        const auto i = static_cast<std::size_t>(slice.intensities[k]);
        REQUIRE(i < n);
        ++seen[i];
        const ChunkKey key = g.keys[g.ids[k]];
        CHECK(key == keys[i]);
        CHECK(files->bucket_of(key) == b);
        CHECK(slice.colors[k] == pts.colors[i]);
        const Vec3d& p = slice.positions[k];
        const Vec3d& q = pts.positions[i];
        // Half a step, plus rounding of the large coordinates (and the clamp
        // of points an ulp outside their nominal cube).
        const double tol = step / 2 + 4e-9;
        CHECK(std::abs(p.x - q.x) <= tol);
        CHECK(std::abs(p.y - q.y) <= tol);
        CHECK(std::abs(p.z - q.z) <= tol);
        // Every restored point lies in its chunk's cube.
        const Box3d cube = grid.chunk_box(key);
        CHECK((p.x >= cube.min.x && p.x <= cube.max.x && p.y >= cube.min.y && p.y <= cube.max.y &&
               p.z >= cube.min.z && p.z <= cube.max.z));
      }
    }
  }
  CHECK(total == n);
  std::size_t once = 0;
  for (int s : seen) once += s == 1 ? 1 : 0;
  CHECK(once == n);
}

TEST_CASE("bucket staging and slices stay at their share when batches fall into few chunks",
          "[ingest][buckets][las]") {
  // Scan-ordered input: each batch lies in one chunk, so a bucket's block is
  // far larger than its staging share. The buffers grown for such a block
  // must be given back, or the staging memory grows with the input; and a
  // slice of several blocks must be sized once, LAS attributes included, not
  // grown block by block (capacity doubling past the slice's share).
  TempDir tmp;
  ArchiveGrid grid;
  grid.origin = {0, 0, 0};
  grid.chunk_edge = 10;
  constexpr std::uint32_t kBuckets = 8;
  constexpr std::size_t kStaging = kBuckets * 8192;
  auto files = BucketFiles::create(tmp.path(), kBuckets, grid, true, true, kStaging, kLasGpsTime);
  REQUIRE(files.is_ok());
  const std::size_t batch_points = 20000;  // ~540 KB of records, against 8 KiB per bucket
  std::uint64_t total = 0;
  for (int b = 0; b < 40; ++b) {
    PointCloud batch;
    for (std::size_t i = 0; i < batch_points; ++i) {
      // A strip along x: batch b covers x in [5 b, 5 b + 5), half a chunk.
      const double x = 5.0 * b + 5.0 * static_cast<double>(i) / batch_points;
      batch.positions.push_back({x, 0.25 * static_cast<double>(i % 37), 1.0});
      batch.colors.push_back({1, 2, 3});
      batch.intensities.push_back(static_cast<float>(i));
      batch.las.gps_time.push_back(static_cast<double>(total + i));
    }
    std::vector<ChunkKey> keys(batch_points);
    grid.keys_of(batch.positions.data(), batch_points, keys.data());
    REQUIRE(files->append(batch, keys.data()).is_ok());
    total += batch_points;
    CHECK(files->staging_capacity() <= kStaging);
  }
  REQUIRE(files->finish_writing().is_ok());
  std::uint64_t read = 0;
  std::uint64_t largest = 0;
  PointCloud slice;
  Grouping g;
  AlignedBuffer buf;
  for (std::uint32_t b = 0; b < files->bucket_count(); ++b) {
    std::uint64_t offset = 0;
    largest = std::max(largest, files->bucket_points(b));
    while (offset < files->bucket_bytes(b)) {
      // Whole buckets, as the bounded mode reads them.
      REQUIRE(files->read_slice(b, &offset, ~std::uint64_t{0}, slice, g, buf).is_ok());
      read += slice.size();
      REQUIRE(slice.las.gps_time.size() == slice.size());
      CHECK(slice.las.gps_time.capacity() <= largest);
      CHECK(slice.positions.capacity() <= largest);
    }
  }
  CHECK(read == total);
}

TEST_CASE("a damaged bucket file is reported, not decoded", "[ingest][buckets]") {
  TempDir tmp;
  ArchiveGrid grid;
  grid.chunk_edge = 2.0;
  const PointCloud pts = points_over_chunks(grid, 5000, 11);
  std::vector<ChunkKey> keys(pts.size());
  grid.keys_of(pts.positions.data(), pts.size(), keys.data());
  auto files = BucketFiles::create(tmp.path(), 1, grid, true, true, 1 << 20);
  REQUIRE(files.is_ok());
  REQUIRE(files->append(pts, keys.data()).is_ok());
  REQUIRE(files->finish_writing().is_ok());
  const std::string path = files->directory() + "/bucket-0";
  REQUIRE(fs::exists(path));

  SECTION("a block header that claims more points than the file holds") {
    const int fd = ::open(path.c_str(), O_WRONLY);
    REQUIRE(fd >= 0);
    const std::uint8_t lie[4] = {0xff, 0xff, 0xff, 0x7f};
    REQUIRE(::pwrite(fd, lie, 4, 0) == 4);
    ::close(fd);
  }
  SECTION("a chunk entry whose key belongs to no chunk of this bucket's counts") {
    const int fd = ::open(path.c_str(), O_WRONLY);
    REQUIRE(fd >= 0);
    // The first entry's count (bytes 8 + 24 .. 8 + 28) set beyond the block.
    const std::uint8_t lie[4] = {0xff, 0xff, 0x00, 0x00};
    REQUIRE(::pwrite(fd, lie, 4, 8 + 24) == 4);
    ::close(fd);
  }
  PointCloud slice;
  Grouping g;
  AlignedBuffer buf;
  std::uint64_t offset = 0;
  const Status s = files->read_slice(0, &offset, 1u << 20, slice, g, buf);
  REQUIRE_FALSE(s.is_ok());
  CHECK(s.message().find("bucket-0") != std::string::npos);
  CHECK(s.message().find("damaged") != std::string::npos);
}

TEST_CASE("a temporary directory left by a killed ingest is removed by the next one", "[ingest][buckets]") {
  TempDir tmp;
  const std::string dead = relief::test::dead_pid();
  REQUIRE_FALSE(dead.empty());
  const std::string alive = std::to_string(::getppid());  // the process that runs this test
  const std::string here = core::host_tag();
  const std::string other = here == "other-host" ? "another-host" : "other-host";
  const auto make_dir = [&](const std::string& name) {
    fs::create_directories(tmp.path() / name);
    std::ofstream(tmp.path() / name / "bucket-0") << "left over";
  };
  const auto make_lock = [&](const std::string& name) {
    const std::string lock = (tmp.path() / name / "lock").string();
    const int fd = ::open(lock.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
    REQUIRE(fd >= 0);
    return fd;
  };
  // Owners on this host without a lock file: the pid decides.
  make_dir("relief-ingest-" + here + "-" + dead + "-Ab12Cd");   // stale: removed
  make_dir("relief-ingest-" + here + "-" + alive + "-Ab12Cd");  // its owner runs: kept
  // An owner on another machine sharing the directory: its pid means nothing
  // here, only its lock does.
  make_dir("relief-ingest-" + other + "-" + dead + "-Ab12Cd");  // no lock (yet): kept
  make_dir("relief-ingest-" + other + "-" + alive + "-Zz99Yy");  // lock free, owner gone: removed
  ::close(make_lock("relief-ingest-" + other + "-" + alive + "-Zz99Yy"));
  make_dir("relief-ingest-" + other + "-" + dead + "-Qq77Rr");  // lock held: kept
  const int held = make_lock("relief-ingest-" + other + "-" + dead + "-Qq77Rr");
  REQUIRE(::flock(held, LOCK_EX | LOCK_NB) == 0);
  make_dir("relief-ingest-" + here + "-" + alive + "-Qq77Rr");  // lock free, pid alive: the lock decides, removed
  ::close(make_lock("relief-ingest-" + here + "-" + alive + "-Qq77Rr"));
  // Not ours.
  make_dir("relief-ingest-" + dead + "-Ab12Cd");                // before host tags: no host, kept
  make_dir("relief-ingest-" + here + "-" + dead + "-Ab12");     // not our pattern: kept
  make_dir("relief-ingest-Ab12Cd");                             // no owner recorded: kept
  make_dir("other-" + dead + "-Ab12Cd");                        // not ours: kept
  std::ofstream(tmp.path() / ("relief-ingest-" + here + "-" + dead + "-Zz99Yy")) << "a file, not a directory";

  ArchiveGrid grid;
  grid.chunk_edge = 2.0;
  std::string own;
  {
    auto files = BucketFiles::create(tmp.path(), 2, grid, false, false, 1 << 16);
    REQUIRE(files.is_ok());
    own = fs::path(files->directory()).filename().string();
    CHECK(own.rfind("relief-ingest-" + here + "-" + std::to_string(::getpid()) + "-", 0) == 0);
    // Its own lock file is held while it lives: another sweep keeps it.
    const int probe = ::open((files->directory() + "/lock").c_str(), O_RDWR | O_CLOEXEC);
    REQUIRE(probe >= 0);
    CHECK(::flock(probe, LOCK_EX | LOCK_NB) != 0);
    ::close(probe);
    CHECK_FALSE(fs::exists(files->directory() + "/lock.new"));

    std::vector<std::string> expected = {"other-" + dead + "-Ab12Cd",
                                         "relief-ingest-" + dead + "-Ab12Cd",
                                         "relief-ingest-" + here + "-" + alive + "-Ab12Cd",
                                         "relief-ingest-" + here + "-" + dead + "-Ab12",
                                         "relief-ingest-" + here + "-" + dead + "-Zz99Yy",
                                         "relief-ingest-" + other + "-" + dead + "-Ab12Cd",
                                         "relief-ingest-" + other + "-" + dead + "-Qq77Rr",
                                         "relief-ingest-Ab12Cd",
                                         own};
    std::sort(expected.begin(), expected.end());
    CHECK(tmp.entries() == expected);
  }
  CHECK_FALSE(fs::exists(tmp.path() / own));  // removed with its lock file
  // The held lock released (its owner gone): the next run removes it.
  ::close(held);
  auto again = BucketFiles::create(tmp.path(), 1, grid, false, false, 1 << 16);
  REQUIRE(again.is_ok());
  CHECK_FALSE(fs::exists(tmp.path() / ("relief-ingest-" + other + "-" + dead + "-Qq77Rr")));
  CHECK(fs::exists(tmp.path() / ("relief-ingest-" + other + "-" + dead + "-Ab12Cd")));
}

TEST_CASE("bucket records carry every LAS attribute", "[ingest][buckets][las]") {
  TempDir tmp;
  ArchiveGrid grid;
  grid.origin = {100.0, 200.0, 0.0};
  grid.chunk_edge = 3.0;
  const std::size_t n = 20000;
  PointCloud pts = points_over_chunks(grid, n, 11);
  std::mt19937 rng(5);
  const auto u8 = [&] { return static_cast<std::uint8_t>(rng()); };
  LasAttributes& a = pts.las;
  for (std::size_t i = 0; i < n; ++i) {
    a.classification.push_back(u8());
    a.class_flags.push_back(u8() & 15);
    a.return_number.push_back(u8() & 15);
    a.number_of_returns.push_back(u8() & 15);
    a.scan_flags.push_back(u8() & 15);
    a.scan_angle.push_back(static_cast<std::int32_t>(rng() % 180001) - 90000);
    a.user_data.push_back(u8());
    a.point_source_id.push_back(static_cast<std::uint16_t>(rng()));
    a.gps_time.push_back(1e8 + static_cast<double>(rng()) * 1e-6);
    a.nir.push_back(static_cast<std::uint16_t>(rng()));
    a.color_low.push_back({u8(), u8(), u8()});
    for (int e = 0; e < 5; ++e) a.extra_bytes.push_back(u8());
  }
  a.extra_bytes_size = 5;
  const std::uint32_t bits = a.carried();
  std::vector<ChunkKey> keys(n);
  grid.keys_of(pts.positions.data(), n, keys.data());
  auto files = BucketFiles::create(tmp.path(), 3, grid, true, true, 3 * 8192, bits, 5);
  REQUIRE(files.is_ok());
  REQUIRE(files->append(pts, keys.data()).is_ok());
  REQUIRE(files->finish_writing().is_ok());
  std::size_t checked = 0;
  PointCloud slice;
  Grouping g;
  AlignedBuffer buf;
  for (std::uint32_t b = 0; b < files->bucket_count(); ++b) {
    std::uint64_t offset = 0;
    while (offset < files->bucket_bytes(b)) {
      REQUIRE(files->read_slice(b, &offset, 5000, slice, g, buf).is_ok());
      REQUIRE(slice.las.carried() == bits);
      REQUIRE(slice.las.extra_bytes_size == 5);
      for (std::size_t k = 0; k < slice.size(); ++k) {
        const auto i = static_cast<std::size_t>(slice.intensities[k]);
        REQUIRE(i < n);
        const LasAttributes& s = slice.las;
        REQUIRE(s.classification[k] == a.classification[i]);
        REQUIRE(s.class_flags[k] == a.class_flags[i]);
        REQUIRE(s.return_number[k] == a.return_number[i]);
        REQUIRE(s.number_of_returns[k] == a.number_of_returns[i]);
        REQUIRE(s.scan_flags[k] == a.scan_flags[i]);
        REQUIRE(s.scan_angle[k] == a.scan_angle[i]);
        REQUIRE(s.user_data[k] == a.user_data[i]);
        REQUIRE(s.point_source_id[k] == a.point_source_id[i]);
        REQUIRE(s.gps_time[k] == a.gps_time[i]);
        REQUIRE(s.nir[k] == a.nir[i]);
        REQUIRE(s.color_low[k] == a.color_low[i]);
        REQUIRE(std::equal(s.extra_bytes.begin() + static_cast<std::ptrdiff_t>(5 * k),
                           s.extra_bytes.begin() + static_cast<std::ptrdiff_t>(5 * k + 5),
                           a.extra_bytes.begin() + static_cast<std::ptrdiff_t>(5 * i)));
        ++checked;
      }
    }
  }
  CHECK(checked == n);
}

TEST_CASE("bounded chunks split sooner for wide points, by their attributes alone", "[ingest][split]") {
  using relief::ingest::bounded_split_points;
  constexpr std::uint64_t kSplit = kMaxBoundedChunkPoints;
  // No LAS attributes, and every LAS point format with up to 7 extra bytes
  // (format 8 with every field: 25 bytes + 7): the 2^20-point split.
  CHECK(bounded_split_points(kSplit, 0, 0) == kSplit);
  CHECK(bounded_split_points(kSplit, 0xFFF, 7) == kSplit);
  // A PLY with 200 bytes of properties per point.
  CHECK(bounded_split_points(kSplit, kLasExtraBytes, 200) == (std::uint64_t{1} << 25) / 200);
  // The widest LAS records still give chunks of some thousands of points.
  CHECK(bounded_split_points(kSplit, 0xFFF, 65535) == relief::ingest::kMinSplitPoints);
  // A smaller requested split wins (tests and tuning), and never 0.
  CHECK(bounded_split_points(1000, kLasExtraBytes, 200) == 1000);
  CHECK(bounded_split_points(0, 0, 0) == 1);
}

TEST_CASE("a bucket too large to load is cut into loads that give the tasks the whole bucket gives",
          "[ingest][buckets][split]") {
  using relief::ingest::BucketSplit;
  using relief::ingest::BucketSplitOptions;
  using relief::ingest::ChunkTask;
  TempDir tmp;
  ArchiveGrid grid;
  grid.origin = {484000.25, 6632000.5, -12.0};
  grid.chunk_edge = 7.5;
  // Most points in one chunk, denser towards a corner (octants of very
  // different sizes, so parts end at several depths), some on the octant
  // mid-planes, 2,500 copies of one point (a
  // part no split can make smaller), and a few other chunks. (In a bucket a
  // point is half a fixed-point step above the plane it was on.)
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  PointCloud pts;
  const auto add = [&](const Vec3d& p) {
    pts.positions.push_back(p);
    const auto i = static_cast<std::uint32_t>(pts.positions.size() - 1);
    pts.colors.push_back({static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(i >> 8), 0});
    pts.intensities.push_back(static_cast<float>(i));
  };
  const Vec3d lo = grid.origin;
  const double e = grid.chunk_edge;
  for (int i = 0; i < 50000; ++i) {
    const double r = u(rng) * u(rng);
    Vec3d p{lo.x + r * e * u(rng), lo.y + r * e * u(rng), lo.z + e * (0.4 + 0.1 * u(rng))};
    if (i % 101 == 0) p.x = lo.x + e / 2;
    if (i % 103 == 0) p.y = lo.y + e / 4;
    add(p);
  }
  for (int i = 0; i < 2500; ++i) add({lo.x + 0.3, lo.y + 0.2, lo.z + 3.1});
  for (int i = 0; i < 3000; ++i) add({lo.x + (1 + 2 * u(rng)) * e, lo.y - u(rng) * e, lo.z + u(rng)});
  // Shuffled, as input order is arbitrary.
  std::vector<std::size_t> perm(pts.size());
  for (std::size_t i = 0; i < perm.size(); ++i) perm[i] = i;
  std::shuffle(perm.begin(), perm.end(), rng);
  PointCloud shuffled;
  for (const std::size_t i : perm) {
    shuffled.positions.push_back(pts.positions[i]);
    shuffled.colors.push_back(pts.colors[i]);
    shuffled.intensities.push_back(pts.intensities[i]);
  }
  auto files = BucketFiles::create(tmp.path().string(), 1, grid, true, true, 1u << 20);
  REQUIRE(files.is_ok());
  for (std::size_t first = 0; first < shuffled.size(); first += 7000) {
    const std::size_t n = std::min<std::size_t>(7000, shuffled.size() - first);
    PointCloud batch;
    batch.positions.assign(shuffled.positions.begin() + first, shuffled.positions.begin() + first + n);
    batch.colors.assign(shuffled.colors.begin() + first, shuffled.colors.begin() + first + n);
    batch.intensities.assign(shuffled.intensities.begin() + first, shuffled.intensities.begin() + first + n);
    std::vector<ChunkKey> keys(n);
    grid.keys_of(batch.positions.data(), n, keys.data());
    REQUIRE(files->append(batch, keys.data()).is_ok());
  }
  REQUIRE(files->finish_writing().is_ok());

  // A task as (key, depth, sub-cube) -> its points' ids, sorted.
  using TaskId = std::tuple<std::int64_t, std::int64_t, std::int64_t, int, std::uint32_t, std::uint32_t, std::uint32_t>;
  const auto collect = [](const std::vector<ChunkTask>& tasks, std::map<TaskId, std::vector<float>>& out) {
    for (const ChunkTask& t : tasks) {
      std::vector<float> ids;
      for (std::size_t k = 0; k < t.count; ++k) ids.push_back(t.source->intensities[t.index[k]]);
      std::sort(ids.begin(), ids.end());
      const TaskId id{t.key.ix, t.key.iy, t.key.iz, t.split_depth, t.sub[0], t.sub[1], t.sub[2]};
      CHECK(out.emplace(id, std::move(ids)).second);
    }
  };
  constexpr std::uint64_t kSplit = 2000;
  AlignedBuffer buf;
  std::map<TaskId, std::vector<float>> whole;
  {
    PointCloud cloud;
    Grouping g;
    std::uint64_t offset = 0;
    REQUIRE(files->read_slice(0, &offset, ~std::uint64_t{0}, cloud, g, buf).is_ok());
    collect(relief::ingest::make_tasks(cloud, kSplit, g, &grid), whole);
  }
  BucketSplitOptions o;
  o.split_points = kSplit;
  o.load_points = 7000;
  o.tmp_parent = tmp.path().string();
  o.staging_bytes = 1u << 20;
  auto split = BucketSplit::create(*files, 0, grid, o, buf);
  REQUIRE(split.is_ok());
  CHECK(split->load_count() > 8);
  CHECK(split->passes() >= 4);  // counts, two double levels at least, routing
  std::map<TaskId, std::vector<float>> loaded;
  std::uint64_t points = 0;
  for (std::uint32_t l = 0; l < split->load_count(); ++l) {
    PointCloud cloud;
    Grouping g;
    auto tasks = split->read_load(l, cloud, g, buf);
    REQUIRE(tasks.is_ok());
    points += cloud.size();
    // A load holds whole parts within its size, or one part alone.
    CHECK((cloud.size() <= o.load_points || tasks->size() == 1));
    for (const ChunkTask& t : *tasks) {
      CHECK((t.count <= kSplit || t.split_depth == relief::ingest::kMaxSplitDepth));
    }
    collect(*tasks, loaded);
    split->discard(l);
  }
  CHECK(points == pts.size());
  CHECK(whole.size() > 20);
  CHECK(loaded == whole);
}

TEST_CASE("the grid's pass can keep what it reads: the same cells, every point once, in order", "[ingest][read-ahead]") {
  TempDir dir;
  ArchiveGrid grid;
  grid.chunk_edge = 10;
  const PointCloud points = points_over_chunks(grid, 300000, 5);
  const std::string a = dir.file("a.ply"), b = dir.file("b.ply");
  PointCloud first_half, second_half;
  for (std::size_t i = 0; i < points.size(); ++i) (i < 200000 ? first_half : second_half).push_back_from(points, i);
  REQUIRE(write_ply(a, first_half).is_ok());
  REQUIRE(write_ply(b, second_half).is_ok());
  const std::vector<std::string> inputs = {a, b};
  // What the files hold, read on their own.
  auto cloud = read_point_file(a);
  REQUIRE(cloud.is_ok());
  auto rest = read_point_file(b);
  REQUIRE(rest.is_ok());
  cloud->append_points(*rest);
  Box3d fresh_bounds;
  const auto fresh = ingest::order_free_cells(inputs, ReaderOptions{}, 16, &fresh_bounds);
  REQUIRE(fresh.is_ok());

  auto in = ingest::open_inputs(inputs, ReaderOptions{});
  REQUIRE(in.is_ok());
  PointCloud first;
  const auto got_first = in->readers[0]->read(first, 1000);
  REQUIRE(got_first.is_ok());
  REQUIRE(*got_first == 1000);
  Box3d kept_bounds;
  const auto kept = ingest::order_free_cells(inputs, ReaderOptions{}, 16, &kept_bounds, nullptr, &*in, &first);
  REQUIRE(kept.is_ok());
  CHECK(kept->points == cloud->size());
  CHECK(kept->points == fresh->points);
  CHECK(kept->density_cell == fresh->density_cell);
  CHECK(kept->base_cell == fresh->base_cell);
  CHECK(kept_bounds.min == fresh_bounds.min);
  CHECK(kept_bounds.max == fresh_bounds.max);
  REQUIRE_FALSE(in->read_ahead.empty());
  // The batches after `first`, in order, hold every other point exactly once.
  PointCloud all = first;
  std::uint64_t next = first.size();
  for (const ingest::ReadBatch& batch : in->read_ahead) {
    CHECK(batch.first == next);
    CHECK(batch.reader == (next < first_half.size() ? 0u : 1u));
    next += batch.points.size();
    all.append_points(batch.points);
  }
  REQUIRE(all.size() == cloud->size());
  for (std::size_t i = 0; i < cloud->size(); ++i) {
    REQUIRE(all.positions[i] == cloud->positions[i]);
    REQUIRE(all.colors[i].r == cloud->colors[i].r);
    REQUIRE(all.colors[i].g == cloud->colors[i].g);
    REQUIRE(all.colors[i].b == cloud->colors[i].b);
    REQUIRE(all.intensities[i] == cloud->intensities[i]);
  }
  // The inputs' readers are at their ends: nothing is read twice.
  PointCloud more;
  for (const auto& reader : in->readers) {
    const auto n = reader->read(more, 1000);
    REQUIRE(n.is_ok());
    CHECK(*n == 0);
  }
}
