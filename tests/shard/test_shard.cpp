// The sharded build: plan, partition, encode and merge give the archive a
// one-box compress_files gives (same blobs byte for byte, same metadata), for
// any number of shards; merge refuses shards that do not fit together; a
// stage run again writes the same files.
#include <catch2/catch.hpp>

#include <algorithm>
#include <atomic>
#include <limits>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <tuple>

#include "core/host.h"
#include "relief/archive.h"
#include "relief/ingest.h"
#include "relief/io.h"
#include "relief/query.h"
#include "relief/shard.h"
#include "support/dead_pid.h"
#include "support/dense_surface.h"
#include "support/las_records.h"
#include "support/open_file_limit.h"
#include "support/run_cli.h"
#include "support/sanitized.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"

using namespace relief;
using relief::test::TempDir;

namespace {

struct Scene {
  std::uint64_t seed;
  std::size_t points;
  std::size_t inputs;
  bool colors;
  bool intensity;
  Vec3d offset;
  double tolerance;    // 0 = automatic
  double chunk_edge;   // 0 = automatic
  std::uint64_t split_points;
  double gap = 0;  // the terrain this far beside the room (x)
};

PointCloud make_scene(const Scene& s) {
  test::SceneOptions o;
  o.seed = s.seed;
  o.points = s.points / 2;
  o.colors = s.colors;
  o.intensity = s.intensity;
  o.noise = 0.003;
  o.offset = s.offset;
  PointCloud a = test::make_room(o, 8.0);
  o.seed = s.seed + 1;
  PointCloud b = test::make_terrain(o, 8.0, 0.4);
  for (Vec3d& p : b.positions) p.x += s.gap;
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  a.colors.insert(a.colors.end(), b.colors.begin(), b.colors.end());
  a.intensities.insert(a.intensities.end(), b.intensities.begin(), b.intensities.end());
  return a;
}

// The scene cut into `inputs` PLY files, interleaved (so every file spans the
// whole scene and every range gets points from every input).
std::vector<std::string> write_inputs(const TempDir& dir, const Scene& s) {
  const PointCloud all = make_scene(s);
  std::vector<std::string> paths;
  for (std::size_t k = 0; k < s.inputs; ++k) {
    PointCloud part;
    for (std::size_t i = k; i < all.size(); i += s.inputs) {
      part.positions.push_back(all.positions[i]);
      if (s.colors) part.colors.push_back(all.colors[i]);
      if (s.intensity) part.intensities.push_back(all.intensities[i]);
    }
    paths.push_back(dir.file("in" + std::to_string(k) + ".ply"));
    REQUIRE(write_ply(paths.back(), part).is_ok());
  }
  return paths;
}

IngestOptions options_for(const Scene& s) {
  IngestOptions o;
  o.tolerance = s.tolerance;
  o.chunk_edge = s.chunk_edge;
  o.split_points = s.split_points;
  o.threads = 2;
  return o;
}

// One chunk row as compared: key, bounds, counts, codec, parameters, blob.
using Row = std::tuple<std::int64_t, std::int64_t, std::int64_t, double, double, double, double, double, double,
                       std::uint64_t, std::uint64_t, std::uint32_t, std::string, std::vector<std::uint8_t>>;

// Every point of an archive, in the order a query returns them.
std::vector<Vec3d> query_positions(const std::string& path) {
  std::vector<Vec3d> out;
  auto reader = ArchiveReader::open(path);
  REQUIRE(reader.is_ok());
  QueryOptions q;
  q.threads = 2;
  const auto r = (*reader)->query_all(q, [&](const PointCloud& batch) {
    out.insert(out.end(), batch.positions.begin(), batch.positions.end());
    return Status::ok();
  });
  REQUIRE(r.is_ok());
  return out;
}

// The SQLite header's page size (big-endian at offset 16; 1 means 65536).
int page_size_of(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  unsigned char header[18] = {};
  if (!f.read(reinterpret_cast<char*>(header), sizeof header)) return 0;
  const int v = (header[16] << 8) | header[17];
  return v == 1 ? 65536 : v;
}

std::vector<Row> rows_of(const std::string& path) {
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto refs = (*archive)->all_chunks();
  REQUIRE(refs.is_ok());
  std::vector<Row> rows;
  for (const ChunkRef& ref : *refs) {
    auto row = (*archive)->read_chunk(ref.id);
    REQUIRE(row.is_ok());
    const Box3d& b = ref.bounds;
    rows.emplace_back(ref.key.ix, ref.key.iy, ref.key.iz, b.min.x, b.min.y, b.min.z, b.max.x, b.max.y, b.max.z,
                      ref.input_points, ref.decoded_points, row->codec, row->codec_params, row->blob);
  }
  std::sort(rows.begin(), rows.end());
  return rows;
}

ArchiveInfo info_of(const std::string& path) {
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto info = (*archive)->info();
  REQUIRE(info.is_ok());
  return *info;
}

void check_same_metadata(const ArchiveInfo& a, const ArchiveInfo& b) {
  CHECK(a.format_version == b.format_version);
  CHECK(a.las_attributes == b.las_attributes);
  CHECK(a.las_point_format == b.las_point_format);
  CHECK(a.las_version_minor == b.las_version_minor);
  CHECK(a.extra_bytes_vlr == b.extra_bytes_vlr);
  CHECK(a.extra_bytes_size == b.extra_bytes_size);
  CHECK(a.las_colors_8bit == b.las_colors_8bit);
  CHECK(a.las_gps_time_type == b.las_gps_time_type);
  CHECK(a.grid.origin == b.grid.origin);
  CHECK(a.grid.chunk_edge == b.grid.chunk_edge);
  CHECK(a.codec_params == b.codec_params);
  CHECK(a.creator == b.creator);
  CHECK(a.crs == b.crs);
  CHECK(a.crs_source == b.crs_source);
  CHECK(a.has_colors == b.has_colors);
  CHECK(a.has_intensity == b.has_intensity);
  CHECK(a.input_points == b.input_points);
  CHECK(a.decoded_points == b.decoded_points);
  CHECK(a.chunk_count == b.chunk_count);
  CHECK(a.blob_bytes == b.blob_bytes);
  CHECK(a.bounds.min == b.bounds.min);
  CHECK(a.bounds.max == b.bounds.max);
  CHECK(a.point_bounds.min == b.point_bounds.min);  // merge carries relief_chunk_extent
  CHECK(a.point_bounds.max == b.point_bounds.max);
  REQUIRE(a.sources.size() == b.sources.size());
  for (std::size_t i = 0; i < a.sources.size(); ++i) {
    CHECK(a.sources[i].path == b.sources[i].path);
    CHECK(a.sources[i].las == b.sources[i].las);
    CHECK(a.sources[i].format == b.sources[i].format);
    CHECK(a.sources[i].point_count == b.sources[i].point_count);
    CHECK(a.sources[i].crs == b.sources[i].crs);
  }
  REQUIRE(a.scans.size() == 1);
  REQUIRE(b.scans.size() == 1);
  CHECK(a.scans[0].complete == b.scans[0].complete);
}

std::vector<std::uint8_t> file_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

// Two Extra Bytes descriptors (3 bytes per point: a u16 and a u8 field).
std::vector<std::uint8_t> extra_vlr() {
  std::vector<std::uint8_t> v = test::extra_bytes_descriptor(3, 0, "height_above_ground");
  const std::vector<std::uint8_t> b = test::extra_bytes_descriptor(1, 0, "confidence");
  v.insert(v.end(), b.begin(), b.end());
  return v;
}

// A LAS file of random records (tests/support/las_records.h) over a 24 m
// square, with 3 extra bytes per point when `extra`.
std::string las_input(const TempDir& dir, const std::string& name, int format, std::uint32_t seed, bool extra,
                      bool wide_colors = true, std::size_t points = 12000) {
  test::TestLasOptions o;
  o.format = format;
  o.points = points;
  o.seed = seed;
  o.extent = 24;
  o.wide_colors = wide_colors;
  o.file_source_id = static_cast<std::uint16_t>(seed);
  // A record every input has and one of its own (an extended VLR in 1.4),
  // which the archive keeps per source and LAS output gives back.
  o.vlrs = {{"TestVendor", 7, "shared", {1, 2, 3}, false},
            {"TestVendor", 8, name, std::vector<std::uint8_t>(name.begin(), name.end()), format >= 6}};
  if (extra) {
    o.extra = 3;
    o.extra_bytes_vlr = extra_vlr();
  }
  const std::string path = dir.file(name);
  REQUIRE(test::write_test_las(path, o));
  return path;
}

// Stages 0-2 in `work` (partition files in work/parts); returns the shards.
std::vector<std::string> build_shards(const std::vector<std::string>& inputs, const IngestOptions& o,
                                      std::uint32_t ranges, const std::string& work, ShardPlan* plan_out = nullptr) {
  std::filesystem::create_directories(work + "/parts");
  ShardPlanOptions po;
  po.ingest = o;
  po.ranges = ranges;
  auto plan = plan_shards(inputs, po);
  REQUIRE(plan.is_ok());
  // Every stage reads the plan from its file, as tasks on other machines do.
  REQUIRE(write_shard_plan(*plan, work + "/plan.txt").is_ok());
  auto reread = read_shard_plan(work + "/plan.txt");
  REQUIRE(reread.is_ok());
  CHECK(shard_plan_text(*reread) == shard_plan_text(*plan));
  for (std::uint32_t i = 0; i < reread->input_count(); ++i) {
    auto r = partition_input(*reread, i, work + "/parts");
    REQUIRE(r.is_ok());
  }
  std::vector<std::string> shards;
  for (std::uint32_t r = 0; r < reread->range_count(); ++r) {
    shards.push_back(work + "/shard-" + std::to_string(r) + ".relief");
    EncodeShardOptions eo;
    eo.threads = 2;
    auto e = encode_shard(*reread, r, work + "/parts", shards.back(), eo);
    REQUIRE(e.is_ok());
  }
  if (plan_out != nullptr) *plan_out = *reread;
  return shards;
}

}  // namespace

