// Filling an archive: out-of-core, parallel ingest of point files, append, and
// live streaming (Golla & Klein 2015, section III-A).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "relief/archive.h"
#include "relief/codec.h"
#include "relief/io.h"
#include "relief/status.h"
#include "relief/types.h"

namespace relief {

struct IngestProgress {
  std::uint64_t points_read = 0;
  std::uint64_t points_total = 0;  // 0 when the inputs do not say
  // Points of the chunks encoded so far (0 while reading; all of them in the
  // "pyramid" and "done" phases): the encoding phase's progress towards
  // points_read.
  std::uint64_t points_encoded = 0;
  // Chunks and blob bytes encoded so far (committed or in the transaction
  // about to be; the pyramid's nodes in its phase).
  std::uint64_t chunks_written = 0;
  std::uint64_t bytes_written = 0;
  double seconds = 0;
  // "scanning" (compress's pass over every point that fixes the grid, when
  // the cell is derived: points_read counts the points scanned, against
  // points_total), then "reading", "encoding", "pyramid", "done"; or
  // "streaming".
  const char* phase = "";
};

// How compress stores points: every point back within a tolerance (chunk
// format 2, the default), or the paper's resampling maps alone (format 1:
// one point per occupied map pixel, the smallest previews).
enum class IngestMode { kBounded, kResample };

// Whether an ingest builds the scan's level-of-detail pyramid (build_pyramid).
enum class PyramidMode { kAuto, kOn, kOff };
// "auto", "on" or "off" (the --pyramid option's words); nullopt for anything else.
std::optional<PyramidMode> pyramid_mode_from_text(std::string_view text);
// kAuto builds a pyramid for scans of at least this many points: below, a
// whole-scan preview decodes in about a second from the chunks themselves.
inline constexpr std::uint64_t kPyramidAutoMinPoints = 10'000'000;


// Tolerance when none is given and no input is LAS: half a millimetre in
// metre units (the 1 mm grid of a typical LAS scale of 0.001).
inline constexpr double kDefaultTolerance = 0.0005;
// In the bounded mode the maps are a coarse base layer for previews and
// levels of detail: cells whose map pixels hold about kBasePointsPerPixel
// points each, measured on the order-free sample while it holds at least
// kMinSamplePointsPerPixel points per such pixel; else (very large inputs),
// kBaseCellFactor times the density-derived cell (~1/16 on a surface). Just
// enough for level of detail kBaseLayerLod (which needs 1/32): the encoder
// snaps the cell down to chunk edge / 2^D (1/17 to 1/31 of the points on the
// shared files) and refines the maps of a chunk that would hold too few.
// Chunks are kDefaultCellsPerChunk density-derived cells across (the same
// chunk edge as the resampling mode).
inline constexpr double kBasePointsPerPixel = 24;
inline constexpr double kMinSamplePointsPerPixel = 1.5;
inline constexpr double kBaseCellFactor = 4;
// Points of the order-independent density sample (bottom of a hash order).
inline constexpr std::size_t kOrderFreeSamplePoints = 1u << 18;
// A chunk holding more points than this is split into octants (recursively)
// before encoding, each its own blob of the same voxel: a rule on the points
// alone, so archives do not depend on --memory. 2^20 (2^22 before
// 2026-11-29): one blob's encoder peaks at ~100 bytes a point, so two of
// 2^20 encode side by side within half the default budget; on dense scans
// the smaller blobs cost 0.2-0.6 % in size and encode 23-55 % faster
// (bench/ingest --dense, bench/README).
inline constexpr std::uint64_t kMaxBoundedChunkPoints = std::uint64_t{1} << 20;

// A new archive's SQLite page size (relief/archive.h): kSmallArchivePageSize
// when its inputs hold at most kSmallArchiveMaxPoints points, kArchivePageSize
// up to kMediumArchiveMaxPoints, kLargeArchivePageSize above. The count is the
// inputs' header counts (a header without one: file bytes / 12), so the
// choice depends on the input files alone, never on the order of their
// points, --memory or --threads; an archive keeps its page size when appended
// to. Streams take kArchivePageSize; a sharded build counts the points its
// plan read. Around a million points the fixed pages an archive saves with
// small pages (~6 KB) are worth what the longer overflow chains cost (0.4 %
// of the blob bytes); around four million, the ~15 pages of 4 KiB every
// archive has (~45 KB more than at 1024) are worth the 0.3 % that 4 KiB
// pages save, and the ingest makes 4x fewer journal and checkpoint calls
// (the 10 M-point survey: 0.11 % smaller, 5-8 % less wall time).
//
// In the bounded mode with the automatic cell and chunk edge, inputs of at most kSmallArchiveMaxPoints points
// (counted exactly by the order-free pass) whose box fits in a chunk of
// kMaxSmallChunkGrowth times the default edge are also one chunk: the edge
// doubles until the box fits.
inline constexpr std::uint64_t kSmallArchiveMaxPoints = std::uint64_t{1} << 20;
inline constexpr std::uint64_t kMediumArchiveMaxPoints = std::uint64_t{1} << 22;
inline constexpr double kMaxSmallChunkGrowth = 4;
std::uint32_t ingest_page_size(std::uint64_t input_points);

// The smallest working-memory budget ingest works in: buffers and encoder
// scratch need this much whatever the input. A smaller
// IngestOptions::memory_budget is raised to it (the CLI refuses one).
inline constexpr std::uint64_t kMinMemoryBudget = std::uint64_t{64} << 20;

struct IngestOptions {
  IngestMode mode = IngestMode::kBounded;
  // Bounded mode: every coordinate within this of its input (coordinate
  // units). 0 = automatic: for LAS inputs half the finest scale among them
  // (the grid is the first LAS input's offset + k * scale, so the LAS integers
  // come back exactly), else kDefaultTolerance on a grid through 0.
  double tolerance = 0;
  // Bounded mode: every colour channel within this many levels (0 = exact).
  int color_tolerance = 0;
  // Bounded mode: every 16-bit intensity within this many levels (0 =
  // exact, up to 32767); float intensities (not whole numbers 0..65535)
  // stay exact.
  int intensity_tolerance = 0;
  // Bounded mode: the points of each chunk come back in the order they were
  // read (the inputs in turn, each file's points in its order), their
  // geometry coded in that order (ErrorBound::keep_order). The archive then
  // depends on the input order; smaller on files in acquisition order
  // without GPS times, larger on others.
  bool keep_order = false;
  // Bounded mode: octree geometry with codec 12 (chunk format 13) instead of
  // codec 13's plane classes (format 16): about twice as fast to encode and
  // decode, ~2 % more geometry bytes (ErrorBound::fast_geometry).
  bool fast_geometry = false;
  // Bounded mode: chunks of more points are split into octants (the archive
  // depends on it as on the tolerance; changed only by tests and tuning).
  std::uint64_t split_points = kMaxBoundedChunkPoints;
  // Codec parameters. cell_size 0 = derived from the point density: in the
  // bounded mode from a sample that depends only on the set of input points
  // (one extra read of the inputs), in the resampling mode from the first
  // input's first points (suggest_cell_size).
  EncodeParams codec;
  // Edge of the world-grid chunks. 0 = kDefaultCellsPerChunk cells.
  double chunk_edge = 0;
  // When > 0: choose codec.cell_size for this RMSE_SNN (coordinate units) by
  // encoding a sample of the first input at trial cell sizes (choose_cell_for_error).
  double error_target = 0;
  // Upper bound for the process's working memory (buffers, two bucket
  // slices, the encoders' scratch). Peak RSS stays near it whatever the input
  // size or density, above a floor of one blob's encoder (README, Limits).
  std::uint64_t memory_budget = std::uint64_t{1} << 30;
  unsigned threads = 0;     // encoder threads; 0 = all cores
  // Decode every blob completely before committing it and compare with what
  // the encoder expects (count and bounds). The index bounds are exact either
  // way (the encoder reconstructs them from its own maps); this adds a full
  // decode, ~10 % of the ingest time, as a belt-and-braces check.
  bool verify_blobs = false;
  // compress_files refuses (kLimitExceeded) a cell size or chunk edge that puts
  // on average fewer than 2 of the first points in a cell or 16 in a chunk: the
  // archive would be many times larger than the input. true skips that check.
  bool allow_sparse = false;
  // Inputs (or an archive and its new inputs) with different CRSs are
  // refused (kInvalidArgument naming both). true: the first input's CRS, or
  // the archive's, is taken for all, with a warning in IngestResult.
  bool assume_crs = false;
  // The inputs' CRS, in any form relief/crs.h reads ("EPSG:32633", WKT,
  // PROJJSON), as PDAL's a_srs: it names the CRS of inputs that give none
  // (XYZ, PLY, PCD, a LAS file without one) and replaces, with a warning, a
  // different one an input gives. Empty: the inputs' own.
  std::string crs;
  std::string tmp_dir;      // temporary bucket files; empty = beside the archive
  // compress_files, bounded mode with the cell derived (the default): the
  // pass that reads every point before the ingest keeps the decoded points
  // of LAZ and text inputs in temporary files (under tmp_dir), and the ingest
  // reads them from there instead of decompressing or parsing each input a
  // second time (28-56 bytes a point of temporary disk for LAS formats 0-8, freed input by
  // input as the ingest reads it). Not when the whole input fits the memory
  // budget (read once anyway), nor when the file system has less than twice
  // that room free, nor after a write error there (then the inputs are read
  // twice, with a warning). false: always read them twice. The archive is
  // the same either way.
  bool spool = true;
  ReaderOptions reader;
  // Called from the ingest's own thread about twice a second and at the end.
  std::function<void(const IngestProgress&)> progress;
  // When set to true (e.g. by a SIGINT handler) the ingest stops at the next
  // check, keeps what is committed, removes its temporary files and returns
  // a kIoError-coded "interrupted" status.
  const std::atomic<bool>* cancel = nullptr;
  // The level-of-detail pyramid (build_pyramid) of the scan: kAuto builds it
  // when the scan holds at least kPyramidAutoMinPoints points.
  PyramidMode pyramid = PyramidMode::kAuto;
  std::string creator = "relief";
};

// Cells per chunk edge when chunk_edge is 0 (a power of two: the chunk cube
// splits into cells exactly).
inline constexpr int kDefaultCellsPerChunk = 32;

// Whatever the cell size: no coordinate, cell size or chunk edge beyond 2^50
// (~1.1e15 units), so squares and sums of squares (PCA, distances) stay finite
// and exact enough.
inline constexpr double kMaxCoordinateMagnitude = 1125899906842624.0;  // 2^50

// The largest coordinate magnitude an archive with this cell size and chunk
// edge accepts: 2^36 x min(cell, chunk edge), at most kMaxCoordinateMagnitude. Within
// it chunk keys stay far inside int64 and a double still resolves 2^-16 of a
// cell. Ingest refuses points beyond it (kInvalidArgument naming the input,
// the point and the value); 0 for a non-positive cell or edge.
double max_coordinate_magnitude(double cell_size, double chunk_edge);

// ---- The level-of-detail pyramid (format-spec/archive.md §9): coarse copies
// of a scan's points at levels 1, 2, ... (nodes of chunk_edge * 2^L, one
// point per cube of a pitch that doubles per level: about a quarter of the
// points of the level below on surfaces), as ordinary chunk blobs in the
// resampling codec, so a preview or a coarse query of any size reads a few
// nodes. A level that would keep more than a third of the points of the last
// stored one is not stored (its thinned points still feed the next level).

struct PyramidOptions {
  unsigned threads = 0;  // 0 = all cores
  std::uint64_t memory_budget = std::uint64_t{1} << 30;
  std::string tmp_dir;  // temporary files; empty = beside the archive
  const std::atomic<bool>* cancel = nullptr;
  // Called now and then with nodes written so far (from the calling thread).
  std::function<void(int level, std::uint64_t nodes)> progress;
};

struct PyramidResult {
  int levels = 0;     // levels stored; 0: no pyramid (a scan without decoded points)
  int top_level = 0;  // the coarsest stored level
  // Set when PyramidMode::kAuto could not build one (not for I/O errors or
  // interruption, which fail the ingest): why, and the scan reads from its
  // chunks. The ingest reports it as a warning.
  std::string skipped;
  std::uint64_t chunks = 0;
  std::uint64_t points = 0;
  std::uint64_t blob_bytes = 0;
  double seconds = 0;
};

// Builds the pyramid of one scan from its stored chunks (the map layer of each
// blob: DecodeOptions::base_layer) and records it complete; a pyramid the scan
// already had is replaced. Deterministic: the same chunks give the same level
// blobs, whatever the threads, budget or how the chunks were made (one run,
// appends, a merge of shards). On error the scan's pyramid rows are removed.
Result<PyramidResult> build_pyramid(Archive& archive, std::int64_t scan_id, const PyramidOptions& options);

struct IngestResult {
  std::uint64_t points_read = 0;
  std::uint64_t points_decoded = 0;  // points a full decode of the new chunks returns
  std::uint64_t chunks_written = 0;
  std::uint64_t blob_bytes = 0;
  double seconds = 0;
  double cell_size = 0;
  double chunk_edge = 0;
  std::int64_t scan_id = 0;
  PyramidResult pyramid;  // levels 0: none built
  // Bytes of decoded LAZ and text points the ingest kept in temporary files
  // and read back (IngestOptions::spool); 0 when it read its inputs again.
  std::uint64_t spooled_bytes = 0;
  // Records of the inputs that hold no point, skipped by design
  // (PointStreamInfo::skipped_points: a PCD's NaN points, a PTX scan's
  // directions without a return); not in points_read.
  std::uint64_t points_skipped = 0;
  // What the input readers noticed but did not refuse (PointStreamInfo::warnings),
  // e.g. a PLY holding more vertices than its header declares.
  std::vector<std::string> warnings;
};

// Creates `archive_path` from `inputs`. The path must not exist (compress never
// overwrites), its directory must. Parameters are checked before any work
// (validate_encode_params, chunk edge, the density check above). On any error
// the new archive is removed; killed mid-way (kill -9), the archive holds every
// chunk committed so far and opens normally.
Result<IngestResult> compress_files(const std::vector<std::string>& inputs, const std::string& archive_path,
                                    const IngestOptions& options);

// Adds `inputs` to an existing archive with the archive's grid and codec
// parameters (options.codec and chunk_edge are ignored). On error the scan's
// chunks are removed again; the archive is as before.
Result<IngestResult> append_files(const std::string& archive_path, const std::vector<std::string>& inputs,
                                  const IngestOptions& options);

// ---- Ingest options by name: the one parser behind the CLI's options and the
// Python bindings' keyword arguments, so both accept and refuse the same values.

// Which command the options are for. Compress takes every option; stream all
// but chunk-edge, error-target, allow-sparse and assume-crs (its chunk edge
// is its own); append only the run's own (memory, threads, tmp, columns,
// verify, assume-crs): the archive fixes the rest.
enum class IngestOptionSet { kCompress, kAppend, kStream };

// How option names appear in messages: "--color-tolerance" (the CLI) or
// "color_tolerance" (Python keyword arguments).
enum class OptionSpelling { kCli, kPython };

struct NamedOption {
  // The CLI's name without dashes, e.g. "color-tolerance"; '_' is read as '-'.
  std::string name;
  // The value as text, as on a command line: "0.01", "512M", "resample".
  // Flags (ingest_flag_names): "" or "true" sets them, "false" leaves them off.
  std::string value;
};

// The names apply_ingest_options accepts for `set`, CLI spelling without
// dashes: the options taking a value, and the flags.
std::vector<std::string> ingest_option_names(IngestOptionSet set);
std::vector<std::string> ingest_flag_names(IngestOptionSet set);
// Applies `given` to `options` (over their current values) and checks them
// together, before any work: kInvalidArgument naming the option (spelled per
// `spelling`) and its value for an unknown name, a malformed or out-of-range
// value, or a combination that cannot work (--tolerance with --mode resample).
Status apply_ingest_options(IngestOptionSet set, const std::vector<NamedOption>& given, OptionSpelling spelling,
                            IngestOptions& options);
// The codec's options alone (cell, decomposition, max-points, resolution,
// codec, quality, color-quality, intensity-quality, height-bits, fill), for
// commands that encode single chunks; apply_ingest_options includes them.
std::vector<std::string> encode_option_names();
Status apply_encode_options(const std::vector<NamedOption>& given, OptionSpelling spelling, EncodeParams& params);
// The error bound of a single chunk (tolerance, color-tolerance,
// intensity-tolerance; the flag keep-order), checked as apply_ingest_options
// checks them: with `tolerance` T, params.bound becomes every point within T
// (grid step 2T from the origin); without it, the others are refused and
// params stays as it is (the paper's maps alone).
std::vector<std::string> bound_option_names();
std::vector<std::string> bound_flag_names();
Status apply_bound_options(const std::vector<NamedOption>& given, OptionSpelling spelling, EncodeParams& params);
// "1G", "512M", "64K", "2GiB" (binary units) or a plain number of MiB; 0 when
// the text is none of these.
std::uint64_t parse_byte_size(std::string_view text);

// The largest cell size whose RMSE_SNN on `sample` stays at or below
// `target`, found by bisection in log space over real encode/decode round
// trips of the sample (other parameters as in `base`). `achieved` receives the
// sample's RMSE at the chosen cell.
Result<double> choose_cell_for_error(const PointCloud& sample, const EncodeParams& base, double target,
                                     double* achieved = nullptr);

// ---- Live streaming (`relief stream`).

struct StreamOptions {
  IngestOptions ingest;
  // A chunk is encoded once this many consecutive batches brought it no point
  // (the paper's "until new incoming data no longer falls into that voxel").
  std::uint32_t idle_batches = 2;
  // Bound on buffered points: above it the chunks idle longest (then the
  // largest) are encoded early.
  std::uint64_t max_buffered_points = 4'000'000;
  // Encode every batch at once, chunk by chunk, without buffering (the
  // paper's "immediate" mode: lower latency, larger archive).
  bool immediate = false;
};

// Feeds points into an archive as a scanner produces them. Creates the
// archive when it does not exist (then options.ingest.codec.cell_size and
// chunk_edge must be set), else appends with the archive's parameters.
class StreamIngest {
 public:
  // Every batch carries colours, intensities and the LAS attributes
  // `las_attributes` (LasAttributeBits: those text columns fill,
  // TextLineParser; kLasTextAttributes, and kLasExtraBytes with
  // `extra_bytes_size` bytes a point described by the Extra Bytes VLR payload
  // `extra_bytes_vlr`, BinaryRecordParser) as opened. Appending to an archive
  // whose chunks have other extra bytes is refused.
  static Result<std::unique_ptr<StreamIngest>> open(const std::string& archive_path, const StreamOptions& options,
                                                    bool has_colors, bool has_intensity,
                                                    std::uint32_t las_attributes = 0,
                                                    const std::string& extra_bytes_vlr = {},
                                                    std::uint32_t extra_bytes_size = 0);
  virtual ~StreamIngest() = default;
  // One batch of incoming points (one read, or one scan line set).
  virtual Status push(const PointCloud& batch) = 0;
  // Encodes everything still buffered, marks the scan complete and closes the
  // archive (Archive::close). When closing fails (a full disk), an archive
  // the stream created is removed, and one it appended to is left intact
  // with its write-ahead log, as the error says; abort() is then not needed.
  virtual Result<IngestResult> finish() = 0;
  // Gives up after a failure: removes everything this stream added, so the
  // archive it created does not exist any more, or the archive it appended to
  // is as before. The stream takes no more calls afterwards. After finish()
  // (which cleans up after itself) it does nothing.
  virtual Status abort() = 0;
};

}  // namespace relief
