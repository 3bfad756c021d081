// CLI input validation and messages (issue 10): refused coordinates, too-fine
// cells, option ranges, output paths, short usage errors.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "relief/archive.h"
#include "relief/image.h"
#include "relief/io.h"
#include "support/run_cli.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;

using relief::test::TempDir;

namespace {

using Run = relief::test::CliRun;

Run run(const std::string& args) { return relief::test::run_cli(RELIEF_CLI, args); }

std::string sample() { return std::string(RELIEF_SOURCE_DIR) + "/tests/data/kinect_milk_scene_rgb.ply"; }

void write_text(const std::string& path, const std::string& text) { std::ofstream(path) << text; }

bool has(const Run& r, const std::string& text) { return r.output.find(text) != std::string::npos; }

// 100 points on a 1 m grid, then `extra` as point 100.
std::string grid_xyz(const std::string& extra) {
  std::string text;
  for (int i = 0; i < 100; ++i) text += std::to_string(i % 10) + " " + std::to_string(i / 10) + " 0\n";
  return text + extra + "\n";
}

}  // namespace

TEST_CASE("compress refuses coordinates beyond the limit on both sides, naming file, point and value",
          "[cli][ingest]") {
  TempDir tmp;
  for (const char* value : {"1e300", "-1e300", "1e13", "-1e13"}) {
    INFO(value);
    write_text(tmp.file("far.xyz"), grid_xyz(std::string(value) + " 0 0"));
    const Run r = run("compress " + tmp.file("far.xyz") + " -o " + tmp.file("far.relief") + " --cell 0.1 --quiet");
    CHECK(r.code == 11);
    CHECK(has(r, "far.xyz: point 100 has x = "));
    CHECK(has(r, "beyond the limit"));
    CHECK_FALSE(fs::exists(tmp.file("far.relief")));
  }
  // Also when the cell comes from an error target (trial encodes of the first points).
  write_text(tmp.file("far.xyz"), grid_xyz("1e300 0 0"));
  const Run target =
      run("compress " + tmp.file("far.xyz") + " -o " + tmp.file("far.relief") + " --error-target 0.1 --quiet");
  CHECK(target.code == 11);
  CHECK(has(target, "far.xyz: point 100 has x = 1e+300"));
  // The limit is 2^36 cells: 6.87e9 with 0.1 cells; just inside is accepted.
  write_text(tmp.file("near.xyz"), grid_xyz("-6e9 0 0"));
  const Run ok = run("compress " + tmp.file("near.xyz") + " -o " + tmp.file("near.relief") + " --cell 0.1 --quiet");
  CHECK(ok.code == 0);
  // An absurd chunk edge cannot overflow the keys either.
  write_text(tmp.file("edge.xyz"), grid_xyz("5 5 5"));
  const Run edge = run("compress " + tmp.file("edge.xyz") + " -o " + tmp.file("edge.relief") +
                       " --cell 1e300 --chunk-edge 1e300 --quiet");
  CHECK(edge.code == 11);
  CHECK_FALSE(has(edge, "chunk ("));
}

TEST_CASE("compress refuses a cell far too fine for the data unless --allow-sparse", "[cli][ingest]") {
  TempDir tmp;
  const Run r = run("compress " + sample() + " -o " + tmp.file("fine.relief") + " --cell 0.000001 --quiet");
  CHECK(r.code == 16);
  CHECK(has(r, "kinect_milk_scene_rgb.ply"));
  CHECK(has(r, "--allow-sparse"));
  CHECK_FALSE(fs::exists(tmp.file("fine.relief")));
  // A chunk edge far too small is refused the same way.
  const Run chunks = run("compress " + sample() + " -o " + tmp.file("fine.relief") + " --chunk-edge 0.001 --quiet");
  CHECK(chunks.code == 16);
  CHECK(has(chunks, "points per chunk"));
  // The default cell passes; a small input is never refused.
  CHECK(run("compress " + sample() + " -o " + tmp.file("ok.relief") + " --quiet").code == 0);
  write_text(tmp.file("small.xyz"), grid_xyz("5 5 5"));
  CHECK(run("compress " + tmp.file("small.xyz") + " -o " + tmp.file("small.relief") + " --cell 0.001 --quiet").code ==
        0);
}

TEST_CASE("compress --allow-sparse overrides the density check", "[cli][ingest]") {
  TempDir tmp;
  // 10,000 points (the check's minimum sample) 2 cm apart on a line, 1 cm
  // cells: one point per cell. 2 m chunks keep them to 100 chunks (20,000
  // one-point chunks took 4 minutes under AddressSanitizer).
  std::string text;
  for (int i = 0; i < 10000; ++i) text += std::to_string(i * 2) + "e-2 0 0\n";
  write_text(tmp.file("line.xyz"), text);
  const std::string base = "compress " + tmp.file("line.xyz") + " --cell 0.01 --chunk-edge 2 --quiet -o ";
  const Run refused = run(base + tmp.file("a.relief"));
  CHECK(refused.code == 16);
  CHECK(has(refused, "10000 cells of 0.01 (1 points per cell"));
  CHECK(has(refused, "--allow-sparse"));
  CHECK(run(base + tmp.file("b.relief") + " --allow-sparse").code == 0);
}

TEST_CASE("encoding options are usage errors before any work", "[cli]") {
  TempDir tmp;
  const std::string out = tmp.file("x.relief");
  for (const char* opt : {"--resolution 12", "--resolution 72", "--height-bits 12", "--height-bits 16",
                          "--quality 0", "--color-quality 101", "--intensity-quality -1", "--fill smooth",
                          "--codec png", "--max-points 0", "--cell -1"}) {
    INFO(opt);
    const Run r = run("compress " + sample() + " -o " + out + " --quiet " + opt);
    CHECK(r.code == 2);
    CHECK_FALSE(has(r, "chunk ("));
    CHECK_FALSE(fs::exists(out));
  }
  const Run bits = run("roundtrip " + sample() + " --height-bits 16");
  CHECK(bits.code == 2);
  CHECK(has(bits, "--codec jpeg2000"));
  CHECK(run("roundtrip " + sample() + " --height-bits 16 --codec jpeg2000").code == 0);
  const Run enc = run("encode-chunk " + sample() + " -o " + tmp.file("c.rlfc") + " --resolution 20");
  CHECK(enc.code == 2);
  CHECK(has(enc, "--resolution"));
}

