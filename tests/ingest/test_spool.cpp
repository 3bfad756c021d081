// The spool of decoded inputs (lib/ingest/spool.h): every attribute comes
// back exactly, in any batch size; a damaged file is an
// error naming it and its input; a write error abandons the spool; and a
// compress that spools its LAZ and text inputs writes the blobs of one that
// reads them twice, leaving no temporary file behind.
#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>
#include <catch2/catch.hpp>

#include <atomic>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "ingest/spool.h"
#include "relief/ingest.h"
#include "relief/io.h"
#include "support/decode_archive.h"
#include "support/las_attributes.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"

using namespace relief;
using relief::ingest::Spool;
using relief::test::TempDir;
namespace fs = std::filesystem;

namespace {

constexpr std::uint32_t kAllLas = ((1u << kLasAttributeCount) - 1) | kLasExtraBytes;
// A point's bytes but x y z with every attribute: colour 3, intensity 4,
// the LAS vectors (classification ... NIR, colour low bytes), 3 extra bytes.
constexpr std::uint64_t kPerPoint = 3 + 4 + (1 + 1 + 1 + 1 + 1 + 4 + 1 + 2 + 8 + 2 + 3) + 3;

// n points on the grid offset + k * scale (or off it), with colours,
// intensities and every LAS attribute (3 extra bytes a point).
PointCloud spool_cloud(std::size_t n, std::uint64_t seed, const Vec3d& offset, const Vec3d& scale,
                       bool on_grid) {
  test::Rng rng(seed);
  PointCloud c;
  for (std::size_t i = 0; i < n; ++i) {
    const auto k = [&] {
      return static_cast<double>(static_cast<std::int32_t>(rng.next() % 2000000) - 1000000);
    };
    Vec3d p{offset.x + scale.x * k(), offset.y + scale.y * k(), offset.z + scale.z * k()};
    if (!on_grid) p.x += 1e-7 * static_cast<double>(i % 7 + 1);
    c.positions.push_back(p);
    c.colors.push_back(Rgb8{static_cast<std::uint8_t>(rng.next()), static_cast<std::uint8_t>(rng.next()),
                            static_cast<std::uint8_t>(rng.next())});
    c.intensities.push_back(static_cast<float>(rng.next() % 65536));
  }
  test::add_las_attributes(c, kAllLas, 3, seed, true);
  return c;
}

// Every point a reader gives, `max` at a time.
PointCloud read_all(PointReader& r, std::size_t max) {
  PointCloud all, batch;
  for (;;) {
    auto got = r.read(batch, max);
    REQUIRE(got.is_ok());
    if (*got == 0) break;
    CHECK(*got <= max);
    if (all.empty()) {
      all = batch;
    } else {
      all.append_points(batch);
    }
  }
  return all;
}

// Runs fn with the process's files limited to `bytes`: a write past it fails
// (EFBIG) part way, as on a full disk (SIGXFSZ ignored meanwhile).
template <typename F>
void with_file_size_limit(rlim_t bytes, F&& fn) {
  rlimit old{};
  REQUIRE(::getrlimit(RLIMIT_FSIZE, &old) == 0);
  rlimit small = old;
  small.rlim_cur = std::min(bytes, old.rlim_max);
  const auto old_handler = ::signal(SIGXFSZ, SIG_IGN);
  REQUIRE(::setrlimit(RLIMIT_FSIZE, &small) == 0);
  fn();
  ::setrlimit(RLIMIT_FSIZE, &old);
  ::signal(SIGXFSZ, old_handler);
}

bool same_points(const PointCloud& a, const PointCloud& b) {
  if (a.size() != b.size() || !a.same_attributes(b)) return false;
  if (std::memcmp(a.positions.data(), b.positions.data(), a.size() * sizeof(Vec3d)) != 0) return false;
  if (a.colors != b.colors || a.intensities != b.intensities || a.las.extra_bytes != b.las.extra_bytes)
    return false;
  bool same = true;
  LasAttributes::for_each_vector_pair(
      a.las, b.las, [&](const auto& x, const auto& y, std::uint32_t) { same = same && x == y; });
  return same;
}

}  // namespace

