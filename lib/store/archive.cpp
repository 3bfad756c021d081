// The Relief archive on SQLite (format-spec/archive.md). Blobs are opaque
// bytes here: the store never links the codec.
#include "relief/archive.h"

#include <fcntl.h>
#include <lzma.h>
#include <sys/resource.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <set>
#include <span>
#include <string_view>
#include <system_error>
#include <tuple>
#include <utility>

#include "core/hex.h"
#include "core/host.h"
#include "store/schema.h"
#include "store/sqlite_util.h"

namespace relief {
namespace {

// A double's bits as an unsigned integer in the same order (IEEE 754
// totalOrder: -0 before +0, NaNs at the ends), so refs of a damaged archive
// still sort.
std::uint64_t ordered_bits(double d) {
  const auto u = std::bit_cast<std::uint64_t>(d);
  return (u >> 63) != 0 ? ~u : (u | (std::uint64_t{1} << 63));
}

// Content order (format-spec/archive.md §4): scan, level, chunk key, then
// the bounds and sizes of the blob, the row id last. Archives holding the
// same blobs then list them, and a query returns their points, in the same
// order, whatever order a writer committed them in (its threads, its memory
// budget). Neither `id` nor `seq` can be part of it before the tie: both
// follow the commit order.
void sort_in_content_order(std::vector<ChunkRef>& refs) {
  const auto rank = [](const ChunkRef& r) {
    return std::make_tuple(r.scan_id, r.level, r.key, ordered_bits(r.bounds.min.x), ordered_bits(r.bounds.min.y),
                           ordered_bits(r.bounds.min.z), ordered_bits(r.bounds.max.x), ordered_bits(r.bounds.max.y),
                           ordered_bits(r.bounds.max.z), r.input_points, r.decoded_points, r.blob_size, r.id);
  };
  std::sort(refs.begin(), refs.end(), [&](const ChunkRef& a, const ChunkRef& b) { return rank(a) < rank(b); });
}

namespace fs = std::filesystem;
using store::Statement;
using store::StatementScope;
using store::Transaction;

// SQLite integers are int64; counts above this cannot be stored.
constexpr std::uint64_t kMaxStoredCount =
    static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max());
constexpr std::int64_t kMaxUint32 = std::numeric_limits<std::uint32_t>::max();
constexpr std::int64_t kMaxInt64 = std::numeric_limits<std::int64_t>::max();
constexpr std::int64_t kMinInt64 = std::numeric_limits<std::int64_t>::min();

// ---- Small helpers

// Shortest text that parses back to the same double (std::to_chars without a
// precision is exactly that), so grid values round-trip bit for bit.
std::string format_double(double value) {
  std::array<char, 32> buffer{};
  const auto result = std::to_chars(buffer.data(), buffer.data() + buffer.size(), value);
  return std::string(buffer.data(), result.ptr);
}

// The whole text as a finite double; no leading space, sign '+', or suffix.
std::optional<double> parse_double(const std::string& text) {
  double value = 0;
  const char* end = text.data() + text.size();
  const auto result = std::from_chars(text.data(), end, value);
  if (result.ec != std::errc() || result.ptr != end || !std::isfinite(value)) return std::nullopt;
  return value;
}

std::string utc_now_iso8601() {
  const std::time_t now = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm utc{};
  gmtime_r(&now, &utc);
  std::array<char, 32> buffer{};
  const std::size_t size = std::strftime(buffer.data(), buffer.size(), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return std::string(buffer.data(), size);
}

std::string key_text(const ChunkKey& key) {
  // Appends rather than "(" + std::to_string(...): GCC 12 warns falsely
  // (-Wrestrict, bug 105329) on a literal plus a temporary string.
  std::string text = "(";
  text += std::to_string(key.ix);
  text += ',';
  text += std::to_string(key.iy);
  text += ',';
  text += std::to_string(key.iz);
  text += ')';
  return text;
}


std::string hex32(std::uint32_t value) {
  std::array<char, 16> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "0x%08X", value);
  return buffer.data();
}

// The same CRC-32 (IEEE 802.3) that closes every chunk blob.
std::uint32_t blob_crc32(const std::vector<std::uint8_t>& blob) {
  return lzma_crc32(blob.data(), blob.size(), 0);
}

bool box_is_finite(const Box3d& box) {
  return std::isfinite(box.min.x) && std::isfinite(box.min.y) && std::isfinite(box.min.z) &&
         std::isfinite(box.max.x) && std::isfinite(box.max.y) && std::isfinite(box.max.z);
}

bool box_has_nan(const Box3d& box) {
  return std::isnan(box.min.x) || std::isnan(box.min.y) || std::isnan(box.min.z) || std::isnan(box.max.x) ||
         std::isnan(box.max.y) || std::isnan(box.max.z);
}

bool boxes_overlap(const Box3d& a, const Box3d& b) {
  return a.max.x >= b.min.x && a.min.x <= b.max.x && a.max.y >= b.min.y && a.min.y <= b.max.y &&
         a.max.z >= b.min.z && a.min.z <= b.max.z;
}

// SQLite's R*Tree keeps each coordinate as a binary32 rounded outward, so an
// entry's minimum lies at most a few binary32 steps below the exact one and
// its maximum as far above. More than 8 steps (2^-20 relative) away, or on the
// wrong side, the entry does not describe its chunk: the index is damaged.
constexpr double kIndexSlack = 0x1p-20;

bool index_bound_fits(double indexed, double exact, bool is_min) {
  if (std::isnan(indexed)) return false;
  if (std::abs(exact) > std::numeric_limits<float>::max()) {
    // Beyond binary32: the entry can only hold the largest float or infinity.
    return is_min ? indexed <= exact || indexed <= -static_cast<double>(std::numeric_limits<float>::max())
                  : indexed >= exact || indexed >= static_cast<double>(std::numeric_limits<float>::max());
  }
  const double slack =
      std::max(std::abs(exact), static_cast<double>(std::numeric_limits<float>::min())) * kIndexSlack;
  return is_min ? indexed <= exact && exact - indexed <= slack : indexed >= exact && indexed - exact <= slack;
}

// `entry` in R*Tree column order: min_x, max_x, min_y, max_y, min_z, max_z.
bool index_entry_fits(const std::array<double, 6>& entry, const Box3d& exact) {
  return index_bound_fits(entry[0], exact.min.x, true) && index_bound_fits(entry[1], exact.max.x, false) &&
         index_bound_fits(entry[2], exact.min.y, true) && index_bound_fits(entry[3], exact.max.y, false) &&
         index_bound_fits(entry[4], exact.min.z, true) && index_bound_fits(entry[5], exact.max.z, false);
}

std::string chunk_label(const ChunkRef& ref) {
  return "chunk " + key_text(ref.key) + " seq " + std::to_string(ref.seq) + " (id " + std::to_string(ref.id) + ")";
}

// ---- Room to undo (format-spec/archive.md, section 8)
//
// Removing a scan rewrites pages: the WAL must grow for it, so on a full disk
// a failed append could not undo itself. A writer therefore commits a batch
// only while the WAL can still take the batch plus the removal of every row
// this handle has written. Upper bounds, in WAL frames (a page + 24 bytes):
// a row needs its blob's overflow pages plus one page for its record and one
// each for the entries it makes in the three b-tree indexes and the R*Tree,
// scattered among older entries (kFramesPerRow); removing it rewrites at most
// those same five pages plus the freelist trunk pages that list its freed
// overflow pages (one per page_size / 4 - 2 of them, and one more), never
// the freed pages themselves: writers turn SQLite's secure_delete off (Debian
// builds it on, and zeroing every freed page made an undo as large as the
// append); interior pages, scan, source and metadata rows take a fixed
// allowance (kFixedFrames).
constexpr std::uint64_t kFramesPerRow = 5;
constexpr std::uint64_t kFixedFrames = 64;
constexpr std::uint64_t kWalFrameHeader = 24;

std::uint64_t file_size_or_zero(const std::string& file) {
  std::error_code ec;
  const std::uintmax_t size = fs::file_size(file, ec);
  return ec ? 0 : static_cast<std::uint64_t>(size);
}

// Bytes the WAL file may still grow by: the free space of its file system
// and the process's file size limit (RLIMIT_FSIZE), whichever is smaller.
std::uint64_t wal_room(const std::string& path) {
  std::uint64_t room = std::numeric_limits<std::uint64_t>::max();
  fs::path directory = fs::path(path).parent_path();
  if (directory.empty()) directory = ".";
  struct statvfs disk {};
  if (::statvfs(directory.c_str(), &disk) == 0) {
    room = static_cast<std::uint64_t>(disk.f_bavail) * static_cast<std::uint64_t>(disk.f_frsize);
  }
  struct rlimit limit {};
  if (::getrlimit(RLIMIT_FSIZE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    const std::uint64_t wal = file_size_or_zero(path + "-wal");
    const auto cap = static_cast<std::uint64_t>(limit.rlim_cur);
    room = std::min(room, cap > wal ? cap - wal : 0);
  }
  return room;
}

std::string megabytes(std::uint64_t bytes) {
  std::array<char, 32> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.1f MB", static_cast<double>(bytes) / 1e6);
  return buffer.data();
}

constexpr const char* kIndexDamaged = " (the spatial index is damaged; 'relief check' lists the damage)";

// ---- The metadata checksum (format version 2, format-spec/archive.md 2.1)

void put_u32_le(std::vector<std::uint8_t>& out, std::uint32_t value) {
  for (int i = 0; i < 4; ++i) out.push_back(static_cast<std::uint8_t>(value >> (8 * i)));
}

// CRC-32 over every relief_meta row but the checksum's own, in key order
// (SQLite's BINARY collation: bytewise): u32 key length, key, u32 value
// length, value. Lengths make the boundaries part of what is checked.
// One field of the checksummed byte strings (meta_crc32, crs_crc32): u32
// little-endian byte count, then the bytes. `n` is below 2^32 (callers check).
void put_checksum_field(std::vector<std::uint8_t>& bytes, const std::uint8_t* data, std::size_t n) {
  put_u32_le(bytes, static_cast<std::uint32_t>(n));
  bytes.insert(bytes.end(), data, data + n);
}

Result<std::uint32_t> compute_meta_checksum(sqlite3* db, const std::string& path) {
  RELIEF_ASSIGN_OR_RETURN(
      std::unique_ptr<Statement> statement,
      Statement::prepare(db, "SELECT key, value FROM relief_meta WHERE key <> ?1 ORDER BY key", path,
                         "read metadata"));
  StatementScope scope(*statement);
  statement->bind_text(1, store::kMetaChecksum);
  std::vector<std::uint8_t> bytes;
  std::vector<std::uint8_t> field;
  for (;;) {
    RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
    if (!row) break;
    for (int column = 0; column < 2; ++column) {
      RELIEF_RETURN_IF_ERROR(statement->column_bytes(column, field));
      if (field.size() > std::numeric_limits<std::uint32_t>::max()) {
        return limit_exceeded(path + ": a metadata value is too long");
      }
      put_checksum_field(bytes, field.data(), field.size());
    }
  }
  return lzma_crc32(bytes.data(), bytes.size(), 0);
}

std::string checksum_text(std::uint32_t crc) { return hex32(crc).substr(2); }

// crs_crc32 (version 3): the CRC-32 of the CRS and its source form, each a
// field as meta_crc32 lays out a value. (SQLite holds no text of 2^32 bytes.)
std::uint32_t crs_checksum(const std::string& crs, const std::string& crs_source) {
  std::vector<std::uint8_t> bytes;
  bytes.reserve(8 + crs.size() + crs_source.size());
  for (const std::string* text : {&crs, &crs_source}) {
    put_checksum_field(bytes, reinterpret_cast<const std::uint8_t*>(text->data()), text->size());
  }
  return lzma_crc32(bytes.data(), bytes.size(), 0);
}

Status append_detail(const Status& status, const std::string& detail) {
  return Status(status.code(), status.message() + " " + detail);
}

Status check_grid(const std::string& path, const ArchiveGrid& grid) {
  if (!std::isfinite(grid.origin.x) || !std::isfinite(grid.origin.y) || !std::isfinite(grid.origin.z)) {
    return invalid_argument(path + ": the grid origin must be finite");
  }
  if (!std::isfinite(grid.chunk_edge) || !(grid.chunk_edge > 0)) {
    return invalid_argument(path + ": the chunk edge must be a finite number > 0, got " +
                            format_double(grid.chunk_edge));
  }
  return Status::ok();
}

// ---- Statements, prepared once per connection and reused.

enum class Sql : std::size_t {
  kMetaGet,
  kMetaAll,
  kMetaPut,
  kScanInsert,
  kOtherScanExists,
  kScanExists,
  kScanFinish,
  kScanSummary,
  kScanFirstCrs,
  kScanFirstCrsSource,
  kScanDelete,
  kSourceInsert,
  kSourceDeleteOfScan,
  kSourceSetPoints,
  kSourceLasInsert,
  kSourceLasDeleteOfScan,
  kSourceLasAll,
  kChunkNextSeq,
  kChunkInsert,
  kIndexInsert,
  kIndexDeleteOfScan,
  kChunkDeleteOfScan,
  kExtentInsert,
  kExtentDeleteOfScan,
  kExtentOfChunk,
  kPointBounds,
  kFindChunks,
  kFindIdsByBounds,
  kFindIdsByBoundsV1,
  kChunkRef,
  kIndexBoxIds,
  kAllChunks,
  kReadChunk,
  kTotals,
  kSources,
  kScans,
  kLevelNextSeq,
  kLevelInsert,
  kLevelDeleteOfScan,
  kLevelScanDelete,
  kLevelScanInsert,
  kFindLevelChunks,
  kReadLevelChunk,
  kScanChunks,
  kScanBaseTotals,
  kPyramidTotals,
  kCount,
};

// Columns of a ChunkRef, in the order every chunk SELECT returns them.
// length(blob) comes from the record header: the blob's pages are not read.
constexpr std::string_view kRefColumns =
    "id, ix, iy, iz, seq, scan_id, min_x, min_y, min_z, max_x, max_y, max_z, "
    "input_points, decoded_points, length(blob)";
enum RefColumn : int {
  kColId,
  kColIx,
  kColIy,
  kColIz,
  kColSeq,
  kColScanId,
  kColMinX,
  kColMinY,
  kColMinZ,
  kColMaxX,
  kColMaxY,
  kColMaxZ,
  kColInputPoints,
  kColDecodedPoints,
  kColBlobSize,
  kRefColumnCount,
};
// read_chunk's extra columns, after the ChunkRef ones.
enum ReadColumn : int {
  kColCodec = kRefColumnCount,
  kColCodecParams,
  kColCrc32,
  kColBlob,
};

struct SqlText {
  const char* what;  // for error messages
  std::string sql;
};

SqlText sql_text(Sql id) {
  const std::string ref_columns(kRefColumns);
  // The R*Tree holds float bounds rounded outward, so it can only say "maybe";
  // the outer WHERE repeats the test on the exact doubles of relief_chunk.
  constexpr const char* kOverlap =
      "max_x >= ?1 AND min_x <= ?4 AND max_y >= ?2 AND min_y <= ?5 AND "
      "max_z >= ?3 AND min_z <= ?6";
  switch (id) {
    case Sql::kMetaGet:
      return {"read metadata", "SELECT value FROM relief_meta WHERE key = ?1"};
    case Sql::kMetaAll:
      return {"read metadata", "SELECT key, value FROM relief_meta"};
    case Sql::kMetaPut:
      return {"write metadata",
              "INSERT INTO relief_meta(key, value) VALUES(?1, ?2) "
              "ON CONFLICT(key) DO UPDATE SET value = excluded.value"};
    case Sql::kScanInsert:
      return {"insert scan",
              "INSERT INTO relief_scan(created_at, complete, has_rgb, has_intensity, crs) "
              "VALUES(?1, 0, ?2, ?3, ?4)"};
    case Sql::kScanExists:
      return {"find scan", "SELECT 1 FROM relief_scan WHERE id = ?1"};
    case Sql::kOtherScanExists:
      return {"find another scan", "SELECT 1 FROM relief_scan WHERE id <> ?1 LIMIT 1"};
    case Sql::kScanFinish:
      return {"finish scan",
              "UPDATE relief_scan SET complete = 1, has_rgb = ?2, has_intensity = ?3, crs = ?4 "
              "WHERE id = ?1"};
    case Sql::kScanSummary:
      return {"summarise scans",
              "SELECT COALESCE(MAX(has_rgb), 0), COALESCE(MAX(has_intensity), 0) "
              "FROM relief_scan"};
    case Sql::kScanFirstCrs:
      return {"summarise scans",
              "SELECT crs FROM relief_scan WHERE crs <> '' ORDER BY id LIMIT 1"};
    case Sql::kScanFirstCrsSource:
      return {"read the CRS source form",
              "SELECT crs FROM relief_source WHERE crs <> '' AND scan_id = "
              "(SELECT id FROM relief_scan WHERE crs <> '' ORDER BY id LIMIT 1) ORDER BY id LIMIT 1"};
    case Sql::kScanDelete:
      return {"delete scan", "DELETE FROM relief_scan WHERE id = ?1"};
    case Sql::kSourceInsert:
      return {"insert source",
              "INSERT INTO relief_source(scan_id, path, format, point_count, crs) "
              "VALUES(?1, ?2, ?3, ?4, ?5)"};
    case Sql::kSourceDeleteOfScan:
      return {"delete sources", "DELETE FROM relief_source WHERE scan_id = ?1"};
    case Sql::kSourceSetPoints:
      return {"record a source's points",
              "UPDATE relief_source SET point_count = ?2 WHERE scan_id = ?1 AND "
              "(SELECT count(*) FROM relief_source WHERE scan_id = ?1) = 1"};
    case Sql::kSourceLasInsert:
      return {"insert a LAS source record",
              "INSERT INTO relief_source_las(source_id, kind, user_id, record_id, description, data) "
              "VALUES(?1, ?2, ?3, ?4, ?5, ?6)"};
    case Sql::kSourceLasDeleteOfScan:
      return {"delete LAS source records",
              "DELETE FROM relief_source_las WHERE source_id IN (SELECT id FROM relief_source WHERE scan_id = ?1)"};
    case Sql::kSourceLasAll:
      return {"read LAS source records",
              "SELECT source_id, kind, user_id, record_id, description, data FROM relief_source_las ORDER BY rowid"};
    case Sql::kChunkNextSeq:
      // Served by the UNIQUE(ix, iy, iz, seq) index: one b-tree descent.
      return {"find next seq",
              "SELECT COALESCE(MAX(seq) + 1, 0) FROM relief_chunk "
              "WHERE ix = ?1 AND iy = ?2 AND iz = ?3"};
    case Sql::kChunkInsert:
      return {"insert chunk",
              "INSERT INTO relief_chunk(ix, iy, iz, seq, scan_id, min_x, min_y, min_z, "
              "max_x, max_y, max_z, input_points, decoded_points, codec, codec_params, crc32, "
              "blob) VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, "
              "?16, ?17)"};
    case Sql::kIndexInsert:
      return {"insert into the spatial index",
              "INSERT INTO relief_chunk_index(id, min_x, max_x, min_y, max_y, min_z, max_z) "
              "VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7)"};
    case Sql::kIndexDeleteOfScan:
      return {"delete from the spatial index",
              "DELETE FROM relief_chunk_index WHERE id IN "
              "(SELECT id FROM relief_chunk WHERE scan_id = ?1)"};
    case Sql::kChunkDeleteOfScan:
      return {"delete chunks", "DELETE FROM relief_chunk WHERE scan_id = ?1"};
    case Sql::kExtentInsert:
      return {"record a chunk's point bounds",
              "INSERT INTO relief_chunk_extent(id, min_x, min_y, min_z, max_x, max_y, max_z) "
              "VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7)"};
    case Sql::kExtentDeleteOfScan:
      return {"delete chunks' point bounds",
              "DELETE FROM relief_chunk_extent WHERE id IN (SELECT id FROM relief_chunk WHERE scan_id = ?1)"};
    case Sql::kExtentOfChunk:
      return {"read a chunk's point bounds",
              "SELECT min_x, min_y, min_z, max_x, max_y, max_z FROM relief_chunk_extent WHERE id = ?1"};
    case Sql::kPointBounds:
      // A chunk's own bounds where it has no usable extent row (none, or a
      // damaged one: not a box within the chunk's bounds, which read_chunk
      // and check report); extent rows of no chunk (left by a writer that
      // does not know the table) do not count.
      return {
          "sum chunks' point bounds",
          "SELECT MIN(IIF(ok, ex0, x0)), MIN(IIF(ok, ey0, y0)), MIN(IIF(ok, ez0, z0)), "
          "MAX(IIF(ok, ex1, x1)), MAX(IIF(ok, ey1, y1)), MAX(IIF(ok, ez1, z1)) FROM ("
          "SELECT c.min_x AS x0, c.min_y AS y0, c.min_z AS z0, c.max_x AS x1, c.max_y AS y1, c.max_z AS z1, "
          "e.min_x AS ex0, e.min_y AS ey0, e.min_z AS ez0, e.max_x AS ex1, e.max_y AS ey1, e.max_z AS ez1, "
          "COALESCE(e.min_x >= c.min_x AND e.min_y >= c.min_y AND e.min_z >= c.min_z AND "
          "e.max_x <= c.max_x AND e.max_y <= c.max_y AND e.max_z <= c.max_z AND e.min_x <= e.max_x AND "
          "e.min_y <= e.max_y AND e.min_z <= e.max_z, 0) AS ok "
          "FROM relief_chunk AS c LEFT JOIN relief_chunk_extent AS e ON e.id = c.id)"};
    case Sql::kFindChunks:
      // Every index entry the box hits, beside the chunk row it names (NULLs
      // when there is none): find_chunks checks one against the other.
      return {"find chunks",
              "SELECT c.id, c.ix, c.iy, c.iz, c.seq, c.scan_id, c.min_x, c.min_y, c.min_z, c.max_x, c.max_y, "
              "c.max_z, c.input_points, c.decoded_points, length(c.blob), r.id, r.min_x, r.max_x, r.min_y, "
              "r.max_y, r.min_z, r.max_z FROM relief_chunk_index AS r LEFT JOIN relief_chunk AS c ON c.id = r.id "
              "WHERE r.max_x >= ?1 AND r.min_x <= ?4 AND r.max_y >= ?2 AND r.min_y <= ?5 AND "
              "r.max_z >= ?3 AND r.min_z <= ?6"};
    case Sql::kFindIdsByBounds:
      // The same box through the exact bounds (version 2's covering index):
      // what the R*Tree must have found.
      return {"find chunks by their bounds", "SELECT id FROM relief_chunk INDEXED BY relief_chunk_bounds WHERE " +
                                                 std::string(kOverlap) + " ORDER BY id"};
    case Sql::kFindIdsByBoundsV1:
      // Version 1 has no bounds index: a scan of the chunk table.
      return {"find chunks by their bounds",
              "SELECT id FROM relief_chunk WHERE " + std::string(kOverlap) + " ORDER BY id"};
    case Sql::kChunkRef:
      return {"read chunk", "SELECT " + ref_columns + " FROM relief_chunk WHERE id = ?1"};
    case Sql::kIndexBoxIds:
      return {"query the spatial index", "SELECT id FROM relief_chunk_index WHERE " + std::string(kOverlap)};
    case Sql::kAllChunks:
      return {"list chunks", "SELECT " + ref_columns + " FROM relief_chunk ORDER BY id"};
    case Sql::kReadChunk:
      return {"read chunk", "SELECT " + ref_columns +
                                ", codec, codec_params, crc32, blob FROM relief_chunk "
                                "WHERE id = ?1"};
    case Sql::kTotals:
      return {"sum chunks",
              "SELECT COUNT(*), COALESCE(SUM(input_points), 0), COALESCE(SUM(decoded_points), 0), "
              "COALESCE(SUM(length(blob)), 0), MIN(min_x), MIN(min_y), MIN(min_z), MAX(max_x), "
              "MAX(max_y), MAX(max_z) FROM relief_chunk"};
    case Sql::kSources:
      return {"list sources",
              "SELECT path, format, point_count, crs, scan_id, id FROM relief_source ORDER BY id"};
    case Sql::kScans:
      return {"list scans", "SELECT id, complete, created_at FROM relief_scan ORDER BY id"};
    case Sql::kLevelNextSeq:
      return {"find next pyramid seq",
              "SELECT COALESCE(MAX(seq) + 1, 0) FROM relief_level_chunk "
              "WHERE level = ?1 AND ix = ?2 AND iy = ?3 AND iz = ?4"};
    case Sql::kLevelInsert:
      return {"insert pyramid node",
              "INSERT INTO relief_level_chunk(level, ix, iy, iz, seq, scan_id, min_x, min_y, min_z, "
              "max_x, max_y, max_z, input_points, decoded_points, codec, codec_params, crc32, blob) "
              "VALUES(?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17, ?18)"};
    case Sql::kLevelDeleteOfScan:
      return {"delete pyramid nodes", "DELETE FROM relief_level_chunk WHERE scan_id = ?1"};
    case Sql::kLevelScanDelete:
      return {"delete the pyramid record", "DELETE FROM relief_level_scan WHERE scan_id = ?1"};
    case Sql::kLevelScanInsert:
      return {"record the pyramid",
              "INSERT OR REPLACE INTO relief_level_scan(scan_id, levels) VALUES(?1, ?2)"};
    case Sql::kFindLevelChunks:
      // Only nodes of scans whose pyramid is finished and that still exist
      // (a writer that does not know the pyramid may have removed the scan).
      return {"find pyramid nodes",
              "SELECT " + ref_columns +
                  " FROM relief_level_chunk INDEXED BY relief_level_chunk_bounds WHERE level = ?7 AND " +
                  std::string(kOverlap) +
                  " AND scan_id IN (SELECT l.scan_id FROM relief_level_scan AS l JOIN relief_scan AS s ON "
                  "s.id = l.scan_id WHERE (l.levels >> ?7) & 1 = 1)"};  // sorted by the caller (content order)
    case Sql::kReadLevelChunk:
      return {"read pyramid node", "SELECT " + ref_columns +
                                       ", codec, codec_params, crc32, blob FROM relief_level_chunk "
                                       "WHERE id = ?1"};
    case Sql::kScanChunks:
      return {"list the chunks of a scan",
              "SELECT " + ref_columns + " FROM relief_chunk WHERE scan_id = ?1 ORDER BY id"};
    case Sql::kScanBaseTotals:
      return {"sum chunks per scan",
              "SELECT scan_id, COUNT(*), COALESCE(SUM(decoded_points), 0) FROM relief_chunk "
              "GROUP BY scan_id ORDER BY scan_id"};
    case Sql::kPyramidTotals:
      return {"sum pyramid levels",
              "SELECT c.scan_id, c.level, COUNT(*), COALESCE(SUM(c.decoded_points), 0), "
              "COALESCE(SUM(length(c.blob)), 0), l.levels FROM relief_level_chunk AS c "
              "JOIN relief_level_scan AS l ON l.scan_id = c.scan_id JOIN relief_scan AS s ON s.id = c.scan_id "
              "WHERE (l.levels >> c.level) & 1 = 1 GROUP BY c.scan_id, c.level ORDER BY c.scan_id, c.level"};
    case Sql::kCount:
      break;
  }
  return {"?", ""};
}

// Reads columns as a hostile file could fill them: SQLite's column types are
// advisory, so a crafted archive can put text where a count belongs. The first
// problem is kept and reported as a format error naming the row.
class RowReader {
 public:
  RowReader(const Statement& statement, const std::string& path, std::string row)
      : statement_(statement), path_(path), row_(std::move(row)) {}

  void rename_row(std::string row) { row_ = std::move(row); }

  std::int64_t integer(int column, const char* name, std::int64_t min, std::int64_t max) {
    if (statement_.column_type(column) != SQLITE_INTEGER) {
      fail(name, "is not an integer");
      return min;
    }
    const std::int64_t value = statement_.column_int64(column);
    if (value < min || value > max) {
      fail(name, "is out of range (" + std::to_string(value) + ")");
      return min;
    }
    return value;
  }

  // A REAL column that may be NULL; integers are accepted as numbers.
  std::optional<double> real_or_null(int column, const char* name) {
    const int type = statement_.column_type(column);
    if (type == SQLITE_NULL) return std::nullopt;
    if (type != SQLITE_FLOAT && type != SQLITE_INTEGER) {
      fail(name, "is not a number");
      return std::nullopt;
    }
    return statement_.column_double(column);
  }

  // Six REAL columns from `first` on (min x, y, z, max x, y, z), none NULL.
  Box3d box(int first, const char* name) {
    std::array<double, 6> v{};
    for (std::size_t i = 0; i < v.size(); ++i) {
      const std::optional<double> value = real_or_null(first + static_cast<int>(i), name);
      if (!value) fail(name, "is NULL");
      v[i] = value.value_or(0.0);
    }
    Box3d b;
    b.min = {v[0], v[1], v[2]};
    b.max = {v[3], v[4], v[5]};
    return b;
  }

  std::string text(int column, const char* name) {
    if (statement_.column_type(column) != SQLITE_TEXT) {
      fail(name, "is not text");
      return {};
    }
    return statement_.column_text(column);
  }

  void fail(const char* name, const std::string& problem) {
    if (error_.empty()) error_ = std::string("column ") + name + " " + problem;
  }

  Status status() const {
    if (error_.empty()) return Status::ok();
    return format_error(path_ + ": " + row_ + ": " + error_);
  }

 private:
  const Statement& statement_;
  const std::string& path_;
  std::string row_;
  std::string error_;
};

// Reads the ChunkRef columns (kRefColumns) of the current row.
Status read_ref(const Statement& statement, const std::string& path, ChunkRef& ref) {
  RowReader row(statement, path, "relief_chunk row");
  ref.id = row.integer(kColId, "id", kMinInt64, kMaxInt64);
  row.rename_row("chunk id " + std::to_string(ref.id));
  ref.key.ix = row.integer(kColIx, "ix", kMinInt64, kMaxInt64);
  ref.key.iy = row.integer(kColIy, "iy", kMinInt64, kMaxInt64);
  ref.key.iz = row.integer(kColIz, "iz", kMinInt64, kMaxInt64);
  ref.seq = static_cast<std::uint32_t>(row.integer(kColSeq, "seq", 0, kMaxUint32));
  ref.scan_id = row.integer(kColScanId, "scan_id", kMinInt64, kMaxInt64);
  ref.input_points = static_cast<std::uint64_t>(row.integer(kColInputPoints, "input_points", 0, kMaxInt64));
  ref.decoded_points =
      static_cast<std::uint64_t>(row.integer(kColDecodedPoints, "decoded_points", 0, kMaxInt64));
  ref.blob_size = static_cast<std::uint64_t>(row.integer(kColBlobSize, "blob", 0, kMaxInt64));

  constexpr std::array<const char*, 6> kBoundNames = {"min_x", "min_y", "min_z", "max_x", "max_y", "max_z"};
  std::array<std::optional<double>, 6> bounds;
  int present = 0;
  for (int i = 0; i < 6; ++i) {
    bounds[static_cast<std::size_t>(i)] =
        row.real_or_null(kColMinX + i, kBoundNames[static_cast<std::size_t>(i)]);
    if (bounds[static_cast<std::size_t>(i)]) ++present;
  }
  ref.bounds = Box3d{};
  if (present == 6) {
    ref.bounds.min = {*bounds[0], *bounds[1], *bounds[2]};
    ref.bounds.max = {*bounds[3], *bounds[4], *bounds[5]};
    if (!box_is_finite(ref.bounds) || ref.bounds.empty()) {
      row.fail("min_x..max_z", "do not form a finite box with min <= max");
    }
  } else if (present != 0) {
    row.fail("min_x..max_z", "are partly NULL (all six or none)");
  }
  return row.status();
}

// ---- Creating the file

void remove_database_files(const std::string& file) {
  std::error_code ignored;
  for (const char* suffix : {"", "-journal", "-wal", "-shm"}) fs::remove(file + suffix, ignored);
}

// Moves the finished temporary file to `path` without ever replacing a file
// that appeared there meanwhile (plain rename() would silently overwrite it).
Status move_into_place(const std::string& temp, const std::string& path) {
  const std::string exists = path + ": already exists (created by another process meanwhile)";
  const auto cannot_move = [&](int error) {
    return io_error(path + ": cannot move the new archive into place: " + std::strerror(error));
  };
#ifdef RENAME_NOREPLACE
  if (::renameat2(AT_FDCWD, temp.c_str(), AT_FDCWD, path.c_str(), RENAME_NOREPLACE) == 0) {
    return Status::ok();
  }
  const int rename_error = errno;
  if (rename_error == EEXIST) return io_error(exists);
  // EINVAL/ENOSYS/ENOTSUP: the file system cannot do it; try a hard link.
  if (rename_error != EINVAL && rename_error != ENOSYS && rename_error != ENOTSUP &&
      rename_error != EOPNOTSUPP) {
    return cannot_move(rename_error);
  }
#endif
  // link() also refuses an existing name.
  if (::link(temp.c_str(), path.c_str()) == 0) {
    ::unlink(temp.c_str());
    return Status::ok();
  }
  if (errno == EEXIST) return io_error(exists);
  // No hard links either (e.g. FAT, some network file systems): rename after
  // one more look, accepting a tiny race window there.
  std::error_code ec;
  if (fs::exists(fs::symlink_status(path, ec))) return io_error(exists);
  if (std::rename(temp.c_str(), path.c_str()) != 0) return cannot_move(errno);
  return Status::ok();
}

// A rename is only durable once the directory entry is on disk. Best effort:
// some file systems refuse fsync on a directory, and the archive is valid
// either way; only its name might not survive a power loss.
void sync_directory_of(const std::string& path) {
  fs::path directory = fs::path(path).parent_path();
  if (directory.empty()) directory = ".";
  const int fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return;
  ::fsync(fd);
  ::close(fd);
}

// Writes a complete, empty archive to `temp` and closes it.
Status write_new_archive(const std::string& temp, const std::string& path, const ArchiveGrid& grid,
                         const std::string& codec_params, const std::string& creator, std::uint32_t page_size) {
  RELIEF_ASSIGN_OR_RETURN(store::Connection connection,
                          store::open_connection(temp, SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, path,
                                                 "cannot create the archive (temporary file " + temp + ")"));
  sqlite3* db = connection.get();
  // Small pages keep the fixed cost of a small archive small: a dozen tables
  // and indexes take a page each, and every blob's last overflow page is on
  // average half empty (4 KiB pages: ~60 KB for an 8-chunk archive of a
  // 35 k-point scan). Blobs are read whole, so larger pages buy little. The
  // caller chooses (kArchivePageSize, or kSmallArchivePageSize for a small input).
  const std::string page_size_sql = "PRAGMA page_size = " + std::to_string(page_size);
  RELIEF_RETURN_IF_ERROR(store::exec(db, page_size_sql.c_str(), path, "set the page size"));
  {
    // The whole schema in one transaction in rollback-journal mode (the
    // default for a new file, synchronous = FULL): COMMIT leaves it on disk.
    Transaction transaction(db, path);
    RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kWrite));
    const std::string header = "PRAGMA application_id = " + std::to_string(kArchiveApplicationId) +
                               "; PRAGMA user_version = " + std::to_string(kArchiveFormatVersion) + ";";
    RELIEF_RETURN_IF_ERROR(store::exec(db, header.c_str(), path, "write the file header"));
    // Compact text: SQLite keeps every CREATE statement in the file as given.
    const std::string schema = store::compact_sql(store::kCreateSchemaSql);
    RELIEF_RETURN_IF_ERROR(store::exec(db, schema.c_str(), path, "create the schema"));
    const std::string bounds_index = store::compact_sql(store::kCreateBoundsIndexSql);
    RELIEF_RETURN_IF_ERROR(store::exec(db, bounds_index.c_str(), path, "create the schema"));

    const std::array<std::pair<const char*, std::string>, 10> meta = {{
        {store::kMetaFormatVersion, std::to_string(kArchiveFormatVersion)},
        {store::kMetaOriginX, format_double(grid.origin.x)},
        {store::kMetaOriginY, format_double(grid.origin.y)},
        {store::kMetaOriginZ, format_double(grid.origin.z)},
        {store::kMetaChunkEdge, format_double(grid.chunk_edge)},
        {store::kMetaCodecParams, codec_params},
        {store::kMetaCreator, creator},
        {store::kMetaCreatedAt, utc_now_iso8601()},
        {store::kMetaCrsChecksum, checksum_text(crs_checksum("", ""))},
        {store::kMetaAttributes, ""},
    }};
    const SqlText put = sql_text(Sql::kMetaPut);
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Statement> statement,
                            Statement::prepare(db, put.sql, path, put.what));
    for (const auto& [key, value] : meta) {
      StatementScope scope(*statement);
      statement->bind_text(1, key);
      statement->bind_text(2, value);
      RELIEF_RETURN_IF_ERROR(statement->run());
    }
    RELIEF_ASSIGN_OR_RETURN(const std::uint32_t checksum, compute_meta_checksum(db, path));
    {
      StatementScope scope(*statement);
      const std::string text = checksum_text(checksum);
      statement->bind_text(1, store::kMetaChecksum);
      statement->bind_text(2, text);
      RELIEF_RETURN_IF_ERROR(statement->run());
    }
    statement.reset();
    RELIEF_RETURN_IF_ERROR(transaction.commit());
  }
  // The file stays in rollback-journal mode: an archive at rest is one file
  // that readers open without creating anything beside it (section 8). A
  // writer switches to WAL while it writes. A failed close means the file may
  // be incomplete.
  RELIEF_RETURN_IF_ERROR(store::close_connection(std::move(connection), path));
  std::error_code ec;
  if (fs::exists(temp + "-journal", ec)) {
    return internal_error(path + ": creating: SQLite left a rollback journal beside " + temp);
  }
  return Status::ok();
}

