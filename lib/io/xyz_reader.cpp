// ASCII XYZ / CSV / PTS reader: one point per line, columns as
// ReaderOptions::xyz_columns says.
//
// Separators: blanks always separate columns (runs count as one). The first
// data line also picks one punctuation delimiter, ';' if it has one, else ','
// if it has one; that character then separates columns too, once per gap, so
// "1,,3" has an empty middle column. Picking one per file matters for European
// CSV, where "1,5;2,5;3,5" must not be read as six columns.
//
// Skipped: blank lines, comment lines (first non-blank characters '#' or
// "//"), a UTF-8 byte order mark, and on the first non-comment line either a
// header (its first column is not a number) or a Leica PTS point count (a
// single integer). Columns after the last one the spec uses are ignored.

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "io/byte_source.h"
#include "io/readers.h"
#include "io/stream_support.h"
#include "io/text_scan.h"
#include "relief/io.h"

namespace relief {

namespace {

// A point line is short; a line this long is not one (binary junk, say).
constexpr std::size_t kMaxLine = std::size_t{1} << 20;

enum class Role : std::uint8_t { kSkip, kX, kY, kZ, kRed, kGreen, kBlue, kIntensity };

struct ColumnPlan {
  std::vector<Role> roles;  // up to the last used column
  bool colors = false;
  bool intensity = false;
};

Result<ColumnPlan> parse_columns(const std::string& spec, const std::string& name) {
  const std::string where = name + ": column spec '" + spec + "': ";
  ColumnPlan plan;
  std::array<int, 8> seen{};
  std::size_t pos = 0;
  for (;;) {
    const std::size_t comma = std::min(spec.find(',', pos), spec.size());
    std::string_view tok(spec.data() + pos, comma - pos);
    while (!tok.empty() && is_blank(tok.front())) tok.remove_prefix(1);
    while (!tok.empty() && is_blank(tok.back())) tok.remove_suffix(1);
    Role role = Role::kSkip;
    if (tok == "x" || tok == "X") {
      role = Role::kX;
    } else if (tok == "y" || tok == "Y") {
      role = Role::kY;
    } else if (tok == "z" || tok == "Z") {
      role = Role::kZ;
    } else if (tok == "r" || tok == "R") {
      role = Role::kRed;
    } else if (tok == "g" || tok == "G") {
      role = Role::kGreen;
    } else if (tok == "b" || tok == "B") {
      role = Role::kBlue;
    } else if (tok == "i" || tok == "I") {
      role = Role::kIntensity;
    } else if (tok != "_") {
      return invalid_argument(where + "unknown column " + quoted(tok) +
                              " (use x y z r g b i or _, comma separated)");
    }
    if (role != Role::kSkip && ++seen[static_cast<std::size_t>(role)] > 1) {
      return invalid_argument(where + "column " + quoted(tok) + " appears twice");
    }
    plan.roles.push_back(role);
    if (comma == spec.size()) break;
    pos = comma + 1;
  }
  auto has = [&](Role r) { return seen[static_cast<std::size_t>(r)] > 0; };
  if (!has(Role::kX) || !has(Role::kY) || !has(Role::kZ)) {
    return invalid_argument(where + "it must name the x, y and z columns");
  }
  const int rgb = static_cast<int>(has(Role::kRed)) + static_cast<int>(has(Role::kGreen)) +
                  static_cast<int>(has(Role::kBlue));
  if (rgb != 0 && rgb != 3) return invalid_argument(where + "r, g and b go together (all or none)");
  plan.colors = rgb == 3;
  plan.intensity = has(Role::kIntensity);
  while (plan.roles.back() == Role::kSkip) plan.roles.pop_back();  // x is there, so this stops
  return plan;
}

// Parses all of `tok` as a number; from_chars rejects the '+' printf may emit.
bool parse_number(std::string_view tok, double& out) {
  const char* first = tok.data();
  const char* const last = tok.data() + tok.size();
  if (last - first > 1 && *first == '+' && first[1] != '-' && first[1] != '+') ++first;
  const auto [p, ec] = std::from_chars(first, last, out);
  return ec == std::errc{} && p == last && first != last;
}

bool is_comment(std::string_view line) {
  std::size_t i = 0;
  while (i < line.size() && is_blank(line[i])) ++i;
  const std::string_view rest = line.substr(i);
  return rest.starts_with('#') || rest.starts_with("//");
}

bool is_blank_line(std::string_view line) {
  return std::all_of(line.begin(), line.end(), [](char c) { return is_blank(c); });
}

class XyzPointReader final : public PointReader {
 public:
  XyzPointReader(std::string name, ByteSource src, ColumnPlan plan)
      : src_(std::move(src)), plan_(std::move(plan)) {
    info_.path = std::move(name);
    info_.format = "xyz";
    info_.has_colors = plan_.colors;
    info_.has_intensity = plan_.intensity;
  }

  const PointStreamInfo& info() const override { return info_; }
  Result<std::size_t> read(PointCloud& batch, std::size_t max_points) override;

 private:
  const std::string& name() const { return info_.path; }
  Status line_error(const std::string& what) const {
    return format_error(name() + ": line " + std::to_string(line_no_) + ": " + what);
  }
  // Handles the first line that is neither blank nor a comment; sets `skip`
  // when it is a header or a PTS count rather than a point.
  void first_content_line(std::string_view line, bool& skip);
  Status parse_point(std::string_view line, PointCloud& batch);