TEST_CASE("spool: every attribute back exactly, in any batch size", "[ingest][spool]") {
  TempDir dir;
  const Vec3d offset{500000.25, 4200000.5, -12.0}, scale{0.01, 0.01, 0.001};
  auto made = Spool::create(dir.path().string(), {true, false, true, true}, 1000);
  REQUIRE(made.is_ok());
  std::shared_ptr<Spool> spool = std::move(*made);
  // Input 0: two batches on its LAS grid (x y z as integers); input 2: off
  // its grid (x y z as doubles) and one batch without a grid; input 3 holds
  // no point. Input 1 is not spooled: its batches are ignored.
  const PointCloud a1 = spool_cloud(700, 1, offset, scale, true),
                   a2 = spool_cloud(650, 2, offset, scale, true);
  const PointCloud b1 = spool_cloud(300, 3, offset, scale, false),
                   b2 = spool_cloud(20, 4, offset, scale, true);
  spool->append(0, a1, offset, scale);
  spool->append(0, a2, offset, scale);
  spool->append(1, a1, offset, scale);
  spool->append(2, b1, offset, scale);
  spool->append(2, b2, Vec3d{0, 0, 0}, Vec3d{0, 0, 0});
  REQUIRE(spool->failure().empty());
  PointStreamInfo info0, info2, info3;
  info0.path = "first.laz";
  info0.warnings = {"a warning only reading found"};
  info2.path = "second.csv";
  info3.path = "empty.laz";
  spool->finish(0, info0);
  spool->finish(2, info2);
  spool->finish(3, info3);
  CHECK_FALSE(fs::exists(spool->file(1)));
  // On the grid 12 bytes of x y z a point, off it 24.
  CHECK(fs::file_size(spool->file(0)) == 2 * (24 + 48) + 1350 * (12 + kPerPoint));
  CHECK(fs::file_size(spool->file(2)) == 2 * 24 + 320 * (24 + kPerPoint));

  PointCloud a = a1;
  a.append_points(a2);
  PointCloud b = b1;
  b.append_points(b2);
  for (const std::size_t max :
       {std::size_t{1}, std::size_t{333}, std::size_t{699}, std::size_t{700}, std::size_t{5000}}) {
    CAPTURE(max);
    // A spool reader deletes its file at the end: a fresh spool each time.
    TempDir d2;
    std::shared_ptr<Spool> s = *Spool::create(d2.path().string(), {true}, 1000);
    s->append(0, a1, offset, scale);
    s->append(0, a2, offset, scale);
    s->finish(0, info0);
    std::unique_ptr<PointReader> r = s->reader(0);
    CHECK(r->info().path == "first.laz");
    CHECK(r->info().warnings == info0.warnings);
    const PointCloud got = read_all(*r, max);
    CHECK(same_points(got, a));
    CHECK_FALSE(fs::exists(s->file(0)));
  }
  std::unique_ptr<PointReader> r2 = spool->reader(2);
  CHECK(same_points(read_all(*r2, 128), b));
  CHECK_FALSE(fs::exists(spool->file(2)));
  std::unique_ptr<PointReader> r3 = spool->reader(3);
  PointCloud none;
  auto got = r3->read(none, 100);
  REQUIRE(got.is_ok());
  CHECK(*got == 0);
  // The directory goes with the spool and its readers.
  const std::string spool_dir = fs::path(spool->file(0)).parent_path().string();
  r2.reset();
  r3.reset();
  spool.reset();
  CHECK_FALSE(fs::exists(spool_dir));
  CHECK(dir.entries().empty());
}

TEST_CASE("spool: a reader gives back the disk of what it has read", "[ingest][spool]") {
  TempDir dir;
  const Vec3d offset{0, 0, 0}, scale{0.01, 0.01, 0.01};
  // Holes after every batch read (1 byte or more at a time).
  std::shared_ptr<Spool> s = *Spool::create(dir.path().string(), {true}, 1000, 1);
  PointCloud all;
  for (std::uint64_t b = 0; b < 3; ++b) {
    const PointCloud c = spool_cloud(1000, 20 + b, offset, scale, true);
    s->append(0, c, offset, scale);
    if (all.empty()) {
      all = c;
    } else {
      all.append_points(c);
    }
  }
  s->finish(0, PointStreamInfo{});
  const std::string file = s->file(0);
  const auto allocated = [&] {
    struct stat st {};
    REQUIRE(::stat(file.c_str(), &st) == 0);
    return static_cast<std::uint64_t>(st.st_blocks) * 512;
  };
  const std::uint64_t size = fs::file_size(file), before = allocated();
  std::unique_ptr<PointReader> r = s->reader(0);
  PointCloud got, batch;
  for (int k = 0; k < 2; ++k) {  // the first batch, then one point of the second
    auto n = r->read(batch, k == 0 ? 1000 : 1);
    REQUIRE(n.is_ok());
    if (got.empty()) {
      got = batch;
    } else {
      got.append_points(batch);
    }
  }
  const std::uint64_t after = allocated();
  if (before >= size) {
    // The first batch (a third of the file) is a hole now.
    CHECK(after + size / 4 < before);
  } else {
    WARN("the file system allocates " << before << " of " << size << " bytes: holes not checked");
  }
  got.append_points(read_all(*r, 700));
  CHECK(same_points(got, all));
  CHECK_FALSE(fs::exists(file));
}

