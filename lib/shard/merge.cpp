// relief merge: shard archives -> one archive, rows copied as they are.
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <map>
#include <memory>
#include <tuple>

#include "core/host.h"
#include "ingest/ingest_common.h"
#include "relief/shard.h"
#include "shard/shard_files.h"

namespace relief {

namespace {

// A transaction per this many rows or blob bytes (as the ingest pipeline).
constexpr std::size_t kBatchRows = 64;
constexpr std::size_t kBatchBytes = std::size_t{32} << 20;
// Shards open at once while their chunks are copied.
constexpr std::size_t kMaxOpenShards = 8;

std::string key_text(const ChunkKey& k) {
  // Appended piece by piece: GCC 12 warns falsely (-Wrestrict, bug 105329)
  // on a literal plus a temporary string.
  std::string text = "(";
  text += std::to_string(k.ix);
  text += ',';
  text += std::to_string(k.iy);
  text += ',';
  text += std::to_string(k.iz);
  text += ')';
  return text;
}

bool same_sources(const std::vector<ArchiveSource>& a, const std::vector<ArchiveSource>& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (a[i].path != b[i].path || a[i].format != b[i].format || a[i].point_count != b[i].point_count ||
        a[i].crs != b[i].crs || a[i].las != b[i].las) {
      return false;
    }
  }
  return true;
}

// What must be equal in every shard, and the name of the first difference.
std::string difference(const ArchiveInfo& a, const ArchiveInfo& b) {
  if (a.format_version != b.format_version) return "format version";
  if (!(a.grid.origin == b.grid.origin) || a.grid.chunk_edge != b.grid.chunk_edge) return "grid";
  if (a.codec_params != b.codec_params) return "codec parameters";
  if (a.creator != b.creator) return "creator";
  if (a.crs != b.crs) return "CRS";
  if (a.has_colors != b.has_colors || a.has_intensity != b.has_intensity) return "attributes";
  if (a.las_attributes != b.las_attributes || a.las_point_format != b.las_point_format ||
      a.las_version_minor != b.las_version_minor || a.las_colors_8bit != b.las_colors_8bit ||
      a.las_gps_time_type != b.las_gps_time_type) {
    return "LAS attributes (set, point format, version, colour levels or GPS time type)";
  }
  if (a.extra_bytes_size != b.extra_bytes_size || a.extra_bytes_vlr != b.extra_bytes_vlr) {
    return "extra bytes (size or Extra Bytes VLR)";
  }
  if (!same_sources(a.sources, b.sources)) return "sources (paths, formats, point counts or LAS headers and records)";
  return "";
}

}  // namespace

