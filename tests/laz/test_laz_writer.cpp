// LAZ writing: seeded random records of every point format the writer
// covers (0-3 and 6-8, with and without extra bytes) come back exactly
// through the reader, with fixed and variable chunk sizes, and an empty file
// is a valid LAZ point region. (Byte-for-byte equality with LASzip's output
// is in test_laz.cpp, on real files.)
#include <catch2/catch.hpp>

#include <cstdint>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "laz/laz_test_util.h"
#include "relief/laz.h"
#include "support/sanitized.h"

using namespace relief::laztest;

namespace relief {
namespace {

class Rng {
 public:
  explicit Rng(std::uint64_t seed) : s_(seed * 2654435761u + 1) {}
  std::uint32_t next() {
    s_ = s_ * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<std::uint32_t>(s_ >> 33);
  }
  std::uint32_t below(std::uint32_t n) { return next() % n; }
  bool one_in(std::uint32_t n) { return below(n) == 0; }
  std::uint64_t next64() { return (static_cast<std::uint64_t>(next()) << 32) | next(); }

 private:
  std::uint64_t s_;
};

std::size_t base_size(int format) {
  constexpr std::size_t kSizes[] = {20, 28, 26, 34, 0, 0, 30, 36, 38};
  return kSizes[format];
}

void put16(std::uint8_t* p, std::uint32_t v) {
  p[0] = static_cast<std::uint8_t>(v);
  p[1] = static_cast<std::uint8_t>(v >> 8);
}
std::uint32_t get16(const std::uint8_t* p) { return static_cast<std::uint32_t>(p[0] | (p[1] << 8)); }
void put32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put64(std::uint8_t* p, std::uint64_t v) {
  put32(p, static_cast<std::uint32_t>(v));
  put32(p + 4, static_cast<std::uint32_t>(v >> 32));
}

// Records in which every field changes in every way the coders tell apart:
// each field mostly repeats or steps (what compresses), sometimes jumps to
// any value; GPS times step, repeat, jump by more than 32 bits, come back to
// an earlier sequence, or are any 64 bits (NaNs included); the scanner
// channel (formats 6-8) switches among all four; and one record in 50 is
// random bytes throughout.
std::vector<std::uint8_t> random_records(int format, std::size_t rl, std::size_t n, std::uint64_t seed) {
  Rng rng(seed);
  const bool layered = format >= 6;
  const bool gps = format == 1 || format == 3 || layered;
  const std::size_t gps_at = layered ? 22 : 20;
  const std::size_t rgb_at = layered ? 30 : (format == 3 ? 28 : 20);
  const bool rgb = format == 2 || format == 3 || format == 7 || format == 8;
  const std::size_t base = base_size(format);
  std::vector<std::uint8_t> out(n * rl);
  std::vector<std::uint8_t> prev(rl, 0);
  std::uint64_t times[3] = {rng.next64() >> 12, 0x41D0000000000000ull, 0x4000000000000000ull};
  std::uint32_t channel = 0;
  // How often fields change: per record set, so that chunks see both runs
  // of repeats (layers left out) and busy stretches.
  const std::uint32_t calm = 1 + rng.below(8);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* p = out.data() + i * rl;
    if (rng.one_in(50)) {
      for (std::size_t b = 0; b < rl; ++b) p[b] = static_cast<std::uint8_t>(rng.next());
      std::memcpy(prev.data(), p, rl);
      continue;
    }
    std::memcpy(p, prev.data(), rl);
    for (int c = 0; c < 3; ++c) {
      std::uint32_t v;
      std::memcpy(&v, p + 4 * c, 4);
      v = rng.one_in(40) ? rng.next() * 2u + rng.below(2) : v + rng.below(2001) - 1000;
      put32(p + 4 * c, v);
    }
    if (rng.one_in(calm)) put16(p + 12, rng.one_in(3) ? rng.below(65536) : get16(p + 12) + rng.below(21) - 10);
    const auto flip = [&](std::size_t at) {
      if (rng.one_in(calm * 2)) p[at] = static_cast<std::uint8_t>(rng.next());
    };
    if (layered) {
      if (rng.one_in(calm)) {
        // Returns: usually a plausible pair, sometimes any two nibbles.
        const std::uint32_t nr = 1 + rng.below(15);
        const std::uint32_t r = rng.one_in(5) ? rng.below(16) : 1 + rng.below(nr);
        p[14] = static_cast<std::uint8_t>(r | (rng.one_in(6) ? rng.below(16) : nr) << 4);
      }
      if (rng.one_in(calm * 2)) channel = rng.below(4);
      std::uint8_t b15 = p[15];
      if (rng.one_in(calm * 2)) b15 = static_cast<std::uint8_t>(rng.next());
      p[15] = static_cast<std::uint8_t>((b15 & 0xCF) | (channel << 4));
      flip(16);
      flip(17);
      if (rng.one_in(calm)) put16(p + 18, rng.below(65536));  // scan angle
      if (rng.one_in(calm * 3)) put16(p + 20, rng.below(65536));
    } else {
      flip(14);
      flip(15);
      flip(16);
      flip(17);
      if (rng.one_in(calm * 3)) put16(p + 18, rng.below(65536));
    }
    if (gps) {
      std::uint64_t t;
      std::memcpy(&t, p + gps_at, 8);
      switch (rng.below(12)) {
        case 0: t = rng.next64(); break;                                   // anything
        case 1: t += (static_cast<std::uint64_t>(rng.next()) << 33); break;  // beyond 32 bits
        case 2: t = times[rng.below(3)]; break;                            // an earlier sequence
        case 3: times[rng.below(3)] = t; break;                            // repeat, remembered
        case 4: t -= rng.below(100000); break;
        default: t += 1000 + rng.below(3) * 17; break;                     // regular pulses
      }
      put64(p + gps_at, t);
    }
    if (rgb && rng.one_in(calm)) {
      if (rng.one_in(3)) {
        const std::uint32_t grey = rng.below(65536);
        for (int c = 0; c < 3; ++c) put16(p + rgb_at + 2 * c, grey);
      } else {
        for (int c = 0; c < 3; ++c) put16(p + rgb_at + 2 * c, get16(p + rgb_at + 2 * c) + rng.below(513) - 256);
      }
    }
    if (format == 8 && rng.one_in(calm)) put16(p + 36, rng.below(65536));
    for (std::size_t b = base; b < rl; ++b) {
      if (rng.one_in(calm + static_cast<std::uint32_t>(b - base))) p[b] = static_cast<std::uint8_t>(rng.next());
    }
    std::memcpy(prev.data(), p, rl);
  }
  return out;
}

// The index of the first record that differs, or -1.
long first_difference(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& b, std::size_t rl) {
  if (a.size() != b.size()) return 0;
  for (std::size_t i = 0; i < a.size(); i += rl) {
    if (std::memcmp(a.data() + i, b.data() + i, rl) != 0) return static_cast<long>(i / rl);
  }
  return -1;
}

}  // namespace

