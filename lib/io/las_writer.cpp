// Streaming LAS writer, field by field after the ASPRS LAS 1.2 and 1.4 (R15)
// specifications.
//
// Version and point format: LAS 1.2 with point data record format 2 (RGB) or
// 0, which every LAS tool reads. A WKT coordinate system needs LAS 1.4 (the
// WKT VLR and the global-encoding WKT bit are 1.4 features, and 1.4 wants the
// 1.4 point formats with WKT), so then the file is LAS 1.4 with format 7
// (RGB) or 6. A CRS whose source gave it as GeoTIFF records gets those
// records back verbatim in the 1.2 file; one given as WKT gets that WKT.
// "EPSG:<code>" and "GeoTIFF keys: ..." (archives made before the crs
// module) are written as a GeoTIFF GeoKeyDirectoryTag VLR in the 1.2 file.
//
// Point format: WriterOptions::las_attributes and las_point_format (the
// archive's LAS attributes and source format) choose it. Formats 6-10 (or
// NIR, or a WKT CRS in a .las, or LAS attributes without a source format)
// give LAS 1.4 with format 8 when NIR is carried,
// else 7 with RGB, else 6; otherwise the legacy format 3/1 (GPS time carried)
// or 2/0 in LAS 1.2. Records are the format's length plus extra_bytes_size
// extra bytes, described by the Extra Bytes VLR when one is given. Each LAS
// attribute carried is written field by field; one not carried is 0, except
// the return number and number of returns, which are 1 ("return 1 of 1").
// The scan angle converts exactly when the units allow (whole degrees for
// 0-5, 0.006 degrees for 6-10) and is rounded to the nearest step otherwise
// (an archive mixing legacy and 1.4 sources). A value a legacy record cannot
// hold (classification above 31, return numbers above 7, the overlap flag, a
// scanner channel) is an error naming the point, never a truncated field.
// 8-bit colour levels become 16-bit ones by (v << 8) | low with the colour
// low bytes (LasAttributes::color_low), else by v * 257 (0 -> 0, 255 -> 65535);
// with WriterOptions::las_colors_8bit (a source that stored 8-bit levels in
// its 16-bit fields) they are written as they are, but where a low byte
// differs from its colour (a level above 255 after the source's sample:
// las_color_level).
//
// The sources' own header fields and records (WriterOptions::las_sources,
// format-spec/archive.md §2.3.1) follow Relief's VLRs: the identity fields all
// sources agree on, each record once across sources; an extended VLR stays
// one in LAS 1.4, one too large for a VLR makes the file LAS 1.4.
//
// Intensity (float) becomes the 16-bit field by one rule for the whole file:
// when every intensity lies in [0, 1] (normalised reflectance, as KITTI's)
// each is scaled by 65535 and rounded (half up), so the 16-bit field keeps
// their resolution; otherwise each is clamped to [0, 65535] and rounded. A
// stream cannot see its last point first, so records are written scaled
// while every intensity so far is in [0, 1]; if a later one is not, finish()
// rewrites the records already written to the plain rule. That is exact: for
// v in [0, 1], round(v * 65535) >= 32768 exactly when v >= 0.5, i.e. when
// round(v) = 1. So the file depends on the set of points, not on the batches.
// Under the plain rule, intensities clamped or rounded are counted and said
// by take_warnings() (the first of each kind named): never changed silently.
//
// Coordinates are stored as X = round((x - offset) / scale) in int32, per
// axis. Scale: WriterOptions::scale when > 0, else 0.1 mm (1e-4; 1e-9 degrees,
// about 0.1 mm on the ground, for x and y of a geographic CRS), raised by
// powers of ten until the expected extent, plus 10 % headroom above it, fits
// 32 bits. Offset: the expected minimum rounded down to a multiple of
// scale * 1e4 (whole metres at 0.1 mm), so offsets are round numbers and
// every expected point maps to 0 or above. The expected extent is
// WriterOptions::expected_bounds, or else the first non-empty batch's bounds
// grown by 10 % of their size on each side. A point that still does not fit
// (data far beyond the expected bounds) is an error naming it, never a
// silently wrapped coordinate.
//
// The header is written first with what is known and rewritten by finish()
// with the point count and the bounds of the coordinates actually stored
// (after quantisation, so they match what readers decode).
//
// LAZ output (.laz) is the same file with the points compressed as LASzip
// compresses them (lib/laz PointCompressor: bit 7 of the format byte, the
// "laszip encoded" VLR, the chunk table offset before the chunks, the chunk
// table after them); a format the compressor does not support is its error,
// naming the output. With a WKT CRS and a legacy source a LAZ file is LAS
// 1.4 with the legacy format (1.4 allows WKT with formats 0-5).

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <ctime>
#include <initializer_list>
#include <limits>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <tuple>
#include <unordered_map>
#include <utility>
#include <vector>

#include "core/parallel.h"
#include "io/output_file.h"
#include "io/point_writers.h"
#include "io/text_scan.h"
#include "relief/laz.h"
#include "relief/crs.h"

#ifndef RELIEF_VERSION
#define RELIEF_VERSION "unknown"
#endif

