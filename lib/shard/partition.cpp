// Stage 1 of a sharded build: one input file -> one partition file per key
// range (partition_file.h), then the input's manifest.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <type_traits>
#include <unordered_set>

#include "core/byte_io.h"
#include "core/host.h"
#include "ingest/ingest_common.h"
#include "ingest/las_columns.h"
#include "relief/codec.h"
#include "relief/io.h"
#include "relief/shard.h"
#include "shard/partition_file.h"
#include "shard/shard_files.h"

namespace relief {

namespace {

// Points per read from the input.
constexpr std::size_t kReadBatch = std::size_t{1} << 20;
// A range's staged records are written out at this size: at most
// kMaxShardRanges x this staged at once (128 MiB).
constexpr std::size_t kFlushBytes = std::size_t{256} << 10;
// Records read per block from a partition file.
constexpr std::uint64_t kReadBlockPoints = std::uint64_t{1} << 16;

Status write_all(int fd, const std::uint8_t* data, std::size_t n, const std::string& path) {
  while (n > 0) {
    const ssize_t w = ::write(fd, data, n);
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) return io_error(path + ": write failed: " + std::strerror(errno));
    data += w;
    n -= static_cast<std::size_t>(w);
  }
  return Status::ok();
}

Status read_all(int fd, std::uint8_t* data, std::size_t n, const std::string& path) {
  while (n > 0) {
    const ssize_t r = ::read(fd, data, n);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) return io_error(path + ": read failed: " + std::strerror(errno));
    if (r == 0) return corrupt_data(path + ": ends early");
    data += r;
    n -= static_cast<std::size_t>(r);
  }
  return Status::ok();
}

void header_bytes(ByteWriter& w, std::uint64_t plan_id, std::uint32_t input, std::uint32_t range,
                  const shard::PartitionLayout& layout, std::uint64_t count) {
  w.bytes(shard::kPartitionMagic, sizeof shard::kPartitionMagic);
  w.u32(kPartitionFormatVersion);
  w.u64(plan_id);
  w.u32(input);
  w.u32(range);
  w.u32(layout.flags());
  w.u32(layout.las);
  w.u32(layout.extra_size);
  w.u64(count);
}

// One LAS value in its partition-file width, little-endian.
template <typename T>
void put_value(ByteWriter& w, const T& v) {
  if constexpr (std::is_same_v<T, Rgb8>) {
    w.u8(v.r);
    w.u8(v.g);
    w.u8(v.b);
  } else if constexpr (std::is_same_v<T, double>) {
    w.f64(v);
  } else if constexpr (std::is_same_v<T, std::int32_t>) {
    w.u32(static_cast<std::uint32_t>(v));
  } else if constexpr (std::is_same_v<T, std::uint16_t>) {
    w.u16(v);
  } else {
    static_assert(std::is_same_v<T, std::uint8_t>);
    w.u8(v);
  }
}

std::uint64_t get_le(const std::uint8_t*& p, int n) {
  std::uint64_t v = 0;
  for (int b = 0; b < n; ++b) v |= static_cast<std::uint64_t>(p[b]) << (8 * b);
  p += n;
  return v;
}

template <typename T>
T get_value(const std::uint8_t*& p) {
  if constexpr (std::is_same_v<T, Rgb8>) {
    const Rgb8 c{p[0], p[1], p[2]};
    p += 3;
    return c;
  } else if constexpr (std::is_same_v<T, double>) {
    const std::uint64_t bits = get_le(p, 8);
    double v = 0;
    std::memcpy(&v, &bits, sizeof v);
    return v;
  } else if constexpr (std::is_same_v<T, std::int32_t>) {
    return static_cast<std::int32_t>(static_cast<std::uint32_t>(get_le(p, 4)));
  } else if constexpr (std::is_same_v<T, std::uint16_t>) {
    return static_cast<std::uint16_t>(get_le(p, 2));
  } else {
    static_assert(std::is_same_v<T, std::uint8_t>);
    return *p++;
  }
}

// The temporary files of one partition task; removed unless committed.
struct TempFiles {
  std::vector<int> fds;
  std::vector<std::string> tmp;
  ~TempFiles() {
    for (std::size_t i = 0; i < fds.size(); ++i) {
      if (fds[i] >= 0) {
        ::close(fds[i]);
        ::unlink(tmp[i].c_str());
      }
    }
  }
};

