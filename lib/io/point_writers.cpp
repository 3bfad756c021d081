// Batch bookkeeping shared by the streaming writers, and the text encoder of
// ascii PLY and XYZ.

#include "io/point_writers.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
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

int grid_decimals(double step, double origin) {
  if (!std::isfinite(step) || !std::isfinite(origin) || step <= 0) return -1;
  double ten = 1;  // 10^k
  for (int k = 0; k <= 9; ++k, ten *= 10) {
    if (std::fabs(step * ten - 1) > 1e-9) continue;
    const double o = origin * ten;  // the origin in steps
    if (!(std::fabs(o) < 0x1p52)) return -1;
    return std::fabs(o - std::nearbyint(o)) <= 1e-6 ? k : -1;
  }
  return -1;
}

CoordinateText coordinate_text(const WriterOptions& options) {
  CoordinateText t;
  if (!options.grid_scale) return t;
  const Vec3d& s = *options.grid_scale;
  const Vec3d o = options.grid_offset.value_or(Vec3d{0, 0, 0});
  t.decimals[0] = grid_decimals(s.x, o.x);
  t.decimals[1] = grid_decimals(s.y, o.y);
  t.decimals[2] = grid_decimals(s.z, o.z);
  return t;
}

std::uint8_t* put_coordinate(std::uint8_t* p, double v, int decimals) {
  static constexpr double kPow10[10] = {1, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
  if (decimals < 0 || decimals > 9) return put_shortest(p, v);
  const double scaled = std::nearbyint(v * kPow10[decimals]);
  if (!(std::fabs(scaled) < 0x1p53)) return put_shortest(p, v);  // NaN, Inf, beyond the digits
  const auto n = static_cast<std::int64_t>(scaled);
  // |n| < 2^53 has at most 16 digits: with a sign, a point and leading zeros
  // below 1 (0.000000001) at most 19 characters.
  if (n < 0) *p++ = '-';
  const std::uint64_t m = n < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(n) : static_cast<std::uint64_t>(n);
  char digits[24];
  const int len = static_cast<int>(std::to_chars(digits, digits + sizeof digits, m).ptr - digits);
  // The integer part: the digits above the last `decimals`, or 0.
  const int whole = len - decimals;
  if (whole <= 0) {
    *p++ = '0';
  } else {
    std::memcpy(p, digits, static_cast<std::size_t>(whole));
    p += whole;
  }
  if (decimals == 0) return p;
  *p++ = '.';
  for (int z = whole; z < 0; ++z) *p++ = '0';
  const int from = whole < 0 ? 0 : whole;
  std::memcpy(p, digits + from, static_cast<std::size_t>(len - from));
  return p + (len - from);
}

std::uint8_t* put_text_point(std::uint8_t* p, const PointCloud& batch, std::size_t i, const WriterOptions& options,
                             const CoordinateText& coords, std::uint8_t sep, bool colors16) {
  const Vec3d& v = batch.positions[i];
  p = put_coordinate(p, v.x, coords.decimals[0]);
  *p++ = sep;
  p = put_coordinate(p, v.y, coords.decimals[1]);
  *p++ = sep;
  p = put_coordinate(p, v.z, coords.decimals[2]);
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
