// LAZ writing: LASzip's two chunked compressors, the chunk table and the
// LASzip VLR. The item coders are in items_v2_write.cpp and
// items_v3_write.cpp; this file lays out their output as LASzip does.
//
// Pointwise chunk (formats 0-3): the first record raw, then one arithmetic
// stream coding every item of every further point.
// Layered chunk (formats 6-8): the first record raw, the chunk's point count
// (u32), the byte count of every layer of every item (u32 each, in item
// order), then the layers' bytes in the same order.
#include <algorithm>
#include <array>
#include <cstring>
#include <memory>

#include "laz/arithmetic_encoder.h"
#include "laz/integer_coder.h"
#include "laz/items.h"
#include "laz/tables.h"
#include "core/parallel.h"
#include "relief/laz.h"

namespace relief::laz {

namespace {

constexpr std::uint16_t kCompressorPointwiseChunked = 2;
constexpr std::uint16_t kCompressorLayeredChunked = 3;
constexpr std::uint16_t kItemVersion2 = 2;
constexpr std::uint16_t kItemVersion3 = 3;
// What the VLR states as the LASzip version the stream follows: 2.2.0 for
// the version 2 items with chunks, 3.4.3 (the release files of the layered
// compressor name) for version 3.
constexpr std::uint8_t kVersionMajorPointwise = 2, kVersionMinorPointwise = 2;
constexpr std::uint16_t kRevisionPointwise = 0;
constexpr std::uint8_t kVersionMajorLayered = 3, kVersionMinorLayered = 4;
constexpr std::uint16_t kRevisionLayered = 3;
constexpr std::int64_t kNoSpecialEvlrs = -1;
constexpr std::uint32_t kChunkTableVersion = 0;
// The chunk table stores byte counts as u32. A compressed point never takes
// more than twice its record plus this (the costliest symbols take under 16
// bits per byte coded), so chunks of at most 2^31 / (2 * record + slack)
// points always fit: longer fixed chunks are refused and variable chunks
// end there.
constexpr std::size_t kCompressedSlackPerPoint = 64;
constexpr std::uint64_t kMaxChunkBytes = std::uint64_t{1} << 31;
// Chunks compressed side by side at most (PointCompressor::create), and only
// chunks of at most this many bytes of records (each waits whole in memory).
constexpr unsigned kMaxCompressThreads = 4;
constexpr std::uint64_t kMaxParallelCompressBytes = std::uint64_t{16} << 20;

}  // namespace

struct PointCompressor::State {
  int format = 0;
  bool layered = false;
  std::size_t record_length = 0;
  std::uint32_t chunk_size = 0;
  std::uint32_t max_chunk_points = 0;
  std::vector<Item> items;
  std::size_t gps_offset = 0, rgb_offset = 0, bytes_offset = 0, extra = 0;

  // Version 2 items and their one stream.
  std::unique_ptr<Point10V2> point10;
  std::unique_ptr<GpsTime11V2> gps;
  std::unique_ptr<Rgb12V2> rgb12;
  std::unique_ptr<ByteV2> bytes;
  ArithmeticEncoder enc;
  // Version 3 items, each with its own layers.
  std::unique_ptr<Point14V3> point14;
  std::unique_ptr<Rgb14V3> rgb14;
  std::unique_ptr<Byte14V3> bytes14;

  std::vector<std::uint8_t> chunk;  // the chunk being written (a carry may still change it)
  std::uint32_t in_chunk = 0;
  std::vector<std::uint32_t> chunk_points, chunk_bytes;

