// Where an archive's bytes go (relief/query.h archive_sections): every
// chunk's section table, summed by section; and the codec's check of a chunk
// row against its blob (chunk_row_check).
#include <array>
#include <cstdio>
#include <span>
#include <string>

#include "query/json_text.h"
#include "relief/codec.h"
#include "relief/query.h"

namespace relief {

using json::json_string;

namespace {

// Section ids of format-spec/chunk.md §3.
constexpr int kMaxSectionId = 22;

std::string chunk_name(const ChunkRef& ref) {
  return "chunk (" + std::to_string(ref.key.ix) + "," + std::to_string(ref.key.iy) + "," + std::to_string(ref.key.iz) +
         ") seq " + std::to_string(ref.seq) + " (id " + std::to_string(ref.id) + ")";
}

}  // namespace

ChunkRowCheck chunk_row_check() {
  return [](const ChunkRef& row, std::span<const std::uint8_t> blob) {
    return chunk_counts_problem(row.input_points, row.decoded_points, blob);
  };
}

Result<ArchiveSections> archive_sections(const Archive& archive,
                                         const std::function<void(std::uint64_t points)>& progress) {
  RELIEF_ASSIGN_OR_RETURN(const ArchiveInfo info, archive.info());
  RELIEF_ASSIGN_OR_RETURN(const std::vector<ChunkRef> refs, archive.all_chunks());
  ArchiveSections out;
  out.file_bytes = info.file_bytes;
  out.pyramid_bytes = info.pyramid_bytes;
  for (const ScanPyramid& p : info.pyramid) {
    for (const PyramidLevel& l : p.levels) out.pyramid_chunks += l.chunks;
  }
  std::array<SectionTotal, kMaxSectionId + 1> totals{};
  for (const ChunkRef& ref : refs) {
    // The header and section table alone: a few hundred bytes of each blob.
    RELIEF_ASSIGN_OR_RETURN(const std::vector<std::uint8_t> head, archive.read_chunk_head(ref.id, kChunkHeadBytes));
    Result<ChunkInfo> chunk = inspect_chunk_head(head, ref.blob_size);
    if (!chunk) {
      return Status(chunk.status().code(),
                    archive.path() + ": " + chunk_name(ref) + ": " + chunk.status().message());
    }
    ++out.chunks;
    out.input_points += ref.input_points;
    out.blob_bytes += ref.blob_size;
    std::uint64_t coded = 0;
    for (const ChunkSectionInfo& s : chunk->sections) {
      // inspect_chunk accepts only the ids of the chunk's version.
      if (s.id > kMaxSectionId) continue;
      SectionTotal& t = totals[s.id];
      t.bytes += s.coded_size;
      ++t.chunks;
      coded += s.coded_size;
    }
    out.framing_bytes += ref.blob_size - coded;
    if (progress) progress(ref.input_points);
  }
  for (int id = 1; id <= kMaxSectionId; ++id) {
    SectionTotal& t = totals[static_cast<std::size_t>(id)];
    if (t.chunks == 0) continue;
    t.id = id;
    t.name = chunk_section_label(id);
    t.maps = chunk_section_is_map(id);
    out.sections.push_back(t);
  }
  return out;
}

std::string archive_sections_json(const ArchiveSections& s) {
  const auto u = [](std::uint64_t v) { return std::to_string(v); };
  std::string out = "{\"chunks\": " + u(s.chunks) + ", \"input_points\": " + u(s.input_points) +
                    ", \"file_bytes\": " + u(s.file_bytes) + ", \"blob_bytes\": " + u(s.blob_bytes) +
                    ", \"framing_bytes\": " + u(s.framing_bytes) + ", \"pyramid_chunks\": " + u(s.pyramid_chunks) +
                    ", \"pyramid_bytes\": " + u(s.pyramid_bytes) + ", \"container_bytes\": " + u(s.container_bytes()) +
                    ", \"sections\": [";
  for (std::size_t k = 0; k < s.sections.size(); ++k) {
    const SectionTotal& t = s.sections[k];
    out += std::string(k == 0 ? "" : ", ") + "{\"id\": " + std::to_string(t.id) + ", \"name\": " + json_string(t.name) +
           ", \"maps\": " + (t.maps ? "true" : "false") + ", \"bytes\": " + u(t.bytes) + ", \"chunks\": " + u(t.chunks) +
           "}";
  }
  return out + "]}";
}

}  // namespace relief
