// LAZ decompression: real files decode to their LAS twins record for record
// (tests/data/simple.laz always; the others from the shared data folder),
// the LAS reader reads LAZ, and damaged files are refused with an error.
#include <catch2/catch.hpp>

#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include "io/stream_support.h"
#include "laz/laz_test_util.h"
#include "relief/io.h"
#include "relief/laz.h"
#include "support/sanitized.h"
#include "support/shared_data.h"
#include "support/temp_dir.h"

// The file helpers of laz_test_util.h, in every namespace block below.
using namespace relief::laztest;

namespace relief {
namespace {

void check_twin(const std::string& laz_path, const std::string& las_path) {
  INFO(laz_path);
  const auto lazf = slurp(laz_path);
  const auto lasf = slurp(las_path);
  const Header h = header_of(lazf);
  const auto want = twin_records(lasf, h);
  auto got = decode_laz(lazf, laz_path);
  REQUIRE(got.is_ok());
  REQUIRE(got->size() == want.size());
  // Report the first differing record rather than a wall of bytes.
  for (std::size_t i = 0; i < want.size(); i += h.record_length) {
    if (std::memcmp(got->data() + i, want.data() + i, h.record_length) != 0) {
      FAIL("record " << i / h.record_length << " of " << h.point_count << " differs");
    }
  }
  SUCCEED();
}

Result<PointCloud> read_all(const std::string& path, const ReaderOptions& options = {});

const std::string kSimpleLaz = std::string(RELIEF_SOURCE_DIR) + "/tests/data/simple.laz";
const std::string kSimpleLas = std::string(RELIEF_SOURCE_DIR) + "/tests/data/simple.las";

}  // namespace

TEST_CASE("simple.laz (LAS 1.2, format 3) decodes to its LAS twin", "[laz]") {
  check_twin(kSimpleLaz, kSimpleLas);
}

TEST_CASE("Shared LAZ files decode to their LAS twins record for record", "[laz][shared-data]") {
  const std::pair<const char*, const char*> files[] = {
      {"laz/simple.laz", "laz/simple.las"},
      {"laz/laszip-generated_with2bytespadding.laz", "laz/laszip-generated_with2bytespadding.las"},
      {"laz/autzen_trim.laz", "laz/autzen_trim.las"},
      {"laz/1.2-with-color.copc.laz", "laz/1.2-with-color.copc.las"},
      {"laz/fr_aerial_rgb_698k.laz", "medium/orig/fr_aerial_rgb_698k.las"},
      {"laz/lone_star_tls_519k.laz", "medium/orig/lone_star_tls_519k.las"},
      // Formats 8 (RGBNIR14 and 3 extra bytes in BYTE14) and 7 (COPC:
      // variable chunks, one per octree node) through the layered compressor.
      {"laz/fr_aerial_rgb_698k.laz", "medium/orig/fr_aerial_rgb_698k.las"},
      {"laz/1.2-with-color.copc.laz", "laz/1.2-with-color.copc.las"},
  };
  for (const auto& [laz_rel, las_rel] : files) {
    DYNAMIC_SECTION(laz_rel) {
      const auto laz_path = test::shared_file(laz_rel);
      const auto las_path = test::shared_file(las_rel);
      if (!laz_path || !las_path) continue;
      check_twin(*laz_path, *las_path);
      // The LAS reader (chunks decoded in parallel) gives the twin's cloud.
      const auto from_laz = read_all(*laz_path);
      const auto from_las = read_all(*las_path);
      REQUIRE(from_laz.is_ok());
      REQUIRE(from_las.is_ok());
      CHECK(from_laz->positions == from_las->positions);
      CHECK(from_laz->colors == from_las->colors);
      CHECK(from_laz->intensities == from_las->intensities);
      // Positions only (layered files decode just the XY and Z layers): the same positions.
      ReaderOptions xyz;
      xyz.positions_only = true;
      const auto positions = read_all(*laz_path, xyz);
      REQUIRE(positions.is_ok());
      CHECK(positions->positions == from_las->positions);
    }
  }
}

}  // namespace relief