// Opens a partition file and checks its header; returns the fd (caller
// closes) and the point count, checked against the file size.
Result<std::pair<int, std::uint64_t>> open_partition(const std::string& path, std::uint64_t plan_id,
                                                     std::uint32_t input, std::uint32_t range,
                                                     const shard::PartitionLayout& layout) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) {
      return io_error(path + ": missing (stage 1 of input " + std::to_string(input) + " has not finished)");
    }
    return io_error(path + ": cannot open: " + std::strerror(errno));
  }
  const auto fail = [fd](Status s) -> Result<std::pair<int, std::uint64_t>> {
    ::close(fd);
    return s;
  };
  struct stat st {};
  if (::fstat(fd, &st) != 0) return fail(io_error(path + ": cannot stat: " + std::strerror(errno)));
  const auto size = static_cast<std::uint64_t>(st.st_size);
  // The magic and version first: they say how long the header is.
  constexpr std::size_t kLead = sizeof shard::kPartitionMagic + 4;
  if (size < shard::kPartitionHeaderBytesV1) return fail(corrupt_data(path + ": shorter than a partition header"));
  std::uint8_t header[shard::kPartitionHeaderBytes] = {};
  if (Status s = read_all(fd, header, kLead, path); !s) return fail(s);
  if (std::memcmp(header, shard::kPartitionMagic, sizeof shard::kPartitionMagic) != 0) {
    return fail(format_error(path + ": not a Relief partition file"));
  }
  const std::uint32_t version = static_cast<std::uint32_t>(header[8]) | (static_cast<std::uint32_t>(header[9]) << 8) |
                                (static_cast<std::uint32_t>(header[10]) << 16) |
                                (static_cast<std::uint32_t>(header[11]) << 24);
  if (version != 1 && version != static_cast<std::uint32_t>(kPartitionFormatVersion)) {
    return fail(unsupported(path + ": partition format version " + std::to_string(version) +
                            " (this build reads versions 1 and " + std::to_string(kPartitionFormatVersion) + ")"));
  }
  const std::size_t header_bytes = version == 1 ? shard::kPartitionHeaderBytesV1 : shard::kPartitionHeaderBytes;
  if (size < header_bytes) return fail(corrupt_data(path + ": shorter than a partition header"));
  if (Status s = read_all(fd, header + kLead, header_bytes - kLead, path); !s) return fail(s);
  ByteReader r(std::span<const std::uint8_t>(header + kLead, header_bytes - kLead), path);
  std::uint32_t file_input = 0, file_range = 0, flags = 0, las = 0, extra_size = 0;
  std::uint64_t file_plan = 0, count = 0;
  if (Status s = r.u64(file_plan, "plan id"); !s) return fail(s);
  if (Status s = r.u32(file_input, "input"); !s) return fail(s);
  if (Status s = r.u32(file_range, "range"); !s) return fail(s);
  if (Status s = r.u32(flags, "flags"); !s) return fail(s);
  if (version != 1) {
    if (Status s = r.u32(las, "LAS attributes"); !s) return fail(s);
    if (Status s = r.u32(extra_size, "extra bytes size"); !s) return fail(s);
  }
  if (Status s = r.u64(count, "point count"); !s) return fail(s);
  if (file_plan != plan_id) {
    return fail(invalid_argument(path + ": written for another plan (" + shard::hex64(file_plan) + ", not " +
                                 shard::hex64(plan_id) + "); clear the partition directory"));
  }
  if (file_input != input || file_range != range) {
    return fail(corrupt_data(path + ": holds input " + std::to_string(file_input) + ", range " +
                             std::to_string(file_range) + " under the name of input " + std::to_string(input) +
                             ", range " + std::to_string(range)));
  }
  if (flags != layout.flags()) return fail(corrupt_data(path + ": attribute flags differ from the plan's"));
  if (las != layout.las || extra_size != layout.extra_size) {
    if (version == 1) {
      return fail(invalid_argument(path + ": a version 1 partition file, which cannot hold the plan's LAS "
                                          "attributes; clear the partition directory"));
    }
    return fail(corrupt_data(path + ": LAS attributes (" + las_attribute_list(las) + "; " +
                             std::to_string(extra_size) + " extra bytes) differ from the plan's (" +
                             las_attribute_list(layout.las) + "; " + std::to_string(layout.extra_size) + ")"));
  }
  const std::uint64_t record = layout.record_bytes();
  const std::uint64_t body = size - header_bytes;
  if (body % record != 0 || body / record != count) {
    return fail(corrupt_data(path + ": " + std::to_string(size) + " bytes, but its header says " +
                             std::to_string(count) + " points (truncated or damaged)"));
  }
  return std::make_pair(fd, count);
}

}  // namespace