// ---- Opening: identification (format-spec/archive.md, section 2)

// The last pyramid row committed (0: none).
constexpr const char* kLastLevelRowSql = "SELECT COALESCE(MAX(id), 0) FROM relief_level_chunk";

Result<std::int64_t> pragma_integer(sqlite3* db, const char* pragma, const std::string& path) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Statement> statement, Statement::prepare(db, pragma, path, pragma));
  StatementScope scope(*statement);
  RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
  if (!row) return internal_error(path + ": " + pragma + " returned nothing");
  return statement->column_int64(0);
}

// Returns the format version of a Relief archive, or why the file is not one
// this build can read. Nothing here writes to the file.
Result<int> identify(sqlite3* db, const std::string& path) {
  Result<std::int64_t> application_id = pragma_integer(db, "PRAGMA application_id", path);
  if (!application_id.is_ok()) {
    // SQLITE_NOTADB or SQLITE_CORRUPT while reading the header page.
    if (application_id.status().code() == StatusCode::kFormatError) {
      return format_error(path + ": not a Relief archive (not a SQLite database, or its header is damaged)");
    }
    return application_id.status();
  }
  if (*application_id != kArchiveApplicationId) {
    return format_error(path + ": not a Relief archive (SQLite application_id " +
                        hex32(static_cast<std::uint32_t>(*application_id)) + ", expected " +
                        hex32(static_cast<std::uint32_t>(kArchiveApplicationId)) + " \"RLIF\")");
  }
  RELIEF_ASSIGN_OR_RETURN(const std::int64_t version, pragma_integer(db, "PRAGMA user_version", path));
  if (version > kArchiveFormatVersion) {
    return unsupported(path + ": archive format version " + std::to_string(version) +
                       " is newer than this build supports (" + std::to_string(kArchiveFormatVersion) + ")");
  }
  if (version < 1) {
    return format_error(path + ": not a valid Relief archive: format version (user_version) " +
                        std::to_string(version) + " is invalid");
  }
  return static_cast<int>(version);
}

