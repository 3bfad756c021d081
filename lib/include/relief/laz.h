// LASzip (LAZ) point compression and decompression, for the LAS reader and
// writer.
//
// A LAZ file is a LAS file whose point format byte has bit 7 set, with a
// "laszip encoded" VLR (record 22204) naming the compressor and the items of
// each point, 8 bytes at the point-data offset giving the chunk table's
// position, the compressed chunks, and the chunk table. COPC files are LAZ
// files and read the same way. Supported, both ways: the chunked pointwise
// compressor (LASzip 2.x; point formats 0-3, items POINT10, GPSTIME11, RGB12
// and BYTE in version 2) and the layered chunked compressor (LASzip 3.x;
// formats 6-8, items POINT14, RGB14, RGBNIR14 and BYTE14 in version 3), extra
// bytes, fixed or variable chunk sizes. Read only: LASzip 1.x's unchunked
// pointwise compressor (1: no chunk table and no table offset, the whole
// point data is one stream) and the pointwise items in version 1, with either
// pointwise compressor and mixed with version-2 items as LASzip allows; the
// waveform formats 4 and 5 (POINT10, GPSTIME11, [RGB12,] WAVEPACKET13, which
// LASzip writes in version 1 beside version-2 items: the descriptors are
// decoded, being interleaved with the other items in one stream). Not
// supported: item version 4. Formats 9 and 10 are read
// with their wave packet layer skipped: the records hold zeros there (a
// chunk's first record its raw bytes), as Relief keeps no wave packets.
// Decoding and encoding go chunk by chunk, so memory is bounded by one
// chunk's compressed bytes whatever the file size (an unchunked stream is
// read in pieces of bounded size).
//
// Every function checks what it reads against the bytes present; errors name
// `name` (the file) and the problem.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "relief/status.h"

namespace relief::laz {

inline constexpr std::string_view kVlrUserId = "laszip encoded";
inline constexpr std::uint16_t kVlrRecordId = 22204;

struct Item {
  std::uint16_t type = 0;
  std::uint16_t size = 0;
  std::uint16_t version = 0;
};

struct Params {
  std::uint16_t compressor = 0;  // 1 = pointwise, 2 = pointwise chunked, 3 = layered chunked
  std::uint32_t chunk_size = 0;  // points per chunk; kVariableChunks when the table says
  std::vector<Item> items;
  std::size_t record_length = 0;
  // LASzip 1.x's compressor 1: no chunk table, one stream (see unchunked_stream()).
  bool unchunked() const { return compressor == 1; }
  // Not from the VLR, a decoding choice: decode only the x, y and z of the
  // layered compressor's points (the channel/returns/XY layer and the Z
  // layer, as LASzip's selective decompression does); every other field of
  // a chunk's points repeats its first point's. The pointwise compressors
  // decode everything regardless (one stream holds every field).
  bool positions_only = false;
};
inline constexpr std::uint32_t kVariableChunks = 0xFFFFFFFFu;

struct Chunk {
  std::uint64_t offset = 0;  // file offset of the chunk's first byte
  std::uint64_t bytes = 0;
  std::uint64_t points = 0;
};

// Parses the LASzip VLR payload and checks it against the LAS header's point
// format (0-10, compression bits cleared) and record length.
Result<Params> parse_vlr(std::span<const std::uint8_t> payload, int point_format, std::size_t record_length,
                         const std::string& name);

// Decodes the chunk table. `table` holds the file from the table's offset to
// the end of the point region (or the file); chunks start at `first_chunk`
// (point-data offset + 8) and must end at or before `table_offset`.
// `point_count` is the header's count: fixed-size chunks take their counts
// from it, and the table must account for exactly that many points.
Result<std::vector<Chunk>> parse_chunk_table(std::span<const std::uint8_t> table, const Params& params,
                                             std::uint64_t first_chunk, std::uint64_t table_offset,
                                             std::uint64_t point_count, const std::string& name);

// For an unchunked file (params.unchunked()): the single "chunk" that is the
// whole point data, from `first` (the point-data offset: there is no table
// offset) to `end` (the extended VLRs or the end of the file), holding the
// header's `point_count` points. Refuses a region that cannot hold them.
Result<Chunk> unchunked_stream(const Params& params, std::uint64_t first, std::uint64_t end,
                               std::uint64_t point_count, const std::string& name);

class ByteFeed;  // lib/laz internal: the rest of a stream given in pieces

// Decompresses chunks into uncompressed LAS point records.
class ChunkDecoder {
 public:
  static Result<std::unique_ptr<ChunkDecoder>> create(const Params& params, const std::string& name);
  virtual ~ChunkDecoder() = default;

