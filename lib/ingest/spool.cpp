#include "ingest/spool.h"

#include "core/file_io.h"
#include "ingest/las_columns.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstring>
#include <type_traits>

namespace relief::ingest {

namespace {

// A batch: this header, then (with kIntPositions) the offset and scale as
// six doubles, then the columns.
constexpr std::uint32_t kMagic = 0x31505352;  // "RSP1"
constexpr std::uint32_t kColors = 1u, kIntensity = 2u, kIntPositions = 4u;
constexpr std::size_t kHeaderBytes = 24;
constexpr std::size_t kGridBytes = 48;
constexpr std::uint32_t kKnownLas = (1u << kLasAttributeCount) - 1;

struct Header {
  std::uint32_t magic = kMagic, points = 0, flags = 0, las = 0, extra_size = 0, reserved = 0;
};
static_assert(sizeof(Header) == kHeaderBytes);

// x y z from the LAS integers, the one formula both the writer's check and
// the reader use (not inlined, so both run the very same instructions).
[[gnu::noinline]] void positions_from_ints(const std::int32_t* k, std::size_t n, const Vec3d& offset,
                                           const Vec3d& scale, Vec3d* out) {
  for (std::size_t i = 0; i < n; ++i) {
    out[i] = Vec3d{offset.x + scale.x * static_cast<double>(k[3 * i]),
                   offset.y + scale.y * static_cast<double>(k[3 * i + 1]),
                   offset.z + scale.z * static_cast<double>(k[3 * i + 2])};
  }
}

// Bytes a point takes in the batch's columns.
std::uint64_t column_bytes(const Header& h) {
  std::uint64_t b = (h.flags & kIntPositions) != 0 ? 12 : 24;
  if ((h.flags & kColors) != 0) b += 3;
  if ((h.flags & kIntensity) != 0) b += 4;
  return b + las_record_bytes(h.las, h.extra_size);
}

Status write_all(int fd, std::vector<iovec>& iov) {
  std::size_t at = 0;
  while (at < iov.size()) {
    const int count = static_cast<int>(std::min<std::size_t>(iov.size() - at, IOV_MAX));
    const ssize_t w = ::writev(fd, iov.data() + at, count);
    if (w < 0) {
      if (errno == EINTR) continue;
      return io_error(std::strerror(errno));
    }
    if (w == 0) return io_error("nothing written");
    auto left = static_cast<std::size_t>(w);
    while (at < iov.size() && left >= iov[at].iov_len) left -= iov[at++].iov_len;
    if (left > 0) {
      iov[at].iov_base = static_cast<std::uint8_t*>(iov[at].iov_base) + left;
      iov[at].iov_len -= left;
    }
  }
  return Status::ok();
}

class SpoolReader final : public PointReader {
 public:
  SpoolReader(std::shared_ptr<const Spool> spool, std::string path, PointStreamInfo info,
              std::uint64_t release_bytes)
      : spool_(std::move(spool)),
        path_(std::move(path)),
        info_(std::move(info)),
        release_bytes_(release_bytes) {}
  ~SpoolReader() override { close_file(); }

  const PointStreamInfo& info() const override { return info_; }

  Result<std::size_t> read(PointCloud& batch, std::size_t max_points) override {
    batch.clear_points();
    if (done_ || max_points == 0) {
      batch = PointCloud();
      return std::size_t{0};
    }
    if (fd_ < 0) {
      // Read-write, to give back the disk of what has been read.
      fd_ = ::open(path_.c_str(), O_RDWR | O_CLOEXEC);
      struct stat st {};
      if (fd_ < 0 || ::fstat(fd_, &st) != 0)
        return io_error(what() + ": cannot read: " + std::strerror(errno));
      size_ = static_cast<std::uint64_t>(st.st_size);
    }
    if (used_ == header_.points) {
      if (next_ == size_) {
        close_file();
        ::unlink(path_.c_str());
        done_ = true;
        batch = PointCloud();
        return std::size_t{0};
      }
      release_read();
      RELIEF_RETURN_IF_ERROR(load_header());
    }
    const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(max_points, header_.points - used_));
    RELIEF_RETURN_IF_ERROR(read_columns(batch, n));
    used_ += n;
    return n;
  }