// ---- The archive

class CheckReport;

class SqliteArchive final : public Archive {
 public:
  SqliteArchive(std::string path, store::Connection connection, Mode mode, int format_version)
      : path_(std::move(path)),
        connection_(std::move(connection)),
        mode_(mode),
        format_version_(format_version) {}

  // A writer hands the file back in rollback-journal mode: one file again.
  ~SqliteArchive() override;

  // Checks the schema, metadata checksum and grid, then sets up a writer's
  // connection. With `verify_meta` false a bad checksum is left for the caller.
  Status initialise(bool verify_meta = true);
  int format_version() const { return format_version_; }
  // This handle made the file: a failed run removes the whole file, so no
  // room is kept for undoing it (check_room).
  void mark_created() { created_ = true; }
  sqlite3* connection() const { return connection_.get(); }
  Status verify_meta_checksum() const;
  // check_archive's chunk and index checks; damage goes to `report`.
  Status check_chunks(CheckReport& report, const ChunkRowCheck& row_check) const;
  // Empty, or how a row's bounds lie beyond its key's cube of the grid.
  std::string bounds_outside_key(const ChunkRef& ref) const;

  const std::string& path() const override { return path_; }
  Status close() override;
  Result<ArchiveInfo> info() const override;
  Result<std::int64_t> begin_scan(const std::vector<ArchiveSource>& sources,
                                  const ScanAttributes& attributes) override;
  Status put_chunks(std::vector<ChunkRow>& rows) override;
  Status finish_scan(std::int64_t scan_id, bool has_colors, bool has_intensity,
                     const std::string& crs) override;
  Status abort_scan(std::int64_t scan_id) override;
  Status set_source_points(std::int64_t scan_id, std::uint64_t points) override;
  Result<std::vector<ChunkRef>> find_chunks(const Box3d& box) const override;
  Result<std::vector<ChunkRef>> all_chunks() const override;
  Result<ChunkRow> read_chunk(std::int64_t id) const override;
  Result<std::vector<std::uint8_t>> read_chunk_head(std::int64_t id, std::size_t max_bytes) const override;
  Status put_level_chunks(int level, std::vector<ChunkRow>& rows) override;
  Status finish_pyramid(std::int64_t scan_id, std::uint64_t levels) override;
  Status remove_pyramid(std::int64_t scan_id) override;
  Result<std::vector<ChunkRef>> scan_chunks(std::int64_t scan_id) const override;
  Result<std::vector<ChunkRef>> find_level_chunks(int level, const Box3d& box) const override;
  Result<ChunkRow> read_level_chunk(std::int64_t id) const override;
  std::uint64_t blob_bytes_read() const override { return blob_bytes_read_.load(std::memory_order_relaxed); }

 private:
  sqlite3* db() const { return connection_.get(); }
  Result<Statement*> statement(Sql id) const;
  Status require_writable(const char* operation) const;
  Result<std::optional<std::string>> meta_value(const char* key) const;
  Status put_meta(const char* key, const std::string& value);
  // Adds a scan's LAS attributes to the archive's (ArchiveInfo::las_attributes).
  Status merge_las_meta(const ScanAttributes& attributes);
  Status read_las_meta(std::map<std::string, std::string>& meta, ArchiveInfo& info) const;
  Status write_meta_checksum();
  Status upgrade_to_current_version();
  Status check_room(const std::vector<ChunkRow>& rows) const;
  // The overflow pages `rows`' blobs take (counted one more each), and the
  // freelist trunk pages that list them when the rows are removed.
  std::uint64_t overflow_pages(const std::vector<ChunkRow>& rows) const;
  std::uint64_t trunk_pages(const std::vector<ChunkRow>& rows) const;
  Result<bool> scan_exists(std::int64_t scan_id);
  Status refresh_scan_summary();
  // The archive's CRS and its source form, from relief_scan and relief_source
  // (what relief_meta's crs and crs_source summarised up to version 2).
  Result<std::pair<std::string, std::string>> scans_crs() const;
  Result<std::vector<ChunkRef>> collect_refs(Statement& statement) const;
  // Whether the optional pyramid tables exist (asked of the file each time:
  // another writer may have created them since this handle opened).
  Result<bool> pyramid_tables_exist() const;
  Result<bool> table_exists(const char* name) const;
  Status insert_source_las(std::int64_t source_id, const LasSourceMetadata& las);
  // Attaches each relief_source_las row to its source (ids: relief_source.id of each).
  Status read_source_las(const std::vector<std::int64_t>& ids, std::vector<ArchiveSource>& sources) const;
  // Checks rows for put_chunks / put_level_chunks and computes their CRC-32s.
  Status check_rows(const std::vector<ChunkRow>& rows, const char* operation, std::vector<std::uint32_t>& checksums,
                    std::set<std::int64_t>& scan_ids) const;
  Status delete_pyramid_rows(std::int64_t scan_id);
  Result<bool> only_connection();
  Status remove_unused_level_rows(std::int64_t unused_up_to);
  Status read_pyramid(ArchiveInfo& info) const;
  Result<ChunkRow> read_row(Sql sql, std::int64_t id, const char* what) const;
  Result<Box3d> chunk_point_bounds(std::int64_t id, const Box3d& bounds, std::string* damage = nullptr) const;

  std::string path_;
  // Declared before the statements so that it is destroyed after them: a
  // connection closes cleanly only once its statements are finalised.
  store::Connection connection_;
  Mode mode_;
  int format_version_;
  bool wal_ = false;  // a writer switched the file to WAL (switched back on close)
  bool bounds_index_ = false;  // version 2: relief_chunk_bounds exists
  std::uint64_t page_size_ = 4096;     // read when opened for writing
  std::uint64_t rows_written_ = 0;     // by this handle: what an abort may have to remove
  std::uint64_t trunks_written_ = 0;   // freelist trunk pages removing those rows may write
  bool created_ = false;
  ArchiveGrid grid_;  // fixed at creation, read once on open
  mutable std::array<std::unique_ptr<Statement>, static_cast<std::size_t>(Sql::kCount)> statements_;
  // Atomic so another thread may read it while the owner reads chunks.
  mutable std::atomic<std::uint64_t> blob_bytes_read_{0};
  // Whether relief_chunk_extent exists, once looked up (it is never dropped).
  mutable std::optional<bool> extent_table_;
};

SqliteArchive::~SqliteArchive() {
  if (mode_ != Mode::kReadWrite || !wal_) return;
  // What close() does, errors ignored (a writer that reports success has
  // called close() and seen them). Statements first: the journal mode
  // changes only on a connection without pending statements. A passive
  // checkpoint copies the WAL into the file as far as readers allow, without
  // waiting for them; the switch to rollback mode then finishes that and
  // deletes the -wal and -shm files. The switch needs exclusive access and
  // fails harmlessly while a reader is connected: the file stays in WAL
  // mode, valid, its content in the file as far as the checkpoint got, until
  // a writer closes alone.
  for (std::unique_ptr<Statement>& statement : statements_) statement.reset();
  sqlite3_wal_checkpoint_v2(db(), nullptr, SQLITE_CHECKPOINT_PASSIVE, nullptr, nullptr);
  sqlite3_exec(db(), "PRAGMA journal_mode = DELETE", nullptr, nullptr, nullptr);
}

}  // namespace

std::string kept_in_wal_note(const std::string& path) {
  return "; the archive is intact, but its last writes stay in " + path +
         "-wal, which must stay beside it until 'relief check --fold-log " + path +
         "' (or any Relief writer) folds it in with room on the disk";
}

namespace {

Status SqliteArchive::close() {
  if (mode_ != Mode::kReadWrite || !wal_) return Status::ok();
  for (std::unique_ptr<Statement>& statement : statements_) statement.reset();
  // Busy or locked: another connection holds the file (a reader); it stays
  // in WAL mode, valid, until a writer closes alone (see the destructor).
  const auto held_by_another = [](int rc) { return (rc & 0xff) == SQLITE_BUSY || (rc & 0xff) == SQLITE_LOCKED; };
  const auto kept_in_wal = [&](int rc) {
    return io_error(
        store::sqlite_error(db(), rc, path_, "cannot fold the write-ahead log into the archive file").message());
  };
  int rc = sqlite3_wal_checkpoint_v2(db(), nullptr, SQLITE_CHECKPOINT_PASSIVE, nullptr, nullptr);
  if (rc != SQLITE_OK && !held_by_another(rc)) return kept_in_wal(rc);
  rc = sqlite3_exec(db(), "PRAGMA journal_mode = DELETE", nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK && !held_by_another(rc)) return kept_in_wal(rc);
  wal_ = false;
  return Status::ok();
}

Result<Statement*> SqliteArchive::statement(Sql id) const {
  std::unique_ptr<Statement>& slot = statements_[static_cast<std::size_t>(id)];
  if (!slot) {
    SqlText text = sql_text(id);
    RELIEF_ASSIGN_OR_RETURN(slot, Statement::prepare(db(), text.sql, path_, text.what));
  }
  return slot.get();
}

Status SqliteArchive::require_writable(const char* operation) const {
  if (mode_ == Mode::kReadWrite) return Status::ok();
  return invalid_argument(path_ + ": " + operation + ": the archive was opened read-only");
}

Result<std::optional<std::string>> SqliteArchive::meta_value(const char* key) const {
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kMetaGet));
  StatementScope scope(*statement);
  statement->bind_text(1, key);
  RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
  if (!row) return std::optional<std::string>();
  if (statement->column_type(0) != SQLITE_TEXT) {
    return format_error(path_ + ": metadata " + key + " is not text");
  }
  return std::optional<std::string>(statement->column_text(0));
}

Status SqliteArchive::put_meta(const char* key, const std::string& value) {
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kMetaPut));
  StatementScope scope(*statement);
  statement->bind_text(1, key);
  statement->bind_text(2, value);
  return statement->run();
}

Status SqliteArchive::write_meta_checksum() {
  RELIEF_ASSIGN_OR_RETURN(const std::uint32_t checksum, compute_meta_checksum(db(), path_));
  return put_meta(store::kMetaChecksum, checksum_text(checksum));
}

Status SqliteArchive::verify_meta_checksum() const {
  // One snapshot: a writer rewrites rows and checksum in one transaction.
  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kRead));
  RELIEF_ASSIGN_OR_RETURN(const std::optional<std::string> stored, meta_value(store::kMetaChecksum));
  if (!stored) {
    return corrupt_data(path_ + ": the metadata checksum (relief_meta " + store::kMetaChecksum +
                        ") is missing: the metadata is damaged");
  }
  RELIEF_ASSIGN_OR_RETURN(const std::uint32_t computed, compute_meta_checksum(db(), path_));
  if (*stored != checksum_text(computed)) {
    return corrupt_data(path_ + ": metadata checksum mismatch (stored " + *stored + ", computed " +
                        checksum_text(computed) + "): the metadata (relief_meta) is damaged");
  }
  return transaction.commit();
}