TEST_CASE("compress --memory below the minimum is a usage error stating the minimum", "[cli][ingest]") {
  TempDir tmp;
  const Run r = run("compress " + sample() + " -o " + tmp.file("x.relief") + " --memory 10M");
  CHECK(r.code == 2);
  CHECK(has(r, "64M"));
  CHECK(run("compress " + sample() + " -o " + tmp.file("x.relief") + " --memory 64M --quiet").code == 0);
}

TEST_CASE("query, decompress and preview: --lod beyond 1024 is a usage error", "[cli][query]") {
  TempDir tmp;
  const std::string a = tmp.file("k.relief");
  REQUIRE(run("compress " + sample() + " -o " + a + " --quiet").code == 0);
  const Run q = run("query " + a + " --box -1,-1,-3,1,1,1 --lod 1000000 -o " + tmp.file("q.ply"));
  CHECK(q.code == 2);
  CHECK(has(q, "--lod"));
  CHECK_FALSE(fs::exists(tmp.file("q.ply")));
  CHECK(run("decompress " + a + " --lod 2000 -o " + tmp.file("d.ply")).code == 2);
  CHECK(run("preview " + a + " --lod 5000 -o " + tmp.file("v.png")).code == 2);
  CHECK(run("query " + a + " --box -1,-1,-3,1,1,1 --lod 1024 -o " + tmp.file("q.ply") + " --quiet").code == 0);
}

TEST_CASE("preview writes PNG or JPEG by the output's extension and refuses others", "[cli][preview]") {
  TempDir tmp;
  const std::string a = tmp.file("k.relief");
  REQUIRE(run("compress " + sample() + " -o " + a + " --quiet").code == 0);
  const auto head = [&](const std::string& name) {
    std::ifstream in(tmp.file(name), std::ios::binary);
    std::string bytes(8, '\0');
    in.read(bytes.data(), 8);
    return bytes;
  };
  for (const char* name : {"view.gif", "view", "view.jpg.txt"}) {
    INFO(name);
    const Run r = run("preview " + a + " -o " + tmp.file(name));
    CHECK(r.code == 2);
    CHECK(has(r, "PNG (.png) or JPEG (.jpg, .jpeg)"));
    CHECK_FALSE(fs::exists(tmp.file(name)));
  }
  for (const char* name : {"view.jpg", "view.JPEG"}) {
    INFO(name);
    REQUIRE(run("preview " + a + " -o " + tmp.file(name) + " --quiet").code == 0);
    CHECK(head(name).substr(0, 3) == "\xFF\xD8\xFF");  // JPEG SOI and the next marker
    CHECK(fs::file_size(tmp.file(name)) > 1000);
  }
  REQUIRE(run("preview " + a + " -o " + tmp.file("view.PNG") + " --quiet").code == 0);
  CHECK(head("view.PNG") == "\x89PNG\r\n\x1a\n");
}

TEST_CASE("encode_jpeg_rgb checks its arguments", "[cli][preview]") {
  const std::vector<std::uint8_t> rgb(4 * 3 * 3, 128);
  CHECK(relief::encode_jpeg_rgb(rgb, 4, 3, 90).is_ok());
  CHECK(relief::encode_jpeg_rgb(rgb, 4, 4, 90).status().code() == relief::StatusCode::kInvalidArgument);
  CHECK(relief::encode_jpeg_rgb(rgb, 4, 3, 0).status().code() == relief::StatusCode::kInvalidArgument);
  CHECK(relief::encode_jpeg_rgb({}, 0, 0, 90).status().code() == relief::StatusCode::kInvalidArgument);
}

TEST_CASE("compress names a missing output directory and an existing non-archive", "[cli][ingest]") {
  TempDir tmp;
  const Run dir = run("compress " + sample() + " -o " + tmp.file("nodir/x.relief"));
  CHECK(dir.code == 12);
  CHECK(has(dir, "the directory " + tmp.file("nodir") + " does not exist"));
  CHECK_FALSE(has(dir, "unable to open database file"));
  CHECK_FALSE(fs::exists(tmp.file("nodir")));

  write_text(tmp.file("notes.relief"), "precious");
  const Run other = run("compress " + sample() + " -o " + tmp.file("notes.relief"));
  CHECK(other.code == 12);
  CHECK(has(other, "not a Relief archive"));
  CHECK(has(other, "never overwrites"));
  CHECK_FALSE(has(other, "relief append"));
  CHECK(fs::file_size(tmp.file("notes.relief")) == 8);

  REQUIRE(run("compress " + sample() + " -o " + tmp.file("k.relief") + " --quiet").code == 0);
  const Run again = run("compress " + sample() + " -o " + tmp.file("k.relief"));
  CHECK(again.code == 12);
  CHECK(has(again, "relief append"));

  const Run stream = run("stream " + tmp.file("nodir/s.relief") + " --cell 1 < /dev/null");
  CHECK(stream.code == 12);
  CHECK(has(stream, "does not exist"));

  // Outputs of the other commands say the same, not "cannot create temporary file".
  for (const std::string cmd :
       {"query " + tmp.file("k.relief") + " --box -1,-1,1,1 -o " + tmp.file("nodir/q.ply"),
        "preview " + tmp.file("k.relief") + " -o " + tmp.file("nodir/v.png"),
        "encode-chunk " + sample() + " -o " + tmp.file("nodir/c.rlfc")}) {
    INFO(cmd);
    const Run r = run(cmd);
    CHECK(r.code == 12);
    CHECK(has(r, "the directory " + tmp.file("nodir") + " does not exist"));
  }
}

TEST_CASE("stream names the attribute that differs from the archive's", "[cli][ingest]") {
  TempDir tmp;
  const std::string a = tmp.file("s.relief");
  write_text(tmp.file("in.txt"), grid_xyz("5 5 5"));
  REQUIRE(run("stream " + a + " --cell 1 --quiet < " + tmp.file("in.txt")).code == 0);
  write_text(tmp.file("rgb.txt"), "1 1 1 255 0 0\n2 2 2 0 255 0\n");
  const Run r = run("stream " + a + " --columns x,y,z,r,g,b --quiet < " + tmp.file("rgb.txt"));
  CHECK(r.code == 11);
  CHECK(has(r, "the archive has no colours or intensity but the stream has colours"));
}

