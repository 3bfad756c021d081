// `relief preview`: the renderer on its own (z-buffer, overlays, PNG) and the
// command end to end on small archives made with `relief compress`.
#include <catch2/catch.hpp>
#include <png.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "box_arg.h"
#include "relief/io.h"
#include "relief/render.h"
#include "support/run_cli.h"
#include "support/synthetic.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using relief::Box3d;
using relief::PointCloud;
using relief::Rgb8;
using relief::Vec3d;
using relief::PreviewImage;
using relief::PreviewOptions;
using relief::PreviewRenderer;
using relief::PreviewView;

namespace {

using Run = relief::test::CliRun;

Run run_cli(const std::string& args) { return relief::test::run_cli(RELIEF_CLI, args); }

// Own prefix and a counter: test_cli.cpp's temporary directories live in the
// same process and must not collide with these.
using PreviewTempDir = relief::test::TempDir;

// Two archives of a 40 x 40 m wavy terrain (x and y from 0 to 40), one with
// colours, one without; made once for all the tests.
struct Archives {
  PreviewTempDir dir;
  std::string colored, plain;
  Archives() {
    relief::test::SceneOptions o;
    o.points = 60000;
    o.colors = true;
    REQUIRE(relief::write_ply(dir.file("rgb.ply"), relief::test::make_terrain(o, 40, 2)).is_ok());
    o.colors = false;
    o.seed = 2;
    REQUIRE(relief::write_ply(dir.file("plain.ply"), relief::test::make_terrain(o, 40, 2)).is_ok());
    colored = dir.file("rgb.relief");
    plain = dir.file("plain.relief");
    const Run a = run_cli("compress " + dir.file("rgb.ply") + " -o " + colored + " --quiet");
    INFO(a.output);
    REQUIRE(a.code == 0);
    const Run b = run_cli("compress " + dir.file("plain.ply") + " -o " + plain + " --quiet");
    INFO(b.output);
    REQUIRE(b.code == 0);
  }
};

const Archives& archives() {
  static const Archives a;
  return a;
}

std::vector<std::uint8_t> file_bytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

std::uint32_t be32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) | p[3];
}

// Width and height from the PNG signature and IHDR chunk; {0, 0} if not a PNG.
std::pair<std::uint32_t, std::uint32_t> png_size(const std::vector<std::uint8_t>& b) {
  static const std::uint8_t kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (b.size() < 24 || !std::equal(kSignature, kSignature + 8, b.begin())) return {0, 0};
  if (std::string(b.begin() + 12, b.begin() + 16) != "IHDR") return {0, 0};
  return {be32(b.data() + 16), be32(b.data() + 20)};
}

std::pair<std::uint32_t, std::uint32_t> png_file_size(const std::string& path) { return png_size(file_bytes(path)); }

// Decodes a PNG file to 8-bit RGB with libpng's simplified API.
PreviewImage read_png(const std::string& path) {
  png_image image{};
  image.version = PNG_IMAGE_VERSION;
  PreviewImage out;
  if (!png_image_begin_read_from_file(&image, path.c_str())) return out;
  image.format = PNG_FORMAT_RGB;
  out.rgb.resize(PNG_IMAGE_SIZE(image));
  if (!png_image_finish_read(&image, nullptr, out.rgb.data(), 0, nullptr)) {
    png_image_free(&image);
    return PreviewImage{};
  }
  out.width = static_cast<int>(image.width);
  out.height = static_cast<int>(image.height);
  return out;
}

// A dense grid of points, one per `step` units, over [x0, x1] x [y0, y1] at height z.
PointCloud grid(double x0, double y0, double x1, double y1, double step, double z, Rgb8 color, bool with_colors) {
  PointCloud c;
  for (double y = y0 + step / 2; y < y1; y += step) {
    for (double x = x0 + step / 2; x < x1; x += step) {
      c.positions.push_back({x, y, z});
      if (with_colors) c.colors.push_back(color);
    }
  }
  return c;
}

