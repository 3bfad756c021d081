// ChunkReader: whole chunks decoded in parallel, handed out in file order;
// an unchunked file's one stream read in pieces.
#include <algorithm>
#include <thread>
#include <utility>

#include "core/parallel.h"
#include "laz/arithmetic_decoder.h"
#include "relief/laz.h"

namespace relief::laz {

namespace {
// Records per piece when an oversized chunk is decoded piecewise.
constexpr std::size_t kPieceRecords = 4096;
}  // namespace

struct ChunkReader::Slot {
  std::unique_ptr<ChunkDecoder> decoder;
  std::vector<std::uint8_t> bytes;
  std::vector<std::uint8_t> records;
  std::size_t chunk = 0;
  Status status;
};

// Compressor 1 (LASzip 1.x) has no chunks: the whole point data is one
// arithmetic stream whose every point depends on the one before, so it can
// be neither split between threads nor held whole. The decoder pulls it
// through this feed a piece at a time, in file order (so `fetch`, the one of
// the running next() call, only ever skips forward).
struct ChunkReader::Stream final : ByteFeed {
  const Fetch* fetch = nullptr;
  std::uint64_t offset = 0;  // file offset of the next piece
  std::uint64_t left = 0;    // bytes of the stream not fetched yet
  std::size_t piece = 0;
  std::vector<std::uint8_t> bytes;
  Status error;  // a failed fetch; the decoder then sees the stream end

  bool more(const std::uint8_t*& begin, const std::uint8_t*& end) override {
    if (left == 0 || fetch == nullptr || !error.is_ok()) return false;
    const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(left, piece));
    // The decoder has read all of the previous piece, so `bytes` may be reused.
    error = (*fetch)(offset, n, bytes);
    if (error.is_ok() && bytes.size() != n) error = internal_error("LAZ stream piece fetched short");
    if (!error.is_ok()) return false;
    offset += n;
    left -= n;
    begin = bytes.data();
    end = begin + n;
    return true;
  }
  std::uint64_t remaining() const override { return left; }
};

ChunkReader::~ChunkReader() = default;

Result<std::unique_ptr<ChunkReader>> ChunkReader::create(const Params& params, std::vector<Chunk> chunks,
                                                         unsigned threads, const std::string& name,
                                                         std::size_t max_whole_chunk, std::size_t stream_piece) {
  std::unique_ptr<ChunkReader> r(new ChunkReader());
  r->record_length_ = params.record_length;
  r->max_whole_chunk_ = max_whole_chunk;
  r->name_ = name;
  r->chunks_ = std::move(chunks);
  threads = std::max(1u, threads);
  if (params.unchunked()) {
    if (r->chunks_.size() != 1) {
      return invalid_argument(name + ": an unchunked LAZ stream is read as exactly one chunk (see unchunked_stream)");
    }
    r->stream_ = std::make_unique<Stream>();
    r->stream_->piece = std::max<std::size_t>(stream_piece, 1);
    threads = 1;
  }
  for (unsigned t = 0; t < threads; ++t) {
    auto slot = std::make_unique<Slot>();
    RELIEF_ASSIGN_OR_RETURN(slot->decoder, ChunkDecoder::create(params, name));
    r->slots_.push_back(std::move(slot));
  }
  return r;
}

// Fetches the next chunks (one per slot, stopping before an oversized one
// unless it comes first) and decodes them, in parallel when there are several.
Status ChunkReader::fill_batch(const Fetch& fetch) {
  batch_size_ = 0;
  serving_ = 0;
  if (stream_) {
    // The first piece holds at least the raw first record.
    const Chunk& c = chunks_[next_chunk_++];
    Slot& slot = *slots_[0];
    const auto first =
        static_cast<std::size_t>(std::min<std::uint64_t>(c.bytes, std::max(stream_->piece, record_length_)));
    RELIEF_RETURN_IF_ERROR(fetch(c.offset, first, slot.bytes));
    stream_->offset = c.offset + first;
    stream_->left = c.bytes - first;
    batch_size_ = 1;
    const Status begun = slot.decoder->begin_fed(slot.bytes, *stream_, c.points);
    RELIEF_RETURN_IF_ERROR(stream_->error);
    RELIEF_RETURN_IF_ERROR(begun);
    streaming_ = true;
    stream_left_ = c.points;
    return Status::ok();
  }
  while (batch_size_ < slots_.size() && next_chunk_ < chunks_.size()) {
    const Chunk& c = chunks_[next_chunk_];
    // Bounded by the chunk table check (points <= bytes * a constant), but
    // records of a huge claimed count are not held whole.
    const bool oversized = c.points > max_whole_chunk_ / std::max<std::size_t>(record_length_, 1);
    if (oversized && batch_size_ > 0) break;
    Slot& slot = *slots_[batch_size_];
    slot.chunk = next_chunk_;
    RELIEF_RETURN_IF_ERROR(fetch(c.offset, static_cast<std::size_t>(c.bytes), slot.bytes));
    ++next_chunk_;
    ++batch_size_;
    if (oversized) {
      RELIEF_RETURN_IF_ERROR(slot.decoder->begin(slot.bytes, c.points, slot.chunk));
      streaming_ = true;
      stream_left_ = c.points;
      return Status::ok();
    }
  }
  auto decode = [&](std::size_t i) {
    Slot& slot = *slots_[i];
    const Chunk& c = chunks_[slot.chunk];
    slot.records.resize(static_cast<std::size_t>(c.points) * record_length_);
    slot.status = slot.decoder->begin(slot.bytes, c.points, slot.chunk);
    if (slot.status.is_ok()) slot.status = slot.decoder->decode(static_cast<std::size_t>(c.points), slot.records.data());
  };
  // One chunk per thread, this one included. (parallel_for_ranges, used
  // until 2026-11-30, runs fewer than two items per thread on the calling
  // thread alone, so the slots never decoded side by side.)
  for_each_parallel(batch_size_, static_cast<unsigned>(batch_size_), decode);
  return Status::ok();
}

Status ChunkReader::next(const Fetch& fetch, std::span<const std::uint8_t>& records) {
  if (stream_) stream_->fetch = &fetch;
  for (;;) {
    if (streaming_) {
      if (stream_left_ > 0) {
        Slot& slot = *slots_[0];
        const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(stream_left_, kPieceRecords));
        slot.records.resize(n * record_length_);
        const Status decoded = slot.decoder->decode(n, slot.records.data());
        // A read error ends the stream early; report it, not the short stream.
        if (stream_ && !stream_->error.is_ok()) return stream_->error;
        RELIEF_RETURN_IF_ERROR(decoded);
        stream_left_ -= n;
        records = slot.records;
        return Status::ok();
      }
      streaming_ = false;
      batch_size_ = 0;
      serving_ = 0;
    }
    if (serving_ < batch_size_) {
      Slot& slot = *slots_[serving_++];
      RELIEF_RETURN_IF_ERROR(slot.status);
      if (slot.records.empty()) continue;  // a chunk of no points
      records = slot.records;
      return Status::ok();
    }
    if (next_chunk_ >= chunks_.size()) {
      records = {};
      return Status::ok();
    }
    RELIEF_RETURN_IF_ERROR(fill_batch(fetch));
  }
}

}  // namespace relief::laz