TEST_CASE("usage errors print the error and one hint line, not the whole help", "[cli]") {
  for (const char* args : {"compress", "query x.relief", "preview", "info", "stream", "roundtrip --bogus"}) {
    INFO(args);
    const Run r = run(args);
    CHECK(r.code == 2);
    CHECK(has(r, "--help'"));
    CHECK_FALSE(has(r, "usage:"));
    CHECK(std::count(r.output.begin(), r.output.end(), '\n') == 2);
  }
  const Run unknown = run("frobnicate");
  CHECK(unknown.code == 2);
  CHECK(std::count(unknown.output.begin(), unknown.output.end(), '\n') == 2);
}

TEST_CASE("a double dash ends the options: later arguments are positional, even starting with a dash",
          "[cli]") {
  TempDir tmp;
  fs::copy_file(std::string(RELIEF_SOURCE_DIR) + "/tests/data/simple.las", tmp.file("-scan.las"));
  // Names relative to the directory, so they start with '-'.
  const auto run_in = [&](const std::string& args) {
    return relief::test::run_cli("cd '" + tmp.path().string() + "' && " + RELIEF_CLI, args);
  };
  const Run refused = run_in("compress -scan.las -o a.relief --quiet");
  CHECK(refused.code == 2);
  CHECK(has(refused, "unknown option -scan.las"));
  const Run c = run_in("compress -o -a.relief --quiet -- -scan.las");
  INFO(c.output);
  REQUIRE(c.code == 0);
  const Run i = run_in("info --json -- -a.relief");
  CHECK(i.code == 0);
  CHECK(has(i, "\"points_in\""));
  // After --, an option's name is an input too: here a second archive, a usage error.
  const Run two = run_in("info -- -a.relief --json");
  CHECK(two.code == 2);
  CHECK_FALSE(has(two, "unknown option"));
  // Every subcommand parses its arguments the same way.
  const Run a = run_in("append --quiet -- -a.relief -scan.las");
  INFO(a.output);
  CHECK(a.code == 0);
}

TEST_CASE("compress warns on stderr when a PLY holds more vertices than its header declares", "[cli][ingest]") {
  TempDir tmp;
  std::string text = "ply\nformat ascii 1.0\nelement vertex 40\nproperty float x\nproperty float y\n"
                     "property float z\nend_header\n";
  for (int i = 0; i < 50; ++i) text += std::to_string(i % 10) + " " + std::to_string(i / 10) + " 0\n";
  write_text(tmp.file("more.ply"), text);
  const Run r = run("compress " + tmp.file("more.ply") + " -o " + tmp.file("m.relief") + " --cell 1 --quiet");
  CHECK(r.code == 0);
  CHECK(has(r, "warning: " + tmp.file("more.ply") + ": the header declares 40 vertices but 50 follow"));
}

TEST_CASE("an archive cut short behind an intact header is called truncated", "[cli][query]") {
  TempDir tmp;
  const std::string a = tmp.file("k.relief");
  REQUIRE(run("compress " + sample() + " -o " + a + " --quiet").code == 0);
  REQUIRE((!fs::exists(a + "-wal") || fs::file_size(a + "-wal") == 0));  // everything is in the main file
  const auto size = fs::file_size(a);
  for (const std::uintmax_t keep : {std::uintmax_t{4096}, size / 2, size - 4096}) {
    INFO(keep);
    fs::copy_file(a, tmp.file("cut.relief"), fs::copy_options::overwrite_existing);
    fs::resize_file(tmp.file("cut.relief"), keep);
    for (const std::string cmd : {"info " + tmp.file("cut.relief"),
                                  "query " + tmp.file("cut.relief") + " --box -1,-1,1,1 -o " + tmp.file("q.ply")}) {
      const Run r = run(cmd);
      CHECK(r.code == 13);
      CHECK(has(r, "cut.relief: truncated"));
      CHECK_FALSE(has(r, "not a SQLite database"));
    }
  }
  // A file that is not SQLite at all keeps its own message.
  write_text(tmp.file("text.relief"), std::string(200, 'x'));
  CHECK(has(run("info " + tmp.file("text.relief")), "not a Relief archive"));
}

TEST_CASE("encode-chunk and roundtrip refuse coordinates beyond 2^50", "[cli]") {
  TempDir tmp;
  write_text(tmp.file("far.xyz"), grid_xyz("1e300 0 0"));
  for (const std::string cmd : {"roundtrip " + tmp.file("far.xyz"),
                                "encode-chunk " + tmp.file("far.xyz") + " -o " + tmp.file("c.rlfc")}) {
    INFO(cmd);
    const Run r = run(cmd);
    CHECK(r.code == 11);
    CHECK(has(r, "far.xyz: point 100 has a coordinate 1e+300"));
  }
  CHECK_FALSE(fs::exists(tmp.file("c.rlfc")));
}

TEST_CASE("stream: unknown binary attributes are a usage error", "[cli][ingest]") {
  TempDir tmp;
  for (const char* attrs : {"color", "rgb,rgb", "rgb,", "rgb,intensity,x"}) {
    INFO(attrs);
    const Run r = run("stream " + tmp.file("s.relief") + " --format binary --cell 1 --attributes " + attrs +
                      " < /dev/null");
    CHECK(r.code == 2);
    CHECK(has(r, "--attributes"));
  }
  // Each format takes its own column option, not the other's.
  const Run text = run("stream " + tmp.file("s.relief") + " --cell 1 --attributes rgb < /dev/null");
  CHECK(text.code == 2);
  CHECK(has(text, "--attributes names the fields of --format binary"));
  const Run binary = run("stream " + tmp.file("s.relief") + " --format binary --cell 1 --columns x,y,z < /dev/null");
  CHECK(binary.code == 2);
  CHECK(has(binary, "--format binary takes --attributes"));
  CHECK_FALSE(fs::exists(tmp.file("s.relief")));
}

