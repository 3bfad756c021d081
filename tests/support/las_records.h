// LAS point records for tests, written and read here independently of
// lib/io (after the ASPRS LAS 1.2 and 1.4 R15 specifications): a seeded
// generator of files of any point format 0-10 with every field random, and a
// reference decoder that turns a LAS file's records into comparable values.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <optional>
#include <random>
#include <string>
#include <tuple>
#include <vector>

namespace relief::test {

// One record's fields, as integers of the LAS record (scan angle in the
// file's own unit: degrees for 0-5, 0.006 degrees for 6-10).
struct LasRecord {
  std::int32_t x = 0, y = 0, z = 0;
  std::uint16_t intensity = 0;
  std::uint8_t return_number = 0, number_of_returns = 0;
  std::uint8_t scan_direction = 0, edge = 0, channel = 0;
  std::uint8_t classification = 0, synthetic = 0, key_point = 0, withheld = 0, overlap = 0;
  std::int32_t scan_angle = 0;
  std::uint8_t user_data = 0;
  std::uint16_t point_source_id = 0;
  double gps_time = 0;
  std::uint16_t red = 0, green = 0, blue = 0, nir = 0;
  std::vector<std::uint8_t> extra;

  auto tie() const {
    return std::tie(x, y, z, intensity, return_number, number_of_returns, scan_direction, edge, channel,
                    classification, synthetic, key_point, withheld, overlap, scan_angle, user_data, point_source_id,
                    gps_time, red, green, blue, nir, extra);
  }
  friend bool operator==(const LasRecord& a, const LasRecord& b) { return a.tie() == b.tie(); }
  friend bool operator<(const LasRecord& a, const LasRecord& b) { return a.tie() < b.tie(); }
};

struct LasFileRecords {
  int format = -1;
  int version_minor = -1;
  std::uint16_t record_length = 0;
  std::array<double, 3> scale{}, offset{};
  std::vector<std::uint8_t> extra_bytes_vlr;  // payload of LASF_Spec record 4, empty when none
  std::vector<LasRecord> records;
};

// "x y z i ret/nret ..." for failure messages.
inline std::string describe(const LasRecord& p) {
  std::string s = std::to_string(p.x) + " " + std::to_string(p.y) + " " + std::to_string(p.z) + " i" +
                  std::to_string(p.intensity) + " ret " + std::to_string(p.return_number) + "/" +
                  std::to_string(p.number_of_returns) + " dir" + std::to_string(p.scan_direction) + " edge" +
                  std::to_string(p.edge) + " ch" + std::to_string(p.channel) + " class " +
                  std::to_string(p.classification) + " flags " + std::to_string(p.synthetic) +
                  std::to_string(p.key_point) + std::to_string(p.withheld) + std::to_string(p.overlap) + " angle " +
                  std::to_string(p.scan_angle) + " user " + std::to_string(p.user_data) + " src " +
                  std::to_string(p.point_source_id) + " gps " + std::to_string(p.gps_time) + " rgb " +
                  std::to_string(p.red) + "," + std::to_string(p.green) + "," + std::to_string(p.blue) + " nir " +
                  std::to_string(p.nir) + " extra";
  for (const std::uint8_t b : p.extra) s += " " + std::to_string(b);
  return s;
}

// Empty when equal, else the first difference.
inline std::string first_difference(const std::vector<LasRecord>& a, const std::vector<LasRecord>& b) {
  if (a.size() != b.size()) return std::to_string(a.size()) + " records against " + std::to_string(b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (!(a[i] == b[i])) return "record " + std::to_string(i) + ": " + describe(a[i]) + " | " + describe(b[i]);
  }
  return "";
}

namespace las_detail {

template <typename T>
T get(const std::uint8_t* p) {
  T v;
  std::memcpy(&v, p, sizeof v);  // the tests run on little-endian machines
  return v;
}
template <typename T>
void put(std::vector<std::uint8_t>& b, std::size_t at, T v) {
  std::memcpy(b.data() + at, &v, sizeof v);
}

// Minimum record length, RGB, GPS and NIR offsets (0 = none) per format.
struct Format {
  std::size_t length, rgb, gps, nir;
};
inline constexpr std::array<Format, 11> kFormats = {{{20, 0, 0, 0},
                                                     {28, 0, 20, 0},
                                                     {26, 20, 0, 0},
                                                     {34, 28, 20, 0},
                                                     {57, 0, 20, 0},
                                                     {63, 28, 20, 0},
                                                     {30, 0, 22, 0},
                                                     {36, 30, 22, 0},
                                                     {38, 30, 22, 36},
                                                     {59, 0, 22, 0},
                                                     {67, 30, 22, 36}}};

}  // namespace las_detail

// The records of a LAS file (uncompressed), or nullopt when it cannot be read.
inline std::optional<LasFileRecords> read_las_records(const std::string& path) {
  using namespace las_detail;
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> f((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (f.size() < 227 || std::memcmp(f.data(), "LASF", 4) != 0) return std::nullopt;
  LasFileRecords out;
  out.version_minor = f[25];
  const auto header_size = get<std::uint16_t>(&f[94]);
  const auto point_offset = get<std::uint32_t>(&f[96]);
  const auto vlrs = get<std::uint32_t>(&f[100]);
  out.format = f[104] & 0x3F;
  if (out.format > 10 || (f[104] & 0x80) != 0) return std::nullopt;
  out.record_length = get<std::uint16_t>(&f[105]);
  std::uint64_t count = get<std::uint32_t>(&f[107]);
  if (out.version_minor >= 4 && get<std::uint64_t>(&f[247]) != 0) count = get<std::uint64_t>(&f[247]);
  for (int a = 0; a < 3; ++a) {
    out.scale[static_cast<std::size_t>(a)] = get<double>(&f[131 + 8 * static_cast<std::size_t>(a)]);
    out.offset[static_cast<std::size_t>(a)] = get<double>(&f[155 + 8 * static_cast<std::size_t>(a)]);
  }
  std::size_t at = header_size;
  for (std::uint32_t v = 0; v < vlrs && at + 54 <= point_offset; ++v) {
    const std::string user(reinterpret_cast<const char*>(&f[at + 2]), strnlen(reinterpret_cast<const char*>(&f[at + 2]), 16));
    const auto id = get<std::uint16_t>(&f[at + 18]);
    const auto len = get<std::uint16_t>(&f[at + 20]);
    if (user == "LASF_Spec" && id == 4 && at + 54 + len <= f.size()) {
      out.extra_bytes_vlr.assign(f.begin() + static_cast<std::ptrdiff_t>(at + 54),
                                 f.begin() + static_cast<std::ptrdiff_t>(at + 54 + len));
    }
    at += 54 + len;
  }
  const Format fm = kFormats[static_cast<std::size_t>(out.format)];
  const std::size_t stride = out.record_length;
  if (stride < fm.length || point_offset + count * stride > f.size()) return std::nullopt;
  const bool ext = out.format >= 6;
  for (std::uint64_t i = 0; i < count; ++i) {
    const std::uint8_t* r = f.data() + point_offset + i * stride;
    LasRecord p;
    p.x = get<std::int32_t>(r);
    p.y = get<std::int32_t>(r + 4);
    p.z = get<std::int32_t>(r + 8);
    p.intensity = get<std::uint16_t>(r + 12);
    if (ext) {
      p.return_number = r[14] & 15;
      p.number_of_returns = r[14] >> 4;
      p.synthetic = r[15] & 1;
      p.key_point = (r[15] >> 1) & 1;
      p.withheld = (r[15] >> 2) & 1;
      p.overlap = (r[15] >> 3) & 1;
      p.channel = (r[15] >> 4) & 3;
      p.scan_direction = (r[15] >> 6) & 1;
      p.edge = r[15] >> 7;
      p.classification = r[16];
      p.user_data = r[17];
      p.scan_angle = get<std::int16_t>(r + 18);
      p.point_source_id = get<std::uint16_t>(r + 20);
    } else {
      p.return_number = r[14] & 7;
      p.number_of_returns = (r[14] >> 3) & 7;
      p.scan_direction = (r[14] >> 6) & 1;
      p.edge = r[14] >> 7;
      p.classification = r[15] & 31;
      p.synthetic = (r[15] >> 5) & 1;
      p.key_point = (r[15] >> 6) & 1;
      p.withheld = r[15] >> 7;
      p.scan_angle = static_cast<std::int8_t>(r[16]);
      p.user_data = r[17];
      p.point_source_id = get<std::uint16_t>(r + 18);
    }
    if (fm.gps) p.gps_time = get<double>(r + fm.gps);
    if (fm.rgb) {
      p.red = get<std::uint16_t>(r + fm.rgb);
      p.green = get<std::uint16_t>(r + fm.rgb + 2);
      p.blue = get<std::uint16_t>(r + fm.rgb + 4);
    }
    if (fm.nir) p.nir = get<std::uint16_t>(r + fm.nir);
    p.extra.assign(r + fm.length, r + stride);
    out.records.push_back(std::move(p));
  }
  return out;
}

// A 192-byte Extra Bytes descriptor.
inline std::vector<std::uint8_t> extra_bytes_descriptor(std::uint8_t data_type, std::uint8_t options,
                                                        const std::string& name, double scale = 1) {
  std::vector<std::uint8_t> d(192, 0);
  d[2] = data_type;
  d[3] = options;
  std::memcpy(d.data() + 4, name.data(), std::min<std::size_t>(name.size(), 32));
  las_detail::put(d, 112, scale);
  return d;
}

// A VLR (or, in a LAS 1.4 file, an extended VLR after the points) to write.
struct TestVlr {
  std::string user_id;      // up to 16 bytes
  std::uint16_t record_id = 0;
  std::string description;  // up to 32 bytes
  std::vector<std::uint8_t> data;
  bool extended = false;
};

struct TestLasOptions {
  int format = 3;
  std::size_t points = 3000;
  std::uint32_t seed = 1;
  std::size_t extra = 0;                       // extra bytes per record
  std::vector<std::uint8_t> extra_bytes_vlr;   // written when non-empty
  bool wide_colors = true;                     // 16-bit colour levels (else 0..255)
  bool zero_colors = false;                    // every colour level 0 (a scanner without a camera)
  double extent = 100;                         // metres in x and y
  double scale = 0.01;
  std::uint16_t global_encoding = 0;           // header bytes 6-7 (bit 0: standard GPS time)
  std::uint16_t file_source_id = 0;
  std::string system_identifier;               // up to 32 bytes
  std::uint16_t creation_day = 0, creation_year = 0;
  std::vector<TestVlr> vlrs;                   // after the Extra Bytes VLR
};

// Writes a LAS file (1.2 for formats 0-5, 1.4 for 6-10) with every field random.
inline bool write_test_las(const std::string& path, const TestLasOptions& o) {
  using namespace las_detail;
  const Format fm = kFormats[static_cast<std::size_t>(o.format)];
  const bool ext = o.format >= 6;
  const std::size_t header = ext ? 375 : 227;
  const std::size_t eb_vlr = o.extra_bytes_vlr.empty() ? 0 : 54 + o.extra_bytes_vlr.size();
  std::size_t vlr = eb_vlr, vlr_count = eb_vlr ? 1 : 0, evlr = 0, evlr_count = 0;
  for (const TestVlr& v : o.vlrs) {
    if (v.extended && ext) {
      evlr += 60 + v.data.size();
      ++evlr_count;
    } else {
      vlr += 54 + v.data.size();
      ++vlr_count;
    }
  }
  const std::size_t stride = fm.length + o.extra;
  std::vector<std::uint8_t> b(header + vlr + o.points * stride + evlr, 0);
  std::memcpy(b.data(), "LASF", 4);
  put<std::uint16_t>(b, 4, o.file_source_id);
  put<std::uint16_t>(b, 6, o.global_encoding);
  std::memcpy(b.data() + 26, o.system_identifier.data(), std::min<std::size_t>(o.system_identifier.size(), 32));
  put<std::uint16_t>(b, 90, o.creation_day);
  put<std::uint16_t>(b, 92, o.creation_year);
  b[24] = 1;
  b[25] = ext ? 4 : 2;
  put<std::uint16_t>(b, 94, static_cast<std::uint16_t>(header));
  put<std::uint32_t>(b, 96, static_cast<std::uint32_t>(header + vlr));
  put<std::uint32_t>(b, 100, static_cast<std::uint32_t>(vlr_count));
  b[104] = static_cast<std::uint8_t>(o.format);
  put<std::uint16_t>(b, 105, static_cast<std::uint16_t>(stride));
  if (!ext) put<std::uint32_t>(b, 107, static_cast<std::uint32_t>(o.points));
  const double offset[3] = {500000, 4000000, 0};
  for (int a = 0; a < 3; ++a) {
    put<double>(b, 131 + 8 * static_cast<std::size_t>(a), o.scale);
    put<double>(b, 155 + 8 * static_cast<std::size_t>(a), offset[a]);
  }
  const std::int32_t span_xy = static_cast<std::int32_t>(o.extent / o.scale);
  const std::int32_t span_z = static_cast<std::int32_t>(10 / o.scale);
  put<double>(b, 179, offset[0] + span_xy * o.scale);
  put<double>(b, 187, offset[0]);
  put<double>(b, 195, offset[1] + span_xy * o.scale);
  put<double>(b, 203, offset[1]);
  put<double>(b, 211, span_z * o.scale);
  put<double>(b, 219, 0.0);
  if (ext) put<std::uint64_t>(b, 247, o.points);
  {
    std::size_t at = header + eb_vlr;
    std::size_t evlr_at = header + vlr + o.points * stride;
    if (evlr_count > 0) {
      put<std::uint64_t>(b, 235, evlr_at);
      put<std::uint32_t>(b, 243, static_cast<std::uint32_t>(evlr_count));
    }
    for (const TestVlr& v : o.vlrs) {
      const bool e = v.extended && ext;
      std::size_t& p = e ? evlr_at : at;
      std::memcpy(b.data() + p + 2, v.user_id.data(), std::min<std::size_t>(v.user_id.size(), 16));
      put<std::uint16_t>(b, p + 18, v.record_id);
      if (e) {
        put<std::uint64_t>(b, p + 20, v.data.size());
      } else {
        put<std::uint16_t>(b, p + 20, static_cast<std::uint16_t>(v.data.size()));
      }
      const std::size_t head = e ? 60 : 54;
      std::memcpy(b.data() + p + head - 32, v.description.data(), std::min<std::size_t>(v.description.size(), 32));
      if (!v.data.empty()) std::memcpy(b.data() + p + head, v.data.data(), v.data.size());
      p += head + v.data.size();
    }
  }
  if (eb_vlr) {
    std::memcpy(b.data() + header + 2, "LASF_Spec", 9);
    put<std::uint16_t>(b, header + 18, 4);
    put<std::uint16_t>(b, header + 20, static_cast<std::uint16_t>(o.extra_bytes_vlr.size()));
    std::memcpy(b.data() + header + 54, o.extra_bytes_vlr.data(), o.extra_bytes_vlr.size());
  }
  std::mt19937 rng(o.seed);
  const auto u = [&](std::uint32_t lo, std::uint32_t hi) {
    return std::uniform_int_distribution<std::uint32_t>(lo, hi)(rng);
  };
  for (std::size_t i = 0; i < o.points; ++i) {
    const std::size_t r = header + vlr + i * stride;
    put<std::int32_t>(b, r, static_cast<std::int32_t>(u(0, static_cast<std::uint32_t>(span_xy))));
    put<std::int32_t>(b, r + 4, static_cast<std::int32_t>(u(0, static_cast<std::uint32_t>(span_xy))));
    put<std::int32_t>(b, r + 8, static_cast<std::int32_t>(u(0, static_cast<std::uint32_t>(span_z))));
    put<std::uint16_t>(b, r + 12, static_cast<std::uint16_t>(u(0, 65535)));
    b[r + 14] = static_cast<std::uint8_t>(u(0, 255));
    b[r + 15] = static_cast<std::uint8_t>(u(0, 255));
    if (ext) {
      b[r + 16] = static_cast<std::uint8_t>(u(0, 255));
      b[r + 17] = static_cast<std::uint8_t>(u(0, 255));
      put<std::int16_t>(b, r + 18, static_cast<std::int16_t>(static_cast<int>(u(0, 30000)) - 15000));
      put<std::uint16_t>(b, r + 20, static_cast<std::uint16_t>(u(0, 65535)));
    } else {
      b[r + 16] = static_cast<std::uint8_t>(static_cast<std::int8_t>(static_cast<int>(u(0, 180)) - 90));
      b[r + 17] = static_cast<std::uint8_t>(u(0, 255));
      put<std::uint16_t>(b, r + 18, static_cast<std::uint16_t>(u(0, 65535)));
    }
    if (fm.gps) put<double>(b, r + fm.gps, 1e8 + u(0, 1u << 30) * 1e-6);
    if (fm.rgb) {
      for (int c = 0; c < 3; ++c) {
        put<std::uint16_t>(b, r + fm.rgb + 2 * static_cast<std::size_t>(c),
                           static_cast<std::uint16_t>(o.zero_colors ? 0 : u(0, o.wide_colors ? 65535 : 255)));
      }
    }
    if (fm.nir) put<std::uint16_t>(b, r + fm.nir, static_cast<std::uint16_t>(u(0, 65535)));
    for (std::size_t e = 0; e < o.extra; ++e) b[r + fm.length + e] = static_cast<std::uint8_t>(u(0, 255));
  }
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(b.data()), static_cast<std::streamsize>(b.size()));
  return static_cast<bool>(out);
}

}  // namespace relief::test
