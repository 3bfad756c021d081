// The blobs of an archive, summed and hashed in content order, so that two
// builds of the same inputs can be compared (bench/ingest --dense, --spool).
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>

#include "relief/archive.h"

namespace relief::bench {

struct Blobs {
  std::uint64_t chunks = 0, largest = 0, bytes = 0;
  std::uint64_t hash = 1469598103934665603ull;  // FNV-1a of the blobs in content order
};

// Zero chunks when the archive cannot be read.
inline Blobs blobs_of(const std::string& path) {
  Blobs b;
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  if (!archive) return b;
  auto refs = (*archive)->all_chunks();  // content order: the same blobs list alike
  if (!refs) return b;
  for (const ChunkRef& ref : *refs) {
    auto row = (*archive)->read_chunk(ref.id);
    if (!row) return Blobs{};
    ++b.chunks;
    b.largest = std::max<std::uint64_t>(b.largest, ref.input_points);
    b.bytes += row->blob.size();
    for (std::uint8_t c : row->blob) b.hash = (b.hash ^ c) * 1099511628211ull;
  }
  return b;
}

}  // namespace relief::bench
