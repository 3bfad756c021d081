// bench/attributes: what the error-bounded codec spends on each LAS attribute
// of the shared LAZ files, against the LAZ file itself.
//
// The points come from each LAZ file's LAS twin, parsed here (LAS 1.0-1.4
// point formats 0-10, ASPRS layouts) straight into PointCloud::las, so the
// codec can be measured before the readers fill it. Points are cut into
// chunks of --chunk points in Morton order of their LAS integers (spatially
// compact, like the archive's chunks) and encoded at the LAS scale (tolerance
// half the scale: lossless); the coded bytes of every section are summed over
// the chunks. For layered LAZ (point formats 6-10) the LAZ bytes of each layer
// are read from the chunk headers, so the two columns compare like for like.
// Every blob is decoded back and its points' LAS attributes checked exact.
// Options: --chunk N (points per chunk, default 131072), --data DIR (the
// shared data folder, default ../shared/data beside the checkout).
// stderr: encode and decode CPU seconds per file (the codec on one thread).
// Prints CSV: file, points, part, relief bytes, relief bits/point, LAZ bytes,
// LAZ bits/point; last per file, the whole archive `relief compress F.laz`
// makes with its defaults (compress_files, SQLite pages and all).
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "relief/codec.h"
#include "relief/ingest.h"
#include "relief/types.h"