// Version 1 lacks the bounds index and the metadata checksum, and versions 1
// and 2 copy the CRS texts into relief_meta where version 3 keeps their
// checksum; everything else is the same, so a writer adds the index, drops
// the copies, writes both checksums and moves the version, in one
// transaction (format-spec/archive.md, section 1).
Status SqliteArchive::upgrade_to_current_version() {
  static constexpr char kWhat[] = "upgrade to format version 3";
  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kWrite));
  RELIEF_RETURN_IF_ERROR(store::exec(db(), store::kCreateBoundsIndexSql, path_, kWhat));
  // A scan that began before version 2 recorded its CRS only when it
  // finished, so a killed one may have none: when no scan names the CRS the
  // metadata names, the earliest scan and its first source take it.
  RELIEF_ASSIGN_OR_RETURN(const std::optional<std::string> meta_crs, meta_value(store::kMetaCrs));
  RELIEF_ASSIGN_OR_RETURN(const std::optional<std::string> meta_source, meta_value(store::kMetaCrsSource));
  RELIEF_ASSIGN_OR_RETURN(const auto scans, scans_crs());
  if (scans.first.empty() && meta_crs && !meta_crs->empty()) {
    const char* const moves[2][2] = {
        {"UPDATE relief_scan SET crs = ?1 WHERE id = (SELECT MIN(id) FROM relief_scan)", "move the CRS to its scan"},
        {"UPDATE relief_source SET crs = ?1 WHERE crs = '' AND id = (SELECT MIN(id) FROM relief_source WHERE "
         "scan_id = (SELECT MIN(id) FROM relief_scan))",
         "move the CRS source form to its source"}};
    const std::string* const values[2] = {&*meta_crs, meta_source ? &*meta_source : nullptr};
    for (int k = 0; k < 2; ++k) {
      if (values[k] == nullptr || values[k]->empty()) continue;
      RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Statement> move, Statement::prepare(db(), moves[k][0], path_, moves[k][1]));
      StatementScope scope(*move);
      move->bind_text(1, *values[k]);
      RELIEF_RETURN_IF_ERROR(move->run());
    }
  }
  RELIEF_RETURN_IF_ERROR(store::exec(db(), "DELETE FROM relief_meta WHERE key IN ('crs', 'crs_source')", path_, kWhat));
  RELIEF_ASSIGN_OR_RETURN(const auto crs, scans_crs());
  RELIEF_RETURN_IF_ERROR(put_meta(store::kMetaCrsChecksum, checksum_text(crs_checksum(crs.first, crs.second))));
  RELIEF_RETURN_IF_ERROR(put_meta(store::kMetaFormatVersion, std::to_string(kArchiveFormatVersion)));
  RELIEF_RETURN_IF_ERROR(write_meta_checksum());
  const std::string version = "PRAGMA user_version = " + std::to_string(kArchiveFormatVersion);
  RELIEF_RETURN_IF_ERROR(store::exec(db(), version.c_str(), path_, kWhat));
  RELIEF_RETURN_IF_ERROR(transaction.commit());
  format_version_ = kArchiveFormatVersion;
  return Status::ok();
}

Status SqliteArchive::initialise(bool verify_meta) {
  {
    RELIEF_ASSIGN_OR_RETURN(
        std::unique_ptr<Statement> table,
        Statement::prepare(db(), "SELECT 1 FROM sqlite_master WHERE type = 'table' AND name = ?1", path_,
                           "read the schema"));
    for (std::string_view name : store::kRequiredTables) {
      StatementScope scope(*table);
      table->bind_text(1, name);
      RELIEF_ASSIGN_OR_RETURN(const bool found, table->step());
      if (!found) {
        return format_error(path_ + ": not a valid Relief archive: table " + std::string(name) +
                            " is missing");
      }
    }
  }
  if (format_version_ >= 2) {
    RELIEF_ASSIGN_OR_RETURN(
        std::unique_ptr<Statement> index,
        Statement::prepare(db(), "SELECT 1 FROM sqlite_master WHERE type = 'index' AND name = ?1", path_,
                           "read the schema"));
    StatementScope scope(*index);
    index->bind_text(1, store::kBoundsIndex);
    RELIEF_ASSIGN_OR_RETURN(const bool found, index->step());
    if (!found) {
      return format_error(path_ + ": not a valid Relief archive: index " + store::kBoundsIndex + " is missing");
    }
    bounds_index_ = true;
    if (verify_meta) RELIEF_RETURN_IF_ERROR(verify_meta_checksum());
  }

  const std::array<std::pair<const char*, double*>, 4> grid_keys = {{
      {store::kMetaOriginX, &grid_.origin.x},
      {store::kMetaOriginY, &grid_.origin.y},
      {store::kMetaOriginZ, &grid_.origin.z},
      {store::kMetaChunkEdge, &grid_.chunk_edge},
  }};
  for (const auto& [key, target] : grid_keys) {
    RELIEF_ASSIGN_OR_RETURN(const std::optional<std::string> text, meta_value(key));
    if (!text) return format_error(path_ + ": not a valid Relief archive: metadata " + key + " is missing");
    const std::optional<double> value = parse_double(*text);
    if (!value) {
      return format_error(path_ + ": metadata " + key + " is not a finite number: '" + *text + "'");
    }
    *target = *value;
  }
  if (!(grid_.chunk_edge > 0)) {
    return format_error(path_ + ": metadata chunk_edge must be > 0, got " + format_double(grid_.chunk_edge));
  }
  if (mode_ == Mode::kReadWrite) {
    // Pyramid rows that no reader uses, left by a run killed while building
    // a pyramid, may go only while no other connection is building one
    // (format-spec/archive.md §9): the rows up to the last one committed
    // now, when this connection then proves to be the only one.
    RELIEF_ASSIGN_OR_RETURN(const bool pyramid, pyramid_tables_exist());
    std::int64_t unused_up_to = 0;
    if (pyramid) {
      RELIEF_ASSIGN_OR_RETURN(const std::int64_t last, pragma_integer(db(), kLastLevelRowSql, path_));
      RELIEF_ASSIGN_OR_RETURN(const bool alone, only_connection());
      if (alone) unused_up_to = last;
    }
    // WAL while writing: readers never block the appending writer, nor it
    // them. The destructor switches the file back to rollback mode.
    std::string journal_mode;
    {
      RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Statement> journal,
                              Statement::prepare(db(), "PRAGMA journal_mode = WAL", path_, "switch to WAL"));
      StatementScope scope(*journal);
      RELIEF_ASSIGN_OR_RETURN(const bool row, journal->step());
      if (row) journal_mode = journal->column_text(0);
    }
    if (journal_mode != "wal") {
      return io_error(path_ + ": cannot use WAL journal mode (got '" + journal_mode +
                      "'); the archive needs a local file system with shared memory");
    }
    wal_ = true;
    // NORMAL in WAL mode: a commit survives a crash of the process at once
    // and a power loss from the next checkpoint on; never corrupts the file.
    // secure_delete off (Debian's SQLite has it on): removing what a failed
    // append added then frees its pages without rewriting each one, so the
    // undo fits the room check_room keeps on a full disk.
    RELIEF_RETURN_IF_ERROR(store::exec(db(),
                                       "PRAGMA synchronous = NORMAL; PRAGMA foreign_keys = ON; "
                                       "PRAGMA secure_delete = OFF",
                                       path_, "configure the connection"));
    if (format_version_ < kArchiveFormatVersion) {
      RELIEF_RETURN_IF_ERROR(upgrade_to_current_version());
      bounds_index_ = true;
    }
    RELIEF_ASSIGN_OR_RETURN(const std::int64_t page_size, pragma_integer(db(), "PRAGMA page_size", path_));
    if (page_size >= 512) page_size_ = static_cast<std::uint64_t>(page_size);
    if (pyramid) RELIEF_RETURN_IF_ERROR(remove_unused_level_rows(unused_up_to));
  }
  return Status::ok();
}

// A Relief writer keeps the file in WAL mode while it is open, and a
// connection to a file in WAL mode holds a shared lock on it until it closes;
// leaving WAL mode needs an exclusive lock, which SQLite refuses at once
// (SQLITE_BUSY, no busy wait) while any other connection is open. So when the
// switch to rollback mode succeeds, or the file is in rollback mode already
// (no writer has it open), no other connection was open at that moment.
Result<bool> SqliteArchive::only_connection() {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Statement> journal,
                          Statement::prepare(db(), "PRAGMA journal_mode = DELETE", path_, "leave WAL mode"));
  StatementScope scope(*journal);
  const Result<bool> row = journal->step();
  return row.is_ok() && *row && journal->column_text(0) == "delete";
}

// Pyramid rows no reader uses (format-spec/archive.md §9): rows and records
// of scans that no longer exist (always: no writer can finish a pyramid for
// them), and rows with ids up to `unused_up_to` (0: none) of scans without a
// record or of levels their record does not name. A pyramid being built has
// rows and no record yet; it is safe here because every row up to that id
// was committed before a moment when this connection was the only one, so
// its writer had closed (killed, or it removes its rows on failure) or
// finished (its record is there).
Status SqliteArchive::remove_unused_level_rows(std::int64_t unused_up_to) {
  const std::string unused_rows =
      " FROM relief_level_chunk AS c WHERE NOT EXISTS (SELECT 1 FROM relief_scan AS s WHERE s.id = "
      "c.scan_id) OR (c.id <= " + std::to_string(unused_up_to) +
      " AND NOT EXISTS (SELECT 1 FROM relief_level_scan AS l WHERE l.scan_id = c.scan_id AND "
      "(l.levels >> c.level) & 1 = 1))";
  const std::string stale_records =
      " FROM relief_level_scan AS l WHERE NOT EXISTS (SELECT 1 FROM relief_scan AS s WHERE s.id = l.scan_id)";
  // Most opens find nothing: look before taking the write lock.
  for (const std::string& where : {unused_rows, stale_records}) {
    const std::string count_sql = "SELECT COUNT(*)" + where;
    RELIEF_ASSIGN_OR_RETURN(const std::int64_t count, pragma_integer(db(), count_sql.c_str(), path_));
    if (count == 0) continue;
    Transaction transaction(db(), path_);
    RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kWrite));
    // Records first, as everywhere (§9).
    const std::string records_sql = "DELETE" + stale_records;
    const std::string rows_sql = "DELETE FROM relief_level_chunk WHERE id IN (SELECT c.id" + unused_rows + ")";
    RELIEF_RETURN_IF_ERROR(store::exec(db(), records_sql.c_str(), path_, "remove unused pyramid records"));
    RELIEF_RETURN_IF_ERROR(store::exec(db(), rows_sql.c_str(), path_, "remove unused pyramid rows"));
    return transaction.commit();
  }
  return Status::ok();
}

Result<bool> SqliteArchive::scan_exists(std::int64_t scan_id) {
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kScanExists));
  StatementScope scope(*statement);
  statement->bind_int64(1, scan_id);
  return statement->step();
}

// relief_meta's crs and attributes summarise every scan, complete or not (a
// scan records its attributes when it begins, so the chunks of a killed run
// decode like the others); they are rewritten in the same transaction as
// every change of relief_scan, so a killed process cannot leave them stale.
Status SqliteArchive::refresh_scan_summary() {
  std::string attributes;
  {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kScanSummary));
    StatementScope scope(*statement);
    RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
    if (row && statement->column_int64(0) != 0) attributes = store::kAttributeRgb;
    if (row && statement->column_int64(1) != 0) {
      if (!attributes.empty()) attributes += ",";
      attributes += store::kAttributeIntensity;
    }
  }
  RELIEF_ASSIGN_OR_RETURN(const auto crs, scans_crs());
  RELIEF_RETURN_IF_ERROR(put_meta(store::kMetaAttributes, attributes));
  // Version 3 keeps the CRS texts in their rows alone and their checksum
  // here (a writer has upgraded the file before it changes anything).
  RELIEF_RETURN_IF_ERROR(put_meta(store::kMetaCrsChecksum, checksum_text(crs_checksum(crs.first, crs.second))));
  return write_meta_checksum();
}

Result<std::pair<std::string, std::string>> SqliteArchive::scans_crs() const {
  std::pair<std::string, std::string> crs;
  {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kScanFirstCrs));
    StatementScope scope(*statement);
    RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
    if (row) crs.first = statement->column_text(0);
  }
  if (!crs.first.empty()) {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kScanFirstCrsSource));
    StatementScope scope(*statement);
    RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
    if (row) crs.second = statement->column_text(0);
  }
  return crs;
}

// The archive's LAS attributes are the union over its scans, kept in
// relief_meta as each scan begins (an aborted scan may leave the set larger:
// the extra attributes then read as 0). Extra bytes must be the same
// (ingest refuses different ones before it gets here).
Status SqliteArchive::merge_las_meta(const ScanAttributes& a) {
  if (a.las_attributes == 0 && a.las_point_format < 0) return Status::ok();
  const auto number = [&](const char* key, long long fallback) -> Result<long long> {
    RELIEF_ASSIGN_OR_RETURN(std::optional<std::string> v, meta_value(key));
    if (!v || v->empty()) return fallback;
    char* end = nullptr;
    const long long n = std::strtoll(v->c_str(), &end, 10);
    if (end == v->c_str() || *end != '\0') return format_error(path_ + ": metadata " + key + " is not a number");
    return n;
  };
  RELIEF_ASSIGN_OR_RETURN(std::optional<std::string> names, meta_value(store::kMetaLasAttributes));
  const std::uint32_t old_bits = names ? las_attributes_from_list(*names) : 0;
  RELIEF_ASSIGN_OR_RETURN(const long long old_format, number(store::kMetaLasPointFormat, -1));
  RELIEF_ASSIGN_OR_RETURN(const long long old_minor, number(store::kMetaLasVersionMinor, -1));
  RELIEF_ASSIGN_OR_RETURN(const long long old_size, number(store::kMetaLasExtraBytesSize, 0));
  RELIEF_ASSIGN_OR_RETURN(const long long old_8bit, number(store::kMetaLasColors8bit, 0));
  RELIEF_ASSIGN_OR_RETURN(std::optional<std::string> old_vlr, meta_value(store::kMetaLasExtraBytesVlr));
  RELIEF_ASSIGN_OR_RETURN(std::optional<std::string> old_time, meta_value(store::kMetaLasGpsTimeType));
  const GpsTimeType old_time_type = parse_gps_time_type(old_time.value_or(""));
  if (old_time_type != GpsTimeType::kUnknown && a.las_gps_time_type != GpsTimeType::kUnknown &&
      old_time_type != a.las_gps_time_type) {
    return invalid_argument(path_ + ": the archive's GPS times are " + gps_time_type_name(old_time_type) +
                            " time but the new scan's are " + gps_time_type_name(a.las_gps_time_type) +
                            " time; one archive holds one kind");
  }
  const bool old_extra = (old_bits & kLasExtraBytes) != 0;
  const bool new_extra = (a.las_attributes & kLasExtraBytes) != 0;
  const std::string vlr_hex = hex_lower(a.extra_bytes_vlr);
  if (old_extra && new_extra && (old_size != a.extra_bytes_size || old_vlr.value_or("") != vlr_hex)) {
    return invalid_argument(path_ + ": the archive's extra bytes (" + std::to_string(old_size) +
                            " per point) differ from the new scan's (" + std::to_string(a.extra_bytes_size) +
                            "), or their Extra Bytes VLRs differ");
  }
  // Colour levels: 8-bit only while every LAS source with colours said so.
  const bool old_rgb = (old_bits & kLasColorLow) != 0;
  const bool new_rgb = (a.las_attributes & kLasColorLow) != 0;
  const bool colors_8bit = old_rgb && new_rgb ? (old_8bit != 0 && a.las_colors_8bit)
                                              : old_rgb ? old_8bit != 0 : a.las_colors_8bit;
  RELIEF_RETURN_IF_ERROR(put_meta(store::kMetaLasAttributes, las_attribute_list(old_bits | a.las_attributes)));
  RELIEF_RETURN_IF_ERROR(
      put_meta(store::kMetaLasPointFormat, std::to_string(std::max<long long>(old_format, a.las_point_format))));
  RELIEF_RETURN_IF_ERROR(
      put_meta(store::kMetaLasVersionMinor, std::to_string(std::max<long long>(old_minor, a.las_version_minor))));
  if (new_extra && !old_extra) {
    RELIEF_RETURN_IF_ERROR(put_meta(store::kMetaLasExtraBytesSize, std::to_string(a.extra_bytes_size)));
    RELIEF_RETURN_IF_ERROR(put_meta(store::kMetaLasExtraBytesVlr, vlr_hex));
  }
  if (old_time_type == GpsTimeType::kUnknown && a.las_gps_time_type != GpsTimeType::kUnknown) {
    RELIEF_RETURN_IF_ERROR(put_meta(store::kMetaLasGpsTimeType, gps_time_type_name(a.las_gps_time_type)));
  }
  return put_meta(store::kMetaLasColors8bit, colors_8bit ? "1" : "0");
}

