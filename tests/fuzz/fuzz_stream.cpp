// libFuzzer target: the parsers `relief stream` feeds from a pipe, with the
// field list a user types. Layout: byte 0 picks the parser (even: text lines,
// odd: binary records), byte 1 is the spec's length L (0..255), the next L
// bytes are the spec (`--columns` / `--attributes`), the rest is the stream.
// Every line or record is parsed into one batch; a point the parser accepts
// must add exactly one entry to every attribute it declares, and one it
// refuses must leave the batch as it was (the parsers' documented contract).
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "relief/io.h"

namespace {

[[noreturn]] void fail(const char* what, std::size_t got, std::size_t want) {
  std::fprintf(stderr, "stream parser: %s: %zu, expected %zu\n", what, got, want);
  std::abort();
}

// The batch holds `points` points, each attribute the parser declares with
// one entry a point (extra bytes: their width each), the others none.
void check_batch(const relief::PointCloud& batch, std::size_t points, bool colors, bool intensity,
                 std::uint32_t las_bits, std::size_t extra_size) {
  if (batch.size() != points) fail("points in the batch", batch.size(), points);
  if (batch.colors.size() != (colors ? points : 0)) fail("colours", batch.colors.size(), colors ? points : 0);
  if (batch.intensities.size() != (intensity ? points : 0)) {
    fail("intensities", batch.intensities.size(), intensity ? points : 0);
  }
  if (batch.las.extra_bytes.size() != ((las_bits & relief::kLasExtraBytes) != 0 ? extra_size * points : 0)) {
    fail("extra bytes", batch.las.extra_bytes.size(), extra_size * points);
  }
  batch.las.for_each_vector([&](const auto& values, std::uint32_t bit) {
    // Colour low bytes come only with 16-bit colours, which no stream carries.
    const std::size_t want = (las_bits & bit) != 0 ? points : 0;
    if (values.size() != want) fail("a LAS attribute's values", values.size(), want);
  });
}

// Extra bytes come with a VLR of whole 192-byte descriptors, and only then.
void check_vlr(const std::string& vlr, std::size_t extra_size) {
  if ((extra_size == 0) != vlr.empty()) fail("extra bytes without a VLR (or a VLR without)", extra_size, 0);
  if (vlr.size() % 192 != 0) fail("Extra Bytes VLR size", vlr.size(), 192);
}

void run_text(const std::string& spec, std::string_view body) {
  auto parser = relief::TextLineParser::create(spec, "fuzz");
  if (!parser.is_ok()) return;
  const auto& p = **parser;
  check_vlr(p.extra_bytes_vlr(), p.extra_bytes_size());
  relief::PointCloud batch;
  std::size_t accepted = 0;
  std::uint64_t line_no = 0;
  while (!body.empty()) {
    const std::size_t nl = body.find('\n');
    const std::string_view line = body.substr(0, nl);
    body = nl == std::string_view::npos ? std::string_view{} : body.substr(nl + 1);
    ++line_no;
    if (p.parse(line, line_no, batch).is_ok()) ++accepted;
    check_batch(batch, accepted, p.colors(), p.intensity(), p.las_attributes(), p.extra_bytes_size());
  }
}

void run_binary(const std::string& spec, const std::uint8_t* data, std::size_t size) {
  auto parser = relief::BinaryRecordParser::create(spec, "fuzz");
  if (!parser.is_ok()) return;
  const auto& p = **parser;
  const std::size_t record = p.record_size();
  if (record < 24) fail("record size below the three f64 coordinates", record, 24);
  const std::size_t extra = p.extra_bytes_size();
  check_vlr(p.extra_bytes_vlr(), extra);
  relief::PointCloud batch;
  std::size_t accepted = 0;
  for (std::size_t at = 0; at + record <= size; at += record) {
    if (p.parse(data + at, at / record + 1, batch).is_ok()) ++accepted;
    check_batch(batch, accepted, p.colors(), p.intensity(), p.las_attributes(), extra);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const bool binary = (data[0] & 1) != 0;
  const std::size_t spec_size = std::min<std::size_t>(data[1], size - 2);
  const std::string spec(reinterpret_cast<const char*>(data + 2), spec_size);
  const std::uint8_t* body = data + 2 + spec_size;
  const std::size_t body_size = size - 2 - spec_size;
  if (binary) {
    run_binary(spec, body, body_size);
  } else {
    run_text(spec, std::string_view(reinterpret_cast<const char*>(body), body_size));
  }
  return 0;
}