TEST_CASE("shard plan: its pass reports progress and stops when cancelled", "[shard][progress]") {
  TempDir dir;
  const std::vector<std::string> inputs = {las_input(dir, "a.las", 3, 1, false), las_input(dir, "b.las", 3, 2, false)};
  ShardPlanOptions po;
  std::vector<std::string> phases;
  po.ingest.progress = [&](const IngestProgress& p) {
    if (phases.empty() || phases.back() != p.phase) phases.emplace_back(p.phase);
  };
  REQUIRE(plan_shards(inputs, po).is_ok());
  REQUIRE_FALSE(phases.empty());
  CHECK(phases.front() == "scanning");
  std::atomic<bool> stop{false};
  po.ingest.cancel = &stop;
  po.ingest.progress = [&](const IngestProgress&) { stop = true; };
  auto r = plan_shards(inputs, po);
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().message().find("interrupted") != std::string::npos);
}

TEST_CASE("sharded build: the merged archive equals a one-box compress", "[shard]") {
  const Scene scenes[] = {
      // Many chunks, some split into octants, colours and intensity.
      {11, 120000, 3, true, true, {0, 0, 0}, 0, 1.5, 3000},
      // Georeferenced offsets, a given tolerance, no attributes, four inputs.
      {21, 80000, 4, false, false, {431000.0, 5200000.0, 120.0}, 0.002, 2.0, kMaxBoundedChunkPoints},
      // Every parameter automatic, two inputs; two clusters far apart, so
      // even the automatic (large) chunks are several.
      {31, 60000, 2, true, false, {0, 0, 0}, 0, 0, kMaxBoundedChunkPoints, 500.0},
  };
  for (const Scene& s : scenes) {
    TempDir dir;
    const std::vector<std::string> inputs = write_inputs(dir, s);
    const IngestOptions o = options_for(s);
    auto one = compress_files(inputs, dir.file("one.relief"), o);
    REQUIRE(one.is_ok());
    const std::vector<Row> want = rows_of(dir.file("one.relief"));
    const ArchiveInfo want_info = info_of(dir.file("one.relief"));
    CHECK(want.size() >= 2);
    // Under the sanitizers 1 and 3 ranges (as the LAS scenes below), else 1 to 4.
    for (std::uint32_t ranges = 1; ranges <= 4; ranges += test::kSanitized ? 2 : 1) {
      INFO("scene seed " << s.seed << ", " << ranges << " ranges");
      const std::string work = dir.file("work" + std::to_string(ranges));
      ShardPlan plan;
      const std::vector<std::string> shards = build_shards(inputs, o, ranges, work, &plan);
      // Scenes with enough chunks really are cut into that many shards.
      if (want.size() >= 8) CHECK(plan.range_count() == ranges);
      auto merged = merge_archives(shards, work + "/merged.relief");
      REQUIRE(merged.is_ok());
      CHECK(merged->chunks == want.size());
      CHECK(rows_of(work + "/merged.relief") == want);
      check_same_metadata(info_of(work + "/merged.relief"), want_info);
      // The page size a one-box compress of these points takes.
      CHECK(page_size_of(work + "/merged.relief") == page_size_of(dir.file("one.relief")));
      // And a query returns the points in the same order, though the merge
      // wrote the rows in key order and the one-box build as its encoders
      // finished them (largest chunks first).
      CHECK(query_positions(work + "/merged.relief") == query_positions(dir.file("one.relief")));
      auto check = check_archive(work + "/merged.relief");
      REQUIRE(check.is_ok());
      CHECK(check->problems.empty());
      // Nothing but the finished files is left behind.
      for (const std::string& name : TempDir::list(work)) CHECK(name.find(".tmp-") == std::string::npos);
    }
  }
}

