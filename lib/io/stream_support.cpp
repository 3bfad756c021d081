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

void BatchPointReader::note_level_above_255(std::uint64_t point, std::uint16_t level, const char* label) {
  if (level_above_255_noted_ || color_shift_ != 0 || level <= 255) return;
  level_above_255_noted_ = true;
  const std::uint64_t sample = std::min(info_.point_count.value_or(kColorSamplePoints), kColorSamplePoints);
  std::string what = info_.path + ": " + label + " " + std::to_string(point) + " has the colour level " +
                     std::to_string(level) + " but the first " + std::to_string(sample) +
                     " points held none above 255, so the file is read as 8-bit levels";
  if (color_low_) {
    what += " stored in 16-bit fields";
    std::uint8_t colour = 0, low = 0;
    split_8bit_level(level, colour, low);
    what += ": such a level is kept exactly beside the 8-bit colour " + std::to_string(colour) +
            " (about level / 256), and LAS and LAZ output give it back when colour is exact (with a " +
            "colour tolerance, that colour)";
  } else {
    what += ": such a level is kept as 255";
  }
  info_.warnings.push_back(std::move(what));
}

void BatchPointReader::note_lost_low_bytes() {
  if (color_shift_ == 0 || color_low_) return;
  const std::uint64_t sample = std::min(info_.point_count.value_or(kColorSamplePoints), kColorSamplePoints);
  info_.warnings.push_back(info_.path + ": its colour levels are 16-bit (a level above 255 within its first " +
                           std::to_string(sample) + " points), but none came early enough for their low bytes to be " +
                           "kept: each level keeps its high byte (level >> 8)");
}

void BatchPointReader::note_levels_above_255(const std::uint16_t* wide, std::size_t n, std::uint64_t first) {
  if (level_above_255_noted_ || color_shift_ != 0) return;
  const std::size_t i = first_level_above_255(wide, n);
  if (i == n) return;
  note_level_above_255(first + i, std::max({wide[3 * i], wide[3 * i + 1], wide[3 * i + 2]}));
}

Result<bool> BatchPointReader::hold_sample(std::uint64_t sample) {
  // Positions 24 bytes, 16-bit levels 6, colours and low bytes 6, intensity
  // 4, the LAS attributes up to 22 (GPS time, NIR and the small ones).
  constexpr std::uint64_t kHeldBytesPerPoint = 64;
  if (sample > hold_bytes_ / (kHeldBytesPerPoint + info_.extra_bytes_size)) return false;
  std::vector<std::uint16_t> wide;
  RELIEF_ASSIGN_OR_RETURN(const std::size_t n, read_into(held_, &wide, 0, static_cast<std::size_t>(sample)));
  settle_rule(max_level(wide.data(), 3 * n));
  note_lost_low_bytes();
  narrow_into(held_, wide.data(), n);
  held_next_ = 0;
  return true;
}

void BatchPointReader::settle_rule(std::uint16_t largest) {
  color_shift_ = color_shift_for(largest);
  shift_known_ = true;
  info_.las_colors_8bit = color_low_ && color_shift_ == 0;
  info_.las_colors_all_zero =
      color_low_ && largest == 0 && info_.point_count.has_value() && *info_.point_count <= kColorSamplePoints;
}

void BatchPointReader::narrow_into(PointCloud& out, const std::uint16_t* wide, std::size_t n) const {
  out.colors.resize(n);
  if (color_low_) {
    out.las.color_low.resize(n);
    narrow_colors(wide, n, color_shift_, out.colors.data(), out.las.color_low.data());
  } else {
    narrow_colors(wide, n, color_shift_, out.colors.data());
  }
}

Result<std::size_t> BatchPointReader::read(PointCloud& batch, std::size_t max_points) {
  if (held_next_ < held_.size()) {
    const std::size_t n = std::min(max_points, held_.size() - held_next_);
    batch.assign_range(held_, held_next_, n);
    held_next_ += n;
    if (held_next_ == held_.size()) {
      held_ = PointCloud{};  // the memory goes back as soon as the sample is out
      held_next_ = 0;
    }
    return n;
  }
  if (!wide_colors_ || shift_known_) return read_into(batch, nullptr, 0, max_points);

  const std::uint64_t sample = std::min(info_.point_count.value_or(kColorSamplePoints), kColorSamplePoints);
  if (max_points < sample) {
    // Decoded once and held, when the caller allows the memory ...
    RELIEF_ASSIGN_OR_RETURN(const bool held, hold_sample(sample));
    if (held) return read(batch, max_points);
    // ... else decided through a second handle (the sample decoded twice).
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<BatchPointReader> probe, reopen());
    if (probe) {
      RELIEF_ASSIGN_OR_RETURN(const LevelSample s, probe->sample_levels(sample, false));
      settle_rule(s.max);
      note_lost_low_bytes();
      return read_into(batch, nullptr, 0, max_points);
    }
  }
  // The first batch holds the whole sample (or the input is a pipe).
  std::vector<std::uint16_t> wide;
  RELIEF_ASSIGN_OR_RETURN(const std::size_t n, read_into(batch, &wide, 0, max_points));
  const auto sampled = static_cast<std::size_t>(std::min<std::uint64_t>(n, sample));
  settle_rule(max_level(wide.data(), 3 * sampled));
  // Levels above 255 after the sample, in this first batch.
  note_levels_above_255(wide.data() + 3 * sampled, n - sampled, sampled);
  note_lost_low_bytes();
  narrow_into(batch, wide.data(), n);
  return n;
}

}  // namespace relief
