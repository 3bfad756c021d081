// Basic value types shared by every Relief module.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include "relief/status.h"

namespace relief {

struct Vec3d {
  double x = 0, y = 0, z = 0;
  friend bool operator==(const Vec3d&, const Vec3d&) = default;
};

struct Rgb8 {
  std::uint8_t r = 0, g = 0, b = 0;
  friend bool operator==(const Rgb8&, const Rgb8&) = default;
};

// Axis-aligned box; empty() until the first point is added.
struct Box3d {
  Vec3d min{+1e308, +1e308, +1e308};
  Vec3d max{-1e308, -1e308, -1e308};

  bool empty() const { return min.x > max.x || min.y > max.y || min.z > max.z; }
  void add(const Vec3d& p) {
    // Inline: ingest and the codec call this once per point.
    min.x = p.x < min.x ? p.x : min.x;
    min.y = p.y < min.y ? p.y : min.y;
    min.z = p.z < min.z ? p.z : min.z;
    max.x = p.x > max.x ? p.x : max.x;
    max.y = p.y > max.y ? p.y : max.y;
    max.z = p.z > max.z ? p.z : max.z;
  }
  // Whether `inner` lies within this box (closed; faces may touch).
  bool contains(const Box3d& inner) const {
    return min.x <= inner.min.x && min.y <= inner.min.y && min.z <= inner.min.z && max.x >= inner.max.x &&
           max.y >= inner.max.y && max.z >= inner.max.z;
  }
  // Length of the diagonal; 0 for an empty box.
  double diagonal() const;
  Vec3d extent() const;
};

// One bit per LasAttributes vector, for the set an input, a chunk or an
// archive carries (a batch of 0 points cannot show it by its vectors).
enum LasAttributeBits : std::uint32_t {
  kLasClassification = 1u << 0,
  kLasClassFlags = 1u << 1,
  kLasReturnNumber = 1u << 2,
  kLasNumberOfReturns = 1u << 3,
  kLasScanFlags = 1u << 4,
  kLasScanAngle = 1u << 5,
  kLasUserData = 1u << 6,
  kLasPointSourceId = 1u << 7,
  kLasGpsTime = 1u << 8,
  kLasNir = 1u << 9,
  kLasColorLow = 1u << 10,
  kLasExtraBytes = 1u << 11,
};
// The LAS dimensions a text column can name (all but the colour low bytes
// and extra bytes): what `relief stream` carries.
inline constexpr std::uint32_t kLasTextAttributes = (kLasColorLow - 1);

// What a LAS source's GPS times count (its header's global encoding bit 0):
// seconds of the GPS week, or adjusted standard GPS time (GPS seconds since
// 1980-01-06 minus 10^9). The values are incomparable, so one archive holds
// one kind; kUnknown where no source said (no GPS time, or an archive made
// before Relief recorded it).
enum class GpsTimeType : int { kUnknown = -1, kWeek = 0, kStandard = 1 };
// "week", "standard" or "" (kUnknown); parse_gps_time_type is the inverse
// ("" and unknown text give kUnknown).
const char* gps_time_type_name(GpsTimeType t);
GpsTimeType parse_gps_time_type(const std::string& text);

// ---- What a LAS file says of itself beyond its points
//
// One variable-length record of a LAS file (ASPRS LAS 1.4 R15 §2.5, §2.6): a
// VLR before the points, or an extended VLR after them, with its user id and
// description as the file had them (NUL padded).
struct LasVlr {
  bool extended = false;
  std::array<std::uint8_t, 16> user_id{};
  std::uint16_t record_id = 0;
  std::array<std::uint8_t, 32> description{};
  std::vector<std::uint8_t> data;
  bool operator==(const LasVlr&) const = default;
};

// A LAS/LAZ source's public header block (its standard 227, 235 or 375
// bytes, as the file had them) and the records Relief keeps of it: every VLR
// and extended VLR except those LAS output writes itself from what the
// archive keeps elsewhere (the CRS's LASF_Projection records, the Extra
// Bytes VLR, LASzip's and COPC's records, a LAStools spatial index) or that
// describe data it does not keep (wave packets). Empty for other sources.
// Records Relief keeps of a LAS source: one of at most kMaxKeptLasRecord
// bytes, at most kMaxKeptLasRecords bytes in all.
inline constexpr std::size_t kMaxKeptLasRecord = std::size_t{1} << 20;
inline constexpr std::size_t kMaxKeptLasRecords = std::size_t{4} << 20;
struct LasSourceMetadata {
  std::vector<std::uint8_t> header;
  std::vector<LasVlr> records;
  bool empty() const { return header.empty() && records.empty(); }
  bool operator==(const LasSourceMetadata&) const = default;
};
// Empty when `m` is well formed: a header block of 0, 227, 235 or 375 bytes
// starting "LASF" (present when there are records), VLR data of at most
// 65,535 bytes, extended VLR data of at most kMaxKeptLasRecord; else what is
// wrong, for an error message.
std::string las_metadata_problem(const LasSourceMetadata& m);

// Names of the LasAttributeBits, in bit order ("classification", "class_flags",
// "return_number", "number_of_returns", "scan_flags", "scan_angle",
// "user_data", "point_source_id", "gps_time", "nir", "color_low",
// "extra_bytes"): the archive metadata and `relief info` use them.
inline constexpr const char* kLasAttributeNames[] = {
    "classification", "class_flags", "return_number", "number_of_returns", "scan_flags", "scan_angle",
    "user_data",      "point_source_id", "gps_time",  "nir",               "color_low",  "extra_bytes"};
inline constexpr std::uint32_t kLasAttributeCount = 12;
// "classification,return_number,..." for `bits`, in bit order.
std::string las_attribute_list(std::uint32_t bits);
// The bits of a comma-separated list; unknown names are ignored.
std::uint32_t las_attributes_from_list(const std::string& list);

struct PointCloud;

// The attributes a reader asks for beyond x, y and z (DecodeOptions,
// QueryOptions): colours, intensities and LasAttributeBits. Asking for fewer
// decodes less. The colour low bytes go with the colours, whatever `las`
// says of kLasColorLow.
struct AttributeSet {
  bool colors = true;
  bool intensity = true;
  std::uint32_t las = ~std::uint32_t{0};
  static AttributeSet all() { return {}; }
  static AttributeSet none() { return {false, false, 0}; }
  bool everything() const { return colors && intensity && (las | ~((1u << kLasAttributeCount) - 1)) == ~0u; }
  // The LasAttributeBits kept: `las`, with the colour low bytes exactly when
  // the colours are.
  std::uint32_t las_kept() const {
    return (las & ~std::uint32_t{kLasColorLow}) | (colors ? std::uint32_t{kLasColorLow} : 0u);
  }
  bool operator==(const AttributeSet&) const = default;
};
// An AttributeSet from a comma-separated list of "rgb", "intensity", the
// kLasAttributeNames, "all" and "none" (x y z alone): the names `relief info`
// lists ("color_low" counts only beside "rgb"). An empty or unknown name is
// kInvalidArgument naming it.
Result<AttributeSet> parse_attribute_set(const std::string& list);
// The names of `set`'s members, as parse_attribute_set takes them
// ("rgb,intensity,classification"; "" for none).
std::string attribute_set_list(const AttributeSet& set);
// Removes from `cloud` what `set` does not ask for (the colour low bytes with
// the colours).
void keep_attributes(PointCloud& cloud, const AttributeSet& set);
// Gives `cloud` exactly the LAS attributes `bits` (extra_bytes_size extra
// bytes per point): one it lacks is zero-filled (colour low bytes: the colour
// itself, so its 16-bit level reads v * 257; none without colours), one it
// has beyond the set is dropped.
void conform_las_attributes(PointCloud& cloud, std::uint32_t bits, std::uint32_t extra_bytes_size);

// Per-point LAS attributes beyond XYZ, RGB and intensity (ASPRS LAS 1.4
// names). Each vector is empty (the cloud does not carry that attribute) or
// holds one value per point. Values are the LAS record's own integers, so a
// LAS/LAZ file comes back bit for bit; the units are chosen so that every
// point format (0-10) maps to them exactly.
struct LasAttributes {
  // Classification value. Formats 0-5 keep 5 bits (0..31), formats 6-10 8 bits.
  std::vector<std::uint8_t> classification;
  // Classification flags, LAS 1.4 bit order: bit 0 synthetic, bit 1 key-point,
  // bit 2 withheld, bit 3 overlap (formats 0-5 have no overlap bit).
  std::vector<std::uint8_t> class_flags;
  // Return number and number of returns (formats 0-5: 0..7, 6-10: 0..15).
  std::vector<std::uint8_t> return_number;
  std::vector<std::uint8_t> number_of_returns;
  // Bit 0 scan direction flag, bit 1 edge of flight line, bits 2-3 scanner
  // channel (formats 6-10 only).
  std::vector<std::uint8_t> scan_flags;
  // Scan angle in thousandths of a degree: formats 0-5 store whole degrees
  // (x1000 here), formats 6-10 steps of 0.006 degrees (x6 here). Exact both ways.
  std::vector<std::int32_t> scan_angle;
  std::vector<std::uint8_t> user_data;
  std::vector<std::uint16_t> point_source_id;
  std::vector<double> gps_time;
  std::vector<std::uint16_t> nir;
  // Low bytes of LAS colours (and of PLY colours wider than 8 bits): the LAS
  // value is las_color_level(colors[i].r, color_low[i].r, ...) below. Empty
  // when the source's colours are 8-bit (the colour is colors[i] itself).
  std::vector<Rgb8> color_low;
  // LAS "extra bytes": extra_bytes_size raw bytes per point, described by the
  // source's Extra Bytes VLR (PointStreamInfo::extra_bytes_vlr); extra_bytes
  // holds size() * extra_bytes_size bytes, or is empty.
  std::vector<std::uint8_t> extra_bytes;
  std::uint32_t extra_bytes_size = 0;