TEST_CASE("LAZ writer: random records of every format come back exactly", "[laz][writer]") {
  for (const int format : {0, 1, 2, 3, 6, 7, 8}) {
    for (const std::size_t extra : {std::size_t{0}, std::size_t{1}, std::size_t{3}, std::size_t{20}}) {
      for (std::uint64_t seed = 1; seed <= (test::kSanitized ? 1u : 3u); ++seed) {
        DYNAMIC_SECTION("format " << format << ", " << extra << " extra bytes, seed " << seed) {
          const std::size_t rl = base_size(format) + extra;
          const auto records = random_records(format, rl, 6000, seed * 100 + static_cast<std::uint64_t>(format));
          CHECK(first_difference(round_trip(records, format, rl, 1000), records, rl) == -1);
          CHECK(first_difference(round_trip(records, format, rl, 50000), records, rl) == -1);
          // Chunks of one point each (on fewer records: every chunk restarts every model).
          const std::vector<std::uint8_t> few(records.begin(), records.begin() + static_cast<std::ptrdiff_t>(300 * rl));
          CHECK(first_difference(round_trip(few, format, rl, 1), few, rl) == -1);
          // Chunks compressed side by side: the same records back.
          CHECK(first_difference(round_trip(records, format, rl, 1000, {}, false, 3), records, rl) == -1);
          CHECK(first_difference(round_trip(few, format, rl, 1, {}, false, 4), few, rl) == -1);
          // Variable chunks of uneven sizes, single points among them.
          CHECK(first_difference(round_trip(records, format, rl, laz::kVariableChunks, {777, 1, 2048, 5, 3000}),
                                 records, rl) == -1);
        }
      }
    }
  }
}

