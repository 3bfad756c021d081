// LASzip 1.x's variants, which Relief reads but does not write: item
// version 1 (POINT10, GPSTIME11, RGB12, BYTE) and the unchunked pointwise
// compressor (1). No LASzip-written file of either is at hand (none on this
// machine, none in the shared data, none found in other projects' tests), so
// the files here come from the test-side encoders of laz_v1_encoder.h:
// records in which every field varies go through them and must come back
// exactly, through the decoder API, the chunk reader (the unchunked stream
// fetched in pieces of every size) and the LAS reader (real records of
// simple.las rewritten as LASzip 1.x would have). Damaged files are refused
// with errors naming the file.
#include <catch2/catch.hpp>

#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "laz/laz_test_util.h"
#include "laz/laz_v1_encoder.h"
#include "relief/io.h"
#include "relief/laz.h"
#include "support/las_records.h"
#include "support/temp_dir.h"

using namespace relief::laztest;

namespace relief {
namespace {

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : s_(seed * 0x9E3779B97F4A7C15ull + 7) {}
  std::uint32_t next() {
    s_ = s_ * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<std::uint32_t>(s_ >> 32);
  }
  std::uint32_t below(std::uint32_t n) { return next() % n; }
  bool one_in(std::uint32_t n) { return below(n) == 0; }

