// Must-reject and memory-safety tests: truncated, corrupted and hostile blobs
// return an error (or, with the checksum bypassed, a bounded result), never crash.
#include <catch2/catch.hpp>

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
    bad[kVersionOffset] = 9;
    auto r = decode_chunk(bad);
    REQUIRE_FALSE(r.is_ok());
    CHECK(r.status().code() == StatusCode::kUnsupported);
    CHECK(r.status().message().find("version 9") != std::string::npos);
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
