// Must-reject and memory-safety tests: truncated, corrupted and hostile blobs
// return an error (or, with the checksum bypassed, a bounded result), never crash.
#include <catch2/catch.hpp>

#include <algorithm>
#include <string>
#include <vector>

#include "codec/atlas.h"
#include "codec/coders.h"
#include "core/byte_io.h"
#include "relief/codec.h"
#include "support/synthetic.h"

using namespace relief;

namespace {

std::vector<std::uint8_t> small_blob(ImageCodec codec) {
  test::SceneOptions o;
  o.seed = 99;
  o.points = 3000;
  o.colors = true;
  o.intensity = true;
  const PointCloud in = test::make_sphere(o, 1.0);
  EncodeParams p;
  p.cell_size = 0.5;
  p.image_codec = codec;
  auto blob = encode_chunk(in, p);
  REQUIRE(blob.is_ok());
  return std::move(blob).value();
}

// Header field offsets (format-spec/chunk.md).
constexpr std::size_t kVersionOffset = 4;
constexpr std::size_t kDecodedPointsOffset = 20;
constexpr std::size_t kPatchCountOffset = 24;

void put_u32(std::vector<std::uint8_t>& b, std::size_t at, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) b[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}

// A hand-made version-1 blob (format-spec/chunk.md): header fields as given,
// a section table, zero payload bytes of the declared coded sizes and a valid
// CRC, so the checksum never hides what the bounds must catch.
struct HostileHeader {
  std::uint8_t map_resolution = 16;
  std::uint8_t tree_depth = 11;
  std::uint8_t section_count = 4;
  std::uint32_t points = 0;  // input and decoded
  std::uint32_t patch_count = 0;
  std::uint16_t tiles_x = 0;
  std::uint16_t tiles_y = 0;
};
struct HostileSection {
  std::uint8_t id;
  std::uint8_t codec;
  std::uint32_t raw_size;
  std::uint32_t coded_size;
};

std::vector<std::uint8_t> hostile_blob(const HostileHeader& h, const std::vector<HostileSection>& sections) {
  ByteWriter w;
  w.bytes("RLFC", 4);
  w.u16(1);   // format version
  w.u16(88);  // header size
  w.u8(0);    // flags
  w.u8(0);    // voxel grid
  w.u8(1);    // JPEG
  w.u8(h.map_resolution);
  w.u8(h.tree_depth);
  w.u8(8);  // height bits
  w.u8(h.section_count);
  w.u8(0);
  w.u32(h.points);
  w.u32(h.points);
  w.u32(h.patch_count);
  w.u16(h.tiles_x);
  w.u16(h.tiles_y);
  for (double v : {0.0, 0.0, 0.0, 1.0, 0.0, 1.0}) w.f64(v);  // grid origin, edge, height range
  w.f32(0);
  w.f32(0);
  std::uint64_t payload = 0;
  for (const HostileSection& s : sections) {
    w.u8(s.id);
    w.u8(s.codec);
    w.u16(0);
    w.u32(s.raw_size);
    w.u32(s.coded_size);
    payload += s.coded_size;
  }
  w.buffer().resize(w.buffer().size() + payload, 0);
  w.u32(codec::crc32(w.buffer()));
  return w.take();
}

// Section codec ids (format-spec/chunk.md): 0 stored, 1 JPEG, 3 LZMA2, 4 JBIG.
constexpr std::uint8_t kStored = 0, kJpegId = 1, kLzma2 = 3, kJbig = 4;

void require_rejected_by(std::span<const std::uint8_t> blob, const std::string& bound) {
  auto decoded = decode_chunk(blob);
  REQUIRE_FALSE(decoded.is_ok());
  CHECK(decoded.status().code() == StatusCode::kCorruptData);
  INFO(decoded.status().message());
  CHECK(decoded.status().message().find(bound) != std::string::npos);
  auto inspected = inspect_chunk(blob);
  REQUIRE_FALSE(inspected.is_ok());
  CHECK(inspected.status().code() == StatusCode::kCorruptData);
  CHECK(inspected.status().message().find(bound) != std::string::npos);
}

}  // namespace