  // True when no per-point LAS attribute is carried.
  bool empty() const;
  // The LasAttributeBits of the non-empty vectors.
  std::uint32_t carried() const;

  // The per-point vectors but extra_bytes, each with its LasAttributeBits
  // bit, as (member pointer, bit) pairs (defined first: the visitors below
  // deduce from it).
  static constexpr auto vectors() {
    return std::tuple{std::pair{&LasAttributes::classification, std::uint32_t{kLasClassification}},
                      std::pair{&LasAttributes::class_flags, std::uint32_t{kLasClassFlags}},
                      std::pair{&LasAttributes::return_number, std::uint32_t{kLasReturnNumber}},
                      std::pair{&LasAttributes::number_of_returns, std::uint32_t{kLasNumberOfReturns}},
                      std::pair{&LasAttributes::scan_flags, std::uint32_t{kLasScanFlags}},
                      std::pair{&LasAttributes::scan_angle, std::uint32_t{kLasScanAngle}},
                      std::pair{&LasAttributes::user_data, std::uint32_t{kLasUserData}},
                      std::pair{&LasAttributes::point_source_id, std::uint32_t{kLasPointSourceId}},
                      std::pair{&LasAttributes::gps_time, std::uint32_t{kLasGpsTime}},
                      std::pair{&LasAttributes::nir, std::uint32_t{kLasNir}},
                      std::pair{&LasAttributes::color_low, std::uint32_t{kLasColorLow}}};
  }