bool is_white(const Rgb8& c) { return c.r == 255 && c.g == 255 && c.b == 255; }

// Longest run of white pixels starting in the left 40 pixels of any of the
// bottom 40 rows: the scale bar.
int scale_bar_length(const PreviewImage& img) {
  int best = 0;
  for (int y = std::max(0, img.height - 40); y < img.height; ++y) {
    for (int x0 = 0; x0 < 40 && x0 < img.width; ++x0) {
      if (!is_white(img.at(x0, y))) continue;
      int x = x0;
      while (x < img.width && is_white(img.at(x, y))) ++x;
      best = std::max(best, x - x0);
      break;
    }
  }
  return best;
}

int count_white(const PreviewImage& img, int x0, int y0, int x1, int y1) {
  int n = 0;
  for (int y = std::max(0, y0); y < std::min(y1, img.height); ++y) {
    for (int x = std::max(0, x0); x < std::min(x1, img.width); ++x) n += is_white(img.at(x, y)) ? 1 : 0;
  }
  return n;
}

Box3d box(double x0, double y0, double z0, double x1, double y1, double z1) {
  Box3d b;
  b.min = {x0, y0, z0};
  b.max = {x1, y1, z1};
  return b;
}

long long number_after(const std::string& text, const std::string& label) {
  const auto at = text.find(label);
  if (at == std::string::npos) return -1;
  return std::stoll(text.substr(at + label.size()));
}

}  // namespace

// ---------------------------------------------------------------- renderer

TEST_CASE("preview renderer: the z-buffer keeps the highest point, whatever the order", "[preview]") {
  // 200 x 100 units at 0.5 units per pixel: 400 x 200 pixels, one point per pixel.
  const Rgb8 red{200, 30, 30}, green{30, 200, 30}, blue{30, 30, 200};
  const PointCloud ground = grid(0, 0, 200, 100, 0.5, 0, red, true);
  const PointCloud roof = grid(90, 40, 110, 60, 0.5, 3, green, true);
  const PointCloud below = grid(0, 0, 200, 100, 0.5, -3, blue, true);
  for (int order = 0; order < 2; ++order) {
    PreviewOptions o;
    o.width = 400;
    o.use_colors = true;
    auto r = PreviewRenderer::create(box(0, 0, -5, 200, 100, 5), o);
    REQUIRE(r.is_ok());
    CHECK(r->width() == 400);
    CHECK(r->height() == 200);
    CHECK(r->pixel_size() == Approx(0.5));
    if (order == 0) {
      REQUIRE(r->add(ground).is_ok());
      REQUIRE(r->add(roof).is_ok());
      REQUIRE(r->add(below).is_ok());
    } else {
      REQUIRE(r->add(below).is_ok());
      REQUIRE(r->add(roof).is_ok());
      REQUIRE(r->add(ground).is_ok());
    }
    CHECK(r->points_drawn() == ground.size() + roof.size() + below.size());
    auto img = r->finish();
    REQUIRE(img.is_ok());
    CHECK(r->detail_level() == 0);  // dense: drawn at full resolution
    // North up: y = 50 is row 100, x = 100 is column 200; the roof's interior is flat.
    CHECK(img->at(200, 100) == green);
    CHECK(img->at(100, 50) == red);  // flat ground away from the roof edge
    CHECK(img->at(300, 150) == red);
  }
}