TEST_CASE("spool: a damaged file is an error naming it and its input, never a crash",
          "[ingest][spool][reject]") {
  const Vec3d offset{0, 0, 0}, scale{0.01, 0.01, 0.01};
  const PointCloud c = spool_cloud(500, 5, offset, scale, true);
  const auto damaged_read = [&](const std::function<void(const std::string&)>& damage) {
    TempDir dir;
    std::shared_ptr<Spool> s = *Spool::create(dir.path().string(), {true}, 1000);
    s->append(0, c, offset, scale);
    s->append(0, c, offset, scale);
    PointStreamInfo info;
    info.path = "survey.laz";
    s->finish(0, info);
    damage(s->file(0));
    std::unique_ptr<PointReader> r = s->reader(0);
    PointCloud batch;
    for (;;) {
      auto got = r->read(batch, 400);
      if (!got.is_ok()) return got.status();
      if (*got == 0) return Status::ok();
    }
  };
  const auto resize = [](std::uint64_t bytes) {
    return [bytes](const std::string& f) { fs::resize_file(f, bytes); };
  };
  const auto poke = [](std::uint64_t at, char v) {
    return [at, v](const std::string& f) {
      std::fstream s(f, std::ios::in | std::ios::out | std::ios::binary);
      s.seekp(static_cast<std::streamoff>(at));
      s.put(v);
    };
  };
  // A batch on the grid: its header, the grid, 500 points.
  const std::uint64_t batch_bytes = 24 + 48 + 500 * (12 + kPerPoint);
  struct Case {
    const char* what;
    std::function<void(const std::string&)> damage;
  };
  const std::vector<Case> cases = {
      {"cut in the second batch's columns", resize(2 * batch_bytes - 100)},
      {"cut in the second header", resize(batch_bytes + 10)},
      {"a bad magic", poke(batch_bytes, 'X')},
      {"a huge count", poke(batch_bytes + 7, '\x7f')},
      {"unknown flags", poke(batch_bytes + 8, '\x40')},
  };
  for (const Case& k : cases) {
    CAPTURE(k.what);
    const Status st = damaged_read(k.damage);
    REQUIRE_FALSE(st.is_ok());
    CHECK(st.code() == StatusCode::kCorruptData);
    CHECK(st.message().find("survey.laz") != std::string::npos);
    CHECK(st.message().find("input-0") != std::string::npos);
  }
  // Deleted under the reader: an I/O error naming it.
  const Status gone = damaged_read([](const std::string& f) { fs::remove(f); });
  REQUIRE_FALSE(gone.is_ok());
  CHECK(gone.message().find("input-0") != std::string::npos);
}

TEST_CASE("spool: a write error abandons it, removing its files", "[ingest][spool][reject]") {
  TempDir dir;
  const Vec3d offset{0, 0, 0}, scale{0.01, 0.01, 0.01};
  std::shared_ptr<Spool> s = *Spool::create(dir.path().string(), {true, true}, 1000);
  s->append(0, spool_cloud(100, 6, offset, scale, true), offset, scale);
  s->finish(0, PointStreamInfo{});
  REQUIRE(fs::exists(s->file(0)));
  // Files of at most 64 KiB (as a full disk, write() fails part way).
  with_file_size_limit(64 << 10,
                       [&] { s->append(1, spool_cloud(5000, 7, offset, scale, false), offset, scale); });
  CHECK(s->failure().find(s->file(1)) != std::string::npos);
  CHECK_FALSE(fs::exists(s->file(0)));
  CHECK_FALSE(fs::exists(s->file(1)));
  // Later calls do nothing.
  s->append(1, spool_cloud(10, 8, offset, scale, true), offset, scale);
  s->finish(1, PointStreamInfo{});
  CHECK_FALSE(fs::exists(s->file(1)));
}

