// LAS 1.0 - 1.4 reader, point data record formats 0-10, and LAZ (LASzip-
// compressed LAS, COPC included; formats 0-3 and 6-8) through lib/laz: a LAZ
// file's chunks are decompressed one at a time into records that the same
// decoding below reads.
//
// Every field of the record is decoded: X Y Z (scaled integers, x = X * scale
// + offset computed in double), intensity, RGB, and into PointCloud::las the
// classification and its flags, return number and number of returns, scan
// flags (direction, edge, scanner channel), scan angle, user data, point
// source ID, GPS time, NIR, and the record's extra bytes beyond its format's
// minimum, raw (described by the Extra Bytes VLR, kept in
// PointStreamInfo::extra_bytes_vlr and checked against the record length).
// Wave packet descriptors (formats 4, 5, 9, 10) are skipped, with a warning. The header is
// validated against the file size before anything is allocated from it; VLRs
// before the points and extended VLRs after them (LAS 1.4, read through a
// second handle that seeks there) are scanned for the coordinate reference
// system and the Extra Bytes VLR; the header block and every other record
// (but those regenerated_record names) are kept in
// PointStreamInfo::las_metadata, which LAS output gives back.
//
// LAS colours are 16-bit. They become 8-bit by the rule in io/stream_support.h:
// from a sample of the first 2^20 points (the whole file when smaller), shift
// every level right by 8 if any sampled level is above 255, else keep the
// levels (files that store 8-bit levels in the 16-bit fields). The low byte
// goes to las.color_low (io/stream_support.h low_level): with the shift the
// 16-bit level comes back exactly as (colour << 8) | low; without it (8-bit
// levels) as level * 257.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "io/byte_source.h"
#include "io/readers.h"
#include "io/stream_support.h"
#include "io/text_scan.h"
#include "relief/crs.h"
#include "relief/io.h"
#include "relief/laz.h"