 private:
  std::uint64_t s_;
};

void put(std::uint8_t* p, std::uint64_t v, int bytes) {
  for (int i = 0; i < bytes; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

constexpr std::size_t kBaseSize[] = {20, 28, 26, 34, 57, 63};

// Records of format 0-3 plus `extra` bytes in which every field varies the
// ways the version-1 models tell apart: coordinates step steadily, jitter,
// jump by up to 2^31 and wrap; intensity, the flag byte, classification,
// scan angle, user data and point source mostly repeat and sometimes
// change; GPS times repeat, step regularly, step by multiples of the last
// step from 0 to over 509 (the extreme multipliers), step backwards, jump by
// more than 32 bits or to any 64 bits; colours repeat or change in one byte,
// one channel or all; extra bytes repeat or change.
std::vector<std::uint8_t> varied_records(int format, std::size_t extra, std::size_t n, std::uint64_t seed) {
  Rng rng(seed);
  const std::size_t rl = kBaseSize[format] + extra;
  const bool gps = format == 1 || format == 3 || format == 4 || format == 5;
  const bool rgb = format == 2 || format == 3 || format == 5;
  const std::size_t rgb_at = format == 3 || format == 5 ? 28 : 20;
  // Formats 4 and 5: the wave packet descriptor last (index, offset,
  // size, return point, x y z step).
  const std::size_t wave_at = format == 4 ? 28 : 34;
  std::uint64_t wave_offset = 60000;
  std::uint32_t wave_size = 256;
  std::vector<std::uint8_t> out(n * rl);
  std::uint32_t x = 1000, y = 2000, z = 300;
  std::uint32_t step = 17;
  std::uint64_t t = 0x41C0000000000000ull;  // a double near 5e8
  std::int64_t t_step = 4096;
  std::uint8_t* prev = nullptr;
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* r = out.data() + i * rl;
    if (prev != nullptr) std::memcpy(r, prev, rl);
    switch (rng.below(8)) {
      case 0: step = rng.below(200); break;
      case 1: x += rng.next(); break;  // any jump, wrapping
      default: break;
    }
    x += step + rng.below(5);
    y += rng.one_in(20) ? rng.next() >> 1 : rng.below(50);
    z = rng.one_in(30) ? rng.next() : z + rng.below(9) - 4;
    put(r, x, 4);
    put(r + 4, y, 4);
    put(r + 8, z, 4);
    if (prev == nullptr || rng.one_in(3)) put(r + 12, rng.one_in(4) ? rng.next() : rng.below(300), 2);
    if (prev == nullptr || rng.one_in(5)) r[14] = static_cast<std::uint8_t>(rng.next());
    if (prev == nullptr || rng.one_in(7)) r[15] = static_cast<std::uint8_t>(rng.below(rng.one_in(3) ? 256 : 8));
    if (prev == nullptr || rng.one_in(9)) r[16] = static_cast<std::uint8_t>(rng.next());
    if (prev == nullptr || rng.one_in(11)) r[17] = static_cast<std::uint8_t>(rng.next());
    if (prev == nullptr || rng.one_in(13)) put(r + 18, rng.one_in(2) ? rng.next() : rng.below(4), 2);
    if (gps) {
      switch (rng.below(16)) {
        case 0: break;                                                      // repeats
        case 1: t_step = static_cast<std::int64_t>(rng.below(100000)) - 50000; break;  // new step
        case 2: t += t_step * static_cast<std::int64_t>(2 + rng.below(600)); break;  // multiples, extreme ones
        case 3: t += static_cast<std::uint64_t>(t_step / 7); break;        // much smaller (multiplier 0)
        case 4: t += std::uint64_t{1} << (33 + rng.below(20)); break;      // beyond 32 bits
        case 5: t = (std::uint64_t{rng.next()} << 32) | rng.next(); break; // any 64 bits
        case 6: t -= static_cast<std::uint64_t>(t_step) * 3; break;        // backwards
        case 7: t_step = 0; break;
        default: t += static_cast<std::uint64_t>(t_step); break;
      }
      put(r + 20, t, 8);
    }
    if (rgb) {
      std::uint8_t* c = r + rgb_at;
      switch (rng.below(6)) {
        case 0: c[rng.below(6)] = static_cast<std::uint8_t>(rng.next()); break;
        case 1: put(c + 2 * rng.below(3), rng.next(), 2); break;
        case 2:
          for (int b = 0; b < 6; ++b) c[b] = static_cast<std::uint8_t>(rng.next());
          break;
        default: break;
      }
      if (prev == nullptr) {
        for (int b = 0; b < 6; ++b) c[b] = static_cast<std::uint8_t>(rng.next());
      }
    }
    if (format >= 4) {
      // The offset repeats, follows the previous packet, steps by a 32-bit
      // difference (forwards or back) or jumps anywhere in 64 bits; the
      // other fields mostly repeat or change a little.
      std::uint8_t* w = r + wave_at;
      if (prev == nullptr || rng.one_in(9)) w[0] = static_cast<std::uint8_t>(rng.below(rng.one_in(4) ? 256 : 3));
      switch (rng.below(8)) {
        case 0: break;
        case 1: wave_offset += static_cast<std::uint64_t>(static_cast<std::int64_t>(static_cast<std::int32_t>(rng.next()))); break;
        case 2: wave_offset = (std::uint64_t{rng.next()} << 32) | rng.next(); break;
        case 3: wave_offset += std::uint64_t{rng.below(1000)}; break;
        default: wave_offset += wave_size; break;
      }
      if (rng.one_in(5)) wave_size = rng.one_in(3) ? rng.next() : 200 + rng.below(100);
      put(w + 1, wave_offset, 8);
      put(w + 9, wave_size, 4);
      for (int f = 0; f < 4; ++f) {
        if (prev == nullptr || rng.one_in(4)) put(w + 13 + 4 * f, rng.one_in(3) ? rng.next() : 0x3F800000u + rng.below(4096), 4);
      }
    }
    for (std::size_t b = 0; b < extra; ++b) {
      if (prev == nullptr || rng.one_in(2 + static_cast<std::uint32_t>(b))) {
        r[kBaseSize[format] + b] = static_cast<std::uint8_t>(rng.one_in(3) ? rng.next() : r[kBaseSize[format] + b] + 1);
      }
    }
    prev = r;
  }
  return out;
}

// Decodes an unchunked stream through the decoder API (the whole stream
// at once).
Result<std::vector<std::uint8_t>> decode_whole(const laz::Params& params, std::span<const std::uint8_t> stream,
                                               std::size_t count) {
  RELIEF_ASSIGN_OR_RETURN(laz::Chunk whole, laz::unchunked_stream(params, 0, stream.size(), count, "v1"));
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<laz::ChunkDecoder> dec, laz::ChunkDecoder::create(params, "v1"));
  std::vector<std::uint8_t> out(count * params.record_length);
  RELIEF_RETURN_IF_ERROR(dec->begin(stream, whole.points, 0));
  std::size_t at = 0;
  while (at < count) {
    const std::size_t n = std::min<std::size_t>(count - at, 333);
    RELIEF_RETURN_IF_ERROR(dec->decode(n, out.data() + at * params.record_length));
    at += n;
  }
  return out;
}

// Decodes a point region (at file offset `base` of `file`) through the
// chunk reader, as the LAS reader does; an unchunked stream is fetched in
// pieces of `piece` bytes.
Result<std::vector<std::uint8_t>> decode_region(const laz::Params& params, const std::vector<std::uint8_t>& file,
                                                std::uint64_t base, std::size_t count, std::size_t piece) {
  std::vector<laz::Chunk> chunks;
  if (params.unchunked()) {
    RELIEF_ASSIGN_OR_RETURN(laz::Chunk whole, laz::unchunked_stream(params, base, file.size(), count, "v1"));
    chunks.push_back(whole);
  } else {
    const std::uint64_t table = le_u64(file.data() + base);
    if (table >= file.size()) return format_error("v1: table outside");
    RELIEF_ASSIGN_OR_RETURN(chunks, laz::parse_chunk_table(std::span(file).subspan(table), params, base + 8, table,
                                                           count, "v1"));
  }
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<laz::ChunkReader> reader,
                          laz::ChunkReader::create(params, chunks, 2, "v1", laz::kMaxParallelChunkBytes, piece));
  std::uint64_t fetched_to = 0;
  const laz::ChunkReader::Fetch fetch = [&](std::uint64_t offset, std::size_t bytes, std::vector<std::uint8_t>& out) {
    if (offset < fetched_to) return internal_error("fetch went backwards");
    if (offset + bytes > file.size()) return io_error("v1: fetch past the end");
    out.assign(file.begin() + static_cast<std::ptrdiff_t>(offset),
               file.begin() + static_cast<std::ptrdiff_t>(offset + bytes));
    fetched_to = offset + bytes;
    return Status::ok();
  };
  std::vector<std::uint8_t> out;
  for (;;) {
    std::span<const std::uint8_t> records;
    RELIEF_RETURN_IF_ERROR(reader->next(fetch, records));
    if (records.empty()) break;
    out.insert(out.end(), records.begin(), records.end());
  }
  return out;
}

