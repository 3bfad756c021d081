// Point-file readers and writers.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "relief/status.h"
#include "relief/types.h"

namespace relief {

enum class PlyEncoding { kAscii, kBinaryLittleEndian, kBinaryBigEndian };
enum class PlyCoordinateType { kFloat32, kFloat64 };

struct PlyWriteOptions {
  PlyEncoding encoding = PlyEncoding::kBinaryLittleEndian;
  PlyCoordinateType coordinate_type = PlyCoordinateType::kFloat64;
};

// Reads the `vertex` element of a PLY file (ascii, binary little or big endian):
// x y z as any numeric type, optional red green blue (uchar, or ushort which is
// shifted to 8 bits when any value exceeds 255), optional intensity (any numeric
// type, stored as float). Other properties and elements, including list
// properties such as faces, are skipped. Errors name `path` and the problem.
Result<PointCloud> read_ply(const std::string& path);
// The same from memory; `name` is used in error messages.
Result<PointCloud> read_ply_memory(std::span<const std::uint8_t> data, const std::string& name);

// Writes `cloud` as PLY: x y z, and red green blue (uchar) and intensity
// (float) when it carries them; its LAS attributes and colour low bytes are
// not written (open_point_writer writes every attribute). The file appears
// atomically: it is written beside the target and renamed, and nothing is
// left behind on failure.
Status write_ply(const std::string& path, const PointCloud& cloud, const PlyWriteOptions& options = {});

// Writes `data` (a chunk blob, a PNG ...) to `path` as every writer here
// writes its file: under a temporary name of this host and process beside
// the target, then renamed, so the file appears whole or not at all, even
// when several hosts write into one shared directory ("-": standard output).
Status write_file(const std::string& path, std::span<const std::uint8_t> data);

// Reads any supported point file, chosen by extension (see open_point_reader).
Result<PointCloud> read_point_file(const std::string& path);

// ---- Streaming readers: inputs far larger than memory are read in batches.

struct PointStreamInfo {
  std::string path;
  std::string format;                        // "ply", "las", "laz", "xyz", "pcd", "ptx", "e57"
  std::optional<std::uint64_t> point_count;  // when the header states it
  bool has_colors = false;
  bool has_intensity = false;
  // Coordinate reference system (LAS only; relief/crs.h) as WKT2, from the
  // LAS WKT VLR or GeoTIFF keys; empty when the file has none. A WKT that
  // PROJ cannot read is kept as the file gave it (with a warning).
  std::string crs;
  // The CRS as the file gave it (relief/crs.h "source form"): the WKT text,
  // or "GeoTIFF VLRs: ..." with the key records verbatim.
  std::string crs_source;
  std::optional<Box3d> header_bounds;        // LAS header min/max
  // LAS/LAZ only: the point data record format (0-10) and LAS minor version
  // of the source (-1 otherwise), the LasAttributeBits every batch carries,
  // and the raw payload of the Extra Bytes VLR (LASF_Spec, record 4; empty
  // when the file has none) describing PointCloud::las.extra_bytes.
  int las_point_format = -1;
  int las_version_minor = -1;
  std::uint32_t las_attributes = 0;
  std::string extra_bytes_vlr;
  // Extra bytes per point record (LasAttributes::extra_bytes_size); 0 when none.
  std::uint32_t extra_bytes_size = 0;
  // LAS/LAZ with RGB: the file stores 8-bit levels (0..255) in its 16-bit
  // colour fields (the colour rule kept them unshifted), so a LAS writer
  // should write each level as it is rather than (colour << 8) | low.
  // Known once read() has returned points (the rule samples them).
  bool las_colors_8bit = false;
  // LAS/LAZ with RGB: every colour level of the file is 0 (no point, or a
  // scanner without a camera), as far as the rule's sample shows and the
  // sample held every point: either rule gives such levels back alike, so
  // an archive of other inputs' 16-bit levels changes none of them.
  bool las_colors_all_zero = false;
  // LAS/LAZ whose points carry GPS time: what the times count (the header's
  // global encoding bit 0); kUnknown otherwise.
  GpsTimeType las_gps_time_type = GpsTimeType::kUnknown;
  // LAS/LAZ: the header block and the VLRs and extended VLRs kept
  // (LasSourceMetadata; a record over kMaxKeptLasRecord bytes, or past
  // kMaxKeptLasRecords in all, is not kept, with a warning). Extended VLRs
  // are read from files, not from pipes.
  LasSourceMetadata las_metadata;
  // Coordinate precision the file stores (LAS scale factors), 0 when not known,
  // and the offset of that grid (LAS: x = X * scale + offset).
  Vec3d scale{0, 0, 0};
  Vec3d offset{0, 0, 0};
  // Records dropped so far by design rather than error: PCD points with a NaN
  // coordinate (organised clouds mark pixels without depth that way), PTX
  // lines 0 0 0 (directions without a return), E57 records whose invalid
  // state is 1 or 2 (a direction without a range, no return). They are
  // included in point_count, which is what the header declares.
  std::uint64_t skipped_points = 0;
  // The points are decimal text (XYZ/CSV/PTS, PTX, ASCII PLY and PCD): a
  // second read parses them all again, so a pass before the ingest keeps
  // what it read in its spool (IngestOptions::spool).
  bool text_body = false;
  // Things the reader noticed but did not refuse, each a sentence naming the
  // file, e.g. a PLY whose vertex records go on past the count its header
  // declares (the header count is kept). Complete once read() has returned 0.
  std::vector<std::string> warnings;
};

struct ReaderOptions {
  // ASCII XYZ/CSV: the meaning of each column, comma separated, from x y z
  // r g b i (intensity) c (classification, 0..255, into las.classification),
  // the LAS dimensions by their LAS or PDAL names (gps_time, return_number,
  // ScanAngleRank ..., into PointCloud::las, range-checked), name:type (a
  // column kept as LAS extra bytes under that name, type u8 i8 u16 i16 u32
  // i32 u64 i64 f32 f64, each value checked to fit it; refused with
  // extra_bytes off) and _ (skip).
  // Unset: the names of a header line (the first line when it is not
  // numeric, or a comment line such as "//X,Y,Z,R,G,B" naming x, y and z;
  // names in any case, red/green/blue, intensity/reflectance and their
  // initials, the LAS dimensions), and every other named column whose first
  // value is a number is kept as a float64 field of extra bytes (see
  // extra_bytes); else "x,y,z". Columns may be
  // separated by commas, semicolons, tabs or spaces; lines starting with '#'
  // or '//' and a first line that is not numeric (a header) are skipped.
  // Colour levels are 0..255, or 0..65535 shifted to 8 bits by the 16-bit
  // rule when the first 2^20 points hold a level above 255.
  std::optional<std::string> xyz_columns;
  // Keep each point's extra bytes: LAS/LAZ extra bytes, and the PLY vertex
  // properties, PCD fields and XYZ/CSV header columns other than x y z,
  // colour, intensity (and, for text, the LAS dimensions): normals, labels,
  // curvature, alpha ..., which those readers deliver as LAS extra bytes
  // described by an Extra Bytes VLR. Off: none are delivered.
  bool extra_bytes = true;
  // The attributes delivered beside x, y and z (relief compress
  // --attributes): the others are dropped as the points are read and are
  // not in info(). The colour low bytes go with the colours.
  AttributeSet attributes;
  // For a pass that uses only x, y and z: LAZ of LAS 1.4 point formats 6-10
  // then decodes only the layers of x, y and z (LASzip's selective
  // decompression; 2-3x less work), and every other value of a chunk's
  // points repeats its first point's. Do not use anything but the
  // positions of what such a reader returns. Other formats read as usual.
  bool positions_only = false;
  // Memory (bytes) a reader of colour levels that may be 16-bit (LAS, LAZ,
  // PLY, text) may hold to settle the colour rule above in one pass when it
  // is read in batches smaller than the rule's sample: the sample's points
  // are then decoded once, kept, and handed out batch by batch. With 0 (or a
  // sample needing more, about 64 bytes a point plus the extra bytes) the
  // sample is decoded twice, once through a second handle to decide, then as
  // it is read: for LAZ, the first 2^20 points' decompression done twice.
  // relief compress and append allow an eighth of their memory budget.
  std::uint64_t color_sample_memory = 0;
  // LAZ: the threads that decompress chunks side by side (one chunk each),
  // 0 for every core; at most 4 either way. relief compress and append pass
  // their --threads.
  unsigned decode_threads = 0;
};

class PointReader {
 public:
  virtual ~PointReader() = default;
  virtual const PointStreamInfo& info() const = 0;
  // Replaces `batch` with the next up to `max_points` points (attributes as
  // info() says). Returns how many were read; 0 at the end. Errors name the file
  // and the point index. A file shorter than its header declares is an error.
  virtual Result<std::size_t> read(PointCloud& batch, std::size_t max_points) = 0;
};

// Opens a point file for streaming, by extension: .ply, .las, .xyz/.txt/.csv/
// .pts, .pcd (ascii, binary and binary_compressed; field names in any case;
// packed rgb/rgba or separate r g b fields), .laz (LASzip-compressed LAS, COPC
// included; see relief/laz.h for what is supported), .ptx (Leica's scans, each
// scan's matrix applied), .e57 (ASTM E2807 3D scans, each scan's pose
// applied; the default bitpack codec; a regular file, not a pipe). Unknown
// extensions give kUnsupported.
Result<std::unique_ptr<PointReader>> open_point_reader(const std::string& path,
                                                       const ReaderOptions& options = {});

// Whether `path` names a file open_point_reader reads, by its extension
// (any case).
bool is_point_file_name(const std::string& path);

// The point files `inputs` name: a file (or a missing path, which the reader
// then names) as it is; a directory, the regular files directly in it whose
// extension open_point_reader takes (any case; names starting with '.'
// skipped), sorted by name, so a folder of tiles is one argument however many
// it holds. A directory without such files is kInvalidArgument, one that
// cannot be listed kIoError. compress_files, append_files and plan_shards
// expand their inputs with it.
Result<std::vector<std::string>> expand_inputs(const std::vector<std::string>& inputs);

// The paths listed in the text file `path`, one a line (blank lines and lines
// starting with '#' skipped, surrounding blanks trimmed): `--input-list`, for
// more inputs than a command line holds. An empty list is kInvalidArgument.
Result<std::vector<std::string>> read_input_list(const std::string& path);

// One line of XYZ/CSV text at a time: what `relief stream` reads from a pipe
// as it arrives. The columns are those of a spec as ReaderOptions::xyz_columns
// names them (x y z, r g b, i, c, the LAS dimensions by name, name:type extra
// fields, _ to skip), separated by any run of blanks, ',' and ';'; colour
// levels are 0..255 (a level outside is an error, never clamped).
class TextLineParser {
 public:
  // kInvalidArgument for a spec that names an unknown column, one twice, or
  // lacks x, y or z; `name` names the input in messages (e.g. "stdin").
  static Result<std::unique_ptr<TextLineParser>> create(const std::string& spec, const std::string& name);
  virtual ~TextLineParser() = default;
  virtual bool colors() const = 0;
  virtual bool intensity() const = 0;
  virtual std::uint32_t las_attributes() const = 0;  // LasAttributeBits the columns fill
  // The name:type columns' Extra Bytes VLR payload and bytes per point (empty
  // and 0 when there are none).
  virtual const std::string& extra_bytes_vlr() const = 0;
  virtual std::uint32_t extra_bytes_size() const = 0;
  // Appends the point of `line` to `batch` (its colours, intensities and LAS
  // attributes as the columns say). A missing column, a value that is not a
  // number or is out of its range is an error naming the input and line_no,
  // and `batch` is unchanged.
  virtual Status parse(std::string_view line, std::uint64_t line_no, PointCloud& batch) const = 0;
  // What the lines parsed since the last call gave a warning for, once each
  // (the first intensity a 32-bit float does not give back, as the XYZ
  // reader's info().warnings), taken out.
  virtual std::vector<std::string> take_warnings() = 0;
};

// Fixed-size little-endian binary records, one point each: what `relief
// stream --format binary` reads from a pipe. A record is f64 x, y, z, then
// the fields `spec` lists, comma separated, in its order:
//   rgb                          3 x u8 (levels 0..255)
//   intensity (or i)             f32
//   gps_time                     f64
//   scan_angle                   f32, degrees (-180..180)
//   point_source_id, nir         u16
//   every other LAS dimension    u8: classification, return_number,
//     number_of_returns, scanner_channel, user_data, and the 0/1 flags
//     synthetic, key_point, withheld, overlap, scan_direction_flag,
//     edge_of_flight_line
//   _N                           N bytes skipped (1..1024: padding, fields
//                                not kept)
//   name:type                    a field kept as LAS extra bytes under its
//                                name (at most 32 bytes): type u8 i8 u16
//                                i16 u32 i32 u64 i64 f32 f64 (amplitude:f32,
//                                ring:u16 ...)
// LAS dimensions go by the names the text columns take (relief/io.h
// ReaderOptions::xyz_columns). When both are named, rgb comes before
// intensity (the record order this format has always had).
class BinaryRecordParser {
 public:
  // kInvalidArgument naming the field for a spec with an unknown name, a
  // name twice, x/y/z (always first, not listed) or intensity before rgb;
  // `name` names the input in messages (e.g. "stdin").
  static Result<std::unique_ptr<BinaryRecordParser>> create(const std::string& spec, const std::string& name);
  virtual ~BinaryRecordParser() = default;
  virtual std::size_t record_size() const = 0;
  virtual bool colors() const = 0;
  virtual bool intensity() const = 0;
  virtual std::uint32_t las_attributes() const = 0;  // LasAttributeBits the fields fill
  // The extra bytes fields (kLasExtraBytes): their Extra Bytes VLR payload
  // and bytes per point (0 and empty when none).
  virtual const std::string& extra_bytes_vlr() const = 0;
  virtual std::uint32_t extra_bytes_size() const = 0;
  // Appends the point of the record_size() bytes at `record` to `batch`. A
  // non-finite coordinate or intensity, or a LAS dimension out of its range,
  // is an error naming the input and record_no (`relief stream` counts from
  // 1), and `batch` is unchanged.
  virtual Status parse(const std::uint8_t* record, std::uint64_t record_no, PointCloud& batch) const = 0;
};

// ---- LAS extra bytes

// One field of a LAS Extra Bytes VLR (LASF_Spec record 4; ASPRS LAS 1.4 R15,
// section 2.5): a 192-byte descriptor per field, the fields laid out in order
// in the extra bytes of every point record.
struct ExtraBytesField {
  std::string name;         // up to 32 characters
  std::string description;  // up to 32 characters
  int data_type = 0;        // 0 = undocumented bytes (options = size), 1-10 scalars, 11-30 arrays (deprecated)
  std::uint8_t options = 0; // bit 0 no_data, 1 min, 2 max, 3 scale, 4 offset are meaningful
  std::size_t offset = 0;   // of the field within a point's extra bytes
  std::size_t size = 0;     // bytes per point
  // Type name ("uint8", "int16", "float64", "uint32[3]", "bytes[5]", ...).
  std::string type_name;
  // Scale and offset of the first component (1 and 0 when options say none).
  double scale = 1;
  double value_offset = 0;
};

// Parses an Extra Bytes VLR payload. kFormatError naming `what` when the
// payload is not a whole number of 192-byte descriptors, a data type is
// reserved (> 30), a size is 0, or the fields need more than `record_extra`
// bytes per point (the bytes the point records have beyond their format).
Result<std::vector<ExtraBytesField>> parse_extra_bytes_vlr(std::span<const std::uint8_t> payload,
                                                           std::size_t record_extra, const std::string& what);

// The inverse: an Extra Bytes VLR payload describing `fields` in order (name,
// description, data_type, options, and scale/offset when the options say so;
// offset, size and type_name are implied and ignored). kInvalidArgument when
// there are more fields than one VLR holds (65535 bytes: 341), a name or
// description is longer than 32 bytes, or a data type is outside 0..30.
Result<std::string> make_extra_bytes_vlr(const std::vector<ExtraBytesField>& fields);
// Bytes per point of one field of data type 1..30 (0 for type 0, whose size
// is its options byte, and for reserved types).
std::size_t extra_bytes_type_size(int data_type);
// The scalar type 1..10 of each component of data type 1..30 (the
// deprecated array types 11..30 repeat 1..10 two or three times); 0 for
// type 0 (undocumented bytes) and reserved types.
int extra_bytes_base_type(int data_type);

// ---- Streaming writers: outputs larger than memory are written in batches.

struct WriterOptions {
  bool colors = false;
  bool intensity = false;
  // A file the points are read from (an archive being queried): the writer
  // refuses a destination that is that file (the same device and inode, by
  // whatever name), which renaming its output into place would replace.
  std::string read_from;
  // LAS: coordinate reference system to write back: WKT (1 or 2), or from
  // older archives "EPSG:<code>" or "GeoTIFF keys: <key>=<value>, ...".
  std::string crs;
  // LAS: how the source gave the CRS (PointStreamInfo::crs_source). GeoTIFF
  // records are written back verbatim, a WKT source as its WKT; empty: as crs.
  std::string crs_source;
  // LAS: bounds of the data to come (to choose offset and to check that the
  // scale fits int32); an empty box lets the writer choose from the first batch.
  Box3d expected_bounds;
  // LAS: coordinate resolution (scale factor). 0 = automatic: 0.1 mm (finer
  // than any map pixel Relief produces, so decoded coordinates survive), or the
  // smallest power of ten that keeps the extent within 32-bit integers.
  double scale = 0;
  // LAS: when set, these per-axis scales and offsets exactly (an error-bounded
  // archive's grid, so LAS integers written back are the source's).
  std::optional<Vec3d> grid_scale;
  std::optional<Vec3d> grid_offset;
  // LAS: grid_offset is the offset of every source the points came from
  // (LAS files of that scale and offset), whose integers all fit it: it is
  // kept whatever expected_bounds says (a box that may reach beyond the
  // points, as an archive's chunk bounds do), each point still checked as it
  // is written. Otherwise a grid offset that cannot hold expected_bounds is
  // moved by a whole number of steps.
  bool grid_offset_exact = false;
  PlyEncoding ply_encoding = PlyEncoding::kBinaryLittleEndian;
  // LAZ: the threads that compress chunks side by side (whole chunks of
  // 50,000 points gathered, one a thread; the bytes do not change), 0 for
  // every core; at most 4 either way.
  unsigned threads = 0;
  // The per-point LAS attributes (LasAttributeBits) every batch carries and
  // the file records (LAS/LAZ; PLY, ASCII or binary, and text write them as
  // properties and columns, see the README); the source's point format and LAS minor
  // version (-1: none, e.g. an archive made from PLY), from which the output
  // format is chosen (see open_point_writer); the Extra Bytes VLR payload
  // describing las.extra_bytes, extra_bytes_size bytes per point (written
  // back as the file's Extra Bytes VLR; empty: the extra bytes are written
  // undocumented).
  std::uint32_t las_attributes = 0;
  int las_point_format = -1;
  int las_version_minor = -1;
  std::string extra_bytes_vlr;
  std::uint32_t extra_bytes_size = 0;
  // LAS/LAZ: write colour levels as the 8-bit values themselves (the source
  // stored 8-bit levels in its 16-bit fields, PointStreamInfo::las_colors_8bit).
  bool las_colors_8bit = false;
  // LAS/LAZ with GPS time: the header's global encoding bit 0 is set for
  // kStandard (adjusted standard GPS time) and clear for kWeek, as the source
  // said; kUnknown lets the times say: clear when every one lies in
  // 0..604800 (seconds of a week), else set (a file of no points: set with
  // formats 6-10 only, as LAS 1.4 asks of new files).
  GpsTimeType las_gps_time_type = GpsTimeType::kUnknown;
  // LAS/LAZ: what the sources said of themselves (LasSourceMetadata, in
  // source order). The file gives back each of the header's file source ID,
  // project ID (GUID), system identifier, creation day and year and, in LAS
  // 1.4, global encoding bit 3 (synthetic return numbers) that every source
  // with a header agrees on (else Relief's own: 0, "Relief", the day it
  // writes); and each kept record once (the first of equal ones), after
  // Relief's own VLRs: an extended VLR as one in LAS 1.4 output, else as a
  // VLR; a record too large for a VLR makes the file LAS 1.4.
  std::vector<LasSourceMetadata> las_sources;
};

class PointWriter {
 public:
  virtual ~PointWriter() = default;
  // Appends points; a batch must carry exactly the attributes the options name.
  virtual Status write(const PointCloud& batch) = 0;
  // Completes the file (counts, bounds) and moves it into place. Without
  // finish() (or on any error) the destination is left untouched.
  virtual Status finish() = 0;
  virtual std::uint64_t points_written() const = 0;
  // What the format could not hold as it was given, said once finish()
  // succeeded (a LAS intensity clamped to 0..65535 or rounded to a whole
  // number, ...); taken out. None by default.
  virtual std::vector<std::string> take_warnings() { return {}; }
};

// Opens a writer by extension: .ply (binary little endian by default),
// .las and .laz: the source's point format where it can (its legacy format
// 0-3 in LAS 1.2, with GPS time and RGB as carried; wave packets are not
// kept, so 4/5 become 1/3), LAS 1.4 with format 6, 7 or 8 where it must (the
// source was 6-10, NIR is carried, a WKT CRS in a .las, or LAS attributes
// without a source format); without LAS
// attributes LAS 1.2 format 2/0, or 1.4 formats 7/6 when the CRS is WKT.
// .xyz/.txt/.csv (text "x y z [r g b] [i]"). "-" writes XYZ text to stdout.
// The file is written beside the destination and renamed by finish().
Result<std::unique_ptr<PointWriter>> open_point_writer(const std::string& path, const WriterOptions& options);

// kInvalidArgument when `output` exists and is `input` (the same device and
// inode, by whatever name): an output renamed into place there would replace
// the file being read.
Status refuse_output_onto_input(const std::string& output, const std::string& input);

}  // namespace relief