TEST_CASE("LAZ positions_only: layered chunks give every x, y, z while skipping the other layers",
          "[laz][selective]") {
  for (const int format : {0, 3, 6, 7, 8}) {
    for (const std::size_t extra : {std::size_t{0}, std::size_t{5}}) {
      DYNAMIC_SECTION("format " << format << ", " << extra << " extra bytes") {
        const std::size_t rl = base_size(format) + extra;
        const auto records = random_records(format, rl, 6000, 77 + static_cast<std::uint64_t>(format));
        for (const std::uint32_t chunk : {std::uint32_t{1000}, std::uint32_t{1}}) {
          const std::vector<std::uint8_t> in(records.begin(),
                                             records.begin() + static_cast<std::ptrdiff_t>((chunk == 1 ? 200 : 6000) * rl));
          const auto got = round_trip(in, format, rl, chunk, {}, /*positions_only=*/true);
          REQUIRE(got.size() == in.size());
          bool same_xyz = true, same_rest = true;
          for (std::size_t i = 0; i < in.size(); i += rl) {
            same_xyz = same_xyz && std::memcmp(got.data() + i, in.data() + i, 12) == 0;
            same_rest = same_rest && std::memcmp(got.data() + i + 12, in.data() + i + 12, rl - 12) == 0;
          }
          CHECK(same_xyz);
          // The pointwise formats decode everything; the layered ones do not
          // decode what changes in other layers (chunks of one point are
          // their raw first points, whole).
          CHECK(same_rest == (format < 6 || chunk == 1));
        }
      }
    }
  }
}

TEST_CASE("LAZ writer: a record that repeats its predecessor in every field", "[laz][writer]") {
  // All layers but XY and Z are then left out of the chunk (and BYTE's
  // stream codes only zeros): the reader must still give the records back.
  for (const int format : {1, 6, 7, 8}) {
    const std::size_t rl = base_size(format) + 4;
    std::vector<std::uint8_t> one(rl);
    for (std::size_t b = 0; b < rl; ++b) one[b] = static_cast<std::uint8_t>(b * 37 + 11);
    std::vector<std::uint8_t> records;
    for (int i = 0; i < 300; ++i) records.insert(records.end(), one.begin(), one.end());
    INFO("format " << format);
    CHECK(round_trip(records, format, rl, 100) == records);
  }
}

TEST_CASE("LAZ writer: no points makes an empty chunk table", "[laz][writer]") {
  for (const int format : {0, 3, 6, 8}) {
    const std::size_t rl = base_size(format) + 2;
    auto comp = laz::PointCompressor::create(format, rl, laz::PointCompressor::kDefaultChunkSize, "empty");
    REQUIRE(comp.is_ok());
    std::vector<std::uint8_t> chunks;
    (*comp)->flush_chunk(chunks);  // nothing to end
    const auto table = (*comp)->finish(chunks);
    CHECK(chunks.empty());
    // Version 0, no chunks.
    CHECK(table == std::vector<std::uint8_t>{0, 0, 0, 0, 0, 0, 0, 0});
    auto params = laz::parse_vlr((*comp)->vlr_payload(), format, rl, "empty");
    REQUIRE(params.is_ok());
    auto parsed = laz::parse_chunk_table(table, *params, 8, 8, 0, "empty");
    REQUIRE(parsed.is_ok());
    CHECK(parsed->empty());
  }
}

TEST_CASE("LAZ writer: flush_chunk ends variable chunks only", "[laz][writer]") {
  const std::size_t rl = base_size(7);
  const auto records = random_records(7, rl, 500, 11);
  const auto compress = [&](std::uint32_t chunk_size, bool flush) {
    auto comp = laz::PointCompressor::create(7, rl, chunk_size, "flush");
    REQUIRE(comp.is_ok());
    std::vector<std::uint8_t> out;
    (*comp)->add(records.data(), 123, out);
    if (flush) (*comp)->flush_chunk(out);
    (*comp)->add(records.data() + 123 * rl, 500 - 123, out);
    const auto table = (*comp)->finish(out);
    out.insert(out.end(), table.begin(), table.end());
    return out;
  };
  // Fixed chunks of 200: a short chunk at 123 would make readers count wrong.
  CHECK(compress(200, true) == compress(200, false));
  CHECK(compress(laz::kVariableChunks, true) != compress(laz::kVariableChunks, false));
}

