// The LASzip VLR, the chunk table and the chunk decoders of the two chunked
// compressors.
#include <algorithm>
#include <cassert>
#include <array>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "core/byte_io.h"
#include "laz/arithmetic_decoder.h"
#include "laz/integer_coder.h"
#include "laz/items.h"
#include "laz/items_v3_state.h"
#include "relief/laz.h"

namespace relief::laz {

namespace {

constexpr std::uint16_t kCompressorPointwise = 1;
constexpr std::uint16_t kCompressorPointwiseChunked = 2;
constexpr std::uint16_t kCompressorLayeredChunked = 3;
constexpr std::uint16_t kCoderArithmetic = 0;
constexpr std::size_t kVlrFixedSize = 34;  // through the item count
constexpr std::size_t kVlrItemSize = 6;
constexpr std::uint32_t kChunkTableVersion = 0;
constexpr std::size_t kChunkTableHeader = 8;
// LASzip's encoder ends each stream with the bytes its decoder will read,
// so a decoder needing more than the stream holds means it was cut short.
constexpr std::size_t kOverrunSlack = 0;
// LASzip's encoder ends a stream with two or three zero bytes so that its
// decoder reads exactly to the end; an unchunked stream of LASzip 1.x (whose
// encoder we could not check for them) is allowed to lack them: the decoder
// then reads as many zeros past the end of the point data.
constexpr std::size_t kUnchunkedOverrunSlack = 3;
// Compressed points can be tiny (a point equal to its predecessor costs a
// few thousandths of a bit), but not free: a chunk claiming more points than
// this per compressed byte is refused, which bounds the work any file can
// ask for by its size.
constexpr std::uint64_t kMaxPointsPerByte = 4096;

std::string item_name(std::uint16_t type) {
  switch (type) {
    case kItemByte: return "BYTE";
    case kItemPoint10: return "POINT10";
    case kItemGpsTime11: return "GPSTIME11";
    case kItemRgb12: return "RGB12";
    case kItemWavePacket13: return "WAVEPACKET13";
    case kItemPoint14: return "POINT14";
    case kItemRgb14: return "RGB14";
    case kItemRgbNir14: return "RGBNIR14";
    case 13: return "WAVEPACKET14";
    case kItemByte14: return "BYTE14";
    default: return "type " + std::to_string(type);
  }
}

}  // namespace

FormatItems items_for_format(int format) {
  switch (format) {
    case 0: return {{kItemPoint10}, 20};
    case 1: return {{kItemPoint10, kItemGpsTime11}, 28};
    case 2: return {{kItemPoint10, kItemRgb12}, 26};
    case 3: return {{kItemPoint10, kItemGpsTime11, kItemRgb12}, 34};
    // The wave packet descriptor is one more item of the pointwise stream:
    // decoded (the next items depend on its bits), then not kept.
    case 4: return {{kItemPoint10, kItemGpsTime11, kItemWavePacket13}, 57};
    case 5: return {{kItemPoint10, kItemGpsTime11, kItemRgb12, kItemWavePacket13}, 63};
    case 6: return {{kItemPoint14}, 30};
    case 7: return {{kItemPoint14, kItemRgb14}, 36};
    case 8: return {{kItemPoint14, kItemRgbNir14}, 38};
    // The wave packet descriptors are one layer of their own, which the
    // layered decoder skips (Relief does not keep them).
    case 9: return {{kItemPoint14, kItemWavePacket14}, 59};
    case 10: return {{kItemPoint14, kItemRgbNir14, kItemWavePacket14}, 67};
    default: return {{}, 0};
  }
}

std::size_t fixed_item_size(std::uint16_t type) {
  switch (type) {
    case kItemPoint10: return kPoint10Size;
    case kItemGpsTime11: return kGpsTime11Size;
    case kItemRgb12: return kRgb12Size;
    case kItemPoint14: return kPoint14Size;
    case kItemRgb14: return kRgb12Size;
    case kItemRgbNir14: return kRgbNir14Size;
    case kItemWavePacket13: return kWavePacketSize;
    case kItemWavePacket14: return kWavePacketSize;
    default: return 0;
  }
}

Result<Params> parse_vlr(std::span<const std::uint8_t> payload, int point_format, std::size_t record_length,
                         const std::string& name) {
  const std::string what = name + ": LASzip VLR";
  ByteReader r(payload, what);
  Params p;
  std::uint16_t coder = 0, revision = 0, item_count = 0;
  std::uint8_t major = 0, minor = 0;
  std::uint32_t options = 0;
  std::uint64_t special_evlrs = 0, special_offset = 0;
  RELIEF_RETURN_IF_ERROR(r.u16(p.compressor, "compressor"));
  RELIEF_RETURN_IF_ERROR(r.u16(coder, "coder"));
  RELIEF_RETURN_IF_ERROR(r.u8(major, "version major"));
  RELIEF_RETURN_IF_ERROR(r.u8(minor, "version minor"));
  RELIEF_RETURN_IF_ERROR(r.u16(revision, "version revision"));
  RELIEF_RETURN_IF_ERROR(r.u32(options, "options"));
  RELIEF_RETURN_IF_ERROR(r.u32(p.chunk_size, "chunk size"));
  RELIEF_RETURN_IF_ERROR(r.u64(special_evlrs, "number of special EVLRs"));
  RELIEF_RETURN_IF_ERROR(r.u64(special_offset, "offset to special EVLRs"));
  RELIEF_RETURN_IF_ERROR(r.u16(item_count, "item count"));
  if (r.remaining() < std::size_t{item_count} * kVlrItemSize) {
    return format_error(what + " lists " + std::to_string(item_count) + " items but holds " +
                        std::to_string(r.remaining() / kVlrItemSize));
  }
  for (std::uint16_t i = 0; i < item_count; ++i) {
    Item it;
    RELIEF_RETURN_IF_ERROR(r.u16(it.type, "item type"));
    RELIEF_RETURN_IF_ERROR(r.u16(it.size, "item size"));
    RELIEF_RETURN_IF_ERROR(r.u16(it.version, "item version"));
    p.items.push_back(it);
  }
  static_assert(kVlrFixedSize == 34);
  p.record_length = record_length;

  if (coder != kCoderArithmetic) {
    return unsupported(what + ": coder " + std::to_string(coder) + " is not LASzip's arithmetic coder (0)");
  }
  if (p.compressor != kCompressorPointwise && p.compressor != kCompressorPointwiseChunked &&
      p.compressor != kCompressorLayeredChunked) {
    return format_error(what + ": unknown compressor " + std::to_string(p.compressor));
  }
  const FormatItems need = items_for_format(point_format);
  if (need.types.empty()) {
    return unsupported(name + ": LAZ point format " + std::to_string(point_format) +
                       " is not supported (LAS defines 0-10)");
  }
  const bool layered = point_format >= 6;
  // LASzip 1.x's unchunked compressor (1) knew the pointwise items only.
  if (layered != (p.compressor == kCompressorLayeredChunked)) {
    return format_error(what + ": compressor " + std::to_string(p.compressor) + " does not fit point format " +
                        std::to_string(point_format));
  }
  // Pointwise items may be version 1 (LASzip 1.x) or 2, each on its own, as
  // LASzip's reader takes them, with either pointwise compressor.
  const std::uint16_t want_version = layered ? 3 : 2;
  const std::uint16_t min_version = layered ? 3 : 1;
  const std::uint16_t byte_type = layered ? kItemByte14 : kItemByte;
  const std::size_t extra = record_length >= need.size ? record_length - need.size : 0;
  const std::size_t want_items = need.types.size() + (extra > 0 ? 1 : 0);
  std::string listed;
  for (const Item& it : p.items) listed += (listed.empty() ? "" : ", ") + item_name(it.type) + " v" + std::to_string(it.version);
  if (p.items.size() != want_items) {
    return format_error(what + ": items (" + listed + ") do not describe point format " +
                        std::to_string(point_format) + " with " + std::to_string(extra) + " extra bytes");
  }
  for (std::size_t i = 0; i < p.items.size(); ++i) {
    const Item& it = p.items[i];
    const std::uint16_t type = i < need.types.size() ? need.types[i] : byte_type;
    const std::size_t size = i < need.types.size() ? fixed_item_size(type) : extra;
    if (it.type != type || it.size != size) {
      return format_error(what + ": items (" + listed + ") do not describe point format " +
                          std::to_string(point_format) + " with " + std::to_string(extra) + " extra bytes");
    }
    // LASzip has only version 1 of the wave packet item, and writes it so
    // beside version-2 items.
    if (it.type == kItemWavePacket13 && it.version != 1) {
      return unsupported(name + ": LASzip item WAVEPACKET13 version " + std::to_string(it.version) +
                         " is not supported (version 1 is)");
    }
    if (it.version < min_version || it.version > want_version) {
      return unsupported(name + ": LASzip item " + item_name(it.type) + " version " + std::to_string(it.version) +
                         " is not supported (" +
                         (layered ? std::string("version 3 is") : std::string("versions 1 and 2 are")) + ")");
    }
  }
  // Without chunks the chunk size means nothing.
  if (p.chunk_size == 0 && p.compressor != kCompressorPointwise) return format_error(what + ": chunk size is 0");
  return p;
}

Result<Chunk> unchunked_stream(const Params& params, std::uint64_t first, std::uint64_t end,
                               std::uint64_t point_count, const std::string& name) {
  const std::string what = name + ": the LAZ point data (one unchunked stream, compressor 1) from byte " +
                           std::to_string(first);
  if (end < first) return format_error(what + " starts past its end at byte " + std::to_string(end));
  Chunk c{first, end - first, point_count};
  if (c.points == 0 && c.bytes > 0) {
    return format_error(what + " holds " + std::to_string(c.bytes) + " bytes but the header declares no points");
  }
  // As for a chunk: the first point raw, and not more points than bytes allow.
  if (c.points > 0 && c.bytes < params.record_length) {
    return format_error(what + " has " + std::to_string(c.bytes) + " bytes, fewer than its first point's " +
                        std::to_string(params.record_length));
  }
  if (c.points > kMaxPointsPerByte * c.bytes) {
    return format_error(what + " cannot hold the header's " + std::to_string(c.points) + " points in " +
                        std::to_string(c.bytes) + " bytes");
  }
  return c;
}

Result<std::vector<Chunk>> parse_chunk_table(std::span<const std::uint8_t> table, const Params& params,
                                             std::uint64_t first_chunk, std::uint64_t table_offset,
                                             std::uint64_t point_count, const std::string& name) {
  const std::string what = name + ": LAZ chunk table at byte " + std::to_string(table_offset);
  if (table_offset < first_chunk) {
    return format_error(what + " lies before the first chunk at byte " + std::to_string(first_chunk));
  }
  ByteReader r(table, what);
  std::uint32_t version = 0, count = 0;
  RELIEF_RETURN_IF_ERROR(r.u32(version, "version"));
  RELIEF_RETURN_IF_ERROR(r.u32(count, "number of chunks"));
  if (version != kChunkTableVersion) {
    return format_error(what + ": version " + std::to_string(version) + " (only 0 exists)");
  }
  const std::uint64_t region = table_offset - first_chunk;
  // Every chunk holds at least its first point uncompressed.
  if (count > region / std::max<std::size_t>(params.record_length, 1)) {
    return format_error(what + " lists " + std::to_string(count) + " chunks, more than the " +
                        std::to_string(region) + " bytes of point data can hold");
  }
  const bool variable = params.chunk_size == kVariableChunks;
  ArithmeticDecoder dec;
  if (!dec.init(table.subspan(kChunkTableHeader))) return format_error(what + " is corrupt");
  IntegerCoder ic(32, 2);
  ic.init();
  std::vector<Chunk> chunks(count);
  std::uint32_t prev_points = 0, prev_bytes = 0;
  std::uint64_t at = first_chunk, total = 0;
  for (std::uint32_t i = 0; i < count; ++i) {
    Chunk& c = chunks[i];
    if (variable) {
      prev_points = static_cast<std::uint32_t>(ic.decompress(dec, static_cast<std::int32_t>(prev_points), 0));
      c.points = prev_points;
    } else {
      c.points = std::min<std::uint64_t>(params.chunk_size, point_count - std::min(point_count, total));
      if (c.points == 0) {
        return format_error(name + ": the LAZ chunk table lists " + std::to_string(count) + " chunks of " +
                            std::to_string(params.chunk_size) + " points, more than the header's " +
                            std::to_string(point_count) + " points fill");
      }
    }
    prev_bytes = static_cast<std::uint32_t>(ic.decompress(dec, static_cast<std::int32_t>(prev_bytes), 1));
    c.bytes = prev_bytes;
    c.offset = at;
    const std::string which = name + ": LAZ chunk " + std::to_string(i + 1) + " of " + std::to_string(count);
    if (dec.overrun() > kOverrunSlack) return format_error(what + " is cut short");
    if (c.bytes > table_offset - at) {
      return format_error(which + " (" + std::to_string(c.bytes) + " bytes at byte " + std::to_string(at) +
                          ") runs past the chunk table at byte " + std::to_string(table_offset));
    }
    if (c.points > 0 && c.bytes < params.record_length) {
      return format_error(which + " has " + std::to_string(c.bytes) + " bytes, fewer than its first point's " +
                          std::to_string(params.record_length));
    }
    if (c.points > kMaxPointsPerByte * c.bytes) {
      return format_error(which + " claims " + std::to_string(c.points) + " points in " +
                          std::to_string(c.bytes) + " bytes");
    }
    at += c.bytes;
    total += c.points;
  }
  if (total != point_count) {
    return format_error(name + ": the header declares " + std::to_string(point_count) +
                        " points but the LAZ chunk table holds " + std::to_string(total));
  }
  return chunks;
}

// ---------------------------------------------------------------- decoders

namespace {

struct PointwiseItem {
  virtual ~PointwiseItem() = default;
  virtual void init(const std::uint8_t* item) = 0;
  virtual void read(ArithmeticDecoder& dec, std::uint8_t* item) = 0;
  std::size_t offset = 0;
};
template <typename T>
struct PointwiseItemOf final : PointwiseItem {
  template <typename... A>
  explicit PointwiseItemOf(A... a) : item(a...) {}
  void init(const std::uint8_t* p) override { item.init(p); }
  void read(ArithmeticDecoder& dec, std::uint8_t* p) override { item.read(dec, p); }
  T item;
};

class ChunkDecoderBase : public ChunkDecoder {
 protected:
  ChunkDecoderBase(const Params& params, std::string name) : rl_(params.record_length), name_(std::move(name)) {}