namespace relief {

namespace {

constexpr std::uint16_t kHeaderSize12 = 227;
constexpr std::uint16_t kHeaderSize14 = 375;
constexpr std::size_t kVlrHeaderSize = 54;
constexpr std::size_t kEvlrHeaderSize = 60;
constexpr std::size_t kMaxVlrPayload = 65535;  // the VLR length field is 16 bits
constexpr std::uint16_t kWktRecordId = 2112;
constexpr std::uint16_t kGeoKeyRecordId = 34735;
constexpr std::uint16_t kGeoDoubleRecordId = 34736;
constexpr std::uint16_t kGeoAsciiRecordId = 34737;
constexpr std::string_view kProjectionUserId = "LASF_Projection";
constexpr std::uint16_t kWktGlobalEncodingBit = 1u << 4;
// Global encoding bit 0: GPS times are adjusted standard GPS time (LAS 1.4
// requires it with formats 6-10).
constexpr std::uint16_t kStandardGpsTimeBit = 1u << 0;
constexpr std::string_view kSpecUserId = "LASF_Spec";
constexpr std::uint16_t kExtraBytesRecordId = 4;
// Legacy formats: 5-bit classification, 3-bit return numbers; 1.4 formats
// 4-bit return numbers; point counts by return: 5 legacy, 15 in LAS 1.4.
constexpr std::uint8_t kLegacyMaxClass = 31;
constexpr std::uint8_t kLegacyMaxReturn = 7;
constexpr std::uint8_t kExtendedMaxReturn = 15;
constexpr std::size_t kLegacyReturnCounts = 5;
constexpr std::size_t kExtendedReturnCounts = 15;
constexpr std::uint8_t kOverlapFlag = 1u << 3;
constexpr std::uint8_t kScannerChannelBits = 0x0C;
constexpr std::int32_t kLegacyScanAngleUnit = 1000;  // thousandths of a degree per LAS unit
constexpr std::int32_t kExtendedScanAngleUnit = 6;
constexpr std::uint32_t kKnownAttributes = (kLasExtraBytes << 1) - 1;
constexpr std::string_view kEpsgPrefix = "EPSG:";
constexpr std::string_view kGeoKeysPrefix = "GeoTIFF keys:";

// GeoKeys (GeoTIFF 1.0 names).
constexpr std::uint16_t kGtModelTypeKey = 1024;  // 1 projected, 2 geographic
constexpr std::uint16_t kGtRasterTypeKey = 1025;  // 1 RasterPixelIsArea
constexpr std::uint16_t kGeographicTypeKey = 2048;
constexpr std::uint16_t kProjectedCsTypeKey = 3072;
constexpr std::uint16_t kUserDefined = 32767;

constexpr std::string_view kSystemIdentifier = "Relief";
constexpr std::uint8_t kLazFormatBit = 0x80;
constexpr std::size_t kChunkTableOffsetSize = 8;
// LAZ: records laid out per step before compression.
constexpr std::size_t kStagingRecords = 8192;
constexpr std::string_view kGeneratingSoftware = "relief " RELIEF_VERSION;

// Exponents of the automatic scale: 1e-4 (0.1 mm), or 1e-9 degrees.
constexpr int kMetricScaleExponent = -4;
constexpr int kDegreeScaleExponent = -9;
// An automatic scale holds the expected extent plus this fraction above it.
constexpr double kAutoHeadroom = 0.1;
// The offset is a multiple of scale * 10^kOffsetUnitExponent.
constexpr int kOffsetUnitExponent = 4;
// The scaled value must round into int32: (-2^31 - 0.5, 2^31 - 1 + 0.5).
constexpr double kLowestScaled = -2147483648.5;
constexpr double kHighestScaled = 2147483647.5;

template <typename T>
void store_le(std::uint8_t* p, T v) {
  if constexpr (std::endian::native == std::endian::little) {
    std::memcpy(p, &v, sizeof(T));
  } else {
    std::uint8_t b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    for (std::size_t i = 0; i < sizeof(T); ++i) p[i] = b[sizeof(T) - 1 - i];
  }
}

// Copies `s` into a fixed-width character field that is already zeroed; the
// field keeps at least one NUL when `s` is shorter than it.
void put_field(std::uint8_t* p, std::string_view s, std::size_t width) {
  std::memcpy(p, s.data(), std::min(s.size(), width));
}

double power_of_ten(int e) {
  double p = 1;
  for (int i = 0; i < (e < 0 ? -e : e); ++i) p *= 10;  // exact up to 1e22
  return e < 0 ? 1 / p : p;                             // the division rounds correctly
}

double& axis(Vec3d& v, int a) { return a == 0 ? v.x : a == 1 ? v.y : v.z; }
double axis(const Vec3d& v, int a) { return a == 0 ? v.x : a == 1 ? v.y : v.z; }
constexpr std::array<const char*, 3> kAxisNames = {"x", "y", "z"};

// "(x, y, z)", built by appending (GCC 12 warns falsely on "(" + string&&).
std::string vec_text(const Vec3d& v) {
  std::string s = "(";
  s += format_double(v.x);
  s += ", ";
  s += format_double(v.y);
  s += ", ";
  s += format_double(v.z);
  s += ")";
  return s;
}

bool all_finite(const Vec3d& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

std::string trimmed(std::string_view s) {
  while (!s.empty() && is_blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && is_blank(s.back())) s.remove_suffix(1);
  return std::string(s);
}

// A decimal number that fits 32 bits, nothing else (no sign, no blanks).
bool parse_u32(std::string_view s, std::uint32_t& out) {
  if (s.empty()) return false;
  const auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc{} && p == s.data() + s.size();
}

// ---------------------------------------------------------------- CRS

struct GeoKey {
  std::uint16_t id;
  std::uint16_t value;
};

struct CrsPlan {
  bool wkt = false;
  std::string wkt_text;
  std::vector<GeoKey> keys;  // sorted by id; empty without GeoTIFF keys
  GeoTiffRecords records;    // the source's GeoTIFF records, written verbatim
  bool geographic = false;   // x and y are degrees
};

// Position of the first of `keywords` in `s` (npos when none occurs).
std::size_t find_first_of_words(std::string_view s, std::initializer_list<std::string_view> keywords) {
  std::size_t best = std::string_view::npos;
  for (std::string_view k : keywords) best = std::min(best, s.find(k));
  return best;
}

// Whether a WKT (1 or 2) CRS has longitude/latitude axes. The outermost
// horizontal CRS comes first in the text: a projected CRS names its
// geographic base inside itself, a compound CRS its horizontal part before
// the vertical one. Guessing "geographic" wrongly only costs a finer scale
// than needed; guessing "projected" wrongly would round degrees to 1e-4
// (about 11 m), so the test errs towards geographic.
bool wkt_is_geographic(std::string_view wkt) {
  const std::size_t projected = find_first_of_words(wkt, {"PROJCS[", "PROJCRS[", "PROJECTEDCRS["});
  std::size_t geographic = find_first_of_words(wkt, {"GEOGCS[", "GEOGCRS[", "GEOGRAPHICCRS["});
  // WKT2 GEODCRS is geographic with an ellipsoidal coordinate system, else
  // geocentric (metres).
  const std::size_t geodetic = find_first_of_words(wkt, {"GEODCRS[", "GEODETICCRS["});
  if (geodetic < geographic && wkt.find("ellipsoidal", geodetic) != std::string_view::npos) {
    geographic = geodetic;
  }
  return geographic < projected;
}

Result<CrsPlan> plan_crs(const std::string& crs, const std::string& source, const std::string& path) {
  CrsPlan plan;
  if (crs.empty()) return plan;
  // A CRS that came from GeoTIFF keys goes back as the same records, in a
  // LAS 1.2 file; one that came as WKT as that WKT text (LAS 1.4).
  if (parse_geotiff_source_text(source, plan.records)) {
    if (plan.records.keys.size() > kMaxVlrPayload || plan.records.doubles.size() > kMaxVlrPayload ||
        plan.records.ascii.size() > kMaxVlrPayload) {
      return invalid_argument(path + ": the GeoTIFF records of the CRS are too large for LAS VLRs");
    }
    // The archive's WKT2 says whether x and y are degrees.
    Result<CrsSummary> summary = describe_crs(crs, path);
    plan.geographic = summary.is_ok() ? summary->geographic : wkt_is_geographic(crs);
    return plan;
  }
  if (!source.empty()) {
    plan.wkt = true;
    plan.wkt_text = source;
    plan.geographic = wkt_is_geographic(source);
    return plan;
  }
  const std::string where = path + ": CRS " + quoted(crs) + ": ";
  const std::string_view text(crs);
  if (text.substr(0, kEpsgPrefix.size()) == kEpsgPrefix) {
    std::uint32_t code = 0;
    // A GeoKey holds a 16-bit value; 0 and 32767 mean "undefined" and
    // "user-defined", not a code.
    if (!parse_u32(trimmed(text.substr(kEpsgPrefix.size())), code) || code == 0 || code > 65535 ||
        code == kUserDefined) {
      return invalid_argument(where + "expected EPSG:<code> with a code from 1 to 65535 (not 32767)");
    }
    const auto value = static_cast<std::uint16_t>(code);
    // EPSG puts the geographic 2D CRSs in 4000-4999; everything else written
    // here is taken as projected.
    plan.geographic = code >= 4000 && code <= 4999;
    if (plan.geographic) {
      plan.keys = {{kGtModelTypeKey, 2}, {kGtRasterTypeKey, 1}, {kGeographicTypeKey, value}};
    } else {
      plan.keys = {{kGtModelTypeKey, 1}, {kGtRasterTypeKey, 1}, {kProjectedCsTypeKey, value}};
    }
    return plan;
  }
  if (text.substr(0, kGeoKeysPrefix.size()) == kGeoKeysPrefix) {
    std::string_view rest = text.substr(kGeoKeysPrefix.size());
    for (;;) {
      const std::size_t comma = std::min(rest.find(','), rest.size());
      const std::string item = trimmed(rest.substr(0, comma));
      const std::size_t eq = item.find('=');
      std::uint32_t id = 0;
      std::uint32_t value = 0;
      if (eq == std::string::npos || !parse_u32(trimmed(std::string_view(item).substr(0, eq)), id) ||
          !parse_u32(trimmed(std::string_view(item).substr(eq + 1)), value) || id > 65535 || value > 65535) {
        return invalid_argument(where + "expected 'GeoTIFF keys: <key>=<value>, ...' with 16-bit numbers, got " +
                                quoted(item));
      }
      plan.keys.push_back({static_cast<std::uint16_t>(id), static_cast<std::uint16_t>(value)});
      if (comma == rest.size()) break;
      rest.remove_prefix(comma + 1);
    }
    // GeoTIFF wants the key entries in increasing KeyID order.
    std::stable_sort(plan.keys.begin(), plan.keys.end(),
                     [](const GeoKey& a, const GeoKey& b) { return a.id < b.id; });
    for (std::size_t i = 0; i < plan.keys.size(); ++i) {
      if (i > 0 && plan.keys[i].id == plan.keys[i - 1].id) {
        return invalid_argument(where + "key " + std::to_string(plan.keys[i].id) + " appears twice");
      }
      if (plan.keys[i].id == kGtModelTypeKey) plan.geographic = plan.keys[i].value == 2;
    }
    return plan;
  }
  plan.wkt = true;
  plan.wkt_text = crs;
  plan.geographic = wkt_is_geographic(text);
  return plan;
}

// The GeoKeyDirectoryTag: KeyDirectoryVersion 1, KeyRevision 1, MinorRevision
// 0, NumberOfKeys, then per key KeyID, TIFFTagLocation 0 (the value is held
// directly), Count 1, Value; all u16.
std::vector<std::uint8_t> geokey_directory(const std::vector<GeoKey>& keys) {
  std::vector<std::uint16_t> words = {1, 1, 0, static_cast<std::uint16_t>(keys.size())};
  for (const GeoKey& k : keys) words.insert(words.end(), {k.id, 0, 1, k.value});
  std::vector<std::uint8_t> bytes(2 * words.size());
  for (std::size_t i = 0; i < words.size(); ++i) store_le(bytes.data() + 2 * i, words[i]);
  return bytes;
}

// VLR header: reserved u16, user id char[16], record id u16, length after
// header u16, description char[32] (54 bytes), then the payload.
void append_vlr(std::vector<std::uint8_t>& out, std::uint16_t record_id, std::string_view description,
                std::span<const std::uint8_t> payload, std::string_view user_id = kProjectionUserId) {
  std::array<std::uint8_t, kVlrHeaderSize> h{};
  put_field(h.data() + 2, user_id, 16);
  store_le(h.data() + 18, record_id);
  store_le(h.data() + 20, static_cast<std::uint16_t>(payload.size()));
  put_field(h.data() + 22, description, 32);
  out.insert(out.end(), h.begin(), h.end());
  out.insert(out.end(), payload.begin(), payload.end());
}

// EVLR header (LAS 1.4): as a VLR but the length is u64 at 20 and the
// description at 28 (60 bytes).
std::vector<std::uint8_t> make_evlr(std::uint16_t record_id, std::string_view description,
                                    std::span<const std::uint8_t> payload,
                                    std::string_view user_id = kProjectionUserId) {
  // Sized once (growing a 60-byte vector by insert draws a false GCC 12
  // -Warray-bounds once inlined).
  std::vector<std::uint8_t> out(kEvlrHeaderSize + payload.size(), 0);
  put_field(out.data() + 2, user_id, 16);
  store_le(out.data() + 18, record_id);
  store_le(out.data() + 20, static_cast<std::uint64_t>(payload.size()));
  put_field(out.data() + 28, description, 32);
  std::copy(payload.begin(), payload.end(), out.begin() + kEvlrHeaderSize);
  return out;
}

// A fixed-width field of a kept record, every byte as it was.
template <std::size_t N>
std::string_view raw_field(const std::array<std::uint8_t, N>& field) {
  return {reinterpret_cast<const char*>(field.data()), N};
}

// What LAS output gives back of its sources (WriterOptions::las_sources): a
// header field when every source with a header agrees on it, each record once.
struct SourceIdentity {
  std::optional<std::uint16_t> file_source_id;
  std::optional<bool> synthetic_returns;  // global encoding bit 3 (LAS 1.3+; 0 in earlier headers)
  std::optional<std::array<std::uint8_t, 16>> project_id;
  std::optional<std::array<std::uint8_t, 32>> system_identifier;
  std::optional<std::pair<std::uint16_t, std::uint16_t>> created;  // day of year, year
  std::vector<const LasVlr*> records;
};

constexpr std::uint16_t kSyntheticReturnsBit = 1u << 3;
constexpr double kSecondsPerWeek = 604800;

SourceIdentity source_identity(const std::vector<LasSourceMetadata>& sources) {
  SourceIdentity out;
  bool first = true;
  const auto agree = [&first](auto& slot, const auto& value) {
    if (first) {
      slot = value;
    } else if (slot && *slot != value) {
      slot.reset();
    }
  };
  // Records of earlier sources, by a hash of their bytes: a record that
  // one of them already gave is not repeated (tiles of one survey carry the
  // same ones); within a source every record stays, repeats included.
  std::unordered_multimap<std::uint64_t, const LasVlr*> given;
  const auto hash = [](const LasVlr& r) {
    std::uint64_t h = 1469598103934665603ull;  // FNV-1a
    const auto mix = [&h](std::span<const std::uint8_t> bytes) {
      for (const std::uint8_t b : bytes) h = (h ^ b) * 1099511628211ull;
    };
    const std::array<std::uint8_t, 3> head{static_cast<std::uint8_t>(r.extended),
                                           static_cast<std::uint8_t>(r.record_id),
                                           static_cast<std::uint8_t>(r.record_id >> 8)};
    mix(head);
    mix(r.user_id);
    mix(r.description);
    mix(r.data);
    return h;
  };
  for (const LasSourceMetadata& s : sources) {
    const std::size_t before = out.records.size();
    for (const LasVlr& r : s.records) {
      const auto [lo, hi] = given.equal_range(hash(r));
      if (std::none_of(lo, hi, [&r](const auto& e) { return *e.second == r; })) out.records.push_back(&r);
    }
    for (std::size_t i = before; i < out.records.size(); ++i) given.emplace(hash(*out.records[i]), out.records[i]);
    if (s.header.size() < 227) continue;  // no header block (not a LAS source)
    const std::uint8_t* h = s.header.data();
    std::array<std::uint8_t, 16> guid{};
    std::array<std::uint8_t, 32> system{};
    std::memcpy(guid.data(), h + 8, guid.size());
    std::memcpy(system.data(), h + 26, system.size());
    const bool v13 = h[25] >= 3;
    agree(out.file_source_id, load_le_value<std::uint16_t>(h + 4));
    agree(out.synthetic_returns, v13 && (load_le_value<std::uint16_t>(h + 6) & kSyntheticReturnsBit) != 0);
    agree(out.project_id, guid);
    agree(out.system_identifier, system);
    agree(out.created, std::make_pair(load_le_value<std::uint16_t>(h + 90), load_le_value<std::uint16_t>(h + 92)));
    first = false;
  }
  return out;
}

// ---------------------------------------------------------------- points

struct Quantizer {
  Vec3d scale{0, 0, 0};
  Vec3d offset{0, 0, 0};
  Vec3d inverse{0, 0, 0};  // 1 / scale: exact (1e4) for the usual scales, unlike dividing by 1e-4
};

struct IntBounds {
  std::array<std::int32_t, 3> min{std::numeric_limits<std::int32_t>::max(),
                                  std::numeric_limits<std::int32_t>::max(),
                                  std::numeric_limits<std::int32_t>::max()};
  std::array<std::int32_t, 3> max{std::numeric_limits<std::int32_t>::min(),
                                  std::numeric_limits<std::int32_t>::min(),
                                  std::numeric_limits<std::int32_t>::min()};
};

bool in_int32_range(double v) { return v > kLowestScaled && v < kHighestScaled; }

// Rounds half away from zero; `v` is in int32 range. Truncation and a
// branch-free correction are much cheaper than a libm call per coordinate.
std::int32_t round_to_int32(double v) {
  const auto t = static_cast<std::int64_t>(v);
  const double frac = v - static_cast<double>(t);  // exact: |v| < 2^32
  return static_cast<std::int32_t>(t + static_cast<std::int64_t>(frac >= 0.5) -
                                   static_cast<std::int64_t>(frac <= -0.5));
}

std::uint16_t intensity_level(float v) {
  // In double: v + 0.5f in float rounds 0.49999997f up to 1.
  return static_cast<std::uint16_t>(std::clamp(static_cast<double>(v), 0.0, 65535.0) + 0.5);
}

// The unit rule (see the top of the file); v is in [0, 1]. v * 65535 is
// exact in double (24 + 16 significant bits).
constexpr double kUnitIntensityScale = 65535;
constexpr std::uint16_t kUnitHalf = 32768;  // round(v * 65535) >= this <=> v >= 0.5
std::uint16_t unit_intensity_level(float v) {
  return static_cast<std::uint16_t>(static_cast<double>(v) * kUnitIntensityScale + 0.5);
}
bool in_unit_range(float v) { return v >= 0.0f && v <= 1.0f; }

// Offset of the intensity field in every LAS point record format.
constexpr std::size_t kIntensityOffset = 12;

std::uint16_t wide_level(std::uint8_t v) { return static_cast<std::uint16_t>(v * 257); }

// Where the fields of the chosen point format lie.
struct RecordPlan {
  bool extended = false;  // formats 6-10
  std::size_t length = 0;
  std::size_t rgb = 0;    // 0 when no colour
  std::size_t gps = 0;    // 0 when no GPS time
  std::size_t nir = 0;    // 0 when no NIR
  std::size_t extra = 0;  // first extra byte
  std::uint32_t attributes = 0;  // LasAttributeBits written from the batch
  std::uint32_t extra_size = 0;
  bool colors_8bit = false;  // colour levels written as they are (WriterOptions::las_colors_8bit)
};

// Encodes coordinates, intensity and colour of points [first, first + n) of
// `batch` at `dst` (records of plan.length bytes, zeroed here). Returns n, or
// the index (from first) of the first point whose coordinates do not fit
// (which includes NaN and infinities).
template <bool kColors, bool kIntensity>
std::size_t encode_las(const PointCloud& batch, std::size_t first, std::size_t n, const Quantizer& q,
                       const RecordPlan& plan, std::uint8_t* dst, IntBounds& b) {
  const Vec3d* pos = batch.positions.data() + first;
  const Vec3d o = q.offset;
  const Vec3d inv = q.inverse;
  const std::size_t stride = plan.length;
  const std::size_t rgb = plan.rgb;
  std::int32_t min_x = b.min[0], min_y = b.min[1], min_z = b.min[2];
  std::int32_t max_x = b.max[0], max_y = b.max[1], max_z = b.max[2];
  std::size_t i = 0;
  for (; i < n; ++i, dst += stride) {
    const double vx = (pos[i].x - o.x) * inv.x;
    const double vy = (pos[i].y - o.y) * inv.y;
    const double vz = (pos[i].z - o.z) * inv.z;
    if (!(in_int32_range(vx) && in_int32_range(vy) && in_int32_range(vz))) break;
    const std::int32_t x = round_to_int32(vx);
    const std::int32_t y = round_to_int32(vy);
    const std::int32_t z = round_to_int32(vz);
    min_x = std::min(min_x, x);
    min_y = std::min(min_y, y);
    min_z = std::min(min_z, z);
    max_x = std::max(max_x, x);
    max_y = std::max(max_y, y);
    max_z = std::max(max_z, z);
    std::memset(dst, 0, stride);
    store_le(dst, x);
    store_le(dst + 4, y);
    store_le(dst + 8, z);
    if constexpr (kIntensity) store_le(dst + kIntensityOffset, intensity_level(batch.intensities[first + i]));
    if constexpr (kColors) {
      const Rgb8& c = batch.colors[first + i];
      store_le(dst + rgb, wide_level(c.r));
      store_le(dst + rgb + 2, wide_level(c.g));
      store_le(dst + rgb + 4, wide_level(c.b));
    }
  }
  b.min = {min_x, min_y, min_z};
  b.max = {max_x, max_y, max_z};
  return i;
}

using EncodeFn = std::size_t (*)(const PointCloud&, std::size_t, std::size_t, const Quantizer&, const RecordPlan&,
                                 std::uint8_t*, IntBounds&);

EncodeFn pick_encoder(bool colors, bool intensity) {
  if (colors) return intensity ? &encode_las<true, true> : &encode_las<true, false>;
  return intensity ? &encode_las<false, true> : &encode_las<false, false>;
}

// A scan angle in thousandths of a degree as `unit`s, rounded half away from
// zero and clamped to the field (exact when it is a multiple of the unit).
template <typename T>
T scan_angle_field(std::int32_t millidegrees, std::int32_t unit) {
  const std::int64_t m = millidegrees;
  const std::int64_t q = (m >= 0 ? m + unit / 2 : m - unit / 2) / unit;
  return static_cast<T>(std::clamp<std::int64_t>(q, std::numeric_limits<T>::min(), std::numeric_limits<T>::max()));
}

// Writes the LAS attributes of points [first, first + n) into records the
// encoder made; counts points by return (index return number - 1). Returns
// n, or the index (from first) of the first point whose values the format
// cannot hold, with `why` saying which.
std::size_t encode_attributes(const PointCloud& batch, std::size_t first, std::size_t n, const RecordPlan& plan,
                              std::uint8_t* dst, std::vector<std::uint64_t>& by_return, std::string& why) {
  const LasAttributes& a = batch.las;
  const std::uint32_t bits = plan.attributes;
  const auto has = [bits](std::uint32_t bit) { return (bits & bit) != 0; };
  const std::size_t stride = plan.length;
  for (std::size_t i = 0; i < n; ++i, dst += stride) {
    const std::size_t k = first + i;
    const std::uint8_t cls = has(kLasClassification) ? a.classification[k] : 0;
    const std::uint8_t flags = has(kLasClassFlags) ? a.class_flags[k] : 0;
    const std::uint8_t ret = has(kLasReturnNumber) ? a.return_number[k] : 1;
    const std::uint8_t nret = has(kLasNumberOfReturns) ? a.number_of_returns[k] : 1;
    const std::uint8_t scan = has(kLasScanFlags) ? a.scan_flags[k] : 0;
    const std::int32_t angle = has(kLasScanAngle) ? a.scan_angle[k] : 0;
    const std::uint8_t user = has(kLasUserData) ? a.user_data[k] : 0;
    const std::uint16_t source = has(kLasPointSourceId) ? a.point_source_id[k] : 0;
    if (plan.extended) {
      if (ret > kExtendedMaxReturn || nret > kExtendedMaxReturn || flags > 0x0F || scan > 0x0F) {
        why = "has return " + std::to_string(ret) + " of " + std::to_string(nret) + ", classification flags " +
              std::to_string(flags) + " or scan flags " + std::to_string(scan) + " beyond LAS 1.4's fields";
        return i;
      }
      dst[14] = static_cast<std::uint8_t>(ret | (nret << 4));
      dst[15] = static_cast<std::uint8_t>(flags | ((scan >> 2) << 4) | ((scan & 0x03) << 6));
      dst[16] = cls;
      dst[17] = user;
      store_le(dst + 18, scan_angle_field<std::int16_t>(angle, kExtendedScanAngleUnit));
      store_le(dst + 20, source);
    } else {
      if (cls > kLegacyMaxClass || ret > kLegacyMaxReturn || nret > kLegacyMaxReturn ||
          (flags & kOverlapFlag) != 0 || flags > 0x0F || (scan & kScannerChannelBits) != 0 || scan > 0x0F) {
        why = "has classification " + std::to_string(cls) + ", return " + std::to_string(ret) + " of " +
              std::to_string(nret) + ", classification flags " + std::to_string(flags) + " or scan flags " +
              std::to_string(scan) + ", which legacy LAS point formats 0-5 cannot hold";
        return i;
      }
      dst[14] = static_cast<std::uint8_t>(ret | (nret << 3) | (scan << 6));
      dst[15] = static_cast<std::uint8_t>(cls | (flags << 5));
      dst[16] = static_cast<std::uint8_t>(scan_angle_field<std::int8_t>(angle, kLegacyScanAngleUnit));
      dst[17] = user;
      store_le(dst + 18, source);
    }
    if (ret >= 1 && ret <= by_return.size()) ++by_return[ret - 1];
    if (plan.gps != 0 && has(kLasGpsTime)) store_le(dst + plan.gps, a.gps_time[k]);
    if (plan.nir != 0 && has(kLasNir)) store_le(dst + plan.nir, a.nir[k]);
    if (plan.rgb != 0 && plan.colors_8bit) {
      // The levels themselves; a low byte that differs from its colour marks
      // a level above 255 (las_color_level).
      const Rgb8& c = batch.colors[k];
      const Rgb8& l = has(kLasColorLow) ? a.color_low[k] : c;
      store_le(dst + plan.rgb, las_color_level(c.r, l.r, true));
      store_le(dst + plan.rgb + 2, las_color_level(c.g, l.g, true));
      store_le(dst + plan.rgb + 4, las_color_level(c.b, l.b, true));
    } else if (plan.rgb != 0 && has(kLasColorLow)) {
      const Rgb8& c = batch.colors[k];
      const Rgb8& l = a.color_low[k];
      store_le(dst + plan.rgb, static_cast<std::uint16_t>((c.r << 8) | l.r));
      store_le(dst + plan.rgb + 2, static_cast<std::uint16_t>((c.g << 8) | l.g));
      store_le(dst + plan.rgb + 4, static_cast<std::uint16_t>((c.b << 8) | l.b));
    }
    if (plan.extra_size != 0 && has(kLasExtraBytes)) {
      std::memcpy(dst + plan.extra, a.extra_bytes.data() + k * plan.extra_size, plan.extra_size);
    }
  }
  return n;
}

// The point format and record layout for `options` (see the top of the file).
RecordPlan plan_records(const WriterOptions& options, bool wkt, bool laz) {
  RecordPlan plan;
  const std::uint32_t bits = options.las_attributes;
  const bool nir = (bits & kLasNir) != 0;
  const bool gps = (bits & kLasGpsTime) != 0;
  // A legacy source with a WKT CRS keeps its format in LAS 1.4 (1.4 allows
  // WKT with formats 0-5); without a source, a .las takes 6/7 as before.
  // LAS attributes without a LAS source (a CSV classification column, a
  // cloud made in code) may hold values only 1.4 formats can: 6-8 then.
  const bool no_source = options.las_point_format < 0;
  plan.extended = options.las_point_format >= 6 || nir || (wkt && !laz && no_source) || (no_source && bits != 0);
  plan.attributes = bits;
  plan.colors_8bit = options.las_colors_8bit && options.colors;
  plan.extra_size = (bits & kLasExtraBytes) != 0 ? options.extra_bytes_size : 0;
  std::size_t base = 0;
  if (plan.extended) {
    plan.gps = 22;
    if (nir) {
      base = 38;
      plan.rgb = 30;
      plan.nir = 36;
    } else if (options.colors) {
      base = 36;
      plan.rgb = 30;
    } else {
      base = 30;
    }
  } else {
    base = 20;
    if (gps) {
      plan.gps = 20;
      base = 28;
    }
    if (options.colors) {
      plan.rgb = base;
      base += 6;
    }
  }
  plan.extra = base;
  plan.length = base + plan.extra_size;
  return plan;
}

int format_of(const RecordPlan& plan) {
  if (plan.extended) return plan.nir != 0 ? 8 : plan.rgb != 0 ? 7 : 6;
  return (plan.gps != 0 ? 1 : 0) + (plan.rgb != 0 ? 2 : 0);
}

// ---------------------------------------------------------------- writer

class LasStreamWriter final : public StreamPointWriter {
 public:
  LasStreamWriter(std::unique_ptr<OutputFile> out, const WriterOptions& options, CrsPlan crs, bool laz)
      : StreamPointWriter(std::move(out), options), crs_(std::move(crs)), laz_(laz) {
    plan_ = plan_records(options, crs_.wkt, laz_);
    identity_ = source_identity(options_.las_sources);  // the copy the writer keeps: identity_ points into it
    // A record too large for a VLR can only follow the points, in LAS 1.4.
    const bool large_record = std::any_of(identity_.records.begin(), identity_.records.end(),
                                          [](const LasVlr* r) { return r->data.size() > kMaxVlrPayload; });
    extended_ = crs_.wkt || plan_.extended || large_record;
    minor_ = extended_ ? 4 : 2;
    format_ = static_cast<std::uint8_t>(format_of(plan_));
    record_length_ = static_cast<std::uint16_t>(plan_.length);
    header_size_ = extended_ ? kHeaderSize14 : kHeaderSize12;
    by_return_.assign(extended_ ? kExtendedReturnCounts : kLegacyReturnCounts, 0);
    encode_ = pick_encoder(options.colors, options.intensity);
    const std::time_t now = std::time(nullptr);
    std::tm utc{};
    if (::gmtime_r(&now, &utc) != nullptr) {
      creation_day_ = static_cast<std::uint16_t>(utc.tm_yday + 1);  // 1 January is day 1
      creation_year_ = static_cast<std::uint16_t>(utc.tm_year + 1900);
    }
    if (identity_.created) std::tie(creation_day_, creation_year_) = *identity_.created;
  }

  // Chooses scale and offset now when the extent is known, and writes the
  // provisional header and the VLRs.
  Status start() {
    if (options_.las_attributes & ~kKnownAttributes) {
      return invalid_argument(out_->path() + ": unknown LAS attribute bits " + std::to_string(options_.las_attributes));
    }
    if (record_length_ != plan_.length) {
      return invalid_argument(out_->path() + ": " + std::to_string(plan_.extra_size) +
                              " extra bytes per point do not fit a LAS record");
    }
    if (!options_.extra_bytes_vlr.empty()) {
      if (options_.extra_bytes_vlr.size() > kMaxVlrPayload) {
        return invalid_argument(out_->path() + ": the Extra Bytes VLR (" +
                                std::to_string(options_.extra_bytes_vlr.size()) + " bytes) is too large for a VLR");
      }
      const std::span<const std::uint8_t> vlr(reinterpret_cast<const std::uint8_t*>(options_.extra_bytes_vlr.data()),
                                              options_.extra_bytes_vlr.size());
      RELIEF_RETURN_IF_ERROR(parse_extra_bytes_vlr(vlr, plan_.extra_size, out_->path()).status());
    }
    if (!options_.expected_bounds.empty()) RELIEF_RETURN_IF_ERROR(place(options_.expected_bounds, true));
    if (laz_) {
      RELIEF_ASSIGN_OR_RETURN(compressor_, laz::PointCompressor::create(format_, record_length_,
                                                                        laz::PointCompressor::kDefaultChunkSize,
                                                                        out_->path(), resolve_threads(options_.threads)));
    }
    build_vlrs();
    if (header_size_ + vlrs_.size() > std::numeric_limits<std::uint32_t>::max()) {
      return limit_exceeded(out_->path() + ": the sources' LAS records take " + std::to_string(vlrs_.size()) +
                            " bytes, more than a LAS file's VLRs can (4 GiB)");
    }
    const std::vector<std::uint8_t> h = header();
    RELIEF_RETURN_IF_ERROR(out_->append(h.data(), h.size()));
    RELIEF_RETURN_IF_ERROR(out_->append(vlrs_.data(), vlrs_.size()));
    if (!laz_) return Status::ok();
    // The chunk table's offset, known once the chunks are written.
    const std::array<std::uint8_t, kChunkTableOffsetSize> placeholder{};
    return out_->append(placeholder.data(), placeholder.size());
  }

 protected:
  bool checks_coordinates() const override { return true; }

  Status write_points(const PointCloud& batch) override {
    const std::size_t n = batch.size();
    if (n == 0) return Status::ok();
    if (!extended_ && points_written() + n > std::numeric_limits<std::uint32_t>::max()) {
      return limit_exceeded(out_->path() + ": a LAS 1.2 file holds at most 4294967295 points");
    }
    if (!placed_) RELIEF_RETURN_IF_ERROR(place_from(batch));
    RELIEF_RETURN_IF_ERROR(check_attributes(batch));
    note_gps_times(batch);
    if (options_.intensity && unit_intensity_ &&
        !std::all_of(batch.intensities.begin(), batch.intensities.end(), in_unit_range)) {
      if (laz_ && points_written() > 0) {
        // Compressed records cannot be rewritten to the plain rule.
        return invalid_argument(out_->path() + ": intensities within 0..1 were followed by one outside it; the "
                                "points already compressed cannot be rewritten: write .las instead");
      }
      unit_intensity_ = false;
      unit_records_ = points_written();  // finish() rewrites these
    }
    if (options_.intensity) note_intensities(batch);
    if (laz_) return write_compressed(batch);
    std::size_t i = 0;
    while (i < n) {
      std::span<std::uint8_t> room;
      RELIEF_RETURN_IF_ERROR(out_->room(record_length_, room));
      const std::size_t k = std::min(n - i, room.size() / record_length_);
      std::size_t coded = 0;
      std::string why;
      const std::size_t done = encode_records(batch, i, k, room.data(), coded, why);
      out_->advance(done * record_length_);
      if (done < coded) return point_error(points_written() + i + done, why);
      if (done < k) return out_of_range(batch, i + done);
      i += k;
    }
    return Status::ok();
  }

  Status complete() override {
    if (!placed_) place_default();
    if (!unit_intensity_) say_changed_intensities();
    if (laz_) {
      compressed_.clear();
      const std::vector<std::uint8_t> table = compressor_->finish(compressed_);
      RELIEF_RETURN_IF_ERROR(out_->append(compressed_.data(), compressed_.size()));
      std::array<std::uint8_t, kChunkTableOffsetSize> offset{};
      store_le(offset.data(), out_->position());
      RELIEF_RETURN_IF_ERROR(out_->append(table.data(), table.size()));
      RELIEF_RETURN_IF_ERROR(out_->patch(header_size_ + vlrs_.size(), offset.data(), offset.size()));
    }
    if (unit_records_ > 0) RELIEF_RETURN_IF_ERROR(unscale_unit_records());
    if (evlr_wkt_ || !evlr_records_.empty()) evlr_start_ = out_->position();
    if (evlr_wkt_) {
      // A WKT too long for a VLR follows the points as an extended VLR.
      const std::vector<std::uint8_t> e = make_evlr(kWktRecordId, "OGC WKT coordinate system", wkt_payload());
      RELIEF_RETURN_IF_ERROR(out_->append(e.data(), e.size()));
    }
    for (const LasVlr* r : evlr_records_) {
      const std::vector<std::uint8_t> e = make_evlr(r->record_id, raw_field(r->description), r->data,
                                                    raw_field(r->user_id));
      RELIEF_RETURN_IF_ERROR(out_->append(e.data(), e.size()));
    }
    const std::vector<std::uint8_t> h = header();
    return out_->patch(0, h.data(), h.size());
  }

 private:
  // Intensities the plain rule (see the top of the file) does not keep as
  // they are: outside 0..65535 (clamped) or with a fraction (rounded). A
  // PTS file's are -2048..2047, a normalised one's fractions.
  struct ChangedValues {
    std::uint64_t count = 0;
    float first = 0;
    void note(float v) {
      if (count++ == 0) first = v;
    }
  };
  void note_intensities(const PointCloud& batch) {
    for (const float v : batch.intensities) {
      if (v < 0.0f || v > 65535.0f) {
        clamped_.note(v);
      } else if (v != std::floor(v)) {
        rounded_.note(v);
      }
    }
  }
  void say_changed_intensities() {
    const auto shortest = [](float v) {
      char text[32];
      return std::string(text, std::to_chars(text, text + sizeof text, v).ptr);
    };
    const auto counted = [](std::uint64_t n, const char* what) {
      return std::to_string(n) + (n == 1 ? " intensity " : " intensities ") + what + (n == 1 ? " was " : " were ");
    };
    if (clamped_.count > 0) {
      warnings_.push_back(out_->path() + ": " + counted(clamped_.count, "outside LAS's 0..65535") +
                          "clamped to it (the first: " + shortest(clamped_.first) + ")");
    }
    if (rounded_.count > 0) {
      warnings_.push_back(out_->path() + ": " + counted(rounded_.count, "with a fraction") +
                          "rounded to a whole number (the first: " + shortest(rounded_.first) +
                          "): LAS keeps whole numbers 0..65535, or 0..1 scaled to them when every intensity of "
                          "the file is within 0..1");
    }
  }

  // The first unit_records_ records were written by the unit rule before an
  // intensity outside [0, 1] arrived: rewrite them to the plain rule.
  Status unscale_unit_records() {
    const std::uint64_t first = header_size_ + vlrs_.size();
    const std::size_t per_block = OutputFile::kBlockSize / record_length_;
    std::vector<std::uint8_t> block(per_block * record_length_);
    for (std::uint64_t done = 0; done < unit_records_;) {
      const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(per_block, unit_records_ - done));
      const std::uint64_t at = first + done * record_length_;
      RELIEF_RETURN_IF_ERROR(out_->read_at(at, block.data(), n * record_length_));
      for (std::size_t j = 0; j < n; ++j) {
        std::uint8_t* field = block.data() + j * record_length_ + kIntensityOffset;
        const auto scaled = static_cast<std::uint16_t>(field[0] | (field[1] << 8));
        const std::uint16_t level = scaled >= kUnitHalf ? 1 : 0;
        store_le(field, level);
      }
      RELIEF_RETURN_IF_ERROR(out_->patch(at, block.data(), n * record_length_));
      done += n;
    }
    return Status::ok();
  }

  std::vector<std::uint8_t> wkt_payload() const {
    std::vector<std::uint8_t> p(crs_.wkt_text.begin(), crs_.wkt_text.end());
    p.push_back(0);  // the specification asks for a NUL-terminated string
    return p;
  }

  // Lays out points [i, i + k) of `batch` as records at `dest`: coordinates
  // and the fixed fields, intensities in 0..1 on the 16-bit scale, then the
  // LAS attributes. `coded` is set to how many points the coordinate encoder
  // took (fewer: one out of range); the result is how many also took their
  // attributes (fewer: `why` says what a point format could not hold).
  std::size_t encode_records(const PointCloud& batch, std::size_t i, std::size_t k, std::uint8_t* dest,
                             std::size_t& coded, std::string& why) {
    coded = encode_(batch, i, k, q_, plan_, dest, bounds_);
    if (options_.intensity && unit_intensity_) {
      for (std::size_t j = 0; j < coded; ++j) {
        store_le(dest + j * record_length_ + kIntensityOffset, unit_intensity_level(batch.intensities[i + j]));
      }
    }
    return encode_attributes(batch, i, coded, plan_, dest, by_return_, why);
  }

  // Records are laid out as for LAS in a staging buffer, then compressed;
  // finished chunks go to the file.
  Status write_compressed(const PointCloud& batch) {
    const std::size_t n = batch.size();
    std::size_t i = 0;
    while (i < n) {
      const std::size_t k = std::min(n - i, kStagingRecords);
      staging_.resize(k * record_length_);
      std::size_t coded = 0;
      std::string why;
      const std::size_t done = encode_records(batch, i, k, staging_.data(), coded, why);
      compressed_.clear();
      compressor_->add(staging_.data(), done, compressed_);
      RELIEF_RETURN_IF_ERROR(out_->append(compressed_.data(), compressed_.size()));
      if (done < coded) return point_error(points_written() + i + done, why);
      if (done < k) return out_of_range(batch, i + done);
      i += k;
    }
    return Status::ok();
  }

  // Every LAS attribute the options name, one value per point.
  Status check_attributes(const PointCloud& batch) const {
    const std::uint32_t carried = batch.las.carried();
    if (carried != options_.las_attributes ||
        ((carried & kLasExtraBytes) != 0 && batch.las.extra_bytes_size != plan_.extra_size)) {
      return invalid_argument(out_->path() + ": a batch carries LAS attributes " + std::to_string(carried) +
                              " (" + std::to_string(batch.las.extra_bytes_size) +
                              " extra bytes) but the writer was opened with " +
                              std::to_string(options_.las_attributes) + " (" + std::to_string(plan_.extra_size) +
                              ")");
    }
    if (carried == 0) return Status::ok();
    // Sizes only: coordinates are checked as they are encoded.
    const LasAttributes& a = batch.las;
    const std::size_t n = batch.size();
    for (const std::size_t have :
         {a.classification.size(), a.class_flags.size(), a.return_number.size(), a.number_of_returns.size(),
          a.scan_flags.size(), a.scan_angle.size(), a.user_data.size(), a.point_source_id.size(), a.gps_time.size(),
          a.nir.size(), a.color_low.size()}) {
      if (have != 0 && have != n) {
        return invalid_argument(out_->path() + ": a batch of " + std::to_string(n) + " points has " +
                                std::to_string(have) + " values of a LAS attribute");
      }
    }
    if (!a.color_low.empty() && batch.colors.size() != n) {
      return invalid_argument(out_->path() + ": colour low bytes without colours");
    }
    if (!a.extra_bytes.empty() && a.extra_bytes.size() != n * std::size_t{a.extra_bytes_size}) {
      return invalid_argument(out_->path() + ": a batch of " + std::to_string(n) + " points has " +
                              std::to_string(a.extra_bytes.size()) + " extra bytes");
    }
    return Status::ok();
  }

  void build_vlrs() {
    if (laz_) {
      append_vlr(vlrs_, laz::kVlrRecordId, "Relief LAZ (LASzip compatible)", compressor_->vlr_payload(),
                 laz::kVlrUserId);
      ++vlr_count_;
    }
    if (!options_.extra_bytes_vlr.empty() && plan_.extra_size != 0) {
      const std::span<const std::uint8_t> vlr(reinterpret_cast<const std::uint8_t*>(options_.extra_bytes_vlr.data()),
                                              options_.extra_bytes_vlr.size());
      append_vlr(vlrs_, kExtraBytesRecordId, "Extra Bytes", vlr, kSpecUserId);
      ++vlr_count_;
    }
    if (crs_.wkt) {
      const std::vector<std::uint8_t> payload = wkt_payload();
      if (payload.size() > kMaxVlrPayload) {
        evlr_wkt_ = true;
      } else {
        append_vlr(vlrs_, kWktRecordId, "OGC WKT coordinate system", payload);
        ++vlr_count_;
      }
    } else if (!crs_.records.keys.empty()) {
      append_vlr(vlrs_, kGeoKeyRecordId, "GeoTIFF GeoKeyDirectoryTag", crs_.records.keys);
      ++vlr_count_;
      if (!crs_.records.doubles.empty()) {
        append_vlr(vlrs_, kGeoDoubleRecordId, "GeoTIFF GeoDoubleParamsTag", crs_.records.doubles);
        ++vlr_count_;
      }
      if (!crs_.records.ascii.empty()) {
        append_vlr(vlrs_, kGeoAsciiRecordId, "GeoTIFF GeoAsciiParamsTag", crs_.records.ascii);
        ++vlr_count_;
      }
    } else if (!crs_.keys.empty()) {
      append_vlr(vlrs_, kGeoKeyRecordId, "GeoTIFF GeoKeyDirectoryTag", geokey_directory(crs_.keys));
      ++vlr_count_;
    }
    // The sources' own records: an extended VLR stays one in LAS 1.4.
    for (const LasVlr* r : identity_.records) {
      if (r->data.size() > kMaxVlrPayload || (r->extended && extended_)) {
        evlr_records_.push_back(r);
        continue;
      }
      append_vlr(vlrs_, r->record_id, raw_field(r->description), r->data, raw_field(r->user_id));
      ++vlr_count_;
    }
  }

  // Scale exponent of the automatic scale for axis `a`.
  int base_exponent(int a) const {
    return crs_.geographic && a < 2 ? kDegreeScaleExponent : kMetricScaleExponent;
  }

  // Sets scale and offset for data within `box` (finite, not empty). With
  // `strict`, a caller's scale that cannot hold the box is an error.
  Status place(const Box3d& box, bool strict) {
    for (int a = 0; a < 3; ++a) {
      const double lo = axis(box.min, a);
      const double hi = axis(box.max, a);
      double scale = 0;
      double offset = 0;
      auto fits = [&](double top) {
        const double inv = 1 / scale;
        return in_int32_range((top - offset) * inv) && in_int32_range((lo - offset) * inv);
      };
      if (options_.grid_scale && options_.grid_offset) {
        // The archive's own grid: its integers are the source's. A grid whose
        // origin lies far from the data (a PLY or CSV source's grid has origin
        // 0, and UTM coordinates at a 1 mm step need more than 32 bits) moves
        // its offset by a whole number of steps (10^4 at a time, as the
        // automatic offsets round): the points stay on the same grid.
        scale = std::fabs(axis(*options_.grid_scale, a));
        offset = axis(*options_.grid_offset, a);
        const bool exact =
            options_.grid_offset_exact && scale > 0 && std::isfinite(scale) && std::isfinite(offset);
        if (exact) {
          axis(q_.scale, a) = scale;
          axis(q_.offset, a) = offset;
          axis(q_.inverse, a) = 1 / scale;
          continue;
        }
        if (scale > 0 && std::isfinite(scale) && std::isfinite(offset) && !fits(hi)) {
          const double unit = scale * power_of_ten(kOffsetUnitExponent);
          offset += std::floor((lo - offset) / unit) * unit;
        }
        if (!(scale > 0) || !std::isfinite(scale) || !std::isfinite(offset) || (strict && !fits(hi))) {
          return invalid_argument(out_->path() + ": the archive's grid (scale " + format_double(scale) + ", offset " +
                                  format_double(offset) + ") cannot hold the " + kAxisNames[static_cast<std::size_t>(a)] +
                                  " extent " + format_double(lo) + " .. " + format_double(hi) + " in LAS 32-bit coordinates");
        }
      } else if (options_.scale > 0) {
        scale = options_.scale;
        const double unit = scale * power_of_ten(kOffsetUnitExponent);
        offset = std::floor(lo / unit) * unit;
        if (!std::isfinite(offset) || (strict && !fits(hi))) {
          return invalid_argument(out_->path() + ": scale " + format_double(scale) + " cannot hold the " +
                                  kAxisNames[static_cast<std::size_t>(a)] + " extent " + format_double(lo) +
                                  " .. " + format_double(hi) +
                                  " in LAS 32-bit coordinates; use a coarser scale or 0 for automatic");
        }
      } else {
        // Headroom above the extent: decoded points may stray slightly beyond
        // the bounds they were promised (lossy codecs), and an extent just
        // under a power-of-ten limit would then fail on them. Below the
        // offset there is always room: the whole negative int32 range.
        const double top = hi + kAutoHeadroom * (hi - lo);
        for (int e = base_exponent(a);; ++e) {
          scale = power_of_ten(e);
          const double unit = power_of_ten(e + kOffsetUnitExponent);
          offset = std::floor(lo / unit) * unit;
          if (std::isfinite(offset) && fits(top)) break;
          if (e > 300) return internal_error(out_->path() + ": no LAS scale fits the extent");
        }
      }
      axis(q_.scale, a) = scale;
      axis(q_.offset, a) = offset;
      axis(q_.inverse, a) = 1 / scale;
    }
    placed_ = true;
    return Status::ok();
  }

  // Places from the first batch: its bounds grown by 10 % on each side, so
  // later batches somewhat beyond the first still fit the chosen scale.
  Status place_from(const PointCloud& batch) {
    Box3d box;
    for (std::size_t i = 0; i < batch.size(); ++i) {
      if (!all_finite(batch.positions[i])) {
        return point_error(points_written() + i, "has a non-finite coordinate (NaN or Inf)");
      }
      box.add(batch.positions[i]);
    }
    const Vec3d e = box.extent();
    for (int a = 0; a < 3; ++a) {
      axis(box.min, a) -= 0.1 * axis(e, a);
      axis(box.max, a) += 0.1 * axis(e, a);
    }
    return place(box, false);
  }

  // No points and no expected bounds: the scale the options ask for, offset 0.
  void place_default() {
    const bool grid = options_.grid_scale && options_.grid_offset;
    for (int a = 0; a < 3; ++a) {
      const double scale = grid ? std::fabs(axis(*options_.grid_scale, a))
                                : options_.scale > 0 ? options_.scale : power_of_ten(base_exponent(a));
      axis(q_.scale, a) = scale;
      axis(q_.offset, a) = grid ? axis(*options_.grid_offset, a) : 0;
      axis(q_.inverse, a) = 1 / scale;
    }
    placed_ = true;
  }

  Status out_of_range(const PointCloud& batch, std::size_t i) const {
    const Vec3d& p = batch.positions[i];
    const std::uint64_t index = points_written() + i;
    if (!all_finite(p)) return point_error(index, "has a non-finite coordinate (NaN or Inf)");
    std::string what = vec_text(p);
    what += " does not fit the LAS 32-bit coordinates at scale ";
    what += vec_text(q_.scale);
    what += " and offset ";
    what += vec_text(q_.offset);
    what += "; the expected bounds must cover all the data";
    return point_error(index, what);
  }

  std::vector<std::uint8_t> header() const {
    std::vector<std::uint8_t> h(header_size_, 0);
    std::uint8_t* p = h.data();
    std::memcpy(p, "LASF", 4);
    // The sources' file source id and GUID where they agree, else 0.
    if (identity_.file_source_id) store_le(p + 4, *identity_.file_source_id);
    if (identity_.project_id) std::memcpy(p + 8, identity_.project_id->data(), 16);
    const bool synthetic = minor_ >= 3 && identity_.synthetic_returns.value_or(false);
    store_le(p + 6, static_cast<std::uint16_t>((crs_.wkt ? kWktGlobalEncodingBit : 0) |
                                               (standard_gps_time() ? kStandardGpsTimeBit : 0) |
                                               (synthetic ? kSyntheticReturnsBit : 0)));
    p[24] = 1;
    p[25] = minor_;
    if (identity_.system_identifier) {
      std::memcpy(p + 26, identity_.system_identifier->data(), 32);
    } else {
      put_field(p + 26, kSystemIdentifier, 32);
    }
    put_field(p + 58, kGeneratingSoftware, 32);
    store_le(p + 90, creation_day_);
    store_le(p + 92, creation_year_);
    store_le(p + 94, header_size_);
    store_le(p + 96, static_cast<std::uint32_t>(header_size_ + vlrs_.size()));
    store_le(p + 100, vlr_count_);
    // Bit 7 of the format byte marks LASzip-compressed points.
    p[104] = static_cast<std::uint8_t>(laz_ ? format_ | kLazFormatBit : format_);
    store_le(p + 105, record_length_);
    const std::uint64_t n = points_written();
    // Formats 6-10 are not legacy compatible: 1.4 wants the legacy counts 0.
    const bool legacy = format_ < 6 && n <= std::numeric_limits<std::uint32_t>::max();
    const auto legacy_count = static_cast<std::uint32_t>(legacy ? n : 0);
    store_le(p + 107, legacy_count);
    // Points by return: 5 legacy counts, 15 in LAS 1.4 (return 0 counts nowhere).
    for (std::size_t r = 0; r < kLegacyReturnCounts; ++r) {
      store_le(p + 111 + 4 * r, static_cast<std::uint32_t>(legacy ? by_return_[r] : 0));
    }
    for (int a = 0; a < 3; ++a) {
      const auto k = static_cast<std::size_t>(8 * a);
      store_le(p + 131 + k, axis(q_.scale, a));
      store_le(p + 155 + k, axis(q_.offset, a));
      double lo = 0;
      double hi = 0;
      if (n > 0) {
        const auto ia = static_cast<std::size_t>(a);
        // As readers decode them: X * scale + offset.
        lo = static_cast<double>(bounds_.min[ia]) * axis(q_.scale, a) + axis(q_.offset, a);
        hi = static_cast<double>(bounds_.max[ia]) * axis(q_.scale, a) + axis(q_.offset, a);
      }
      store_le(p + 179 + 2 * k, hi);  // max x, min x, max y, min y, max z, min z
      store_le(p + 187 + 2 * k, lo);
    }
    if (minor_ >= 4) {
      // 227: start of waveform data 0 (none).
      store_le(p + 235, evlr_start_);
      store_le<std::uint32_t>(p + 243, static_cast<std::uint32_t>((evlr_wkt_ ? 1 : 0) + evlr_records_.size()));
      store_le(p + 247, n);
      for (std::size_t r = 0; r < kExtendedReturnCounts; ++r) {
        store_le(p + 255 + 8 * r, static_cast<std::uint64_t>(r < by_return_.size() ? by_return_[r] : 0));
      }
    }
    return h;
  }

  // Global encoding bit 0 says what the source's GPS times counted, as
  // LAStools and PDAL forward it. When no source said (text, PLY, a stream),
  // the times say: all within one week's seconds (0 <= t < 604800) count the
  // week, any other is adjusted standard GPS time (GPS seconds - 10^9, which
  // stays outside that range but for a week of September 2011); a file of
  // no points keeps LAS 1.4's wish for formats 6-10.
  bool standard_gps_time() const {
    if (plan_.gps == 0) return false;
    switch (options_.las_gps_time_type) {
      case GpsTimeType::kStandard:
        return true;
      case GpsTimeType::kWeek:
        return false;
      case GpsTimeType::kUnknown:
        break;
    }
    if (points_written() == 0) return format_ >= 6;
    return !times_in_week_;
  }

  // Whether every GPS time written so far lies within one week's seconds
  // (standard_gps_time, for sources that did not say what they count).
  void note_gps_times(const PointCloud& batch) {
    if (!times_in_week_ || plan_.gps == 0 || options_.las_gps_time_type != GpsTimeType::kUnknown) return;
    for (const double t : batch.las.gps_time) {
      if (!(t >= 0 && t < kSecondsPerWeek)) {
        times_in_week_ = false;
        return;
      }
    }
  }

  CrsPlan crs_;
  bool laz_ = false;
  std::unique_ptr<laz::PointCompressor> compressor_;
  std::vector<std::uint8_t> staging_;     // LAZ: uncompressed records of one step
  std::vector<std::uint8_t> compressed_;  // LAZ: chunks completed by one step
  bool extended_ = false;  // LAS 1.4
  std::uint8_t minor_ = 2;
  std::uint8_t format_ = 0;
  std::uint16_t record_length_ = 0;
  std::uint16_t header_size_ = 0;
  std::uint16_t creation_day_ = 0;
  std::uint16_t creation_year_ = 0;
  std::vector<std::uint8_t> vlrs_;
  std::uint32_t vlr_count_ = 0;
  bool evlr_wkt_ = false;
  SourceIdentity identity_;
  std::vector<const LasVlr*> evlr_records_;  // the sources' records that follow the points
  std::uint64_t evlr_start_ = 0;
  RecordPlan plan_;
  std::vector<std::uint64_t> by_return_;  // points by return number 1..5 (legacy) or 1..15
  EncodeFn encode_ = nullptr;
  bool times_in_week_ = true;      // every GPS time so far in [0, 604800)
  bool unit_intensity_ = true;     // every intensity so far in [0, 1]
  std::uint64_t unit_records_ = 0;  // records to rewrite when that ended
  ChangedValues clamped_, rounded_;  // intensities, for say_changed_intensities()
  bool placed_ = false;
  Quantizer q_;
  IntBounds bounds_;
};

}  // namespace

Result<std::unique_ptr<PointWriter>> open_las_writer(const std::string& path, const WriterOptions& options,
                                                     bool laz) {
  // Arguments first, so that a bad option is reported as such even when the
  // destination is also unwritable.
  if (!(options.scale >= 0) || !std::isfinite(options.scale)) {
    return invalid_argument(path + ": LAS scale " + format_double(options.scale) +
                            " must be positive, or 0 for automatic");
  }
  const Box3d& eb = options.expected_bounds;
  if (!eb.empty() && (!all_finite(eb.min) || !all_finite(eb.max))) {
    return invalid_argument(path + ": the expected bounds are not finite");
  }
  RELIEF_ASSIGN_OR_RETURN(CrsPlan crs, plan_crs(options.crs, options.crs_source, path));
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<OutputFile> out, OutputFile::create(path));
  if (out->is_stdout()) {
    return invalid_argument("LAS cannot be written to standard output (its header is completed last)");
  }
  auto writer = std::make_unique<LasStreamWriter>(std::move(out), options, std::move(crs), laz);
  RELIEF_RETURN_IF_ERROR(writer->start());
  return std::unique_ptr<PointWriter>(std::move(writer));
}

}  // namespace relief