TEST_CASE("LAZ writer: the VLR names the items of the format and its extra bytes", "[laz][writer]") {
  struct Case {
    int format;
    std::size_t extra;
    std::uint16_t compressor;
    std::vector<laz::Item> items;
  };
  const Case cases[] = {
      {0, 0, 2, {{6, 20, 2}}},
      {1, 5, 2, {{6, 20, 2}, {7, 8, 2}, {0, 5, 2}}},
      {3, 0, 2, {{6, 20, 2}, {7, 8, 2}, {8, 6, 2}}},
      {6, 0, 3, {{10, 30, 3}}},
      {7, 2, 3, {{10, 30, 3}, {11, 6, 3}, {14, 2, 3}}},
      {8, 3, 3, {{10, 30, 3}, {12, 8, 3}, {14, 3, 3}}},
  };
  for (const Case& c : cases) {
    INFO("format " << c.format);
    const std::size_t rl = base_size(c.format) + c.extra;
    auto comp = laz::PointCompressor::create(c.format, rl, 1234, "vlr");
    REQUIRE(comp.is_ok());
    auto params = laz::parse_vlr((*comp)->vlr_payload(), c.format, rl, "vlr");
    REQUIRE(params.is_ok());
    CHECK(params->compressor == c.compressor);
    CHECK(params->chunk_size == 1234);
    REQUIRE(params->items.size() == c.items.size());
    for (std::size_t i = 0; i < c.items.size(); ++i) {
      CHECK(params->items[i].type == c.items[i].type);
      CHECK(params->items[i].size == c.items[i].size);
      CHECK(params->items[i].version == c.items[i].version);
    }
  }
}

TEST_CASE("LAZ writer: formats and sizes it cannot write are refused", "[laz][writer][reject]") {
  for (const int format : {-1, 4, 5, 9, 10, 11}) {
    INFO("format " << format);
    const auto r = laz::PointCompressor::create(format, 64, 1000, "out.laz");
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find("out.laz") != std::string::npos);
  }
  CHECK_FALSE(laz::PointCompressor::create(3, 33, 1000, "short.laz").is_ok());   // shorter than format 3's
  CHECK_FALSE(laz::PointCompressor::create(6, 29, 1000, "short.laz").is_ok());
  CHECK_FALSE(laz::PointCompressor::create(0, 20, 0, "zero.laz").is_ok());       // no chunk size
  CHECK_FALSE(laz::PointCompressor::create(0, 20, 0x7FFFFFFF, "huge.laz").is_ok());  // u32 byte counts
  CHECK(laz::PointCompressor::create(0, 20, laz::kVariableChunks, "var.laz").is_ok());
}

// A wave packet descriptor's bytes (LAS 1.4 R15 Table 14).
constexpr std::size_t kWavePacketBytes = 29;

