#include "ingest/bucket_files.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace relief::ingest {

namespace {

constexpr std::size_t kMinBucketBuffer = 4096;

std::uint64_t mix(std::uint64_t z) {
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

void put_f64(std::uint8_t* p, double v) {
  std::uint64_t b;
  std::memcpy(&b, &v, 8);
  for (int i = 0; i < 8; ++i) p[i] = static_cast<std::uint8_t>(b >> (8 * i));
}

double get_f64(const std::uint8_t* p) {
  std::uint64_t b = 0;
  for (int i = 0; i < 8; ++i) b |= static_cast<std::uint64_t>(p[i]) << (8 * i);
  double v;
  std::memcpy(&v, &b, 8);
  return v;
}

void put_f32(std::uint8_t* p, float v) {
  std::uint32_t b;
  std::memcpy(&b, &v, 4);
  for (int i = 0; i < 4; ++i) p[i] = static_cast<std::uint8_t>(b >> (8 * i));
}

float get_f32(const std::uint8_t* p) {
  std::uint32_t b = 0;
  for (int i = 0; i < 4; ++i) b |= static_cast<std::uint32_t>(p[i]) << (8 * i);
  float v;
  std::memcpy(&v, &b, 4);
  return v;
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

}  // namespace

std::size_t record_size(bool colors, bool intensity) { return 24 + (colors ? 3 : 0) + (intensity ? 4 : 0); }

Result<BucketFiles> BucketFiles::create(const std::string& parent, std::uint32_t buckets, std::size_t buffer_bytes,
                                        bool colors, bool intensity) {
  BucketFiles b;
  std::string pattern = (parent.empty() ? std::string(".") : parent) + "/relief-ingest-XXXXXX";
  std::vector<char> templ(pattern.begin(), pattern.end());
  templ.push_back('\0');
  if (::mkdtemp(templ.data()) == nullptr) {
    return io_error(parent + ": cannot create a temporary directory: " + std::strerror(errno));
  }
  b.dir_ = templ.data();
  b.colors_ = colors;
  b.intensity_ = intensity;
  b.record_ = record_size(colors, intensity);
  b.per_bucket_buffer_ = std::max(kMinBucketBuffer, buffer_bytes / std::max<std::uint32_t>(1, buckets));
  b.files_.assign(buckets, -1);
  b.buffers_.resize(buckets);
  b.counts_.assign(buckets, 0);
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
    buffers_ = std::move(o.buffers_);
    counts_ = std::move(o.counts_);
    per_bucket_buffer_ = o.per_bucket_buffer_;
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

Status BucketFiles::append(const PointCloud& points, const std::vector<ChunkKey>& keys) {
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::uint32_t b = bucket_of(keys[i]);
    std::vector<std::uint8_t>& buf = buffers_[b];
    const std::size_t at = buf.size();
    buf.resize(at + record_);
    std::uint8_t* p = buf.data() + at;
    put_f64(p, points.positions[i].x);
    put_f64(p + 8, points.positions[i].y);
    put_f64(p + 16, points.positions[i].z);
    std::size_t off = 24;
    if (colors_) {
      p[off] = points.colors[i].r;
      p[off + 1] = points.colors[i].g;
      p[off + 2] = points.colors[i].b;
      off += 3;
    }
    if (intensity_) put_f32(p + off, points.intensities[i]);
    ++counts_[b];
    if (buf.size() >= per_bucket_buffer_) RELIEF_RETURN_IF_ERROR(flush(b));
  }
  return Status::ok();
}

Status BucketFiles::flush(std::uint32_t b) {
  std::vector<std::uint8_t>& buf = buffers_[b];
  if (buf.empty()) return Status::ok();
  RELIEF_RETURN_IF_ERROR(write_all(files_[b], buf.data(), buf.size(), paths_[b]));
  buf.clear();
  return Status::ok();
}

Status BucketFiles::finish_writing() {
  for (std::uint32_t b = 0; b < files_.size(); ++b) {
    RELIEF_RETURN_IF_ERROR(flush(b));
    std::vector<std::uint8_t>().swap(buffers_[b]);
  }
  return Status::ok();
}

Status BucketFiles::read(std::uint32_t b, std::uint64_t first, std::uint64_t count, PointCloud& out) const {
  out.positions.resize(count);
  out.colors.resize(colors_ ? count : 0);
  out.intensities.resize(intensity_ ? count : 0);
  constexpr std::size_t kBlockRecords = 1 << 16;
  std::vector<std::uint8_t> block(kBlockRecords * record_);
  std::uint64_t done = 0;
  while (done < count) {
    const std::size_t n = static_cast<std::size_t>(std::min<std::uint64_t>(kBlockRecords, count - done));
    const auto offset = static_cast<off_t>((first + done) * record_);
    std::size_t got = 0;
    while (got < n * record_) {
      const ssize_t r = ::pread(files_[b], block.data() + got, n * record_ - got, offset + static_cast<off_t>(got));
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) {
        return io_error(paths_[b] + ": read failed: " + (r < 0 ? std::strerror(errno) : "unexpected end"));
      }
      got += static_cast<std::size_t>(r);
    }
    for (std::size_t i = 0; i < n; ++i) {
      const std::uint8_t* p = block.data() + i * record_;
      const std::size_t k = static_cast<std::size_t>(done) + i;
      out.positions[k] = {get_f64(p), get_f64(p + 8), get_f64(p + 16)};
      std::size_t off = 24;
      if (colors_) {
        out.colors[k] = {p[off], p[off + 1], p[off + 2]};
        off += 3;
      }
      if (intensity_) out.intensities[k] = get_f32(p + off);
    }
    done += n;
  }
  return Status::ok();
}

void BucketFiles::discard(std::uint32_t b) {
  if (files_[b] >= 0) ::close(files_[b]);
  files_[b] = -1;
  ::unlink(paths_[b].c_str());
}

}  // namespace relief::ingest