namespace relief {
namespace {

// Reads every point of `path` through the LAS reader.
Result<PointCloud> read_all(const std::string& path, const ReaderOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> reader, open_point_reader(path, options));
  PointCloud all, batch;
  for (;;) {
    RELIEF_ASSIGN_OR_RETURN(std::size_t n, reader->read(batch, 500));
    if (n == 0) break;
    all.positions.insert(all.positions.end(), batch.positions.begin(), batch.positions.end());
    all.colors.insert(all.colors.end(), batch.colors.begin(), batch.colors.end());
    all.intensities.insert(all.intensities.end(), batch.intensities.begin(), batch.intensities.end());
  }
  return all;
}

// Writes `bytes` as `file` in `tmp` and expects reading it to fail with a
// message naming it.
void expect_rejected(const test::TempDir& tmp, const std::vector<std::uint8_t>& bytes, const std::string& what) {
  INFO(what);
  const std::string path = tmp.file("bad.laz");
  spit(path, bytes);
  const auto r = read_all(path);
  REQUIRE_FALSE(r.is_ok());
  CHECK(r.status().message().find("bad.laz") != std::string::npos);
}

}  // namespace

TEST_CASE("The LAS reader reads LAZ: the same cloud as the LAS twin", "[laz][io]") {
  auto laz = read_all(kSimpleLaz);
  auto las = read_all(kSimpleLas);
  REQUIRE(laz.is_ok());
  REQUIRE(las.is_ok());
  REQUIRE(laz->positions.size() == 1065);
  CHECK(laz->positions == las->positions);
  CHECK(laz->colors == las->colors);
  CHECK(laz->intensities == las->intensities);
  auto reader = open_point_reader(kSimpleLaz);
  REQUIRE(reader.is_ok());
  CHECK((*reader)->info().format == "laz");
  CHECK((*reader)->info().point_count == 1065u);
  CHECK((*reader)->info().has_colors);
}

TEST_CASE("Truncated LAZ files are refused at every length", "[laz][reject]") {
  const auto f = slurp(kSimpleLaz);
  test::TempDir tmp;
  std::vector<std::size_t> lengths;
  for (std::size_t n = 0; n < 400; ++n) lengths.push_back(n);
  for (std::size_t n = 400; n + 32 < f.size(); n += 97) lengths.push_back(n);
  for (std::size_t n = f.size() - 32; n < f.size(); ++n) lengths.push_back(n);
  for (std::size_t n : lengths) {
    expect_rejected(tmp, std::vector<std::uint8_t>(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(n)),
                    "truncated to " + std::to_string(n) + " of " + std::to_string(f.size()) + " bytes");
  }
}

TEST_CASE("A LAZ file cut inside its points says it is truncated", "[laz][reject]") {
  // A cut download or copy: the chunk table offset points past the end.
  const auto f = slurp(kSimpleLaz);
  const Header h = header_of(f);
  test::TempDir tmp;
  for (const std::size_t n : {static_cast<std::size_t>(h.point_offset) + 8, static_cast<std::size_t>(h.point_offset) + 100,
                              f.size() / 2}) {
    INFO("cut to " << n << " bytes");
    const std::string path = tmp.file("cut.laz");
    spit(path, std::vector<std::uint8_t>(f.begin(), f.begin() + static_cast<std::ptrdiff_t>(n)));
    const auto r = read_all(path);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find("cut.laz: truncated: the LAZ chunk table is at byte ") != std::string::npos);
    CHECK(r.status().message().find("but the file ends at byte " + std::to_string(n)) != std::string::npos);
  }
}

TEST_CASE("Damaged LASzip VLRs are refused", "[laz][reject]") {
  const auto f = slurp(kSimpleLaz);
  const Header h = header_of(f);
  const auto [at, len] = laszip_vlr(f, h);
  REQUIRE(len == 34 + 6 * 3);
  test::TempDir tmp;
  // compressor, coder, item count and every item field decide how to decode.
  std::vector<std::size_t> fields = {0, 1, 2, 3, 32, 33};
  for (std::size_t i = 34; i < len; ++i) fields.push_back(i);
  for (std::size_t i : fields) {
    auto bad = f;
    bad[at + i] ^= 0xFF;
    expect_rejected(tmp, bad, "VLR byte " + std::to_string(i) + " flipped");
  }
  SECTION("without the VLR") {
    auto bad = f;
    bad[at - 54 + 2] ^= 0x20;  // the user id no longer reads "laszip encoded"
    expect_rejected(tmp, bad, "VLR user id changed");
  }
  SECTION("chunked data under compressor 1 (LASzip 1.x, unchunked) is refused as damaged") {
    // The 8-byte table offset, the chunks and the table read as one stream
    // do not decode to the header's points.
    auto bad = f;
    bad[at] = 1;
    bad[at + 1] = 0;
    expect_rejected(tmp, bad, "compressor 1 over chunked data");
  }
}