TEST_CASE("sharded build: a range larger than the stage-2 budget is sorted through files, with the same blobs",
          "[shard][split]") {
  TempDir dir;
  // 950 k points in one key range: a 650 k-point chunk (more than the two
  // slices of the 64 MiB budget, ~287 k points each: split into loads,
  // ingest/bucket_split.h) and a 300 k-point one. More than half the budget
  // holds (~860 k points), so encode_shard takes compress's external sort at
  // 64 MiB and reads the range whole at the default 1 GiB: the same rows.
  PointCloud all = test::dense_surface(650000, 7, true);
  PointCloud other = test::dense_surface(300000, 8);
  for (Vec3d& p : other.positions) p.x += 4;
  all.append_points(other);
  std::vector<std::string> inputs;
  for (int k = 0; k < 2; ++k) {
    PointCloud part;
    for (std::size_t i = static_cast<std::size_t>(k); i < all.size(); i += 2) part.positions.push_back(all.positions[i]);
    inputs.push_back(dir.file("in" + std::to_string(k) + ".ply"));
    REQUIRE(write_ply(inputs.back(), part).is_ok());
  }
  IngestOptions o;
  o.tolerance = 0.001;
  o.chunk_edge = 4;
  o.split_points = 1u << 16;
  o.threads = 2;
  ShardPlan plan;
  const std::vector<std::string> shards = build_shards(inputs, o, 1, dir.file("work"), &plan);
  REQUIRE(shards.size() == 1);
  const std::vector<Row> want = rows_of(shards[0]);
  CHECK(want.size() > 14);  // parts of at most 2^16 points
  EncodeShardOptions small;
  small.threads = 2;
  small.memory_budget = 64u << 20;
  small.tmp_dir = dir.file("tmp");
  std::filesystem::create_directories(small.tmp_dir);
  std::vector<IngestProgress> seen;
  small.progress = [&](const IngestProgress& p) { seen.push_back(p); };
  auto e = encode_shard(plan, 0, dir.file("work/parts"), dir.file("small.relief"), small);
  INFO((e ? std::string() : e.status().to_string()));
  REQUIRE(e.is_ok());
  CHECK(e->points_read == 950000);
  // Progress ends with "done" and every point (the others are rate-limited).
  REQUIRE_FALSE(seen.empty());
  CHECK(std::string(seen.back().phase) == "done");
  CHECK(seen.back().points_read == 950000);
  CHECK(seen.back().chunks_written == e->chunks_written);
  small.progress = nullptr;
  CHECK(rows_of(dir.file("small.relief")) == want);
  // The bucket files went, with their directory.
  CHECK(TempDir::list(dir.file("tmp")).empty());
  // Interrupted (Ctrl-C, SIGTERM: the CLI sets the flag), either way: an
  // error saying so, and neither the shard nor its bucket files are left.
  std::atomic<bool> stop{true};
  for (const std::uint64_t budget : {std::uint64_t{64} << 20, std::uint64_t{1} << 30}) {
    EncodeShardOptions cancelled = small;
    cancelled.memory_budget = budget;
    cancelled.cancel = &stop;
    auto c = encode_shard(plan, 0, dir.file("work/parts"), dir.file("cancelled.relief"), cancelled);
    REQUIRE_FALSE(c.is_ok());
    CHECK(c.status().message().find("interrupted") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir.file("cancelled.relief")));
    CHECK(TempDir::list(dir.file("tmp")).empty());
  }
  for (const std::string& name : TempDir::list(dir.path().string())) CHECK(name.find(".tmp-") == std::string::npos);
  // Stage 1 too: no partition file, no manifest.
  std::filesystem::create_directories(dir.file("parts2"));
  auto p = partition_input(plan, 0, dir.file("parts2"), &stop);
  REQUIRE_FALSE(p.is_ok());
  CHECK(p.status().message().find("interrupted") != std::string::npos);
  CHECK(TempDir::list(dir.file("parts2")).empty());
  // A tmp directory that is not there is an error naming it, and no shard.
  small.tmp_dir = dir.file("missing");
  auto bad = encode_shard(plan, 0, dir.file("work/parts"), dir.file("bad.relief"), small);
  REQUIRE_FALSE(bad.is_ok());
  CHECK(bad.status().message().find("missing") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(dir.file("bad.relief")));
  // The CLI takes the budget and refuses one below the minimum.
  const auto cli = test::run_cli(RELIEF_CLI, "shard-encode " + dir.file("work/plan.txt") + " --range 0 --dir " +
                                                 dir.file("work/parts") + " -o " + dir.file("cli.relief") +
                                                 " --memory 8M");
  CHECK(cli.code == 2);
  CHECK(cli.output.find("minimum") != std::string::npos);
}