TEST_CASE("stream refuses a colour level outside 0..255 instead of clamping it", "[cli][ingest]") {
  TempDir tmp;
  for (const char* level : {"256", "-1", "65535", "nan"}) {
    INFO(level);
    write_text(tmp.file("in.txt"), std::string("1 2 3 10 20 30\n2 3 4 9 ") + level + " 7\n");
    const Run r = run("stream " + tmp.file("s.relief") + " --columns x,y,z,r,g,b --cell 1 --quiet < " +
                      tmp.file("in.txt"));
    CHECK(r.code == 13);
    CHECK(has(r, std::string("stdin: line 2: colour level")));
    CHECK_FALSE(fs::exists(tmp.file("s.relief")));
  }
  // 255 and fractions that round into range are levels.
  write_text(tmp.file("in.txt"), "1 2 3 10 20 30\n2 3 4 255 0 2.4\n");
  CHECK(run("stream " + tmp.file("s.relief") + " --columns x,y,z,r,g,b --cell 1 --quiet < " + tmp.file("in.txt"))
            .code == 0);
}

TEST_CASE("stream warns of a text intensity a float does not give back, as compress does", "[cli][ingest]") {
  TempDir tmp;
  write_text(tmp.file("in.txt"), "1 2 3 10\n2 3 4 1234.5678901\n3 4 5 1234.5678902\n");
  const std::string warning =
      ": line 2: intensity 1234.5678901 is kept as the 32-bit float 1234.5679 (intensities are 32-bit floats";
  const Run streamed = run("stream " + tmp.file("s.relief") + " --columns x,y,z,i --cell 1 --quiet < " +
                           tmp.file("in.txt"));
  CHECK(streamed.code == 0);
  CHECK(has(streamed, "relief stream: warning: stdin" + warning));
  const Run compressed = run("compress " + tmp.file("in.txt") + " --columns x,y,z,i --cell 1 --quiet -o " +
                             tmp.file("c.relief"));
  CHECK(compressed.code == 0);
  CHECK(has(compressed, "relief compress: warning: " + tmp.file("in.txt") + warning));
  // Once: the later line is not listed.
  CHECK_FALSE(has(streamed, "line 3"));
}

TEST_CASE("stream reads LAS dimensions by name and gives them back", "[cli][ingest]") {
  TempDir tmp;
  write_text(tmp.file("in.txt"),
             "1 2 3 100.25 2 7 1\n"
             "1.5,2,3,100.5,1,31,2\n"
             "2;2;3;100.75;3;2;1\n");
  const std::string archive = tmp.file("s.relief");
  const Run r = run("stream " + archive + " --columns x,y,z,gps_time,return_number,classification,_ --cell 1 --quiet < " +
                    tmp.file("in.txt"));
  REQUIRE(r.code == 0);
  REQUIRE(run("decompress " + archive + " -o " + tmp.file("out.csv") + " --quiet").code == 0);
  std::ifstream in(tmp.file("out.csv"));
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  REQUIRE(lines.size() == 4);
  CHECK(lines[0] == "X,Y,Z,Classification,ReturnNumber,GpsTime");
  std::sort(lines.begin() + 1, lines.end());
  CHECK(lines[1] == "1.000,2.000,3.000,7,2,100.25");
  CHECK(lines[2] == "1.500,2.000,3.000,31,1,100.5");
  CHECK(lines[3] == "2.000,2.000,3.000,2,3,100.75");
  // A value out of its dimension's range, or an unknown name, is refused.
  write_text(tmp.file("bad.txt"), "1 2 3 16\n");
  const Run bad = run("stream " + tmp.file("b.relief") + " --columns x,y,z,return_number --cell 1 --quiet < " +
                      tmp.file("bad.txt"));
  CHECK(bad.code == 13);
  CHECK(has(bad, "stdin: line 1: return number 16"));
  CHECK_FALSE(fs::exists(tmp.file("b.relief")));
  const Run unknown = run("stream " + tmp.file("b.relief") + " --columns x,y,z,foo --cell 1 < " + tmp.file("bad.txt"));
  CHECK(unknown.code == 2);
  CHECK(has(unknown, "unknown column 'foo'"));
}

TEST_CASE("compress and append take directories and --input-list: the same archive as the files", "[cli][ingest]") {
  TempDir tmp;
  fs::create_directories(tmp.file("tiles"));
  std::string list = "# tiles\n";
  for (int t = 0; t < 3; ++t) {
    std::string text;
    for (int i = 0; i < 40; ++i) {
      text += std::to_string(10 * t + (i % 7)) + " " + std::to_string(i / 7) + " " + std::to_string(i % 3) + "\n";
    }
    const std::string name = tmp.file("tiles/t" + std::to_string(t) + ".xyz");
    write_text(name, text);
    list += name + "\n";
  }
  write_text(tmp.file("list.txt"), list);
  const std::string files = tmp.file("tiles/t0.xyz") + " " + tmp.file("tiles/t1.xyz") + " " + tmp.file("tiles/t2.xyz");
  REQUIRE(run("compress " + files + " -o " + tmp.file("f.relief") + " --quiet").code == 0);
  REQUIRE(run("compress " + tmp.file("tiles") + " -o " + tmp.file("d.relief") + " --quiet").code == 0);
  REQUIRE(run("compress --input-list " + tmp.file("list.txt") + " -o " + tmp.file("l.relief") + " --quiet").code == 0);
  const auto rows = [](const std::string& path) {
    auto a = relief::Archive::open(path, relief::Archive::Mode::kReadOnly);
    REQUIRE(a.is_ok());
    auto refs = (*a)->all_chunks();
    REQUIRE(refs.is_ok());
    std::vector<std::vector<std::uint8_t>> blobs;
    for (const auto& r : *refs) {
      auto row = (*a)->read_chunk(r.id);
      REQUIRE(row.is_ok());
      blobs.push_back(row->blob);
    }
    auto info = (*a)->info();
    REQUIRE(info.is_ok());
    CHECK(info->sources.size() == 3);
    return blobs;
  };
  const auto want = rows(tmp.file("f.relief"));
  CHECK(rows(tmp.file("d.relief")) == want);
  CHECK(rows(tmp.file("l.relief")) == want);
  // append takes them too; a command without inputs, an empty directory or
  // list, or an unreadable list, is refused before anything is written.
  REQUIRE(run("compress " + tmp.file("tiles/t0.xyz") + " -o " + tmp.file("a.relief") + " --quiet").code == 0);
  REQUIRE(run("append " + tmp.file("a.relief") + " --input-list " + tmp.file("list.txt") + " --quiet").code == 0);
  CHECK(run("compress -o " + tmp.file("n.relief")).code == 2);
  fs::create_directories(tmp.file("empty"));
  const Run empty = run("compress " + tmp.file("empty") + " -o " + tmp.file("n.relief"));
  CHECK(empty.code == 11);
  CHECK(has(empty, "a directory without point files"));
  const Run missing = run("compress --input-list " + tmp.file("nope.txt") + " -o " + tmp.file("n.relief"));
  CHECK(missing.code == 2);
  CHECK(has(missing, "nope.txt: cannot open the input list"));
  CHECK_FALSE(fs::exists(tmp.file("n.relief")));
}