  ByteSource src_;
  ColumnPlan plan_;
  PointStreamInfo info_;
  std::uint64_t line_no_ = 0;
  bool seen_content_ = false;
  bool delimiter_known_ = false;
  char delimiter_ = ' ';  // ' ' means blanks only
};

void XyzPointReader::first_content_line(std::string_view line, bool& skip) {
  seen_content_ = true;
  std::size_t i = 0;
  while (i < line.size() && is_blank(line[i])) ++i;
  std::size_t end = i;
  while (end < line.size() && !is_blank(line[end]) && line[end] != ',' && line[end] != ';') ++end;
  double value = 0;
  const std::string_view first = line.substr(i, end - i);
  if (!parse_number(first, value)) {
    skip = true;  // a header such as "x,y,z,red,green,blue"
    return;
  }
  std::size_t rest = end;
  while (rest < line.size() && is_blank(line[rest])) ++rest;
  if (rest == line.size() && plan_.roles.size() > 1 &&
      first.find_first_not_of("0123456789") == std::string_view::npos) {
    skip = true;  // a Leica PTS file starts with its point count alone on a line
  }
}

Status XyzPointReader::parse_point(std::string_view line, PointCloud& batch) {
  double v[8] = {};
  std::size_t pos = 0;
  while (pos < line.size() && is_blank(line[pos])) ++pos;
  const std::size_t columns = plan_.roles.size();
  for (std::size_t c = 0; c < columns; ++c) {
    if (pos >= line.size()) {
      return line_error("expected at least " + std::to_string(columns) + " columns but found " +
                        std::to_string(c));
    }
    const std::size_t start = pos;
    while (pos < line.size() && !is_blank(line[pos]) && line[pos] != delimiter_) ++pos;
    const std::string_view tok = line.substr(start, pos - start);
    while (pos < line.size() && is_blank(line[pos])) ++pos;
    if (pos < line.size() && line[pos] == delimiter_) {
      ++pos;
      while (pos < line.size() && is_blank(line[pos])) ++pos;
    }
    const Role role = plan_.roles[c];
    if (role == Role::kSkip) continue;
    double value = 0;
    if (!parse_number(tok, value)) {
      return line_error("column " + std::to_string(c + 1) + " " +
                        (tok.empty() ? std::string("is empty") : quoted(tok) + " is not a number"));
    }
    v[static_cast<std::size_t>(role)] = value;
  }
  const Vec3d p{v[static_cast<std::size_t>(Role::kX)], v[static_cast<std::size_t>(Role::kY)],
                v[static_cast<std::size_t>(Role::kZ)]};
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
    return line_error("non-finite coordinate (" + format_double(p.x) + ", " + format_double(p.y) + ", " +
                      format_double(p.z) + ")");
  }
  Rgb8 color;
  if (plan_.colors) {
    std::uint8_t levels[3] = {};
    const Role roles[3] = {Role::kRed, Role::kGreen, Role::kBlue};
    for (int k = 0; k < 3; ++k) {
      const double level = v[static_cast<std::size_t>(roles[k])];
      if (!(level >= 0 && level <= 255)) {
        return line_error("colour level " + format_double(level) + " is outside 0..255");
      }
      levels[k] = static_cast<std::uint8_t>(std::lround(level));
    }
    color = {levels[0], levels[1], levels[2]};
  }
  float intensity = 0;
  if (plan_.intensity) {
    const double raw = v[static_cast<std::size_t>(Role::kIntensity)];
    // Converting a double beyond the float range is undefined; reject it first.
    if (!std::isfinite(raw) || std::abs(raw) > std::numeric_limits<float>::max()) {
      return line_error("intensity " + format_double(raw) + " is not a finite float");
    }
    intensity = static_cast<float>(raw);
  }
  batch.positions.push_back(p);
  if (plan_.colors) batch.colors.push_back(color);
  if (plan_.intensity) batch.intensities.push_back(intensity);
  return Status::ok();
}

Result<std::size_t> XyzPointReader::read(PointCloud& batch, std::size_t max_points) {
  size_batch(batch, 0, plan_.colors, plan_.intensity);  // keeps the capacity
  std::size_t got = 0;
  while (got < max_points) {
    std::string_view line;
    LineStatus state = LineStatus::kEnd;
    RELIEF_RETURN_IF_ERROR(next_line(src_, kMaxLine, line, state));
    if (state == LineStatus::kEnd) break;
    ++line_no_;
    if (state == LineStatus::kTooLong) {
      return line_error("line longer than " + std::to_string(kMaxLine) + " bytes");
    }
    if (line_no_ == 1 && line.starts_with("\xEF\xBB\xBF")) line.remove_prefix(3);
    if (is_blank_line(line) || is_comment(line)) continue;
    if (!seen_content_) {
      bool skip = false;
      first_content_line(line, skip);
      if (skip) continue;
    }
    if (!delimiter_known_) {
      // The first data line picks the delimiter (see the top of the file).
      delimiter_known_ = true;
      if (line.find(';') != std::string_view::npos) {
        delimiter_ = ';';
      } else if (line.find(',') != std::string_view::npos) {
        delimiter_ = ',';
      }
    }
    RELIEF_RETURN_IF_ERROR(parse_point(line, batch));
    ++got;
  }
  return got;
}

}  // namespace

Result<std::unique_ptr<PointReader>> open_xyz_reader(const InputSpec& input, const ReaderOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(ColumnPlan plan, parse_columns(options.xyz_columns, input.name));
  RELIEF_ASSIGN_OR_RETURN(ByteSource src, input.open());
  return std::unique_ptr<PointReader>(new XyzPointReader(input.name, std::move(src), std::move(plan)));
}

}  // namespace relief
