// CLI tests with expected exit codes and messages (README "Exit codes").
#include <catch2/catch.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <tuple>

#include "relief/codec.h"
#include "relief/io.h"
#include "relief/polygon.h"
#include "support/run_cli.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;

using relief::test::TempDir;

namespace {

using Run = relief::test::CliRun;

Run run(const std::string& args) { return relief::test::run_cli(RELIEF_CLI, args); }


std::string sample() { return std::string(RELIEF_SOURCE_DIR) + "/tests/data/kinect_milk_scene_rgb.ply"; }

void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

std::string file_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

}  // namespace

TEST_CASE("relief roundtrip on the bundled sample prints size, bits per point and error", "[cli]") {
  TempDir tmp;
  const Run r = run("roundtrip " + sample() + " -o " + tmp.file("out.ply") + " --blob " + tmp.file("k.rlfc"));
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(r.output.find("bits/point") != std::string::npos);
  CHECK(r.output.find("RMSE_SNN") != std::string::npos);
  CHECK(r.output.find("points out (reconstructed)") != std::string::npos);
  CHECK(r.output.find("RMSE_RGB_SNN") != std::string::npos);
  CHECK(fs::file_size(tmp.file("k.rlfc")) > 1000);
  // The written reconstruction reads back and decode-chunk reproduces it.
  const Run d = run("decode-chunk " + tmp.file("k.rlfc") + " -o " + tmp.file("d.ply") + " --quiet");
  REQUIRE(d.code == 0);
  auto a = relief::read_ply(tmp.file("out.ply"));
  auto b = relief::read_ply(tmp.file("d.ply"));
  REQUIRE(a.is_ok());
  REQUIRE(b.is_ok());
  CHECK(a->positions == b->positions);
  const Run e = run("eval " + sample() + " " + tmp.file("d.ply") + " --json");
  REQUIRE(e.code == 0);
  CHECK(e.output.find("\"rmse_snn\"") != std::string::npos);
}

