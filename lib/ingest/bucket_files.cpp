#include "ingest/bucket_files.h"
#include "core/file_io.h"
#include "ingest/las_columns.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <new>

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

// A block's chunk entry: the key, then its record count.
void put_entry(std::uint8_t* e, const ChunkKey& key, std::uint32_t count) {
  put_i64(e, key.ix);
  put_i64(e + 8, key.iy);
  put_i64(e + 16, key.iz);
  put_u32(e + 24, count);
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

std::size_t round_up(std::size_t n, std::size_t a) { return (n + a - 1) / a * a; }

}  // namespace

AlignedBuffer::~AlignedBuffer() { std::free(data_); }

AlignedBuffer::AlignedBuffer(AlignedBuffer&& o) noexcept : data_(o.data_), capacity_(o.capacity_) {
  o.data_ = nullptr;
  o.capacity_ = 0;
}

AlignedBuffer& AlignedBuffer::operator=(AlignedBuffer&& o) noexcept {
  if (this != &o) {
    std::free(data_);
    data_ = o.data_;
    capacity_ = o.capacity_;
    o.data_ = nullptr;
    o.capacity_ = 0;
  }
  return *this;
}

void AlignedBuffer::reserve(std::size_t bytes, std::size_t keep) {
  if (bytes <= capacity_) return;
  const std::size_t cap = round_up(bytes, kAlign);
  auto* p = static_cast<std::uint8_t*>(std::aligned_alloc(kAlign, cap));
  if (p == nullptr) throw std::bad_alloc();
  if (keep > 0) std::memcpy(p, data_, keep);
  std::free(data_);
  data_ = p;
  capacity_ = cap;
}

