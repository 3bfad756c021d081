// The Relief archive: one SQLite file holding compressed chunks keyed by the
// voxel index of a world grid (format-spec/archive.md). Blobs are opaque bytes
// here; the codec (relief/codec.h) makes and reads them.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "relief/status.h"
#include "relief/types.h"

namespace relief {

// PRAGMA application_id: "RLIF" big-endian.
inline constexpr std::int32_t kArchiveApplicationId = 0x524C4946;
// PRAGMA user_version: the archive format version this build writes. It reads
// every version from 1 on; version 1 lacks the metadata checksum and the
// bounds index, versions 1 and 2 keep a copy of the CRS texts in relief_meta
// where version 3 keeps their checksum (format-spec/archive.md, version log).
inline constexpr int kArchiveFormatVersion = 3;

// Pyramid levels are 1..kMaxPyramidLevel (a node of level L spans 2^L chunks
// per axis; 40 levels cover any grid a 64-bit key can address in practice).
inline constexpr int kMaxPyramidLevel = 40;

// SQLite page size of a new archive (fixed when it is created). Every table
// and index takes at least one page, so small pages keep a small archive's
// fixed cost small; every overflow page of a blob spends 4 bytes on the
// chain's link, so larger pages cost less per blob byte (0.1 % at 4096, 0.4 %
// at 1024, 0.8 % at 512) and fewer writes and reads (SQLite's journal and
// checkpoint move a page per call). Ingest takes kSmallArchivePageSize for
// small inputs and kLargeArchivePageSize for large ones (ingest_page_size in
// relief/ingest.h).
inline constexpr std::uint32_t kArchivePageSize = 1024;
inline constexpr std::uint32_t kSmallArchivePageSize = 512;
inline constexpr std::uint32_t kLargeArchivePageSize = 4096;

struct ChunkKey {
  std::int64_t ix = 0, iy = 0, iz = 0;
  friend bool operator==(const ChunkKey&, const ChunkKey&) = default;
  friend auto operator<=>(const ChunkKey&, const ChunkKey&) = default;
};

// The world grid: chunk (ix, iy, iz) covers [origin + i * edge, origin + (i + 1) * edge).
struct ArchiveGrid {
  Vec3d origin{0, 0, 0};
  double chunk_edge = 0;  // > 0

