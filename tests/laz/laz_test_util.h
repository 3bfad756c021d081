// Helpers of the LAZ test files: read and write whole files, the few LAS
// header fields the tests need, the LASzip VLR, decoding a whole file with the
// lib/laz API alone, a LAS twin's records, and compressing records and
// decoding them back.
#pragma once

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "io/stream_support.h"
#include "relief/laz.h"

namespace relief::laztest {

inline std::vector<std::uint8_t> slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

inline void spit(const std::string& path, const std::vector<std::uint8_t>& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// The few LAS header fields these tests need.
struct Header {
  std::uint16_t header_size = 0;
  std::uint32_t point_offset = 0;
  std::uint32_t vlr_count = 0;
  int format = 0;
  std::uint16_t record_length = 0;
  std::uint64_t point_count = 0;
};

inline Header header_of(const std::vector<std::uint8_t>& f) {
  REQUIRE(f.size() >= 227);
  Header h;
  h.header_size = load_le<std::uint16_t>(f.data() + 94);
  h.point_offset = load_le<std::uint32_t>(f.data() + 96);
  h.vlr_count = load_le<std::uint32_t>(f.data() + 100);
  h.format = f[104] & 0x3F;
  h.record_length = load_le<std::uint16_t>(f.data() + 105);
  h.point_count = load_le<std::uint32_t>(f.data() + 107);
  if (f[25] >= 4 && f.size() >= 255) {
    const auto c64 = load_le<std::uint64_t>(f.data() + 247);
    if (c64 != 0) h.point_count = c64;
  }
  return h;
}

// Offset of the LASzip VLR's payload and its length (0 when absent).
inline std::pair<std::size_t, std::size_t> laszip_vlr(const std::vector<std::uint8_t>& f, const Header& h) {
  std::size_t p = h.header_size;
  for (std::uint32_t i = 0; i < h.vlr_count && p + 54 <= f.size(); ++i) {
    const std::string user(reinterpret_cast<const char*>(f.data() + p + 2),
                           ::strnlen(reinterpret_cast<const char*>(f.data() + p + 2), 16));
    const auto id = load_le<std::uint16_t>(f.data() + p + 18);
    const auto len = load_le<std::uint16_t>(f.data() + p + 20);
    if (user == laz::kVlrUserId && id == laz::kVlrRecordId) return {p + 54, len};
    p += 54 + len;
  }
  return {0, 0};
}

// Decompresses every point record of an in-memory LAZ file with the
// lib/laz API alone.
inline Result<std::vector<std::uint8_t>> decode_laz(const std::vector<std::uint8_t>& f, const std::string& name) {
  const Header h = header_of(f);
  const auto [vlr_at, vlr_len] = laszip_vlr(f, h);
  if (vlr_len == 0) return format_error(name + ": no LASzip VLR");
  RELIEF_ASSIGN_OR_RETURN(laz::Params params,
                          laz::parse_vlr(std::span(f).subspan(vlr_at, vlr_len), h.format, h.record_length, name));
  if (f.size() < h.point_offset + 8) return format_error(name + ": short");
  const auto table = load_le<std::uint64_t>(f.data() + h.point_offset);
  if (table >= f.size()) return format_error(name + ": table outside");
  RELIEF_ASSIGN_OR_RETURN(std::vector<laz::Chunk> chunks,
                          laz::parse_chunk_table(std::span(f).subspan(table), params, h.point_offset + 8, table,
                                                 h.point_count, name));
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<laz::ChunkDecoder> dec, laz::ChunkDecoder::create(params, name));
  std::vector<std::uint8_t> out(h.point_count * h.record_length);
  std::size_t at = 0;
  for (std::size_t i = 0; i < chunks.size(); ++i) {
    const laz::Chunk& c = chunks[i];
    RELIEF_RETURN_IF_ERROR(dec->begin(std::span(f).subspan(c.offset, c.bytes), c.points, i));
    // Odd batch sizes, so that batch edges fall everywhere in a chunk.
    std::uint64_t left = c.points;
    while (left > 0) {
      const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(left, 777));
      RELIEF_RETURN_IF_ERROR(dec->decode(n, out.data() + at));
      at += n * h.record_length;
      left -= n;
    }
  }
  return out;
}

// The twin's point records (the twin keeps the LAZ file's header and VLRs).
inline std::vector<std::uint8_t> twin_records(const std::vector<std::uint8_t>& las, const Header& laz_header) {
  const Header h = header_of(las);
  REQUIRE(h.record_length == laz_header.record_length);
  REQUIRE(h.point_count == laz_header.point_count);
  const std::size_t bytes = h.point_count * h.record_length;
  REQUIRE(las.size() >= h.point_offset + bytes);
  return {las.begin() + h.point_offset, las.begin() + static_cast<std::ptrdiff_t>(h.point_offset + bytes)};
}

// Compresses `records`, lays them out as a file would (8-byte table offset,
// chunks, table), and decodes them through the reading API. With
// kVariableChunks a chunk ends after each count in `variable` in turn. With
// `threads` > 1 the compressor writes fixed chunks side by side.
inline std::vector<std::uint8_t> round_trip(const std::vector<std::uint8_t>& records, int format, std::size_t rl,
                                     std::uint32_t chunk_size, const std::vector<std::size_t>& variable = {},
                                     bool positions_only = false, unsigned threads = 1) {
  auto comp = laz::PointCompressor::create(format, rl, chunk_size, "test", threads);
  INFO(comp.status().to_string());
  REQUIRE(comp.is_ok());
  const std::size_t count = records.size() / rl;
  std::vector<std::uint8_t> file(8, 0);
  std::size_t at = 0;
  if (chunk_size == laz::kVariableChunks) {
    for (std::size_t i = 0; at < count; ++i) {
      const std::size_t n = std::min(variable.at(i % variable.size()), count - at);
      (*comp)->add(records.data() + at * rl, n, file);
      (*comp)->flush_chunk(file);
      at += n;
    }
  } else {
    // Uneven batches, as a writer would feed them.
    for (std::size_t step = 1; at < count; step = step * 3 + 1) {
      const std::size_t n = std::min(step, count - at);
      (*comp)->add(records.data() + at * rl, n, file);
      at += n;
    }
  }
  const auto table = (*comp)->finish(file);
  const std::uint64_t table_at = file.size();
  file.insert(file.end(), table.begin(), table.end());
  auto params = laz::parse_vlr((*comp)->vlr_payload(), format, rl, "test");
  INFO(params.status().to_string());
  REQUIRE(params.is_ok());
  auto chunks = laz::parse_chunk_table(std::span(file).subspan(table_at), *params, 8, table_at, count, "test");
  INFO(chunks.status().to_string());
  REQUIRE(chunks.is_ok());
  if (chunk_size != laz::kVariableChunks) CHECK(chunks->size() == (count + chunk_size - 1) / chunk_size);
  params->positions_only = positions_only;
  auto dec = laz::ChunkDecoder::create(*params, "test");
  REQUIRE(dec.is_ok());
  std::vector<std::uint8_t> out(records.size());
  std::size_t o = 0;
  for (std::size_t i = 0; i < chunks->size(); ++i) {
    const laz::Chunk& c = (*chunks)[i];
    const Status b = (*dec)->begin(std::span(file).subspan(c.offset, c.bytes), c.points, i);
    INFO(b.to_string());
    REQUIRE(b.is_ok());
    const Status d = (*dec)->decode(static_cast<std::size_t>(c.points), out.data() + o);
    INFO(d.to_string());
    REQUIRE(d.is_ok());
    o += c.points * rl;
  }
  return out;
}

}  // namespace relief::laztest
