// Batch bookkeeping shared by the streaming writers, and the text encoder of
// ascii PLY and XYZ.

#include "io/point_writers.h"

#include <algorithm>
#include <cmath>
#include <span>
#include <string>

namespace relief {

namespace {

// Decimal text of a colour level, without to_chars' generality.
std::uint8_t* put_level(std::uint8_t* p, std::uint8_t v) {
  if (v >= 100) *p++ = static_cast<std::uint8_t>('0' + v / 100);
  if (v >= 10) *p++ = static_cast<std::uint8_t>('0' + v / 10 % 10);
  *p++ = static_cast<std::uint8_t>('0' + v % 10);
  return p;
}

std::string count_text(std::size_t n, const char* one, const char* many) {
  return std::to_string(n) + " " + (n == 1 ? one : many);
}

}  // namespace

Status StreamPointWriter::point_error(std::uint64_t index, const std::string& what) const {
  return invalid_argument(out_->path() + ": point " + std::to_string(index) + " " + what);
}

Status StreamPointWriter::check_batch(const PointCloud& batch) const {
  const std::size_t n = batch.size();
  const std::string& path = out_->path();
  const std::string points = count_text(n, "point", "points");
  // A mismatch is a bug in the caller, which chose the options: dropping or
  // inventing attributes silently would hide it.
  if (options_.colors && batch.colors.size() != n) {
    return invalid_argument(path + ": a batch of " + points + " has " +
                            count_text(batch.colors.size(), "colour", "colours") +
                            " but the writer was opened with colours");
  }
  if (!options_.colors && !batch.colors.empty()) {
    return invalid_argument(path + ": a batch has colours but the writer was opened without them");
  }
  if (options_.intensity && batch.intensities.size() != n) {
    return invalid_argument(path + ": a batch of " + points + " has " +
                            count_text(batch.intensities.size(), "intensity", "intensities") +
                            " but the writer was opened with intensity");
  }
  if (!options_.intensity && !batch.intensities.empty()) {
    return invalid_argument(path + ": a batch has intensities but the writer was opened without them");
  }
  if (!checks_coordinates()) {
    for (std::size_t i = 0; i < n; ++i) {
      const Vec3d& p = batch.positions[i];
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
        return point_error(count_ + i, "has a non-finite coordinate (NaN or Inf)");
      }
    }
  }
  for (std::size_t i = 0; i < batch.intensities.size(); ++i) {
    if (!std::isfinite(batch.intensities[i])) {
      return point_error(count_ + i, "has a non-finite intensity (NaN or Inf)");
    }
  }
  return Status::ok();
}

Status StreamPointWriter::fail(Status status) {
  error_ = status;
  out_->discard();
  return status;
}

Status StreamPointWriter::write(const PointCloud& batch) {
  if (!error_.is_ok()) return error_;
  if (finished_) return invalid_argument(out_->path() + ": write() after finish()");
  Status s = check_batch(batch);
  if (s.is_ok()) s = write_points(batch);
  if (!s.is_ok()) return fail(std::move(s));
  count_ += batch.size();
  return Status::ok();
}

Status StreamPointWriter::finish() {
  if (!error_.is_ok()) return error_;
  if (finished_) return invalid_argument(out_->path() + ": finish() called twice");
  finished_ = true;
  Status s = complete();
  if (s.is_ok()) s = out_->commit();
  if (!s.is_ok()) return fail(std::move(s));
  return Status::ok();
}

std::uint8_t* put_text_point(std::uint8_t* p, const PointCloud& batch, std::size_t i, const WriterOptions& options,
                             std::uint8_t sep, bool colors16) {
  const Vec3d& v = batch.positions[i];
  p = put_shortest(p, v.x);
  *p++ = sep;
  p = put_shortest(p, v.y);
  *p++ = sep;
  p = put_shortest(p, v.z);
  if (options.colors && colors16) {
    const Rgb8& c = batch.colors[i];
    const Rgb8& low = batch.las.color_low[i];
    for (const auto& [hi, lo] : {std::pair{c.r, low.r}, std::pair{c.g, low.g}, std::pair{c.b, low.b}}) {
      *p++ = sep;
      p = put_integer(p, static_cast<unsigned>(hi) << 8 | lo);
    }
  } else if (options.colors) {
    const Rgb8& c = batch.colors[i];
    *p++ = sep;
    p = put_level(p, c.r);
    *p++ = sep;
    p = put_level(p, c.g);
    *p++ = sep;
    p = put_level(p, c.b);
  }
  if (options.intensity) {
    *p++ = sep;
    p = put_shortest(p, batch.intensities[i]);
  }
  return p;
}

Status write_text_points(OutputFile& out, const PointCloud& batch, const WriterOptions& options,
                         char separator) {
  return write_text_lines(out, batch, options, separator, 0, [](std::uint8_t* p, std::size_t) { return p; });
}

}  // namespace relief