Result<MergeResult> merge_archives(const std::vector<std::string>& shards, const std::string& out,
                                   const MergeOptions& options) {
  using namespace ingest;
  if (shards.empty()) return invalid_argument("no shards to merge");
  struct stat st {};
  if (::stat(out.c_str(), &st) == 0) return io_error(out + ": already exists (merge never overwrites)");
  RELIEF_RETURN_IF_ERROR(check_output_directory(out));
  // Each shard is opened to be checked and listed, then closed: a Slurm
  // array may leave thousands, more than the process may hold open (three
  // files each, with a page cache). The copy below opens them again, a few
  // at a time (shards hold disjoint key ranges, so it reads them mostly in
  // turn).
  struct Shard {
    std::unique_ptr<Archive> archive;
    ArchiveInfo info;
    std::vector<ChunkRef> refs;
  };
  std::vector<Shard> opened;
  std::map<std::pair<dev_t, ino_t>, std::string> files;
  for (const std::string& path : shards) {
    struct stat shard_stat {};
    if (::stat(path.c_str(), &shard_stat) == 0) {
      const auto [it, inserted] = files.emplace(std::make_pair(shard_stat.st_dev, shard_stat.st_ino), path);
      if (!inserted) return invalid_argument(path + ": given twice (also as " + it->second + ")");
    }
    Shard s;
    RELIEF_ASSIGN_OR_RETURN(s.archive, Archive::open(path, Archive::Mode::kReadOnly));
    RELIEF_ASSIGN_OR_RETURN(s.info, s.archive->info());
    if (s.info.scans.size() != 1 || !s.info.scans[0].complete) {
      return invalid_argument(path + ": not a shard (one complete scan) but an archive of " +
                              std::to_string(s.info.scans.size()) + " scans" +
                              (s.info.scans.size() == 1 ? ", incomplete (its encode was killed?)" : ""));
    }
    if (!opened.empty()) {
      const std::string diff = difference(opened[0].info, s.info);
      if (!diff.empty()) {
        return invalid_argument(path + ": its " + diff + " differ from " + shards[0] +
                                "'s: not a shard of the same plan");
      }
    }
    RELIEF_ASSIGN_OR_RETURN(s.refs, s.archive->all_chunks());
    s.archive.reset();
    opened.push_back(std::move(s));
  }
  // Every chunk, in key order; a voxel must come from one shard only.
  struct Entry {
    ChunkKey key;
    std::size_t shard;
    std::int64_t id;
  };
  std::vector<Entry> entries;
  std::map<ChunkKey, std::size_t> owner;
  for (std::size_t i = 0; i < opened.size(); ++i) {
    for (const ChunkRef& ref : opened[i].refs) {
      const auto [it, inserted] = owner.emplace(ref.key, i);
      if (!inserted && it->second != i) {
        return invalid_argument(shards[i] + " and " + shards[it->second] + " both hold chunk " + key_text(ref.key) +
                                ": shards must hold disjoint key ranges (the same shard twice?)");
      }
      entries.push_back(Entry{ref.key, i, ref.id});
    }
  }
  std::sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    return std::tie(a.key, a.shard, a.id) < std::tie(b.key, b.shard, b.id);
  });
  // Together the shards hold every point of the plan's inputs (their
  // sources, the same in each, count them): a shard left out would make an
  // archive that looks complete.
  std::uint64_t held = 0, planned = 0;
  for (const Shard& s : opened) held += s.info.input_points;
  for (const ArchiveSource& src : opened[0].info.sources) planned += src.point_count;
  if (held != planned) {
    return invalid_argument("the " + std::to_string(opened.size()) + " shards hold " + std::to_string(held) +
                            " points, their plan's inputs " + std::to_string(planned) +
                            (held < planned ? ": a shard of the plan is missing (every key range's shard-encode "
                                              "output must be merged)"
                                            : ": not the shards of one build"));
  }

  const ArchiveInfo& first = opened[0].info;
  core::remove_stale_temps_beside(out);  // left by killed tasks of this host writing `out`
  const std::string tmp = core::temp_path_beside(out);
  remove_archive_files(tmp);
  // The page size a one-box compress of the same points takes.
  std::uint64_t merged_points = 0;
  for (const Shard& s : opened) merged_points += s.info.input_points;
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<Archive> archive,
                          Archive::create(tmp, first.grid, first.codec_params, first.creator,
                                          ingest_page_size(merged_points)));
  const auto failed = [&](Status s) -> Result<MergeResult> {
    archive.reset();
    remove_archive_files(tmp);
    return s;
  };
  // The shards' scan attributes, LAS metadata included (what the plan gave them).
  ScanAttributes attributes;
  attributes.has_colors = first.has_colors;
  attributes.has_intensity = first.has_intensity;
  attributes.crs = first.crs;
  attributes.las_attributes = first.las_attributes;
  attributes.las_point_format = first.las_point_format;
  attributes.las_version_minor = first.las_version_minor;
  attributes.extra_bytes_vlr = first.extra_bytes_vlr;
  attributes.extra_bytes_size = first.extra_bytes_size;
  attributes.las_colors_8bit = first.las_colors_8bit;
  attributes.las_gps_time_type = first.las_gps_time_type;
  auto scan_id = archive->begin_scan(first.sources, attributes);
  if (!scan_id) return failed(scan_id.status());
  MergeResult result;
  result.shards = opened.size();
  std::vector<ChunkRow> batch;
  std::size_t batch_bytes = 0;
  std::string row_params;
  const auto flush = [&]() -> Status {
    if (batch.empty()) return Status::ok();
    RELIEF_RETURN_IF_ERROR(archive->put_chunks(batch));
    batch.clear();
    batch_bytes = 0;
    return Status::ok();
  };
  // The shards open for reading, most recently used last.
  std::vector<std::size_t> open_shards;
  const auto shard_archive = [&](std::size_t k) -> Result<Archive*> {
    const auto at = std::find(open_shards.begin(), open_shards.end(), k);
    if (at != open_shards.end()) {
      open_shards.erase(at);
    } else {
      if (open_shards.size() >= kMaxOpenShards) {
        opened[open_shards.front()].archive.reset();
        open_shards.erase(open_shards.begin());
      }
      RELIEF_ASSIGN_OR_RETURN(opened[k].archive, Archive::open(shards[k], Archive::Mode::kReadOnly));
    }
    open_shards.push_back(k);
    return opened[k].archive.get();
  };
  for (std::size_t i = 0; i < entries.size();) {
    // One voxel's blobs (the parts of a split chunk), ordered by content:
    // the merged archive does not depend on the order the shard committed them.
    std::size_t j = i;
    std::vector<ChunkRow> voxel;
    for (; j < entries.size() && entries[j].key == entries[i].key; ++j) {
      auto shard = shard_archive(entries[j].shard);
      if (!shard) return failed(shard.status());
      auto row = (*shard)->read_chunk(entries[j].id);
      if (!row) return failed(row.status());
      if (row_params.empty()) row_params = row->codec_params;
      if (row->codec_params != row_params) {
        return failed(invalid_argument(shards[entries[j].shard] + ": chunk " + key_text(row->ref.key) +
                                       " was encoded with other parameters than " + shards[entries[0].shard] +
                                       "'s chunks (another plan?)"));
      }
      row->ref.scan_id = *scan_id;
      voxel.push_back(std::move(row).value());
    }
    std::sort(voxel.begin(), voxel.end(), [](const ChunkRow& a, const ChunkRow& b) { return a.blob < b.blob; });
    for (ChunkRow& row : voxel) {
      ++result.chunks;
      result.input_points += row.ref.input_points;
      result.blob_bytes += row.blob.size();
      batch_bytes += row.blob.size();
      batch.push_back(std::move(row));
    }
    if (batch.size() >= kBatchRows || batch_bytes >= kBatchBytes) {
      if (Status s = flush(); !s) return failed(s);
    }
    i = j;
  }
  if (Status s = flush(); !s) return failed(s);
  if (options.pyramid == PyramidMode::kOn ||
      (options.pyramid == PyramidMode::kAuto && result.input_points >= kPyramidAutoMinPoints)) {
    PyramidOptions p;
    p.threads = options.threads;
    p.memory_budget = options.memory_budget;
    auto pyramid = build_pyramid(*archive, *scan_id, p);
    if (!pyramid) return failed(pyramid.status());
    result.pyramid = *pyramid;
  }
  if (Status s = finish_scan(*archive, *scan_id, first.has_colors, first.has_intensity, first.crs); !s) {
    return failed(s);
  }
  if (Status s = archive->close(); !s) {  // one file before it moves
    return failed(Status(s.code(), s.message() + "; nothing of the merged archive is kept"));
  }
  archive.reset();
  // Into place only when complete, and never over a file that appeared
  // meanwhile: link(2) fails on an existing name where rename would replace it.
  if (::link(tmp.c_str(), out.c_str()) != 0) {
    const int err = errno;
    remove_archive_files(tmp);
    return io_error(out + ": cannot move the merged archive into place: " + std::strerror(err));
  }
  ::unlink(tmp.c_str());
  return result;
}

}  // namespace relief