TEST_CASE("compress: spooled LAZ and text inputs give the blobs of inputs read twice", "[ingest][spool]") {
  TempDir dir;
  // A LAZ survey tile with every LAS 1.2 attribute, and a CSV beside it
  // (text states no count, so the ingest never holds it whole in memory and
  // the pass reads every point first).
  const Vec3d offset{1000, 2000, 0}, scale{0.01, 0.01, 0.01};
  PointCloud tile;
  test::Rng rng(11);
  for (std::size_t i = 0; i < 60000; ++i) {
    const double x = 1000 + 0.01 * static_cast<double>(rng.next() % 30000);
    const double y = 2000 + 0.01 * static_cast<double>(rng.next() % 30000);
    tile.positions.push_back(Vec3d{x, y, 0.01 * std::round(100 * (0.1 * x + 0.05 * y))});
    tile.colors.push_back(Rgb8{static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(i >> 3), 7});
    tile.intensities.push_back(static_cast<float>(i % 4000));
  }
  const std::uint32_t las = kLasClassification | kLasReturnNumber | kLasNumberOfReturns | kLasGpsTime |
                            kLasPointSourceId | kLasScanAngle | kLasUserData | kLasClassFlags | kLasScanFlags;
  test::add_las_attributes(tile, las, 0, 12, false);
  for (auto& a : tile.las.scan_angle) a = a / 1000 * 1000;
  for (auto& c : tile.las.classification) c &= 31;
  for (auto& f : tile.las.class_flags) f &= 7;
  for (auto& f : tile.las.scan_flags) f &= 3;
  for (auto& r : tile.las.return_number) r = static_cast<std::uint8_t>(std::clamp<int>(r, 1, 7));
  for (auto& r : tile.las.number_of_returns) r = static_cast<std::uint8_t>(std::clamp<int>(r, 1, 7));
  WriterOptions wo;
  wo.colors = wo.intensity = true;
  wo.las_attributes = las;
  wo.las_point_format = 3;
  wo.las_version_minor = 2;
  wo.grid_scale = scale;
  wo.grid_offset = offset;
  {
    auto w = open_point_writer(dir.file("tile.laz"), wo);
    REQUIRE(w.is_ok());
    REQUIRE((*w)->write(tile).is_ok());
    REQUIRE((*w)->finish().is_ok());
  }
  // Text: one wholly within the first points the ingest reads (before the
  // pass), one beyond them.
  const auto write_csv = [&](const std::string& name, std::size_t n) {
    std::ofstream csv(dir.file(name));
    csv << "x,y,z,r,g,b,i\n";
    for (std::size_t i = 0; i < n; ++i) {
      csv << 1100 + 0.01 * static_cast<double>(i % 997) << "," << 2100 + 0.02 * static_cast<double>(i % 509)
          << "," << 0.5 * static_cast<double>(i % 13) << "," << i % 256 << "," << (i * 7) % 256 << ",3,"
          << i % 1000 << "\n";
    }
  };
  write_csv("small.csv", 20000);
  write_csv("big.csv", 171072);  // 40,000 points past the first 2^17
  // ASCII PLY and PCD parse as slowly as text: spooled too (binary ones are not).
  {
    std::ofstream ply(dir.file("scan.ply"));
    ply << "ply\nformat ascii 1.0\nelement vertex 30000\nproperty double x\nproperty double y\n"
           "property double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n";
    for (std::size_t i = 0; i < 30000; ++i) {
      ply << 1200 + 0.01 * static_cast<double>(i % 991) << " " << 2050 + 0.01 * static_cast<double>(i % 577) << " "
          << 0.25 * static_cast<double>(i % 7) << " " << i % 256 << " 5 " << (i * 3) % 256 << "\n";
    }
    std::ofstream pcd(dir.file("scan.pcd"));
    pcd << "VERSION 0.7\nFIELDS x y z intensity\nSIZE 8 8 8 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 20000\n"
           "HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 20000\nDATA ascii\n";
    for (std::size_t i = 0; i < 20000; ++i) {
      pcd << 1250 + 0.02 * static_cast<double>(i % 499) << " " << 2120 + 0.01 * static_cast<double>(i % 811) << " "
          << 0.5 * static_cast<double>(i % 5) << " " << i % 300 << "\n";
    }
  }
  const std::vector<std::string> inputs = {dir.file("small.csv"), dir.file("tile.laz"), dir.file("big.csv"),
                                           dir.file("scan.ply"), dir.file("scan.pcd")};
  IngestOptions o;
  o.tmp_dir = dir.file("tmp");
  o.chunk_edge = 64;
  fs::create_directory(o.tmp_dir);
  auto spooled = compress_files(inputs, dir.file("spooled.relief"), o);
  REQUIRE(spooled.is_ok());
  o.spool = false;
  auto twice = compress_files(inputs, dir.file("twice.relief"), o);
  REQUIRE(twice.is_ok());
  CHECK(spooled->points_read == 301072);
  CHECK(spooled->points_decoded == 301072);
  CHECK(spooled->warnings == twice->warnings);
  // The tile's 60,000 points (42 bytes each), the big text's 171,072 (31
  // bytes), the PLY's 30,000 (27) and the PCD's 20,000 (28) went through it.
  CHECK(spooled->spooled_bytes > 60000 * 42 + 171072 * 31 + 30000 * 27 + 20000 * 28);
  CHECK(twice->spooled_bytes == 0);
  const auto blobs = test::archive_blobs(dir.file("spooled.relief"));
  CHECK(blobs.size() > 1);
  CHECK(blobs == test::archive_blobs(dir.file("twice.relief")));
  CHECK(TempDir::list(o.tmp_dir).empty());

  // A spool that cannot be written (files of at most 6 MiB: the spool's
  // first batch, 300,000 points of 31 bytes, is larger, every bucket file
  // (a quarter of 431,072 points of 19 bytes over 200 chunks) and the
  // archive smaller) falls
  // back to reading the inputs twice, with a warning, and the same blobs.
  {
    std::ofstream csv(dir.file("wide.csv"));
    csv << "x,y,z,r,g,b,i\n";
    for (std::size_t i = 0; i < 431072; ++i) {
      csv << 0.01 * static_cast<double>(i * 7919 % 100000) << ","
          << 0.01 * static_cast<double>(i * 104729 % 80000) << "," << 0.5 * static_cast<double>(i % 13) << ","
          << i % 256 << ",9," << (i * 3) % 256 << "," << i % 1000 << "\n";
    }
  }
  o.spool = true;
  Result<IngestResult> fallback = internal_error("not run");
  with_file_size_limit(
      6 << 20, [&] { fallback = compress_files({dir.file("wide.csv")}, dir.file("fallback.relief"), o); });
  INFO(fallback.status().message());
  REQUIRE(fallback.is_ok());
  CHECK(fallback->spooled_bytes == 0);
  REQUIRE(fallback->warnings.size() == 1);
  CHECK(fallback->warnings[0].find("read a second time") != std::string::npos);
  o.spool = false;
  REQUIRE(compress_files({dir.file("wide.csv")}, dir.file("csv_twice.relief"), o).is_ok());
  CHECK(test::archive_blobs(dir.file("fallback.relief")) ==
        test::archive_blobs(dir.file("csv_twice.relief")));
  CHECK(TempDir::list(o.tmp_dir).empty());
}