TEST_CASE("sharded build: merge takes more shards than the process may hold open at once", "[shard]") {
  // A Slurm array's worth of shards under a limit of 48 open files (each
  // open archive holds three): merge opens a few at a time.
  TempDir dir;
  const Scene s{41, 60000, 2, true, true, {0, 0, 0}, 0, 1.0, kMaxBoundedChunkPoints};
  const std::vector<std::string> inputs = write_inputs(dir, s);
  const IngestOptions o = options_for(s);
  REQUIRE(compress_files(inputs, dir.file("one.relief"), o).is_ok());
  ShardPlan plan;
  const std::vector<std::string> shards = build_shards(inputs, o, 60, dir.file("work"), &plan);
  REQUIRE(plan.range_count() >= 40);
  const std::string merged = dir.file("merged.relief");
  REQUIRE(test::with_open_file_limit(48, [&] { return merge_archives(shards, merged).status(); }) == 0);
  CHECK(rows_of(merged) == rows_of(dir.file("one.relief")));
}

TEST_CASE("sharded build: the merged archive equals a one-box compress, LAS attributes included", "[shard][las]") {
  struct LasScene {
    const char* what;
    std::vector<std::string> (*inputs)(const TempDir&);
    std::uint32_t must_carry;  // LasAttributeBits the archive must show
    bool colors_8bit;          // what the archive must say of the colour levels
    AttributeSet keep = {};    // compress --attributes (in the plan: keep_attributes)
  };
  const LasScene scenes[] = {
      // Three point formats: 1.2 format 3 and 1.4 format 8 with the same extra
      // bytes, 1.4 format 7 without (its points carry zero extra bytes and NIR);
      // 16-bit colours, so the colour low bytes travel too.
      {"formats 3, 8, 7 with extra bytes",
       [](const TempDir& d) {
         return std::vector<std::string>{las_input(d, "a.las", 3, 1, true), las_input(d, "b.las", 8, 2, true),
                                         las_input(d, "c.las", 7, 3, false)};
       },
       kLasClassification | kLasReturnNumber | kLasGpsTime | kLasNir | kLasColorLow | kLasExtraBytes |
           kLasScanAngle | kLasPointSourceId,
       false},
      // 8-bit colour levels in 16-bit fields (the archive says so) and a
      // format without colours: colours and their low bytes are dropped.
      {"8-bit colours, then a format without colours",
       [](const TempDir& d) {
         return std::vector<std::string>{las_input(d, "a.las", 2, 4, true, false),
                                         las_input(d, "b.las", 3, 5, true, false),
                                         las_input(d, "c.las", 1, 6, true)};
       },
       kLasClassification | kLasGpsTime | kLasExtraBytes, true},
      // LAZ and its LAS twin (tests/data: LASzip point format 3).
      {"LAZ and LAS",
       [](const TempDir&) {
         const std::string data = std::string(RELIEF_SOURCE_DIR) + "/tests/data/";
         return std::vector<std::string>{data + "simple.laz", data + "simple.las"};
       },
       kLasClassification | kLasGpsTime | kLasColorLow, true},
      // Only some attributes kept: the plan records them, every stage reads
      // the inputs with them alone.
      {"formats 3 and 8, classification, GPS time and extra bytes kept",
       [](const TempDir& d) {
         return std::vector<std::string>{las_input(d, "a.las", 3, 7, true), las_input(d, "b.las", 8, 8, true)};
       },
       kLasClassification | kLasGpsTime | kLasExtraBytes, false,
       AttributeSet{false, false, kLasClassification | kLasGpsTime | kLasExtraBytes}},
  };
  for (const LasScene& s : scenes) {
    INFO(s.what);
    TempDir dir;
    const std::vector<std::string> inputs = s.inputs(dir);
    IngestOptions o;
    o.chunk_edge = 6;
    o.split_points = 2500;
    o.threads = 2;
    o.allow_sparse = true;
    o.reader.attributes = s.keep;
    auto one = compress_files(inputs, dir.file("one.relief"), o);
    REQUIRE(one.is_ok());
    const std::vector<Row> want = rows_of(dir.file("one.relief"));
    const ArchiveInfo want_info = info_of(dir.file("one.relief"));
    CHECK((want_info.las_attributes & s.must_carry) == s.must_carry);
    if (!s.keep.everything()) {
      CHECK(want_info.las_attributes == s.must_carry);
      CHECK_FALSE(want_info.has_colors);
      CHECK_FALSE(want_info.has_intensity);
    }
    CHECK(want_info.las_colors_8bit == s.colors_8bit);
    CHECK(want.size() >= 4);
    for (const std::uint32_t ranges : {1u, 3u}) {
      INFO(ranges << " ranges");
      const std::string work = dir.file("work" + std::to_string(ranges));
      ShardPlan plan;
      const std::vector<std::string> shards = build_shards(inputs, o, ranges, work, &plan);
      CHECK(plan.attributes.las_attributes == want_info.las_attributes);
      if (want.size() >= 8) CHECK(plan.range_count() == ranges);
      // Version 3: the inputs' LAS headers and records travel in the plan.
      CHECK(shard_plan_text(plan).rfind("relief-shard-plan\t3\n", 0) == 0);
      CHECK((shard_plan_text(plan).find("\nkeep_attributes\tclassification,gps_time,extra_bytes\n") !=
             std::string::npos) == !s.keep.everything());
      auto merged = merge_archives(shards, work + "/merged.relief");
      REQUIRE(merged.is_ok());
      CHECK(merged->chunks == want.size());
      CHECK(rows_of(work + "/merged.relief") == want);
      const ArchiveInfo got = info_of(work + "/merged.relief");
      check_same_metadata(got, want_info);
      auto check = check_archive(work + "/merged.relief");
      REQUIRE(check.is_ok());
      CHECK(check->problems.empty());
    }
  }
}