 private:
  std::string what() const { return path_ + " (decoded points of " + info_.path + ")"; }
  Status damaged(const std::string& why) const {
    return corrupt_data(what() + ": temporary file damaged at byte " + std::to_string(next_) + ": " + why);
  }
  void close_file() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }
  Status pread_all(void* to, std::size_t n, std::uint64_t at) const {
    const int e = pread_exact(fd_, to, n, at);
    if (e == 0) return Status::ok();
    return e > 0 ? io_error(what() + ": cannot read: " + std::strerror(e)) : damaged("truncated");
  }

  // Gives the file system back the blocks of the batches read (a hole
  // punched before next_, at least release_bytes at a time), so that the
  // spool shrinks as the ingest's bucket files grow. A file system without
  // holes keeps them until the file is deleted at its end.
  void release_read() {
#if defined(FALLOC_FL_PUNCH_HOLE)
    if (next_ - released_ < release_bytes_) return;
    if (::fallocate(fd_, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, static_cast<off_t>(released_),
                    static_cast<off_t>(next_ - released_)) == 0) {
      released_ = next_;
    } else {
      release_bytes_ = UINT64_MAX;  // not supported here: stop trying
    }
#endif
  }

  // Reads the header at next_ and lays out the batch's columns; bounded by
  // the bytes the file holds before anything is sized from its count.
  Status load_header() {
    if (size_ - next_ < kHeaderBytes) return damaged("a batch header cut short");
    Header h;
    RELIEF_RETURN_IF_ERROR(pread_all(&h, kHeaderBytes, next_));
    if (h.magic != kMagic || h.points == 0 || (h.flags & ~(kColors | kIntensity | kIntPositions)) != 0 ||
        (h.las & ~(kKnownLas | kLasExtraBytes)) != 0 || h.reserved != 0 ||
        ((h.las & kLasExtraBytes) == 0) != (h.extra_size == 0) || h.extra_size > 0xFFFF) {
      return damaged("not a batch header");
    }
    std::uint64_t at = next_ + kHeaderBytes;
    if ((h.flags & kIntPositions) != 0) {
      if (size_ - at < kGridBytes) return damaged("a batch header cut short");
      double grid[6];
      RELIEF_RETURN_IF_ERROR(pread_all(grid, kGridBytes, at));
      offset_ = Vec3d{grid[0], grid[1], grid[2]};
      scale_ = Vec3d{grid[3], grid[4], grid[5]};
      at += kGridBytes;
    }
    const std::uint64_t per_point = column_bytes(h);
    if ((size_ - at) / per_point < h.points)
      return damaged("a batch of " + std::to_string(h.points) + " points cut short");
    header_ = h;
    columns_ = at;
    used_ = 0;
    next_ = at + per_point * h.points;
    return Status::ok();
  }