  // Common start: the chunk's first point is stored raw.
  Status start(std::span<const std::uint8_t> bytes, std::uint64_t points, std::uint64_t index) {
    index_ = index;
    left_ = points;
    first_pending_ = points > 0;
    decoded_ = 0;
    if (points == 0) return Status::ok();
    if (bytes.size() < rl_) return corrupt(std::to_string(bytes.size()) + " bytes cannot hold its first point");
    first_.assign(bytes.begin(), bytes.begin() + static_cast<std::ptrdiff_t>(rl_));
    return Status::ok();
  }
  // A damaged input file: kFormatError (exit 13), as a truncated or lying
  // one is; kCorruptData (14) says an archive is damaged.
  Status corrupt(const std::string& what) const {
    if (unchunked_) {
      return format_error(name_ + ": LAZ point data (one unchunked stream, compressor 1): " + what);
    }
    return format_error(name_ + ": LAZ chunk " + std::to_string(index_ + 1) + ": " + what);
  }
  // The encoder's stream ends exactly where its decoder stops reading, so
  // bytes left over mean the point count (or the chunk size) is wrong.
  Status trailing(std::size_t unread) const {
    return corrupt(std::to_string(unread) + " compressed bytes are left after its " + std::to_string(decoded_) +
                   " points (a wrong point count or chunk size)");
  }
  Status cut_short() const {
    return corrupt("the compressed data ends before point " + std::to_string(decoded_) +
                   (unchunked_ ? std::string() : std::string(" of the chunk")));
  }