TEST_CASE("sharded build: the merged archive's pyramid equals a one-box compress's", "[shard][pyramid]") {
  const Scene s{61, 120000, 3, true, true, {0, 0, 0}, 0, 1.5, 3000};
  TempDir dir;
  const std::vector<std::string> inputs = write_inputs(dir, s);
  IngestOptions o = options_for(s);
  o.pyramid = PyramidMode::kOn;
  REQUIRE(compress_files(inputs, dir.file("one.relief"), o).is_ok());
  const auto levels_of = [](const std::string& path) {
    auto archive = Archive::open(path, Archive::Mode::kReadOnly);
    REQUIRE(archive.is_ok());
    const double inf = std::numeric_limits<double>::infinity();
    std::vector<std::pair<std::string, std::vector<std::uint8_t>>> out;
    for (int level = 1; level <= kMaxPyramidLevel; ++level) {
      auto refs = (*archive)->find_level_chunks(level, Box3d{{-inf, -inf, -inf}, {inf, inf, inf}});
      REQUIRE(refs.is_ok());
      for (const ChunkRef& ref : *refs) {
        auto row = (*archive)->read_level_chunk(ref.id);
        REQUIRE(row.is_ok());
        out.emplace_back(std::to_string(level) + ":" + std::to_string(ref.key.ix) + "," + std::to_string(ref.key.iy) +
                             "," + std::to_string(ref.key.iz),
                         row->blob);
      }
    }
    std::sort(out.begin(), out.end());
    return out;
  };
  const auto want = levels_of(dir.file("one.relief"));
  REQUIRE(want.size() >= 2);
  // The plan takes no pyramid (merge builds it): refused if given.
  ShardPlanOptions po;
  po.ingest = o;
  auto refused = plan_shards(inputs, po);
  REQUIRE_FALSE(refused.is_ok());
  CHECK(refused.status().message().find("merge builds it") != std::string::npos);
  IngestOptions plan_options = o;
  plan_options.pyramid = PyramidMode::kAuto;
  const std::vector<std::string> shards = build_shards(inputs, plan_options, 3, dir.file("work"), nullptr);
  MergeOptions mo;
  mo.pyramid = PyramidMode::kOn;
  auto merged = merge_archives(shards, dir.file("merged.relief"), mo);
  REQUIRE(merged.is_ok());
  CHECK(merged->pyramid.levels >= 1);
  CHECK(levels_of(dir.file("merged.relief")) == want);
  // The shards themselves carry no pyramid: the merge builds the one pyramid.
  CHECK(levels_of(shards[0]).empty());
}

TEST_CASE("sharded build: a stage run again writes the same files", "[shard]") {
  TempDir dir;
  const Scene s{41, 60000, 2, true, true, {0, 0, 0}, 0, 1.5, 4000};
  const std::vector<std::string> inputs = write_inputs(dir, s);
  ShardPlan plan;
  const std::vector<std::string> shards = build_shards(inputs, options_for(s), 3, dir.file("w"), &plan);
  REQUIRE(plan.range_count() == 3);
  const std::string parts = dir.file("w/parts");
  std::vector<std::vector<std::uint8_t>> before;
  for (const std::string& name : TempDir::list(parts)) before.push_back(file_bytes(parts + "/" + name));
  const std::vector<Row> shard_rows = rows_of(shards[1]);
  // A killed task's leftovers (a temporary file) do not disturb the retry;
  // those of a dead process of this host are swept by it, another host's
  // are left alone (its pids mean nothing here).
  { std::ofstream(parts + "/" + partition_file_name(1, 0) + ".tmp-deadhost-1") << "partial"; }
  const std::string dead = relief::test::dead_pid();
  REQUIRE_FALSE(dead.empty());
  const std::string stale = parts + "/" + partition_file_name(1, 2) + ".tmp-" + relief::core::host_tag() + "-" + dead;
  { std::ofstream(stale) << "partial"; }
  // The retries: input 1 partitioned again, range 1 encoded again.
  REQUIRE(partition_input(plan, 1, parts).is_ok());
  CHECK_FALSE(std::filesystem::exists(stale));
  REQUIRE(std::filesystem::exists(parts + "/" + partition_file_name(1, 0) + ".tmp-deadhost-1"));
  std::filesystem::remove(parts + "/" + partition_file_name(1, 0) + ".tmp-deadhost-1");
  std::vector<std::vector<std::uint8_t>> after;
  for (const std::string& name : TempDir::list(parts)) after.push_back(file_bytes(parts + "/" + name));
  CHECK(after == before);
  REQUIRE(encode_shard(plan, 1, parts, shards[1]).is_ok());
  CHECK(rows_of(shards[1]) == shard_rows);
  REQUIRE(merge_archives(shards, dir.file("merged.relief")).is_ok());
}