Result<BucketFiles> BucketFiles::create(const std::string& parent, std::uint32_t buckets, const ArchiveGrid& grid,
                                        bool colors, bool intensity, std::size_t staging_bytes,
                                        std::uint32_t las_attributes, std::uint32_t extra_bytes_size) {
  BucketFiles b;
  RELIEF_ASSIGN_OR_RETURN(b.dir_, IngestTempDir::create(parent));
  b.grid_ = grid;
  b.step_ = grid.chunk_edge / kScale;
  b.colors_ = colors;
  b.intensity_ = intensity;
  b.las_ = las_attributes;
  b.extra_size_ = (las_attributes & kLasExtraBytes) != 0 ? extra_bytes_size : 0;
  b.record_ = 12 + (colors ? 3 : 0) + (intensity ? 4 : 0) + las_record_bytes(las_attributes, b.extra_size_);
  b.files_.assign(buckets, -1);
  b.counts_.assign(buckets, 0);
  b.bytes_.assign(buckets, 0);
  b.staging_.resize(buckets);
  b.staged_.assign(buckets, 0);
  b.file_pos_.assign(buckets, 0);
  b.staging_target_ = std::max<std::size_t>(2 * AlignedBuffer::kAlign,
                                            round_up(staging_bytes / std::max<std::uint32_t>(1, buckets),
                                                     AlignedBuffer::kAlign));
  b.direct_ = true;
  for (std::uint32_t i = 0; i < buckets; ++i) {
    b.paths_.push_back(b.dir_.path() + "/bucket-" + std::to_string(i));
    const char* path = b.paths_.back().c_str();
    int fd = -1;
#if defined(O_DIRECT)
    if (b.direct_) {
      fd = ::open(path, O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC | O_DIRECT, 0600);
      // File systems without direct I/O (tmpfs) refuse it: use the page cache.
      if (fd < 0 && errno == EINVAL) {
        ::unlink(path);
        b.direct_ = false;
      }
    }
#else
    b.direct_ = false;
#endif
    if (fd < 0 && !b.direct_) fd = ::open(path, O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
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
    staging_ = std::move(o.staging_);
    staged_ = std::move(o.staged_);
    file_pos_ = std::move(o.file_pos_);
    staging_target_ = o.staging_target_;
    direct_ = o.direct_;
    grid_ = o.grid_;
    step_ = o.step_;
    explicit_buckets_ = o.explicit_buckets_;
    colors_ = o.colors_;
    intensity_ = o.intensity_;
    las_ = o.las_;
    extra_size_ = o.extra_size_;
    record_ = o.record_;
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
  dir_.remove();
  paths_.clear();
  files_.clear();
}

std::uint32_t BucketFiles::bucket_of(const ChunkKey& key) const {
  const std::uint64_t h = mix(static_cast<std::uint64_t>(key.ix) * 0x9e3779b97f4a7c15ULL ^
                              mix(static_cast<std::uint64_t>(key.iy) + 0x632be59bd9b4e019ULL) ^
                              mix(static_cast<std::uint64_t>(key.iz) * 3 + 0x8cb92ba72f3d8dd7ULL));
  return static_cast<std::uint32_t>(h % files_.size());
}

Result<std::uint8_t*> BucketFiles::stage_block(std::uint32_t bucket, std::size_t size) {
  if (staged_[bucket] + size > staging_target_) RELIEF_RETURN_IF_ERROR(flush(bucket, false));
  AlignedBuffer& buf = staging_[bucket];
  buf.reserve(std::max(staging_target_, staged_[bucket] + size), staged_[bucket]);
  std::uint8_t* h = buf.data() + staged_[bucket];
  staged_[bucket] += size;
  bytes_[bucket] += size;
  return h;
}

// A block larger than a bucket's staging share (a batch falling into few
// chunks, as scan-ordered inputs do) grew that bucket's buffer: write it out
// now and give the memory back. Otherwise every bucket would keep the largest
// block it ever received, and the staging memory would grow with the input
// (872 buckets x ~9 MB on a 1 G-point aerial scan) instead of staying at its
// share of the budget plus one batch.
Status BucketFiles::shrink_staging(std::uint32_t bucket) {
  if (staging_[bucket].capacity() <= staging_target_) return Status::ok();
  RELIEF_RETURN_IF_ERROR(flush(bucket, false));
  AlignedBuffer fresh;
  fresh.reserve(staging_target_, 0);
  std::memcpy(fresh.data(), staging_[bucket].data(), staged_[bucket]);  // under one page
  staging_[bucket] = std::move(fresh);
  return Status::ok();
}

Status BucketFiles::append(const PointCloud& points, const ChunkKey* keys) {
  const std::size_t n = points.size();
  if (n == 0) return Status::ok();
  // Chunk id of every point, and each chunk's point count and cube corner.
  batch_.clear();
  batch_.add_keys(keys, n);
  const std::vector<ChunkKey>& chunk_keys = batch_.keys;
  const std::size_t chunks = chunk_keys.size();
  chunk_counts_.assign(chunks, 0);
  for (const std::uint32_t id : batch_.ids) ++chunk_counts_[id];
  chunk_min_.resize(chunks);
  for (std::size_t c = 0; c < chunks; ++c) chunk_min_[c] = grid_.chunk_box(chunk_keys[c]).min;
  // Chunks ordered by bucket; each bucket's chunks form one block, laid out
  // in that bucket's staging buffer.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> by_bucket(chunks);
  for (std::uint32_t c = 0; c < chunks; ++c) by_bucket[c] = {bucket_of(chunk_keys[c]), c};
  std::sort(by_bucket.begin(), by_bucket.end());
  chunk_cursor_.assign(chunks, nullptr);
  for (std::size_t i = 0; i < chunks;) {
    const std::uint32_t bucket = by_bucket[i].first;
    std::size_t j = i;
    std::uint32_t block_points = 0;
    while (j < chunks && by_bucket[j].first == bucket) block_points += chunk_counts_[by_bucket[j++].second];
    const std::size_t size = kBlockHeader + (j - i) * kChunkEntry + static_cast<std::size_t>(block_points) * record_;
    RELIEF_ASSIGN_OR_RETURN(std::uint8_t* const h, stage_block(bucket, size));
    put_u32(h, block_points);
    put_u32(h + 4, static_cast<std::uint32_t>(j - i));
    std::uint8_t* rec = h + kBlockHeader + (j - i) * kChunkEntry;
    for (std::size_t k = i; k < j; ++k) {
      const std::uint32_t id = by_bucket[k].second;
      std::uint8_t* e = h + kBlockHeader + (k - i) * kChunkEntry;
      put_entry(e, chunk_keys[id], chunk_counts_[id]);
      chunk_cursor_[id] = rec;
      rec += static_cast<std::size_t>(chunk_counts_[id]) * record_;
    }
    counts_[bucket] += block_points;
    i = j;
  }
  // Records, each to its chunk's next slot.
  const double inv_step = kScale / grid_.chunk_edge;
  for (std::size_t i = 0; i < n; ++i) {
    const std::uint32_t id = batch_.ids[i];
    std::uint8_t* r = chunk_cursor_[id];
    chunk_cursor_[id] += record_;
    const Vec3d& lo = chunk_min_[id];
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
    if (intensity_) {
      put_f32(r + off, points.intensities[i]);
      off += 4;
    }
    if (las_ != 0) put_las_record(r + off, points.las, i, las_);
  }
  for (std::size_t i = 0; i < chunks; ++i) {
    const std::uint32_t bucket = by_bucket[i].first;
    if (i > 0 && by_bucket[i - 1].first == bucket) continue;
    RELIEF_RETURN_IF_ERROR(shrink_staging(bucket));
  }
  return Status::ok();
}

Status BucketFiles::append_block(std::uint32_t bucket, const std::vector<std::pair<ChunkKey, std::uint32_t>>& runs,
                                 const std::uint8_t* records, std::uint32_t points) {
  if (runs.empty()) return Status::ok();
  const std::size_t size = kBlockHeader + runs.size() * kChunkEntry + static_cast<std::size_t>(points) * record_;
  RELIEF_ASSIGN_OR_RETURN(std::uint8_t* const h, stage_block(bucket, size));
  put_u32(h, points);
  put_u32(h + 4, static_cast<std::uint32_t>(runs.size()));
  std::uint8_t* e = h + kBlockHeader;
  for (const auto& [key, count] : runs) {
    put_entry(e, key, count);
    e += kChunkEntry;
  }
  std::memcpy(e, records, static_cast<std::size_t>(points) * record_);
  counts_[bucket] += points;
  return shrink_staging(bucket);
}

std::size_t BucketFiles::staging_capacity() const {
  std::size_t n = 0;
  for (const AlignedBuffer& b : staging_) n += b.capacity();
  return n;
}

Status BucketFiles::flush(std::uint32_t bucket, bool all) {
  AlignedBuffer& buf = staging_[bucket];
  const std::size_t staged = staged_[bucket];
  std::size_t out = staged / AlignedBuffer::kAlign * AlignedBuffer::kAlign;
  if (all && out < staged) {
    out = round_up(staged, AlignedBuffer::kAlign);
    std::memset(buf.data() + staged, 0, out - staged);
  }
  if (out == 0) return Status::ok();
  std::size_t done = 0;
  while (done < out) {
    const ssize_t w = ::pwrite(files_[bucket], buf.data() + done, out - done,
                               static_cast<off_t>(file_pos_[bucket] + done));
    if (w < 0) {
      if (errno == EINTR) continue;
      return io_error(paths_[bucket] + ": write failed: " + std::strerror(errno));
    }
    done += static_cast<std::size_t>(w);
  }
  file_pos_[bucket] += out;
  const std::size_t rest = all ? 0 : staged - out;
  if (rest > 0) std::memmove(buf.data(), buf.data() + out, rest);
  staged_[bucket] = rest;
  return Status::ok();
}

Status BucketFiles::finish_writing() {
  for (std::uint32_t b = 0; b < files_.size(); ++b) {
    RELIEF_RETURN_IF_ERROR(flush(b, true));
    staging_[b] = AlignedBuffer();
  }
  return Status::ok();
}

Status BucketFiles::read_range(std::uint32_t bucket, std::uint64_t from, std::size_t n, AlignedBuffer& buf) const {
  const std::uint64_t start = from / AlignedBuffer::kAlign * AlignedBuffer::kAlign;
  const std::size_t len = round_up(static_cast<std::size_t>(from - start) + n, AlignedBuffer::kAlign);
  if (start + len > file_pos_[bucket]) {
    return corrupt_data(paths_[bucket] + ": temporary file shorter than written");
  }
  buf.reserve(len, 0);
  const int e = pread_exact(files_[bucket], buf.data(), len, start);
  if (e == 0) return Status::ok();
  return io_error(paths_[bucket] + ": read failed: " + (e > 0 ? std::strerror(e) : "unexpected end"));
}

Vec3d BucketFiles::position(const Vec3d& cube_min, const std::uint8_t* r) const {
  return {cube_min.x + (get_u32(r) + 0.5) * step_, cube_min.y + (get_u32(r + 4) + 0.5) * step_,
          cube_min.z + (get_u32(r + 8) + 0.5) * step_};
}

Status BucketFiles::damaged_at(std::uint32_t bucket, std::uint64_t offset, const std::string& what) const {
  return corrupt_data(paths_[bucket] + ": temporary file damaged at byte " + std::to_string(offset) + ": " + what);
}

Status BucketFiles::peek_block(std::uint32_t bucket, std::uint64_t offset, AlignedBuffer& buf, Window& w,
                               Block& block, std::uint64_t max_points) const {
  const auto damaged = [&](const std::string& what) { return damaged_at(bucket, offset, what); };
  // Windows of at least kWindow bytes: blocks are often small.
  constexpr std::size_t kWindow = 2u << 20;
  const auto load = [&](std::uint64_t from, std::size_t n) -> Status {
    const std::uint64_t end = std::min<std::uint64_t>(bytes_[bucket], from + std::max(n, kWindow));
    RELIEF_RETURN_IF_ERROR(read_range(bucket, from, static_cast<std::size_t>(end - from), buf));
    w = {from, end, static_cast<std::size_t>(from % AlignedBuffer::kAlign)};
    return Status::ok();
  };
  const auto view = [&](std::uint64_t at) { return buf.data() + w.skip + (at - w.from); };
  if (bytes_[bucket] - offset < kBlockHeader) return damaged("truncated block header");
  if (offset < w.from || offset + kBlockHeader > w.to) RELIEF_RETURN_IF_ERROR(load(offset, kBlockHeader));
  block.points = get_u32(view(offset));
  block.chunks = get_u32(view(offset) + 4);
  block.entries = nullptr;
  if (block.points > max_points) return Status::ok();
  block.size = kBlockHeader + static_cast<std::uint64_t>(block.chunks) * kChunkEntry +
               static_cast<std::uint64_t>(block.points) * record_;
  if (block.chunks == 0 || block.chunks > block.points || block.size > bytes_[bucket] - offset) {
    return damaged("block overruns the file");
  }
  if (offset + block.size > w.to) RELIEF_RETURN_IF_ERROR(load(offset, static_cast<std::size_t>(block.size)));
  block.entries = view(offset) + kBlockHeader;
  return Status::ok();
}

Status BucketFiles::each_run(std::uint32_t bucket, std::uint64_t offset, const Block& block,
                             const std::function<Status(const ChunkKey&, std::uint32_t, const std::uint8_t*)>& fn) const {
  const auto damaged = [&](const std::string& what) { return damaged_at(bucket, offset, what); };
  const std::uint8_t* r = block.entries + static_cast<std::size_t>(block.chunks) * kChunkEntry;
  std::uint64_t listed = 0;
  for (std::uint32_t c = 0; c < block.chunks; ++c) {
    const std::uint8_t* e = block.entries + static_cast<std::size_t>(c) * kChunkEntry;
    const ChunkKey key{get_i64(e), get_i64(e + 8), get_i64(e + 16)};
    const std::uint32_t count = get_u32(e + 24);
    listed += count;
    if (listed > block.points) return damaged("chunk counts exceed the block's points");
    if (!explicit_buckets_ && bucket_of(key) != bucket) return damaged("a chunk in the wrong bucket");
    if (Status s = fn(key, count, r); !s) return s;
    r += static_cast<std::size_t>(count) * record_;
  }
  if (listed != block.points) return damaged("chunk counts do not add up to the block's points");
  return Status::ok();
}

Status BucketFiles::read_slice(std::uint32_t bucket, std::uint64_t* offset, std::uint64_t max_points,
                               PointCloud& out, Grouping& g, AlignedBuffer& buf) const {
  out.clear_points();
  g.clear();
  // Capacity for the whole slice up front: growing block by block would
  // double the vectors past the slice's share of the memory budget.
  const auto cap = static_cast<std::size_t>(std::min(max_points, counts_[bucket]));
  out.reserve(cap, colors_, intensity_);
  if (las_ != 0) reserve_las(out.las, cap, las_, extra_size_);
  g.ids.reserve(cap);
  Window w;
  Block block;
  while (*offset < bytes_[bucket]) {
    // At least one block, then whole blocks while they fit.
    const std::uint64_t room = out.empty() ? ~std::uint64_t{0} : max_points - std::min<std::uint64_t>(max_points, out.size());
    RELIEF_RETURN_IF_ERROR(peek_block(bucket, *offset, buf, w, block, room));
    if (block.entries == nullptr) break;
    const std::size_t at = out.size();
    const std::size_t points = block.points;
    out.positions.resize(at + points);
    if (colors_) out.colors.resize(at + points);
    if (intensity_) out.intensities.resize(at + points);
    if (las_ != 0) resize_las(out.las, at + points, las_, extra_size_);
    std::size_t k = at;
    RELIEF_RETURN_IF_ERROR(each_run(bucket, *offset, block, [&](const ChunkKey& key, std::uint32_t count,
                                                                 const std::uint8_t* r) {
      g.add_run(key, count);
      const Vec3d lo = grid_.chunk_box(key).min;
      for (std::uint32_t i = 0; i < count; ++i, ++k, r += record_) {
        out.positions[k] = position(lo, r);
        std::size_t off = 12;
        if (colors_) {
          out.colors[k] = {r[off], r[off + 1], r[off + 2]};
          off += 3;
        }
        if (intensity_) {
          out.intensities[k] = get_f32(r + off);
          off += 4;
        }
        if (las_ != 0) get_las_record(r + off, out.las, k, las_);
      }
      return Status::ok();
    }));
    *offset += block.size;
  }
  return Status::ok();
}

Status BucketFiles::scan(std::uint32_t bucket, AlignedBuffer& buf, const RunVisitor& visit) const {
  Window w;
  Block block;
  for (std::uint64_t offset = 0; offset < bytes_[bucket]; offset += block.size) {
    RELIEF_RETURN_IF_ERROR(peek_block(bucket, offset, buf, w, block, ~std::uint64_t{0}));
    RELIEF_RETURN_IF_ERROR(each_run(bucket, offset, block, [&](const ChunkKey& key, std::uint32_t count,
                                                                const std::uint8_t* r) {
      return visit(key, grid_.chunk_box(key).min, r, count);
    }));
  }
  return Status::ok();
}

void BucketFiles::discard(std::uint32_t b) {
  if (files_[b] >= 0) ::close(files_[b]);
  files_[b] = -1;
  ::unlink(paths_[b].c_str());
}

}  // namespace relief::ingest
