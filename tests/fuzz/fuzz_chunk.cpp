// libFuzzer target: the chunk decoder with the CRC check bypassed, so mutated
// blobs reach the tree, patch, bilevel, image and LZMA decoders, plus
// inspect_chunk. max_points is small so a lying header cannot make a run use
// much memory; every decode that succeeds must respect it. A decode of some
// attributes alone (DecodeOptions::attributes) must equal the full decode's.
#include <algorithm>
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
  // The head alone (what relief info --sections reads) must accept whatever
  // the whole blob passes, and see the same sections.
  const auto whole = relief::inspect_chunk(blob);
  const auto head = relief::inspect_chunk_head(blob.first(std::min(size, relief::kChunkHeadBytes)), size);
  if (whole.is_ok() && (!head.is_ok() || head->sections.size() != whole->sections.size())) std::abort();
  relief::DecodeOptions options;
  options.verify_checksum = false;
  options.max_points = kMaxPoints;
  relief::PointCloud full;
  // The last byte picks a level of detail too, so the LOD path is reached.
  for (std::uint32_t lod : {1u, size > 0 ? 1u + data[size - 1] % 8u : 2u}) {
    options.lod = lod;
    auto cloud = relief::decode_chunk(blob, options);
    if (!cloud.is_ok()) return 0;  // the first decode failing means the second would too
    if (cloud->size() > kMaxPoints || cloud->positions.size() != cloud->size()) {
      std::fprintf(stderr, "decode_chunk returned %zu points, limit %llu\n", cloud->size(),
                   static_cast<unsigned long long>(kMaxPoints));
      std::abort();
    }
    if (lod == 1) full = std::move(cloud).value();
  }
  // The two bytes before it pick attributes to decode alone: what the
  // decoder skips must not change what it keeps.
  if (size < 3) return 0;
  const unsigned pick = data[size - 2] | (unsigned{data[size - 3]} << 8);
  options.lod = 1;
  options.attributes = {(pick & 1) != 0, (pick & 2) != 0, pick >> 2};
  auto part = relief::decode_chunk(blob, options);
  if (!part.is_ok()) return 0;
  relief::PointCloud want = full;
  relief::keep_attributes(want, options.attributes);
  bool same = part->positions == want.positions && part->colors == want.colors &&
              part->intensities == want.intensities && part->las.extra_bytes == want.las.extra_bytes;
  relief::LasAttributes::for_each_vector_pair(part->las, want.las,
                                              [&](const auto& a, const auto& b, std::uint32_t) { same = same && a == b; });
  if (!same) {
    std::fprintf(stderr, "decoding attributes '%s' alone differs from the full decode\n",
                 relief::attribute_set_list(options.attributes).c_str());
    std::abort();
  }
  return 0;
}
