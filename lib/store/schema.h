// The archive schema, format version 2 (format-spec/archive.md, section 2).
// Kept in one place so the spec's CREATE statements and the writer agree.
#pragma once

#include <array>
#include <string_view>

namespace relief::store {

// Tables a version-1 reader needs; open() refuses a file that lacks one.
inline constexpr std::array<std::string_view, 5> kRequiredTables = {
    "relief_meta", "relief_scan", "relief_source", "relief_chunk", "relief_chunk_index"};

// Run inside the creating transaction, after the header pragmas.
//
// AUTOINCREMENT on scans and chunks: ids are never reused after abort_scan, so
// an id a reader saw can never name a different chunk later.
// relief_meta is keyed by its key alone (WITHOUT ROWID: no second b-tree
// for the key's uniqueness), and relief_source, a row per input file, has no
// index on scan_id (archives before 2026-11-27 have one, relief_source_scan),
// and relief_chunk's index on scan_id comes with the second scan
// (kCreateChunkScanIndexSql): each of those took a page of every archive.
// The blob is the last column of relief_chunk: SQLite stores a row's columns
// in order and a large blob spills to overflow pages, so index scans and
// length(blob) read the other columns without touching the blob's pages.
inline constexpr char kCreateSchemaSql[] = R"sql(
CREATE TABLE relief_meta (
  key   TEXT PRIMARY KEY NOT NULL,
  value TEXT NOT NULL
) WITHOUT ROWID;
CREATE TABLE relief_scan (
  id            INTEGER PRIMARY KEY AUTOINCREMENT,
  created_at    TEXT NOT NULL,
  complete      INTEGER NOT NULL DEFAULT 0 CHECK (complete IN (0, 1)),
  has_rgb       INTEGER NOT NULL DEFAULT 0 CHECK (has_rgb IN (0, 1)),
  has_intensity INTEGER NOT NULL DEFAULT 0 CHECK (has_intensity IN (0, 1)),
  crs           TEXT NOT NULL DEFAULT ''
);
CREATE TABLE relief_source (
  id          INTEGER PRIMARY KEY,
  scan_id     INTEGER NOT NULL REFERENCES relief_scan(id),
  path        TEXT NOT NULL,
  format      TEXT NOT NULL,
  point_count INTEGER NOT NULL CHECK (point_count >= 0),
  crs         TEXT NOT NULL DEFAULT ''
);
CREATE TABLE relief_chunk (
  id             INTEGER PRIMARY KEY AUTOINCREMENT,
  ix             INTEGER NOT NULL,
  iy             INTEGER NOT NULL,
  iz             INTEGER NOT NULL,
  seq            INTEGER NOT NULL CHECK (seq BETWEEN 0 AND 4294967295),
  scan_id        INTEGER NOT NULL REFERENCES relief_scan(id),
  min_x          REAL,
  min_y          REAL,
  min_z          REAL,
  max_x          REAL,
  max_y          REAL,
  max_z          REAL,
  input_points   INTEGER NOT NULL CHECK (input_points >= 0),
  decoded_points INTEGER NOT NULL CHECK (decoded_points >= 0),
  codec          INTEGER NOT NULL,
  codec_params   TEXT NOT NULL DEFAULT '',
  crc32          INTEGER NOT NULL CHECK (crc32 BETWEEN 0 AND 4294967295),
  blob           BLOB NOT NULL,
  UNIQUE (ix, iy, iz, seq)
);
CREATE VIRTUAL TABLE relief_chunk_index USING rtree(id, min_x, max_x, min_y, max_y, min_z, max_z);
)sql";

// Chunks by scan, for removing or listing one scan's chunks among others':
// created when a second scan begins (archives before 2026-11-28 have it from
// the start). With one scan, those are all the rows and the index would only
// take a page of every small archive.
inline constexpr char kCreateChunkScanIndexSql[] =
    "CREATE INDEX IF NOT EXISTS relief_chunk_scan ON relief_chunk(scan_id)";

// Version 2: a plain b-tree over the exact bounds. Box queries take their
// candidates from the R*Tree and check them against this index, so a damaged
// R*Tree cannot make a query miss a chunk silently. Covering (the id is the
// rowid), so the check never reads chunk rows.
inline constexpr char kBoundsIndex[] = "relief_chunk_bounds";
inline constexpr char kCreateBoundsIndexSql[] =
    "CREATE INDEX IF NOT EXISTS relief_chunk_bounds ON relief_chunk(min_x, max_x, min_y, max_y, min_z, max_z)";

// The exact bounds of the points a full decode of a chunk returns, for the
// chunks whose row bounds (which cover the base layer a coarse level of detail
// decodes too) are wider (format-spec/archive.md §2.6). An optional table,
// created by the first writer that stores such a chunk: readers that do not
// know it take the row bounds, which contain these, so the format version
// does not change. A row whose id names no chunk is ignored.
inline constexpr char kExtentTable[] = "relief_chunk_extent";
inline constexpr char kCreateExtentSql[] = R"sql(
CREATE TABLE IF NOT EXISTS relief_chunk_extent (
  id    INTEGER PRIMARY KEY,
  min_x REAL NOT NULL,
  min_y REAL NOT NULL,
  min_z REAL NOT NULL,
  max_x REAL NOT NULL,
  max_y REAL NOT NULL,
  max_z REAL NOT NULL
);
)sql";