TEST_CASE("compress and append read LAZ, decompress writes it, info records it as laz", "[cli][laz]") {
  TempDir tmp;
  const std::string laz = std::string(RELIEF_SOURCE_DIR) + "/tests/data/simple.laz";
  const std::string las = std::string(RELIEF_SOURCE_DIR) + "/tests/data/simple.las";
  const std::string out = tmp.file("a.relief");
  const Run c = run("compress " + laz + " -o " + out + " --quiet");
  INFO(c.output);
  REQUIRE(c.code == 0);
  const Run a = run("append " + out + " " + las + " --quiet");
  INFO(a.output);
  REQUIRE(a.code == 0);
  const Run i = run("info " + out);
  REQUIRE(i.code == 0);
  CHECK(i.output.find("simple.laz (laz, 1065 points") != std::string::npos);
  CHECK(i.output.find("simple.las (las, 1065 points") != std::string::npos);
  CHECK(i.output.find("2130 in") != std::string::npos);
  // LAZ output: decompress and query write it, and it reads back like LAS.
  REQUIRE(run("decompress " + out + " -o " + tmp.file("d.laz") + " --quiet").code == 0);
  REQUIRE(run("decompress " + out + " -o " + tmp.file("d.las") + " --quiet").code == 0);
  auto from_laz = relief::read_point_file(tmp.file("d.laz"));
  auto from_las = relief::read_point_file(tmp.file("d.las"));
  REQUIRE(from_laz.is_ok());
  REQUIRE(from_las.is_ok());
  CHECK(from_laz->size() > 0);
  CHECK(from_laz->positions == from_las->positions);
  CHECK(from_laz->colors == from_las->colors);
  CHECK(from_laz->intensities == from_las->intensities);
  CHECK(fs::file_size(tmp.file("d.laz")) < fs::file_size(tmp.file("d.las")));
  // A LAZ file cut before its chunk table: malformed input (13), no archive.
  std::ifstream in(laz, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  write_text(tmp.file("cut.laz"), bytes.substr(0, bytes.size() / 2));
  const Run cut = run("compress " + tmp.file("cut.laz") + " -o " + tmp.file("b.relief"));
  CHECK(cut.code == 13);
  CHECK(cut.output.find("cut.laz") != std::string::npos);
  CHECK_FALSE(fs::exists(tmp.file("b.relief")));
}

TEST_CASE("compress --intensity-tolerance says where it could not apply", "[cli]") {
  TempDir tmp;
  relief::test::SceneOptions o;
  o.points = 5000;
  o.intensity = true;  // a smooth field of fractional values: float intensities
  const relief::PointCloud cloud = relief::test::make_terrain(o, 10.0, 0.5);
  REQUIRE(relief::write_ply(tmp.file("f.ply"), cloud).is_ok());
  const Run r = run("compress " + tmp.file("f.ply") + " -o " + tmp.file("f.relief") + " --intensity-tolerance 3");
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(r.output.find("warning: the intensity tolerance was not applied to 1 of 1 chunks: their intensities are "
                      "not all whole numbers 0..65535 (they stay exact)") != std::string::npos);
  // Whole-number intensities take it, without a word.
  relief::PointCloud whole = cloud;
  for (float& v : whole.intensities) v = std::round(v);
  REQUIRE(relief::write_ply(tmp.file("w.ply"), whole).is_ok());
  const Run w = run("compress " + tmp.file("w.ply") + " -o " + tmp.file("w.relief") + " --intensity-tolerance 3");
  INFO(w.output);
  REQUIRE(w.code == 0);
  CHECK(w.output.find("intensity tolerance") == std::string::npos);
  CHECK(run("info " + tmp.file("w.relief")).output.find("intensity within 3") != std::string::npos);
  CHECK(run("compress " + tmp.file("w.ply") + " -o " + tmp.file("r.relief") + " --mode resample --intensity-tolerance 3")
            .code == 2);
}

TEST_CASE("encode-chunk and decode-chunk with a level of detail", "[cli]") {
  TempDir tmp;
  REQUIRE(run("encode-chunk " + sample() + " -o " + tmp.file("a.rlfc") + " --quality 50 --codec jpeg2000").code == 0);
  const Run d = run("decode-chunk " + tmp.file("a.rlfc") + " -o " + tmp.file("a4.ply") + " --lod 4");
  REQUIRE(d.code == 0);
  auto full = relief::read_ply(sample());
  auto lod = relief::read_ply(tmp.file("a4.ply"));
  REQUIRE(lod.is_ok());
  CHECK(lod->size() < full->size() / 4);
}

TEST_CASE("encode-chunk and roundtrip make an error-bounded blob with --tolerance", "[cli]") {
  TempDir tmp;
  const std::string las = std::string(RELIEF_SOURCE_DIR) + "/tests/data/simple.las";
  // Half the file's 0.01 scale: every point back, its attributes exact.
  const Run r = run("roundtrip " + las + " --tolerance 0.005 -o " + tmp.file("r.las") + " --blob " + tmp.file("r.rlfc"));
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(r.output.find("points out (reconstructed)  1065") != std::string::npos);
  // The bounded sections by name (they printed as "?" before).
  CHECK(r.output.find("  geometry ") != std::string::npos);
  CHECK(r.output.find("  classification ") != std::string::npos);
  CHECK(r.output.find("  ? ") == std::string::npos);
  auto in = relief::read_point_file(las);
  auto out = relief::read_point_file(tmp.file("r.las"));
  REQUIRE(in.is_ok());
  REQUIRE(out.is_ok());
  REQUIRE(out->size() == in->size());
  CHECK(out->las.classification.size() == in->size());
  auto sorted = [](std::vector<relief::Vec3d> v) {
    std::sort(v.begin(), v.end(), [](const relief::Vec3d& a, const relief::Vec3d& b) {
      return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z);
    });
    return v;
  };
  const auto a = sorted(in->positions), b = sorted(out->positions);
  double worst = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    worst = std::max({worst, std::abs(a[i].x - b[i].x), std::abs(a[i].y - b[i].y), std::abs(a[i].z - b[i].z)});
  }
  CHECK(worst <= 0.005 + 1e-9);
  // encode-chunk makes the same blob; decode-chunk reads it back whole.
  REQUIRE(run("encode-chunk " + las + " --tolerance 0.005 -o " + tmp.file("e.rlfc") + " --quiet").code == 0);
  CHECK(fs::file_size(tmp.file("e.rlfc")) == fs::file_size(tmp.file("r.rlfc")));
  REQUIRE(run("decode-chunk " + tmp.file("e.rlfc") + " -o " + tmp.file("e.ply") + " --quiet").code == 0);
  CHECK(relief::read_ply(tmp.file("e.ply"))->size() == in->size());
  // "-o -": the blob alone on standard output (no report mixed in), the
  // same bytes; decode-chunk reads it and writes text there too.
  REQUIRE(run("encode-chunk " + las + " --tolerance 0.005 -o - > " + tmp.file("piped.rlfc")).code == 0);
  CHECK(file_bytes(tmp.file("piped.rlfc")) == file_bytes(tmp.file("e.rlfc")));
  const Run text = run("decode-chunk " + tmp.file("piped.rlfc") + " -o -");
  REQUIRE(text.code == 0);
  CHECK(std::count(text.output.begin(), text.output.end(), '\n') == 1066);  // a header line and the points
  CHECK(text.output.find("M points/s") == std::string::npos);
  CHECK(run("roundtrip " + las + " --tolerance 0.005 --blob -").code == 2);
  // --keep-order: the points in the file's order.
  REQUIRE(run("encode-chunk " + las + " --tolerance 0.005 --keep-order -o " + tmp.file("k.rlfc") + " --quiet").code == 0);
  REQUIRE(run("decode-chunk " + tmp.file("k.rlfc") + " -o " + tmp.file("k.ply") + " --quiet").code == 0);
  auto kept = relief::read_ply(tmp.file("k.ply"));
  REQUIRE(kept.is_ok());
  REQUIRE(kept->size() == in->size());
  double order_err = 0;
  for (std::size_t i = 0; i < in->size(); ++i) {
    order_err = std::max(order_err, std::abs(kept->positions[i].x - in->positions[i].x));
  }
  CHECK(order_err <= 0.005 + 1e-9);
  // Options of the bounded mode need --tolerance; a tolerance must be positive.
  for (const char* bad : {" --keep-order", " --color-tolerance 2", " --intensity-tolerance 2", " --tolerance 0",
                          " --tolerance -1", " --tolerance nan", " --tolerance 0.01 --color-tolerance 128"}) {
    INFO(bad);
    const Run e = run("encode-chunk " + las + " -o " + tmp.file("x.rlfc") + bad);
    CHECK(e.code == 2);
    CHECK_FALSE(fs::exists(tmp.file("x.rlfc")));
  }
}