TEST_CASE("preview renderer: height colours and hill-shading without RGB", "[preview]") {
  PreviewOptions o;
  o.width = 400;
  auto r = PreviewRenderer::create(box(0, 0, 0, 200, 100, 10), o);
  REQUIRE(r.is_ok());
  REQUIRE(r->add(grid(0, 0, 200, 100, 0.5, 0, {}, false)).is_ok());
  REQUIRE(r->add(grid(90, 40, 110, 60, 0.5, 5, {}, false)).is_ok());
  auto img = r->finish();
  REQUIRE(img.is_ok());
  const Rgb8 low = img->at(100, 50), high = img->at(200, 100);
  // Low is the dark violet end of the ramp, high the yellow end.
  CHECK(high.g > low.g + 100);
  CHECK(high.r > low.r);
  CHECK(low.b > low.g);
  // Hill-shading with light from the north-west: the roof's east and south
  // edges (facing away) are much darker than its west and north edges and
  // than its flat middle. Columns 180..219 and rows 80..119 are the roof.
  const auto brightness = [](Rgb8 c) { return c.r + c.g + c.b; };
  CHECK(brightness(img->at(180, 100)) > brightness(img->at(219, 100)) + 100);  // west vs east edge
  CHECK(brightness(img->at(200, 80)) > brightness(img->at(200, 119)) + 100);   // north vs south edge
  CHECK(brightness(img->at(219, 100)) < brightness(high) / 2);
}

TEST_CASE("preview renderer: scale bar, label and north arrow in the top view", "[preview]") {
  PreviewOptions o;
  o.width = 400;
  auto r = PreviewRenderer::create(box(0, 0, 0, 200, 100, 1), o);
  REQUIRE(r.is_ok());
  REQUIRE(r->add(grid(0, 0, 200, 100, 0.5, 0, {}, false)).is_ok());
  auto img = r->finish();
  REQUIRE(img.is_ok());
  // 20 % of 200 units is 40: the nearest 1-2-5 length is 50 units = 100 pixels.
  const int bar = scale_bar_length(*img);
  CHECK(bar == 100);
  CHECK(bar >= 0.12 * img->width);
  CHECK(bar <= 0.32 * img->width);
  CHECK(count_white(*img, 0, img->height - 50, 80, img->height - 20) > 20);  // the "50 m" label
  CHECK(count_white(*img, img->width - 40, 0, img->width, 50) > 30);         // the north arrow and N
  // Nothing white in the middle of the plane.
  CHECK(count_white(*img, 100, 50, 300, 150) == 0);

  o.overlays = false;
  auto bare = PreviewRenderer::create(box(0, 0, 0, 200, 100, 1), o);
  REQUIRE(bare.is_ok());
  REQUIRE(bare->add(grid(0, 0, 200, 100, 0.5, 0, {}, false)).is_ok());
  auto bare_img = bare->finish();
  REQUIRE(bare_img.is_ok());
  CHECK(scale_bar_length(*bare_img) == 0);
}

TEST_CASE("preview renderer: nice scale lengths and their labels", "[preview]") {
  using relief::format_length;
  using relief::nice_length;
  CHECK(nice_length(40) == Approx(50));
  CHECK(nice_length(37) == Approx(50));
  CHECK(nice_length(140) == Approx(100));
  CHECK(nice_length(170) == Approx(200));
  CHECK(nice_length(0.3) == Approx(0.2));
  CHECK(nice_length(0.04) == Approx(0.05));
  CHECK(nice_length(8000) == Approx(10000));
  CHECK(format_length(50) == "50 m");
  CHECK(format_length(2000) == "2 km");
  CHECK(format_length(0.5) == "0.5 m");
  CHECK(format_length(0.05) == "0.05 m");
  CHECK(format_length(10000) == "10 km");
}

TEST_CASE("preview renderer: image size rules", "[preview]") {
  PreviewOptions o;
  o.width = 1000;
  // Tall frame: the height would be 100000, so it is capped and the width shrinks.
  auto tall = PreviewRenderer::create(box(0, 0, 0, 10, 1000, 1), o);
  REQUIRE(tall.is_ok());
  CHECK(tall->height() == relief::kMaxPreviewSide);
  CHECK(tall->width() == 82);
  // One point (zero extent) still makes a valid image.
  auto dot = PreviewRenderer::create(box(5, 5, 5, 5, 5, 5), o);
  REQUIRE(dot.is_ok());
  CHECK(dot->width() == 1000);
  CHECK(dot->height() >= 1);
  // Bad arguments.
  o.width = 0;
  CHECK(PreviewRenderer::create(box(0, 0, 0, 1, 1, 1), o).status().code() == relief::StatusCode::kInvalidArgument);
  o.width = 100;
  o.view = PreviewView::kOblique;
  const double inf = std::numeric_limits<double>::infinity();
  CHECK_FALSE(PreviewRenderer::create(box(0, 0, -inf, 1, 1, inf), o).is_ok());  // oblique needs finite z
  o.elevation_deg = 95;
  CHECK_FALSE(PreviewRenderer::create(box(0, 0, 0, 1, 1, 1), o).is_ok());
}