TEST_CASE("Damaged LAZ chunk tables are refused", "[laz][reject]") {
  const auto f = slurp(kSimpleLaz);
  const Header h = header_of(f);
  const auto table = static_cast<std::size_t>(load_le<std::uint64_t>(f.data() + h.point_offset));
  test::TempDir tmp;
  // The version and chunk count fields.
  for (std::size_t i = table; i < table + 8; ++i) {
    auto bad = f;
    bad[i] ^= 0xFF;
    expect_rejected(tmp, bad, "chunk table byte " + std::to_string(i - table) + " flipped");
  }
  // The compressed entries: a flip either changes a chunk's size (refused:
  // the chunk no longer fits or its stream ends early) or lands in the
  // coder's final padding and changes nothing.
  const auto good = read_all(kSimpleLaz);
  REQUIRE(good.is_ok());
  std::size_t refused = 0;
  for (std::size_t i = table + 8; i < f.size(); ++i) {
    INFO("chunk table byte " << i - table << " flipped");
    auto bad = f;
    bad[i] ^= 0xFF;
    spit(tmp.file("bad.laz"), bad);
    const auto r = read_all(tmp.file("bad.laz"));
    if (r.is_ok()) {
      CHECK(r->positions == good->positions);
    } else {
      ++refused;
    }
  }
  CHECK(refused >= (f.size() - table - 8) / 2);
  for (std::size_t i = 0; i < 8; ++i) {
    auto bad = f;
    bad[h.point_offset + i] ^= 0xFF;
    expect_rejected(tmp, bad, "chunk table offset byte " + std::to_string(i) + " flipped");
  }
}

TEST_CASE("LAZ headers that lie about the point count are refused", "[laz][reject]") {
  const auto f = slurp(kSimpleLaz);
  test::TempDir tmp;
  for (std::uint32_t count : {0u, 1u, 1064u, 1066u, 50001u, 0xFFFFFFFFu}) {
    auto bad = f;
    for (int i = 0; i < 4; ++i) bad[107 + i] = static_cast<std::uint8_t>(count >> (8 * i));
    expect_rejected(tmp, bad, "point count " + std::to_string(count));
  }
}

TEST_CASE("Damaged LAZ point data never crashes the decoder", "[laz][reject]") {
  // Flipped bits inside the compressed points cannot always be detected (the
  // stream stays decodable); what must hold is bounded, in-bounds decoding
  // (checked under ASan/UBSan) and an error or a full cloud.
  const auto f = slurp(kSimpleLaz);
  const Header h = header_of(f);
  const auto table = static_cast<std::size_t>(load_le<std::uint64_t>(f.data() + h.point_offset));
  test::TempDir tmp;
  std::size_t refused = 0, tries = 0;
  // (One byte in 52 under the sanitizers, one in 13 otherwise.)
  const std::size_t stride = test::kSanitized ? 52 : 13;
  for (std::size_t i = h.point_offset + 8; i < table; i += stride) {
    auto bad = f;
    bad[i] ^= static_cast<std::uint8_t>(0x5A + i);
    spit(tmp.file("bad.laz"), bad);
    const auto r = read_all(tmp.file("bad.laz"));
    ++tries;
    if (!r.is_ok()) {
      ++refused;
      CHECK(r.status().message().find("bad.laz") != std::string::npos);
      // A damaged input file (exit 13), not a damaged archive (14).
      CHECK(r.status().code() == StatusCode::kFormatError);
    } else {
      CHECK(r->positions.size() == h.point_count);
    }
  }
  CHECK(tries > (test::kSanitized ? 200u : 1000u));
  WARN(refused << " of " << tries << " damaged files refused");
}

}  // namespace relief