  // Calls f(vector, bit) for each per-point vector but extra_bytes (which
  // holds extra_bytes_size values a point), in LasAttributeBits order: the
  // one list of them, for code that treats every attribute alike.
  template <typename F>
  void for_each_vector(F&& f) {
    std::apply([&](auto... m) { (f(this->*m.first, m.second), ...); }, vectors());
  }
  template <typename F>
  void for_each_vector(F&& f) const {
    std::apply([&](auto... m) { (f(this->*m.first, m.second), ...); }, vectors());
  }
  // Calls f(a's vector, b's same vector, bit) for each of them.
  template <typename A, typename B, typename F>
  static void for_each_vector_pair(A& a, B& b, F&& f) {
    std::apply([&](auto... m) { (f(a.*m.first, b.*m.first, m.second), ...); }, vectors());
  }

};

// A colour channel's LAS level from its 8-bit colour and its low byte
// (LasAttributes::color_low), by the rule of the source or archive
// (format-spec/archive.md §2.1, las_colors_8bit). 16-bit levels
// (`levels_8bit` false): (colour << 8) | low. Levels stored as 8-bit values
// in the 16-bit fields (`levels_8bit` true): the colour itself when the low
// byte equals it; a low byte that differs marks a level above 255 met after
// the file's sample held none, split by split_8bit_level.
inline std::uint16_t las_color_level(std::uint8_t colour, std::uint8_t low, bool levels_8bit) {
  if (!levels_8bit) return static_cast<std::uint16_t>((colour << 8) | low);
  if (low == colour) return colour;
  return static_cast<std::uint16_t>(256 + 255 * colour + (low < colour ? low : low - 1));
}
// The colour and low byte of a level of a source that stores 8-bit levels in
// its 16-bit fields, so that las_color_level(colour, low, true) gives it
// back: a level up to 255 is both; a level above 255 (one that came after
// the sample) takes colour = (level - 256) / 255 (about level / 256, its
// 16-bit meaning) and one of the 255 low bytes that differ from the colour.
inline void split_8bit_level(std::uint16_t level, std::uint8_t& colour, std::uint8_t& low) {
  if (level <= 255) {
    colour = low = static_cast<std::uint8_t>(level);
    return;
  }
  const unsigned c = (level - 256u) / 255u, r = (level - 256u) % 255u;
  colour = static_cast<std::uint8_t>(c);
  low = static_cast<std::uint8_t>(r < c ? r : r + 1);
}

// A point cloud with optional per-point attributes. Coordinates are double
// end to end so georeferenced data keeps sub-millimetre precision.
struct PointCloud {
  std::vector<Vec3d> positions;
  std::vector<Rgb8> colors;         // empty, or one per position
  std::vector<float> intensities;   // empty, or one per position
  LasAttributes las;                // each vector empty, or one per position

