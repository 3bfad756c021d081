#include "io/stream_support.h"

namespace relief {

Result<std::uint16_t> BatchPointReader::sample_max_level(std::uint64_t sample) {
  // Decoding whole points is more work than the colours need, but only runs
  // when the caller's first batch is smaller than the sample.
  constexpr std::size_t kStep = std::size_t{1} << 16;
  PointCloud scratch;
  std::vector<std::uint16_t> wide;
  std::uint16_t max = 0;
  std::uint64_t seen = 0;
  while (seen < sample) {
    const auto want = static_cast<std::size_t>(std::min<std::uint64_t>(kStep, sample - seen));
    RELIEF_ASSIGN_OR_RETURN(const std::size_t n, read_into(scratch, &wide, 0, want));
    if (n == 0) break;
    max = std::max(max, max_level(wide.data(), 3 * n));
    seen += n;
  }
  return max;
}

Result<bool> BatchPointReader::decide_color_shift_now() {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<BatchPointReader> probe, reopen());
  if (!probe) return false;
  const std::uint64_t sample = std::min(info_.point_count.value_or(kColorSamplePoints), kColorSamplePoints);
  RELIEF_ASSIGN_OR_RETURN(const std::uint16_t max, probe->sample_max_level(sample));
  color_shift_ = color_shift_for(max);
  shift_known_ = true;
  return true;
}

Result<std::size_t> BatchPointReader::read(PointCloud& batch, std::size_t max_points) {
  if (!wide_colors_ || shift_known_) return read_into(batch, nullptr, 0, max_points);

  const std::uint64_t sample = std::min(info_.point_count.value_or(kColorSamplePoints), kColorSamplePoints);
  if (max_points < sample) {
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<BatchPointReader> probe, reopen());
    if (probe) {
      RELIEF_ASSIGN_OR_RETURN(const std::uint16_t max, probe->sample_max_level(sample));
      color_shift_ = color_shift_for(max);
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