namespace relief {
namespace {

// Seeded records that exercise every field and coder path: small and huge
// coordinate steps, return counts 0-7, flag and class changes, point source
// and scan angle changes, colours with equal and different channels.
std::vector<std::uint8_t> synthetic_records(std::size_t n, std::size_t rl, std::uint32_t seed) {
  std::vector<std::uint8_t> out(n * rl);
  std::uint64_t s = seed;
  auto rnd = [&] {
    s = s * 6364136223846793005ull + 1442695040888963407ull;
    return static_cast<std::uint32_t>(s >> 33);
  };
  std::int32_t x = 0, y = 0, z = 0;
  std::uint16_t rgb[3] = {0, 0, 0};
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* p = out.data() + i * rl;
    const std::uint32_t mode = rnd() % 16;
    if (mode == 0) {
      x = static_cast<std::int32_t>(rnd() * 2u);  // a jump anywhere in 32 bits
      y = static_cast<std::int32_t>(rnd() * 2u);
    } else {
      x += static_cast<std::int32_t>(rnd() % 200) - 100;
      y += static_cast<std::int32_t>(rnd() % (mode * 30 + 1)) - static_cast<std::int32_t>(mode * 15);
    }
    z += static_cast<std::int32_t>(rnd() % 41) - 20;
    std::memcpy(p, &x, 4);
    std::memcpy(p + 4, &y, 4);
    std::memcpy(p + 8, &z, 4);
    const std::uint16_t intensity = static_cast<std::uint16_t>(mode < 8 ? rnd() % 70000 : 300 + rnd() % 3);
    std::memcpy(p + 12, &intensity, 2);
    p[14] = static_cast<std::uint8_t>(mode < 12 ? 0x09 : rnd() % 256);  // return bits, flags
    p[15] = static_cast<std::uint8_t>(mode < 10 ? 2 : rnd() % 256);
    p[16] = static_cast<std::uint8_t>(mode < 13 ? 0 : rnd() % 256);
    p[17] = static_cast<std::uint8_t>(mode < 14 ? 7 : rnd() % 256);
    const std::uint16_t source = static_cast<std::uint16_t>(mode < 15 ? 12 : rnd() % 65536);
    std::memcpy(p + 18, &source, 2);
    if (rl >= 26) {
      if (mode % 3 == 0) {
        for (auto& c : rgb) c = static_cast<std::uint16_t>(rnd() % 65536);
      } else if (mode % 3 == 1) {
        rgb[0] = rgb[1] = rgb[2] = static_cast<std::uint16_t>(rgb[0] + rnd() % 600 - 300);  // grey
      }
      std::memcpy(p + 20, rgb, 6);
    }
  }
  return out;
}

}  // namespace

TEST_CASE("PointCompressor output decodes to the same records", "[laz][writer]") {
  SECTION("format 2 from simple.las (real coordinates and colours)") {
    const auto las = slurp(kSimpleLas);
    const Header h = header_of(las);
    std::vector<std::uint8_t> records;
    for (std::uint64_t i = 0; i < h.point_count; ++i) {
      const std::uint8_t* p = las.data() + h.point_offset + i * h.record_length;
      records.insert(records.end(), p, p + 20);
      records.insert(records.end(), p + 28, p + 34);  // format 3's RGB after the GPS time
    }
    CHECK(round_trip(records, 2, 26, 50000) == records);
    CHECK(round_trip(records, 2, 26, 100) == records);
  }
  for (std::uint32_t seed : {1u, 2u, 3u}) {
    DYNAMIC_SECTION("synthetic, seed " << seed) {
      const auto f0 = synthetic_records(5000, 20, seed);
      CHECK(round_trip(f0, 0, 20, 1000) == f0);
      const auto f2 = synthetic_records(5000, 26, seed);
      CHECK(round_trip(f2, 2, 26, 777) == f2);
      const auto one = synthetic_records(3, 26, seed);
      CHECK(round_trip(one, 2, 26, 1) == one);  // chunks of one point
    }
  }
}

}  // namespace relief