  ChunkKey key_of(const Vec3d& p) const;
  // key_of of points[0..n) into out[0..n): the same keys, computed in bulk.
  void keys_of(const Vec3d* points, std::size_t n, ChunkKey* out) const;
  Box3d chunk_box(const ChunkKey& key) const;
};

// One input file as recorded in the archive.
struct ArchiveSource {
  std::string path;
  std::string format;  // "ply", "las", "laz", "xyz", "pcd", "ptx", "stream"
  std::uint64_t point_count = 0;
  std::string crs;     // as the file gave it (relief/crs.h source form), empty when none
  std::int64_t scan_id = 0;
  // LAS/LAZ: its header block and kept VLRs (relief/types.h), which LAS
  // output gives back (WriterOptions::las_sources); empty for other formats.
  LasSourceMetadata las;
};

// What every point of a scan carries, known when the scan begins.
struct ScanAttributes {
  bool has_colors = false;
  bool has_intensity = false;
  std::string crs;  // of the scan's sources (WKT2, relief/crs.h); empty when none
  // LAS attributes of the scan (LasAttributes; see ArchiveInfo::las_attributes).
  // The archive's set becomes the union of every scan's.
  std::uint32_t las_attributes = 0;
  int las_point_format = -1;
  int las_version_minor = -1;
  std::string extra_bytes_vlr;
  std::uint32_t extra_bytes_size = 0;
  bool las_colors_8bit = false;
  GpsTimeType las_gps_time_type = GpsTimeType::kUnknown;
};

// A scan is what one compress, append or stream run adds.
struct ArchiveScan {
  std::int64_t id = 0;
  bool complete = false;  // false: the run was killed or is still going
  std::string created_at;  // UTC, ISO 8601
};

// One level of a scan's level-of-detail pyramid (format-spec/archive.md §9).
struct PyramidLevel {
  int level = 0;  // 1, 2, ...: nodes of chunk_edge * 2^level
  std::uint64_t chunks = 0;
  std::uint64_t points = 0;  // decoded points of the level's nodes
  std::uint64_t blob_bytes = 0;
};

// What a scan holds at full resolution and in its pyramid.
struct ScanPyramid {
  std::int64_t scan_id = 0;
  std::uint64_t base_points = 0;  // decoded points of the scan's chunks (level 0)
  std::uint64_t base_chunks = 0;
  // Its finished pyramid, the stored levels in order (not every level number
  // is stored: see Archive::finish_pyramid); empty when the scan has none
  // (archives and scans written without one: queries read its chunks).
  std::vector<PyramidLevel> levels;
};

struct ArchiveInfo {
  int format_version = 0;
  ArchiveGrid grid;
  std::string codec_params;  // the codec's defaults for this archive (encode_params_to_string)
  std::string creator;       // tool and version that created the archive
  // Of the earliest scan that had one: WKT2 (archives before the crs module:
  // as the file gave it, e.g. "EPSG:2154"); empty when none.
  std::string crs;
  // How the first source with that CRS gave it (ArchiveSource::crs of that
  // source), so a LAS writer can give it back the same way; may be empty.
  std::string crs_source;
  bool has_colors = false;
  bool has_intensity = false;
  // Per-point LAS attributes the archive carries (LasAttributeBits; the union
  // over its scans: points of a scan without one read it as 0), the widest
  // source point format (0-10; a 1.4 format when any source had one) and
  // the highest LAS minor version of its sources (-1 when no source was
  // LAS), the Extra Bytes VLR payload describing las.extra_bytes
  // (extra_bytes_size bytes per point), and whether the LAS sources stored
  // 8-bit colour levels (WriterOptions::las_colors_8bit), and what the GPS
  // times count (kUnknown: no source said, or the archive predates the key).
  // Archives written before these existed carry none.
  std::uint32_t las_attributes = 0;
  int las_point_format = -1;
  int las_version_minor = -1;
  std::string extra_bytes_vlr;
  std::uint32_t extra_bytes_size = 0;
  bool las_colors_8bit = false;
  GpsTimeType las_gps_time_type = GpsTimeType::kUnknown;
  // Totals over all chunk rows (every scan, complete or not).
  std::uint64_t input_points = 0;
  std::uint64_t decoded_points = 0;
  std::uint64_t chunk_count = 0;
  std::uint64_t blob_bytes = 0;
  // Of every point any query can return, a coarse level of detail's included
  // (the union of the chunk rows' bounds); empty for an empty archive.
  Box3d bounds;
  // Of the points a full decode returns (every point of an error-bounded
  // archive, exact), within `bounds`: what `relief info` reports. Archives
  // written before relief_chunk_extent (format-spec/archive.md §2.6) give
  // `bounds` here, which may reach beyond the points by the base layer's
  // overhang.
  Box3d point_bounds;
  std::uint64_t file_bytes = 0;  // size of the SQLite file (+ WAL) on disk
  std::vector<ArchiveSource> sources;
  std::vector<ArchiveScan> scans;
  // Per scan with chunks, in scan id order: its points and its pyramid.
  std::vector<ScanPyramid> pyramid;
  std::uint64_t pyramid_bytes = 0;  // blob bytes of every usable pyramid level row
};

// Index entry of a stored chunk (no blob).
struct ChunkRef {
  std::int64_t id = 0;
  ChunkKey key;
  std::uint32_t seq = 0;  // 0, 1, ... for several blobs in one voxel (appended scans)
  std::int64_t scan_id = 0;
  Box3d bounds;  // of the decoded points at any level of detail, exact (double)
  // Of the points a full decode (lod 1) returns, exact, when they lie within
  // narrower bounds than `bounds` (an error-bounded blob whose base layer
  // reaches beyond its points); empty: the same as `bounds`. Written to
  // relief_chunk_extent by put_chunks, filled by read_chunk.
  Box3d point_bounds;
  std::uint64_t input_points = 0;
  std::uint64_t decoded_points = 0;
  std::uint64_t blob_size = 0;
  // 0: a chunk of the full-resolution data (relief_chunk); 1, 2, ...: a node
  // of that level of detail of the pyramid (relief_level_chunk), whose key is
  // on the grid of chunk edge chunk_edge * 2^level.
  int level = 0;
};

// A chunk to write (ingest) or a chunk read back (query).
struct ChunkRow {
  ChunkRef ref;                // id and seq are assigned by put_chunks
  std::uint32_t codec = 1;     // 1 = Relief chunk blob (format-spec/chunk.md)
  std::string codec_params;    // encode_params_to_string of what made the blob
  std::vector<std::uint8_t> blob;
};

// What a user must know when Archive::close() failed on an archive that is
// kept: "; the archive is intact, but its last writes stay in PATH-wal ...".
std::string kept_in_wal_note(const std::string& path);

class Archive {
 public:
  enum class Mode { kReadOnly, kReadWrite };