TEST_CASE("decode-chunk writes every attribute a blob holds, to PLY or LAS", "[cli]") {
  TempDir tmp;
  const std::string blob_path = std::string(RELIEF_SOURCE_DIR) + "/format-spec/vectors/bounded_las_attributes_v13.rlfc";
  std::ifstream f(blob_path, std::ios::binary);
  const std::vector<std::uint8_t> blob{std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
  auto want = relief::decode_chunk(blob);
  REQUIRE(want.is_ok());
  REQUIRE(want->las.carried() == 0xFFFu);
  REQUIRE(run("decode-chunk " + blob_path + " -o " + tmp.file("d.ply") + " --quiet").code == 0);
  std::ifstream ply(tmp.file("d.ply"), std::ios::binary);
  std::string header(4096, '\0');
  ply.read(header.data(), static_cast<std::streamsize>(header.size()));
  for (const char* p : {"property ushort red", "property uchar classification", "property double gps_time",
                        "property uchar extra_4"}) {
    CHECK(header.find(p) != std::string::npos);
  }
  REQUIRE(run("decode-chunk " + blob_path + " -o " + tmp.file("d.las") + " --quiet").code == 0);
  auto las = relief::read_point_file(tmp.file("d.las"));
  REQUIRE(las.is_ok());
  REQUIRE(las->size() == want->size());
  CHECK(las->las.classification == want->las.classification);
  CHECK(las->las.gps_time == want->las.gps_time);
  CHECK(las->las.color_low == want->las.color_low);
}

TEST_CASE("bad input gives a clear error, a documented exit code and no output file", "[cli]") {
  TempDir tmp;
  SECTION("missing input file: I/O error naming it") {
    const Run r = run("encode-chunk " + tmp.file("nope.ply") + " -o " + tmp.file("x.rlfc"));
    CHECK(r.code == 12);
    CHECK(r.output.find("nope.ply") != std::string::npos);
    CHECK_FALSE(fs::exists(tmp.file("x.rlfc")));
  }
  SECTION("NaN coordinate: format error naming the file and vertex") {
    write_text(tmp.file("nan.ply"),
               "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
               "property float z\nend_header\n0 0 0\n1 nan 2\n");
    const Run r = run("encode-chunk " + tmp.file("nan.ply") + " -o " + tmp.file("x.rlfc"));
    CHECK(r.code == 13);
    CHECK(r.output.find("nan.ply") != std::string::npos);
    CHECK_FALSE(fs::exists(tmp.file("x.rlfc")));
  }
  SECTION("header that lies about the vertex count") {
    write_text(tmp.file("lie.ply"),
               "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\n"
               "property float z\nend_header\n0 0 0\n1 1 1\n");
    const Run r = run("roundtrip " + tmp.file("lie.ply"));
    CHECK(r.code == 13);
    CHECK(r.output.find("lie.ply") != std::string::npos);
  }
  SECTION("unwritable output: I/O error, nothing left behind") {
    const Run r = run("encode-chunk " + sample() + " -o " + tmp.file("no/such/dir/x.rlfc"));
    CHECK(r.code == 12);
    CHECK(r.output.find("x.rlfc") != std::string::npos);
    CHECK(fs::is_empty(tmp.path()));
  }
  SECTION("truncated and corrupted blobs: corrupt-data") {
    REQUIRE(run("encode-chunk " + sample() + " -o " + tmp.file("ok.rlfc") + " --quiet").code == 0);
    std::ifstream in(tmp.file("ok.rlfc"), std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(tmp.file("cut.rlfc"), std::ios::binary).write(bytes.data(), 100);
    Run r = run("decode-chunk " + tmp.file("cut.rlfc") + " -o " + tmp.file("cut.ply"));
    CHECK(r.code == 14);
    CHECK(r.output.find("cut.rlfc") != std::string::npos);
    CHECK_FALSE(fs::exists(tmp.file("cut.ply")));
    bytes[bytes.size() / 2] = static_cast<char>(bytes[bytes.size() / 2] ^ 0x20);
    std::ofstream(tmp.file("flip.rlfc"), std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    r = run("decode-chunk " + tmp.file("flip.rlfc") + " -o " + tmp.file("flip.ply"));
    CHECK(r.code == 14);
    CHECK(r.output.find("checksum") != std::string::npos);
  }
  SECTION("not a chunk at all") {
    write_text(tmp.file("text.rlfc"), "hello");
    const Run r = run("decode-chunk " + tmp.file("text.rlfc") + " -o " + tmp.file("t.ply"));
    CHECK(r.code == 14);
    CHECK(r.output.find("not a Relief chunk") != std::string::npos);
  }
  SECTION("unsupported input type") {
    write_text(tmp.file("scan.fls"), "FARO");
    const Run r = run("roundtrip " + tmp.file("scan.fls"));
    CHECK(r.code == 15);
  }
}

TEST_CASE("usage errors exit 2 and --help exits 0", "[cli]") {
  CHECK(run("").code == 2);
  CHECK(run("frobnicate").code == 2);
  CHECK(run("encode-chunk --bogus x").code == 2);
  CHECK(run("encode-chunk in.ply").code == 2);  // missing -o
  const Run q = run("roundtrip " + sample() + " --quality 500");
  CHECK(q.code == 2);
  CHECK(q.output.find("--quality") != std::string::npos);
  CHECK(run("roundtrip " + sample() + " --resolution 12").code == 2);
  // Numbers for one option written apart: said as such, not "expected one ARCHIVE".
  const Run box = run("query a.relief --box 1 2 3 4 -o out.las");
  CHECK(box.code == 2);
  CHECK(box.output.find("option --box takes one value, but '2' follows it: separate several numbers with commas") !=
        std::string::npos);
  for (const char* cmd : {"roundtrip", "encode-chunk", "decode-chunk", "eval"}) {
    const Run h = run(std::string(cmd) + " --help");
    CHECK(h.code == 0);
    CHECK(h.output.find("usage: relief") != std::string::npos);
  }
  CHECK(run("--version").output.find("chunk format " + std::to_string(relief::kChunkFormatVersion)) != std::string::npos);
}

TEST_CASE("compress: bad inputs exit non-zero with a clear error and leave no archive", "[cli][ingest]") {
  TempDir tmp;
  const std::string out = tmp.file("x.relief");
  const auto no_archive = [&] {
    CHECK_FALSE(fs::exists(out));
    CHECK_FALSE(fs::exists(out + "-wal"));
    for (const auto& e : fs::directory_iterator(tmp.path())) {
      CHECK(e.path().filename().string().rfind("relief-ingest-", 0) != 0);
    }
  };
  // A valid LAS written by our own writer, then damaged.
  relief::test::SceneOptions o;
  o.points = 20000;
  o.intensity = true;
  const relief::PointCloud cloud = relief::test::make_terrain(o, 10.0, 0.5);
  {
    relief::WriterOptions w;
    w.intensity = true;
    auto writer = relief::open_point_writer(tmp.file("ok.las"), w);
    REQUIRE(writer.is_ok());
    REQUIRE((*writer)->write(cloud).is_ok());
    REQUIRE((*writer)->finish().is_ok());
  }
  SECTION("truncated LAS") {
    fs::copy_file(tmp.file("ok.las"), tmp.file("cut.las"));
    fs::resize_file(tmp.file("cut.las"), fs::file_size(tmp.file("cut.las")) - 500);
    const Run r = run("compress " + tmp.file("cut.las") + " -o " + out + " --quiet");
    CHECK(r.code == 13);
    CHECK(r.output.find("cut.las") != std::string::npos);
    no_archive();
  }
  SECTION("PLY whose header count lies") {
    write_text(tmp.file("lie.ply"),
               "ply\nformat ascii 1.0\nelement vertex 100\nproperty float x\nproperty float y\n"
               "property float z\nend_header\n0 0 0\n1 1 1\n");
    const Run r = run("compress " + tmp.file("lie.ply") + " -o " + out + " --quiet");
    CHECK(r.code == 13);
    no_archive();
  }
  SECTION("NaN coordinate in an XYZ file") {
    write_text(tmp.file("nan.xyz"), "0 0 0\n1 1 1\n2 nan 2\n");
    const Run r = run("compress " + tmp.file("nan.xyz") + " -o " + out + " --quiet --cell 1");
    CHECK(r.code == 13);
    CHECK(r.output.find("nan.xyz") != std::string::npos);
    no_archive();
  }
  SECTION("missing input") {
    const Run r = run("compress " + tmp.file("nope.las") + " -o " + out);
    CHECK(r.code == 12);
    no_archive();
  }
  SECTION("LAZ that is only a LAS signature") {
    write_text(tmp.file("scan.laz"), "LASF");
    const Run r = run("compress " + tmp.file("scan.laz") + " -o " + out);
    CHECK(r.code == 13);
    CHECK(r.output.find("scan.laz") != std::string::npos);
    no_archive();
  }
  SECTION("unwritable output") {
    const Run r = run("compress " + tmp.file("ok.las") + " -o " + tmp.file("no/dir/x.relief"));
    CHECK(r.code == 12);
    CHECK_FALSE(fs::exists(tmp.file("no")));
  }
  SECTION("existing output is not touched") {
    write_text(out, "precious");
    const Run r = run("compress " + tmp.file("ok.las") + " -o " + out);
    CHECK(r.code == 12);
    CHECK(fs::file_size(out) == 8);
  }
}

TEST_CASE("query and decompress: LAS output keeps coordinates within the scale", "[cli][query]") {
  TempDir tmp;
  REQUIRE(run("compress " + sample() + " -o " + tmp.file("k.relief") + " --quiet").code == 0);
  REQUIRE(run("query " + tmp.file("k.relief") + " --box -0.5,-0.2,-2.1,0.5,0.5,-0.5 -o " + tmp.file("q.las") +
              " --quiet")
              .code == 0);
  REQUIRE(run("query " + tmp.file("k.relief") + " --box -0.5,-0.2,-2.1,0.5,0.5,-0.5 -o " + tmp.file("q.ply") +
              " --quiet")
              .code == 0);
  auto las = relief::read_point_file(tmp.file("q.las"));
  auto ply = relief::read_point_file(tmp.file("q.ply"));
  REQUIRE(las.is_ok());
  REQUIRE(ply.is_ok());
  REQUIRE(las->size() == ply->size());
  REQUIRE(las->size() > 1000);
  double worst = 0;
  for (std::size_t i = 0; i < las->size(); ++i) {
    worst = std::max({worst, std::abs(las->positions[i].x - ply->positions[i].x),
                      std::abs(las->positions[i].y - ply->positions[i].y),
                      std::abs(las->positions[i].z - ply->positions[i].z)});
  }
  CHECK(worst <= 0.00005 + 1e-12);  // half the 0.1 mm scale
  CHECK(las->colors == ply->colors);
  // The summary line says what was read: the level of detail, and whether a
  // point limit thinned the points (it said "lod 1" whatever the plan).
  const std::string q =
      "query " + tmp.file("k.relief") + " --box -0.5,-0.2,-2.1,0.5,0.5,-0.5 -o " + tmp.file("s.ply");
  const Run whole = run(q);
  REQUIRE(whole.code == 0);
  CHECK(whole.output.find(std::to_string(ply->size()) + " points from") != std::string::npos);
  CHECK(whole.output.find(", lod 1, ") != std::string::npos);
  CHECK(whole.output.find("thinned") == std::string::npos);
  const Run coarse = run(q + " --lod 8");
  REQUIRE(coarse.code == 0);
  CHECK(coarse.output.find(", lod 8, ") != std::string::npos);
  const Run limited = run(q + " --max-points " + std::to_string(ply->size() - 10));
  REQUIRE(limited.code == 0);
  CHECK(limited.output.find(std::to_string(ply->size() - 10) + " points from") != std::string::npos);
  CHECK(limited.output.find(", lod 1, thinned evenly to " + std::to_string(ply->size() - 10) + ", ") !=
        std::string::npos);
  // decompress to stdout as XYZ text.
  const Run d = run("decompress " + tmp.file("k.relief") + " -o - --quiet");
  CHECK(d.code == 0);
  CHECK(std::count(d.output.begin(), d.output.end(), '\n') > 50000);
}

TEST_CASE("decompress and query to LAS keep a LAS source's offset with integers near the 32-bit limit",
          "[cli][query][las]") {
  // The writer placed its grid by the archive's chunk bounds, which reach
  // beyond the points (they hold the base layer's too): the source's offset
  // could not hold them, so it moved (other integers) or the export failed.
  TempDir tmp;
  relief::PointCloud in;
  const std::int64_t top = 2147483647;  // the largest LAS integer
  for (std::int64_t i = 0; i < 3000; ++i) {
    const std::int64_t X = top - (i * 7919) % 2000000, Y = (i * 104729) % 3000000 - 1500000, Z = i % 1000;
    in.positions.push_back(
        {static_cast<double>(X) * 0.001, static_cast<double>(Y) * 0.001, static_cast<double>(Z) * 0.001});
  }
  in.positions.push_back({static_cast<double>(top) * 0.001, 0.0, 0.0});
  const auto header_offset = [](const std::string& path) {
    std::ifstream f(path, std::ios::binary);
    std::array<double, 3> o{};
    f.seekg(155);
    f.read(reinterpret_cast<char*>(o.data()), sizeof o);
    return o;
  };
  relief::WriterOptions w;
  w.grid_scale = relief::Vec3d{0.001, 0.001, 0.001};
  w.grid_offset = relief::Vec3d{0, 0, 0};
  w.grid_offset_exact = true;  // the test's own file at offset 0, whatever its bounds
  {
    auto writer = relief::open_point_writer(tmp.file("edge.las"), w);
    REQUIRE(writer.is_ok());
    REQUIRE((*writer)->write(in).is_ok());
    REQUIRE((*writer)->finish().is_ok());
  }
  REQUIRE(header_offset(tmp.file("edge.las")) == std::array<double, 3>{0, 0, 0});
  REQUIRE(run("compress " + tmp.file("edge.las") + " -o " + tmp.file("e.relief") + " --quiet").code == 0);
  const auto integers = [](const relief::PointCloud& c) {
    std::vector<std::array<long long, 3>> v;
    for (const relief::Vec3d& p : c.positions) {
      v.push_back({std::llround(p.x / 0.001), std::llround(p.y / 0.001), std::llround(p.z / 0.001)});
    }
    std::sort(v.begin(), v.end());
    return v;
  };
  for (const std::string cmd :
       {"decompress " + tmp.file("e.relief") + " -o " + tmp.file("out.las"),
        "query " + tmp.file("e.relief") + " --box 0,-2000,-1,2200000,2000,2 -o " + tmp.file("out.las")}) {
    CAPTURE(cmd);
    const Run r = run(cmd + " --quiet");
    INFO(r.output);
    REQUIRE(r.code == 0);
    CHECK(header_offset(tmp.file("out.las")) == std::array<double, 3>{0, 0, 0});
    auto back = relief::read_point_file(tmp.file("out.las"));
    REQUIRE(back.is_ok());
    CHECK(integers(*back) == integers(in));
  }
}

TEST_CASE("query and decompress --polygon: the points inside a WKT area", "[cli][query][polygon]") {
  TempDir tmp;
  const std::string a = tmp.file("k.relief");
  REQUIRE(run("compress " + sample() + " -o " + a + " --quiet").code == 0);
  const std::string wkt = "POLYGON ((-0.5 -0.2, 0.5 -0.2, 0.1 0.5, -0.5 -0.2), (-0.1 -0.1, 0.1 -0.1, 0 0.1, -0.1 -0.1))";
  write_text(tmp.file("area.wkt"), wkt + "\n");
  auto area = relief::Polygon2D::from_wkt(wkt, "area");
  REQUIRE(area.is_ok());
  REQUIRE(run("decompress " + a + " -o " + tmp.file("all.ply") + " --quiet").code == 0);
  auto all = relief::read_point_file(tmp.file("all.ply"));
  REQUIRE(all.is_ok());
  std::vector<std::array<double, 3>> want;
  for (const relief::Vec3d& p : all->positions) {
    if (area->contains(p.x, p.y) && p.z <= -1.0) want.push_back({p.x, p.y, p.z});
  }
  std::sort(want.begin(), want.end());
  REQUIRE(want.size() > 1000);
  REQUIRE(want.size() < all->size() / 2);
  // query: a WKT file, and a box beside it (all heights up to z = -1);
  // decompress: the WKT itself, then the same height cut here.
  const Run q = run("query " + a + " --polygon @" + tmp.file("area.wkt") + " --box -9,-9,-9,9,9,-1 -o " +
                    tmp.file("q.ply"));
  REQUIRE(q.code == 0);
  const Run d = run("decompress " + a + " --polygon '" + wkt + "' -o " + tmp.file("d.ply") + " --quiet");
  REQUIRE(d.code == 0);
  for (const std::string& name : {"q.ply", "d.ply"}) {
    auto got = relief::read_point_file(tmp.file(name));
    REQUIRE(got.is_ok());
    std::vector<std::array<double, 3>> v;
    for (const relief::Vec3d& p : got->positions) {
      if (name == "q.ply" || p.z <= -1.0) v.push_back({p.x, p.y, p.z});
    }
    std::sort(v.begin(), v.end());
    INFO(name);
    CHECK(v == want);
  }
  // stats of the same area, and refused for a point file.
  const Run st = run("stats " + a + " --polygon @" + tmp.file("area.wkt") + " --box -9,-9,-9,9,9,-1 --json");
  REQUIRE(st.code == 0);
  CHECK(st.output.find("\"points\": " + std::to_string(want.size()) + ",") != std::string::npos);
  CHECK(run("stats " + tmp.file("all.ply") + " --polygon @" + tmp.file("area.wkt")).code == 2);
  // Refusals: usage errors naming --polygon, and no output.
  for (const std::string& bad : {std::string("'POLYGON ((0 0, 1 1, 0 0))'"), std::string("'LINESTRING (0 0, 1 1)'"),
                                 "@" + tmp.file("missing.wkt"), "@" + tmp.path().string()}) {
    const Run r = run("query " + a + " --polygon " + bad + " -o " + tmp.file("o.ply"));
    INFO(bad);
    CHECK(r.code == 2);
    CHECK(r.output.find("--polygon: ") != std::string::npos);
  }
  CHECK_FALSE(fs::exists(tmp.file("o.ply")));
  CHECK(run("query " + a + " -o " + tmp.file("o.ply")).output.find("missing --box (or --polygon)") != std::string::npos);
}

TEST_CASE("query, decompress and preview refuse to write their output over the archive they read",
          "[cli][query]") {
  // An archive is opened by its content whatever its name: arch.las, read and
  // written to arch.las, was replaced by the query's points.
  TempDir tmp;
  REQUIRE(run("compress " + sample() + " -o " + tmp.file("k.relief") + " --quiet").code == 0);
  for (const char* name : {"arch.las", "arch.ply", "arch.png"}) {
    const std::string a = tmp.file(name);
    fs::copy_file(tmp.file("k.relief"), a);
    const std::string before = file_bytes(a);
    const std::string cmd = std::string(name) == "arch.png" ? "preview " + a + " -o " + a
                            : std::string(name) == "arch.ply"
                                ? "decompress " + a + " -o " + tmp.file("./arch.ply")
                                : "query " + a + " --box -10,-10,10,10 -o " + a;
    const Run r = run(cmd);
    INFO(cmd << "\n" << r.output);
    CHECK(r.code == 11);
    CHECK(r.output.find("the file being read") != std::string::npos);
    CHECK(file_bytes(a) == before);
  }
  // Through a hard link too.
  fs::create_hard_link(tmp.file("k.relief"), tmp.file("link.ply"));
  CHECK(run("decompress " + tmp.file("k.relief") + " -o " + tmp.file("link.ply")).code == 11);
  CHECK(run("info " + tmp.file("k.relief")).code == 0);
}

TEST_CASE("a full standard output and a file size limit are I/O errors, not success or a signal", "[cli]") {
  TempDir tmp;
  REQUIRE(run("compress " + sample() + " -o " + tmp.file("k.relief") + " --quiet").code == 0);
  const std::string a = tmp.file("k.relief");
  // /dev/full: every write fails with ENOSPC. info, stats and check said nothing and exited 0.
  for (const std::string cmd : {"info " + a, "info --json " + a, "stats " + a, "check " + a}) {
    INFO(cmd);
    CHECK(run(cmd + " >/dev/full").code == 12);
  }
  // ulimit -f: writes beyond the limit fail with EFBIG instead of killing the process (SIGXFSZ,
  // exit 153) with its temporary file left.
  const relief::test::CliRun limited =
      relief::test::run_cli("ulimit -f 64; exec " + std::string(RELIEF_CLI),
                            "decompress " + a + " -o " + tmp.file("out.las") + " --quiet");
  INFO(limited.output);
  CHECK(limited.code == 12);
  CHECK(limited.output.find("File too large") != std::string::npos);
  std::size_t left = 0;
  for (const auto& e : fs::directory_iterator(tmp.path()))
    left += e.path().filename().string().rfind("out.las", 0) == 0;
  CHECK(left == 0);
}

TEST_CASE("query and info: clear errors for bad archives and boxes", "[cli][query]") {
  TempDir tmp;
  REQUIRE(run("compress " + sample() + " -o " + tmp.file("k.relief") + " --quiet").code == 0);
  const std::string a = tmp.file("k.relief");
  CHECK(run("query " + tmp.file("missing.relief") + " --box 0,0,1,1 -o " + tmp.file("o.ply")).code == 12);
  write_text(tmp.file("text.relief"), "not sqlite at all, not at all, really not");
  const Run foreign = run("info " + tmp.file("text.relief"));
  CHECK(foreign.code == 13);
  CHECK(foreign.output.find("not a Relief archive") != std::string::npos);
  for (const char* box : {"1,1,0,0", "a,b,c,d", "1,2,3", "0,0,0,1,1,nan", "5,0,0,4,1,1"}) {
    const Run r = run("query " + a + " --box " + box + " -o " + tmp.file("o.ply"));
    INFO(box);
    CHECK(r.code == 2);
    CHECK(r.output.find("--box") != std::string::npos);
  }
  CHECK_FALSE(fs::exists(tmp.file("o.ply")));
  const Run info = run("info " + a + " --json");
  CHECK(info.code == 0);
  CHECK(info.output.find("\"format_version\": 3") != std::string::npos);
  CHECK(info.output.find("\"points_in\": 241407") != std::string::npos);
  // --sections: the bytes of each section, the rest of the file, and the same in the JSON.
  const Run parts = run("info " + a + " --sections");
  INFO(parts.output);
  CHECK(parts.code == 0);
  CHECK(parts.output.find("\n  geometry ") != std::string::npos);
  CHECK(parts.output.find("\n  rgb ") != std::string::npos);
  CHECK(parts.output.find("    height map ") != std::string::npos);
  CHECK(parts.output.find("\n  file " + std::string(20 - 4, ' ') + std::string(14 - std::to_string(fs::file_size(a)).size(), ' ') +
                          std::to_string(fs::file_size(a)) + "  100.0 %") != std::string::npos);
  const Run parts_json = run("info " + a + " --json --sections");
  CHECK(parts_json.code == 0);
  CHECK(parts_json.output.find("\"sections\": {\"chunks\": ") != std::string::npos);
  CHECK(parts_json.output.find("\"name\": \"geometry\"") != std::string::npos);
  // Still one object: the sections close it.
  CHECK(parts_json.output.substr(parts_json.output.size() - 5) == "]}\n}\n");
  for (const char* cmd : {"compress", "append", "stream", "query", "decompress", "info", "preview", "check"}) {
    const Run h = run(std::string(cmd) + " --help");
    CHECK(h.code == 0);
    CHECK(h.output.find("usage: relief") != std::string::npos);
  }
}