long first_difference(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b, std::size_t rl) {
  if (a.size() != b.size()) return -2;
  for (std::size_t i = 0; i < a.size(); i += rl) {
    if (std::memcmp(a.data() + i, b.data() + i, rl) != 0) return static_cast<long>(i / rl);
  }
  return -1;
}

}  // namespace

TEST_CASE("LAZ v1: version-1 items, alone and mixed with version 2, come back exactly", "[laz][v1]") {
  constexpr std::size_t kPoints = 2500;
  for (int format = 0; format <= 3; ++format) {
    for (const std::size_t extra : {std::size_t{0}, std::size_t{3}}) {
      const std::size_t rl = kBaseSize[format] + extra;
      const auto records = varied_records(format, extra, kPoints, 100 + static_cast<std::uint64_t>(format) * 7 + extra);
      const std::size_t item_count = laz::items_for_format(format).types.size() + (extra > 0 ? 1 : 0);
      // Every assignment of versions 1 and 2 to the items (LASzip's reader
      // takes each item's version on its own).
      for (unsigned mask = 0; mask < (1u << item_count); ++mask) {
        const auto items = pointwise_items(format, extra, mask);
        INFO("format " << format << ", " << extra << " extra bytes, version-1 items mask " << mask);
        {
          auto params = laz::parse_vlr(pointwise_vlr(1, 0, items), format, rl, "v1");
          INFO(params.status().to_string());
          REQUIRE(params.is_ok());
          CHECK(params->unchunked());
          const auto stream = encode_pointwise(records, rl, items);
          auto whole = decode_whole(*params, stream, kPoints);
          INFO(whole.status().to_string());
          REQUIRE(whole.is_ok());
          CHECK(first_difference(*whole, records, rl) == -1);
          // Through the chunk reader, the stream in pieces of every kind of
          // size: a byte, odd sizes, more than the stream.
          std::vector<std::uint8_t> file(5 + stream.size(), 0xEE);  // the stream need not start at 0
          std::copy(stream.begin(), stream.end(), file.begin() + 5);
          for (const std::size_t piece : {std::size_t{1}, std::size_t{7}, std::size_t{1000}, std::size_t{1} << 20}) {
            auto got = decode_region(*params, file, 5, kPoints, piece);
            INFO("pieces of " << piece << " bytes: " << got.status().to_string());
            REQUIRE(got.is_ok());
            CHECK(first_difference(*got, records, rl) == -1);
          }
        }
        {
          // Version-1 items in LASzip 2's chunks: each chunk starts afresh.
          auto params = laz::parse_vlr(pointwise_vlr(2, 777, items), format, rl, "v1");
          INFO(params.status().to_string());
          REQUIRE(params.is_ok());
          const auto region = chunked_region(records, rl, items, 777, 0);
          auto got = decode_region(*params, region, 0, kPoints, laz::kStreamPieceBytes);
          INFO(got.status().to_string());
          REQUIRE(got.is_ok());
          CHECK(first_difference(*got, records, rl) == -1);
        }
      }
    }
  }
}