Result<std::int64_t> SqliteArchive::begin_scan(const std::vector<ArchiveSource>& sources,
                                               const ScanAttributes& attributes) {
  RELIEF_RETURN_IF_ERROR(require_writable("begin_scan"));
  for (const ArchiveSource& source : sources) {
    if (source.point_count > kMaxStoredCount) {
      return invalid_argument(path_ + ": begin_scan: source " + source.path +
                              " has too many points to record (" + std::to_string(source.point_count) + ")");
    }
    if (const std::string problem = las_metadata_problem(source.las); !problem.empty()) {
      return invalid_argument(path_ + ": begin_scan: source " + source.path + ": " + problem);
    }
  }
  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kWrite));
  const std::string created_at = utc_now_iso8601();
  {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kScanInsert));
    StatementScope scope(*statement);
    statement->bind_text(1, created_at);
    statement->bind_int64(2, attributes.has_colors ? 1 : 0);
    statement->bind_int64(3, attributes.has_intensity ? 1 : 0);
    statement->bind_text(4, attributes.crs);
    RELIEF_RETURN_IF_ERROR(statement->run());
  }
  const std::int64_t scan_id = sqlite3_last_insert_rowid(db());
  {
    // A second scan: from now on one scan's chunks are some of the rows.
    RELIEF_ASSIGN_OR_RETURN(Statement * others, statement(Sql::kOtherScanExists));
    StatementScope scope(*others);
    others->bind_int64(1, scan_id);
    RELIEF_ASSIGN_OR_RETURN(const bool another, others->step());
    if (another) {
      RELIEF_RETURN_IF_ERROR(
          store::exec(db(), store::kCreateChunkScanIndexSql, path_, "create the index of chunks by scan"));
    }
  }
  if (std::any_of(sources.begin(), sources.end(), [](const ArchiveSource& s) { return !s.las.empty(); })) {
    RELIEF_RETURN_IF_ERROR(store::exec(db(), store::compact_sql(store::kCreateSourceLasSql).c_str(), path_,
                                       "create the LAS source table"));
  }
  RELIEF_ASSIGN_OR_RETURN(Statement * insert, statement(Sql::kSourceInsert));
  for (const ArchiveSource& source : sources) {
    {
      StatementScope scope(*insert);
      insert->bind_int64(1, scan_id);
      insert->bind_text(2, source.path);
      insert->bind_text(3, source.format);
      insert->bind_int64(4, static_cast<std::int64_t>(source.point_count));
      insert->bind_text(5, source.crs);
      RELIEF_RETURN_IF_ERROR(insert->run());
    }
    if (!source.las.empty()) RELIEF_RETURN_IF_ERROR(insert_source_las(sqlite3_last_insert_rowid(db()), source.las));
  }
  RELIEF_RETURN_IF_ERROR(merge_las_meta(attributes));
  RELIEF_RETURN_IF_ERROR(refresh_scan_summary());
  RELIEF_RETURN_IF_ERROR(transaction.commit());
  return scan_id;
}

std::uint64_t SqliteArchive::overflow_pages(const std::vector<ChunkRow>& rows) const {
  const std::uint64_t overflow_page = page_size_ - 4;  // 4 bytes link the overflow chain
  std::uint64_t pages = 0;
  for (const ChunkRow& row : rows) pages += row.blob.size() / overflow_page + 1;
  return pages;
}

std::uint64_t SqliteArchive::trunk_pages(const std::vector<ChunkRow>& rows) const {
  const std::uint64_t per_trunk = page_size_ / 4 - 2;
  return overflow_pages(rows) / per_trunk + 1;
}

Status SqliteArchive::check_room(const std::vector<ChunkRow>& rows) const {
  if (created_) return Status::ok();
  const std::uint64_t frame = page_size_ + kWalFrameHeader;
  const std::uint64_t need = kFixedFrames + overflow_pages(rows) + kFramesPerRow * rows.size();
  const std::uint64_t reserve =
      kFixedFrames + kFramesPerRow * (rows_written_ + rows.size()) + trunks_written_ + trunk_pages(rows);
  // Twice the batch: the WAL takes it, and the checkpoint that follows its
  // commit writes the same pages into the archive file while the WAL keeps
  // its size (a 13 MB disk took an 11 MB WAL and a 2.4 MB file, and the
  // commit failed with the check passed).
  const std::uint64_t wanted = (2 * need + reserve) * frame;
  const std::uint64_t room = wal_room(path_);
  if (wanted <= room) return Status::ok();
  return io_error(path_ + ": the disk is full: adding " + std::to_string(rows.size()) + " chunks needs " +
                  megabytes(2 * need * frame) + " (the log and the file) and undoing this run " +
                  megabytes(reserve * frame) + ", but only " + megabytes(room) + " can still be written");
}

// Binds a chunk row's columns, ix .. blob in the order of relief_chunk (and
// of relief_level_chunk after its level), from parameter `first` on.
void bind_row_columns(Statement& insert, int first, const ChunkRow& row, std::int64_t seq, std::uint32_t crc) {
  const ChunkRef& ref = row.ref;
  int c = first;
  insert.bind_int64(c++, ref.key.ix);
  insert.bind_int64(c++, ref.key.iy);
  insert.bind_int64(c++, ref.key.iz);
  insert.bind_int64(c++, seq);
  insert.bind_int64(c++, ref.scan_id);
  const bool has_bounds = !ref.bounds.empty();
  for (const double v : {ref.bounds.min.x, ref.bounds.min.y, ref.bounds.min.z, ref.bounds.max.x, ref.bounds.max.y,
                         ref.bounds.max.z}) {
    if (has_bounds) {
      insert.bind_double(c++, v);
    } else {
      insert.bind_null(c++);
    }
  }
  insert.bind_int64(c++, static_cast<std::int64_t>(ref.input_points));
  insert.bind_int64(c++, static_cast<std::int64_t>(ref.decoded_points));
  insert.bind_int64(c++, static_cast<std::int64_t>(row.codec));
  insert.bind_text(c++, row.codec_params);
  insert.bind_int64(c++, static_cast<std::int64_t>(crc));
  insert.bind_blob(c, row.blob.data(), row.blob.size());
}

Status SqliteArchive::check_rows(const std::vector<ChunkRow>& rows, const char* operation,
                                 std::vector<std::uint32_t>& checksums, std::set<std::int64_t>& scan_ids) const {
  checksums.resize(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const ChunkRow& row = rows[i];
    const ChunkRef& ref = row.ref;
    const std::string which =
        path_ + ": " + operation + ": row " + std::to_string(i) + ", chunk " + key_text(ref.key) + ": ";
    if (box_has_nan(ref.bounds)) return invalid_argument(which + "bounds contain NaN");
    if (ref.bounds.empty()) {
      if (ref.decoded_points != 0) {
        return invalid_argument(which + std::to_string(ref.decoded_points) +
                                " decoded points but empty bounds");
      }
    } else {
      if (!box_is_finite(ref.bounds)) return invalid_argument(which + "bounds are not finite");
      if (ref.decoded_points == 0) {
        return invalid_argument(which + "bounds given for a chunk without decoded points");
      }
    }
    if (ref.input_points > kMaxStoredCount || ref.decoded_points > kMaxStoredCount) {
      return invalid_argument(which + "point counts too large to store");
    }
    const Box3d& e = ref.point_bounds;
    if (box_has_nan(e)) return invalid_argument(which + "point bounds contain NaN");
    if (!e.empty() && (ref.bounds.empty() || !box_is_finite(e) || !ref.bounds.contains(e))) {
      return invalid_argument(which + "point bounds are not finite or not within the chunk's bounds");
    }
    checksums[i] = blob_crc32(row.blob);
    scan_ids.insert(ref.scan_id);
  }
  return Status::ok();
}

Status SqliteArchive::put_chunks(std::vector<ChunkRow>& rows) {
  RELIEF_RETURN_IF_ERROR(require_writable("put_chunks"));
  if (rows.empty()) return Status::ok();

  // Everything that can be checked without the file is checked before the
  // write lock is taken, and so are the checksums (the slow part).
  std::vector<std::uint32_t> checksums;
  std::set<std::int64_t> scan_ids;
  RELIEF_RETURN_IF_ERROR(check_rows(rows, "put_chunks", checksums, scan_ids));

  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kWrite));
  RELIEF_RETURN_IF_ERROR(check_room(rows));
  for (const std::int64_t scan_id : scan_ids) {
    RELIEF_ASSIGN_OR_RETURN(const bool exists, scan_exists(scan_id));
    if (!exists) {
      return invalid_argument(path_ + ": put_chunks: no scan with id " + std::to_string(scan_id) +
                              " (begin_scan makes one)");
    }
  }

  RELIEF_ASSIGN_OR_RETURN(Statement * next_seq, statement(Sql::kChunkNextSeq));
  RELIEF_ASSIGN_OR_RETURN(Statement * insert, statement(Sql::kChunkInsert));
  RELIEF_ASSIGN_OR_RETURN(Statement * index, statement(Sql::kIndexInsert));
  // Point bounds narrower than a row's go to relief_chunk_extent, created by
  // the first write that has some (a resampling archive never has any).
  Statement* extent = nullptr;
  if (std::any_of(rows.begin(), rows.end(), [](const ChunkRow& r) { return !r.ref.point_bounds.empty(); })) {
    RELIEF_RETURN_IF_ERROR(store::exec(db(), store::compact_sql(store::kCreateExtentSql).c_str(), path_,
                                       "create the point bounds table"));
    extent_table_.reset();  // looked up again after this transaction, whatever its fate
    RELIEF_ASSIGN_OR_RETURN(extent, statement(Sql::kExtentInsert));
  }
  // Written back only after COMMIT: on failure the caller's rows are untouched.
  std::vector<std::pair<std::int64_t, std::uint32_t>> assigned(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const ChunkRow& row = rows[i];
    const ChunkRef& ref = row.ref;
    const std::string which = "(chunk " + key_text(ref.key) + ")";

    std::int64_t seq = 0;
    {
      StatementScope scope(*next_seq);
      next_seq->bind_int64(1, ref.key.ix);
      next_seq->bind_int64(2, ref.key.iy);
      next_seq->bind_int64(3, ref.key.iz);
      RELIEF_ASSIGN_OR_RETURN(const bool found, next_seq->step());
      if (found) seq = next_seq->column_int64(0);
    }
    if (seq < 0 || seq > kMaxUint32) {
      return limit_exceeded(path_ + ": put_chunks: voxel " + key_text(ref.key) +
                            " already holds the most blobs a voxel can (seq up to 2^32 - 1)");
    }

    const bool has_bounds = !ref.bounds.empty();
    {
      StatementScope scope(*insert);
      bind_row_columns(*insert, 1, row, seq, checksums[i]);
      const Status status = insert->run();
      if (!status.is_ok()) return append_detail(status, which);
    }
    const std::int64_t id = sqlite3_last_insert_rowid(db());

    // A chunk without decoded points has no extent and no index entry: no
    // box query can find points in it.
    if (has_bounds) {
      StatementScope scope(*index);
      index->bind_int64(1, id);
      index->bind_double(2, ref.bounds.min.x);
      index->bind_double(3, ref.bounds.max.x);
      index->bind_double(4, ref.bounds.min.y);
      index->bind_double(5, ref.bounds.max.y);
      index->bind_double(6, ref.bounds.min.z);
      index->bind_double(7, ref.bounds.max.z);
      const Status status = index->run();
      if (!status.is_ok()) return append_detail(status, which);
    }
    if (const Box3d& e = ref.point_bounds; !e.empty()) {
      StatementScope scope(*extent);
      extent->bind_int64(1, id);
      extent->bind_double(2, e.min.x);
      extent->bind_double(3, e.min.y);
      extent->bind_double(4, e.min.z);
      extent->bind_double(5, e.max.x);
      extent->bind_double(6, e.max.y);
      extent->bind_double(7, e.max.z);
      const Status status = extent->run();
      if (!status.is_ok()) return append_detail(status, which);
    }
    assigned[i] = {id, static_cast<std::uint32_t>(seq)};
  }
  RELIEF_RETURN_IF_ERROR(transaction.commit());
  rows_written_ += rows.size();
  trunks_written_ += trunk_pages(rows);

  for (std::size_t i = 0; i < rows.size(); ++i) {
    rows[i].ref.id = assigned[i].first;
    rows[i].ref.seq = assigned[i].second;
    rows[i].ref.blob_size = rows[i].blob.size();
  }
  return Status::ok();
}

Status SqliteArchive::finish_scan(std::int64_t scan_id, bool has_colors, bool has_intensity,
                                  const std::string& crs) {
  RELIEF_RETURN_IF_ERROR(require_writable("finish_scan"));
  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kWrite));
  {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kScanFinish));
    StatementScope scope(*statement);
    statement->bind_int64(1, scan_id);
    statement->bind_int64(2, has_colors ? 1 : 0);
    statement->bind_int64(3, has_intensity ? 1 : 0);
    statement->bind_text(4, crs);
    RELIEF_RETURN_IF_ERROR(statement->run());
  }
  if (sqlite3_changes(db()) == 0) {
    return invalid_argument(path_ + ": finish_scan: no scan with id " + std::to_string(scan_id));
  }
  RELIEF_RETURN_IF_ERROR(refresh_scan_summary());
  return transaction.commit();
}

Status SqliteArchive::set_source_points(std::int64_t scan_id, std::uint64_t points) {
  RELIEF_RETURN_IF_ERROR(require_writable("set_source_points"));
  if (points > kMaxStoredCount) {
    return invalid_argument(path_ + ": set_source_points: too many points to record (" + std::to_string(points) + ")");
  }
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kSourceSetPoints));
  StatementScope scope(*statement);
  statement->bind_int64(1, scan_id);
  statement->bind_int64(2, static_cast<std::int64_t>(points));
  RELIEF_RETURN_IF_ERROR(statement->run());
  if (sqlite3_changes(db()) == 0) {
    return invalid_argument(path_ + ": set_source_points: scan " + std::to_string(scan_id) +
                            " does not exist or has more than one source");
  }
  return Status::ok();
}

Status SqliteArchive::abort_scan(std::int64_t scan_id) {
  RELIEF_RETURN_IF_ERROR(require_writable("abort_scan"));
  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kWrite));
  RELIEF_ASSIGN_OR_RETURN(const bool exists, scan_exists(scan_id));
  if (!exists) {
    return invalid_argument(path_ + ": abort_scan: no scan with id " + std::to_string(scan_id));
  }
  RELIEF_RETURN_IF_ERROR(delete_pyramid_rows(scan_id));
  RELIEF_ASSIGN_OR_RETURN(const bool las_table, table_exists(store::kSourceLasTable));
  if (las_table) {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kSourceLasDeleteOfScan));
    StatementScope scope(*statement);
    statement->bind_int64(1, scan_id);
    RELIEF_RETURN_IF_ERROR(statement->run());
  }
  RELIEF_ASSIGN_OR_RETURN(const bool extent_table, table_exists(store::kExtentTable));
  if (extent_table) {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kExtentDeleteOfScan));
    StatementScope scope(*statement);
    statement->bind_int64(1, scan_id);
    RELIEF_RETURN_IF_ERROR(statement->run());
  }
  // Children before parents: the index entries are found through the chunk
  // rows, and the foreign keys want chunks and sources gone before the scan.
  for (const Sql id :
       {Sql::kIndexDeleteOfScan, Sql::kChunkDeleteOfScan, Sql::kSourceDeleteOfScan, Sql::kScanDelete}) {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(id));
    StatementScope scope(*statement);
    statement->bind_int64(1, scan_id);
    RELIEF_RETURN_IF_ERROR(statement->run());
  }
  RELIEF_RETURN_IF_ERROR(refresh_scan_summary());
  return transaction.commit();
}

Result<bool> SqliteArchive::table_exists(const char* name) const {
  RELIEF_ASSIGN_OR_RETURN(
      std::unique_ptr<Statement> table,
      Statement::prepare(db(), "SELECT COUNT(*) FROM sqlite_master WHERE type = 'table' AND name = ?1", path_,
                         "read the schema"));
  table->bind_text(1, name);
  RELIEF_ASSIGN_OR_RETURN(const bool row, table->step());
  return row && table->column_int64(0) == 1;
}

Status SqliteArchive::insert_source_las(std::int64_t source_id, const LasSourceMetadata& las) {
  RELIEF_ASSIGN_OR_RETURN(Statement * insert, statement(Sql::kSourceLasInsert));
  const auto put = [&](int kind, std::span<const std::uint8_t> user_id, int record_id,
                       std::span<const std::uint8_t> description, std::span<const std::uint8_t> data) -> Status {
    StatementScope scope(*insert);
    insert->bind_int64(1, source_id);
    insert->bind_int64(2, kind);
    insert->bind_blob(3, user_id.data(), user_id.size());
    insert->bind_int64(4, record_id);
    insert->bind_blob(5, description.data(), description.size());
    insert->bind_blob(6, data.data(), data.size());
    return insert->run();
  };
  if (!las.header.empty()) RELIEF_RETURN_IF_ERROR(put(0, {}, 0, {}, las.header));
  for (const LasVlr& r : las.records) {
    RELIEF_RETURN_IF_ERROR(put(r.extended ? 2 : 1, r.user_id, r.record_id, r.description, r.data));
  }
  return Status::ok();
}