  std::size_t rl_;
  std::string name_;
  bool unchunked_ = false;
  std::uint64_t index_ = 0;
  std::uint64_t left_ = 0;
  std::uint64_t decoded_ = 0;
  bool first_pending_ = false;
  std::vector<std::uint8_t> first_;
};

// Both pointwise compressors: the chunked one (2) gives each chunk its own
// stream; the unchunked one (1) has a single "chunk", the whole point data,
// which comes through begin_fed() in pieces.
class PointwiseDecoder final : public ChunkDecoderBase {
 public:
  PointwiseDecoder(const Params& params, std::string name)
      : ChunkDecoderBase(params, std::move(name)),
        slack_(params.compressor == kCompressorPointwise ? kUnchunkedOverrunSlack : kOverrunSlack) {
    unchunked_ = params.compressor == kCompressorPointwise;
    std::size_t offset = 0;
    for (const Item& it : params.items) {
      std::unique_ptr<PointwiseItem> item;
      const bool v1 = it.version == 1;
      switch (it.type) {
        case kItemPoint10:
          item = v1 ? make_item<Point10V1>() : make_item<Point10V2>();
          break;
        case kItemGpsTime11:
          item = v1 ? make_item<GpsTime11V1>() : make_item<GpsTime11V2>();
          break;
        case kItemRgb12:
          item = v1 ? make_item<Rgb12V1>() : make_item<Rgb12V2>();
          break;
        case kItemWavePacket13:
          item = make_item<WavePacket13V1>();  // version 1 only (parse_vlr)
          break;
        default:
          item = v1 ? make_item<ByteV1>(std::size_t{it.size}) : make_item<ByteV2>(std::size_t{it.size});
          break;
      }
      item->offset = offset;
      offset += it.size;
      items_.push_back(std::move(item));
    }
  }