  // Starts the chunk `index` whose compressed bytes are `bytes` (which must
  // stay alive until the chunk is done) and which holds `points` points.
  virtual Status begin(std::span<const std::uint8_t> bytes, std::uint64_t points, std::uint64_t index) = 0;
  // As begin() for a stream too long to hold (compressor 1): `first` is its
  // first piece (at least one record), `feed` gives the rest as the decoder
  // needs it. Pointwise decoders only.
  virtual Status begin_fed(std::span<const std::uint8_t> first, ByteFeed& feed, std::uint64_t points);
  // Writes the next `n` records (n * record_length bytes) of the chunk to
  // `out`; n must not exceed the points left in the chunk.
  virtual Status decode(std::size_t n, std::uint8_t* out) = 0;
};

inline constexpr std::size_t kMaxParallelChunkBytes = std::size_t{16} << 20;
inline constexpr std::size_t kStreamPieceBytes = std::size_t{1} << 20;

// Streams the decoded records of a file's chunks in order, decoding up to
// `threads` chunks at once (one per thread). Memory: per thread one chunk's
// compressed bytes and decoded records; a chunk whose records would exceed
// kMaxParallelChunkBytes is decoded in small batches on the calling thread.
// An unchunked file (compressor 1) is one stream that cannot be split: it is
// fetched in pieces of kStreamPieceBytes and decoded in small batches on the
// calling thread, never in parallel.
class ChunkReader {
 public:
  // Copies `bytes` bytes at file offset `offset` (never before the end of the
  // previous fetch) into `out`, or fails naming the file.
  using Fetch = std::function<Status(std::uint64_t offset, std::size_t bytes, std::vector<std::uint8_t>& out)>;

  // `max_whole_chunk` (bytes of decoded records) is kMaxParallelChunkBytes
  // and `stream_piece` kStreamPieceBytes but for tests of the piecewise paths.
  static Result<std::unique_ptr<ChunkReader>> create(const Params& params, std::vector<Chunk> chunks,
                                                     unsigned threads, const std::string& name,
                                                     std::size_t max_whole_chunk = kMaxParallelChunkBytes,
                                                     std::size_t stream_piece = kStreamPieceBytes);
  ~ChunkReader();

  // Sets `records` to the next decoded records (a whole number of them;
  // valid until the next call), empty after the last chunk.
  Status next(const Fetch& fetch, std::span<const std::uint8_t>& records);

 private:
  struct Slot;
  struct Stream;
  ChunkReader() = default;
  Status fill_batch(const Fetch& fetch);

  std::size_t record_length_ = 0;
  std::size_t max_whole_chunk_ = 0;
  std::string name_;
  std::vector<Chunk> chunks_;
  std::vector<std::unique_ptr<Slot>> slots_;
  std::size_t next_chunk_ = 0;
  std::size_t batch_size_ = 0;  // slots filled by the last batch
  std::size_t serving_ = 0;     // slot whose records are handed out next
  bool streaming_ = false;      // slot 0 decodes an oversized chunk piecewise
  std::uint64_t stream_left_ = 0;
  std::unique_ptr<Stream> stream_;  // compressor 1: the point data's pieces
};

// Compresses LAS point records as LASzip does, so LASzip-compatible readers
// (and ChunkDecoder) read the result: formats 0-3 with the chunked pointwise
// compressor (items POINT10, GPSTIME11, RGB12 and, for records longer than
// the format's, BYTE, all version 2) and formats 6-8 with the layered
// chunked compressor (POINT14, RGB14 or RGBNIR14 and BYTE14, version 3; the
// LAS header must then say LAS 1.4). With LASzip's chunking the chunks are
// LASzip's byte for byte.
class PointCompressor {
 public:
  static constexpr std::uint32_t kDefaultChunkSize = 50000;  // LASzip's default
  // `chunk_size` points per chunk, or kVariableChunks to end chunks at
  // flush_chunk() (as COPC does, one chunk per octree node). Refuses other
  // formats (waveform formats 4, 5, 9, 10 are not written), a record_length
  // shorter than the format's or over 65535, and chunks so long that their
  // byte counts could overflow the chunk table's 32 bits (a variable chunk
  // ends there by itself).
  // With `threads` > 1 and fixed chunks (of up to 16 MiB of records), up to
  // 4 chunks are gathered and compressed side by side; the bytes are the same.
  static Result<std::unique_ptr<PointCompressor>> create(int point_format, std::size_t record_length,
                                                         std::uint32_t chunk_size, const std::string& name,
                                                         unsigned threads = 1);
  ~PointCompressor();

  // The LASzip VLR's payload (user id kVlrUserId, record kVlrRecordId).
  std::vector<std::uint8_t> vlr_payload() const;
  // Compresses `n` records; completed chunks are appended to `out`.
  void add(const std::uint8_t* records, std::size_t n, std::vector<std::uint8_t>& out);
  // With kVariableChunks, ends the current chunk (if it holds points) and
  // appends it to `out`. With a fixed chunk size it does nothing: readers
  // take every chunk but the last to hold chunk_size points.
  void flush_chunk(std::vector<std::uint8_t>& out);
  // Appends the last chunk to `out` and returns the chunk table, which goes
  // after the chunks (its offset in the 8 bytes before the first chunk).
  std::vector<std::uint8_t> finish(std::vector<std::uint8_t>& out);

 private:
  struct State;
  PointCompressor();
  static std::unique_ptr<State> make_state(int point_format, std::size_t record_length, std::uint32_t chunk_size,
                                           std::uint32_t max_points);
  static void start_chunk(State& s, const std::uint8_t* record);
  static void end_chunk(State& s, std::vector<std::uint8_t>& out);
  // Compresses n records with `s`, ending its chunks as they fill.
  static void encode(State& s, const std::uint8_t* records, std::size_t n, std::vector<std::uint8_t>& out);
  // The gathered records' chunks, side by side, appended to `out` in order.
  void compress_pending(std::vector<std::uint8_t>& out);

  std::vector<std::unique_ptr<State>> states_;  // one a thread; the first keeps the chunk table
  State* state_ = nullptr;                      // states_[0]
  std::vector<std::uint8_t> pending_;           // records of whole chunks waiting (several states)
};

}  // namespace relief::laz