  std::vector<std::span<OutLayer>> layer_groups() {
    std::vector<std::span<OutLayer>> g = {point14->out_layers()};
    if (rgb14) g.push_back(rgb14->out_layers());
    if (bytes14) g.push_back(bytes14->out_layers());
    return g;
  }
};

PointCompressor::PointCompressor() = default;
PointCompressor::~PointCompressor() = default;

Result<std::unique_ptr<PointCompressor>> PointCompressor::create(int point_format, std::size_t record_length,
                                                                 std::uint32_t chunk_size, const std::string& name,
                                                                 unsigned threads) {
  // Formats 4, 5, 9 and 10 are read (their wave packets decoded or
  // skipped, and not kept), not written.
  const bool wave = point_format == 4 || point_format == 5 || point_format == 9 || point_format == 10;
  const FormatItems need = wave ? FormatItems{} : items_for_format(point_format);
  if (need.types.empty()) {
    return unsupported(name + ": LAZ output is written in point formats 0-3 and 6-8, not " +
                       std::to_string(point_format));
  }
  if (record_length < need.size || record_length > UINT16_MAX) {
    return invalid_argument(name + ": LAZ point format " + std::to_string(point_format) + " needs records of " +
                            std::to_string(need.size) + " to 65535 bytes, not " + std::to_string(record_length));
  }
  const auto max_points = static_cast<std::uint32_t>(
      kMaxChunkBytes / (2 * record_length + kCompressedSlackPerPoint));
  if (chunk_size == 0 || (chunk_size != kVariableChunks && chunk_size > max_points)) {
    return invalid_argument(name + ": LAZ chunks of " + std::to_string(chunk_size) + " points (1 to " +
                            std::to_string(max_points) + " for " + std::to_string(record_length) +
                            "-byte records, or variable)");
  }
  std::unique_ptr<PointCompressor> c(new PointCompressor());
  // One state per thread: each compresses whole chunks on its own (a chunk
  // starts every model afresh, so the bytes do not depend on which state
  // wrote it). Variable chunks end at the caller's word: one state.
  const bool parallel = chunk_size != kVariableChunks && std::uint64_t{chunk_size} * record_length <= kMaxParallelCompressBytes;
  const unsigned states = parallel ? std::clamp(threads, 1u, kMaxCompressThreads) : 1u;
  for (unsigned i = 0; i < states; ++i) c->states_.push_back(make_state(point_format, record_length, chunk_size, max_points));
  c->state_ = c->states_.front().get();
  return c;
}

std::unique_ptr<PointCompressor::State> PointCompressor::make_state(int point_format, std::size_t record_length,
                                                                    std::uint32_t chunk_size,
                                                                    std::uint32_t max_points) {
  const FormatItems need = items_for_format(point_format);
  auto state = std::make_unique<State>();
  State& s = *state;
  s.format = point_format;
  s.layered = point_format >= 6;
  s.record_length = record_length;
  s.chunk_size = chunk_size;
  s.max_chunk_points = max_points;
  s.extra = record_length - need.size;
  const std::uint16_t version = s.layered ? kItemVersion3 : kItemVersion2;
  std::size_t offset = 0;
  for (const std::uint16_t type : need.types) {
    const std::size_t size = fixed_item_size(type);
    s.items.push_back({type, static_cast<std::uint16_t>(size), version});
    switch (type) {
      case kItemPoint10: s.point10 = std::make_unique<Point10V2>(); break;
      case kItemGpsTime11:
        s.gps = std::make_unique<GpsTime11V2>();
        s.gps_offset = offset;
        break;
      case kItemRgb12:
        s.rgb12 = std::make_unique<Rgb12V2>();
        s.rgb_offset = offset;
        break;
      case kItemPoint14: s.point14 = std::make_unique<Point14V3>(); break;
      default:  // RGB14 or RGBNIR14
        s.rgb14 = std::make_unique<Rgb14V3>(type == kItemRgbNir14);
        s.rgb_offset = offset;
        break;
    }
    offset += size;
  }
  if (s.extra > 0) {
    s.items.push_back({s.layered ? kItemByte14 : kItemByte, static_cast<std::uint16_t>(s.extra), version});
    s.bytes_offset = offset;
    if (s.layered) {
      s.bytes14 = std::make_unique<Byte14V3>(s.extra);
    } else {
      s.bytes = std::make_unique<ByteV2>(s.extra);
    }
  }
  return state;
}

std::vector<std::uint8_t> PointCompressor::vlr_payload() const {
  const State& s = *state_;
  std::vector<std::uint8_t> p;
  auto u8 = [&](std::uint8_t v) { p.push_back(v); };
  auto u16 = [&](std::uint16_t v) {
    u8(static_cast<std::uint8_t>(v));
    u8(static_cast<std::uint8_t>(v >> 8));
  };
  auto u32 = [&](std::uint32_t v) {
    u16(static_cast<std::uint16_t>(v));
    u16(static_cast<std::uint16_t>(v >> 16));
  };
  auto u64 = [&](std::uint64_t v) {
    u32(static_cast<std::uint32_t>(v));
    u32(static_cast<std::uint32_t>(v >> 32));
  };
  u16(s.layered ? kCompressorLayeredChunked : kCompressorPointwiseChunked);
  u16(0);  // arithmetic coder
  u8(s.layered ? kVersionMajorLayered : kVersionMajorPointwise);
  u8(s.layered ? kVersionMinorLayered : kVersionMinorPointwise);
  u16(s.layered ? kRevisionLayered : kRevisionPointwise);
  u32(0);  // options
  u32(s.chunk_size);
  u64(static_cast<std::uint64_t>(kNoSpecialEvlrs));
  u64(static_cast<std::uint64_t>(kNoSpecialEvlrs));
  u16(static_cast<std::uint16_t>(s.items.size()));
  for (const Item& it : s.items) {
    u16(it.type);
    u16(it.size);
    u16(it.version);
  }
  return p;
}

void PointCompressor::start_chunk(State& s, const std::uint8_t* record) {
  // A chunk starts with its first point raw; the streams code the rest.
  s.chunk.insert(s.chunk.end(), record, record + s.record_length);
  if (s.layered) {
    for (auto g : s.layer_groups()) {
      for (OutLayer& l : g) l.start();
    }
    const std::uint32_t context = s.point14->init(record);
    if (s.rgb14) s.rgb14->init(record + s.rgb_offset, context);
    if (s.bytes14) s.bytes14->init(record + s.bytes_offset, context);
  } else {
    s.point10->init(record);
    if (s.gps) s.gps->init(record + s.gps_offset);
    if (s.rgb12) s.rgb12->init(record + s.rgb_offset);
    if (s.bytes) s.bytes->init(record + s.bytes_offset);
    s.enc.init(s.chunk);
  }
}

void PointCompressor::end_chunk(State& s, std::vector<std::uint8_t>& out) {
  if (s.layered) {
    std::array<std::uint8_t, 4> word{};
    put_u32(word.data(), s.in_chunk);
    s.chunk.insert(s.chunk.end(), word.begin(), word.end());
    const auto groups = s.layer_groups();
    for (auto g : groups) {
      for (OutLayer& l : g) {
        l.enc.done();
        put_u32(word.data(), l.changed ? static_cast<std::uint32_t>(l.bytes.size()) : 0);
        s.chunk.insert(s.chunk.end(), word.begin(), word.end());
      }
    }
    for (auto g : groups) {
      for (OutLayer& l : g) {
        if (l.changed) s.chunk.insert(s.chunk.end(), l.bytes.begin(), l.bytes.end());
      }
    }
  } else {
    s.enc.done();
  }
  s.chunk_points.push_back(s.in_chunk);
  s.chunk_bytes.push_back(static_cast<std::uint32_t>(s.chunk.size()));
  out.insert(out.end(), s.chunk.begin(), s.chunk.end());
  s.chunk.clear();
  s.in_chunk = 0;
}

void PointCompressor::add(const std::uint8_t* records, std::size_t n, std::vector<std::uint8_t>& out) {
  if (states_.size() == 1) return encode(*state_, records, n, out);
  // Whole chunks are gathered, then compressed side by side, one a state,
  // and appended in order.
  State& s = *state_;
  const std::size_t chunk_bytes = std::size_t{s.chunk_size} * s.record_length;
  const std::size_t batch_bytes = states_.size() * chunk_bytes;
  while (n > 0) {
    const std::size_t take = std::min(n, (batch_bytes - pending_.size()) / s.record_length);
    pending_.insert(pending_.end(), records, records + take * s.record_length);
    records += take * s.record_length;
    n -= take;
    if (pending_.size() == batch_bytes) compress_pending(out);
  }
}

void PointCompressor::compress_pending(std::vector<std::uint8_t>& out) {
  State& main = *state_;
  const std::size_t chunk_bytes = std::size_t{main.chunk_size} * main.record_length;
  const std::size_t chunks = (pending_.size() + chunk_bytes - 1) / chunk_bytes;
  if (chunks == 0) return;
  std::vector<std::vector<std::uint8_t>> outs(chunks);
  for_each_parallel(chunks, static_cast<unsigned>(chunks), [&](std::size_t i) {
    State& w = *states_[i];
    const std::size_t begin = i * chunk_bytes;
    const std::size_t bytes = std::min(chunk_bytes, pending_.size() - begin);
    encode(w, pending_.data() + begin, bytes / main.record_length, outs[i]);
    end_chunk(w, outs[i]);
  });
  for (std::size_t i = 0; i < chunks; ++i) {
    State& w = *states_[i];
    out.insert(out.end(), outs[i].begin(), outs[i].end());
    if (i > 0) {  // the first state is the main one: its counts are in place
      main.chunk_points.insert(main.chunk_points.end(), w.chunk_points.begin(), w.chunk_points.end());
      main.chunk_bytes.insert(main.chunk_bytes.end(), w.chunk_bytes.begin(), w.chunk_bytes.end());
      w.chunk_points.clear();
      w.chunk_bytes.clear();
    }
  }
  pending_.clear();
}

void PointCompressor::encode(State& s, const std::uint8_t* records, std::size_t n, std::vector<std::uint8_t>& out) {
  const std::uint32_t limit = s.chunk_size == kVariableChunks ? s.max_chunk_points : s.chunk_size;
  for (std::size_t i = 0; i < n; ++i, records += s.record_length) {
    if (s.in_chunk == limit) end_chunk(s, out);
    if (s.in_chunk == 0) {
      start_chunk(s, records);
    } else if (s.layered) {
      const std::uint32_t context = s.point14->write(records);
      if (s.rgb14) s.rgb14->write(records + s.rgb_offset, context);
      if (s.bytes14) s.bytes14->write(records + s.bytes_offset, context);
    } else {
      s.point10->write(s.enc, records);
      if (s.gps) s.gps->write(s.enc, records + s.gps_offset);
      if (s.rgb12) s.rgb12->write(s.enc, records + s.rgb_offset);
      if (s.bytes) s.bytes->write(s.enc, records + s.bytes_offset);
    }
    ++s.in_chunk;
  }
}

void PointCompressor::flush_chunk(std::vector<std::uint8_t>& out) {
  if (state_->chunk_size == kVariableChunks && state_->in_chunk > 0) end_chunk(*state_, out);
}

std::vector<std::uint8_t> PointCompressor::finish(std::vector<std::uint8_t>& out) {
  State& s = *state_;
  compress_pending(out);
  if (s.in_chunk > 0) end_chunk(s, out);
  std::vector<std::uint8_t> table(8);
  put_u32(table.data(), kChunkTableVersion);
  put_u32(table.data() + 4, static_cast<std::uint32_t>(s.chunk_bytes.size()));
  if (!s.chunk_bytes.empty()) {
    // Counts (variable chunks only) and byte counts, each against the
    // previous chunk's, interleaved chunk by chunk.
    const bool variable = s.chunk_size == kVariableChunks;
    ArithmeticEncoder enc;
    enc.init(table);
    IntegerCoder ic(32, 2);
    ic.init();
    for (std::size_t i = 0; i < s.chunk_bytes.size(); ++i) {
      if (variable) {
        ic.compress(enc, static_cast<std::int32_t>(i ? s.chunk_points[i - 1] : 0),
                    static_cast<std::int32_t>(s.chunk_points[i]), 0);
      }
      ic.compress(enc, static_cast<std::int32_t>(i ? s.chunk_bytes[i - 1] : 0),
                  static_cast<std::int32_t>(s.chunk_bytes[i]), 1);
    }
    enc.done();
  }
  return table;
}

}  // namespace relief::laz