TEST_CASE("sharded build: stages and merge refuse what does not fit", "[shard]") {
  TempDir dir;
  const Scene s{51, 60000, 2, true, true, {0, 0, 0}, 0, 1.5, kMaxBoundedChunkPoints};
  const std::vector<std::string> inputs = write_inputs(dir, s);
  IngestOptions o = options_for(s);
  ShardPlan plan;
  const std::vector<std::string> shards = build_shards(inputs, o, 2, dir.file("a"), &plan);
  REQUIRE(shards.size() == 2);

  SECTION("the same shard twice") {
    auto r = merge_archives({shards[0], shards[0]}, dir.file("m.relief"));
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kInvalidArgument);
    CHECK(r.status().message().find("given twice") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir.file("m.relief")));
  }
  SECTION("a shard left out") {
    // It made an archive of fewer points that said it was complete.
    const std::vector<std::string> three = build_shards(inputs, o, 3, dir.file("c"));
    REQUIRE(three.size() == 3);
    auto r = merge_archives({three[0], three[2]}, dir.file("m.relief"));
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kInvalidArgument);
    CHECK(r.status().message().find("a shard of the plan is missing") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir.file("m.relief")));
    CHECK(merge_archives(three, dir.file("m.relief")).is_ok());
  }
  SECTION("overlapping shards (two plans' ranges)") {
    const std::vector<std::string> one = build_shards(inputs, o, 1, dir.file("b"));
    auto r = merge_archives({shards[0], one[0]}, dir.file("m.relief"));
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kInvalidArgument);
    CHECK(r.status().message().find("both hold chunk") != std::string::npos);
    CHECK(r.status().message().find(one[0]) != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir.file("m.relief")));
  }
  SECTION("shards of another plan (another tolerance)") {
    IngestOptions other = o;
    other.tolerance = 0.004;
    const std::vector<std::string> b = build_shards(inputs, other, 2, dir.file("b"));
    auto r = merge_archives({shards[0], b[1]}, dir.file("m.relief"));
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kInvalidArgument);
    CHECK(r.status().message().find(b[1]) != std::string::npos);
    CHECK(r.status().message().find("not a shard of the same plan") != std::string::npos);
  }
  SECTION("an existing output is never overwritten") {
    { std::ofstream(dir.file("m.relief")) << "keep me"; }
    auto r = merge_archives(shards, dir.file("m.relief"));
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kIoError);
    CHECK(file_bytes(dir.file("m.relief")).size() == 7);
  }
  SECTION("an unfinished stage 1 and damaged partition files") {
    const std::string parts = dir.file("a/parts");
    const std::string file = parts + "/" + partition_file_name(1, 0);
    std::filesystem::rename(parts + "/" + partition_manifest_name(1), parts + "/moved");
    auto missing = encode_shard(plan, 0, parts, dir.file("x.relief"));
    REQUIRE_FALSE(missing.is_ok());
    CHECK(missing.status().message().find("stage 1 of input 1 has not finished") != std::string::npos);
    std::filesystem::rename(parts + "/moved", parts + "/" + partition_manifest_name(1));
    const std::vector<std::uint8_t> bytes = file_bytes(file);
    REQUIRE(bytes.size() > 100);
    std::filesystem::resize_file(file, bytes.size() - 5);
    auto truncated = encode_shard(plan, 0, parts, dir.file("x.relief"));
    REQUIRE_FALSE(truncated.is_ok());
    CHECK(truncated.status().code() == StatusCode::kCorruptData);
    CHECK(truncated.status().message().find(file) != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir.file("x.relief")));
    // A partition file of another plan.
    IngestOptions other = o;
    other.tolerance = 0.004;
    build_shards(inputs, other, 2, dir.file("b"));
    std::filesystem::copy_file(dir.file("b/parts/") + partition_file_name(1, 0), file,
                               std::filesystem::copy_options::overwrite_existing);
    auto foreign = encode_shard(plan, 0, parts, dir.file("x.relief"));
    REQUIRE_FALSE(foreign.is_ok());
    CHECK(foreign.status().message().find("another plan") != std::string::npos);
  }
  SECTION("an input changed since the plan") {
    auto cloud = read_point_file(inputs[1]);
    REQUIRE(cloud.is_ok());
    cloud->resize_points(cloud->size() / 2);
    REQUIRE(write_ply(inputs[1], *cloud).is_ok());
    REQUIRE(partition_input(plan, 1, dir.file("a/parts")).is_ok());
    auto r = encode_shard(plan, 0, dir.file("a/parts"), dir.file("x.relief"));
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kInvalidArgument);
    CHECK(r.status().message().find("changed since the plan") != std::string::npos);
  }
  SECTION("a damaged plan file") {
    const std::string text = shard_plan_text(plan);
    for (std::size_t cut : {std::size_t{0}, text.size() / 2, text.size() - 4}) {
      { std::ofstream(dir.file("p.txt"), std::ios::binary) << text.substr(0, cut); }
      auto r = read_shard_plan(dir.file("p.txt"));
      REQUIRE_FALSE(r.is_ok());
      CHECK(r.status().message().find(dir.file("p.txt")) != std::string::npos);
    }
  }
  SECTION("the resampling mode is refused") {
    ShardPlanOptions po;
    po.ingest = o;
    po.ingest.mode = IngestMode::kResample;
    auto r = plan_shards(inputs, po);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kInvalidArgument);
  }
  SECTION("a plan without LAS attributes is version 1, its partition files of version 1 still read") {
    CHECK(shard_plan_text(plan).rfind("relief-shard-plan\t1\n", 0) == 0);
    CHECK(shard_plan_text(plan).find("\nlas\t") == std::string::npos);
    // Every file of range 0 rewritten as version 1 (the 40-byte header
    // without the LAS fields): the shard is the same.
    const std::string parts = dir.file("a/parts");
    const std::vector<Row> before = rows_of(shards[0]);
    for (std::uint32_t i = 0; i < plan.input_count(); ++i) {
      const std::string file = parts + "/" + partition_file_name(i, 0);
      std::vector<std::uint8_t> bytes = file_bytes(file);
      REQUIRE(bytes.size() >= 48);
      REQUIRE(bytes[8] == 2);
      for (std::size_t k = 32; k < 40; ++k) REQUIRE(bytes[k] == 0);  // no LAS attributes, no extra bytes
      bytes.erase(bytes.begin() + 32, bytes.begin() + 40);
      bytes[8] = 1;
      std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                                  static_cast<std::streamsize>(bytes.size()));
    }
    REQUIRE(encode_shard(plan, 0, parts, dir.file("v1.relief")).is_ok());
    CHECK(rows_of(dir.file("v1.relief")) == before);
  }
}