TEST_CASE("preview renderer: oblique view fits the points and keeps the nearest", "[preview]") {
  PreviewOptions o;
  o.view = PreviewView::kOblique;
  o.width = 500;
  o.use_colors = true;
  // The frame is much larger than the points: the image is fitted to the points.
  auto r = PreviewRenderer::create(box(-1000, -1000, -10, 1000, 1000, 10), o);
  REQUIRE(r.is_ok());
  const Rgb8 red{200, 30, 30}, green{30, 200, 30};
  REQUIRE(r->add(grid(0, 0, 100, 100, 0.25, 0, red, true)).is_ok());
  REQUIRE(r->add(grid(30, 30, 70, 70, 0.25, 8, green, true)).is_ok());
  auto img = r->finish();
  REQUIRE(img.is_ok());
  CHECK(img->width == 500);
  CHECK(r->width() == 500);
  // Projected extent of a 100 x 100 square at azimuth 30, elevation 35 (plus
  // the raised block): roughly 137 x 78 units, so about 280 pixels high.
  CHECK(img->height > 220);
  CHECK(img->height < 340);
  // The image centre shows the raised green block (nearest to the viewer).
  const Rgb8 c = img->at(img->width / 2, img->height / 2);
  CHECK(c.g > c.r);
  // Corners of the fitted image are background; the label is drawn.
  CHECK(img->at(2, 2) == relief::kPreviewBackground);
  CHECK(count_white(*img, 0, img->height - 30, 200, img->height) > 20);
}

TEST_CASE("preview renderer: sparse points are drawn at a coarser level, without holes", "[preview]") {
  PreviewOptions o;
  o.width = 400;
  auto r = PreviewRenderer::create(box(0, 0, 0, 200, 100, 1), o);
  REQUIRE(r.is_ok());
  // One point per 2 units = every 4 pixels.
  REQUIRE(r->add(grid(0, 0, 200, 100, 2, 0, {}, false)).is_ok());
  auto img = r->finish();
  REQUIRE(img.is_ok());
  CHECK(r->detail_level() == 2);
  int background = 0;
  for (int y = 20; y < 160; ++y) {
    for (int x = 20; x < 380; ++x) background += img->at(x, y) == relief::kPreviewBackground ? 1 : 0;
  }
  CHECK(background == 0);
}

TEST_CASE("preview renderer: PNG encoding", "[preview]") {
  PreviewImage img;
  img.width = 37;
  img.height = 11;
  img.rgb.assign(37 * 11 * 3, 0);
  for (std::size_t i = 0; i < img.rgb.size(); ++i) img.rgb[i] = static_cast<std::uint8_t>(i * 7);
  auto png = relief::encode_png(img);
  REQUIRE(png.is_ok());
  CHECK(png_size(*png) == std::pair<std::uint32_t, std::uint32_t>(37, 11));
  PreviewTempDir tmp;
  std::ofstream(tmp.file("t.png"), std::ios::binary)
      .write(reinterpret_cast<const char*>(png->data()), static_cast<std::streamsize>(png->size()));
  const PreviewImage back = read_png(tmp.file("t.png"));
  CHECK(back.width == 37);
  CHECK(back.rgb == img.rgb);
  img.rgb.pop_back();
  CHECK_FALSE(relief::encode_png(img).is_ok());
}