namespace relief {
namespace {

// Compresses a LAZ file's twin records with the file's chunking (its chunk
// size, or with variable chunks its chunk table's point counts) and compares
// the chunks and the chunk table with the file's, byte for byte.
// With `threads` > 1 (fixed chunks) the compressor gathers chunks and
// compresses them side by side; the records then arrive in uneven pieces.
void check_same_bytes_as_laszip(const std::string& laz_path, const std::string& las_path, unsigned threads = 1) {
  INFO(laz_path << ", " << threads << " threads");
  const auto lazf = slurp(laz_path);
  const auto lasf = slurp(las_path);
  const Header h = header_of(lazf);
  const auto records = twin_records(lasf, h);
  const auto [vlr_at, vlr_len] = laszip_vlr(lazf, h);
  auto params = laz::parse_vlr(std::span(lazf).subspan(vlr_at, vlr_len), h.format, h.record_length, laz_path);
  REQUIRE(params.is_ok());
  const auto table_at = static_cast<std::size_t>(load_le<std::uint64_t>(lazf.data() + h.point_offset));
  auto want_chunk_list = laz::parse_chunk_table(std::span(lazf).subspan(table_at), *params, h.point_offset + 8,
                                                table_at, h.point_count, laz_path);
  REQUIRE(want_chunk_list.is_ok());
  auto comp = laz::PointCompressor::create(h.format, h.record_length, params->chunk_size, laz_path, threads);
  REQUIRE(comp.is_ok());
  CHECK((*comp)->vlr_payload().size() == vlr_len);
  if (h.format >= 6) {
    // The VLR too (for formats 0-3 it names LASzip 2.2, these files 3.4 or 2.2).
    const std::vector<std::uint8_t> want_vlr(lazf.begin() + static_cast<std::ptrdiff_t>(vlr_at),
                                             lazf.begin() + static_cast<std::ptrdiff_t>(vlr_at + vlr_len));
    CHECK((*comp)->vlr_payload() == want_vlr);
  }
  std::vector<std::uint8_t> chunks;
  if (params->chunk_size == laz::kVariableChunks) {
    std::size_t at = 0;
    for (const laz::Chunk& c : *want_chunk_list) {
      (*comp)->add(records.data() + at * h.record_length, static_cast<std::size_t>(c.points), chunks);
      (*comp)->flush_chunk(chunks);
      at += static_cast<std::size_t>(c.points);
    }
  } else if (threads == 1) {
    (*comp)->add(records.data(), records.size() / h.record_length, chunks);
  } else {
    const std::size_t n = records.size() / h.record_length;
    for (std::size_t at = 0, piece = 1; at < n; at += piece, piece = piece * 7 + 3) {
      piece = std::min(piece, n - at);
      (*comp)->add(records.data() + at * h.record_length, piece, chunks);
    }
  }
  const auto table = (*comp)->finish(chunks);
  const std::vector<std::uint8_t> want_chunks(lazf.begin() + h.point_offset + 8,
                                              lazf.begin() + static_cast<std::ptrdiff_t>(table_at));
  REQUIRE(chunks.size() == want_chunks.size());
  // Name the first differing chunk rather than printing megabytes.
  for (std::size_t i = 0, at = 0; i < want_chunk_list->size(); ++i) {
    const auto bytes = static_cast<std::size_t>((*want_chunk_list)[i].bytes);
    INFO("chunk " << i + 1 << " of " << want_chunk_list->size());
    REQUIRE(std::memcmp(chunks.data() + at, want_chunks.data() + at, bytes) == 0);
    at += bytes;
  }
  const std::vector<std::uint8_t> want_table(lazf.begin() + static_cast<std::ptrdiff_t>(table_at),
                                             lazf.begin() + static_cast<std::ptrdiff_t>(table_at + table.size()));
  CHECK(table == want_table);
}

}  // namespace

TEST_CASE("PointCompressor writes the bytes LASzip writes", "[laz][writer]") {
  check_same_bytes_as_laszip(kSimpleLaz, kSimpleLas);
  check_same_bytes_as_laszip(kSimpleLaz, kSimpleLas, 3);
}

TEST_CASE("PointCompressor writes the bytes LASzip writes (shared files)", "[laz][writer][shared-data]") {
  const std::pair<const char*, const char*> files[] = {
      {"laz/autzen_trim.laz", "laz/autzen_trim.las"},
      {"laz/lone_star_tls_519k.laz", "medium/orig/lone_star_tls_519k.las"},
      // Formats 8 (RGBNIR14 and 3 extra bytes in BYTE14) and 7 (COPC:
      // variable chunks, one per octree node) through the layered compressor.
      {"laz/fr_aerial_rgb_698k.laz", "medium/orig/fr_aerial_rgb_698k.las"},
      {"laz/1.2-with-color.copc.laz", "laz/1.2-with-color.copc.las"},
  };
  for (const auto& [laz_rel, las_rel] : files) {
    DYNAMIC_SECTION(laz_rel) {
      const auto laz_path = test::shared_file(laz_rel);
      const auto las_path = test::shared_file(las_rel);
      if (!laz_path || !las_path) continue;
      check_same_bytes_as_laszip(*laz_path, *las_path);
      check_same_bytes_as_laszip(*laz_path, *las_path, 3);
    }
  }
}

}  // namespace relief