namespace relief {

namespace {

constexpr std::size_t kVlrHeaderSize = 54;
constexpr std::size_t kEvlrHeaderSize = 60;
// Projection records we keep in memory; real WKT strings are a few KiB.
constexpr std::uint64_t kMaxProjectionRecord = std::uint64_t{16} << 20;
constexpr std::uint16_t kWktRecordId = 2112;
constexpr std::uint16_t kGeoKeyRecordId = 34735;
constexpr std::uint16_t kGeoDoubleRecordId = 34736;
constexpr std::uint16_t kGeoAsciiRecordId = 34737;
constexpr std::string_view kProjectionUserId = "LASF_Projection";
constexpr std::string_view kSpecUserId = "LASF_Spec";
constexpr std::uint16_t kExtraBytesRecordId = 4;
// Global encoding bit 0: the GPS times are adjusted standard GPS time, not
// seconds of the GPS week.
constexpr std::uint16_t kStandardGpsTimeBit = 1u << 0;
// Extra Bytes descriptors are 192 bytes each; more than this many bytes of
// them (a record holds at most 65535 extra bytes) is refused.
constexpr std::uint64_t kMaxExtraBytesRecord = std::uint64_t{192} * 65535;
// LAZ: the chunk table is 8 bytes plus a few per chunk, a chunk a few MiB;
// larger ones are refused rather than held in memory.
constexpr std::uint64_t kMaxChunkTable = std::uint64_t{64} << 20;
constexpr std::uint64_t kMaxLazChunk = std::uint64_t{256} << 20;
// LAZ chunks decoded at once, one per thread (more cores than this do not
// pay: the ingest's other stages need them).
constexpr unsigned kMaxLazThreads = 4;
constexpr std::size_t kChunkTableOffsetSize = 8;
// A writer that could not seek back leaves -1 here and the offset in the
// file's last 8 bytes.
constexpr std::uint64_t kChunkTableAtEnd = ~std::uint64_t{0};

// Public header size by minor version: 1.0-1.2, 1.3, 1.4.
constexpr std::size_t header_size_for(int minor) { return minor <= 2 ? 227 : minor == 3 ? 235 : 375; }
constexpr std::size_t kLargestHeader = 375;
constexpr std::size_t kSmallestHeader = 227;
// LASzip sets bit 7 (and some writers bit 6) of the point format byte; the
// low six bits keep the uncompressed format.
constexpr std::uint8_t kLazFormatBits = 0xC0;
constexpr std::uint8_t kLasFormatMask = 0x3F;

struct PointFormat {
  std::size_t min_length;  // bytes of the record without extra bytes
  std::size_t rgb_offset;  // 0 when the format has no colour
  std::size_t gps_offset;  // 0 when the format has no GPS time
  std::size_t nir_offset;  // 0 when the format has no NIR
};

// Formats 0-5 share the legacy 20-byte core; 6-10 the 30-byte 1.4 core.
constexpr std::array<PointFormat, 11> kPointFormats = {{
    {20, 0, 0, 0},    // 0
    {28, 0, 20, 0},   // 1: + GPS time
    {26, 20, 0, 0},   // 2: + RGB
    {34, 28, 20, 0},  // 3: + GPS time + RGB
    {57, 0, 20, 0},   // 4: 1 + wave packet
    {63, 28, 20, 0},  // 5: 3 + wave packet
    {30, 0, 22, 0},   // 6
    {36, 30, 22, 0},  // 7: + RGB
    {38, 30, 22, 36}, // 8: + RGB + NIR
    {59, 0, 22, 0},   // 9: 6 + wave packet
    {67, 30, 22, 36}, // 10: 8 + wave packet
}};
constexpr int kFirstExtendedFormat = 6;
// Scan angle units in LasAttributes::scan_angle (thousandths of a degree):
// formats 0-5 store whole degrees, 6-10 steps of 0.006 degrees.
constexpr std::int32_t kLegacyScanAngleUnit = 1000;
constexpr std::int32_t kExtendedScanAngleUnit = 6;

// The LasAttributeBits a point format carries (colour low bytes and extra
// bytes are decided by the reader).
std::uint32_t format_attributes(int format) {
  const PointFormat& pf = kPointFormats[static_cast<std::size_t>(format)];
  std::uint32_t bits = kLasClassification | kLasClassFlags | kLasReturnNumber | kLasNumberOfReturns | kLasScanFlags |
                       kLasScanAngle | kLasUserData | kLasPointSourceId;
  if (pf.gps_offset != 0) bits |= kLasGpsTime;
  if (pf.nir_offset != 0) bits |= kLasNir;
  if (pf.rgb_offset != 0) bits |= kLasColorLow;
  return bits;
}

struct LasHeader {
  int version_minor = 0;
  std::uint16_t global_encoding = 0;
  std::uint16_t header_size = 0;
  std::uint32_t point_offset = 0;
  std::uint32_t vlr_count = 0;
  int format = 0;
  std::uint16_t record_length = 0;
  std::uint64_t point_count = 0;
  Vec3d scale;
  Vec3d offset;
  std::optional<Box3d> bounds;
  std::uint64_t evlr_start = 0;
  std::uint32_t evlr_count = 0;
  bool compressed = false;  // LAZ
};

Vec3d load_vec3(const std::uint8_t* p) {
  return {load_le<double>(p), load_le<double>(p + 8), load_le<double>(p + 16)};
}

bool all_finite(const Vec3d& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

std::string version_text(int major, int minor) { return std::to_string(major) + "." + std::to_string(minor); }

// Parses and checks the public header block held in `h` (h.size() bytes).
Result<LasHeader> parse_header(std::span<const std::uint8_t> h, const std::string& name) {
  if (h.empty()) return format_error(name + ": not a LAS file: it is empty");
  if (h.size() < 4 || std::memcmp(h.data(), "LASF", 4) != 0) {
    return format_error(name + ": not a LAS file: it does not start with 'LASF'");
  }
  if (h.size() < kSmallestHeader) {
    return format_error(name + ": truncated: the LAS header needs " + std::to_string(kSmallestHeader) +
                        " bytes but the file has " + std::to_string(h.size()));
  }
  const int major = h[24];
  const int minor = h[25];
  if (major != 1 || minor > 4) {
    return unsupported(name + ": LAS version " + version_text(major, minor) +
                       " is not supported (1.0 to 1.4 are)");
  }
  LasHeader out;
  out.version_minor = minor;
  out.global_encoding = load_le<std::uint16_t>(h.data() + 6);
  out.header_size = load_le<std::uint16_t>(h.data() + 94);
  const std::size_t need = header_size_for(minor);
  if (out.header_size < need) {
    return format_error(name + ": header size " + std::to_string(out.header_size) + " is smaller than the " +
                        std::to_string(need) + " bytes of a LAS " + version_text(major, minor) + " header");
  }
  if (h.size() < need) {
    return format_error(name + ": truncated: the LAS " + version_text(major, minor) + " header needs " +
                        std::to_string(need) + " bytes but the file has " + std::to_string(h.size()));
  }
  // The top two bits of the format byte mark LASzip-compressed points, but
  // only with a real point format below them; any other value (99 = 0x63) is
  // an unknown format, not LAZ.
  const std::uint8_t format_byte = h[104];
  const int base_format = format_byte & kLasFormatMask;
  out.compressed = (format_byte & kLazFormatBits) != 0 && base_format < static_cast<int>(kPointFormats.size());
  out.format = out.compressed ? base_format : format_byte;
  if (out.format >= static_cast<int>(kPointFormats.size())) {
    return unsupported(name + ": LAS point data format " + std::to_string(out.format) +
                       " is not supported (0 to 10 are)");
  }
  out.record_length = load_le<std::uint16_t>(h.data() + 105);
  const std::size_t min_length = kPointFormats[static_cast<std::size_t>(out.format)].min_length;
  if (out.record_length < min_length) {
    return format_error(name + ": point record length " + std::to_string(out.record_length) +
                        " is shorter than the " + std::to_string(min_length) +
                        " bytes of point data format " + std::to_string(out.format));
  }
  out.point_offset = load_le<std::uint32_t>(h.data() + 96);
  if (out.point_offset < out.header_size) {
    return format_error(name + ": offset to point data " + std::to_string(out.point_offset) +
                        " lies inside the " + std::to_string(out.header_size) + "-byte header");
  }
  out.vlr_count = load_le<std::uint32_t>(h.data() + 100);
  out.point_count = load_le<std::uint32_t>(h.data() + 107);
  if (minor >= 4) {
    out.evlr_start = load_le<std::uint64_t>(h.data() + 235);
    out.evlr_count = load_le<std::uint32_t>(h.data() + 243);
    // 1.4 writers set the legacy count to 0 for formats 6-10 and for more
    // than 2^32 points; the 64-bit count is the authoritative one.
    const auto count64 = load_le<std::uint64_t>(h.data() + 247);
    if (count64 != 0) out.point_count = count64;
  }
  out.scale = load_vec3(h.data() + 131);
  out.offset = load_vec3(h.data() + 155);
  // Checked once here so that no decoded coordinate can be NaN or infinite:
  // |X| <= 2^31, so |X * scale + offset| <= 2^31 |scale| + |offset|.
  for (const auto& [s, o] : {std::pair{out.scale.x, out.offset.x}, std::pair{out.scale.y, out.offset.y},
                             std::pair{out.scale.z, out.offset.z}}) {
    const double reach = std::abs(s) * 2147483648.0 + std::abs(o);
    if (!std::isfinite(s) || !std::isfinite(o) || s == 0 || !std::isfinite(reach)) {
      return format_error(name + ": invalid scale " + format_double(s) + " or offset " + format_double(o) +
                          " (they must be finite and the scale non-zero)");
    }
  }
  // Stored as max x, min x, max y, min y, max z, min z.
  Box3d b;
  b.max.x = load_le<double>(h.data() + 179);
  b.min.x = load_le<double>(h.data() + 187);
  b.max.y = load_le<double>(h.data() + 195);
  b.min.y = load_le<double>(h.data() + 203);
  b.max.z = load_le<double>(h.data() + 211);
  b.min.z = load_le<double>(h.data() + 219);
  if (all_finite(b.min) && all_finite(b.max)) out.bounds = b;
  return out;
}

// ---------------------------------------------------------------- CRS

struct ProjectionRecords {
  std::optional<std::vector<std::uint8_t>> extra_bytes;  // the Extra Bytes VLR payload
  std::optional<std::string> wkt;
  GeoTiffRecords geotiff;  // keys empty when the file has none
  std::optional<std::vector<std::uint8_t>> laszip;  // the LASzip VLR payload
};

std::string_view user_id_text(std::span<const std::uint8_t> user_id) {
  // The user id is a 16-byte field padded with NULs.
  const auto* chars = reinterpret_cast<const char*>(user_id.data());
  return std::string_view(chars, ::strnlen(chars, user_id.size()));
}

bool is_projection_record(std::span<const std::uint8_t> user_id, std::uint16_t record_id) {
  return user_id_text(user_id) == kProjectionUserId &&
         (record_id == kWktRecordId || record_id == kGeoKeyRecordId || record_id == kGeoDoubleRecordId ||
          record_id == kGeoAsciiRecordId);
}

bool is_extra_bytes_record(std::span<const std::uint8_t> user_id, std::uint16_t record_id) {
  return user_id_text(user_id) == kSpecUserId && record_id == kExtraBytesRecordId;
}

bool is_laszip_record(std::span<const std::uint8_t> user_id, std::uint16_t record_id) {
  return user_id_text(user_id) == laz::kVlrUserId && record_id == laz::kVlrRecordId;
}

// Records LAS output writes itself from what an archive keeps elsewhere (the
// CRS, the Extra Bytes VLR, LASzip's and COPC's records, a LAStools spatial
// index of the file's point order), and those describing wave packets, which
// are not kept: the rest are kept (LasSourceMetadata).
constexpr std::string_view kCopcUserId = "copc";
constexpr std::string_view kLibLasUserId = "liblas";  // its copy of the CRS as WKT
constexpr std::string_view kLasToolsUserId = "LAStools";
constexpr std::uint16_t kLaxRecordId = 30;
constexpr std::uint16_t kFirstWaveDescriptorId = 100;
constexpr std::uint16_t kLastWaveDescriptorId = 354;
constexpr std::uint16_t kWaveDataRecordId = 65535;

bool regenerated_record(std::span<const std::uint8_t> user_id, std::uint16_t record_id) {
  const std::string_view user = user_id_text(user_id);
  if (user == kProjectionUserId || user == laz::kVlrUserId || user == kCopcUserId) return true;
  if (user == kLibLasUserId) return record_id == kWktRecordId;
  if (user == kSpecUserId) {
    return record_id == kExtraBytesRecordId || record_id == kWaveDataRecordId ||
           (record_id >= kFirstWaveDescriptorId && record_id <= kLastWaveDescriptorId);
  }
  return user == kLasToolsUserId && record_id == kLaxRecordId;
}

// A record's user id, record id and description, from its VLR or extended
// VLR header (the same layout up to the length).
LasVlr record_head(std::span<const std::uint8_t> head, bool extended) {
  LasVlr r;
  r.extended = extended;
  std::memcpy(r.user_id.data(), head.data() + 2, r.user_id.size());
  r.record_id = load_le<std::uint16_t>(head.data() + 18);
  const std::size_t description_at = extended ? 28 : 22;
  std::memcpy(r.description.data(), head.data() + description_at, r.description.size());
  return r;
}

void keep_projection_record(std::uint16_t record_id, std::span<const std::uint8_t> payload,
                            ProjectionRecords& out) {
  if (record_id == kWktRecordId) {
    if (out.wkt) return;  // the first one wins
    // Written NUL-terminated, sometimes with padding after the terminator.
    const auto* chars = reinterpret_cast<const char*>(payload.data());
    std::string wkt(chars, ::strnlen(chars, payload.size()));
    while (!wkt.empty() &&
           (wkt.back() == ' ' || wkt.back() == '\n' || wkt.back() == '\r' || wkt.back() == '\t')) {
      wkt.pop_back();
    }
    if (!wkt.empty()) out.wkt = std::move(wkt);
    return;
  }
  std::vector<std::uint8_t>& slot = record_id == kGeoKeyRecordId      ? out.geotiff.keys
                                    : record_id == kGeoDoubleRecordId ? out.geotiff.doubles
                                                                      : out.geotiff.ascii;
  if (slot.empty()) slot.assign(payload.begin(), payload.end());  // the first one wins
}

// The CRS of the file (lib/crs): LAS 1.4 names it by WKT, earlier versions
// by GeoTIFF keys (a WKT VLR there is a courtesy copy some writers add, used
// only without keys). A malformed key directory is an error naming the file;
// a WKT PROJ cannot read, or keys that name no CRS, are kept as given or
// dropped with a warning.
Status take_crs(const ProjectionRecords& records, int version_minor, const std::string& name,
                PointStreamInfo& info) {
  const bool use_wkt = records.wkt && (version_minor >= 4 || records.geotiff.keys.empty());
  if (use_wkt) {
    info.crs_source = *records.wkt;
    Result<std::string> wkt2 = wkt_to_wkt2(*records.wkt, name + ": WKT VLR");
    if (wkt2.is_ok()) {
      info.crs = *wkt2;
    } else {
      info.crs = *records.wkt;
      info.warnings.push_back(wkt2.status().message() + "; the WKT is kept as given");
    }
  } else if (!records.geotiff.keys.empty()) {
    RELIEF_ASSIGN_OR_RETURN(CrsDefinition crs, crs_from_geotiff(records.geotiff, name));
    if (crs.wkt.empty()) {
      info.warnings.push_back(name + ": the GeoTIFF keys name no coordinate reference system; none is recorded");
    } else {
      info.crs = std::move(crs.wkt);
      info.crs_source = std::move(crs.source);
    }
  }
  return Status::ok();
}

// ---------------------------------------------------------------- points

enum class ColorOut { kNone, kNarrow, kWide };

struct LasLayout {
  std::size_t record_length = 0;
  std::size_t rgb_offset = 0;
  std::size_t gps_offset = 0;
  std::size_t nir_offset = 0;
  std::size_t extra_offset = 0;  // first extra byte (the format's minimum length)
  std::size_t extra_size = 0;    // extra bytes per record
  Vec3d scale;
  Vec3d offset;
  int color_shift = 0;
};

// Where one batch's values go; `at` is already applied.
struct LasTargets {
  Vec3d* pos = nullptr;
  float* intensity = nullptr;
  Rgb8* col = nullptr;
  Rgb8* low = nullptr;  // with col: the colour low bytes
  std::uint16_t* wide = nullptr;
  LasAttributes* las = nullptr;
  std::size_t at = 0;
  // With col and color_shift 0: set to the first of the n points with a
  // level above 255 (left alone when there is none).
  std::size_t* above_255 = nullptr;
};

// Decodes the fields every format has, and the colour. One loop per format
// family (legacy 0-5, extended 6-10) and colour mode: no per-point branch.
template <ColorOut kColor, bool kExtended>
void decode_las(const std::uint8_t* src, std::size_t n, const LasLayout& lay, const LasTargets& t) {
  const std::size_t stride = lay.record_length;
  const Vec3d s = lay.scale;
  const Vec3d o = lay.offset;
  LasAttributes& a = *t.las;
  std::uint8_t* const cls = a.classification.data() + t.at;
  std::uint8_t* const flags = a.class_flags.data() + t.at;
  std::uint8_t* const ret = a.return_number.data() + t.at;
  std::uint8_t* const nret = a.number_of_returns.data() + t.at;
  std::uint8_t* const scan = a.scan_flags.data() + t.at;
  std::int32_t* const angle = a.scan_angle.data() + t.at;
  std::uint8_t* const user = a.user_data.data() + t.at;
  std::uint16_t* const source = a.point_source_id.data() + t.at;
  for (std::size_t i = 0; i < n; ++i, src += stride) {
    const auto x = load_le<std::int32_t>(src);
    const auto y = load_le<std::int32_t>(src + 4);
    const auto z = load_le<std::int32_t>(src + 8);
    t.pos[i] = Vec3d{static_cast<double>(x) * s.x + o.x, static_cast<double>(y) * s.y + o.y,
                     static_cast<double>(z) * s.z + o.z};
    t.intensity[i] = static_cast<float>(load_le<std::uint16_t>(src + 12));
    const std::uint8_t b14 = src[14];
    const std::uint8_t b15 = src[15];
    if constexpr (kExtended) {
      // 14: return number (0-3), number of returns (4-7); 15: classification
      // flags (0-3), scanner channel (4-5), scan direction (6), edge (7);
      // 16 classification, 17 user data, 18 scan angle i16, 20 source ID.
      ret[i] = b14 & 0x0F;
      nret[i] = b14 >> 4;
      flags[i] = b15 & 0x0F;
      scan[i] = static_cast<std::uint8_t>(((b15 >> 6) & 0x03) | (((b15 >> 4) & 0x03) << 2));
      cls[i] = src[16];
      user[i] = src[17];
      angle[i] = static_cast<std::int32_t>(load_le<std::int16_t>(src + 18)) * kExtendedScanAngleUnit;
      source[i] = load_le<std::uint16_t>(src + 20);
    } else {
      // 14: return number (0-2), number of returns (3-5), scan direction (6),
      // edge (7); 15: classification (0-4), synthetic, key-point, withheld;
      // 16 scan angle rank i8, 17 user data, 18 source ID.
      ret[i] = b14 & 0x07;
      nret[i] = (b14 >> 3) & 0x07;
      scan[i] = b14 >> 6;
      cls[i] = b15 & 0x1F;
      flags[i] = b15 >> 5;
      angle[i] = static_cast<std::int32_t>(static_cast<std::int8_t>(src[16])) * kLegacyScanAngleUnit;
      user[i] = src[17];
      source[i] = load_le<std::uint16_t>(src + 18);
    }
    if constexpr (kColor != ColorOut::kNone) {
      const std::uint8_t* c = src + lay.rgb_offset;
      const auto r = load_le<std::uint16_t>(c);
      const auto g = load_le<std::uint16_t>(c + 2);
      const auto b = load_le<std::uint16_t>(c + 4);
      if constexpr (kColor == ColorOut::kWide) {
        t.wide[3 * i] = r;
        t.wide[3 * i + 1] = g;
        t.wide[3 * i + 2] = b;
      } else {
        if (t.low != nullptr) {
          t.col[i] = split_levels(r, g, b, lay.color_shift, t.low[i]);
        } else {
          t.col[i] = Rgb8{narrow_level(r, lay.color_shift), narrow_level(g, lay.color_shift),
                          narrow_level(b, lay.color_shift)};
        }
        if (lay.color_shift == 0 && (r | g | b) > 255 && *t.above_255 > i) *t.above_255 = i;
      }
    }
  }
}

// The fields only some formats have, each in its own pass over the records.
void decode_las_optional(const std::uint8_t* src, std::size_t n, const LasLayout& lay, const LasTargets& t) {
  const std::size_t stride = lay.record_length;
  LasAttributes& a = *t.las;
  if (lay.gps_offset != 0) {
    double* gps = a.gps_time.data() + t.at;
    const std::uint8_t* p = src + lay.gps_offset;
    for (std::size_t i = 0; i < n; ++i, p += stride) gps[i] = load_le<double>(p);
  }
  if (lay.nir_offset != 0) {
    std::uint16_t* nir = a.nir.data() + t.at;
    const std::uint8_t* p = src + lay.nir_offset;
    for (std::size_t i = 0; i < n; ++i, p += stride) nir[i] = load_le<std::uint16_t>(p);
  }
  if (lay.extra_size != 0) {
    const std::size_t w = lay.extra_size;
    std::uint8_t* extra = a.extra_bytes.data() + t.at * w;
    const std::uint8_t* p = src + lay.extra_offset;
    for (std::size_t i = 0; i < n; ++i, p += stride, extra += w) std::memcpy(extra, p, w);
  }
}

using DecodeFn = void (*)(const std::uint8_t*, std::size_t, const LasLayout&, const LasTargets&);

template <bool kExtended>
DecodeFn pick_decoder(ColorOut color) {
  switch (color) {
    case ColorOut::kWide:
      return &decode_las<ColorOut::kWide, kExtended>;
    case ColorOut::kNarrow:
      return &decode_las<ColorOut::kNarrow, kExtended>;
    case ColorOut::kNone:
      break;
  }
  return &decode_las<ColorOut::kNone, kExtended>;
}

class LasPointReader final : public BatchPointReader {
 public:
  static Result<std::unique_ptr<LasPointReader>> open(const InputSpec& input, bool positions_only,
                                                      unsigned decode_threads) {
    RELIEF_ASSIGN_OR_RETURN(ByteSource src, input.open());
    std::unique_ptr<LasPointReader> reader(new LasPointReader(input, std::move(src)));
    reader->positions_only_ = positions_only;
    reader->decode_threads_ = decode_threads;
    RELIEF_RETURN_IF_ERROR(reader->start());
    return reader;
  }

  Result<std::size_t> read_into(PointCloud& out, std::vector<std::uint16_t>* wide, std::size_t at,
                                std::size_t max_points) override;

 protected:
  Result<std::unique_ptr<BatchPointReader>> reopen() const override {
    if (!input_.memory && !src_.size()) return std::unique_ptr<BatchPointReader>();
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<LasPointReader> again, open(input_, positions_only_, decode_threads_));
    return std::unique_ptr<BatchPointReader>(std::move(again));
  }

 private:
  LasPointReader(InputSpec input, ByteSource src) : input_(std::move(input)), src_(std::move(src)) {}
  bool positions_only_ = false;  // ReaderOptions::positions_only
  unsigned decode_threads_ = 0;  // ReaderOptions::decode_threads

  Status start();
  Status check_size();
  Status read_vlrs(ProjectionRecords& records);
  Status read_evlrs(ProjectionRecords& records);
  Status start_laz(const ProjectionRecords& records);
  // Whether record `r` of `length` bytes is kept (else says why, as a warning).
  bool keep_record(const LasVlr& r, std::uint64_t length, const std::string& which);
  // The first Extra Bytes record describes the extra bytes; a later one that
  // differs from it is ignored, with a warning.
  void keep_extra_bytes_record(std::span<const std::uint8_t> payload, const std::string& which,
                               ProjectionRecords& records);
  Status fetch_chunk(std::uint64_t offset, std::size_t bytes, std::vector<std::uint8_t>& out);
  // The next decoded records: the file's bytes, or for LAZ decompressed ones.
  Status fill_points(std::size_t stride, std::span<const std::uint8_t>& view);
  void consume_points(std::size_t n) {
    if (laz_) {
      laz_pos_ += n;
    } else {
      src_.consume(n);
    }
  }
  // A GPS time that is NaN or infinite has no place in the archive (nor in
  // any time order): refused here, naming the file and the point, rather
  // than by the encoder, which knows neither. `first` is the file index of
  // times[0]. One pass without branches when all are finite.
  Status check_gps_times(const double* times, std::size_t n, std::uint64_t first) const {
    double acc = 0;  // t - t is NaN exactly when t is NaN or infinite
    for (std::size_t i = 0; i < n; ++i) acc += times[i] - times[i];
    if (acc == 0) return Status::ok();
    std::size_t i = 0;
    while (std::isfinite(times[i])) ++i;
    return format_error(name() + ": point " + std::to_string(first + i) +
                        " (counted from 0) has a GPS time of " + format_double(times[i]) +
                        ", not a finite number");
  }
  Status truncated(std::uint64_t holds) const {
    return format_error(name() + ": truncated: header declares " + std::to_string(header_.point_count) +
                        " points but the file holds " + std::to_string(holds));
  }
  const std::string& name() const { return input_.name; }

  InputSpec input_;
  ByteSource src_;
  LasHeader header_;
  LasLayout layout_;
  bool has_rgb_ = false;
  bool extended_ = false;  // point formats 6-10
  // The file size is known and holds every declared point, so batches may be
  // sized before they are read.
  bool backed_ = false;
  std::uint64_t done_ = 0;
  std::uint64_t kept_record_bytes_ = 0;
  // LAZ state: the chunk reader and the decoded records it last handed out.
  bool laz_ = false;
  std::unique_ptr<laz::ChunkReader> laz_reader_;
  std::span<const std::uint8_t> laz_records_;
  std::size_t laz_pos_ = 0;
};

Status LasPointReader::start() {
  std::span<const std::uint8_t> view;
  RELIEF_RETURN_IF_ERROR(src_.fill(kLargestHeader, view));
  RELIEF_ASSIGN_OR_RETURN(header_, parse_header(view.first(std::min(view.size(), kLargestHeader)), name()));
  {
    const std::size_t standard = header_size_for(header_.version_minor);  // parse_header checked view holds it
    info_.las_metadata.header.assign(view.begin(), view.begin() + static_cast<std::ptrdiff_t>(standard));
  }
  RELIEF_RETURN_IF_ERROR(check_size());

  ProjectionRecords records;
  RELIEF_RETURN_IF_ERROR(read_vlrs(records));
  RELIEF_RETURN_IF_ERROR(read_evlrs(records));
  if (header_.compressed) RELIEF_RETURN_IF_ERROR(start_laz(records));

  const PointFormat& pf = kPointFormats[static_cast<std::size_t>(header_.format)];
  has_rgb_ = pf.rgb_offset != 0;
  layout_.record_length = header_.record_length;
  layout_.rgb_offset = pf.rgb_offset;
  layout_.gps_offset = pf.gps_offset;
  layout_.nir_offset = pf.nir_offset;
  layout_.extra_offset = pf.min_length;
  layout_.extra_size = header_.record_length - pf.min_length;
  layout_.scale = header_.scale;
  layout_.offset = header_.offset;
  extended_ = header_.format >= kFirstExtendedFormat;
  if (records.extra_bytes) {
    // Checked now, so every reader of the archive can trust the VLR.
    RELIEF_RETURN_IF_ERROR(parse_extra_bytes_vlr(*records.extra_bytes, layout_.extra_size, name()).status());
    info_.extra_bytes_vlr.assign(records.extra_bytes->begin(), records.extra_bytes->end());
  }
  info_.extra_bytes_size = static_cast<std::uint32_t>(layout_.extra_size);
  info_.las_point_format = header_.format;
  info_.las_version_minor = header_.version_minor;
  for (const auto& [axis, scale] :
       {std::pair{"x", header_.scale.x}, std::pair{"y", header_.scale.y}, std::pair{"z", header_.scale.z}}) {
    if (scale < 0) {
      info_.warnings.push_back(name() + ": the " + axis + " scale factor is negative (" +
                               format_double(scale) +
                               "): the coordinates are kept, but LAS output writes them at scale " +
                               format_double(-scale) + ", so their integers come back negated");
    }
  }
  if (header_.format == 4 || header_.format == 5 || header_.format == 9 || header_.format == 10) {
    info_.warnings.push_back(name() + ": point format " + std::to_string(header_.format) +
                             " carries wave packet descriptors (where each pulse's waveform lies), which are not "
                             "kept: the points and their other attributes are, and LAS output writes them as format " +
                             std::to_string(header_.format == 4 ? 1 : header_.format == 5 ? 3 : header_.format == 9 ? 6 : 8));
  }
  info_.las_attributes = format_attributes(header_.format) | (layout_.extra_size != 0 ? kLasExtraBytes : 0u);
  if ((info_.las_attributes & kLasGpsTime) != 0) {
    info_.las_gps_time_type =
        (header_.global_encoding & kStandardGpsTimeBit) != 0 ? GpsTimeType::kStandard : GpsTimeType::kWeek;
  }
  color_low_ = has_rgb_;

  info_.path = name();
  info_.format = laz_ ? "laz" : "las";
  info_.point_count = header_.point_count;
  info_.has_colors = has_rgb_;
  info_.has_intensity = true;  // every point format has it
  RELIEF_RETURN_IF_ERROR(take_crs(records, header_.version_minor, name(), info_));
  info_.header_bounds = header_.bounds;
  info_.scale = header_.scale;
  info_.offset = header_.offset;
  wide_colors_ = has_rgb_;  // LAS colours are 16-bit
  return Status::ok();
}

// Checks the declared layout against the file size, when it is known, before
// anything trusts it.
Status LasPointReader::check_size() {
  const auto size = src_.size();
  if (!size) return Status::ok();  // a pipe: checked as the data arrives
  if (header_.point_offset > *size) {
    return format_error(name() + ": truncated: the point data should start at byte " +
                        std::to_string(header_.point_offset) + " but the file has " + std::to_string(*size) +
                        " bytes");
  }
  std::uint64_t end = *size;
  if (header_.evlr_count > 0) {
    if (header_.evlr_start < header_.point_offset) {
      return format_error(name() + ": the extended VLRs start at byte " + std::to_string(header_.evlr_start) +
                          ", before the point data at byte " + std::to_string(header_.point_offset));
    }
    if (header_.evlr_start > *size) {
      return format_error(name() + ": truncated: the extended VLRs start at byte " +
                          std::to_string(header_.evlr_start) + " but the file has " + std::to_string(*size) +
                          " bytes");
    }
    end = header_.evlr_start;
  }
  if (header_.compressed) return Status::ok();  // the chunk table is checked in start_laz()
  const std::uint64_t holds =
      end >= header_.point_offset ? (end - header_.point_offset) / header_.record_length : 0;
  if (header_.point_count > holds) return truncated(holds);
  backed_ = true;
  return Status::ok();
}

Status LasPointReader::read_vlrs(ProjectionRecords& records) {
  std::uint64_t skipped = 0;
  RELIEF_RETURN_IF_ERROR(src_.skip(header_.header_size, skipped));
  std::uint64_t pos = header_.header_size;
  const std::uint64_t limit = header_.point_offset;
  const std::string count_text = std::to_string(header_.vlr_count);
  for (std::uint32_t i = 0; i < header_.vlr_count; ++i) {
    const std::string which = name() + ": VLR " + std::to_string(i + 1) + " of " + count_text;
    if (limit - pos < kVlrHeaderSize) {
      return format_error(which + " does not fit before the point data at byte " + std::to_string(limit));
    }
    std::span<const std::uint8_t> view;
    RELIEF_RETURN_IF_ERROR(src_.fill(kVlrHeaderSize, view));
    if (view.size() < kVlrHeaderSize) return format_error(which + " is cut short by the end of the file");
    const auto record_id = load_le<std::uint16_t>(view.data() + 18);
    const auto length = load_le<std::uint16_t>(view.data() + 20);
    const bool laszip = is_laszip_record(view.subspan(2, 16), record_id);
    const bool extra = is_extra_bytes_record(view.subspan(2, 16), record_id);
    const bool wanted = is_projection_record(view.subspan(2, 16), record_id) || laszip || extra;
    LasVlr kept = record_head(view, false);
    const bool keep = !regenerated_record(view.subspan(2, 16), record_id) && keep_record(kept, length, which);
    src_.consume(kVlrHeaderSize);
    pos += kVlrHeaderSize;
    if (limit - pos < length) {
      return format_error(which + " (" + std::to_string(length) +
                          " bytes) runs past the start of the point data at byte " + std::to_string(limit));
    }
    if (keep) {
      RELIEF_RETURN_IF_ERROR(src_.fill(length, view));
      if (view.size() < length) return format_error(which + " is cut short by the end of the file");
      kept.data.assign(view.begin(), view.begin() + length);
      info_.las_metadata.records.push_back(std::move(kept));
      src_.consume(length);
    } else if (wanted) {
      RELIEF_RETURN_IF_ERROR(src_.fill(length, view));
      if (view.size() < length) return format_error(which + " is cut short by the end of the file");
      if (laszip) {
        if (!records.laszip) records.laszip.emplace(view.begin(), view.begin() + length);
      } else if (extra) {
        keep_extra_bytes_record(view.first(static_cast<std::size_t>(length)), which, records);
      } else {
        keep_projection_record(record_id, view.first(length), records);
      }
      src_.consume(length);
    } else {
      RELIEF_RETURN_IF_ERROR(src_.skip(length, skipped));
      if (skipped < length) return format_error(which + " is cut short by the end of the file");
    }
    pos += length;
  }
  // Writers may leave user bytes between the VLRs and the points.
  RELIEF_RETURN_IF_ERROR(src_.skip(limit - pos, skipped));
  if (skipped < limit - pos) return truncated(0);
  return Status::ok();
}

// LAS 1.4 extended VLRs follow the points; a second handle seeks to them so
// the point stream stays sequential. A pipe cannot seek, so there they are
// not read (the CRS may then be missing).
Status LasPointReader::read_evlrs(ProjectionRecords& records) {
  const auto size = src_.size();
  if (header_.evlr_count == 0 || !size) return Status::ok();
  RELIEF_ASSIGN_OR_RETURN(ByteSource evlr_src, input_.open());
  std::uint64_t skipped = 0;
  RELIEF_RETURN_IF_ERROR(evlr_src.skip(header_.evlr_start, skipped));
  std::uint64_t pos = header_.evlr_start;  // <= size, see check_size()
  const std::string count_text = std::to_string(header_.evlr_count);
  for (std::uint32_t i = 0; i < header_.evlr_count; ++i) {
    const std::string which = name() + ": extended VLR " + std::to_string(i + 1) + " of " + count_text;
    std::span<const std::uint8_t> view;
    RELIEF_RETURN_IF_ERROR(evlr_src.fill(kEvlrHeaderSize, view));
    if (*size - pos < kEvlrHeaderSize || view.size() < kEvlrHeaderSize) {
      return format_error(which + " is cut short by the end of the file");
    }
    const auto record_id = load_le<std::uint16_t>(view.data() + 18);
    const auto length = load_le<std::uint64_t>(view.data() + 20);
    const bool extra = is_extra_bytes_record(view.subspan(2, 16), record_id);
    const bool wanted = is_projection_record(view.subspan(2, 16), record_id) || extra;
    LasVlr kept = record_head(view, true);
    const bool keep = !regenerated_record(view.subspan(2, 16), record_id) && keep_record(kept, length, which);
    evlr_src.consume(kEvlrHeaderSize);
    pos += kEvlrHeaderSize;
    if (*size - pos < length) {
      return format_error(which + " (" + std::to_string(length) + " bytes) runs past the end of the file");
    }
    if (keep) {
      const auto len = static_cast<std::size_t>(length);  // <= kMaxKeptLasRecord
      RELIEF_RETURN_IF_ERROR(evlr_src.fill(len, view));
      if (view.size() < len) return format_error(which + " is cut short by the end of the file");
      kept.data.assign(view.begin(), view.begin() + static_cast<std::ptrdiff_t>(len));
      info_.las_metadata.records.push_back(std::move(kept));
      evlr_src.consume(len);
    } else if (wanted) {
      if (length > (extra ? kMaxExtraBytesRecord : kMaxProjectionRecord)) {
        return format_error(which + ": a " + (extra ? "Extra Bytes" : "projection") + " record of " +
                            std::to_string(length) + " bytes is absurdly large");
      }
      const auto len = static_cast<std::size_t>(length);
      RELIEF_RETURN_IF_ERROR(evlr_src.fill(len, view));
      if (view.size() < len) return format_error(which + " is cut short by the end of the file");
      if (extra) {
        keep_extra_bytes_record(view.first(len), which, records);
      } else {
        keep_projection_record(record_id, view.first(len), records);
      }
      evlr_src.consume(len);
    } else {
      RELIEF_RETURN_IF_ERROR(evlr_src.skip(length, skipped));
      if (skipped < length) return format_error(which + " is cut short by the end of the file");
    }
    pos += length;
  }
  return Status::ok();
}

void LasPointReader::keep_extra_bytes_record(std::span<const std::uint8_t> payload, const std::string& which,
                                             ProjectionRecords& records) {
  if (!records.extra_bytes) {
    records.extra_bytes.emplace(payload.begin(), payload.end());
  } else if (!std::equal(payload.begin(), payload.end(), records.extra_bytes->begin(),
                         records.extra_bytes->end())) {
    info_.warnings.push_back(which +
                             " is a second Extra Bytes record that differs from the first: the first "
                             "describes the extra bytes and this one is ignored");
  }
}

bool LasPointReader::keep_record(const LasVlr& r, std::uint64_t length, const std::string& which) {
  const bool too_large = length > kMaxKeptLasRecord;
  if (!too_large && length <= kMaxKeptLasRecords - kept_record_bytes_) {
    kept_record_bytes_ += length;
    return true;
  }
  std::string what = which;
  what += " (user id '";
  what += user_id_text(r.user_id);
  what += "', record ";
  what += std::to_string(r.record_id);
  what += ", ";
  what += std::to_string(length);
  what += " bytes) is not kept: ";
  what += too_large ? "records over " + std::to_string(kMaxKeptLasRecord >> 20) + " MiB are not"
                    : "the file's kept records would exceed " + std::to_string(kMaxKeptLasRecords >> 20) + " MiB";
  info_.warnings.push_back(std::move(what));
  return false;
}

// LAZ: the LASzip VLR describes the items, 8 bytes at the point offset give
// the chunk table's position; the table is read through a second handle
// (like the extended VLRs), so the chunks then stream in order.
Status LasPointReader::start_laz(const ProjectionRecords& records) {
  const auto size = src_.size();
  if (!size) {
    return unsupported(name() + ": LAZ cannot be read from a pipe (its chunk table is at the end); "
                                "give the file itself");
  }
  if (!records.laszip) {
    return format_error(name() + ": the point format byte marks LAZ (LASzip-compressed points) but there is no "
                                 "LASzip VLR");
  }
  RELIEF_ASSIGN_OR_RETURN(laz::Params params,
                          laz::parse_vlr(*records.laszip, header_.format, header_.record_length, name()));
  params.positions_only = positions_only_;
  if (params.unchunked()) {
    // LASzip 1.x without chunks: no table offset and no table; the points
    // are one stream to the extended VLRs (when they follow) or the end.
    std::uint64_t end = *size;
    if (header_.evlr_count > 0 && header_.evlr_start >= header_.point_offset) end = std::min(end, header_.evlr_start);
    RELIEF_ASSIGN_OR_RETURN(laz::Chunk whole, laz::unchunked_stream(params, header_.point_offset, end,
                                                                    header_.point_count, name()));
    RELIEF_ASSIGN_OR_RETURN(laz_reader_, laz::ChunkReader::create(params, {whole}, 1, name()));
    laz_ = true;
    backed_ = true;  // the stream is long enough for every declared point
    return Status::ok();
  }
  std::span<const std::uint8_t> view;
  RELIEF_RETURN_IF_ERROR(src_.fill(kChunkTableOffsetSize, view));
  if (view.size() < kChunkTableOffsetSize) {
    return format_error(name() + ": truncated: the LAZ chunk table offset at byte " +
                        std::to_string(header_.point_offset) + " is cut short");
  }
  std::uint64_t table_offset = load_le<std::uint64_t>(view.data());
  src_.consume(kChunkTableOffsetSize);
  const std::uint64_t first_chunk = header_.point_offset + kChunkTableOffsetSize;

  RELIEF_ASSIGN_OR_RETURN(ByteSource table_src, input_.open());
  std::uint64_t skipped = 0;
  if (table_offset == kChunkTableAtEnd) {
    if (*size < first_chunk + kChunkTableOffsetSize) {
      return format_error(name() + ": truncated: no room for the LAZ chunk table offset at the end");
    }
    RELIEF_RETURN_IF_ERROR(table_src.skip(*size - kChunkTableOffsetSize, skipped));
    RELIEF_RETURN_IF_ERROR(table_src.fill(kChunkTableOffsetSize, view));
    if (view.size() < kChunkTableOffsetSize) return format_error(name() + ": truncated at the end");
    table_offset = load_le<std::uint64_t>(view.data());
    RELIEF_ASSIGN_OR_RETURN(table_src, input_.open());
  }
  // The table runs to the extended VLRs when they follow it, else to the end.
  std::uint64_t end = *size;
  if (header_.evlr_count > 0 && header_.evlr_start > table_offset) end = header_.evlr_start;
  if (table_offset >= *size && table_offset != kChunkTableAtEnd) {
    // The usual sign of a cut download or copy: say so.
    return format_error(name() + ": truncated: the LAZ chunk table is at byte " + std::to_string(table_offset) +
                        " but the file ends at byte " + std::to_string(*size));
  }
  if (table_offset < first_chunk || table_offset >= end) {
    return format_error(name() + ": the LAZ chunk table offset " + std::to_string(table_offset) +
                        " lies outside the point data (bytes " + std::to_string(first_chunk) + " to " +
                        std::to_string(end) + ")");
  }
  const auto table_bytes = static_cast<std::size_t>(std::min(end - table_offset, kMaxChunkTable));
  RELIEF_RETURN_IF_ERROR(table_src.skip(table_offset, skipped));
  RELIEF_RETURN_IF_ERROR(table_src.fill(table_bytes, view));
  if (skipped < table_offset || view.size() < table_bytes) {
    return format_error(name() + ": truncated: the LAZ chunk table is cut short");
  }
  RELIEF_ASSIGN_OR_RETURN(std::vector<laz::Chunk> chunks,
                          laz::parse_chunk_table(view.first(table_bytes), params, first_chunk, table_offset,
                                                 header_.point_count, name()));
  const unsigned threads =
      std::clamp(decode_threads_ != 0 ? decode_threads_ : std::thread::hardware_concurrency(), 1u, kMaxLazThreads);
  RELIEF_ASSIGN_OR_RETURN(laz_reader_, laz::ChunkReader::create(params, std::move(chunks), threads, name()));
  laz_ = true;
  backed_ = true;  // the table accounts for every declared point
  return Status::ok();
}

// Copies one chunk's compressed bytes; chunks come in file order, so this
// only ever skips forward.
Status LasPointReader::fetch_chunk(std::uint64_t offset, std::size_t bytes, std::vector<std::uint8_t>& out) {
  const std::string which = name() + ": LAZ chunk at byte " + std::to_string(offset);
  if (bytes > kMaxLazChunk) {
    return limit_exceeded(which + " has " + std::to_string(bytes) + " bytes, over the " +
                          std::to_string(kMaxLazChunk >> 20) + " MiB limit");
  }
  if (offset < src_.position()) return format_error(which + " overlaps the chunk before it");
  std::uint64_t skipped = 0;
  const std::uint64_t gap = offset - src_.position();
  RELIEF_RETURN_IF_ERROR(src_.skip(gap, skipped));
  if (skipped < gap) return format_error(which + " lies past the end of the file");
  std::span<const std::uint8_t> view;
  RELIEF_RETURN_IF_ERROR(src_.fill(bytes, view));
  if (view.size() < bytes) return format_error(which + " is cut short by the end of the file");
  out.assign(view.begin(), view.begin() + static_cast<std::ptrdiff_t>(bytes));
  src_.consume(bytes);
  return Status::ok();
}

Status LasPointReader::fill_points(std::size_t stride, std::span<const std::uint8_t>& view) {
  if (!laz_) return src_.fill(stride, view);
  if (laz_pos_ >= laz_records_.size()) {
    laz_pos_ = 0;
    RELIEF_RETURN_IF_ERROR(laz_reader_->next(
        [this](std::uint64_t offset, std::size_t bytes, std::vector<std::uint8_t>& out) {
          return fetch_chunk(offset, bytes, out);
        },
        laz_records_));
  }
  view = laz_records_.subspan(laz_pos_);
  return Status::ok();
}

Result<std::size_t> LasPointReader::read_into(PointCloud& out, std::vector<std::uint16_t>* wide,
                                              std::size_t at, std::size_t max_points) {
  const auto want =
      static_cast<std::size_t>(std::min<std::uint64_t>(max_points, header_.point_count - done_));
  const bool to_wide = wide != nullptr && has_rgb_;
  const bool col8 = has_rgb_ && !to_wide;
  // With wide colours the low bytes are filled by read() once the shift is known.
  const bool low = col8 && color_low_;
  const std::uint32_t bits = info_.las_attributes;
  auto size_to = [&](std::size_t n) {
    size_batch(out, n, col8, true);
    if (to_wide) wide->resize(3 * n);
    LasAttributes& a = out.las;
    a.classification.resize(n);
    a.class_flags.resize(n);
    a.return_number.resize(n);
    a.number_of_returns.resize(n);
    a.scan_flags.resize(n);
    a.scan_angle.resize(n);
    a.user_data.resize(n);
    a.point_source_id.resize(n);
    a.gps_time.resize((bits & kLasGpsTime) != 0 ? n : 0);
    a.nir.resize((bits & kLasNir) != 0 ? n : 0);
    a.color_low.resize(low ? n : 0);
    a.extra_bytes_size = static_cast<std::uint32_t>(layout_.extra_size);
    a.extra_bytes.resize(n * layout_.extra_size);
  };
  // Sized once when the file is known to hold the points, so that a batch
  // reused at the same size is not touched twice; otherwise grown as data
  // arrives, so a lying header on a pipe allocates nothing.
  if (backed_) size_to(at + want);
  layout_.color_shift = color_shift_;
  const ColorOut color = to_wide ? ColorOut::kWide : col8 ? ColorOut::kNarrow : ColorOut::kNone;
  const DecodeFn decode = extended_ ? pick_decoder<true>(color) : pick_decoder<false>(color);
  const std::size_t stride = layout_.record_length;
  std::size_t got = 0;
  while (got < want) {
    std::span<const std::uint8_t> view;
    RELIEF_RETURN_IF_ERROR(fill_points(stride, view));
    const std::size_t avail = view.size() / stride;
    if (avail == 0) return truncated(done_ + got);
    const std::size_t n = std::min(want - got, avail);
    const std::size_t i0 = at + got;
    if (!backed_) size_to(i0 + n);
    LasTargets t;
    t.pos = out.positions.data() + i0;
    t.intensity = out.intensities.data() + i0;
    t.col = col8 ? out.colors.data() + i0 : nullptr;
    t.low = low ? out.las.color_low.data() + i0 : nullptr;
    t.wide = to_wide ? wide->data() + 3 * i0 : nullptr;
    t.las = &out.las;
    t.at = i0;
    std::size_t above_255 = n;
    t.above_255 = &above_255;
    decode(view.data(), n, layout_, t);
    if (above_255 < n) {
      const std::uint8_t* c = view.data() + above_255 * stride + layout_.rgb_offset;
      note_level_above_255(done_ + got + above_255, std::max({load_le<std::uint16_t>(c), load_le<std::uint16_t>(c + 2),
                                                             load_le<std::uint16_t>(c + 4)}));
    }
    decode_las_optional(view.data(), n, layout_, t);
    if (layout_.gps_offset != 0) {
      RELIEF_RETURN_IF_ERROR(check_gps_times(out.las.gps_time.data() + i0, n, done_ + got));
    }
    consume_points(n * stride);
    got += n;
  }
  size_to(at + got);
  done_ += got;
  return got;
}

}  // namespace

Result<std::unique_ptr<PointReader>> open_las_reader(const InputSpec& input, bool positions_only,
                                                     unsigned decode_threads) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<LasPointReader> reader,
                          LasPointReader::open(input, positions_only, decode_threads));
  return std::unique_ptr<PointReader>(std::move(reader));
}

}  // namespace relief