  // Creates a new archive at `path` (kIoError if the file exists or cannot be
  // created). The file is complete and valid as soon as this returns.
  // `page_size`: a power of two from 512 to 65536 (kInvalidArgument otherwise).
  static Result<std::unique_ptr<Archive>> create(const std::string& path, const ArchiveGrid& grid,
                                                 const std::string& codec_params,
                                                 const std::string& creator,
                                                 std::uint32_t page_size = kArchivePageSize);
  // Opens an existing archive. Not a SQLite file, not a Relief archive (wrong
  // application_id) -> kFormatError naming the file; a newer format version ->
  // kUnsupported. Read-only handles may be opened while a writer appends (WAL).
  // Opening for writing removes pyramid rows no reader uses: always those of
  // scans that are gone, and, when no other connection has the file open,
  // those of unfinished pyramids (format-spec/archive.md §9).
  static Result<std::unique_ptr<Archive>> open(const std::string& path, Mode mode);

  // Closing a handle that wrote folds SQLite's write-ahead log into the file
  // and leaves WAL mode, so the archive is one file again; the destructor
  // does so and ignores failures, close() reports them.
  virtual ~Archive() = default;
  virtual const std::string& path() const = 0;

  // Ends writing: folds the write-ahead log into the file and leaves WAL mode
  // (nothing to do for a read-only handle, or twice). A full disk or another
  // I/O error is a kIoError naming the file: the archive is then intact, but
  // its last writes are in PATH-wal, which must stay beside it until a writer
  // closes it with room on the disk (kept_in_wal_note() says so to a user).
  // Another open connection (a reader) is not an error: the file then stays
  // in WAL mode until a writer closes alone. A writer calls it before it
  // reports success or moves the file.
  virtual Status close() = 0;

  virtual Result<ArchiveInfo> info() const = 0;

  // ---- Writing (read-write handles only; kInvalidArgument otherwise).
  // Starts a scan with its sources and attributes, committed at once with
  // complete = false. The archive's attributes and CRS include the scan's from
  // here on, so the chunks of a run killed before finish_scan read like any.
  virtual Result<std::int64_t> begin_scan(const std::vector<ArchiveSource>& sources,
                                          const ScanAttributes& attributes = {}) = 0;
  // Stores the rows in one transaction: assigns each the next free seq of its
  // voxel key and its id; updates the totals. Either all rows land or none.
  // On an archive this handle opened (not created), a batch is refused with
  // kIoError ("the disk is full") unless the disk and RLIMIT_FSIZE leave room
  // for it plus the removal of every row the handle wrote, so abort_scan can
  // always run.
  virtual Status put_chunks(std::vector<ChunkRow>& rows) = 0;
  // Marks the scan complete (and records its attributes again, as given).
  virtual Status finish_scan(std::int64_t scan_id, bool has_colors, bool has_intensity,
                             const std::string& crs) = 0;
  // Removes every chunk and source of the scan in one transaction (a failed append).
  virtual Status abort_scan(std::int64_t scan_id) = 0;
  // Records the points read from the scan's one source, known only at its
  // end (a stream's). kInvalidArgument when the scan does not exist or has
  // more than one source.
  virtual Status set_source_points(std::int64_t scan_id, std::uint64_t points) = 0;

  // ---- The level-of-detail pyramid (format-spec/archive.md §9).
  // Stores pyramid nodes of `level` (>= 1) in one transaction, like
  // put_chunks (each row's ref.key on that level's grid, ref.scan_id an
  // existing scan); creates the pyramid tables on first use.
  virtual Status put_level_chunks(int level, std::vector<ChunkRow>& rows) = 0;
  // Records that the scan's pyramid is complete with the levels whose bits
  // are set in `levels` (bit L: level L; a level that would hold nearly as
  // many points as the one below is not stored): from then on readers use
  // it. Until then its level rows are ignored.
  virtual Status finish_pyramid(std::int64_t scan_id, std::uint64_t levels) = 0;
  // Removes the scan's pyramid (rows and record, finished or not), e.g.
  // before a rebuild (build_pyramid starts with it).
  virtual Status remove_pyramid(std::int64_t scan_id) = 0;