// The level-of-detail pyramid (format-spec/archive.md §9). Optional tables,
// created by the first writer that stores a pyramid: readers that do not know
// them read the archive's full-resolution chunks as before, so the format
// version does not change. A pyramid level row is used only once its scan has
// a relief_level_scan row (written last, in the same transaction as nothing
// else) and that scan still exists.
inline constexpr char kLevelChunkTable[] = "relief_level_chunk";
inline constexpr char kLevelScanTable[] = "relief_level_scan";
inline constexpr char kCreatePyramidSql[] = R"sql(
CREATE TABLE IF NOT EXISTS relief_level_chunk (
  id             INTEGER PRIMARY KEY AUTOINCREMENT,
  level          INTEGER NOT NULL CHECK (level BETWEEN 1 AND 40),
  ix             INTEGER NOT NULL,
  iy             INTEGER NOT NULL,
  iz             INTEGER NOT NULL,
  seq            INTEGER NOT NULL CHECK (seq BETWEEN 0 AND 4294967295),
  scan_id        INTEGER NOT NULL REFERENCES relief_scan(id),
  min_x          REAL,
  min_y          REAL,
  min_z          REAL,
  max_x          REAL,
  max_y          REAL,
  max_z          REAL,
  input_points   INTEGER NOT NULL CHECK (input_points >= 0),
  decoded_points INTEGER NOT NULL CHECK (decoded_points >= 0),
  codec          INTEGER NOT NULL,
  codec_params   TEXT NOT NULL DEFAULT '',
  crc32          INTEGER NOT NULL CHECK (crc32 BETWEEN 0 AND 4294967295),
  blob           BLOB NOT NULL,
  UNIQUE (level, ix, iy, iz, seq)
);
CREATE INDEX IF NOT EXISTS relief_level_chunk_bounds
  ON relief_level_chunk(level, min_x, max_x, min_y, max_y, min_z, max_z, scan_id);
CREATE INDEX IF NOT EXISTS relief_level_chunk_scan ON relief_level_chunk(scan_id);
CREATE TABLE IF NOT EXISTS relief_level_scan (
  scan_id INTEGER PRIMARY KEY REFERENCES relief_scan(id),
  levels  INTEGER NOT NULL CHECK (levels BETWEEN 2 AND 2199023255550)
);
)sql";

// What LAS sources said of themselves (format-spec/archive.md §2.3.1): an
// optional table, created by the first writer that records a LAS source.
// Readers that do not know it lose nothing but those records. Rows of a
// source come in rowid order: its header block (kind 0) first, then its
// records as the file had them (kind 1 a VLR, 2 an extended VLR).
inline constexpr char kSourceLasTable[] = "relief_source_las";
inline constexpr char kCreateSourceLasSql[] = R"sql(
CREATE TABLE IF NOT EXISTS relief_source_las (
  source_id   INTEGER NOT NULL REFERENCES relief_source(id),
  kind        INTEGER NOT NULL CHECK (kind IN (0, 1, 2)),
  user_id     BLOB NOT NULL,
  record_id   INTEGER NOT NULL CHECK (record_id BETWEEN 0 AND 65535),
  description BLOB NOT NULL,
  data        BLOB NOT NULL
);
)sql";

// relief_meta keys.
inline constexpr char kMetaFormatVersion[] = "format_version";
inline constexpr char kMetaOriginX[] = "grid_origin_x";
inline constexpr char kMetaOriginY[] = "grid_origin_y";
inline constexpr char kMetaOriginZ[] = "grid_origin_z";
inline constexpr char kMetaChunkEdge[] = "chunk_edge";
inline constexpr char kMetaCodecParams[] = "codec_params";
inline constexpr char kMetaCreator[] = "creator";
inline constexpr char kMetaCreatedAt[] = "created_at";
// Versions 1 and 2: the archive's CRS (that of the earliest scan with one).
inline constexpr char kMetaCrs[] = "crs";
// Version 2: how the first source with the archive's CRS gave it (relief/crs.h
// "source form"): its relief_source.crs. Absent in archives written before it.
inline constexpr char kMetaCrsSource[] = "crs_source";
// Version 3, in place of the two: the CRC-32 of the CRS and its source form as
// read from relief_scan and relief_source (format-spec/archive.md, section
// 2.1), as 8 upper-case hexadecimal digits.
inline constexpr char kMetaCrsChecksum[] = "crs_crc32";
inline constexpr char kMetaAttributes[] = "attributes";
// Version 2: CRC-32 of every other relief_meta row (format-spec/archive.md,
// section 2.1), as 8 upper-case hexadecimal digits.
inline constexpr char kMetaChecksum[] = "meta_crc32";

// LAS attributes (format-spec/archive.md 2.1): absent in archives written
// before them, which carry none. las_attributes: comma-separated names
// (kLasAttributeNames); las_point_format, las_version_minor,
// las_extra_bytes_size: decimal; las_extra_bytes_vlr: the Extra Bytes VLR
// payload in lower-case hexadecimal; las_colors_8bit: "1" or "0";
// las_gps_time_type: "week" or "standard" (absent: not known).
inline constexpr char kMetaLasAttributes[] = "las_attributes";
inline constexpr char kMetaLasPointFormat[] = "las_point_format";
inline constexpr char kMetaLasVersionMinor[] = "las_version_minor";
inline constexpr char kMetaLasExtraBytesVlr[] = "las_extra_bytes_vlr";
inline constexpr char kMetaLasExtraBytesSize[] = "las_extra_bytes_size";
inline constexpr char kMetaLasColors8bit[] = "las_colors_8bit";
inline constexpr char kMetaLasGpsTimeType[] = "las_gps_time_type";

// Names in the comma-separated `attributes` value.
inline constexpr char kAttributeRgb[] = "rgb";
inline constexpr char kAttributeIntensity[] = "intensity";

}  // namespace relief::store