namespace shard {

PartitionLayout PartitionLayout::of(const ShardPlan& plan) {
  PartitionLayout l;
  const ScanAttributes& a = plan.attributes;
  l.colors = a.has_colors;
  l.intensity = a.has_intensity;
  l.las = a.las_attributes;
  l.extra_size = (a.las_attributes & kLasExtraBytes) != 0 ? a.extra_bytes_size : 0;
  return l;
}

std::uint32_t PartitionLayout::flags() const { return (colors ? kFlagRgb : 0) | (intensity ? kFlagIntensity : 0); }

std::size_t PartitionLayout::record_bytes() const {
  return 24 + (colors ? 3 : 0) + (intensity ? 4 : 0) + ingest::las_record_bytes(las, extra_size);
}

Result<std::uint64_t> partition_file_points(const std::string& path, std::uint64_t plan_id, std::uint32_t input,
                                            std::uint32_t range, const PartitionLayout& layout) {
  RELIEF_ASSIGN_OR_RETURN(const auto opened, open_partition(path, plan_id, input, range, layout));
  ::close(opened.first);
  return opened.second;
}

Result<std::uint64_t> read_partition_batches(const std::string& path, std::uint64_t plan_id, std::uint32_t input,
                                             std::uint32_t range, const PartitionLayout& layout,
                                             std::uint64_t batch_points,
                                             const std::function<Status(PointCloud&)>& take) {
  RELIEF_ASSIGN_OR_RETURN(const auto opened, open_partition(path, plan_id, input, range, layout));
  const int fd = opened.first;
  const std::uint64_t count = opened.second;
  const std::size_t record = layout.record_bytes();
  const bool extra = (layout.las & kLasExtraBytes) != 0;
  const std::uint64_t per_batch = std::max<std::uint64_t>(1, batch_points);
  PointCloud out;
  if (extra) out.las.extra_bytes_size = layout.extra_size;
  std::vector<std::uint8_t> block;
  std::uint64_t done = 0;
  const auto failed = [fd](Status s) -> Result<std::uint64_t> {
    ::close(fd);
    return s;
  };
  while (done < count) {
    // A batch: blocks of the file until it holds batch_points (or the rest).
    out.clear_points();
    const std::uint64_t batch_end = done + std::min(per_batch, count - done);
    while (done < batch_end) {
      const auto n = static_cast<std::size_t>(std::min(kReadBlockPoints, batch_end - done));
      block.resize(n * record);
      if (Status s = read_all(fd, block.data(), block.size(), path); !s) return failed(s);
      const std::uint8_t* p = block.data();
      for (std::size_t i = 0; i < n; ++i) {
        const double x = get_value<double>(p);
        const double y = get_value<double>(p);
        const double z = get_value<double>(p);
        out.positions.push_back(Vec3d{x, y, z});
        if (layout.colors) out.colors.push_back(get_value<Rgb8>(p));
        if (layout.intensity) {
          const auto bits = static_cast<std::uint32_t>(get_le(p, 4));
          float v = 0;
          std::memcpy(&v, &bits, sizeof v);
          out.intensities.push_back(v);
        }
        out.las.for_each_vector([&](auto& v, std::uint32_t bit) {
          if ((layout.las & bit) != 0) v.push_back(get_value<typename std::decay_t<decltype(v)>::value_type>(p));
        });
        if (extra) {
          out.las.extra_bytes.insert(out.las.extra_bytes.end(), p, p + layout.extra_size);
          p += layout.extra_size;
        }
      }
      done += n;
    }
    if (Status s = take(out); !s) return failed(s);
  }
  ::close(fd);
  return count;
}

Result<std::uint64_t> read_partition_file(const std::string& path, std::uint64_t plan_id, std::uint32_t input,
                                          std::uint32_t range, const PartitionLayout& layout, PointCloud& out) {
  if ((layout.las & kLasExtraBytes) != 0) out.las.extra_bytes_size = layout.extra_size;
  return read_partition_batches(path, plan_id, input, range, layout, kReadBlockPoints, [&](PointCloud& batch) {
    out.append_points(batch);
    return Status::ok();
  });
}

Result<Manifest> read_manifest(const std::string& path, std::uint64_t plan_id, std::uint32_t input) {
  constexpr std::uint64_t kMaxManifestBytes = std::uint64_t{16} << 20;
  auto text = read_text(path, kMaxManifestBytes);
  if (!text) {
    if (::access(path.c_str(), F_OK) != 0) {
      return io_error(path + ": missing (stage 1 of input " + std::to_string(input) + " has not finished)");
    }
    return text.status();
  }
  RELIEF_ASSIGN_OR_RETURN(const std::vector<TextLine> lines, split_lines(path, *text));
  Manifest m;
  bool ended = false, have_points = false;
  const auto bad = [&path](const std::string& what) { return format_error(path + ": " + what); };
  // Versions 1 and 2 of the manifest are the same lines.
  if (lines.empty() || lines[0].key != kManifestMagic || lines[0].fields.size() != 1 ||
      (lines[0].fields[0] != "1" && lines[0].fields[0] != std::to_string(kPartitionFormatVersion))) {
    return bad("not a Relief partition manifest of version 1 or " + std::to_string(kPartitionFormatVersion));
  }
  for (std::size_t i = 1; i < lines.size(); ++i) {
    const TextLine& l = lines[i];
    if (ended) return bad("text after 'end'");
    if (l.key == "plan" && l.fields.size() == 1) {
      if (l.fields[0] != hex64(plan_id)) {
        return invalid_argument(path + ": written for another plan (" + l.fields[0] + ", not " + hex64(plan_id) +
                                "); clear the partition directory");
      }
    } else if (l.key == "input" && l.fields.size() == 1) {
      if (l.fields[0] != std::to_string(input)) return bad("names input " + l.fields[0]);
    } else if (l.key == "points" && l.fields.size() == 1) {
      char* end = nullptr;
      errno = 0;
      const unsigned long long v = std::strtoull(l.fields[0].c_str(), &end, 10);
      if (l.fields[0].empty() || *end != '\0' || errno != 0 || l.fields[0][0] == '-') return bad("a bad point count");
      m.points = v;
      have_points = true;
    } else if (l.key == "warning" && l.fields.size() == 1) {
      m.warnings.push_back(l.fields[0]);
    } else if (l.key == "end" && l.fields.empty()) {
      ended = true;
    } else {
      return bad("unexpected line '" + l.key + "'");
    }
  }
  if (!ended || !have_points) return bad("truncated manifest");
  return m;
}

}  // namespace shard