TEST_CASE("LAZ v1: a read error in the middle of an unchunked stream is reported as such", "[laz][v1][reject]") {
  const auto items = pointwise_items(1, 0, 0x3);
  auto params = laz::parse_vlr(pointwise_vlr(1, 0, items), 1, 28, "v1");
  REQUIRE(params.is_ok());
  const auto records = varied_records(1, 0, 20000, 9);
  const auto stream = encode_pointwise(records, 28, items);
  REQUIRE(stream.size() > 3000);
  auto whole = laz::unchunked_stream(*params, 0, stream.size(), 20000, "v1");
  REQUIRE(whole.is_ok());
  auto reader = laz::ChunkReader::create(*params, {*whole}, 4, "v1", laz::kMaxParallelChunkBytes, 1000);
  REQUIRE(reader.is_ok());
  // The third piece cannot be read.
  const laz::ChunkReader::Fetch fetch = [&](std::uint64_t offset, std::size_t bytes, std::vector<std::uint8_t>& out) {
    if (offset >= 2000) return io_error("v1: the disk failed at byte " + std::to_string(offset));
    out.assign(stream.begin() + static_cast<std::ptrdiff_t>(offset),
               stream.begin() + static_cast<std::ptrdiff_t>(offset + bytes));
    return Status::ok();
  };
  std::size_t got = 0;
  Status status;
  for (;;) {
    std::span<const std::uint8_t> out;
    status = (*reader)->next(fetch, out);
    if (!status.is_ok() || out.empty()) break;
    CHECK(std::memcmp(out.data(), records.data() + got * 28, out.size()) == 0);
    got += out.size() / 28;
  }
  REQUIRE_FALSE(status.is_ok());
  CHECK(status.code() == StatusCode::kIoError);
  CHECK(status.message().find("the disk failed at byte 2000") != std::string::npos);
  CHECK(got < 20000);
}

TEST_CASE("LAZ v1: one point, and a stream of repeats, decode", "[laz][v1]") {
  const auto items = pointwise_items(3, 2, 0xF);
  auto params = laz::parse_vlr(pointwise_vlr(1, 0, items), 3, 36, "v1");
  REQUIRE(params.is_ok());
  auto records = varied_records(3, 2, 1, 5);
  auto one = decode_whole(*params, encode_pointwise(records, 36, items), 1);
  REQUIRE(one.is_ok());
  CHECK(*one == records);
  // The same record 5000 times: a few bytes of stream.
  std::vector<std::uint8_t> same;
  for (int i = 0; i < 5000; ++i) same.insert(same.end(), records.begin(), records.end());
  const auto stream = encode_pointwise(same, 36, items);
  CHECK(stream.size() < 36 + 1000);
  auto got = decode_whole(*params, stream, 5000);
  REQUIRE(got.is_ok());
  CHECK(*got == same);
}