TEST_CASE("stream and compress keep name:type text columns as extra bytes", "[cli][ingest][extra]") {
  TempDir tmp;
  write_text(tmp.file("in.txt"),
             "1 2 3 0.5 40 7\n"
             "1.5,2,3,0.25,41,8\n"
             "2;2;3;-1;65535;9\n");
  const std::string columns = " --columns x,y,z,amplitude:f32,ring:u16,_";
  const std::string streamed = tmp.file("s.relief");
  REQUIRE(run("stream " + streamed + columns + " --cell 1 --quiet < " + tmp.file("in.txt")).code == 0);
  const std::string compressed = tmp.file("c.relief");
  // A file picks one delimiter from its first line (a stream takes any on each line).
  write_text(tmp.file("in.csv"), "1,2,3,0.5,40,7\n1.5,2,3,0.25,41,8\n2,2,3,-1,65535,9\n");
  REQUIRE(run("compress " + tmp.file("in.csv") + " -o " + compressed + columns + " --quiet").code == 0);
  for (const std::string& archive : {streamed, compressed}) {
    CAPTURE(archive);
    REQUIRE(run("decompress " + archive + " -o " + tmp.file("out.csv") + " --quiet").code == 0);
    std::ifstream in(tmp.file("out.csv"));
    std::vector<std::string> lines;
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    REQUIRE(lines.size() == 4);
    CHECK(lines[0] == "X,Y,Z,amplitude,ring");
    std::sort(lines.begin() + 1, lines.end());
    CHECK(lines[1] == "1.000,2.000,3.000,0.5,40");
    CHECK(lines[2] == "1.500,2.000,3.000,0.25,41");
    CHECK(lines[3] == "2.000,2.000,3.000,-1,65535");
  }
  // A stream of other extra fields does not append; a value that does not fit
  // its type names the line and writes nothing.
  const Run other = run("stream " + streamed + " --columns x,y,z,amplitude:f64,ring:u16 --quiet < " +
                        tmp.file("in.txt"));
  CHECK(other.code == 11);
  CHECK(has(other, "other extra bytes fields"));
  write_text(tmp.file("bad.txt"), "1 2 3 0.5 40\n1 2 3 0.5 65536\n");
  const Run bad = run("stream " + tmp.file("b.relief") + " --columns x,y,z,amplitude:f32,ring:u16 --cell 1 --quiet < " +
                      tmp.file("bad.txt"));
  CHECK(bad.code == 13);
  CHECK(has(bad, "stdin: line 2: column 5 '65536' is out of range (the uint16 field 'ring')"));
  CHECK_FALSE(fs::exists(tmp.file("b.relief")));
  const Run typo = run("stream " + tmp.file("b.relief") + " --columns x,y,z,amplitude:f16 --cell 1 < " +
                       tmp.file("bad.txt"));
  CHECK(typo.code == 2);
  CHECK(has(typo, "the type of an extra field is one of u8"));
}

TEST_CASE("stream --format binary reads typed LAS fields and gives them back", "[cli][ingest]") {
  TempDir tmp;
  // Records: f64 x y z, u8 r g b, f32 intensity, f64 GPS time, u8 return
  // number, 2 padding bytes, u16 point source ID.
  const auto record = [](double x, std::uint8_t r, float intensity, double t, std::uint8_t ret, std::uint16_t src) {
    std::string b;
    const auto put = [&](const auto v) { b.append(reinterpret_cast<const char*>(&v), sizeof v); };
    put(x), put(2.0), put(3.0), put(r), put(std::uint8_t{0}), put(std::uint8_t{9}), put(intensity), put(t), put(ret);
    b.append("\xEE\xEE", 2);
    put(src);
    return b;
  };
  const std::string fields = " --format binary --attributes rgb,intensity,gps_time,return_number,_2,point_source_id";
  {
    std::ofstream f(tmp.file("in.bin"), std::ios::binary);
    f << record(1, 10, 5, 100.25, 2, 7) << record(1.5, 11, 6, 100.5, 1, 65535) << record(2, 12, 7, 100.75, 3, 0);
  }
  const std::string archive = tmp.file("s.relief");
  REQUIRE(run("stream " + archive + fields + " --cell 1 --quiet < " + tmp.file("in.bin")).code == 0);
  REQUIRE(run("decompress " + archive + " -o " + tmp.file("out.csv") + " --quiet").code == 0);
  std::ifstream in(tmp.file("out.csv"));
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  REQUIRE(lines.size() == 4);
  CHECK(lines[0] == "X,Y,Z,Red,Green,Blue,Intensity,ReturnNumber,PointSourceId,GpsTime");
  std::sort(lines.begin() + 1, lines.end());
  CHECK(lines[1] == "1.000,2.000,3.000,10,0,9,5,2,7,100.25");
  CHECK(lines[2] == "1.500,2.000,3.000,11,0,9,6,1,65535,100.5");
  CHECK(lines[3] == "2.000,2.000,3.000,12,0,9,7,3,0,100.75");
  // Fields of other kinds as extra bytes, named and typed.
  {
    std::ofstream f(tmp.file("extra.bin"), std::ios::binary);
    for (int i = 0; i < 3; ++i) {
      const double xyz[3] = {1.0 + i, 2.0, 3.0};
      const float amplitude = 0.5f * static_cast<float>(i);
      const std::uint16_t ring = static_cast<std::uint16_t>(40 + i);
      f.write(reinterpret_cast<const char*>(xyz), sizeof xyz);
      f.write(reinterpret_cast<const char*>(&amplitude), sizeof amplitude);
      f.write(reinterpret_cast<const char*>(&ring), sizeof ring);
    }
  }
  const std::string extra = tmp.file("e.relief");
  REQUIRE(run("stream " + extra + " --format binary --attributes amplitude:f32,ring:u16 --cell 1 --quiet < " +
              tmp.file("extra.bin")).code == 0);
  REQUIRE(run("decompress " + extra + " -o " + tmp.file("e.csv") + " --quiet").code == 0);
  {
    std::ifstream in(tmp.file("e.csv"));
    std::vector<std::string> rows;
    for (std::string line; std::getline(in, line);) rows.push_back(line);
    REQUIRE(rows.size() == 4);
    CHECK(rows[0] == "X,Y,Z,amplitude,ring");
    std::sort(rows.begin() + 1, rows.end());
    CHECK(rows[1] == "1.000,2.000,3.000,0,40");
    CHECK(rows[3] == "3.000,2.000,3.000,1,42");
  }
  // Appending other extra fields to that archive is refused.
  const Run other = run("stream " + extra + " --format binary --attributes amplitude:f64,ring:u16 --quiet < " +
                        tmp.file("extra.bin"));
  CHECK(other.code == 11);
  CHECK(has(other, "other extra bytes fields"));
  // A value out of its dimension's range names the record and keeps nothing.
  {
    std::ofstream f(tmp.file("bad.bin"), std::ios::binary);
    f << record(1, 10, 5, 100.25, 2, 7) << record(1.5, 11, 6, 100.5, 16, 1);
  }
  const Run bad = run("stream " + tmp.file("b.relief") + fields + " --cell 1 --quiet < " + tmp.file("bad.bin"));
  CHECK(bad.code == 13);
  CHECK(has(bad, "stdin: record 2: return number 16"));
  CHECK_FALSE(fs::exists(tmp.file("b.relief")));
}