std::string partition_file_name(std::uint32_t input, std::uint32_t range) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "input-%06u.range-%04u.rpart", input, range);
  return buf;
}

std::string partition_manifest_name(std::uint32_t input) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "input-%06u.done", input);
  return buf;
}

Result<PartitionResult> partition_input(const ShardPlan& plan, std::uint32_t input, const std::string& dir,
                                        const std::atomic<bool>* cancel) {
  using namespace ingest;
  if (input >= plan.input_count()) {
    return invalid_argument("input " + std::to_string(input) + " of a plan of " + std::to_string(plan.input_count()) +
                            " inputs");
  }
  RELIEF_ASSIGN_OR_RETURN(const EncodeParams params, encode_params_from_string(plan.archive_params));
  const std::string& path = plan.sources[input].path;
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> reader, open_point_reader(path, plan.reader_options()));
  const PointStreamInfo& info = reader->info();
  const ScanAttributes& a = plan.attributes;
  // The plan's LAS set is the union of the inputs' (colour low bytes only
  // with colours), with one Extra Bytes layout.
  const std::uint32_t las_outside =
      info.las_attributes & ~a.las_attributes & ~(a.has_colors ? 0u : std::uint32_t{kLasColorLow});
  const bool other_extra = (info.las_attributes & kLasExtraBytes) != 0 &&
                           (info.extra_bytes_size != a.extra_bytes_size || info.extra_bytes_vlr != a.extra_bytes_vlr);
  if ((a.has_colors && !info.has_colors) || (a.has_intensity && !info.has_intensity) ||
      info.format != plan.sources[input].format || las_outside != 0 || other_extra) {
    return invalid_argument(path + ": is not the file the plan was made from (format or attributes differ)");
  }
  const shard::PartitionLayout layout = shard::PartitionLayout::of(plan);
  const std::uint64_t plan_id = shard_plan_id(plan);
  const std::uint32_t ranges = plan.range_count();
  const std::string base = dir.empty() ? std::string(".") : dir;
  TempFiles files;
  std::vector<std::string> finals(ranges);
  std::vector<ByteWriter> staged(ranges);
  std::vector<std::uint64_t> counts(ranges, 0);
  // What a killed task of this host left while writing these files: one
  // listing of the (shared) work directory for all of them.
  std::unordered_set<std::string> names;
  for (std::uint32_t r = 0; r < ranges; ++r) names.insert(partition_file_name(input, r));
  core::remove_stale_temps_in(base, names);
  for (std::uint32_t r = 0; r < ranges; ++r) {
    finals[r] = base + "/" + partition_file_name(input, r);
    files.tmp.push_back(core::temp_path_beside(finals[r]));
    const int fd = ::open(files.tmp.back().c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) {
      files.tmp.pop_back();
      return io_error(finals[r] + ": cannot create: " + std::strerror(errno));
    }
    files.fds.push_back(fd);
    // The header's count is written last, over this placeholder.
    header_bytes(staged[r], plan_id, input, r, layout, 0);
  }
  const double limit = max_coordinate_magnitude(params.cell_size, plan.grid.chunk_edge);
  PointCloud batch;
  std::vector<ChunkKey> keys;
  std::uint64_t read = 0;
  for (;;) {
    if (cancel != nullptr && cancel->load()) return io_error(path + ": interrupted");
    RELIEF_ASSIGN_OR_RETURN(const std::size_t got, reader->read(batch, kReadBatch));
    if (got == 0) break;
    RELIEF_RETURN_IF_ERROR(stage_points(batch, limit, path, read, a.has_colors, a.has_intensity, params));
    // The plan's LAS attributes, those this input lacks as 0 (as compress).
    conform_las(batch, a.las_attributes, layout.extra_size);
    read += got;
    keys.resize(batch.size());
    plan.grid.keys_of(batch.positions.data(), batch.size(), keys.data());
    ChunkKey last{};
    std::uint32_t last_range = 0;
    bool have_last = false;
    for (std::size_t i = 0; i < batch.size(); ++i) {
      if (!have_last || !(keys[i] == last)) {
        last = keys[i];
        last_range = plan.range_of(last);
        have_last = true;
      }
      ByteWriter& w = staged[last_range];
      const Vec3d& p = batch.positions[i];
      w.f64(p.x);
      w.f64(p.y);
      w.f64(p.z);
      if (a.has_colors) {
        w.u8(batch.colors[i].r);
        w.u8(batch.colors[i].g);
        w.u8(batch.colors[i].b);
      }
      if (a.has_intensity) w.f32(batch.intensities[i]);
      if (layout.las != 0) {
        batch.las.for_each_vector([&](const auto& v, std::uint32_t bit) {
          if ((layout.las & bit) != 0) put_value(w, v[i]);
        });
        if (layout.extra_size != 0) w.bytes(batch.las.extra_bytes.data() + i * layout.extra_size, layout.extra_size);
      }
      ++counts[last_range];
      if (w.size() >= kFlushBytes) {
        RELIEF_RETURN_IF_ERROR(write_all(files.fds[last_range], w.buffer().data(), w.size(), finals[last_range]));
        w.buffer().clear();
      }
    }
  }
  for (std::uint32_t r = 0; r < ranges; ++r) {
    ByteWriter& w = staged[r];
    RELIEF_RETURN_IF_ERROR(write_all(files.fds[r], w.buffer().data(), w.size(), finals[r]));
    w.buffer().clear();
    ByteWriter header;
    header_bytes(header, plan_id, input, r, layout, counts[r]);
    if (::pwrite(files.fds[r], header.buffer().data(), header.size(), 0) != static_cast<ssize_t>(header.size())) {
      return io_error(finals[r] + ": write failed: " + std::strerror(errno));
    }
  }
  for (std::uint32_t r = 0; r < ranges; ++r) {
    const int fd = files.fds[r];
    files.fds[r] = -1;  // sync_and_rename closes it (and removes it on failure)
    RELIEF_RETURN_IF_ERROR(shard::sync_and_rename(fd, files.tmp[r], finals[r]));
  }
  PartitionResult result;
  result.points = read;
  result.range_points = counts;
  result.warnings = info.warnings;
  // The manifest last: its presence says every range file of this input is in place.
  std::string manifest = std::string(shard::kManifestMagic) + "\t" + std::to_string(kPartitionFormatVersion) + "\n";
  manifest += "plan\t" + shard::hex64(plan_id) + "\n";
  manifest += "input\t" + std::to_string(input) + "\n";
  manifest += "points\t" + std::to_string(read) + "\n";
  for (const std::string& w : result.warnings) manifest += "warning\t" + shard::escape_field(w) + "\n";
  manifest += "end\n";
  RELIEF_RETURN_IF_ERROR(shard::write_text_atomic(base + "/" + partition_manifest_name(input), manifest));
  return result;
}

}  // namespace relief