TEST_CASE("parse_box: 4 or 6 finite numbers, min <= max", "[preview]") {
  using relief::cli::parse_box;
  Box3d b;
  std::string err;
  REQUIRE(parse_box("1,2,3,4,5,6", b, err));
  CHECK(b.min == Vec3d{1, 2, 3});
  CHECK(b.max == Vec3d{4, 5, 6});
  REQUIRE(parse_box(" -10.5, 2e1 ,+30,40 ", b, err));
  CHECK(b.min.x == -10.5);
  CHECK(b.min.y == 20);
  CHECK(b.max.x == 30);
  CHECK(b.max.y == 40);
  CHECK(std::isinf(b.min.z));
  CHECK(b.min.z < 0);
  CHECK(std::isinf(b.max.z));
  CHECK(b.max.z > 0);
  REQUIRE(parse_box("0,0,0,0,0,0", b, err));  // closed box: a point is fine
  for (const char* bad : {"", "1,2,3", "1,2,3,4,5", "1,2,3,4,5,6,7", "a,b,c,d", "1,2,,4", "1,2,3,nan",
                          "1,2,3,inf", "5,0,1,1", "0,5,1,1", "0,0,5,1,1,1", "1;2;3;4", "1,2,3,4x"}) {
    err.clear();
    INFO(bad);
    CHECK_FALSE(parse_box(bad, b, err));
    CHECK_FALSE(err.empty());
  }
  CHECK_FALSE(parse_box("5,0,1,1", b, err));
  CHECK(err.find("xmin > xmax") != std::string::npos);
  CHECK_FALSE(parse_box("1,2,3", b, err));
  CHECK(err.find("got 3") != std::string::npos);
}

// ---------------------------------------------------------------- command

TEST_CASE("relief preview: top-down and oblique, coloured and not", "[cli][preview]") {
  const Archives& a = archives();
  PreviewTempDir tmp;
  for (const std::string& archive : {a.colored, a.plain}) {
    INFO(archive);
    Run r = run_cli("preview " + archive + " -o " + tmp.file("top.png"));
    INFO(r.output);
    REQUIRE(r.code == 0);
    CHECK(r.output.find("1024 x") != std::string::npos);
    CHECK(number_after(r.output, "points drawn") > 1000);
    CHECK(number_after(r.output, "chunks decoded") >= 1);
    const auto size = png_file_size(tmp.file("top.png"));
    CHECK(size.first == 1024);
    // The terrain is square (within the sampling): so is the image.
    CHECK(size.second >= 1000);
    CHECK(size.second <= 1048);

    r = run_cli("preview " + archive + " -o " + tmp.file("obl.png") +
                " --view oblique --azimuth 45 --elevation 30 --width 600 --quiet");
    INFO(r.output);
    REQUIRE(r.code == 0);
    CHECK(r.output.empty());
    const auto oblique = png_file_size(tmp.file("obl.png"));
    CHECK(oblique.first == 600);
    CHECK(oblique.second > 100);
    CHECK(oblique.second < 600);
  }
  // Only the PNGs are left (the temporary file was renamed into place).
  int files = 0;
  for (const auto& e : fs::directory_iterator(tmp.path())) {
    CHECK(e.path().extension() == ".png");
    ++files;
  }
  CHECK(files == 2);
}