TEST_CASE("stream refuses a chunk edge of more than 2^21 cells before creating the archive", "[cli][ingest]") {
  TempDir tmp;
  write_text(tmp.file("in.txt"), grid_xyz("5 5 5"));
  const Run r = run("stream " + tmp.file("s.relief") + " --cell 1 --chunk-edge 1e9 < " + tmp.file("in.txt"));
  CHECK(r.code == 11);
  CHECK(has(r, "more than 2^21 cells"));
  CHECK_FALSE(has(r, "chunk ("));
  CHECK_FALSE(fs::exists(tmp.file("s.relief")));
}

namespace {

// A valid LAS 1.2 header (point format 0) declaring no points.
std::string empty_las() {
  std::string h;
  auto put = [&h](auto v) {
    for (std::size_t i = 0; i < sizeof v; ++i) {
      std::uint64_t bits = 0;
      std::memcpy(&bits, &v, sizeof v);
      h.push_back(static_cast<char>((bits >> (8 * i)) & 0xFF));
    }
  };
  h += "LASF";
  put(std::uint16_t{0});                 // file source id
  put(std::uint16_t{0});                 // global encoding
  h.append(16, '\0');                    // project GUID
  put(std::uint8_t{1});                  // version 1.2
  put(std::uint8_t{2});
  h.append(64, '\0');                    // system identifier, generating software
  put(std::uint16_t{1});                 // creation day, year
  put(std::uint16_t{2024});
  put(std::uint16_t{227});               // header size
  put(std::uint32_t{227});               // offset to point data
  put(std::uint32_t{0});                 // VLR count
  put(std::uint8_t{0});                  // point format
  put(std::uint16_t{20});                // record length
  for (int i = 0; i < 6; ++i) put(std::uint32_t{0});  // point count, by return
  for (int i = 0; i < 3; ++i) put(0.001);             // scale
  for (int i = 0; i < 9; ++i) put(0.0);               // offset, then max/min per axis
  return h;
}

}  // namespace

TEST_CASE("empty LAS, PLY and XYZ inputs give empty archives that info and decompress read", "[cli][ingest]") {
  TempDir tmp;
  const std::string las = empty_las();
  REQUIRE(las.size() == 227);
  std::ofstream(tmp.file("empty.las"), std::ios::binary) << las;
  write_text(tmp.file("empty.ply"),
             "ply\nformat binary_little_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
             "property float z\nend_header\n");
  write_text(tmp.file("empty.xyz"), "# no points here\n");
  for (const char* name : {"empty.las", "empty.ply", "empty.xyz"}) {
    for (const char* mode : {"bounded", "resample"}) {
      INFO(name << " " << mode);
      const std::string archive = tmp.file(std::string(name) + "." + mode + ".relief");
      const Run c = run("compress " + tmp.file(name) + " -o " + archive + " --mode " + mode + " --quiet");
      CHECK(c.code == 0);
      CHECK(c.output == "");
      const Run info = run("info " + archive);
      CHECK(info.code == 0);
      CHECK(has(info, "points          0 in, 0 decodable"));
      CHECK(has(info, "chunk edge 32"));
      const Run d = run("decompress " + archive + " -o " + tmp.file("back.xyz") + " --quiet");
      CHECK(d.code == 0);
      std::ifstream back(tmp.file("back.xyz"));
      const std::string text((std::istreambuf_iterator<char>(back)), std::istreambuf_iterator<char>());
      // A LAS source's attributes give the text a header line naming its
      // columns (the bounded mode keeps every one, the resampling mode the
      // classification); nothing follows it.
      if (std::string(name) != "empty.las") {
        CHECK(text.empty());
      } else if (std::string(mode) == "bounded") {
        CHECK(text.starts_with("X Y Z Intensity Classification Synthetic KeyPoint Withheld Overlap ReturnNumber"));
        CHECK(text.find('\n') == text.size() - 1);
      } else {
        CHECK(text == "X Y Z Intensity Classification\n");
      }
    }
  }
}