namespace {

const std::string kSimpleLaz = std::string(RELIEF_SOURCE_DIR) + "/tests/data/simple.laz";
const std::string kSimpleLas = std::string(RELIEF_SOURCE_DIR) + "/tests/data/simple.las";

// simple.laz as LASzip 1.x would have written it: its header and VLRs with
// the LASzip VLR saying `compressor` and item versions (`v1_mask`), then
// simple.las's records compressed so (with chunks of 500 for compressor 2).
TEST_CASE("LAZ: waveform formats 4 and 5 come back exactly, their wave packets decoded", "[laz][v1][wave]") {
  constexpr std::size_t kPoints = 3000;
  for (int format = 4; format <= 5; ++format) {
    for (const std::size_t extra : {std::size_t{0}, std::size_t{2}}) {
      const std::size_t rl = kBaseSize[format] + extra;
      const auto records = varied_records(format, extra, kPoints, 300 + static_cast<std::uint64_t>(format) * 5 + extra);
      // Every version of the other items; the wave packets in version 1.
      for (const unsigned mask : {0u, 1u, 0x7u, 0xFu}) {
        const auto items = pointwise_items(format, extra, mask);
        INFO("format " << format << ", " << extra << " extra bytes, version-1 items mask " << mask);
        for (const std::uint16_t compressor : {std::uint16_t{1}, std::uint16_t{2}}) {
          INFO("compressor " << compressor);
          auto params = laz::parse_vlr(pointwise_vlr(compressor, compressor == 1 ? 0 : 1000, items), format, rl,
                                       "wave.laz");
          INFO(params.status().to_string());
          REQUIRE(params.is_ok());
          const auto region = compressor == 1 ? encode_pointwise(records, rl, items)
                                              : chunked_region(records, rl, items, 1000, 0);
          auto got = decode_region(*params, region, 0, kPoints, 777);
          INFO(got.status().to_string());
          REQUIRE(got.is_ok());
          CHECK(first_difference(*got, records, rl) == -1);
        }
      }
    }
  }
  // The wave packet item exists in version 1 only.
  const std::vector<laz::Item> v2 = {{laz::kItemPoint10, 20, 2}, {laz::kItemGpsTime11, 8, 2}, {laz::kItemWavePacket13, 29, 2}};
  const auto r = laz::parse_vlr(pointwise_vlr(2, 1000, v2), 4, 57, "wave.laz");
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().message().find("wave.laz") != std::string::npos);
  CHECK(r.status().message().find("WAVEPACKET13 version 2") != std::string::npos);
}

std::vector<std::uint8_t> simple_as(std::uint16_t compressor, unsigned v1_mask) {
  const auto laz = slurp(kSimpleLaz);
  const auto las = slurp(kSimpleLas);
  const Header h = header_of(laz);
  const auto records = twin_records(las, h);
  const auto [vlr_at, vlr_len] = laszip_vlr(laz, h);
  REQUIRE(vlr_len == 34 + 3 * 6);
  const auto items = pointwise_items(h.format, 0, v1_mask);
  const auto vlr = pointwise_vlr(compressor, compressor == 1 ? 0 : 500, items);
  REQUIRE(vlr.size() == vlr_len);
  std::vector<std::uint8_t> f(laz.begin(), laz.begin() + h.point_offset);
  std::copy(vlr.begin(), vlr.end(), f.begin() + static_cast<std::ptrdiff_t>(vlr_at));
  const auto region = compressor == 1 ? encode_pointwise(records, h.record_length, items)
                                      : chunked_region(records, h.record_length, items, 500, h.point_offset);
  f.insert(f.end(), region.begin(), region.end());
  return f;
}

// Every point of `path` through the LAS reader, with its LAS attributes.
Result<PointCloud> read_all(const std::string& path) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> reader, open_point_reader(path));
  PointCloud all;
  RELIEF_ASSIGN_OR_RETURN(std::size_t n, reader->read(all, 1u << 20));
  PointCloud rest;
  RELIEF_ASSIGN_OR_RETURN(std::size_t more, reader->read(rest, 1u << 20));
  if (more != 0) return internal_error("more points than asked for");
  (void)n;
  return all;
}

void check_same_cloud(const PointCloud& a, const PointCloud& b) {
  CHECK(a.positions == b.positions);
  CHECK(a.colors == b.colors);
  CHECK(a.intensities == b.intensities);
  CHECK(a.las.classification == b.las.classification);
  CHECK(a.las.class_flags == b.las.class_flags);
  CHECK(a.las.return_number == b.las.return_number);
  CHECK(a.las.number_of_returns == b.las.number_of_returns);
  CHECK(a.las.scan_flags == b.las.scan_flags);
  CHECK(a.las.scan_angle == b.las.scan_angle);
  CHECK(a.las.user_data == b.las.user_data);
  CHECK(a.las.point_source_id == b.las.point_source_id);
  REQUIRE(a.las.gps_time.size() == b.las.gps_time.size());
  CHECK(std::memcmp(a.las.gps_time.data(), b.las.gps_time.data(), a.las.gps_time.size() * sizeof(double)) == 0);
}

}  // namespace