  Status begin(std::span<const std::uint8_t> bytes, std::uint64_t points, std::uint64_t index) override {
    return begin_with(bytes, nullptr, points, index);
  }
  Status begin_fed(std::span<const std::uint8_t> first, ByteFeed& feed, std::uint64_t points) override {
    return begin_with(first, &feed, points, 0);
  }

  Status decode(std::size_t n, std::uint8_t* out) override {
    assert(n <= left_);
    for (std::size_t i = 0; i < n; ++i, out += rl_) {
      if (first_pending_) {
        std::memcpy(out, first_.data(), rl_);
        first_pending_ = false;
      } else {
        for (auto& item : items_) item->read(dec_, out + item->offset);
      }
      ++decoded_;
    }
    left_ -= n;
    if (dec_.overrun() > slack_) return cut_short();
    if (left_ == 0 && dec_.unread() > 0) return trailing(static_cast<std::size_t>(dec_.unread()));
    return Status::ok();
  }

 private:
  template <typename T, typename... A>
  static std::unique_ptr<PointwiseItem> make_item(A... a) {
    return std::make_unique<PointwiseItemOf<T>>(a...);
  }

  Status begin_with(std::span<const std::uint8_t> bytes, ByteFeed* feed, std::uint64_t points,
                    std::uint64_t index) {
    RELIEF_RETURN_IF_ERROR(start(bytes, points, index));
    if (points == 0) return Status::ok();
    for (auto& item : items_) item->init(first_.data() + item->offset);
    if (!dec_.init(bytes.subspan(rl_), feed)) return corrupt("the compressed stream is invalid");
    return Status::ok();
  }