TEST_CASE("every truncation of a valid blob is rejected", "[codec][reject]") {
  for (ImageCodec codec : {ImageCodec::kJpeg, ImageCodec::kJpeg2000}) {
    const std::vector<std::uint8_t> blob = small_blob(codec);
    for (std::size_t len = 0; len < blob.size(); ++len) {
      const std::span<const std::uint8_t> cut(blob.data(), len);
      for (bool verify : {true, false}) {
        DecodeOptions o;
        o.verify_checksum = verify;
        auto r = decode_chunk(cut, o);
        INFO("length " << len << " verify " << verify);
        REQUIRE_FALSE(r.is_ok());
        CHECK(!r.status().message().empty());
      }
    }
  }
}

TEST_CASE("flipped bytes are caught by the checksum", "[codec][reject]") {
  const std::vector<std::uint8_t> blob = small_blob(ImageCodec::kJpeg);
  test::Rng rng(1234);
  for (int i = 0; i < 300; ++i) {
    std::vector<std::uint8_t> bad = blob;
    const std::size_t at = rng.next() % bad.size();
    bad[at] ^= static_cast<std::uint8_t>(1u << (rng.next() % 8));
    auto r = decode_chunk(bad);
    INFO("flip at " << at);
    REQUIRE_FALSE(r.is_ok());
    CHECK((r.status().code() == StatusCode::kCorruptData || r.status().code() == StatusCode::kUnsupported));
  }
}

TEST_CASE("flipped bytes with the checksum bypassed never crash the inner decoders",
          "[codec][reject]") {
  for (ImageCodec codec : {ImageCodec::kJpeg, ImageCodec::kJpeg2000}) {
    const std::vector<std::uint8_t> blob = small_blob(codec);
    test::Rng rng(codec == ImageCodec::kJpeg ? 77 : 78);
    DecodeOptions o;
    o.verify_checksum = false;
    int decoded = 0;
    for (int i = 0; i < 400; ++i) {
      std::vector<std::uint8_t> bad = blob;
      const int flips = 1 + static_cast<int>(rng.next() % 4);
      for (int f = 0; f < flips; ++f) bad[rng.next() % bad.size()] ^= static_cast<std::uint8_t>(rng.next() | 1);
      auto r = decode_chunk(bad, o);
      if (r.is_ok()) {
        ++decoded;
        CHECK(r->size() <= o.max_points);
      }
    }
    // Flips inside image payloads can decode to other pixels; that is fine.
    CHECK(decoded < 400);
  }
}

TEST_CASE("hostile header fields are rejected before any large allocation", "[codec][reject]") {
  const std::vector<std::uint8_t> blob = small_blob(ImageCodec::kJpeg);
  DecodeOptions o;
  o.verify_checksum = false;
  SECTION("bad magic") {
    std::vector<std::uint8_t> bad = blob;
    bad[0] = 'X';
    auto r = decode_chunk(bad);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().message().find("magic") != std::string::npos);
  }
  SECTION("newer format version") {
    std::vector<std::uint8_t> bad = blob;
    bad[kVersionOffset] = static_cast<std::uint8_t>(kChunkFormatVersion + 1);
    auto r = decode_chunk(bad);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kUnsupported);
    CHECK(r.status().message().find("version " + std::to_string(kChunkFormatVersion + 1)) != std::string::npos);
  }
  SECTION("patch count that lies") {
    for (std::uint32_t v : {0u, 1u, 0xffffffffu, 0x10000000u}) {
      std::vector<std::uint8_t> bad = blob;
      put_u32(bad, kPatchCountOffset, v);
      CHECK_FALSE(decode_chunk(bad, o).is_ok());
    }
  }
  SECTION("decoded point count above the decoder limit") {
    std::vector<std::uint8_t> bad = blob;
    DecodeOptions tight = o;
    tight.max_points = 10;
    auto r = decode_chunk(bad, tight);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kLimitExceeded);
    put_u32(bad, kDecodedPointsOffset, 0xfffffff0u);
    CHECK_FALSE(decode_chunk(bad, o).is_ok());
  }
  SECTION("trailing bytes") {
    std::vector<std::uint8_t> bad = blob;
    bad.push_back(0);
    CHECK_FALSE(decode_chunk(bad).is_ok());
  }
  SECTION("empty input") {
    CHECK_FALSE(decode_chunk(std::span<const std::uint8_t>()).is_ok());
    CHECK_FALSE(inspect_chunk(std::span<const std::uint8_t>()).is_ok());
  }
}