  // Points [used_, used_ + n) of the batch, column by column.
  Status read_columns(PointCloud& out, std::size_t n) {
    const Header& h = header_;
    std::uint64_t col = columns_;
    const auto column = [&](void* to, std::size_t width) -> Status {
      RELIEF_RETURN_IF_ERROR(pread_all(to, n * width, col + used_ * width));
      col += std::uint64_t{h.points} * width;
      return Status::ok();
    };
    out.positions.resize(n);
    if ((h.flags & kIntPositions) != 0) {
      ints_.resize(3 * n);
      RELIEF_RETURN_IF_ERROR(column(ints_.data(), 12));
      positions_from_ints(ints_.data(), n, offset_, scale_, out.positions.data());
    } else {
      RELIEF_RETURN_IF_ERROR(column(out.positions.data(), sizeof(Vec3d)));
    }
    out.colors.resize((h.flags & kColors) != 0 ? n : 0);
    if (!out.colors.empty()) RELIEF_RETURN_IF_ERROR(column(out.colors.data(), sizeof(Rgb8)));
    out.intensities.resize((h.flags & kIntensity) != 0 ? n : 0);
    if (!out.intensities.empty()) RELIEF_RETURN_IF_ERROR(column(out.intensities.data(), sizeof(float)));
    resize_las(out.las, n, h.las, h.extra_size);
    Status status;
    out.las.for_each_vector([&](auto& v, std::uint32_t) {
      if (status && !v.empty())
        status = column(v.data(), sizeof(typename std::decay_t<decltype(v)>::value_type));
    });
    RELIEF_RETURN_IF_ERROR(status);
    if (h.extra_size > 0) RELIEF_RETURN_IF_ERROR(column(out.las.extra_bytes.data(), h.extra_size));
    return Status::ok();
  }

  std::shared_ptr<const Spool> spool_;  // keeps the directory while this reads
  std::string path_;
  PointStreamInfo info_;
  int fd_ = -1;
  std::uint64_t size_ = 0;
  std::uint64_t next_ = 0;      // the next batch's header
  Header header_;               // the batch being read (points 0 before the first)
  std::uint64_t columns_ = 0;   // its columns' start
  std::uint64_t used_ = 0;      // its points handed out
  std::uint64_t released_ = 0;  // bytes before this are a hole (release_read)
  std::uint64_t release_bytes_;
  Vec3d offset_{0, 0, 0}, scale_{0, 0, 0};
  std::vector<std::int32_t> ints_;
  bool done_ = false;
};

}  // namespace

Result<std::shared_ptr<Spool>> Spool::create(const std::string& parent, std::vector<bool> wanted,
                                             std::size_t batch_points, std::uint64_t release_bytes) {
  std::shared_ptr<Spool> s(new Spool());
  s->release_bytes_ = std::max<std::uint64_t>(1, release_bytes);
  s->batch_points_ = std::max<std::size_t>(1, batch_points);
  RELIEF_ASSIGN_OR_RETURN(s->dir_, IngestTempDir::create(parent));
  s->finished_.assign(wanted.size(), false);
  s->infos_.resize(wanted.size());
  s->wanted_ = std::move(wanted);
  return s;
}

Spool::~Spool() {
  close_open();
  for (std::size_t i = 0; i < wanted_.size(); ++i) {
    if (wanted_[i]) ::unlink(file(i).c_str());
  }
}

std::string Spool::file(std::size_t input) const { return dir_.path() + "/input-" + std::to_string(input); }

void Spool::close_open() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

void Spool::abandon(const std::string& why) {
  if (!failure_.empty()) return;
  failure_ = why;
  close_open();
  for (std::size_t i = 0; i < wanted_.size(); ++i) {
    if (wanted_[i]) ::unlink(file(i).c_str());
  }
}

std::uint64_t Spool::point_bytes(const PointStreamInfo& info) {
  return 24 + (info.has_colors ? 3 : 0) + (info.has_intensity ? 4 : 0) +
         las_record_bytes(info.las_attributes, info.extra_bytes_size);
}