Status SqliteArchive::read_source_las(const std::vector<std::int64_t>& ids, std::vector<ArchiveSource>& sources) const {
  RELIEF_ASSIGN_OR_RETURN(const bool exists, table_exists(store::kSourceLasTable));
  if (!exists) return Status::ok();
  std::map<std::int64_t, std::size_t> index;
  for (std::size_t i = 0; i < ids.size(); ++i) index[ids[i]] = i;
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kSourceLasAll));
  StatementScope scope(*statement);
  std::uint64_t row_number = 0;
  for (;;) {
    RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
    if (!row) break;
    ++row_number;
    RowReader reader(*statement, path_, "relief_source_las row " + std::to_string(row_number));
    const std::int64_t source_id = reader.integer(0, "source_id", kMinInt64, kMaxInt64);
    const int kind = static_cast<int>(reader.integer(1, "kind", 0, 2));
    const auto record_id = static_cast<std::uint16_t>(reader.integer(3, "record_id", 0, 65535));
    RELIEF_RETURN_IF_ERROR(reader.status());
    const auto at = index.find(source_id);
    const std::string where = path_ + ": relief_source_las row " + std::to_string(row_number);
    if (at == index.end()) return format_error(where + " names source " + std::to_string(source_id) + ", which does not exist");
    LasSourceMetadata& las = sources[at->second].las;
    std::vector<std::uint8_t> user_id, description, data;
    RELIEF_RETURN_IF_ERROR(statement->column_bytes(2, user_id));
    RELIEF_RETURN_IF_ERROR(statement->column_bytes(4, description));
    RELIEF_RETURN_IF_ERROR(statement->column_bytes(5, data));
    if (kind == 0) {
      const bool sized = data.size() == 227 || data.size() == 235 || data.size() == 375;
      if (!las.header.empty() || !las.records.empty() || !sized || std::memcmp(data.data(), "LASF", 4) != 0 ||
          !user_id.empty() || !description.empty() || record_id != 0) {
        return format_error(where + ": not the first and only LAS header block (227, 235 or 375 bytes) of source " +
                            std::to_string(source_id));
      }
      las.header = std::move(data);
      continue;
    }
    LasVlr r;
    if (user_id.size() != r.user_id.size() || description.size() != r.description.size() ||
        data.size() > kMaxKeptLasRecord || (kind == 1 && data.size() > 65535)) {
      return format_error(where + ": a LAS record needs a 16-byte user id, a 32-byte description and at most " +
                          std::to_string(kind == 1 ? 65535 : kMaxKeptLasRecord) + " bytes of data");
    }
    r.extended = kind == 2;
    std::memcpy(r.user_id.data(), user_id.data(), r.user_id.size());
    r.record_id = record_id;
    std::memcpy(r.description.data(), description.data(), r.description.size());
    r.data = std::move(data);
    las.records.push_back(std::move(r));
  }
  return Status::ok();
}

Result<bool> SqliteArchive::pyramid_tables_exist() const {
  RELIEF_ASSIGN_OR_RETURN(const bool chunks, table_exists(store::kLevelChunkTable));
  if (!chunks) return false;
  return table_exists(store::kLevelScanTable);
}

Status SqliteArchive::put_level_chunks(int level, std::vector<ChunkRow>& rows) {
  RELIEF_RETURN_IF_ERROR(require_writable("put_level_chunks"));
  if (level < 1 || level > kMaxPyramidLevel) {
    return invalid_argument(path_ + ": put_level_chunks: level " + std::to_string(level) + " is not 1.." +
                            std::to_string(kMaxPyramidLevel));
  }
  if (rows.empty()) return Status::ok();
  std::vector<std::uint32_t> checksums;
  std::set<std::int64_t> scan_ids;
  RELIEF_RETURN_IF_ERROR(check_rows(rows, "put_level_chunks", checksums, scan_ids));

  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kWrite));
  RELIEF_RETURN_IF_ERROR(check_room(rows));
  RELIEF_RETURN_IF_ERROR(
      store::exec(db(), store::compact_sql(store::kCreatePyramidSql).c_str(), path_, "create the pyramid tables"));
  for (const std::int64_t scan_id : scan_ids) {
    RELIEF_ASSIGN_OR_RETURN(const bool exists, scan_exists(scan_id));
    if (!exists) {
      return invalid_argument(path_ + ": put_level_chunks: no scan with id " + std::to_string(scan_id));
    }
  }
  RELIEF_ASSIGN_OR_RETURN(Statement * next_seq, statement(Sql::kLevelNextSeq));
  RELIEF_ASSIGN_OR_RETURN(Statement * insert, statement(Sql::kLevelInsert));
  std::vector<std::pair<std::int64_t, std::uint32_t>> assigned(rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const ChunkRow& row = rows[i];
    const ChunkRef& ref = row.ref;
    std::int64_t seq = 0;
    {
      StatementScope scope(*next_seq);
      next_seq->bind_int64(1, level);
      next_seq->bind_int64(2, ref.key.ix);
      next_seq->bind_int64(3, ref.key.iy);
      next_seq->bind_int64(4, ref.key.iz);
      RELIEF_ASSIGN_OR_RETURN(const bool found, next_seq->step());
      if (found) seq = next_seq->column_int64(0);
    }
    if (seq < 0 || seq > kMaxUint32) {
      return limit_exceeded(path_ + ": put_level_chunks: level " + std::to_string(level) + " node " +
                            key_text(ref.key) + " already holds the most blobs a node can");
    }
    StatementScope scope(*insert);
    insert->bind_int64(1, level);
    bind_row_columns(*insert, 2, row, seq, checksums[i]);
    const Status status = insert->run();
    if (!status.is_ok()) return append_detail(status, "(level " + std::to_string(level) + " node " + key_text(ref.key) + ")");
    assigned[i] = {sqlite3_last_insert_rowid(db()), static_cast<std::uint32_t>(seq)};
  }
  RELIEF_RETURN_IF_ERROR(transaction.commit());
  rows_written_ += rows.size();
  trunks_written_ += trunk_pages(rows);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    rows[i].ref.id = assigned[i].first;
    rows[i].ref.seq = assigned[i].second;
    rows[i].ref.level = level;
    rows[i].ref.blob_size = rows[i].blob.size();
  }
  return Status::ok();
}

Status SqliteArchive::finish_pyramid(std::int64_t scan_id, std::uint64_t levels) {
  RELIEF_RETURN_IF_ERROR(require_writable("finish_pyramid"));
  constexpr std::uint64_t kAllLevels = ((std::uint64_t{1} << kMaxPyramidLevel) - 1) << 1;
  if (levels == 0 || (levels & ~kAllLevels) != 0) {
    return invalid_argument(path_ + ": finish_pyramid: the level set " + std::to_string(levels) +
                            " is empty or names a level outside 1.." + std::to_string(kMaxPyramidLevel));
  }
  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kWrite));
  RELIEF_ASSIGN_OR_RETURN(const bool exists, scan_exists(scan_id));
  if (!exists) return invalid_argument(path_ + ": finish_pyramid: no scan with id " + std::to_string(scan_id));
  RELIEF_RETURN_IF_ERROR(
      store::exec(db(), store::compact_sql(store::kCreatePyramidSql).c_str(), path_, "create the pyramid tables"));
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kLevelScanInsert));
  StatementScope scope(*statement);
  statement->bind_int64(1, scan_id);
  statement->bind_int64(2, static_cast<std::int64_t>(levels));
  RELIEF_RETURN_IF_ERROR(statement->run());
  return transaction.commit();
}

Status SqliteArchive::delete_pyramid_rows(std::int64_t scan_id) {
  RELIEF_ASSIGN_OR_RETURN(const bool tables, pyramid_tables_exist());
  if (!tables) return Status::ok();
  // The record first: a pyramid is never usable with rows missing.
  for (const Sql id : {Sql::kLevelScanDelete, Sql::kLevelDeleteOfScan}) {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(id));
    StatementScope scope(*statement);
    statement->bind_int64(1, scan_id);
    RELIEF_RETURN_IF_ERROR(statement->run());
  }
  return Status::ok();
}

Status SqliteArchive::remove_pyramid(std::int64_t scan_id) {
  RELIEF_RETURN_IF_ERROR(require_writable("remove_pyramid"));
  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kWrite));
  RELIEF_RETURN_IF_ERROR(delete_pyramid_rows(scan_id));
  return transaction.commit();
}

Result<std::vector<ChunkRef>> SqliteArchive::scan_chunks(std::int64_t scan_id) const {
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kScanChunks));
  StatementScope scope(*statement);
  statement->bind_int64(1, scan_id);
  RELIEF_ASSIGN_OR_RETURN(std::vector<ChunkRef> refs, collect_refs(*statement));
  sort_in_content_order(refs);
  return refs;
}

Result<std::vector<ChunkRef>> SqliteArchive::find_level_chunks(int level, const Box3d& box) const {
  if (box_has_nan(box)) return invalid_argument(path_ + ": find_level_chunks: the box contains NaN");
  if (box.empty() || level < 1 || level > kMaxPyramidLevel) return std::vector<ChunkRef>();
  RELIEF_ASSIGN_OR_RETURN(const bool tables, pyramid_tables_exist());
  if (!tables) return std::vector<ChunkRef>();
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kFindLevelChunks));
  StatementScope scope(*statement);
  statement->bind_double(1, box.min.x);
  statement->bind_double(2, box.min.y);
  statement->bind_double(3, box.min.z);
  statement->bind_double(4, box.max.x);
  statement->bind_double(5, box.max.y);
  statement->bind_double(6, box.max.z);
  statement->bind_int64(7, level);
  RELIEF_ASSIGN_OR_RETURN(std::vector<ChunkRef> refs, collect_refs(*statement));
  for (ChunkRef& ref : refs) ref.level = level;
  sort_in_content_order(refs);
  return refs;
}

Result<ChunkRow> SqliteArchive::read_row(Sql sql, std::int64_t id, const char* what) const {
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(sql));
  StatementScope scope(*statement);
  statement->bind_int64(1, id);
  RELIEF_ASSIGN_OR_RETURN(const bool found, statement->step());
  if (!found) return invalid_argument(path_ + ": read " + what + ": none with id " + std::to_string(id));

  ChunkRow row;
  RELIEF_RETURN_IF_ERROR(read_ref(*statement, path_, row.ref));
  RowReader reader(*statement, path_, std::string(what) + " id " + std::to_string(id));
  row.codec = static_cast<std::uint32_t>(reader.integer(kColCodec, "codec", 0, kMaxUint32));
  row.codec_params = reader.text(kColCodecParams, "codec_params");
  const auto stored_crc = static_cast<std::uint32_t>(reader.integer(kColCrc32, "crc32", 0, kMaxUint32));
  if (statement->column_type(kColBlob) != SQLITE_BLOB) reader.fail("blob", "is not a BLOB");
  RELIEF_RETURN_IF_ERROR(reader.status());
  RELIEF_RETURN_IF_ERROR(statement->column_bytes(kColBlob, row.blob));
  blob_bytes_read_.fetch_add(row.blob.size(), std::memory_order_relaxed);

  if (blob_crc32(row.blob) != stored_crc) {
    return corrupt_data(path_ + ": " + what + " " + key_text(row.ref.key) + " seq " + std::to_string(row.ref.seq) +
                        " (id " + std::to_string(id) + "): checksum mismatch, the blob is damaged");
  }
  return row;
}

Result<ChunkRow> SqliteArchive::read_level_chunk(std::int64_t id) const {
  RELIEF_ASSIGN_OR_RETURN(const bool tables, pyramid_tables_exist());
  if (!tables) return invalid_argument(path_ + ": read pyramid node: the archive has no pyramid");
  RELIEF_ASSIGN_OR_RETURN(ChunkRow row, read_row(Sql::kReadLevelChunk, id, "pyramid node"));
  return row;
}

// The per-scan totals of relief_chunk and, where the tables exist, of the
// finished pyramids. A pyramid missing a level it records is not used.
Status SqliteArchive::read_pyramid(ArchiveInfo& info) const {
  {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kScanBaseTotals));
    StatementScope scope(*statement);
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
      if (!row) break;
      RowReader reader(*statement, path_, "chunk totals per scan");
      ScanPyramid scan;
      scan.scan_id = reader.integer(0, "scan_id", kMinInt64, kMaxInt64);
      scan.base_chunks = static_cast<std::uint64_t>(reader.integer(1, "count", 0, kMaxInt64));
      scan.base_points = static_cast<std::uint64_t>(reader.integer(2, "decoded_points", 0, kMaxInt64));
      RELIEF_RETURN_IF_ERROR(reader.status());
      info.pyramid.push_back(std::move(scan));
    }
  }
  RELIEF_ASSIGN_OR_RETURN(const bool tables, pyramid_tables_exist());
  if (!tables) return Status::ok();
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kPyramidTotals));
  StatementScope scope(*statement);
  std::map<std::int64_t, std::pair<std::uint64_t, std::vector<PyramidLevel>>> found;
  for (;;) {
    RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
    if (!row) break;
    RowReader reader(*statement, path_, "pyramid totals");
    const std::int64_t scan_id = reader.integer(0, "scan_id", kMinInt64, kMaxInt64);
    PyramidLevel level;
    level.level = static_cast<int>(reader.integer(1, "level", 1, kMaxPyramidLevel));
    level.chunks = static_cast<std::uint64_t>(reader.integer(2, "count", 0, kMaxInt64));
    level.points = static_cast<std::uint64_t>(reader.integer(3, "decoded_points", 0, kMaxInt64));
    level.blob_bytes = static_cast<std::uint64_t>(reader.integer(4, "blob", 0, kMaxInt64));
    const auto levels = static_cast<std::uint64_t>(reader.integer(5, "levels", 0, kMaxInt64));
    RELIEF_RETURN_IF_ERROR(reader.status());
    auto& entry = found[scan_id];
    entry.first = levels;
    entry.second.push_back(level);
  }
  for (ScanPyramid& scan : info.pyramid) {
    const auto it = found.find(scan.scan_id);
    if (it == found.end()) continue;
    const auto& [levels, rows] = it->second;
    // Every level the record names has rows (the query selected only those).
    std::uint64_t present = 0;
    for (const PyramidLevel& l : rows) present |= std::uint64_t{1} << l.level;
    if (present != levels) continue;
    scan.levels = rows;
    for (const PyramidLevel& l : rows) info.pyramid_bytes += l.blob_bytes;
  }
  return Status::ok();
}

Result<std::vector<ChunkRef>> SqliteArchive::collect_refs(Statement& statement) const {
  std::vector<ChunkRef> refs;
  for (;;) {
    RELIEF_ASSIGN_OR_RETURN(const bool row, statement.step());
    if (!row) break;
    ChunkRef ref;
    RELIEF_RETURN_IF_ERROR(read_ref(statement, path_, ref));
    refs.push_back(ref);
  }
  return refs;
}

Result<std::vector<ChunkRef>> SqliteArchive::find_chunks(const Box3d& box) const {
  if (box_has_nan(box)) return invalid_argument(path_ + ": find_chunks: the box contains NaN");
  if (box.empty()) return std::vector<ChunkRef>();
  const auto bind_box = [&](Statement& statement) {
    statement.bind_double(1, box.min.x);
    statement.bind_double(2, box.min.y);
    statement.bind_double(3, box.min.z);
    statement.bind_double(4, box.max.x);
    statement.bind_double(5, box.max.y);
    statement.bind_double(6, box.max.z);
  };
  // One snapshot for both lookups: a writer committing between them would
  // otherwise look like damage.
  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kRead));

  // The R*Tree's candidates, each checked against the chunk row it names.
  std::vector<ChunkRef> refs;
  {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kFindChunks));
    StatementScope scope(*statement);
    bind_box(*statement);
    constexpr int kEntryId = kRefColumnCount;
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
      if (!row) break;
      RowReader entry_reader(*statement, path_, "spatial index entry");
      const std::int64_t entry = entry_reader.integer(kEntryId, "id", kMinInt64, kMaxInt64);
      std::array<double, 6> entry_box{};
      for (int i = 0; i < 6; ++i) {
        const std::optional<double> value = entry_reader.real_or_null(kEntryId + 1 + i, "bounds");
        entry_box[static_cast<std::size_t>(i)] = value.value_or(std::nan(""));
      }
      RELIEF_RETURN_IF_ERROR(entry_reader.status());
      if (statement->column_type(kColId) == SQLITE_NULL) {
        return corrupt_data(path_ + ": spatial index entry " + std::to_string(entry) + " names no chunk" +
                            kIndexDamaged);
      }
      ChunkRef ref;
      RELIEF_RETURN_IF_ERROR(read_ref(*statement, path_, ref));
      if (ref.bounds.empty() || !index_entry_fits(entry_box, ref.bounds)) {
        return corrupt_data(path_ + ": " + chunk_label(ref) + ": its spatial index entry does not match its bounds" +
                            kIndexDamaged);
      }
      if (boxes_overlap(ref.bounds, box)) refs.push_back(ref);
    }
  }
  std::sort(refs.begin(), refs.end(), [](const ChunkRef& a, const ChunkRef& b) { return a.id < b.id; });

  // What the exact bounds say the box holds: a damaged node can hide a whole
  // subtree from the R*Tree, and that must not pass as "no chunk there".
  std::vector<std::int64_t> expected;
  {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement,
                            statement(bounds_index_ ? Sql::kFindIdsByBounds : Sql::kFindIdsByBoundsV1));
    StatementScope scope(*statement);
    bind_box(*statement);
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
      if (!row) break;
      expected.push_back(statement->column_int64(0));
    }
  }
  std::size_t k = 0;
  for (const std::int64_t id : expected) {
    if (k < refs.size() && refs[k].id == id) {
      ++k;
      continue;
    }
    // In the chunk table but not among the R*Tree's answers.
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kChunkRef));
    StatementScope scope(*statement);
    statement->bind_int64(1, id);
    RELIEF_ASSIGN_OR_RETURN(const bool found, statement->step());
    ChunkRef missing;
    missing.id = id;
    if (found) RELIEF_RETURN_IF_ERROR(read_ref(*statement, path_, missing));
    return corrupt_data(path_ + ": " + chunk_label(missing) + ": in the box but missing from the spatial index" +
                        kIndexDamaged);
  }
  if (k != refs.size() || expected.size() != refs.size()) {
    // Found by the R*Tree (with matching bounds) but not by the bounds index.
    for (const ChunkRef& ref : refs) {
      if (!std::binary_search(expected.begin(), expected.end(), ref.id)) {
        return corrupt_data(path_ + ": " + chunk_label(ref) + ": missing from the bounds index " +
                            store::kBoundsIndex + " (the archive is damaged; 'relief check' lists the damage)");
      }
    }
  }
  RELIEF_RETURN_IF_ERROR(transaction.commit());
  sort_in_content_order(refs);
  return refs;
}

