// CLI tests with expected exit codes and messages (README "Exit codes").
#include <catch2/catch.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include "relief/io.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;

using relief::test::TempDir;

namespace {

struct Run {
  int code = -1;
  std::string output;  // stdout and stderr together
};

Run run(const std::string& args) {
  const std::string cmd = std::string(RELIEF_CLI) + " " + args + " 2>&1";
  Run r;
  FILE* p = popen(cmd.c_str(), "r");
  REQUIRE(p != nullptr);
  std::array<char, 4096> buf{};
  std::size_t n = 0;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}


std::string sample() { return std::string(RELIEF_SOURCE_DIR) + "/tests/data/kinect_milk_scene_rgb.ply"; }

void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

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
    write_text(tmp.file("scan.laz"), "LASF");
    const Run r = run("roundtrip " + tmp.file("scan.laz"));
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
  CHECK(run("roundtrip " + sample() + " --resolution 12").code == 11);
  for (const char* cmd : {"roundtrip", "encode-chunk", "decode-chunk", "eval"}) {
    const Run h = run(std::string(cmd) + " --help");
    CHECK(h.code == 0);
    CHECK(h.output.find("usage: relief") != std::string::npos);
  }
  CHECK(run("--version").output.find("chunk format 1") != std::string::npos);
}