  // ---- Reading.
  // Lists of refs come in content order (format-spec/archive.md §4: scan,
  // level, chunk key, then the blob's bounds and sizes, the id last), not in
  // id order: archives with the same blobs list them alike whatever order
  // their writer committed them in.
  // Chunks whose decoded-point bounds intersect `box` (closed boxes), through
  // the spatial index.
  virtual Result<std::vector<ChunkRef>> find_chunks(const Box3d& box) const = 0;
  virtual Result<std::vector<ChunkRef>> all_chunks() const = 0;
  // The scan's chunks (level 0).
  virtual Result<std::vector<ChunkRef>> scan_chunks(std::int64_t scan_id) const = 0;
  // Pyramid nodes of `level` whose bounds intersect `box`, of scans with a
  // finished pyramid (refs have `level` set).
  virtual Result<std::vector<ChunkRef>> find_level_chunks(int level, const Box3d& box) const = 0;
  // Reads one pyramid node's blob, checked like read_chunk.
  virtual Result<ChunkRow> read_level_chunk(std::int64_t id) const = 0;
  // Reads one blob and verifies its CRC-32: a mismatch is kCorruptData naming
  // the chunk (key, seq, id) and the archive file.
  virtual Result<ChunkRow> read_chunk(std::int64_t id) const = 0;
  // The first `max_bytes` bytes of a chunk's blob (all of it when shorter),
  // read without the rest (SQLite's incremental blob I/O: the first pages
  // of its overflow chain), so not checked against its CRC-32. For a
  // blob's header and section table (inspect_chunk_head).
  virtual Result<std::vector<std::uint8_t>> read_chunk_head(std::int64_t id, std::size_t max_bytes) const = 0;
  // Blob bytes read by read_chunk so far (for tests and benchmarks).
  virtual std::uint64_t blob_bytes_read() const = 0;
};

// What `check_archive` looked at and what it found damaged.
struct ArchiveCheck {
  int format_version = 0;
  std::vector<std::string> checked;   // one line per check made
  std::vector<std::string> problems;  // one line per damage found; empty = intact
};

// What check_archive is doing, for a progress display: the stage (a short
// text: "SQLite integrity check", "chunk blobs", "pyramid nodes", "spatial
// index", "spatial index tree") and, in the stages that go chunk by chunk,
// how many of `total` are done; total 0: a stage that is not counted, but
// for the SQLite integrity check, whose `done` is the pages SQLite has read
// so far (no total: it may read a page more than once). Called on the
// caller's thread, at each stage's start, after every chunk and, in the
// SQLite check, every few thousand of SQLite's instructions.
using CheckProgress = std::function<void(const char* stage, std::uint64_t done, std::uint64_t total)>;

// What a chunk row says against what its blob holds, for check_archive to
// ask of each blob whose CRC-32 matches (the store keeps blobs opaque: the
// codec answers: relief::chunk_row_check in relief/query.h). Returns
// the damage found, empty when the row and its blob agree.
using ChunkRowCheck = std::function<std::string(const ChunkRef& row, std::span<const std::uint8_t> blob)>;

// Checks a whole archive without trusting any part of it: SQLite's own
// integrity check, the metadata checksum (absent in version 1), the CRS
// checksum (from version 3), every blob's CRC-32, each chunk row's codec,
// scan (one that exists) and bounds (within its key's cube of the grid),
// `row_check` on each row and blob when given, and the spatial index
// against the chunk table (every chunk with bounds has exactly one index
// entry with those bounds, found by a box query; every entry names a chunk).
// Damage goes to `problems`; an error is returned only when the file cannot
// be checked at all (missing, not an archive, newer version). Reads only.
Result<ArchiveCheck> check_archive(const std::string& path, const CheckProgress& progress = nullptr,
                                   const ChunkRowCheck& row_check = nullptr);

}  // namespace relief