  std::size_t size() const { return positions.size(); }
  bool empty() const { return positions.empty(); }
  bool has_colors() const { return !colors.empty(); }
  bool has_intensity() const { return !intensities.empty(); }

  // Attribute arrays match the positions and every coordinate and intensity
  // is finite. `what` names the cloud in the error (a file name, "chunk").
  Status validate(const std::string& what) const;
  Box3d bounds() const;
  void reserve(std::size_t n, bool with_colors, bool with_intensity);

  // Generic per-point operations over every attribute the cloud carries
  // (positions, colours, intensities and each non-empty LasAttributes vector),
  // so code that moves points never forgets one.
  // A cloud "carries" an attribute when its vector is non-empty, so a cloud
  // of 0 points carries none; code that needs the set for empty batches keeps
  // it elsewhere (PointStreamInfo, archive metadata).
  // Removes all points (every vector cleared; extra_bytes_size kept).
  void clear_points();
  // Appends point `i` of `src`, which must carry the same attributes.
  void push_back_from(const PointCloud& src, std::size_t i);
  // Appends every point of `src`, which must carry the same attributes.
  void append_points(const PointCloud& src);
  // This cloud becomes points [first, first + n) of `src` with the
  // attributes `src` carries (first + n <= src.size()).
  void assign_range(const PointCloud& src, std::size_t first, std::size_t n);
  // Reorders (or selects) points: the result's point k is this cloud's point order[k].
  PointCloud gathered(const std::vector<std::uint32_t>& order) const;
  // Resizes positions and every carried attribute to n points (new points zeroed).
  void resize_points(std::size_t n);
  // True when `other` carries the same set of attributes (same extra_bytes_size).
  bool same_attributes(const PointCloud& other) const;
};

// A process setting for programs that decode or encode many chunks (the
// relief CLI and the bench programs call it first thing). Every chunk's
// decoder allocates and frees buffers of a few MB; glibc's malloc by default
// hands such blocks back to the kernel when they are freed (its mmap and trim
// thresholds), so the next chunk's buffers fault in fresh zeroed pages: on
// this project's 2-core VM that was a third of a whole-archive decode's time.
// This keeps freed blocks up to 32 MiB in the allocator for reuse (glibc
// mallopt M_MMAP_THRESHOLD 32 MiB, M_TRIM_THRESHOLD 256 MiB), and has every
// thread allocate from one arena (M_ARENA_MAX 1: a thread's own arena unmaps
// its extra heaps whenever they empty, and keeps memory other threads cannot
// reuse). Peak memory is lower; memory freed after the peak stays with the process until it
// ends or the ingest's own trimming returns it. Global to the process, which
// is why the library never calls it itself: a host program (Python, say)
// decides. A no-op without glibc.
void retain_freed_memory();

}  // namespace relief