// Issue 10: a 92-byte blob claiming 2^32 - 1 patches at depth >= 11 passed the
// 8^depth check and made the atlas layout visit every claimed patch (2.3 CPU
// seconds) before anything compared the count with the bytes present.
TEST_CASE("a header claiming 2^32-1 patches is rejected by the atlas bound", "[codec][reject]") {
  HostileHeader h;
  h.points = 0xffffffffu;
  h.patch_count = 0xffffffffu;
  for (std::uint8_t depth : {11, 21}) {
    h.tree_depth = depth;
    h.tiles_x = h.tiles_y = 0;  // the true layout (65536 tiles wide) does not fit a u16
    const std::vector<std::uint8_t> blob = hostile_blob(h, {});
    REQUIRE(blob.size() == 92);
    require_rejected_by(blob, "patches do not fit an atlas of 0x0 tiles");
    // The largest atlas a header may declare still holds fewer tiles.
    h.tiles_x = h.tiles_y = 65500 / 16;
    require_rejected_by(hostile_blob(h, {}), "patches do not fit an atlas of 4093x4093 tiles");
  }
}

TEST_CASE("counts beyond what the sections can hold are rejected before decoding", "[codec][reject]") {
  // 9 patches: a 4x3-tile atlas, depth 2 (8^1 cells are too few).
  HostileHeader h;
  h.tree_depth = 2;
  h.points = 9;
  h.patch_count = 9;
  h.tiles_x = 4;
  h.tiles_y = 3;
  const std::uint32_t pixels = 4 * 3 * 16 * 16;
  SECTION("more patches than the tree bytes have leaves") {
    const auto blob = hostile_blob(h, {{1, kStored, 1, 1}, {2, kStored, 63, 63}, {3, kJbig, pixels, 1}, {4, kJpegId, pixels, 1}});
    require_rejected_by(blob, "tree section of 1 bytes holds at most 8 leaves, header declares 9 patches");
  }
  SECTION("an LZMA2 section declaring more bytes than its stream can hold") {
    const auto blob = hostile_blob(h, {{1, kLzma2, 19, 5}, {2, kStored, 63, 63}, {3, kJbig, pixels, 1}, {4, kJpegId, pixels, 1}});
    require_rejected_by(blob, "tree section of 5 LZMA2 bytes cannot hold 19 bytes");
  }
  SECTION("more decoded points than occupancy pixels") {
    HostileHeader one;
    one.tree_depth = 0;
    one.map_resolution = 8;
    one.points = 65;
    one.patch_count = 1;
    one.tiles_x = one.tiles_y = 1;
    require_rejected_by(hostile_blob(one, {}), "65 decoded points do not fit an occupancy map of 64 pixels");
  }
}

TEST_CASE("the closed-form atlas layout matches placing every tile", "[codec][reject]") {
  std::uint32_t side = 1, max_y = 0;
  for (std::uint32_t n = 1; n <= 70000; ++n) {
    while (static_cast<std::uint64_t>(side) * side < n) side <<= 1;
    std::uint32_t tx = 0, ty = 0;
    codec::tile_position(n - 1, tx, ty);
    max_y = std::max(max_y, ty);
    const codec::AtlasLayout layout = codec::atlas_layout(n);
    INFO("patches " << n);
    REQUIRE(layout.tiles_x == side);
    REQUIRE(layout.tiles_y == max_y + 1);
  }
  CHECK(codec::atlas_layout(0xffffffffu).tiles_x == 65536);
  CHECK(codec::atlas_layout(0xffffffffu).tiles_y == 65536);
}

TEST_CASE("an atlas above the decoder's pixel limit is refused before any image is decoded", "[codec][reject]") {
  for (ImageCodec codec : {ImageCodec::kJpeg, ImageCodec::kJpeg2000}) {
    const std::vector<std::uint8_t> blob = small_blob(codec);
    auto info = inspect_chunk(blob);
    REQUIRE(info.is_ok());
    const std::uint64_t pixels = static_cast<std::uint64_t>(info->atlas_width) * info->atlas_height;
    DecodeOptions o;
    o.max_atlas_pixels = pixels;
    CHECK(decode_chunk(blob, o).is_ok());
    o.max_atlas_pixels = pixels - 1;
    auto r = decode_chunk(blob, o);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kLimitExceeded);
    CHECK(r.status().message().find("atlas") != std::string::npos);
  }
}