TEST_CASE("LAZ v1: the LAS reader reads LASzip 1.x files to the twin's cloud", "[laz][v1][io]") {
  test::TempDir tmp;
  const auto want = read_all(kSimpleLas);
  REQUIRE(want.is_ok());
  REQUIRE(want->positions.size() == 1065);
  const struct {
    std::uint16_t compressor;
    unsigned v1_mask;
    const char* what;
  } cases[] = {
      {1, 0x7, "unchunked, version-1 items"},
      {1, 0x0, "unchunked, version-2 items"},
      {1, 0x5, "unchunked, POINT10 and RGB12 in version 1, GPSTIME11 in version 2"},
      {2, 0x7, "chunked, version-1 items"},
  };
  for (const auto& c : cases) {
    INFO(c.what);
    const std::string path = tmp.file("old.laz");
    spit(path, simple_as(c.compressor, c.v1_mask));
    const auto got = read_all(path);
    INFO(got.status().to_string());
    REQUIRE(got.is_ok());
    check_same_cloud(*got, *want);
  }
}

namespace {

// A LAS file (1.2, no VLRs) rewritten as LAZ with `items`, chunks of 400.
std::vector<std::uint8_t> laz_of_las(const std::vector<std::uint8_t>& las, const std::vector<laz::Item>& items) {
  const Header h = header_of(las);
  REQUIRE(h.point_offset == 227);
  const std::vector<std::uint8_t> records(las.begin() + h.point_offset, las.end());
  const auto payload = pointwise_vlr(2, 400, items);
  std::vector<std::uint8_t> f(las.begin(), las.begin() + h.point_offset);
  std::vector<std::uint8_t> vlr(54, 0);
  std::memcpy(vlr.data() + 2, "laszip encoded", 14);
  put(vlr.data() + 18, 22204, 2);
  put(vlr.data() + 20, payload.size(), 2);
  f.insert(f.end(), vlr.begin(), vlr.end());
  f.insert(f.end(), payload.begin(), payload.end());
  put(f.data() + 96, f.size(), 4);  // offset to the point data
  put(f.data() + 100, 1, 4);        // one VLR
  f[104] = static_cast<std::uint8_t>(f[104] | 0x80);
  const auto region = chunked_region(records, h.record_length, items, 400, f.size());
  f.insert(f.end(), region.begin(), region.end());
  return f;
}

}  // namespace

TEST_CASE("LAZ: the LAS reader reads waveform LAZ (formats 4 and 5) to the LAS file's cloud", "[laz][v1][wave][io]") {
  test::TempDir tmp;
  for (const int format : {4, 5}) {
    for (const std::size_t extra : {std::size_t{0}, std::size_t{3}}) {
      INFO("format " << format << ", " << extra << " extra bytes");
      test::TestLasOptions o;
      o.format = format;
      o.points = 2100;
      o.extra = extra;
      o.seed = static_cast<std::uint32_t>(format * 10 + extra);
      const std::string las = tmp.file("w.las"), lazf = tmp.file("w.laz");
      REQUIRE(test::write_test_las(las, o));
      spit(lazf, laz_of_las(slurp(las), pointwise_items(format, extra, 0)));
      const auto want = read_all(las);
      REQUIRE(want.is_ok());
      REQUIRE(want->size() == 2100);
      const auto got = read_all(lazf);
      INFO(got.status().to_string());
      REQUIRE(got.is_ok());
      check_same_cloud(*got, *want);
      CHECK(got->las.extra_bytes == want->las.extra_bytes);
    }
  }
}

