// libFuzzer target: the chunk decoder with the CRC check bypassed, so mutated
// blobs reach the tree, patch, bilevel, image and LZMA decoders, plus
// inspect_chunk. max_points is small so a lying header cannot make a run use
// much memory; every decode that succeeds must respect it.
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>

#include "relief/codec.h"

namespace {

// Points a fuzz decode may return; blobs claiming more are rejected early.
constexpr std::uint64_t kMaxPoints = 1 << 16;

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> blob(data, size);
  (void)relief::inspect_chunk(blob);
  relief::DecodeOptions options;
  options.verify_checksum = false;
  options.max_points = kMaxPoints;
  // The last byte picks a level of detail too, so the LOD path is reached.
  for (std::uint32_t lod : {1u, size > 0 ? 1u + data[size - 1] % 8u : 2u}) {
    options.lod = lod;
    auto cloud = relief::decode_chunk(blob, options);
    if (!cloud.is_ok()) break;  // the first decode failing means the second would too
    if (cloud->size() > kMaxPoints || cloud->positions.size() != cloud->size()) {
      std::fprintf(stderr, "decode_chunk returned %zu points, limit %llu\n", cloud->size(),
                   static_cast<unsigned long long>(kMaxPoints));
      std::abort();
    }
  }
  return 0;
}