TEST_CASE("relief preview: --box restricts the area, --lod the points", "[cli][preview]") {
  const Archives& a = archives();
  PreviewTempDir tmp;
  const Run all = run_cli("preview " + a.colored + " -o " + tmp.file("all.png") + " --lod 1");
  REQUIRE(all.code == 0);
  const long long all_points = number_after(all.output, "points drawn");

  // The west half (x 0..20), all heights: an image twice as high as wide.
  const Run half = run_cli("preview " + a.colored + " --box 0,0,20,40 --width 400 --lod 1 -o " + tmp.file("half.png"));
  INFO(half.output);
  REQUIRE(half.code == 0);
  CHECK(png_file_size(tmp.file("half.png")) == std::pair<std::uint32_t, std::uint32_t>(400, 800));
  const long long half_points = number_after(half.output, "points drawn");
  CHECK(half_points > all_points * 4 / 10);
  CHECK(half_points < all_points * 6 / 10);

  // A 3D box keeps only the points above z = 0 (about half of them).
  const Run upper = run_cli("preview " + a.colored + " --box=0,0,0,40,40,10 --lod 1 -o " + tmp.file("upper.png"));
  INFO(upper.output);
  REQUIRE(upper.code == 0);
  const long long upper_points = number_after(upper.output, "points drawn");
  CHECK(upper_points > all_points * 3 / 10);
  CHECK(upper_points < all_points * 7 / 10);

  // A coarser level of detail draws fewer points.
  const Run coarse = run_cli("preview " + a.colored + " --lod 16 -o " + tmp.file("coarse.png"));
  REQUIRE(coarse.code == 0);
  CHECK(number_after(coarse.output, "points drawn") < all_points / 4);
}

TEST_CASE("relief preview: a box without points gives an all-background image and exit 0", "[cli][preview]") {
  // The choice: an empty region is a valid answer (scripts tiling an area get
  // an image per tile), said by a warning on stderr.
  const Archives& a = archives();
  PreviewTempDir tmp;
  const Run r = run_cli("preview " + a.colored + " --box 1000,1000,1100,1050 --width 200 -o " + tmp.file("empty.png"));
  INFO(r.output);
  REQUIRE(r.code == 0);
  CHECK(r.output.find("no points in the box") != std::string::npos);
  CHECK(number_after(r.output, "points drawn") == 0);
  const PreviewImage img = read_png(tmp.file("empty.png"));
  REQUIRE(img.width == 200);
  CHECK(img.height == 100);
  CHECK(img.at(100, 50) == relief::kPreviewBackground);
  CHECK(img.at(150, 20) == relief::kPreviewBackground);
}

TEST_CASE("relief preview: errors exit with documented codes and leave no file", "[cli][preview]") {
  const Archives& a = archives();
  PreviewTempDir tmp;
  const std::string out = tmp.file("v.png");
  SECTION("bad boxes are usage errors (exit 2)") {
    for (const char* bad : {"1,2,3", "1,2,3,4,5", "a,b,c,d", "10,0,0,5", "0,0,10,40,40,5", "0,0,0,40", "1,2,3,nan"}) {
      INFO(bad);
      const Run r = run_cli("preview " + a.colored + " --box " + bad + " -o " + out);
      CHECK(r.code == 2);
      CHECK(r.output.find("--box") != std::string::npos);
    }
    CHECK(run_cli("preview " + a.colored + " --box 10,0,0,5 -o " + out).output.find("empty") != std::string::npos);
  }
  SECTION("other usage errors") {
    CHECK(run_cli("preview " + a.colored).code == 2);                                   // no -o
    CHECK(run_cli("preview -o " + out).code == 2);                                      // no archive
    CHECK(run_cli("preview " + a.colored + " --view side -o " + out).code == 2);
    CHECK(run_cli("preview " + a.colored + " --lod 0 -o " + out).code == 2);
    CHECK(run_cli("preview " + a.colored + " --width 9000 -o " + out).code == 2);
    CHECK(run_cli("preview " + a.colored + " --view oblique --elevation 100 -o " + out).code == 2);
    CHECK(run_cli("preview " + a.colored + " --azimuth 10 -o " + out).code == 2);     // needs --view oblique
    CHECK(run_cli("preview " + a.colored + " --bogus -o " + out).code == 2);
    const Run h = run_cli("preview --help");
    CHECK(h.code == 0);
    CHECK(h.output.find("usage: relief preview") != std::string::npos);
  }
  SECTION("a box wider than doubles measure: invalid argument (11), not a NaN's undefined conversion") {
    const Run r = run_cli("preview " + a.colored + " --box -1e308,-1e308,1e308,1e308 -o " + out);
    CHECK(r.code == 11);
    CHECK(r.output.find("wider than doubles can measure") != std::string::npos);
  }
  SECTION("missing archive: I/O error (12) naming it") {
    const Run r = run_cli("preview " + tmp.file("nope.relief") + " -o " + out);
    CHECK(r.code == 12);
    CHECK(r.output.find("nope.relief") != std::string::npos);
  }
  SECTION("not an archive: format error (13)") {
    std::ofstream(tmp.file("text.relief")) << "hello, I am not a SQLite file\n";
    const Run r = run_cli("preview " + tmp.file("text.relief") + " -o " + out);
    CHECK(r.code == 13);
    CHECK(r.output.find("text.relief") != std::string::npos);
    fs::remove(tmp.file("text.relief"));
  }
  SECTION("empty archive: a clear error (invalid argument, 11), with or without a box") {
    PreviewTempDir other;
    const std::string empty = other.file("empty.relief");
    REQUIRE(run_cli("stream " + empty + " --cell 1 --quiet < /dev/null").code == 0);
    for (const std::string& extra : {std::string(), std::string(" --box 0,0,1,1")}) {
      const Run r = run_cli("preview " + empty + extra + " -o " + out);
      CHECK(r.code == 11);
      CHECK(r.output.find("holds no points") != std::string::npos);
    }
  }
  SECTION("unwritable output: I/O error (12) naming it, nothing left behind") {
    const Run r = run_cli("preview " + a.colored + " -o " + tmp.file("no/such/dir/v.png"));
    CHECK(r.code == 12);
    CHECK(r.output.find("v.png") != std::string::npos);
  }
  CHECK(fs::is_empty(tmp.path()));
}