TEST_CASE("LAZ formats 9 and 10: the wave packet layer is skipped, every other field decoded", "[laz][wave]") {
  // A LASzip layered chunk of format 6 or 8 becomes one of format 9 or 10 by
  // adding the wave packet item: 29 raw bytes after the first record's, a
  // layer size after the other items' sizes and that layer after theirs.
  for (const auto& [base, wave_format] : {std::pair{6, 9}, std::pair{8, 10}}) {
    for (const std::uint32_t wave_bytes : {0u, 37u}) {
      DYNAMIC_SECTION("format " << wave_format << ", a wave layer of " << wave_bytes << " bytes") {
        const std::size_t rl = base_size(base);
        const std::size_t rl_wave = rl + kWavePacketBytes;
        const std::size_t layers = base == 8 ? 9 + 2 : 9;
        const auto records = random_records(base, rl, 2500, 77 + static_cast<std::uint64_t>(wave_bytes));
        auto comp = laz::PointCompressor::create(base, rl, 1000, "test");
        REQUIRE(comp.is_ok());
        std::vector<std::uint8_t> file(8, 0);
        (*comp)->add(records.data(), records.size() / rl, file);
        const auto table = (*comp)->finish(file);
        const std::uint64_t table_at = file.size();
        file.insert(file.end(), table.begin(), table.end());
        auto params = laz::parse_vlr((*comp)->vlr_payload(), base, rl, "test");
        REQUIRE(params.is_ok());
        auto chunks = laz::parse_chunk_table(std::span(file).subspan(table_at), *params, 8, table_at, 2500, "test");
        REQUIRE(chunks.is_ok());
        REQUIRE(chunks->size() == 3);

        // The VLR with one more item: WAVEPACKET14, 29 bytes, version 3.
        std::vector<std::uint8_t> vlr = (*comp)->vlr_payload();
        const auto items = load_le<std::uint16_t>(vlr.data() + 32);
        vlr[32] = static_cast<std::uint8_t>(items + 1);
        for (const std::uint8_t b : {13, 0, 29, 0, 3, 0}) vlr.push_back(b);
        auto wave_params = laz::parse_vlr(vlr, wave_format, rl_wave, "test");
        INFO(wave_params.status().to_string());
        REQUIRE(wave_params.is_ok());
        auto dec = laz::ChunkDecoder::create(*wave_params, "test");
        REQUIRE(dec.is_ok());
        std::vector<std::uint8_t> out(2500 * rl_wave);
        std::size_t at = 0;
        for (std::size_t i = 0; i < chunks->size(); ++i) {
          const laz::Chunk& c = (*chunks)[i];
          const std::span<const std::uint8_t> old = std::span(file).subspan(c.offset, c.bytes);
          std::vector<std::uint8_t> chunk(old.begin(), old.begin() + static_cast<std::ptrdiff_t>(rl));
          for (std::size_t k = 0; k < kWavePacketBytes; ++k) chunk.push_back(static_cast<std::uint8_t>(0xA0 + k));
          const std::size_t sizes_end = rl + 4 + 4 * layers;  // the count, then the layer sizes
          chunk.insert(chunk.end(), old.begin() + static_cast<std::ptrdiff_t>(rl),
                       old.begin() + static_cast<std::ptrdiff_t>(sizes_end));
          for (int s = 0; s < 4; ++s) chunk.push_back(static_cast<std::uint8_t>(wave_bytes >> (8 * s)));
          chunk.insert(chunk.end(), old.begin() + static_cast<std::ptrdiff_t>(sizes_end), old.end());
          for (std::uint32_t k = 0; k < wave_bytes; ++k) chunk.push_back(static_cast<std::uint8_t>(k * 13));
          const Status b = (*dec)->begin(chunk, c.points, i);
          INFO(b.to_string());
          REQUIRE(b.is_ok());
          const Status d = (*dec)->decode(static_cast<std::size_t>(c.points), out.data() + at);
          INFO(d.to_string());
          REQUIRE(d.is_ok());
          at += c.points * rl_wave;
        }
        // Every record's other fields as they were; the wave packets are not
        // decoded (zeros; a chunk's first record keeps its raw bytes).
        for (std::size_t p = 0; p < 2500; ++p) {
          CAPTURE(p);
          REQUIRE(std::memcmp(out.data() + p * rl_wave, records.data() + p * rl, rl) == 0);
          const bool first = p % 1000 == 0;
          REQUIRE(out[p * rl_wave + rl] == (first ? 0xA0 : 0));
        }
        // A wave layer longer than the chunk holds is corrupt.
        std::vector<std::uint8_t> cut(file.begin() + static_cast<std::ptrdiff_t>((*chunks)[0].offset),
                                      file.begin() + static_cast<std::ptrdiff_t>((*chunks)[0].offset + rl));
        cut.resize(cut.size() + kWavePacketBytes + 4 + 4 * layers, 0);
        cut[rl + kWavePacketBytes] = 0xE8;  // 1000 points
        cut[rl + kWavePacketBytes + 1] = 0x03;
        for (int s = 0; s < 4; ++s) cut.push_back(0xFF);
        CHECK_FALSE((*dec)->begin(cut, 1000, 0).is_ok());
      }
    }
  }
}

}  // namespace relief
