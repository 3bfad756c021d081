// libFuzzer target: the LAZ writer against the LAZ reader. The input is
// records to compress: byte 0 picks the point format (0-3, 6-8), byte 1 the
// extra bytes (0-31), byte 2 the chunk size (1-255 points, or 0 for variable
// chunks ended every byte-3 points); the rest, cut to whole records, are the
// records. Compressing them and decoding the result must give them back
// exactly; anything else aborts.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <span>
#include <vector>

#include "relief/laz.h"

namespace {

constexpr int kFormats[] = {0, 1, 2, 3, 6, 7, 8};
constexpr std::size_t kBaseSizes[] = {20, 28, 26, 34, 30, 36, 38};
constexpr std::size_t kHeader = 4;

[[noreturn]] void fail(const char* what) {
  std::fprintf(stderr, "laz writer round trip: %s\n", what);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < kHeader) return 0;
  const std::size_t pick = data[0] % std::size(kFormats);
  const int format = kFormats[pick];
  const std::size_t rl = kBaseSizes[pick] + data[1] % 32;
  const std::uint32_t chunk_size = data[2] == 0 ? relief::laz::kVariableChunks : data[2];
  const std::size_t flush_every = 1 + data[3];
  const std::size_t count = (size - kHeader) / rl;
  const std::uint8_t* records = data + kHeader;

  auto comp = relief::laz::PointCompressor::create(format, rl, chunk_size, "fuzz.laz");
  if (!comp.is_ok()) fail("create refused a valid format");
  std::vector<std::uint8_t> file(8, 0);
  for (std::size_t at = 0; at < count;) {
    const std::size_t n = std::min(flush_every, count - at);
    (*comp)->add(records + at * rl, n, file);
    if (chunk_size == relief::laz::kVariableChunks) (*comp)->flush_chunk(file);
    at += n;
  }
  const auto table = (*comp)->finish(file);
  const std::uint64_t table_at = file.size();
  file.insert(file.end(), table.begin(), table.end());

  auto params = relief::laz::parse_vlr((*comp)->vlr_payload(), format, rl, "fuzz.laz");
  if (!params.is_ok()) fail("the reader refuses the writer's VLR");
  auto chunks = relief::laz::parse_chunk_table(std::span(file).subspan(table_at), *params, 8, table_at, count,
                                                "fuzz.laz");
  if (!chunks.is_ok()) fail("the reader refuses the writer's chunk table");
  auto dec = relief::laz::ChunkDecoder::create(*params, "fuzz.laz");
  if (!dec.is_ok()) fail("no decoder");
  std::vector<std::uint8_t> out(count * rl);
  std::size_t o = 0;
  for (std::size_t i = 0; i < chunks->size(); ++i) {
    const relief::laz::Chunk& c = (*chunks)[i];
    if (!(*dec)->begin(std::span(file).subspan(c.offset, c.bytes), c.points, i).is_ok()) fail("begin");
    if (!(*dec)->decode(static_cast<std::size_t>(c.points), out.data() + o).is_ok()) fail("decode");
    o += static_cast<std::size_t>(c.points) * rl;
  }
  if (o != out.size() || (count > 0 && std::memcmp(out.data(), records, out.size()) != 0)) {
    fail("records differ");
  }
  return 0;
}