TEST_CASE("render_preview: the library call behind relief preview", "[preview]") {
  const Archives& a = archives();
  auto reader = relief::ArchiveReader::open(a.colored);
  REQUIRE(reader.is_ok());
  relief::PreviewRequest request;
  request.options.width = 200;
  auto whole = relief::render_preview(**reader, request);
  REQUIRE(whole.is_ok());
  CHECK(whole->image.width == 200);
  CHECK(whole->image.height == 200);  // a 40 x 40 m square
  // No pyramid in a 60 k-point archive: lod 16, or the finer lod whose points
  // fill the budget of 2 points a pixel when it holds fewer than 16 budgets.
  const double budget = relief::kPreviewPointsPerPixel * 200 * 200;
  const auto want_lod = static_cast<std::uint32_t>(
      std::clamp(std::ceil(static_cast<double>((*reader)->info().decoded_points) / budget), 1.0, 16.0));
  CHECK(whole->lod == want_lod);
  CHECK(whole->points_drawn > 1000);
  CHECK(whole->stats.chunks_decoded > 0);
  // The CLI writes the same image.
  PreviewTempDir tmp;
  REQUIRE(run_cli("preview " + a.colored + " --width 200 --quiet -o " + tmp.file("p.png")).code == 0);
  const PreviewImage png = read_png(tmp.file("p.png"));
  CHECK(png.rgb == whole->image.rgb);
  // A box: half the width, the same scale.
  request.box = relief::Box3d{{0, 0, -1e300}, {20, 40, 1e300}};
  auto half = relief::render_preview(**reader, request);
  REQUIRE(half.is_ok());
  CHECK(half->image.height == 400);
  CHECK(half->points_drawn < whole->points_drawn);
  // Refusals.
  request.box = relief::Box3d{{0, 0, 0}, {0, 40, 1}};
  CHECK(relief::render_preview(**reader, request).status().code() == relief::StatusCode::kInvalidArgument);
  request.box.reset();
  request.lod = 0;
  CHECK(relief::render_preview(**reader, request).status().code() == relief::StatusCode::kInvalidArgument);
}