Result<std::vector<ChunkRef>> SqliteArchive::all_chunks() const {
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kAllChunks));
  StatementScope scope(*statement);
  RELIEF_ASSIGN_OR_RETURN(std::vector<ChunkRef> refs, collect_refs(*statement));
  sort_in_content_order(refs);
  return refs;
}

Result<ChunkRow> SqliteArchive::read_chunk(std::int64_t id) const {
  RELIEF_ASSIGN_OR_RETURN(ChunkRow row, read_row(Sql::kReadChunk, id, "chunk"));
  RELIEF_ASSIGN_OR_RETURN(row.ref.point_bounds, chunk_point_bounds(id, row.ref.bounds));
  return row;
}

// A chunk's relief_chunk_extent row, or empty (its bounds are its points').
// A row that is not a finite box within the chunk's bounds is damage: not
// used (empty), and said in `damage` for check. A query does not fail for it:
// nothing but the archive's reported bounds depends on the row.
Result<Box3d> SqliteArchive::chunk_point_bounds(std::int64_t id, const Box3d& bounds,
                                                std::string* damage) const {
  if (!extent_table_) {
    RELIEF_ASSIGN_OR_RETURN(const bool exists, table_exists(store::kExtentTable));
    extent_table_ = exists;
  }
  if (!*extent_table_) return Box3d{};
  RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kExtentOfChunk));
  StatementScope scope(*statement);
  statement->bind_int64(1, id);
  RELIEF_ASSIGN_OR_RETURN(const bool found, statement->step());
  if (!found) return Box3d{};
  RowReader reader(*statement, path_, "relief_chunk_extent row " + std::to_string(id));
  const Box3d e = reader.box(0, "min_x..max_z");
  std::string problem = reader.status().message();
  if (problem.empty() && (e.empty() || !box_is_finite(e) || bounds.empty() || !bounds.contains(e))) {
    problem = path_ + ": relief_chunk_extent row " + std::to_string(id) +
              ": the point bounds are not a finite box within the chunk's bounds";
  }
  if (problem.empty()) return e;
  if (damage != nullptr) *damage = std::move(problem);
  return Box3d{};
}

Result<std::vector<std::uint8_t>> SqliteArchive::read_chunk_head(std::int64_t id, std::size_t max_bytes) const {
  const std::string what = "read the head of chunk id " + std::to_string(id);
  sqlite3_blob* blob = nullptr;
  int rc = sqlite3_blob_open(db(), "main", "relief_chunk", "blob", id, 0, &blob);
  if (rc != SQLITE_OK) {
    Status status = store::sqlite_error(db(), rc, path_, what);
    sqlite3_blob_close(blob);
    return status;
  }
  const auto size = static_cast<std::size_t>(std::max(sqlite3_blob_bytes(blob), 0));
  std::vector<std::uint8_t> head(std::min(size, max_bytes));
  rc = head.empty() ? SQLITE_OK : sqlite3_blob_read(blob, head.data(), static_cast<int>(head.size()), 0);
  Status status = rc == SQLITE_OK ? Status::ok() : store::sqlite_error(db(), rc, path_, what);
  sqlite3_blob_close(blob);
  RELIEF_RETURN_IF_ERROR(status);
  blob_bytes_read_.fetch_add(head.size(), std::memory_order_relaxed);
  return head;
}

// The LAS keys of relief_meta (absent: no LAS attributes). A value that does
// not parse is damage, named.
Status SqliteArchive::read_las_meta(std::map<std::string, std::string>& meta, ArchiveInfo& info) const {
  const auto number = [&](const char* key, long long lo, long long hi, long long fallback) -> Result<long long> {
    const std::string& v = meta[key];
    if (v.empty()) return fallback;
    char* end = nullptr;
    const long long n = std::strtoll(v.c_str(), &end, 10);
    if (end == v.c_str() || *end != '\0' || n < lo || n > hi) {
      return format_error(path_ + ": metadata " + key + " is not a number from " + std::to_string(lo) + " to " +
                          std::to_string(hi) + ": '" + v + "'");
    }
    return n;
  };
  info.las_attributes = las_attributes_from_list(meta[store::kMetaLasAttributes]);
  RELIEF_ASSIGN_OR_RETURN(const long long format, number(store::kMetaLasPointFormat, -1, 10, -1));
  RELIEF_ASSIGN_OR_RETURN(const long long minor, number(store::kMetaLasVersionMinor, -1, 255, -1));
  RELIEF_ASSIGN_OR_RETURN(const long long size, number(store::kMetaLasExtraBytesSize, 0, 65535, 0));
  RELIEF_ASSIGN_OR_RETURN(const long long colors_8bit, number(store::kMetaLasColors8bit, 0, 1, 0));
  info.las_point_format = static_cast<int>(format);
  info.las_version_minor = static_cast<int>(minor);
  info.extra_bytes_size = static_cast<std::uint32_t>(size);
  info.las_colors_8bit = colors_8bit != 0;
  const std::string& time_type = meta[store::kMetaLasGpsTimeType];
  info.las_gps_time_type = parse_gps_time_type(time_type);
  if (!time_type.empty() && info.las_gps_time_type == GpsTimeType::kUnknown) {
    return format_error(path_ + ": metadata " + store::kMetaLasGpsTimeType + " is not 'week' or 'standard': '" +
                        time_type + "'");
  }
  const std::optional<std::string> vlr = bytes_from_hex(meta[store::kMetaLasExtraBytesVlr], true);
  if (!vlr) return format_error(path_ + ": metadata " + store::kMetaLasExtraBytesVlr + " is not hexadecimal");
  info.extra_bytes_vlr = *vlr;
  if ((info.las_attributes & kLasExtraBytes) != 0 && info.extra_bytes_size == 0) {
    return format_error(path_ + ": metadata names extra bytes but " + store::kMetaLasExtraBytesSize + " is 0");
  }
  if ((info.las_attributes & kLasExtraBytes) == 0) info.extra_bytes_size = 0;
  return Status::ok();
}

Result<ArchiveInfo> SqliteArchive::info() const {
  ArchiveInfo info;
  info.format_version = format_version_;
  info.grid = grid_;

  // One snapshot for all the SELECTs: a writer appending meanwhile is either
  // wholly in the totals, sources and scans, or not at all.
  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kRead));
  {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kMetaAll));
    StatementScope scope(*statement);
    std::map<std::string, std::string> meta;
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
      if (!row) break;
      meta[statement->column_text(0)] = statement->column_text(1);
    }
    info.codec_params = meta[store::kMetaCodecParams];
    info.creator = meta[store::kMetaCreator];
    if (format_version_ >= 3) {
      // The texts live in relief_scan and relief_source, which no other
      // checksum covers: crs_crc32 (under meta_crc32) vouches for them.
      RELIEF_ASSIGN_OR_RETURN(auto crs, scans_crs());
      const auto stored = meta.find(store::kMetaCrsChecksum);
      const std::string computed = checksum_text(crs_checksum(crs.first, crs.second));
      if (stored == meta.end() || stored->second != computed) {
        return corrupt_data(path_ + ": CRS checksum " +
                            (stored == meta.end() ? std::string("missing") : "mismatch (stored " + stored->second +
                                                                                 ", computed " + computed + ")") +
                            ": the CRS text of relief_scan or relief_source is damaged");
      }
      info.crs = std::move(crs.first);
      info.crs_source = std::move(crs.second);
    } else {
      info.crs = meta[store::kMetaCrs];
      info.crs_source = meta[store::kMetaCrsSource];
    }
    // "rgb,intensity": names separated by commas; unknown names are ignored.
    const std::string& attributes = meta[store::kMetaAttributes];
    std::size_t start = 0;
    while (start <= attributes.size()) {
      std::size_t end = attributes.find(',', start);
      if (end == std::string::npos) end = attributes.size();
      const std::string_view name(attributes.data() + start, end - start);
      if (name == store::kAttributeRgb) info.has_colors = true;
      if (name == store::kAttributeIntensity) info.has_intensity = true;
      start = end + 1;
    }
    RELIEF_RETURN_IF_ERROR(read_las_meta(meta, info));
  }
  {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kTotals));
    StatementScope scope(*statement);
    RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
    if (!row) return internal_error(path_ + ": sum chunks: no result row");
    RowReader reader(*statement, path_, "chunk totals");
    info.chunk_count = static_cast<std::uint64_t>(reader.integer(0, "count", 0, kMaxInt64));
    info.input_points = static_cast<std::uint64_t>(reader.integer(1, "input_points", 0, kMaxInt64));
    info.decoded_points = static_cast<std::uint64_t>(reader.integer(2, "decoded_points", 0, kMaxInt64));
    info.blob_bytes = static_cast<std::uint64_t>(reader.integer(3, "blob", 0, kMaxInt64));
    std::array<std::optional<double>, 6> bounds;
    bool all = true;
    for (int i = 0; i < 6; ++i) {
      bounds[static_cast<std::size_t>(i)] = reader.real_or_null(4 + i, "bounds");
      all = all && bounds[static_cast<std::size_t>(i)].has_value();
    }
    RELIEF_RETURN_IF_ERROR(reader.status());
    if (all) {
      info.bounds.min = {*bounds[0], *bounds[1], *bounds[2]};
      info.bounds.max = {*bounds[3], *bounds[4], *bounds[5]};
    }
  }
  info.point_bounds = info.bounds;
  RELIEF_ASSIGN_OR_RETURN(const bool extents, table_exists(store::kExtentTable));
  if (extents && !info.bounds.empty()) {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kPointBounds));
    StatementScope scope(*statement);
    RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
    if (!row) return internal_error(path_ + ": sum chunks' point bounds: no result row");
    RowReader reader(*statement, path_, "chunk point bounds");
    const Box3d b = reader.box(0, "bounds");
    RELIEF_RETURN_IF_ERROR(reader.status());
    // Damaged extent rows (outside their chunks' bounds) must not widen or
    // empty what is reported: read_chunk and check name them.
    if (!b.empty() && box_is_finite(b) && info.bounds.contains(b)) info.point_bounds = b;
  }
  {
    std::vector<std::int64_t> source_ids;
    {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kSources));
    StatementScope scope(*statement);
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
      if (!row) break;
      RowReader reader(*statement, path_, "relief_source row");
      ArchiveSource source;
      source.path = reader.text(0, "path");
      source.format = reader.text(1, "format");
      source.point_count = static_cast<std::uint64_t>(reader.integer(2, "point_count", 0, kMaxInt64));
      source.crs = reader.text(3, "crs");
      source.scan_id = reader.integer(4, "scan_id", kMinInt64, kMaxInt64);
      source_ids.push_back(reader.integer(5, "id", kMinInt64, kMaxInt64));
      RELIEF_RETURN_IF_ERROR(reader.status());
      info.sources.push_back(std::move(source));
    }
    }
    RELIEF_RETURN_IF_ERROR(read_source_las(source_ids, info.sources));
  }
  {
    RELIEF_ASSIGN_OR_RETURN(Statement * statement, statement(Sql::kScans));
    StatementScope scope(*statement);
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
      if (!row) break;
      RowReader reader(*statement, path_, "relief_scan row");
      ArchiveScan scan;
      scan.id = reader.integer(0, "id", kMinInt64, kMaxInt64);
      scan.complete = reader.integer(1, "complete", 0, 1) == 1;
      scan.created_at = reader.text(2, "created_at");
      RELIEF_RETURN_IF_ERROR(reader.status());
      info.scans.push_back(std::move(scan));
    }
  }
  RELIEF_RETURN_IF_ERROR(read_pyramid(info));
  RELIEF_RETURN_IF_ERROR(transaction.commit());

  // What the archive costs on disk right now: the file plus the WAL that a
  // checkpoint has not yet folded into it.
  for (const std::string& file : {path_, path_ + "-wal"}) {
    std::error_code ec;
    const std::uintmax_t size = fs::file_size(file, ec);
    if (!ec) info.file_bytes += static_cast<std::uint64_t>(size);
  }
  return info;
}

Result<std::unique_ptr<SqliteArchive>> open_sqlite(const std::string& path, Archive::Mode mode, bool verify_meta,
                                                   Status* init_status);

}  // namespace

// ---- Public entry points

Result<std::unique_ptr<Archive>> Archive::create(const std::string& path, const ArchiveGrid& grid,
                                                 const std::string& codec_params,
                                                 const std::string& creator, std::uint32_t page_size) {
  if (page_size < 512 || page_size > 65536 || (page_size & (page_size - 1)) != 0) {
    return invalid_argument(path + ": page size " + std::to_string(page_size) +
                            " is not a power of two from 512 to 65536");
  }
  if (path.empty()) return invalid_argument("the archive path is empty");
  std::error_code ec;
  if (fs::exists(fs::symlink_status(path, ec))) {
    return io_error(path + ": already exists (an archive is never overwritten)");
  }
  RELIEF_RETURN_IF_ERROR(check_grid(path, grid));
  {
    // Said plainly (SQLite's own message on a read-only file system is
    // "unable to open database file (No such file or directory)").
    const fs::path parent = fs::path(path).parent_path();
    const std::string dir = parent.empty() ? "." : parent.string();
    if (::access(dir.c_str(), W_OK) != 0 && (errno == EROFS || errno == EACCES)) {
      return io_error(path + ": cannot create the archive: " + dir + " is not writable (" +
                      std::strerror(errno) + ")");
    }
  }

  // Built beside the target and renamed into place when complete: a crash
  // during creation leaves at most a temporary file, never a half-made
  // archive under the real name.
  core::remove_stale_temps_beside(path);  // left by killed writers of this path, on this host
  const std::string temp = core::temp_path_beside(path);
  remove_database_files(temp);  // left by a crashed process of this host that had our pid
  Status status = write_new_archive(temp, path, grid, codec_params, creator, page_size);
  if (status.is_ok()) status = move_into_place(temp, path);
  if (!status.is_ok()) {
    remove_database_files(temp);
    return status;
  }
  // The name is ours now (the move never replaces a file). Log files under it
  // belong to an archive deleted without them (a killed writer's -wal and
  // -shm, a -journal): SQLite would replay them into this one when it opens
  // it, so they go first.
  for (const char* suffix : {"-wal", "-shm", "-journal"}) {
    std::error_code removed;
    const std::string log = path + suffix;
    if (fs::exists(fs::symlink_status(log, removed)) && !fs::remove(log, removed)) {
      remove_database_files(path);
      return io_error(path + ": cannot remove " + log + ", left by an archive deleted without it (" +
                      removed.message() + "); SQLite would replay it into the new archive");
    }
  }
  sync_directory_of(path);
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<SqliteArchive> archive,
                          open_sqlite(path, Mode::kReadWrite, true, nullptr));
  archive->mark_created();
  return std::unique_ptr<Archive>(std::move(archive));
}

