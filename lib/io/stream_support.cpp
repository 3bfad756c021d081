#include "io/stream_support.h"

namespace relief {

Result<BatchPointReader::LevelSample> BatchPointReader::sample_levels(std::uint64_t sample, bool stop_when_wide) {
  // Decoding whole points is more work than the colours need, but only runs
  // when the caller's first batch is smaller than the sample.
  constexpr std::size_t kStep = std::size_t{1} << 16;
  PointCloud scratch;
  std::vector<std::uint16_t> wide;
  LevelSample s;
  while (s.points < sample && !(stop_when_wide && s.max > 255)) {
    const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(kStep, sample - s.points));
    RELIEF_ASSIGN_OR_RETURN(const std::size_t n, read_into(scratch, &wide, 0, want));
    if (n == 0) {
      s.whole = true;
      break;
    }
    s.max = std::max(s.max, max_level(wide.data(), 3 * n));
    s.points += n;
  }
  return s;
}

Result<bool> BatchPointReader::decide_color_shift_now(std::uint64_t within) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<BatchPointReader> probe, reopen());
  if (!probe) return false;
  const std::uint64_t sample = std::min(info_.point_count.value_or(kColorSamplePoints), kColorSamplePoints);
  RELIEF_ASSIGN_OR_RETURN(const LevelSample s, probe->sample_levels(std::min(within, sample), true));
  // A level above 255 decides for 16 bits whatever follows; none decides
  // for 8 only when the rule's whole sample was seen.
  if (s.max <= 255 && !s.whole && s.points < sample) return false;
  color_shift_ = color_shift_for(s.max);
  shift_known_ = true;
  return true;
}

Result<std::size_t> BatchPointReader::read(PointCloud& batch, std::size_t max_points) {
  if (!wide_colors_ || shift_known_) return read_into(batch, nullptr, 0, max_points);

  const std::uint64_t sample = std::min(info_.point_count.value_or(kColorSamplePoints), kColorSamplePoints);
  if (max_points < sample) {
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<BatchPointReader> probe, reopen());
    if (probe) {
      RELIEF_ASSIGN_OR_RETURN(const LevelSample s, probe->sample_levels(sample, false));
      color_shift_ = color_shift_for(s.max);
      shift_known_ = true;
      info_.las_colors_8bit = color_low_ && color_shift_ == 0;
      return read_into(batch, nullptr, 0, max_points);
    }
  }
  // The first batch holds the whole sample (or the input is a pipe).
  std::vector<std::uint16_t> wide;
  RELIEF_ASSIGN_OR_RETURN(const std::size_t n, read_into(batch, &wide, 0, max_points));
  const auto sampled = static_cast<std::size_t>(std::min<std::uint64_t>(n, sample));
  color_shift_ = color_shift_for(max_level(wide.data(), 3 * sampled));
  shift_known_ = true;
  info_.las_colors_8bit = color_low_ && color_shift_ == 0;
  batch.colors.resize(n);
  if (color_low_) {
    batch.las.color_low.resize(n);
    narrow_colors(wide.data(), n, color_shift_, batch.colors.data(), batch.las.color_low.data());
  } else {
    narrow_colors(wide.data(), n, color_shift_, batch.colors.data());
  }
  return n;
}

}  // namespace relief
