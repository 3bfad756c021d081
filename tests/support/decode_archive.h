// Every chunk of an archive, decoded and concatenated, for ingest tests: each
// blob must decode to the count its row declares, inside its index bounds.
// And every blob of an archive as stored, for determinism tests.
#pragma once

#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdint>
#include <map>
#include <set>
#include <string>
#include <string_view>
#include <tuple>
#include <vector>

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

// Every blob of an archive, keyed by voxel and content (seq may differ).
inline std::multimap<std::tuple<std::int64_t, std::int64_t, std::int64_t>, std::vector<std::uint8_t>> archive_blobs(
    const std::string& path) {
  auto archive = Archive::open(path, Archive::Mode::kReadOnly);
  REQUIRE(archive.is_ok());
  auto refs = (*archive)->all_chunks();
  REQUIRE(refs.is_ok());
  std::multimap<std::tuple<std::int64_t, std::int64_t, std::int64_t>, std::vector<std::uint8_t>> out;
  for (const ChunkRef& ref : *refs) {
    auto row = (*archive)->read_chunk(ref.id);
    REQUIRE(row.is_ok());
    out.emplace(std::make_tuple(ref.key.ix, ref.key.iy, ref.key.iz), row->blob);
  }
  // Sort the blobs of one voxel by content, so split parts compare as sets.
  std::multimap<std::tuple<std::int64_t, std::int64_t, std::int64_t>, std::vector<std::uint8_t>> sorted;
  for (auto it = out.begin(); it != out.end();) {
    auto range = out.equal_range(it->first);
    std::vector<std::vector<std::uint8_t>> v;
    for (auto j = range.first; j != range.second; ++j) v.push_back(j->second);
    // (Compared as string views: GCC 12 with LTO warns, wrongly, about the
    // memcmp of vector<uint8_t>'s operator< inside std::sort.)
    const auto bytes = [](const std::vector<std::uint8_t>& b) {
      return std::string_view(reinterpret_cast<const char*>(b.data()), b.size());
    };
    std::sort(v.begin(), v.end(), [&](const auto& a, const auto& b) { return bytes(a) < bytes(b); });
    for (auto& b : v) sorted.emplace(it->first, std::move(b));
    it = range.second;
  }
  return sorted;
}

}  // namespace relief::test