TEST_CASE("KITTI-like float intensities in 0..1 survive: exactly in PLY, scaled by 65535 in LAS", "[cli][io]") {
  TempDir tmp;
  std::string csv = "x,y,z,intensity\n";
  std::vector<float> values;
  for (int i = 0; i < 400; ++i) {
    // Reflectance as KITTI stores it: floats in 0..1, most not integers.
    const float v = static_cast<float>((i * 37) % 101) / 100.0f;
    values.push_back(v);
    char line[96];
    std::snprintf(line, sizeof line, "%d,%d,%.3f,%.9g\n", i % 20, i / 20, 0.01 * (i % 7), static_cast<double>(v));
    csv += line;
  }
  write_text(tmp.file("kitti.csv"), csv);
  const Run c = run("compress " + tmp.file("kitti.csv") + " -o " + tmp.file("k.relief") + " --quiet");
  REQUIRE(c.code == 0);
  for (const char* out : {"k.ply", "k.las"}) {
    INFO(out);
    const Run d = run("decompress " + tmp.file("k.relief") + " -o " + tmp.file(out) + " --quiet");
    REQUIRE(d.code == 0);
    const relief::Result<relief::PointCloud> got = relief::read_point_file(tmp.file(out));
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    REQUIRE(got->intensities.size() == values.size());
    // Decoded order is the archive's: match points by their grid position.
    for (std::size_t k = 0; k < got->size(); ++k) {
      const auto i = static_cast<std::size_t>(std::lround(got->positions[k].x + 20 * got->positions[k].y));
      REQUIRE(i < values.size());
      const float want = std::string(out) == "k.ply" ? values[i] : static_cast<float>(std::floor(static_cast<double>(values[i]) * 65535.0 + 0.5));
      CHECK(got->intensities[k] == want);
    }
  }
}

TEST_CASE("PLY normals and labels survive compress and decompress, to PLY and to LAS", "[cli][io][extra]") {
  TempDir tmp;
  // 4,000 points on a 2 cm grid, each with normals (float), a label (int32)
  // and a weight (double) that together identify it.
  const int n = 4000;
  std::string ply = "ply\nformat binary_little_endian 1.0\nelement vertex " + std::to_string(n) +
                    "\nproperty double x\nproperty double y\nproperty double z\nproperty float nx\nproperty float ny\n"
                    "property float nz\nproperty int label\nproperty double weight\nend_header\n";
  struct Row {
    relief::Vec3d p;
    std::array<std::uint8_t, 24> extra{};  // nx ny nz label weight, little endian
  };
  std::vector<Row> rows;
  for (int i = 0; i < n; ++i) {
    Row r;
    r.p = {0.02 * (i % 80), 0.02 * (i / 80), 0.001 * (i % 13)};
    const float nx = static_cast<float>(i % 17) / 17.0f, ny = -nx, nz = 0.5f;
    const std::int32_t label = i * 7919 - 1000000;
    const double weight = i / 3.0;
    std::size_t at = 0;
    auto add = [&](const auto& v) {
      std::memcpy(r.extra.data() + at, &v, sizeof(v));
      at += sizeof(v);
    };
    add(nx), add(ny), add(nz), add(label), add(weight);
    ply.append(reinterpret_cast<const char*>(&r.p), sizeof(r.p));
    ply.append(reinterpret_cast<const char*>(r.extra.data()), r.extra.size());
    rows.push_back(std::move(r));
  }
  {
    std::ofstream f(tmp.file("normals.ply"), std::ios::binary);
    f.write(ply.data(), static_cast<std::streamsize>(ply.size()));
  }
  const Run c = run("compress " + tmp.file("normals.ply") + " -o " + tmp.file("n.relief") + " --tolerance 0.001 --quiet");
  REQUIRE(c.code == 0);
  const Run info = run("info " + tmp.file("n.relief"));
  CHECK(has(info, "24 extra bytes: nx (float32), ny (float32), nz (float32), label (int32), weight (float64)"));
  CHECK(has(info, "no LAS input"));

  auto by_extra = [](const Row& a, const Row& b) { return a.extra < b.extra; };
  std::sort(rows.begin(), rows.end(), by_extra);
  for (const char* out : {"back.ply", "back.las"}) {
    INFO(out);
    REQUIRE(run("decompress " + tmp.file("n.relief") + " -o " + tmp.file(out) + " --quiet").code == 0);
    auto reader = relief::open_point_reader(tmp.file(out));
    REQUIRE(reader.is_ok());
    const relief::PointStreamInfo& ri = (*reader)->info();
    REQUIRE(ri.extra_bytes_size == 24);
    std::vector<Row> got;
    relief::PointCloud batch;
    for (;;) {
      auto k = (*reader)->read(batch, 1000);
      REQUIRE(k.is_ok());
      if (*k == 0) break;
      for (std::size_t i = 0; i < *k; ++i) {
        Row r{batch.positions[i], {}};
        std::memcpy(r.extra.data(), batch.las.extra_bytes.data() + i * 24, 24);
        got.push_back(r);
      }
    }
    REQUIRE(got.size() == rows.size());
    std::sort(got.begin(), got.end(), by_extra);
    double worst = 0;
    std::size_t same = 0;
    for (std::size_t i = 0; i < rows.size(); ++i) {
      same += got[i].extra == rows[i].extra ? 1 : 0;
      worst = std::max({worst, std::abs(got[i].p.x - rows[i].p.x), std::abs(got[i].p.y - rows[i].p.y),
                        std::abs(got[i].p.z - rows[i].p.z)});
    }
    CHECK(same == rows.size());  // every point keeps its values exactly, beside its own position
    CHECK(worst <= 0.001 * (1 + 1e-9));
  }

  // --no-extra-bytes drops them.
  REQUIRE(run("compress " + tmp.file("normals.ply") + " -o " + tmp.file("plain.relief") + " --no-extra-bytes --quiet")
              .code == 0);
  CHECK_FALSE(has(run("info " + tmp.file("plain.relief")), "extra bytes"));
  // A PLY whose properties differ from the first's is refused, naming both.
  write_text(tmp.file("other.ply"), "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
                                    "property float z\nproperty uchar label\nend_header\n0.5 0.5 0 3\n");
  const Run mixed = run("compress " + tmp.file("normals.ply") + " " + tmp.file("other.ply") + " -o " +
                        tmp.file("mixed.relief") + " --quiet");
  CHECK(mixed.code != 0);
  CHECK(has(mixed, "other.ply has 1 extra bytes per point described by a different Extra Bytes VLR than"));
  CHECK(has(mixed, "normals.ply"));
  CHECK_FALSE(fs::exists(tmp.file("mixed.relief")));
}

