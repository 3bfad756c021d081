// Every chunk of an archive, decoded and concatenated, for ingest tests: each
// blob must decode to the count its row declares, inside its index bounds.
#pragma once

#include <catch2/catch.hpp>

#include <cstdint>
#include <set>
#include <string>

#include "relief/archive.h"
#include "relief/codec.h"
#include "relief/types.h"

namespace relief::test {

inline PointCloud decode_archive(const std::string& path, std::set<std::int64_t>* scans = nullptr) {
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto refs = (*archive)->all_chunks();
  REQUIRE(refs.is_ok());
  PointCloud all;
  for (const ChunkRef& ref : *refs) {
    auto row = (*archive)->read_chunk(ref.id);
    REQUIRE(row.is_ok());
    auto pts = decode_chunk(row->blob);
    REQUIRE(pts.is_ok());
    CHECK(pts->size() == ref.decoded_points);
    for (const Vec3d& p : pts->positions) {
      // The index bounds hold every decoded point.
      CHECK((p.x >= ref.bounds.min.x && p.x <= ref.bounds.max.x && p.y >= ref.bounds.min.y &&
             p.y <= ref.bounds.max.y && p.z >= ref.bounds.min.z && p.z <= ref.bounds.max.z));
    }
    all.append_points(*pts);
    if (scans) scans->insert(ref.scan_id);
  }
  return all;
}

}  // namespace relief::test