namespace {

// Opens the file and identifies it; `init_status`, when given, receives a
// failure of initialise() (which otherwise fails the open) and the archive is
// returned anyway, for check_archive to report it with the rest.
Result<std::unique_ptr<SqliteArchive>> open_sqlite(const std::string& path, Archive::Mode mode, bool verify_meta,
                                                   Status* init_status) {
  using Mode = Archive::Mode;
  std::error_code ec;
  const fs::file_status status = fs::status(path, ec);
  if (!fs::exists(status)) {
    if (ec && ec != std::errc::no_such_file_or_directory) {
      return io_error(path + ": cannot open: " + ec.message());
    }
    return io_error(path + ": no such file");
  }
  if (fs::is_directory(status)) return io_error(path + ": is a directory, not an archive");
  // SQLite treats an empty file as an empty database; say what it really is.
  if (fs::is_regular_file(status) && fs::file_size(path, ec) == 0 && !ec) {
    return format_error(path + ": not a Relief archive (empty file)");
  }

  // A cut-short file is reported by SQLite as "not a database" or
  // "malformed"; when opening fails as malformed, say it is truncated if its
  // header shows so. (Checked only then: while a writer checkpoints, page 1
  // may briefly announce pages not yet written.)
  const auto explain = [&path](Status failed) {
    if (failed.code() != StatusCode::kFormatError) return failed;
    Status truncated = store::check_not_truncated(path);
    return truncated ? failed : truncated;
  };
  const int flags = mode == Mode::kReadOnly ? SQLITE_OPEN_READONLY : SQLITE_OPEN_READWRITE;
  Result<store::Connection> opened = store::open_connection(path, flags, path, "cannot open");
  if (!opened) return explain(opened.status());
  store::Connection connection = std::move(opened).value();
  Result<int> version = identify(connection.get(), path);
  if (!version && version.status().code() == StatusCode::kIoError && mode == Mode::kReadOnly) {
    // A file left in WAL mode (a writer is running, or was killed) needs a
    // -shm file beside it; on read-only media SQLite cannot create one.
    // Immutable mode reads the file alone, which is all there is to read
    // there: nothing can be writing to read-only media.
    Result<store::Connection> immutable = store::open_connection(
        store::immutable_uri(path), SQLITE_OPEN_READONLY | SQLITE_OPEN_URI, path, "cannot open");
    if (immutable) {
      Result<int> retry = identify(immutable->get(), path);
      if (retry) {
        connection = std::move(immutable).value();
        version = retry;
      }
    }
  }
  if (!version) return explain(version.status());
  auto archive = std::make_unique<SqliteArchive>(path, std::move(connection), mode, *version);
  const Status initialised = archive->initialise(verify_meta);
  if (init_status != nullptr) {
    *init_status = initialised;
  } else if (!initialised) {
    return explain(initialised);
  }
  return archive;
}


// Damage beyond this many findings is counted, not listed.
constexpr std::size_t kMaxProblems = 1000;

class CheckReport {
 public:
  CheckReport(ArchiveCheck& out, const CheckProgress& progress) : out_(out), progress_(progress) {}
  void stage(const char* name, std::uint64_t done = 0, std::uint64_t total = 0) const {
    if (progress_) progress_(name, done, total);
  }
  ~CheckReport() {
    if (dropped_ > 0) out_.problems.push_back("... and " + std::to_string(dropped_) + " more");
  }
  void checked(std::string what) { out_.checked.push_back(std::move(what)); }
  void problem(std::string what) {
    if (out_.problems.size() < kMaxProblems) {
      out_.problems.push_back(std::move(what));
    } else {
      ++dropped_;
    }
  }

 private:
  ArchiveCheck& out_;
  const CheckProgress& progress_;
  std::uint64_t dropped_ = 0;
};

// Pages SQLite has read into its cache on this connection so far.
std::uint64_t pages_read(sqlite3* db) {
  int current = 0, highwater = 0;
  if (sqlite3_db_status(db, SQLITE_DBSTATUS_CACHE_MISS, &current, &highwater, 0) != SQLITE_OK) return 0;
  return current > 0 ? static_cast<std::uint64_t>(current) : 0;
}

// Rows of a single-column text query ("PRAGMA integrity_check",
// "rtreecheck"): every row but a lone "ok" is a problem.
Status text_rows_problems(sqlite3* db, const char* sql, const std::string& path, const std::string& label,
                          CheckReport& report) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Statement> statement, Statement::prepare(db, sql, path, label));
  StatementScope scope(*statement);
  for (;;) {
    RELIEF_ASSIGN_OR_RETURN(const bool row, statement->step());
    if (!row) break;
    std::string text = statement->column_text(0);
    if (text == "ok") continue;
    while (!text.empty() && text.back() == '\n') text.pop_back();
    std::size_t start = 0;
    while (start <= text.size()) {  // rtreecheck reports several lines in one
      std::size_t end = text.find('\n', start);
      if (end == std::string::npos) end = text.size();
      if (end > start) report.problem(label + ": " + text.substr(start, end - start));
      start = end + 1;
    }
  }
  return Status::ok();
}

}  // namespace

// The one chunk codec (format-spec/archive.md 2.4: 1 = Relief chunk blob).
constexpr std::uint32_t kChunkCodecRelief = 1;
// How far a row's bounds may reach beyond its key's cube, in chunk edges:
// the base layer's points, rebuilt from its maps, may lie outside it (1.5 %
// of an edge in default archives, 18.6 % with cells 100 times the edge); a
// row under a key two or more away from its own lies beyond this.
constexpr double kBoundsOverhang = 1.0;

std::string SqliteArchive::bounds_outside_key(const ChunkRef& ref) const {
  if (ref.bounds.empty()) return {};
  const double edge = grid_.chunk_edge;
  const std::int64_t key[3] = {ref.key.ix, ref.key.iy, ref.key.iz};
  const double origin[3] = {grid_.origin.x, grid_.origin.y, grid_.origin.z};
  const double lo[3] = {ref.bounds.min.x, ref.bounds.min.y, ref.bounds.min.z};
  const double hi[3] = {ref.bounds.max.x, ref.bounds.max.y, ref.bounds.max.z};
  for (int a = 0; a < 3; ++a) {
    const double cube = origin[a] + static_cast<double>(key[a]) * edge;
    if (lo[a] < cube - kBoundsOverhang * edge || hi[a] > cube + edge + kBoundsOverhang * edge) {
      return "its bounds (" + format_double(lo[a]) + " .. " + format_double(hi[a]) + " on axis " +
             std::string(1, static_cast<char>('x' + a)) + ") lie outside its key's cube (" +
             format_double(cube) + " .. " + format_double(cube + edge) + ")";
    }
  }
  return {};
}

Status SqliteArchive::check_chunks(CheckReport& report, const ChunkRowCheck& row_check) const {
  // One snapshot: a writer appending or aborting meanwhile must not look
  // like a chunk without its index entry.
  Transaction transaction(db(), path_);
  RELIEF_RETURN_IF_ERROR(transaction.begin(Transaction::Kind::kRead));
  RELIEF_ASSIGN_OR_RETURN(const std::vector<ChunkRef> refs, all_chunks());
  std::set<std::int64_t> scans;
  {
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Statement> ids,
                            Statement::prepare(db(), "SELECT id FROM relief_scan", path_, "list the scans"));
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool row, ids->step());
      if (!row) break;
      scans.insert(ids->column_int64(0));
    }
  }
  // Blobs: read_chunk verifies each CRC-32; then the row against the grid,
  // the scans and (row_check) what the blob holds.
  const std::uint64_t total = refs.size();
  report.stage("chunk blobs", 0, total);
  for (std::uint64_t i = 0; i < total; ++i) {
    const Result<ChunkRow> row = read_chunk(refs[i].id);
    const std::string label = path_ + ": " + chunk_label(refs[i]);
    if (!row) {
      report.problem(row.status().message());
    } else {
      if (row->codec != kChunkCodecRelief) {
        report.problem(label + ": codec " + std::to_string(row->codec) +
                       ", which no reader knows (damaged, or written by a newer Relief)");
      }
      if (scans.count(refs[i].scan_id) == 0) {
        report.problem(label + ": names scan " + std::to_string(refs[i].scan_id) + ", which does not exist");
      }
      if (const std::string outside = bounds_outside_key(refs[i]); !outside.empty()) {
        report.problem(label + ": " + outside);
      }
      if (row_check) {
        if (const std::string wrong = row_check(refs[i], row->blob); !wrong.empty()) {
          report.problem(label + ": " + wrong);
        }
      }
      std::string damage;
      RELIEF_RETURN_IF_ERROR(chunk_point_bounds(refs[i].id, refs[i].bounds, &damage).status());
      if (!damage.empty()) report.problem(damage);
    }
    report.stage("chunk blobs", i + 1, total);
  }
  report.checked(std::to_string(refs.size()) +
                 " chunk blobs against their CRC-32, and their rows' codec, scan" +
                 std::string(row_check ? ", counts" : "") + " and bounds");
  RELIEF_ASSIGN_OR_RETURN(const bool extents, table_exists(store::kExtentTable));
  if (extents) {
    // Each row's point bounds were checked with its chunk above (a finite
    // box within the chunk's bounds); rows naming no chunk are not damage.
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Statement> count,
                            Statement::prepare(db(),
                                               "SELECT COUNT(*), COUNT(c.id) FROM relief_chunk_extent AS e "
                                               "LEFT JOIN relief_chunk AS c ON c.id = e.id",
                                               path_, "count the chunks' point bounds"));
    RELIEF_ASSIGN_OR_RETURN(const bool row, count->step());
    const std::int64_t rows = row ? count->column_int64(0) : 0;
    const std::int64_t named = row ? count->column_int64(1) : 0;
    std::string line =
        std::to_string(named) + " chunks' point bounds (relief_chunk_extent), each within its chunk's bounds";
    if (rows > named) {
      line +=
          "; " + std::to_string(rows - named) +
          " rows that name no chunk (left by a writer that does not know the table), which readers ignore";
    }
    report.checked(line);
  }
  RELIEF_ASSIGN_OR_RETURN(const bool pyramid, pyramid_tables_exist());
  if (pyramid) {
    // Every pyramid row, finished or not: each level's nodes by a box query
    // over everything, each blob against its CRC-32.
    const double inf = std::numeric_limits<double>::infinity();
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Statement> ids,
                            Statement::prepare(db(), "SELECT id FROM relief_level_chunk ORDER BY id", path_,
                                               "list pyramid nodes"));
    std::uint64_t nodes = 0;
    report.stage("pyramid nodes");
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool row, ids->step());
      if (!row) break;
      ++nodes;
      report.stage("pyramid nodes", nodes);
      const Result<ChunkRow> node = read_level_chunk(ids->column_int64(0));
      if (!node) report.problem(node.status().message());
    }
    std::uint64_t reachable = 0;
    const Box3d everything{{-inf, -inf, -inf}, {inf, inf, inf}};
    for (int level = 1; level <= kMaxPyramidLevel; ++level) {
      RELIEF_ASSIGN_OR_RETURN(const std::vector<ChunkRef> found, find_level_chunks(level, everything));
      reachable += found.size();
    }
    std::string line = std::to_string(nodes) + " pyramid node blobs against their CRC-32 (" +
                       std::to_string(reachable) + " in finished pyramids";
    if (nodes > reachable) {
      // Not damage: a pyramid being built, or left by a killed run.
      line += "; " + std::to_string(nodes - reachable) +
              " that no reader uses, which the next writer to open the archive alone removes";
    }
    report.checked(line + ")");
  }

  // Chunk rows -> index: one entry per chunk with bounds, matching them, and
  // reachable by a box query (a damaged node hides entries only from those).
  RELIEF_ASSIGN_OR_RETURN(
      std::unique_ptr<Statement> entry,
      Statement::prepare(db(), "SELECT min_x, max_x, min_y, max_y, min_z, max_z FROM relief_chunk_index WHERE id = ?1",
                         path_, "read the spatial index"));
  RELIEF_ASSIGN_OR_RETURN(Statement * box_ids, statement(Sql::kIndexBoxIds));
  std::uint64_t indexed = 0;
  std::uint64_t done = 0;
  for (const ChunkRef& ref : refs) {
    report.stage("spatial index", done++, total);
    std::optional<std::array<double, 6>> found;
    {
      StatementScope scope(*entry);
      entry->bind_int64(1, ref.id);
      RELIEF_ASSIGN_OR_RETURN(const bool row, entry->step());
      if (row) {
        std::array<double, 6> values{};
        for (int i = 0; i < 6; ++i) values[static_cast<std::size_t>(i)] = entry->column_double(i);
        found = values;
      }
    }
    const std::string label = path_ + ": " + chunk_label(ref);
    if (ref.bounds.empty()) {
      if (found) report.problem(label + ": has no bounds but a spatial index entry");
      continue;
    }
    ++indexed;
    if (!found) {
      report.problem(label + ": has no spatial index entry");
      continue;
    }
    if (!index_entry_fits(*found, ref.bounds)) {
      report.problem(label + ": its spatial index entry does not match its bounds");
      continue;
    }
    StatementScope scope(*box_ids);
    box_ids->bind_double(1, ref.bounds.min.x);
    box_ids->bind_double(2, ref.bounds.min.y);
    box_ids->bind_double(3, ref.bounds.min.z);
    box_ids->bind_double(4, ref.bounds.max.x);
    box_ids->bind_double(5, ref.bounds.max.y);
    box_ids->bind_double(6, ref.bounds.max.z);
    bool reached = false;
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool row, box_ids->step());
      if (!row) break;
      reached = reached || box_ids->column_int64(0) == ref.id;
    }
    if (!reached) report.problem(label + ": a box query over its own bounds does not find it in the spatial index");
  }
  // Index -> chunk rows: no entry without its chunk.
  {
    RELIEF_ASSIGN_OR_RETURN(
        std::unique_ptr<Statement> orphans,
        Statement::prepare(db(),
                           "SELECT id FROM relief_chunk_index WHERE id NOT IN (SELECT id FROM relief_chunk) ORDER BY id",
                           path_, "read the spatial index"));
    StatementScope scope(*orphans);
    for (;;) {
      RELIEF_ASSIGN_OR_RETURN(const bool row, orphans->step());
      if (!row) break;
      report.problem(path_ + ": spatial index entry " + std::to_string(orphans->column_int64(0)) +
                     " names no chunk");
    }
  }
  report.checked("the spatial index against " + std::to_string(refs.size()) + " chunk rows (" +
                 std::to_string(indexed) + " with bounds): one matching entry each, found by a box query, "
                 "and no entry without its chunk");
  report.stage("spatial index", total, total);
  report.stage("spatial index tree");
  RELIEF_RETURN_IF_ERROR(text_rows_problems(db(), "SELECT rtreecheck('relief_chunk_index')", path_,
                                            path_ + ": spatial index structure (rtreecheck)", report));
  report.checked("the spatial index's tree structure (rtreecheck)");
  return transaction.commit();
}

Result<ArchiveCheck> check_archive(const std::string& path, const CheckProgress& progress,
                                   const ChunkRowCheck& row_check) {
  Status init_status;
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<SqliteArchive> archive,
                          open_sqlite(path, Archive::Mode::kReadOnly, false, &init_status));
  ArchiveCheck result;
  result.format_version = archive->format_version();
  {
    CheckReport report(result, progress);
    const auto attempt = [&](const Status& status, const std::string& what) {
      if (!status) report.problem(status.message() + " (while checking " + what + ")");
    };
    {
      // SQLite checks every page in one step of the statement: a progress
      // handler reports the pages it has read so far (its cache misses),
      // a few times a second at most on a terminal (the printer's rate).
      constexpr const char* kStage = "SQLite integrity check";
      constexpr int kOpsPerReport = 4096;  // virtual-machine instructions between reports
      struct Watch {
        sqlite3* db;
        const CheckReport* report;
        std::uint64_t base;
        std::uint64_t pages() const { return pages_read(db) - base; }
      };
      Watch watch{archive->connection(), &report, pages_read(archive->connection())};
      report.stage(kStage);
      sqlite3_progress_handler(
          watch.db, kOpsPerReport,
          [](void* p) {
            const auto* w = static_cast<const Watch*>(p);
            w->report->stage(kStage, w->pages());
            return 0;
          },
          &watch);
      attempt(text_rows_problems(watch.db, "PRAGMA integrity_check", path, path + ": SQLite integrity check", report),
              "the SQLite structure");
      sqlite3_progress_handler(watch.db, 0, nullptr, nullptr);
      report.stage(kStage, watch.pages());
    }
    report.checked("the SQLite file structure (PRAGMA integrity_check)");
    if (!init_status) report.problem(init_status.message());
    report.checked("tables, indexes and grid metadata");
    if (archive->format_version() >= 2) {
      attempt(archive->verify_meta_checksum(), "the metadata checksum");
      report.checked("the metadata checksum (relief_meta meta_crc32)");
    } else {
      report.checked("the metadata checksum: absent in format version 1, nothing to check");
    }
    if (init_status) {
      // Scans and sources, the LAS headers and records of sources included.
      attempt(archive->info().status(), "the scans and sources");
      report.checked(archive->format_version() >= 3
                         ? "scans and sources (their LAS headers and records, the CRS checksum relief_meta crs_crc32)"
                         : "scans and sources (their LAS headers and records)");
      attempt(archive->check_chunks(report, row_check), "the chunks");
    } else {
      report.checked("chunks and spatial index: not checked (the archive's schema or grid is unusable)");
    }
  }
  return result;
}

Result<std::unique_ptr<Archive>> Archive::open(const std::string& path, Mode mode) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<SqliteArchive> archive, open_sqlite(path, mode, true, nullptr));
  return std::unique_ptr<Archive>(std::move(archive));
}

}  // namespace relief