TEST_CASE("A PDAL text export keeps its LAS dimensions and other columns through compress and LAS output",
          "[cli][io][xyz][las]") {
  TempDir tmp;
  // 3,000 points as PDAL's writers.text writes them (precision 3), with a
  // scalar field beside the LAS dimensions. GPS times are unique, so they
  // pair each output point with its input.
  struct Row {
    double x, y, z, t, dev;
    int cls, ret, nret, dir, edge, user, src, angle_steps;
  };
  std::vector<Row> rows;
  std::string csv = "\"X\",\"Y\",\"Z\",\"ReturnNumber\",\"NumberOfReturns\",\"ScanDirectionFlag\",\"EdgeOfFlightLine\","
                    "\"Classification\",\"ScanAngleRank\",\"UserData\",\"PointSourceId\",\"GpsTime\",\"Deviation\"\n";
  char line[512];
  for (int i = 0; i < 3000; ++i) {
    Row r;
    r.x = 500000 + 0.01 * (i % 60);
    r.y = 4000000 + 0.01 * (i / 60);
    r.z = 100 + 0.001 * (i % 37);
    r.ret = 1 + i % 3;
    r.nret = 3;
    r.dir = i % 2;
    r.edge = (i / 7) % 2;
    r.cls = (i * 13) % 40;
    r.angle_steps = (i % 301) - 150;  // 0.006 degree steps, as LAS 1.4 stores them
    r.user = i % 256;
    r.src = 7000 + i % 5;
    r.t = 245000 + 0.001 * i;
    r.dev = (i % 11) * 0.125 - 0.5;
    rows.push_back(r);
    std::snprintf(line, sizeof line, "%.3f,%.3f,%.3f,%d,%d,%d,%d,%d,%.3f,%d,%d,%.3f,%.3f\n", r.x, r.y, r.z, r.ret,
                  r.nret, r.dir, r.edge, r.cls, 0.006 * r.angle_steps, r.user, r.src, r.t, r.dev);
    csv += line;
  }
  write_text(tmp.file("pdal.csv"), csv);
  REQUIRE(run("compress " + tmp.file("pdal.csv") + " -o " + tmp.file("p.relief") + " --tolerance 0.0005 --quiet").code ==
          0);
  const Run info = run("info " + tmp.file("p.relief"));
  CHECK(has(info, "classification"));
  CHECK(has(info, "gps_time"));
  CHECK(has(info, "8 extra bytes: Deviation (float64)"));
  REQUIRE(run("decompress " + tmp.file("p.relief") + " -o " + tmp.file("back.las") + " --quiet").code == 0);
  const auto back = relief::read_point_file(tmp.file("back.las"));
  REQUIRE(back.is_ok());
  const relief::PointCloud& c = *back;
  REQUIRE(c.size() == rows.size());
  REQUIRE(c.las.gps_time.size() == rows.size());
  REQUIRE(c.las.extra_bytes_size == 8);
  std::size_t same = 0;
  for (std::size_t i = 0; i < c.size(); ++i) {
    const auto k = static_cast<std::size_t>(std::lround((c.las.gps_time[i] - 245000) * 1000));
    REQUIRE(k < rows.size());
    const Row& r = rows[k];
    double dev = 0;
    std::memcpy(&dev, c.las.extra_bytes.data() + 8 * i, 8);
    const bool ok = std::abs(c.positions[i].x - r.x) <= 0.0005 + 1e-9 && std::abs(c.positions[i].z - r.z) <= 0.0005 + 1e-9 &&
                    c.las.return_number[i] == r.ret && c.las.number_of_returns[i] == r.nret &&
                    c.las.scan_flags[i] == (r.dir | r.edge << 1) && c.las.classification[i] == r.cls &&
                    c.las.scan_angle[i] == 6 * r.angle_steps && c.las.user_data[i] == r.user &&
                    c.las.point_source_id[i] == r.src && dev == r.dev;
    same += ok ? 1 : 0;
  }
  CHECK(same == rows.size());
}

TEST_CASE("LAS output of a non-LAS archive at UTM coordinates and a 1 mm grid moves the grid's offset",
          "[cli][las]") {
  // A text source's grid has origin 0: 4,000,000 m at 1 mm needs more than
  // 32 bits, so the writer shifts the offset by whole steps and every point
  // stays on the grid (before, the decompress was refused).
  TempDir tmp;
  std::string xyz;
  for (int i = 0; i < 500; ++i) {
    xyz += std::to_string(500000.0 + 0.013 * i) + " " + std::to_string(4000000.0 + 0.007 * (i % 50)) + " " +
           std::to_string(100.0 + 0.001 * (i % 9)) + "\n";
  }
  write_text(tmp.file("utm.xyz"), xyz);
  REQUIRE(run("compress " + tmp.file("utm.xyz") + " -o " + tmp.file("u.relief") + " --quiet").code == 0);
  const Run d = run("decompress " + tmp.file("u.relief") + " -o " + tmp.file("u.las") + " --quiet");
  INFO(d.output);
  REQUIRE(d.code == 0);
  const auto got = relief::read_point_file(tmp.file("u.las"));
  REQUIRE(got.is_ok());
  REQUIRE(got->size() == 500);
  std::vector<relief::Vec3d> want;
  for (int i = 0; i < 500; ++i) {
    want.push_back({500000.0 + 0.013 * i, 4000000.0 + 0.007 * (i % 50), 100.0 + 0.001 * (i % 9)});
  }
  std::vector<relief::Vec3d> back = got->positions;
  const auto by_x = [](const relief::Vec3d& a, const relief::Vec3d& b) { return a.x < b.x; };
  std::sort(back.begin(), back.end(), by_x);
  double worst = 0;
  for (std::size_t i = 0; i < back.size(); ++i) {
    const relief::Vec3d& p = back[i];
    // On the 1 mm grid of origin 0 (to the double rounding of the LAS sum).
    for (const double v : {p.x, p.y, p.z}) CHECK(std::abs(v * 1000 - std::round(v * 1000)) < 1e-4);
    worst = std::max({worst, std::abs(p.x - want[i].x), std::abs(p.y - want[i].y), std::abs(p.z - want[i].z)});
  }
  CHECK(worst <= 0.0005 + 1e-9);  // the default tolerance
}