  std::size_t slack_;
  std::vector<std::unique_ptr<PointwiseItem>> items_;
  ArithmeticDecoder dec_;
};

class LayeredDecoder final : public ChunkDecoderBase {
 public:
  LayeredDecoder(const Params& params, std::string name)
      : ChunkDecoderBase(params, std::move(name)), positions_only_(params.positions_only) {
    std::size_t offset = 0;
    for (const Item& it : params.items) {
      switch (it.type) {
        case kItemPoint14: break;
        case kItemRgb14:
        case kItemRgbNir14:
          rgb_ = std::make_unique<Rgb14V3>(it.type == kItemRgbNir14);
          rgb_offset_ = offset;
          break;
        case kItemWavePacket14:
          wave_ = true;
          wave_offset_ = offset;
          break;
        default:
          bytes_ = std::make_unique<Byte14V3>(it.size);
          bytes_offset_ = offset;
          break;
      }
      offset += it.size;
    }
  }

  Status begin(std::span<const std::uint8_t> bytes, std::uint64_t points, std::uint64_t index) override {
    RELIEF_RETURN_IF_ERROR(start(bytes, points, index));
    if (points == 0) return Status::ok();
    ByteReader r(bytes.subspan(rl_), name_ + ": LAZ chunk " + std::to_string(index + 1));
    std::uint32_t count = 0;
    RELIEF_RETURN_IF_ERROR(r.u32(count, "point count"));
    if (count != points) {
      return corrupt("holds " + std::to_string(count) + " points but the chunk table says " +
                     std::to_string(points));
    }
    // Layer sizes and layers come in item order: POINT14, RGB(NIR)14, the
    // wave packets' one layer (skipped), BYTE14.
    std::uint32_t wave_bytes = 0;
    std::vector<std::span<Layer>> groups = {point_.layers()};
    if (rgb_) groups.push_back(rgb_->layers());
    std::uint64_t total = 0;
    for (auto& g : groups) {
      for (Layer& layer : g) {
        RELIEF_RETURN_IF_ERROR(r.u32(layer.size, "layer size"));
        total += layer.size;
      }
    }
    if (wave_) {
      RELIEF_RETURN_IF_ERROR(r.u32(wave_bytes, "wave packet layer size"));
      total += wave_bytes;
    }
    if (bytes_) {
      for (Layer& layer : bytes_->layers()) {
        RELIEF_RETURN_IF_ERROR(r.u32(layer.size, "layer size"));
        total += layer.size;
      }
    }
    if (total > r.remaining()) {
      return corrupt("its layers need " + std::to_string(total) + " bytes but the chunk has " +
                     std::to_string(r.remaining()) + " left");
    }
    std::span<const std::uint8_t> data = bytes.subspan(rl_ + r.position());
    const auto start_group = [&](std::span<Layer> g) {
      std::uint64_t size = 0;
      for (Layer& layer : g) size += layer.size;
      const bool ok = start_layers(g, data.first(static_cast<std::size_t>(size)));
      data = data.subspan(static_cast<std::size_t>(size));
      return ok;
    };
    for (auto& g : groups) {
      if (!start_group(g)) return corrupt("a compressed layer is invalid");
    }
    data = data.subspan(wave_bytes);  // within `total`, checked above
    if (bytes_ && !start_group(bytes_->layers())) return corrupt("a compressed layer is invalid");
    if (positions_only_) {
      // Every layer but XY and Z reads as unchanged: its fields keep the
      // first point's values, and its bytes are neither decoded nor checked.
      const auto skip = [](std::span<Layer> g, std::size_t from) {
        for (std::size_t i = from; i < g.size(); ++i) g[i].changed = false;
      };
      skip(point_.layers(), kZ + 1);
      if (rgb_) skip(rgb_->layers(), 0);
      if (bytes_) skip(bytes_->layers(), 0);
    }
    const std::uint32_t context = point_.init(first_.data());
    if (rgb_) rgb_->init(first_.data() + rgb_offset_, context);
    if (bytes_) bytes_->init(first_.data() + bytes_offset_, context);
    return Status::ok();
  }

