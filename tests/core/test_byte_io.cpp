#include <catch2/catch.hpp>
#include <cmath>

#include "core/byte_io.h"

using namespace relief;

TEST_CASE("ByteWriter writes little-endian fields and ByteReader reads them back", "[core]") {
  ByteWriter w;
  w.u8(0xab);
  w.u16(0x1234);
  w.u32(0xdeadbeef);
  w.u64(0x0102030405060708ULL);
  w.f32(1.5f);
  w.f64(-2.25);
  w.varint(300);
  const std::vector<std::uint8_t> b = w.take();
  REQUIRE(b.size() == 1 + 2 + 4 + 8 + 4 + 8 + 2);
  CHECK(b[1] == 0x34);
  CHECK(b[2] == 0x12);
  CHECK(b[3] == 0xef);
  ByteReader r(b, "test");
  std::uint8_t a = 0;
  std::uint16_t c = 0;
  std::uint32_t d = 0;
  std::uint64_t e = 0, v = 0;
  float f = 0;
  double g = 0;
  REQUIRE(r.u8(a, "a").is_ok());
  REQUIRE(r.u16(c, "c").is_ok());
  REQUIRE(r.u32(d, "d").is_ok());
  REQUIRE(r.u64(e, "e").is_ok());
  REQUIRE(r.f32(f, "f").is_ok());
  REQUIRE(r.f64(g, "g").is_ok());
  REQUIRE(r.varint(v, "v").is_ok());
  CHECK(a == 0xab);
  CHECK(c == 0x1234);
  CHECK(d == 0xdeadbeef);
  CHECK(e == 0x0102030405060708ULL);
  CHECK(f == 1.5f);
  CHECK(g == -2.25);
  CHECK(v == 300);
  CHECK(r.at_end());
}

TEST_CASE("ByteReader reports short reads with the field name", "[core]") {
  const std::vector<std::uint8_t> b = {1, 2, 3};
  ByteReader r(b, "tiny blob");
  std::uint32_t x = 0;
  const Status s = r.u32(x, "count");
  REQUIRE_FALSE(s.is_ok());
  CHECK(s.code() == StatusCode::kCorruptData);
  CHECK(s.message().find("tiny blob") == 0);
  CHECK(s.message().find("'count'") != std::string::npos);
  std::span<const std::uint8_t> view;
  CHECK_FALSE(r.span(view, 4, "payload").is_ok());
  CHECK(r.span(view, 3, "payload").is_ok());
  const std::vector<std::uint8_t> endless(12, 0xff);
  ByteReader r2(endless, "varint");
  std::uint64_t v = 0;
  CHECK_FALSE(r2.varint(v, "v").is_ok());
}