TEST_CASE("compress: the pass that fixes the grid reports its progress and stops when cancelled",
          "[ingest][spool][progress]") {
  TempDir dir;
  {
    std::ofstream csv(dir.file("p.csv"));
    csv << "x,y,z,i\n";
    for (std::size_t i = 0; i < 150000; ++i) {
      csv << 0.01 * static_cast<double>(i * 7919 % 30000) << ","
          << 0.01 * static_cast<double>(i * 104729 % 20000) << "," << 0.5 * static_cast<double>(i % 13) << ","
          << i % 1000 << "\n";
    }
  }
  for (const bool spool : {true, false}) {
    CAPTURE(spool);
    IngestOptions o;
    o.spool = spool;
    o.tmp_dir = dir.file("tmp");
    fs::create_directories(o.tmp_dir);
    // The first progress call of a phase is never throttled: the pass's
    // first batch reports "scanning", before any "reading".
    std::vector<std::string> phases;
    o.progress = [&](const IngestProgress& p) {
      if (phases.empty() || phases.back() != p.phase) phases.emplace_back(p.phase);
    };
    const std::string out = dir.file(spool ? "a.relief" : "b.relief");
    REQUIRE(compress_files({dir.file("p.csv")}, out, o).is_ok());
    REQUIRE(phases.size() >= 3);
    CHECK(phases.front() == "scanning");
    CHECK(phases[1] == "reading");
    CHECK(phases.back() == "done");
    // Cancelled while scanning: "interrupted", no archive, no temporary file.
    std::atomic<bool> stop{false};
    o.cancel = &stop;
    o.progress = [&](const IngestProgress& p) {
      if (std::string(p.phase) == "scanning") stop = true;
    };
    const std::string stopped = dir.file("stopped.relief");
    auto r = compress_files({dir.file("p.csv")}, stopped, o);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kIoError);
    CHECK(r.status().message().find("interrupted") != std::string::npos);
    CHECK_FALSE(fs::exists(stopped));
    CHECK(TempDir::list(o.tmp_dir).empty());
  }
}