TEST_CASE("sharded build: LAS inputs, refused and damaged as compress and the spec say", "[shard][las]") {
  TempDir dir;
  const std::string a = las_input(dir, "a.las", 3, 11, true);
  const std::string b = las_input(dir, "b.las", 6, 12, true);
  IngestOptions o;
  o.chunk_edge = 6;
  o.threads = 2;
  o.allow_sparse = true;

  SECTION("different Extra Bytes VLRs: the error compress gives") {
    test::TestLasOptions lo;
    lo.format = 3;
    lo.points = 2000;
    lo.extra = 3;
    lo.extra_bytes_vlr = test::extra_bytes_descriptor(0, 3, "opaque");
    const std::string c = dir.file("c.las");
    REQUIRE(test::write_test_las(c, lo));
    auto one = compress_files({a, c}, dir.file("x.relief"), o);
    REQUIRE_FALSE(one.is_ok());
    ShardPlanOptions po;
    po.ingest = o;
    auto planned = plan_shards({a, c}, po);
    REQUIRE_FALSE(planned.is_ok());
    CHECK(planned.status().code() == one.status().code());
    CHECK(planned.status().message() == one.status().message());
    CHECK(planned.status().message().find(c) != std::string::npos);
  }
  SECTION("damaged and foreign version 2 partition files") {
    ShardPlan plan;
    const std::vector<std::string> shards = build_shards({a, b}, o, 2, dir.file("w"), &plan);
    REQUIRE(plan.range_count() == 2);
    REQUIRE(plan.attributes.extra_bytes_size == 3);
    const std::string parts = dir.file("w/parts");
    const std::string file = parts + "/" + partition_file_name(1, 1);
    const std::vector<std::uint8_t> good = file_bytes(file);
    REQUIRE(good.size() > 48);
    const auto put = [&](const std::vector<std::uint8_t>& bytes) {
      std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(bytes.data()),
                                                  static_cast<std::streamsize>(bytes.size()));
    };
    const auto refused = [&](const char* what) {
      INFO(what);
      auto r = encode_shard(plan, 1, parts, dir.file("x.relief"));
      REQUIRE_FALSE(r.is_ok());
      CHECK(r.status().message().find(file) != std::string::npos);
      CHECK_FALSE(std::filesystem::exists(dir.file("x.relief")));
      return r.status();
    };
    std::vector<std::uint8_t> bytes = good;
    bytes[33] ^= static_cast<std::uint8_t>(kLasGpsTime >> 8);  // a LAS attribute less than the plan's
    put(bytes);
    CHECK(refused("LAS bits").message().find("LAS attributes") != std::string::npos);
    bytes = good;
    bytes[36] = 200;  // 200 extra bytes per point
    put(bytes);
    CHECK(refused("extra size").code() == StatusCode::kCorruptData);
    bytes = good;
    for (int k = 0; k < 8; ++k) bytes[40 + k] = 0xff;  // a point count far beyond the bytes present
    put(bytes);
    CHECK(refused("count").message().find("truncated or damaged") != std::string::npos);
    bytes = good;
    REQUIRE(!bytes.empty());
    bytes.pop_back();  // (not resize(size() - 1): GCC 12 under ASan warns, wrongly, of a huge memset)
    put(bytes);
    CHECK(refused("truncated").code() == StatusCode::kCorruptData);
    bytes = good;
    bytes[8] = 3;
    put(bytes);
    CHECK(refused("version").code() == StatusCode::kUnsupported);
    // A version 1 file cannot hold the plan's attributes.
    bytes = good;
    bytes.erase(bytes.begin() + 32, bytes.begin() + 40);
    bytes[8] = 1;
    put(bytes);
    CHECK(refused("version 1").message().find("version 1") != std::string::npos);
    put(good);
    const std::vector<Row> want = rows_of(shards[1]);
    REQUIRE(encode_shard(plan, 1, parts, dir.file("x.relief")).is_ok());
    CHECK(rows_of(dir.file("x.relief")) == want);
  }
  SECTION("an input whose LAS attributes changed since the plan") {
    ShardPlan plan;
    build_shards({a, b}, o, 1, dir.file("w"), &plan);
    // b rewritten with other extra bytes: stage 1 names it.
    test::TestLasOptions lo;
    lo.format = 6;
    lo.points = 2000;
    lo.extra = 5;
    lo.extra_bytes_vlr = test::extra_bytes_descriptor(0, 5, "opaque");
    REQUIRE(test::write_test_las(b, lo));
    auto r = partition_input(plan, 1, dir.file("w/parts"));
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find(b) != std::string::npos);
    CHECK(r.status().message().find("not the file the plan was made from") != std::string::npos);
  }
  SECTION("damaged LAS lines of a plan") {
    ShardPlanOptions po;
    po.ingest = o;
    auto plan = plan_shards({a, b}, po);
    REQUIRE(plan.is_ok());
    const std::string text = shard_plan_text(*plan);
    REQUIRE(text.find("\nlas\t") != std::string::npos);
    REQUIRE(text.find("\nextra_bytes\t3\t") != std::string::npos);
    const auto replaced = [&](const std::string& from, const std::string& to) {
      std::string t = text;
      const std::size_t at = t.find(from);
      REQUIRE(at != std::string::npos);
      t.replace(at, from.size(), to);
      return t;
    };
    const std::string bad[] = {
        replaced("relief-shard-plan\t3", "relief-shard-plan\t1"),    // LAS lines in a version 1 plan
        replaced("relief-shard-plan\t3", "relief-shard-plan\t2"),    // LAS headers in a version 2 plan
        replaced("\nlas_header\t4c415346", "\nlas_header\t4c415347"),  // not "LASF"
        replaced("\nlas_header\t4c", "\nlas_header\t4"),              // odd length
        replaced("\nlas_record\tvlr\t", "\nlas_record\tvrl\t"),       // neither vlr nor evlr
        replaced("\nlas_record\tvlr\t54", "\nlas_record\tvlr\t5454"), // a 17-byte user id
        replaced("\nlas_record\tvlr\t", "\nlas_record\t"),            // four fields
        replaced("\ninput\t", "\nlas_record\tvlr\t\t0\t\t\ninput\t"),   // before any input
        replaced("\nlas\tclassification", "\nlas\tclassificatio"), // an unknown name
        replaced("\nextra_bytes\t3\t", "\nextra_bytes\t0\t"),      // no extra bytes per point
        replaced("\nextra_bytes\t3\t", "\nextra_bytes\t3\tz"),     // not hexadecimal
        replaced("\nextra_bytes\t3\t", "\nextra_bytes\t3\t0"),     // odd length
        replaced("\nextra_bytes\t", "\nxtra_bytes\t"),               // an unknown key
    };
    for (const std::string& t : bad) {
      { std::ofstream(dir.file("p.txt"), std::ios::binary) << t; }
      auto r = read_shard_plan(dir.file("p.txt"));
      REQUIRE_FALSE(r.is_ok());
      CHECK(r.status().message().find(dir.file("p.txt")) != std::string::npos);
    }
    { std::ofstream(dir.file("p.txt"), std::ios::binary) << text; }
    auto r = read_shard_plan(dir.file("p.txt"));
    REQUIRE(r.is_ok());
    CHECK(shard_plan_text(*r) == text);
    const std::vector<std::uint8_t> vlr = extra_vlr();
    CHECK(r->attributes.extra_bytes_vlr == std::string(vlr.begin(), vlr.end()));
  }
}

