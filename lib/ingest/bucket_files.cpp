#include "ingest/bucket_files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>

namespace relief::ingest {

namespace {

constexpr std::size_t kBlockHeader = 8;
constexpr std::size_t kChunkEntry = 28;
constexpr double kScale = 4294967296.0;  // 2^32
constexpr double kMaxQ = 4294967295.0;

std::uint64_t mix(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

void put_u32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::uint32_t get_u32(const std::uint8_t* p) {
  std::uint32_t v = 0;
  for (int i = 0; i < 4; ++i) v |= static_cast<std::uint32_t>(p[i]) << (8 * i);
  return v;
}

void put_i64(std::uint8_t* p, std::int64_t v) {
  const auto u = static_cast<std::uint64_t>(v);
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(u >> (8 * i));
}

std::int64_t get_i64(const std::uint8_t* p) {
  std::uint64_t u = 0;
  for (int i = 0; i < 8; ++i) u |= static_cast<std::uint64_t>(p[i]) << (8 * i);
  return static_cast<std::int64_t>(u);
}

void put_f32(std::uint8_t* p, float v) {
  std::uint32_t b;
  std::memcpy(&b, &v, 4);
  put_u32(p, b);
}

float get_f32(const std::uint8_t* p) {
  const std::uint32_t b = get_u32(p);
  float v;
  std::memcpy(&v, &b, 4);
  return v;
}

// Fixed-point offset of v in [lo, lo + edge), clamped: a point keyed to this
// chunk may lie an ulp outside its nominal cube (format-spec/archive.md §3).
// Truncation is floor here, the value being positive.
std::uint32_t quantize(double v, double lo, double inv_step) {
  const double q = (v - lo) * inv_step;
  if (!(q > 0)) return 0;
  return q >= kMaxQ ? 0xffffffffu : static_cast<std::uint32_t>(q);
}

Status write_all(int fd, const std::uint8_t* data, std::size_t n, const std::string& path) {
  while (n > 0) {
    const ssize_t w = ::write(fd, data, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return io_error(path + ": write failed: " + std::strerror(errno));
    }
    data += w;
    n -= static_cast<std::size_t>(w);
  }
  return Status::ok();
}

Status read_exact(int fd, std::uint8_t* data, std::size_t n, std::uint64_t offset, const std::string& path) {
  std::size_t got = 0;
  while (got < n) {
    const ssize_t r = ::pread(fd, data + got, n - got, static_cast<off_t>(offset + got));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) return io_error(path + ": read failed: " + (r < 0 ? std::strerror(errno) : "unexpected end"));
    got += static_cast<std::size_t>(r);
  }
  return Status::ok();
}

}  // namespace

Result<BucketFiles> BucketFiles::create(const std::string& parent, std::uint32_t buckets, const ArchiveGrid& grid,
                                        bool colors, bool intensity) {
  BucketFiles b;
  std::string pattern = (parent.empty() ? std::string(".") : parent) + "/relief-ingest-XXXXXX";
  std::vector<char> templ(pattern.begin(), pattern.end());
  templ.push_back('\0');
  if (::mkdtemp(templ.data()) == nullptr) {
    return io_error(parent + ": cannot create a temporary directory: " + std::strerror(errno));
  }
  b.dir_ = templ.data();
  b.grid_ = grid;
  b.colors_ = colors;
  b.intensity_ = intensity;
  b.record_ = 12 + (colors ? 3 : 0) + (intensity ? 4 : 0);
  b.files_.assign(buckets, -1);
  b.counts_.assign(buckets, 0);
  b.bytes_.assign(buckets, 0);
  for (std::uint32_t i = 0; i < buckets; ++i) {
    b.paths_.push_back(b.dir_ + "/bucket-" + std::to_string(i));
    const int fd = ::open(b.paths_.back().c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd < 0) return io_error(b.paths_.back() + ": cannot create: " + std::strerror(errno));
    b.files_[i] = fd;
  }
  return b;
}

BucketFiles::BucketFiles(BucketFiles&& o) noexcept { *this = std::move(o); }

BucketFiles& BucketFiles::operator=(BucketFiles&& o) noexcept {
  if (this != &o) {
    remove_all();
    dir_ = std::move(o.dir_);
    paths_ = std::move(o.paths_);
    files_ = std::move(o.files_);
    counts_ = std::move(o.counts_);
    bytes_ = std::move(o.bytes_);
    grid_ = o.grid_;
    colors_ = o.colors_;
    intensity_ = o.intensity_;
    record_ = o.record_;
    o.dir_.clear();
    o.paths_.clear();
    o.files_.clear();
  }
  return *this;
}

BucketFiles::~BucketFiles() { remove_all(); }

void BucketFiles::remove_all() {
  for (std::size_t i = 0; i < files_.size(); ++i) {
    if (files_[i] >= 0) ::close(files_[i]);
    files_[i] = -1;
  }
  for (const std::string& p : paths_) ::unlink(p.c_str());
  if (!dir_.empty()) ::rmdir(dir_.c_str());
  paths_.clear();
  files_.clear();
  dir_.clear();
}

std::uint32_t BucketFiles::bucket_of(const ChunkKey& key) const {
  const std::uint64_t h = mix(static_cast<std::uint64_t>(key.ix) * 0x9e3779b97f4a7c15ULL ^
                              mix(static_cast<std::uint64_t>(key.iy) + 0x632be59bd9b4e019ULL) ^
                              mix(static_cast<std::uint64_t>(key.iz) * 3 + 0x8cb92ba72f3d8dd7ULL));
  return static_cast<std::uint32_t>(h % files_.size());
}

void BucketFiles::pack(const PointCloud& points, const ChunkKey* keys, PackedBatch& out) const {
  const std::size_t n = points.size();
  // Chunk id of every point (runs of one key are common: check the last one first).
  out.lookup.clear();
  out.chunk_keys.clear();
  out.chunk_min.clear();
  out.chunk_counts.clear();
  out.chunk_of_point.resize(n);
  std::uint32_t last_id = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (out.chunk_keys.empty() || !(keys[i] == out.chunk_keys[last_id])) {
      auto [it, inserted] = out.lookup.try_emplace(keys[i], static_cast<std::uint32_t>(out.chunk_keys.size()));
      if (inserted) {
        out.chunk_keys.push_back(keys[i]);
        out.chunk_min.push_back(grid_.chunk_box(keys[i]).min);
        out.chunk_counts.push_back(0);
      }
      last_id = it->second;
    }
    out.chunk_of_point[i] = last_id;
    ++out.chunk_counts[last_id];
  }
  // Chunks ordered by bucket; each bucket's chunks form one block.
  const std::size_t chunks = out.chunk_keys.size();
  std::vector<std::pair<std::uint32_t, std::uint32_t>> by_bucket(chunks);
  for (std::uint32_t c = 0; c < chunks; ++c) by_bucket[c] = {bucket_of(out.chunk_keys[c]), c};
  std::sort(by_bucket.begin(), by_bucket.end());
  out.blocks.clear();
  out.chunk_cursor.assign(chunks, 0);
  std::size_t total = 0;
  for (std::size_t i = 0; i < chunks;) {
    std::size_t j = i;
    std::uint32_t block_points = 0;
    while (j < chunks && by_bucket[j].first == by_bucket[i].first) block_points += out.chunk_counts[by_bucket[j++].second];
    PackedBatch::Block b;
    b.bucket = by_bucket[i].first;
    b.offset = total;
    b.points = block_points;
    b.size = kBlockHeader + (j - i) * kChunkEntry + static_cast<std::size_t>(block_points) * record_;
    out.blocks.push_back(b);
    total += b.size;
    i = j;
  }
  out.bytes.resize(total);
  std::uint8_t* base = out.bytes.data();
  // Headers, and where each chunk's records start.
  std::size_t c = 0;
  for (const PackedBatch::Block& b : out.blocks) {
    std::uint8_t* h = base + b.offset;
    std::size_t first = c;
    while (c < chunks && by_bucket[c].first == b.bucket) ++c;
    put_u32(h, b.points);
    put_u32(h + 4, static_cast<std::uint32_t>(c - first));
    std::size_t rec = b.offset + kBlockHeader + (c - first) * kChunkEntry;
    for (std::size_t k = first; k < c; ++k) {
      const std::uint32_t id = by_bucket[k].second;
      std::uint8_t* e = h + kBlockHeader + (k - first) * kChunkEntry;
      put_i64(e, out.chunk_keys[id].ix);
      put_i64(e + 8, out.chunk_keys[id].iy);
      put_i64(e + 16, out.chunk_keys[id].iz);
      put_u32(e + 24, out.chunk_counts[id]);
      out.chunk_cursor[id] = rec;
      rec += static_cast<std::size_t>(out.chunk_counts[id]) * record_;
    }
  }
  // Records, each to its chunk's next slot.
  const double inv_step = kScale / grid_.chunk_edge;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t id = out.chunk_of_point[i];
    std::uint8_t* r = base + out.chunk_cursor[id];
    out.chunk_cursor[id] += record_;
    const Vec3d& lo = out.chunk_min[id];
    const Vec3d& p = points.positions[i];
    put_u32(r, quantize(p.x, lo.x, inv_step));
    put_u32(r + 4, quantize(p.y, lo.y, inv_step));
    put_u32(r + 8, quantize(p.z, lo.z, inv_step));
    std::size_t off = 12;
    if (colors_) {
      r[off] = points.colors[i].r;
      r[off + 1] = points.colors[i].g;
      r[off + 2] = points.colors[i].b;
      off += 3;
    }
    if (intensity_) put_f32(r + off, points.intensities[i]);
  }
}