namespace {

namespace fs = std::filesystem;
using namespace relief;

std::vector<std::uint8_t> slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

template <typename T>
T get(const std::vector<std::uint8_t>& d, std::size_t at) {
  T v{};
  if (at + sizeof(T) <= d.size()) std::memcpy(&v, d.data() + at, sizeof(T));
  return v;
}

// Each point's LAS attributes as one byte string, sorted: the decoder returns
// the points in its own order, so the check compares the multisets.
std::vector<std::string> las_records(const LasAttributes& a, std::size_t n) {
  std::vector<std::string> out(n);
  const auto add = [&](const auto& v, std::size_t width) {
    if (v.empty()) return;
    for (std::size_t i = 0; i < n; ++i) {
      out[i].append(reinterpret_cast<const char*>(v.data()) + i * width * sizeof(v[0]), width * sizeof(v[0]));
    }
  };
  add(a.classification, 1);
  add(a.class_flags, 1);
  add(a.return_number, 1);
  add(a.number_of_returns, 1);
  add(a.scan_flags, 1);
  add(a.scan_angle, 1);
  add(a.user_data, 1);
  add(a.point_source_id, 1);
  add(a.gps_time, 1);
  add(a.nir, 1);
  add(a.color_low, 1);
  add(a.extra_bytes, a.extra_bytes_size);
  std::sort(out.begin(), out.end());
  return out;
}

// CPU seconds of this process (the codec runs on this one thread), so a busy
// machine slows the figures less than wall time.
double cpu_seconds() {
  timespec t{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

struct LasFile {
  int format = 0;
  PointCloud cloud;
  std::vector<std::array<std::int32_t, 3>> ints;
  Vec3d scale, offset;
};

// Standard record sizes of point formats 0-10; the rest of a record is extra bytes.
constexpr int kRecordSize[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};

bool parse_las(const fs::path& path, LasFile& out, std::string& error) {
  const std::vector<std::uint8_t> d = slurp(path);
  if (d.size() < 227 || std::memcmp(d.data(), "LASF", 4) != 0) {
    error = "not a LAS file";
    return false;
  }
  const int minor = d[25];
  const auto offset = get<std::uint32_t>(d, 96);
  const int format = d[104] & 0x3F;
  const auto rec = get<std::uint16_t>(d, 105);
  std::uint64_t n = get<std::uint32_t>(d, 107);
  if (minor >= 4 && d.size() >= 255 && n == 0) n = get<std::uint64_t>(d, 247);
  if (format > 10 || rec < kRecordSize[format] || offset + n * rec > d.size()) {
    error = "unsupported point format or truncated records";
    return false;
  }
  out.format = format;
  out.scale = {get<double>(d, 131), get<double>(d, 139), get<double>(d, 147)};
  out.offset = {get<double>(d, 155), get<double>(d, 163), get<double>(d, 171)};
  const bool legacy = format <= 5;
  const bool has_gps = format == 1 || format >= 3;
  const bool has_rgb = format == 2 || format == 3 || format == 5 || format == 7 || format == 8 || format == 10;
  const bool has_nir = format == 8 || format == 10;
  const std::uint32_t extra = rec - static_cast<std::uint32_t>(kRecordSize[format]);
  PointCloud& c = out.cloud;
  LasAttributes& a = c.las;
  a.extra_bytes_size = extra;
  std::vector<std::array<std::uint16_t, 3>> rgb16;
  for (std::uint64_t i = 0; i < n; ++i) {
    const std::size_t p = offset + i * rec;
    const std::array<std::int32_t, 3> xyz{get<std::int32_t>(d, p), get<std::int32_t>(d, p + 4), get<std::int32_t>(d, p + 8)};
    out.ints.push_back(xyz);
    c.positions.push_back({out.offset.x + xyz[0] * out.scale.x, out.offset.y + xyz[1] * out.scale.y,
                           out.offset.z + xyz[2] * out.scale.z});
    c.intensities.push_back(get<std::uint16_t>(d, p + 12));
    std::size_t gps_at = 0, rgb_at = 0;
    if (legacy) {
      const std::uint8_t ret = d[p + 14], cls = d[p + 15];
      a.return_number.push_back(ret & 7);
      a.number_of_returns.push_back((ret >> 3) & 7);
      a.scan_flags.push_back(static_cast<std::uint8_t>(ret >> 6));
      a.classification.push_back(cls & 31);
      a.class_flags.push_back(static_cast<std::uint8_t>(cls >> 5));
      a.scan_angle.push_back(static_cast<std::int8_t>(d[p + 16]) * 1000);
      a.user_data.push_back(d[p + 17]);
      a.point_source_id.push_back(get<std::uint16_t>(d, p + 18));
      gps_at = p + 20;
      rgb_at = format == 2 ? p + 20 : p + 28;
    } else {
      const std::uint8_t ret = d[p + 14], flags = d[p + 15];
      a.return_number.push_back(ret & 15);
      a.number_of_returns.push_back(ret >> 4);
      a.class_flags.push_back(flags & 15);
      a.scan_flags.push_back(static_cast<std::uint8_t>(((flags >> 6) & 3) | ((flags >> 4) & 3) << 2));
      a.classification.push_back(d[p + 16]);
      a.user_data.push_back(d[p + 17]);
      a.scan_angle.push_back(get<std::int16_t>(d, p + 18) * 6);
      a.point_source_id.push_back(get<std::uint16_t>(d, p + 20));
      gps_at = p + 22;
      rgb_at = p + 30;
    }
    if (has_gps) a.gps_time.push_back(get<double>(d, gps_at));
    if (has_rgb) {
      rgb16.push_back({get<std::uint16_t>(d, rgb_at), get<std::uint16_t>(d, rgb_at + 2), get<std::uint16_t>(d, rgb_at + 4)});
    }
    if (has_nir) a.nir.push_back(get<std::uint16_t>(d, rgb_at + 6));
    const std::size_t extra_at = p + static_cast<std::size_t>(kRecordSize[format]);
    a.extra_bytes.insert(a.extra_bytes.end(), d.begin() + static_cast<std::ptrdiff_t>(extra_at),
                         d.begin() + static_cast<std::ptrdiff_t>(extra_at + extra));
  }
  if (has_rgb) {
    // The readers' rule (io/stream_support.h): levels all at most 255 are
    // 8-bit levels kept as they are, colour and low byte both the level;
    // otherwise the colour is the high byte and the low byte the rest.
    std::uint16_t max_level = 0;
    for (const auto& v : rgb16) max_level = std::max({max_level, v[0], v[1], v[2]});
    const int shift = max_level > 255 ? 8 : 0;
    for (const auto& v : rgb16) {
      c.colors.push_back({static_cast<std::uint8_t>(v[0] >> shift), static_cast<std::uint8_t>(v[1] >> shift),
                          static_cast<std::uint8_t>(v[2] >> shift)});
      a.color_low.push_back({static_cast<std::uint8_t>(v[0]), static_cast<std::uint8_t>(v[1]),
                             static_cast<std::uint8_t>(v[2])});
    }
  }
  if (extra == 0) a.extra_bytes_size = 0;
  return true;
}

// LAZ layer bytes of a layered (point format 6-10) file, by layer name;
// empty when the file is pointwise or not understood.
std::map<std::string, std::uint64_t> laz_layers(const fs::path& path, int format, std::uint32_t extra) {
  std::map<std::string, std::uint64_t> out;
  if (format < 6) return out;
  const std::vector<std::uint8_t> d = slurp(path);
  const auto offset = get<std::uint32_t>(d, 96);
  const auto rec = get<std::uint16_t>(d, 105);
  std::uint64_t n = get<std::uint32_t>(d, 107);
  if (n == 0) n = get<std::uint64_t>(d, 247);
  std::vector<std::string> names = {"xy", "z", "classification", "flags", "intensity", "scan_angle", "user_data",
                                    "point_source_id", "gps_time"};
  if (format == 7 || format == 8 || format == 10) names.push_back("rgb");
  if (format == 8 || format == 10) names.push_back("nir");
  for (std::uint32_t j = 0; j < extra; ++j) names.push_back("extra_bytes");
  const auto table = get<std::int64_t>(d, offset);
  std::size_t at = offset + 8;
  std::uint64_t seen = 0;
  while (seen < n && at + rec + 4 <= d.size()) {
    at += rec;  // the chunk's first point, raw
    const auto count = get<std::uint32_t>(d, at);
    at += 4;
    std::vector<std::uint32_t> sizes(names.size());
    for (auto& s : sizes) {
      s = get<std::uint32_t>(d, at);
      at += 4;
    }
    out["first point + sizes"] += rec + 4 + 4 * names.size();
    for (std::size_t k = 0; k < names.size(); ++k) {
      out[names[k]] += sizes[k];
      at += sizes[k];
    }
    seen += count;
  }
  if (static_cast<std::int64_t>(at) != table) out.clear();  // not the layout we expect
  return out;
}

std::uint64_t spread3(std::uint32_t v) {
  std::uint64_t x = v & 0x1FFFFF;
  x = (x | x << 32) & 0x1F00000000FFFFull;
  x = (x | x << 16) & 0x1F0000FF0000FFull;
  x = (x | x << 8) & 0x100F00F00F00F00Full;
  x = (x | x << 4) & 0x10C30C30C30C30C3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}

}  // namespace

// The size of the archive `relief compress` makes of `input` with its
// defaults (two threads), in `tmp`; nothing when it fails (said on stderr).
std::optional<std::uint64_t> archive_bytes(const fs::path& input, const fs::path& tmp) {
  const std::string archive = (tmp / "attributes.relief").string();
  fs::remove(archive);
  relief::IngestOptions o;
  o.threads = 2;
  auto made = relief::compress_files({input.string()}, archive, o);
  if (!made) {
    std::fprintf(stderr, "attributes: relief compress %s: %s\n", input.c_str(), made.status().to_string().c_str());
    return std::nullopt;
  }
  const std::uint64_t bytes = fs::file_size(archive);
  fs::remove(archive);
  return bytes;
}

int main(int argc, char** argv) {
  relief::retain_freed_memory();  // as the relief CLI does (relief/types.h)
  std::size_t chunk = std::size_t{1} << 17;
  fs::path data = RELIEF_BENCH_DATA_DIR;
  bool no_las = false;  // encode without the LAS attributes (for the time they cost)
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--chunk") == 0 && i + 1 < argc) chunk = std::strtoull(argv[++i], nullptr, 10);
    if (std::strcmp(argv[i], "--data") == 0 && i + 1 < argc) data = argv[++i];
    if (std::strcmp(argv[i], "--no-las") == 0) no_las = true;
  }
  if (chunk == 0) chunk = 1;
  const fs::path dir = data / "laz";
  if (!fs::exists(dir)) {
    std::fprintf(stderr, "attributes: %s is absent; nothing to measure\n", dir.c_str());
    return 0;
  }
  std::vector<fs::path> lazs;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() == ".laz") lazs.push_back(e.path());
  }
  std::sort(lazs.begin(), lazs.end());
  const fs::path tmp = fs::temp_directory_path() / ("relief-bench-attributes-" + std::to_string(::getpid()));
  fs::create_directories(tmp);
  std::printf("file,points,part,relief_bytes,relief_bits_per_point,laz_bytes,laz_bits_per_point\n");
  for (const fs::path& laz : lazs) {
    fs::path twin = laz;
    twin.replace_extension(".las");
    if (!fs::exists(twin)) twin = dir.parent_path() / "medium" / "orig" / twin.filename();
    if (!fs::exists(twin)) {
      std::fprintf(stderr, "attributes: no LAS twin for %s\n", laz.c_str());
      continue;
    }
    LasFile las;
    std::string error;
    if (!parse_las(twin, las, error)) {
      std::fprintf(stderr, "attributes: %s: %s\n", twin.c_str(), error.c_str());
      continue;
    }
    const std::size_t n = las.cloud.size();
    // Morton order of the LAS integers, then runs of `chunk` points.
    std::array<std::int32_t, 3> lo{INT32_MAX, INT32_MAX, INT32_MAX};
    for (const auto& v : las.ints) {
      for (int a = 0; a < 3; ++a) lo[static_cast<std::size_t>(a)] = std::min(lo[static_cast<std::size_t>(a)], v[static_cast<std::size_t>(a)]);
    }
    std::vector<std::pair<std::uint64_t, std::uint32_t>> keys(n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto& v = las.ints[i];
      const auto c = [&](int a) {
        return static_cast<std::uint32_t>(static_cast<std::int64_t>(v[static_cast<std::size_t>(a)]) - lo[static_cast<std::size_t>(a)]) >> 0;
      };
      keys[i] = {spread3(c(0) >> 3) | spread3(c(1) >> 3) << 1 | spread3(c(2) >> 3) << 2, static_cast<std::uint32_t>(i)};
    }
    std::sort(keys.begin(), keys.end());
    EncodeParams p;
    p.bound = ErrorBound{};
    p.bound->step = las.scale;
    p.bound->origin = las.offset;
    std::map<int, std::uint64_t> bytes;
    std::uint64_t total = 0;
    double seconds = 0, decode_seconds = 0;
    for (std::size_t s = 0; s < n; s += chunk) {
      std::vector<std::uint32_t> idx;
      for (std::size_t k = s; k < std::min(n, s + chunk); ++k) idx.push_back(keys[k].second);
      PointCloud part = las.cloud.gathered(idx);
      if (no_las) part.las = LasAttributes{};
      p.cell_size = suggest_cell_size(part, 16);
      const double t0 = cpu_seconds();
      auto blob = encode_chunk(part, p);
      seconds += cpu_seconds() - t0;
      if (!blob) {
        std::fprintf(stderr, "attributes: %s: %s\n", laz.c_str(), blob.status().to_string().c_str());
        return 1;
      }
      const double t1 = cpu_seconds();
      auto check = decode_chunk(*blob);
      decode_seconds += cpu_seconds() - t1;
      if (!check || check->size() != part.size() || check->las.carried() != part.las.carried() ||
          las_records(check->las, check->size()) != las_records(part.las, part.size())) {
        std::fprintf(stderr, "attributes: %s: the blob does not decode back\n", laz.c_str());
        return 1;
      }
      auto info = inspect_chunk(*blob);
      total += blob->size();
      for (const auto& sec : info->sections) bytes[sec.id] += sec.coded_size;
    }
    const std::uint32_t extra = las.cloud.las.extra_bytes_size;
    const std::map<std::string, std::uint64_t> layers = laz_layers(laz, las.format, extra);
    const auto bpp = [n](std::uint64_t b) { return 8.0 * static_cast<double>(b) / static_cast<double>(n); };
    const std::string name = laz.filename().string();
    // LAZ's layers that hold one relief section, where the split is the same.
    const std::map<std::string, std::string> same = {
        {"classification", "classification"}, {"user_data", "user_data"}, {"point_source_id", "point_source_id"},
        {"gps_time", "gps_time"}, {"scan_angle", "scan_angle"}, {"nir", "nir"}, {"extra_bytes", "extra_bytes"},
        {"rgb", "rgb"}, {"intensity", "intensity"}};
    std::uint64_t base = 0;
    for (const auto& [id, b] : bytes) {
      if (id <= 6) {
        base += b;
        continue;
      }
      const std::string part = relief::chunk_section_label(id);
      const auto it = same.count(part) ? layers.find(part) : layers.end();
      if (it != layers.end()) {
        std::printf("%s,%zu,%s,%llu,%.3f,%llu,%.3f\n", name.c_str(), n, part.c_str(), static_cast<unsigned long long>(b),
                    bpp(b), static_cast<unsigned long long>(it->second), bpp(it->second));
      } else {
        std::printf("%s,%zu,%s,%llu,%.3f,,\n", name.c_str(), n, part.c_str(), static_cast<unsigned long long>(b), bpp(b));
      }
    }
    // LAZ's "flags" layer holds the classification flags, scan direction,
    // edge and scanner channel; its "xy" layer also holds the return numbers.
    const auto sum = [&](std::initializer_list<int> ids) {
      std::uint64_t b = 0;
      for (const int id : ids) b += bytes.count(id) ? bytes[id] : 0;
      return b;
    };
    if (layers.count("flags")) {
      const std::uint64_t flags = sum({11, 14});
      std::printf("%s,%zu,class_flags+scan_flags vs LAZ flags,%llu,%.3f,%llu,%.3f\n", name.c_str(), n,
                  static_cast<unsigned long long>(flags), bpp(flags),
                  static_cast<unsigned long long>(layers.at("flags")), bpp(layers.at("flags")));
      const std::uint64_t geo = sum({7, 12, 13});
      const std::uint64_t xyz = layers.at("xy") + layers.at("z");
      std::printf("%s,%zu,geometry+returns vs LAZ xy+z,%llu,%.3f,%llu,%.3f\n", name.c_str(), n,
                  static_cast<unsigned long long>(geo), bpp(geo), static_cast<unsigned long long>(xyz), bpp(xyz));
    }
    std::printf("%s,%zu,base layer (maps),%llu,%.3f,,\n", name.c_str(), n, static_cast<unsigned long long>(base), bpp(base));
    const auto laz_size = static_cast<std::uint64_t>(fs::file_size(laz));
    std::printf("%s,%zu,whole (blobs / LAZ file),%llu,%.3f,%llu,%.3f\n", name.c_str(), n,
                static_cast<unsigned long long>(total), bpp(total), static_cast<unsigned long long>(laz_size),
                bpp(laz_size));
    // What a user gets: `relief compress F.laz` with its defaults (lossless at
    // the LAS scale, every attribute, the archive's own chunks), the whole file.
    if (const std::optional<std::uint64_t> archive = archive_bytes(laz, tmp)) {
      std::printf("%s,%zu,archive (relief compress / LAZ file),%llu,%.3f,%llu,%.3f\n", name.c_str(), n,
                  static_cast<unsigned long long>(*archive), bpp(*archive), static_cast<unsigned long long>(laz_size),
                  bpp(laz_size));
      std::fprintf(stderr, "%s: relief compress: %llu bytes, %.3f x the LAZ file\n", name.c_str(),
                   static_cast<unsigned long long>(*archive),
                   static_cast<double>(*archive) / static_cast<double>(laz_size));
    }
    std::fprintf(stderr,
                 "%s: point format %d, %zu points, %u extra bytes, encode %.2f s (%.2f M points/s), decode %.2f s "
                 "(%.2f M points/s), one thread, CPU seconds\n",
                 name.c_str(), las.format, n, extra, seconds, static_cast<double>(n) / seconds * 1e-6, decode_seconds,
                 static_cast<double>(n) / decode_seconds * 1e-6);
  }
  std::error_code ignored;
  fs::remove_all(tmp, ignored);
  return 0;
}