TEST_CASE("sharded build: the CLI stages and merge, with their exit codes", "[shard][cli]") {
  using test::run_cli;
  TempDir dir;
  const Scene s{61, 40000, 2, true, true, {0, 0, 0}, 0, 1.5, kMaxBoundedChunkPoints};
  const std::vector<std::string> inputs = write_inputs(dir, s);
  const std::string cli = RELIEF_CLI;
  const std::string in = inputs[0] + " " + inputs[1];
  REQUIRE(run_cli(cli, "compress " + in + " -o " + dir.file("one.relief") + " --chunk-edge 1.5 --quiet").code == 0);
  std::filesystem::create_directories(dir.file("parts"));
  const std::string plan = dir.file("plan.txt");
  auto planned = run_cli(cli, "shard-plan " + in + " -o " + plan + " --chunk-edge 1.5 --ranges 2");
  REQUIRE(planned.code == 0);
  CHECK(planned.output.find("2 key ranges") != std::string::npos);
  for (int i = 0; i < 2; ++i) {
    REQUIRE(run_cli(cli, "shard-partition " + plan + " --input " + std::to_string(i) + " --dir " + dir.file("parts") +
                             " --quiet")
                .code == 0);
  }
  // Input 2 does not exist: exit 10 + kInvalidArgument.
  CHECK(run_cli(cli, "shard-partition " + plan + " --input 2 --dir " + dir.file("parts")).code == 11);
  for (int r = 0; r < 2; ++r) {
    REQUIRE(run_cli(cli, "shard-encode " + plan + " --range " + std::to_string(r) + " --dir " + dir.file("parts") +
                             " -o " + dir.file("s" + std::to_string(r) + ".relief") + " --quiet")
                .code == 0);
  }
  const std::string shards = dir.file("s0.relief") + " " + dir.file("s1.relief");
  REQUIRE(run_cli(cli, "merge " + shards + " -o " + dir.file("m.relief")).code == 0);
  CHECK(rows_of(dir.file("m.relief")) == rows_of(dir.file("one.relief")));
  // Never over an existing file (exit 10 + kIoError), never the same shard twice.
  auto again = run_cli(cli, "merge " + shards + " -o " + dir.file("m.relief"));
  CHECK(again.code == 12);
  CHECK(again.output.find("already exists") != std::string::npos);
  auto twice = run_cli(cli, "merge " + dir.file("s0.relief") + " " + dir.file("s0.relief") + " -o " +
                                dir.file("m2.relief"));
  CHECK(twice.code == 11);
  CHECK(twice.output.find("s0.relief") != std::string::npos);
  CHECK(run_cli(cli, "merge -o " + dir.file("m3.relief")).code == 2);
  // A shard left out is refused; --pyramid goes to merge, not to the plan.
  auto missing = run_cli(cli, "merge " + dir.file("s1.relief") + " -o " + dir.file("m4.relief"));
  CHECK(missing.code == 11);
  CHECK(missing.output.find("a shard of the plan is missing") != std::string::npos);
  CHECK(run_cli(cli, "shard-plan " + in + " -o " + dir.file("p2.txt") + " --chunk-edge 1.5 --pyramid on").code == 2);
  REQUIRE(run_cli(cli, "merge " + shards + " -o " + dir.file("m5.relief") + " --pyramid on --quiet").code == 0);
  REQUIRE(run_cli(cli, "compress " + in + " -o " + dir.file("one-p.relief") + " --chunk-edge 1.5 --pyramid on --quiet")
              .code == 0);
  const auto pyramid_of = [&](const std::string& a) {
    auto r = run_cli(cli, "info " + a + " --json");
    const std::size_t at = r.output.find("\"pyramid\"");
    return at == std::string::npos ? std::string() : r.output.substr(at, r.output.find(']', at) - at);
  };
  CHECK(pyramid_of(dir.file("m5.relief")).find("\"level\"") != std::string::npos);
  CHECK(rows_of(dir.file("m5.relief")) == rows_of(dir.file("one.relief")));
  CHECK(run_cli(cli, "merge " + shards + " -o " + dir.file("m6.relief") + " --pyramid sometimes").code == 2);
  // shard-encode replaces an earlier shard but no other file (an input, here).
  const std::string input_copy = dir.file("input-copy.ply");
  std::filesystem::copy_file(inputs[0], input_copy);
  auto over = run_cli(cli, "shard-encode " + plan + " --range 0 --dir " + dir.file("parts") + " -o " + input_copy);
  CHECK(over.code == 12);
  CHECK(over.output.find("not a Relief archive") != std::string::npos);
  CHECK(std::filesystem::file_size(input_copy) == std::filesystem::file_size(inputs[0]));
  CHECK(run_cli(cli, "shard-encode " + plan + " --range 0 --dir " + dir.file("parts") + " -o " + dir.file("s0.relief") +
                         " --quiet")
            .code == 0);
  CHECK(run_cli(cli, "shard-encode " + plan + " --dir " + dir.file("parts") + " -o x.relief").code == 2);
}