Status BucketFiles::write(const PackedBatch& batch) {
  for (const PackedBatch::Block& b : batch.blocks) {
    RELIEF_RETURN_IF_ERROR(write_all(files_[b.bucket], batch.bytes.data() + b.offset, b.size, paths_[b.bucket]));
    counts_[b.bucket] += b.points;
    bytes_[b.bucket] += b.size;
  }
  return Status::ok();
}

Status BucketFiles::finish_writing() { return Status::ok(); }

Status BucketFiles::read_slice(std::uint32_t bucket, std::uint64_t* offset, std::uint64_t max_points,
                               PointCloud& out, Grouping& g, std::vector<std::uint8_t>& buf) const {
  out.positions.clear();
  out.colors.clear();
  out.intensities.clear();
  g.clear();
  const std::string& path = paths_[bucket];
  const auto damaged = [&](const std::string& what) {
    return corrupt_data(path + ": temporary file damaged at byte " + std::to_string(*offset) + ": " + what);
  };
  const double step = grid_.chunk_edge / kScale;
  while (*offset < bytes_[bucket]) {
    std::uint8_t header[kBlockHeader];
    if (bytes_[bucket] - *offset < kBlockHeader) return damaged("truncated block header");
    RELIEF_RETURN_IF_ERROR(read_exact(files_[bucket], header, kBlockHeader, *offset, path));
    const std::uint32_t points = get_u32(header);
    const std::uint32_t chunks = get_u32(header + 4);
    if (!out.empty() && out.size() + points > max_points) break;
    const std::uint64_t size = kBlockHeader + static_cast<std::uint64_t>(chunks) * kChunkEntry +
                               static_cast<std::uint64_t>(points) * record_;
    if (chunks == 0 || chunks > points || size > bytes_[bucket] - *offset) return damaged("block overruns the file");
    buf.resize(static_cast<std::size_t>(size - kBlockHeader));
    RELIEF_RETURN_IF_ERROR(read_exact(files_[bucket], buf.data(), buf.size(), *offset + kBlockHeader, path));
    const std::size_t at = out.size();
    out.positions.resize(at + points);
    if (colors_) out.colors.resize(at + points);
    if (intensity_) out.intensities.resize(at + points);
    const std::uint8_t* r = buf.data() + static_cast<std::size_t>(chunks) * kChunkEntry;
    std::size_t k = at;
    std::uint64_t listed = 0;
    for (std::uint32_t c = 0; c < chunks; ++c) {
      const std::uint8_t* e = buf.data() + static_cast<std::size_t>(c) * kChunkEntry;
      const ChunkKey key{get_i64(e), get_i64(e + 8), get_i64(e + 16)};
      const std::uint32_t count = get_u32(e + 24);
      listed += count;
      if (listed > points) return damaged("chunk counts exceed the block's points");
      if (bucket_of(key) != bucket) return damaged("a chunk in the wrong bucket");
      g.add_run(key, count);
      const Box3d cube = grid_.chunk_box(key);
      for (std::uint32_t i = 0; i < count; ++i, ++k, r += record_) {
        out.positions[k] = {cube.min.x + (get_u32(r) + 0.5) * step, cube.min.y + (get_u32(r + 4) + 0.5) * step,
                            cube.min.z + (get_u32(r + 8) + 0.5) * step};
        std::size_t off = 12;
        if (colors_) {
          out.colors[k] = {r[off], r[off + 1], r[off + 2]};
          off += 3;
        }
        if (intensity_) out.intensities[k] = get_f32(r + off);
      }
    }
    if (listed != points) return damaged("chunk counts do not add up to the block's points");
    *offset += size;
  }
  return Status::ok();
}

void BucketFiles::discard(std::uint32_t b) {
  if (files_[b] >= 0) ::close(files_[b]);
  files_[b] = -1;
  ::unlink(paths_[b].c_str());
}

}  // namespace relief::ingest