void Spool::append(std::size_t input, const PointCloud& batch, const Vec3d& offset, const Vec3d& scale) {
  if (!failure_.empty() || !wants(input) || batch.empty()) return;
  if (fd_ < 0 || fd_input_ != input) {
    close_open();
    const std::string path = file(input);
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0600);
    if (fd_ < 0) return abandon(path + ": cannot create: " + std::strerror(errno));
    fd_input_ = input;
  }
  const std::size_t n = batch.size();
  if (n > 0xFFFFFFFFu) return abandon("a batch of more than 2^32 points");
  Header h;
  h.points = static_cast<std::uint32_t>(n);
  h.flags = (batch.has_colors() ? kColors : 0u) | (batch.has_intensity() ? kIntensity : 0u);
  h.las = batch.las.carried();
  h.extra_size = (h.las & kLasExtraBytes) != 0 ? batch.las.extra_bytes_size : 0;
  if (((h.las & kLasExtraBytes) != 0 && h.extra_size == 0) || h.extra_size > 0xFFFF) {
    return abandon("extra bytes of an unexpected size");
  }
  // The LAS integers, when they give every coordinate back bit for bit.
  const double grid[6] = {offset.x, offset.y, offset.z, scale.x, scale.y, scale.z};
  if (scale.x > 0 && scale.y > 0 && scale.z > 0) {
    ints_.resize(3 * n);
    bool fits = true;
    const auto to_int = [&](double v, int a, std::int32_t& k) {
      const double t = std::nearbyint((v - grid[a]) / grid[3 + a]);
      if (!(std::fabs(t) <= 2147483647.0)) return false;
      k = static_cast<std::int32_t>(t);
      return true;
    };
    for (std::size_t i = 0; i < n && fits; ++i) {
      const Vec3d& p = batch.positions[i];
      fits = to_int(p.x, 0, ints_[3 * i]) && to_int(p.y, 1, ints_[3 * i + 1]) &&
             to_int(p.z, 2, ints_[3 * i + 2]);
    }
    if (fits) {
      check_.resize(n);
      positions_from_ints(ints_.data(), n, offset, scale, check_.data());
      fits = std::memcmp(check_.data(), batch.positions.data(), n * sizeof(Vec3d)) == 0;
    }
    if (fits) h.flags |= kIntPositions;
  }
  std::vector<iovec> iov;
  const auto add = [&](const void* p, std::size_t bytes) {
    if (bytes > 0) iov.push_back(iovec{const_cast<void*>(p), bytes});
  };
  add(&h, kHeaderBytes);
  if ((h.flags & kIntPositions) != 0) {
    add(grid, kGridBytes);
    add(ints_.data(), 12 * n);
  } else {
    add(batch.positions.data(), n * sizeof(Vec3d));
  }
  add(batch.colors.data(), batch.colors.size() * sizeof(Rgb8));
  add(batch.intensities.data(), batch.intensities.size() * sizeof(float));
  bool sized = (batch.colors.empty() || batch.colors.size() == n) &&
               (batch.intensities.empty() || batch.intensities.size() == n);
  batch.las.for_each_vector([&](const auto& v, std::uint32_t) {
    sized = sized && (v.empty() || v.size() == n);
    add(v.data(), v.size() * sizeof(typename std::decay_t<decltype(v)>::value_type));
  });
  sized = sized && batch.las.extra_bytes.size() == n * std::size_t{h.extra_size};
  if (!sized) return abandon("a batch whose attributes do not match its points");
  add(batch.las.extra_bytes.data(), batch.las.extra_bytes.size());
  std::uint64_t bytes = 0;
  for (const iovec& v : iov) bytes += v.iov_len;
  if (Status s = write_all(fd_, iov); !s) return abandon(file(input) + ": cannot write: " + s.message());
  bytes_written_ += bytes;
}

void Spool::finish(std::size_t input, const PointStreamInfo& info) {
  if (!failure_.empty() || !wants(input)) return;
  if (fd_ >= 0 && fd_input_ == input) close_open();
  // An input without a point still gets its (empty) file.
  const int fd = ::open(file(input).c_str(), O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0600);
  if (fd < 0) return abandon(file(input) + ": cannot create: " + std::strerror(errno));
  ::close(fd);
  infos_[input] = info;
  finished_[input] = true;
}

std::unique_ptr<PointReader> Spool::reader(std::size_t input) {
  return std::make_unique<SpoolReader>(shared_from_this(), file(input), infos_[input], release_bytes_);
}

}  // namespace relief::ingest
