// relief preview ARCHIVE -o view.png: a quick-look image of an archive (or of
// a box of it) at a coarse level of detail, top-down or oblique.
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <mutex>

#include "box_arg.h"
#include "cli_common.h"
#include "commands.h"
#include "relief/image.h"
#include "relief/query.h"
#include "relief/render.h"

namespace relief::cli {

namespace {

constexpr const char* kCommand = "preview";
// -o *.jpg: high enough that the scale bar's text and thin lines stay clean.
constexpr int kPreviewJpegQuality = 90;

}  // namespace

int run_preview(int argc, char** argv) {
  static const std::string usage =
      "usage: relief preview ARCHIVE -o VIEW.png [--box xmin,ymin,xmax,ymax | --box xmin,ymin,zmin,xmax,ymax,zmax]\n"
      "                      [--lod L] [--width W] [--view top|oblique] [--azimuth DEG] [--elevation DEG]\n"
      "                      [--threads N] [--quiet]\n"
      "Draws a quick-look image of an archive, or of the points inside a box, decoding only the chunks\n"
      "the box touches at a coarse level of detail.\n"
      "  -o VIEW.png        output image, PNG (.png) or JPEG (.jpg, .jpeg) by extension (written\n"
      "                     atomically: no partial file on failure)\n"
      "  --box B            region to show: 4 numbers = all heights, 6 = a 3D box (default: the\n"
      "                     archive's bounds). A box without points gives an all-background image\n"
      "                     (exit 0) and a warning; an archive without points is an error (11).\n"
      "  --lod L            level of detail: about 1/L of the points (1..1024; 1 = all). Default: an\n"
      "                     archive with a level-of-detail pyramid reads the finest level that gives\n"
      "                     at most 2 points per pixel; one without, lod 16\n"
      "  --width W          image width in pixels, 16..8192 (default 1024); the height follows the\n"
      "                     aspect ratio, at most 8192\n"
      "  --view top|oblique top: straight down, north up, with a scale bar (default);\n"
      "                     oblique: rotated by the azimuth about z, tilted by the elevation\n"
      "  --azimuth DEG      oblique view rotation about z (default 30)\n"
      "  --elevation DEG    oblique view angle above the horizon, 0..90 (default 35)\n"
      "  --threads N        decoder threads (default: all cores)\n"
      "  --quiet            print nothing on success\n"
      "Colours: the points' RGB when the archive has colours, else a height colour map; both are\n"
      "hill-shaded (light from the north-west in the top view).\n";
  Args args(argc, argv, {"--help", "--quiet"},
            {"-o", "--box", "--lod", "--width", "--view", "--azimuth", "--elevation", "--threads"});
  if (args.has("--help")) {
    std::cout << usage;
    return kExitOk;
  }
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (args.positional().size() != 1) return usage_error(kCommand, "expected one archive");
  const auto out_path = args.get("-o");
  if (!out_path || out_path->empty()) return usage_error(kCommand, "missing -o VIEW.png");
  // The file type follows the name, so a .jpg never gets PNG bytes.
  std::string ext = std::filesystem::path(*out_path).extension().string();
  for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
  const bool jpeg = ext == ".jpg" || ext == ".jpeg";
  if (ext != ".png" && !jpeg) {
    return usage_error(kCommand, "-o " + *out_path + ": preview writes PNG (.png) or JPEG (.jpg, .jpeg)");
  }
  if (Status s = refuse_output_onto_input(*out_path, args.positional()[0]); !s) return fail(kCommand, s);

  PreviewRequest request;
  PreviewOptions& popt = request.options;
  if (args.has("--lod")) request.lod = static_cast<std::uint32_t>(args.get_int("--lod", 16, 1, kMaxLod));
  popt.width = static_cast<int>(args.get_int("--width", 1024, 16, kMaxPreviewSide));
  request.threads = static_cast<unsigned>(args.get_int("--threads", 0, 0, 1024));
  if (const auto v = args.get("--view")) {
    if (*v == "top") {
      popt.view = PreviewView::kTop;
    } else if (*v == "oblique") {
      popt.view = PreviewView::kOblique;
    } else {
      return usage_error(kCommand, "--view must be top or oblique, got '" + *v + "'");
    }
  }
  popt.azimuth_deg = args.get_double("--azimuth", 30);
  popt.elevation_deg = args.get_double("--elevation", 35);
  if (!args.ok()) return usage_error(kCommand, args.error());
  if (popt.view == PreviewView::kTop && (args.has("--azimuth") || args.has("--elevation"))) {
    return usage_error(kCommand, "--azimuth and --elevation need --view oblique");
  }
  if (!(popt.elevation_deg >= 0 && popt.elevation_deg <= 90)) {
    return usage_error(kCommand, "--elevation must be from 0 to 90 degrees");
  }
  if (!(std::fabs(popt.azimuth_deg) <= 360)) {
    return usage_error(kCommand, "--azimuth must be from -360 to 360 degrees");
  }
  if (args.has("--box")) {
    Box3d box;
    std::string err;
    if (!parse_box(*args.get("--box"), box, err)) return usage_error(kCommand, "--box: " + err);
    if (!(box.max.x > box.min.x) || !(box.max.y > box.min.y)) {
      return usage_error(kCommand, "--box must have xmax > xmin and ymax > ymin to make an image");
    }
    request.box = box;
  }
  const bool quiet = args.has("--quiet");
  const std::string& archive_path = args.positional()[0];

  const std::int64_t t0 = now_ns();
  // A missing file is an I/O error however the store would report it.
  struct stat st {};
  if (::stat(archive_path.c_str(), &st) != 0) {
    return fail(kCommand, io_error(archive_path + ": cannot open: " + std::strerror(errno)));
  }
  auto reader = ArchiveReader::open(archive_path);
  if (!reader) return fail(kCommand, reader.status());
  auto rendered = render_preview(**reader, request);
  if (!rendered) return fail(kCommand, rendered.status());
  const PreviewResult& r = *rendered;
  const PreviewImage& image = r.image;
  const double render_s = seconds_since(t0);
  const std::int64_t t1 = now_ns();
  // Very large images: the fastest zlib level (a few seconds saved, ~20 % bigger).
  auto png = jpeg ? encode_jpeg_rgb(image.rgb, image.width, image.height, kPreviewJpegQuality)
                  : encode_png(image, image.rgb.size() > (std::size_t{48} << 20) ? 1 : 3);
  if (!png) return fail(kCommand, png.status().with_context(*out_path));
  if (Status s = write_file(*out_path, *png); !s) return fail(kCommand, s);
  const double png_s = seconds_since(t1);

  if (r.points_drawn == 0) {
    // Not an error: an empty region is a valid answer, and scripts that tile
    // an area want an image for every tile.
    std::cerr << "relief preview: warning: no points in the " << (request.box ? "box" : "archive")
              << "; " << *out_path << " is all background\n";
  }
  if (!quiet) {
    const std::string detail = r.max_points > 0 ? "at most " + std::to_string(r.max_points) + " points"
                                                : "lod " + std::to_string(r.lod);
    std::printf("%s: %d x %d px, %s view, %s, %.4g units/px\n", out_path->c_str(), image.width, image.height,
                popt.view == PreviewView::kTop ? "top" : "oblique", detail.c_str(), r.pixel_size);
    std::printf("points drawn    %llu (of %llu delivered)", static_cast<unsigned long long>(r.points_drawn),
                static_cast<unsigned long long>(r.stats.points));
    if (r.detail_level > 0) {
      // Said so that a soft image is not mistaken for a codec problem.
      std::printf(", sparse: drawn at 1/%d resolution and scaled up%s", 1 << r.detail_level,
                  r.lod > 1 ? " (a lower --lod is sharper)" : "");
    }
    std::printf("\n");
    std::printf("chunks decoded  %llu (of %llu in the archive)", static_cast<unsigned long long>(r.stats.chunks_decoded),
                static_cast<unsigned long long>((*reader)->info().chunk_count));
    if (r.stats.pyramid_level > 0) std::printf(", up to pyramid level %d", r.stats.pyramid_level);
    std::printf(", %s of blobs read\n", format_bytes(r.stats.blob_bytes_read).c_str());
    std::printf("time            %.3f s (open, query, drawing and shading %.3f s, %s %.3f s, %s)\n",
                seconds_since(t0), render_s, jpeg ? "JPEG" : "PNG", png_s, format_bytes(png->size()).c_str());
  }
  return kExitOk;
}

}  // namespace relief::cli