  Status decode(std::size_t n, std::uint8_t* out) override {
    assert(n <= left_);
    for (std::size_t i = 0; i < n; ++i, out += rl_) {
      if (first_pending_) {
        std::memcpy(out, first_.data(), rl_);
        first_pending_ = false;
      } else {
        const std::uint32_t context = point_.read(out);
        if (rgb_) rgb_->read(out + rgb_offset_, context);
        if (wave_) std::memset(out + wave_offset_, 0, kWavePacketSize);  // not decoded
        if (bytes_) bytes_->read(out + bytes_offset_, context);
      }
      ++decoded_;
    }
    left_ -= n;
    if (decoded_ > 1) {
      const auto over = [](std::span<Layer> g, bool first_always) {
        for (std::size_t i = 0; i < g.size(); ++i) {
          if ((g[i].changed || (first_always && i == 0)) && g[i].dec.overrun() > kOverrunSlack) return true;
        }
        return false;
      };
      if (over(point_.layers(), true) || (rgb_ && over(rgb_->layers(), false)) ||
          (bytes_ && over(bytes_->layers(), false))) {
        return cut_short();
      }
    }
    if (left_ == 0) {
      std::size_t unread = 0;
      for (auto g : {point_.layers(), rgb_ ? rgb_->layers() : std::span<Layer>(),
                     bytes_ ? bytes_->layers() : std::span<Layer>()}) {
        for (std::size_t i = 0; i < g.size(); ++i) {
          // (Layers skipped for positions_only are not read at all.)
          if (!positions_only_ || (g.data() == point_.layers().data() && i <= kZ)) unread += g[i].dec.unread();
        }
      }
      if (unread > 0) return trailing(unread);
    }
    return Status::ok();
  }

 private:
  Point14V3 point_;
  std::unique_ptr<Rgb14V3> rgb_;
  std::unique_ptr<Byte14V3> bytes_;
  std::size_t rgb_offset_ = 0;
  std::size_t bytes_offset_ = 0;
  bool wave_ = false;
  std::size_t wave_offset_ = 0;
  bool positions_only_ = false;
};

}  // namespace

Status ChunkDecoder::begin_fed(std::span<const std::uint8_t>, ByteFeed&, std::uint64_t) {
  return unsupported("only the pointwise LAZ compressors decode a stream given in pieces");
}

Result<std::unique_ptr<ChunkDecoder>> ChunkDecoder::create(const Params& params, const std::string& name) {
  if (params.compressor == kCompressorLayeredChunked) {
    return std::unique_ptr<ChunkDecoder>(std::make_unique<LayeredDecoder>(params, name));
  }
  if (params.compressor == kCompressorPointwiseChunked || params.compressor == kCompressorPointwise) {
    return std::unique_ptr<ChunkDecoder>(std::make_unique<PointwiseDecoder>(params, name));
  }
  return unsupported(name + ": LASzip compressor " + std::to_string(params.compressor) + " is not supported");
}

}  // namespace relief::laz