namespace relief {

TEST_CASE("Damaged layered (v3) LAZ never crashes the decoder", "[laz][reject][shared-data]") {
  // The COPC file: 65 variable-size chunks of POINT14 + RGB14 layers. Flips
  // land in raw first points, layer sizes and layer streams.
  const auto path = test::shared_file("laz/1.2-with-color.copc.laz");
  if (!path) return;
  const auto f = slurp(*path);
  const Header h = header_of(f);
  const auto table = static_cast<std::size_t>(load_le<std::uint64_t>(f.data() + h.point_offset));
  test::TempDir tmp;
  std::size_t refused = 0, tries = 0;
  // (One byte in 116 under the sanitizers, one in 29 otherwise.)
  const std::size_t stride = test::kSanitized ? 116 : 29;
  for (std::size_t i = h.point_offset + 8; i < table; i += stride) {
    auto bad = f;
    bad[i] ^= static_cast<std::uint8_t>(0x3C + i);
    spit(tmp.file("bad.laz"), bad);
    const auto r = read_all(tmp.file("bad.laz"));
    ++tries;
    if (!r.is_ok()) {
      ++refused;
      CHECK(r.status().message().find("bad.laz") != std::string::npos);
    } else {
      CHECK(r->positions.size() == h.point_count);
    }
  }
  CHECK(tries > (test::kSanitized ? 200u : 1000u));
  WARN(refused << " of " << tries << " damaged files refused");
}

}  // namespace relief

namespace relief {
namespace {

// Every record of `f` through ChunkReader with the given threads and
// whole-chunk limit.
std::vector<std::uint8_t> read_with_chunk_reader(const std::vector<std::uint8_t>& f, unsigned threads,
                                                 std::size_t max_whole_chunk) {
  const Header h = header_of(f);
  const auto [vlr_at, vlr_len] = laszip_vlr(f, h);
  auto params = laz::parse_vlr(std::span(f).subspan(vlr_at, vlr_len), h.format, h.record_length, "t");
  REQUIRE(params.is_ok());
  const auto table = load_le<std::uint64_t>(f.data() + h.point_offset);
  auto chunks = laz::parse_chunk_table(std::span(f).subspan(table), *params, h.point_offset + 8, table,
                                       h.point_count, "t");
  REQUIRE(chunks.is_ok());
  auto reader = laz::ChunkReader::create(*params, *chunks, threads, "t", max_whole_chunk);
  REQUIRE(reader.is_ok());
  std::uint64_t fetched_to = 0;
  const laz::ChunkReader::Fetch fetch = [&](std::uint64_t offset, std::size_t bytes, std::vector<std::uint8_t>& out) {
    CHECK(offset >= fetched_to);  // chunks are fetched in file order
    fetched_to = offset + bytes;
    out.assign(f.begin() + static_cast<std::ptrdiff_t>(offset),
               f.begin() + static_cast<std::ptrdiff_t>(offset + bytes));
    return Status::ok();
  };
  std::vector<std::uint8_t> all;
  for (;;) {
    std::span<const std::uint8_t> records;
    const Status s = (*reader)->next(fetch, records);
    INFO(s.to_string());
    REQUIRE(s.is_ok());
    if (records.empty()) break;
    CHECK(records.size() % h.record_length == 0);
    all.insert(all.end(), records.begin(), records.end());
  }
  return all;
}

}  // namespace

TEST_CASE("ChunkReader: whole chunks in parallel and oversized chunks piecewise give the same records",
          "[laz]") {
  std::vector<std::pair<std::string, std::string>> files = {{kSimpleLaz, kSimpleLas}};
  for (const auto& [laz_rel, las_rel] : {std::pair{"laz/fr_aerial_rgb_698k.laz", "medium/orig/fr_aerial_rgb_698k.las"},
                                         std::pair{"laz/1.2-with-color.copc.laz", "laz/1.2-with-color.copc.las"}}) {
    const auto a = test::shared_file(laz_rel);
    const auto b = test::shared_file(las_rel);
    if (a && b) files.emplace_back(*a, *b);
  }
  for (const auto& [laz_path, las_path] : files) {
    INFO(laz_path);
    const auto f = slurp(laz_path);
    const auto want = twin_records(slurp(las_path), header_of(f));
    for (unsigned threads : {1u, 2u, 3u}) {
      // Whole chunks; none whole (every chunk piecewise); a limit between
      // (fr_aerial: 50,000-point chunks piecewise, its last of 47,721 whole).
      for (std::size_t limit : {laz::kMaxParallelChunkBytes, std::size_t{0}, std::size_t{48000} * 41}) {
        INFO("threads " << threads << ", whole-chunk limit " << limit);
        CHECK(read_with_chunk_reader(f, threads, limit) == want);
      }
    }
  }
}

}  // namespace relief