TEST_CASE("LAZ v1: damaged LASzip 1.x files are refused naming the file, never crash", "[laz][v1][reject]") {
  test::TempDir tmp;
  const auto good = simple_as(1, 0x7);
  const Header h = header_of(good);
  const auto want = read_all(kSimpleLas);
  REQUIRE(want.is_ok());
  const std::string path = tmp.file("bad.laz");
  // Cut anywhere in the point data: refused, but for the last 3 bytes, which
  // may be the encoder's final zeros (a decoder reads zeros past the end).
  std::size_t refused = 0;
  for (std::size_t n = h.point_offset; n + 3 < good.size(); n += (n < h.point_offset + 64 ? 1 : 101)) {
    INFO("cut to " << n << " of " << good.size() << " bytes");
    spit(path, std::vector<std::uint8_t>(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(n)));
    const auto r = read_all(path);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find("bad.laz") != std::string::npos);
    ++refused;
  }
  CHECK(refused > 100);
  for (std::size_t cut = 1; cut <= 3; ++cut) {
    spit(path, std::vector<std::uint8_t>(good.begin(), good.end() - static_cast<std::ptrdiff_t>(cut)));
    const auto r = read_all(path);
    if (r.is_ok()) check_same_cloud(*r, *want);
  }
  // Bytes after the stream: the header's count no longer accounts for the data.
  {
    auto longer = good;
    longer.insert(longer.end(), 16, 0x55);
    spit(path, longer);
    const auto r = read_all(path);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find("bad.laz") != std::string::npos);
    CHECK(r.status().message().find("compressor 1") != std::string::npos);
  }
  // Flipped bytes: an error naming the file, or (undetectable in a
  // decodable stream) a full cloud; never a crash or unbounded work.
  std::size_t tries = 0;
  refused = 0;
  for (std::size_t i = h.point_offset; i < good.size(); i += 29) {
    auto bad = good;
    bad[i] ^= static_cast<std::uint8_t>(0x35 + i);
    spit(path, bad);
    const auto r = read_all(path);
    ++tries;
    if (!r.is_ok()) {
      ++refused;
      CHECK(r.status().message().find("bad.laz") != std::string::npos);
    } else {
      CHECK(r->positions.size() == 1065);
    }
  }
  CHECK(tries > 700);
  CHECK(refused > tries / 2);
  WARN(refused << " of " << tries << " damaged LASzip 1.x files refused");
  // Header counts the stream cannot hold, or that leave bytes over.
  for (const std::uint32_t count : {0u, 1u, 1064u, 1066u, 0x7FFFFFFFu}) {
    auto bad = good;
    put(bad.data() + 107, count, 4);
    spit(path, bad);
    const auto r = read_all(path);
    INFO("point count " << count);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find("bad.laz") != std::string::npos);
  }
}

TEST_CASE("LAZ v1: variants still not read are refused naming the file and the variant", "[laz][v1][reject]") {
  const auto p10 = [](std::uint16_t version) { return laz::Item{laz::kItemPoint10, 20, version}; };
  struct Case {
    std::uint16_t compressor;
    int format;
    std::vector<laz::Item> items;
    std::size_t rl;
    const char* expect;
  };
  const Case cases[] = {
      {1, 0, {p10(4)}, 20, "POINT10 version 4"},
      {2, 0, {p10(0)}, 20, "POINT10 version 0"},
      {1, 6, {{laz::kItemPoint14, 30, 3}}, 30, "compressor 1"},
      {3, 6, {{laz::kItemPoint14, 30, 1}}, 30, "POINT14 version 1"},
      {2, 4, {p10(2), {laz::kItemGpsTime11, 8, 2}, {9, 29, 3}}, 57, "WAVEPACKET13 version 3"},
      {2, 11, {p10(2)}, 20, "point format 11"},
  };
  for (const Case& c : cases) {
    INFO(c.expect);
    const auto r = laz::parse_vlr(pointwise_vlr(c.compressor, 0, c.items), c.format, c.rl, "old.laz");
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find("old.laz") != std::string::npos);
    CHECK(r.status().message().find(c.expect) != std::string::npos);
  }
}

// Not a test: writes the fuzz seed of the LAS target for LASzip 1.x files
// (tests/fuzz/corpus/las/seed-laz-v1-unchunked.laz) when
// RELIEF_FUZZ_SEED_DIR names the corpus folder.
TEST_CASE("LAZ v1: fuzz seed", "[.seed]") {
  const char* dir = std::getenv("RELIEF_FUZZ_SEED_DIR");
  if (dir == nullptr) return;
  // simple.laz's first 16 points, unchunked, in version 1.
  auto f = simple_as(1, 0x7);
  const Header h = header_of(f);
  const auto records = twin_records(slurp(kSimpleLas), header_of(slurp(kSimpleLaz)));
  const auto items = pointwise_items(h.format, 0, 0x7);
  const auto stream = encode_pointwise(std::span(records).first(16 * h.record_length), h.record_length, items);
  f.resize(h.point_offset);
  f.insert(f.end(), stream.begin(), stream.end());
  put(f.data() + 107, 16, 4);
  spit(std::string(dir) + "/seed-laz-v1-unchunked.laz", f);
  // A waveform LAZ (format 5, every field random): 40 points in chunks of 400.
  test::TempDir tmp;
  test::TestLasOptions o;
  o.format = 5;
  o.points = 40;
  o.seed = 5;
  REQUIRE(test::write_test_las(tmp.file("w.las"), o));
  spit(std::string(dir) + "/seed-laz-wave-format5.laz", laz_of_las(slurp(tmp.file("w.las")), pointwise_items(5, 0, 0)));
}

}  // namespace relief
