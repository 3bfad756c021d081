// ASCII XYZ / CSV / PTS reader: one point per line, columns as
// ReaderOptions::xyz_columns says, or else as a header line names them, or
// else x y z.
//
// Header names: the first non-comment line when its first column is not a
// number, or else the last comment line before the data (CloudCompare writes
// "//X,Y,Z,R,G,B") when it names x, y and z. Names match in any case, with
// quotes and a leading '#' or "//" removed: x y z; red green blue (or r g b,
// diffuse_red ...); intensity (or i, reflectance, scalar_intensity);
// classification (or class, scalar_classification: LAS classes 0..255, into
// PointCloud::las.classification). Other names (normals, time ...) are
// skipped columns, listed in a warning (PLY, PCD and LAS inputs keep such
// values as extra bytes; text gives no types to keep them by). A header
// that does not name x, y and z leaves the columns at x y z.
//
// Colour levels may be 8- or 16-bit: text declares no type, so the file-wide
// 16-bit rule of the binary formats applies (io/stream_support.h): every
// level is shifted right by 8 when the first 2^20 points hold a level above
// 255, a decision that does not depend on the caller's batch size.
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

#include <cctype>
#include <optional>

#include "io/byte_source.h"
#include "io/readers.h"
#include "io/stream_support.h"
#include "io/text_scan.h"
#include "relief/io.h"

namespace relief {

namespace {

// A point line is short; a line this long is not one (binary junk, say).
constexpr std::size_t kMaxLine = std::size_t{1} << 20;

enum class Role : std::uint8_t { kSkip, kX, kY, kZ, kRed, kGreen, kBlue, kIntensity, kClass };
constexpr std::size_t kRoleCount = 9;
// Classification values are LAS classes, 0..255.
constexpr double kMaxClass = 255;

struct ColumnPlan {
  std::vector<Role> roles;  // up to the last used column
  bool colors = false;
  bool intensity = false;
  bool classification = false;
  // Header names of the columns not read (a warning lists them).
  std::vector<std::string> unread;
};

Result<ColumnPlan> parse_columns(const std::string& spec, const std::string& name) {
  const std::string where = name + ": column spec '" + spec + "': ";
  ColumnPlan plan;
  std::array<int, kRoleCount> seen{};
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
    } else if (tok == "c" || tok == "C") {
      role = Role::kClass;
    } else if (tok != "_") {
      return invalid_argument(where + "unknown column " + quoted(tok) +
                              " (use x y z r g b i c or _, comma separated)");
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
  plan.classification = has(Role::kClass);
  while (plan.roles.back() == Role::kSkip) plan.roles.pop_back();  // x is there, so this stops
  return plan;
}

// The role a header name gives its column, if any.
std::optional<Role> role_of_name(std::string_view name) {
  std::string n;
  for (const char c : name) {
    if (c != '"' && c != '\'') n.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  }
  while (n.starts_with('#') || n.starts_with("//")) n.erase(0, n.starts_with('#') ? 1 : 2);
  if (n == "x") return Role::kX;
  if (n == "y") return Role::kY;
  if (n == "z") return Role::kZ;
  if (n == "red" || n == "r" || n == "diffuse_red") return Role::kRed;
  if (n == "green" || n == "g" || n == "diffuse_green") return Role::kGreen;
  if (n == "blue" || n == "b" || n == "diffuse_blue") return Role::kBlue;
  if (n == "intensity" || n == "i" || n == "reflectance" || n == "scalar_intensity") return Role::kIntensity;
  if (n == "classification" || n == "class" || n == "scalar_classification") return Role::kClass;
  return std::nullopt;
}

// Columns from a header line, when it names x, y and z. Separators: blanks,
// ',' and ';'. A name seen twice keeps its first column.
std::optional<ColumnPlan> plan_from_header(std::string_view line) {
  ColumnPlan plan;
  std::vector<std::string> names;  // per column, as the header gives it
  std::array<bool, kRoleCount> seen{};
  std::size_t pos = 0;
  while (pos < line.size()) {
    while (pos < line.size() && is_blank(line[pos])) ++pos;
    if (pos == line.size()) break;
    std::size_t end = pos;
    while (end < line.size() && !is_blank(line[end]) && line[end] != ',' && line[end] != ';') ++end;
    const std::string_view name = line.substr(pos, end - pos);
    const std::optional<Role> role = role_of_name(name);
    Role r = Role::kSkip;
    if (role && !seen[static_cast<std::size_t>(*role)]) {
      r = *role;
      seen[static_cast<std::size_t>(r)] = true;
    }
    plan.roles.push_back(r);
    names.emplace_back(name);
    pos = end;
    while (pos < line.size() && is_blank(line[pos])) ++pos;
    if (pos < line.size() && (line[pos] == ',' || line[pos] == ';')) ++pos;
  }
  auto has = [&](Role r) { return seen[static_cast<std::size_t>(r)]; };
  if (!has(Role::kX) || !has(Role::kY) || !has(Role::kZ)) return std::nullopt;
  plan.colors = has(Role::kRed) && has(Role::kGreen) && has(Role::kBlue);
  if (!plan.colors) {
    for (Role& r : plan.roles) {
      if (r == Role::kRed || r == Role::kGreen || r == Role::kBlue) r = Role::kSkip;  // a partial set
    }
  }
  plan.intensity = has(Role::kIntensity);
  plan.classification = has(Role::kClass);
  for (std::size_t c = 0; c < names.size(); ++c) {
    if (plan.roles[c] == Role::kSkip && !names[c].empty()) plan.unread.push_back(names[c]);
  }
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

// The largest 16-bit colour level.
constexpr double kMaxWideLevel = 65535;

bool is_point_count(std::string_view line, std::string_view first) {
  std::size_t rest = first.data() - line.data() + first.size();
  while (rest < line.size() && is_blank(line[rest])) ++rest;
  return rest == line.size() && first.find_first_not_of("0123456789") == std::string_view::npos;
}

// The first column of `line` (up to a blank, ',' or ';').
std::string_view first_column(std::string_view line) {
  std::size_t i = 0;
  while (i < line.size() && is_blank(line[i])) ++i;
  std::size_t end = i;
  while (end < line.size() && !is_blank(line[end]) && line[end] != ',' && line[end] != ';') ++end;
  return line.substr(i, end - i);
}

class XyzPointReader final : public BatchPointReader {
 public:
  // Reads up to the first data line and settles the columns.
  static Result<std::unique_ptr<XyzPointReader>> open(const InputSpec& input, const ReaderOptions& options) {
    std::optional<ColumnPlan> explicit_plan;
    if (options.xyz_columns) {
      RELIEF_ASSIGN_OR_RETURN(ColumnPlan p, parse_columns(*options.xyz_columns, input.name));
      explicit_plan = std::move(p);
    }
    RELIEF_ASSIGN_OR_RETURN(ByteSource src, input.open());
    std::unique_ptr<XyzPointReader> r(new XyzPointReader(input, options, std::move(src)));
    RELIEF_RETURN_IF_ERROR(r->start(std::move(explicit_plan)));
    return r;
  }

  Result<std::size_t> read_into(PointCloud& out, std::vector<std::uint16_t>* wide, std::size_t at,
                                std::size_t max_points) override;

 protected:
  Result<std::unique_ptr<BatchPointReader>> reopen() const override {
    // A pipe cannot be read twice; a regular file or memory can.
    if (!input_.memory && !src_.size()) return std::unique_ptr<BatchPointReader>();
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<XyzPointReader> again, open(input_, options_));
    return std::unique_ptr<BatchPointReader>(std::move(again));
  }

 private:
  XyzPointReader(InputSpec input, ReaderOptions options, ByteSource src)
      : input_(std::move(input)), options_(std::move(options)), src_(std::move(src)) {
    info_.path = input_.name;
    info_.format = "xyz";
  }

  const std::string& name() const { return info_.path; }
  Status line_error(std::uint64_t line_no, const std::string& what) const {
    return format_error(name() + ": line " + std::to_string(line_no) + ": " + what);
  }
  Status start(std::optional<ColumnPlan> explicit_plan);
  // Next line that is neither blank nor a comment; `line` empty at the end.
  Status next_content_line(std::string_view& line, bool& end, std::string* last_comment_header);
  Status parse_point(std::string_view line, std::uint64_t line_no, PointCloud& out,
                     std::vector<std::uint16_t>* wide);

  InputSpec input_;
  ReaderOptions options_;
  ByteSource src_;
  ColumnPlan plan_;
  std::uint64_t line_no_ = 0;
  std::string pending_;  // the first data line, read by start()
  std::uint64_t pending_line_no_ = 0;
  bool has_pending_ = false;
  bool delimiter_known_ = false;
  char delimiter_ = ' ';  // ' ' means blanks only
};

Status XyzPointReader::next_content_line(std::string_view& line, bool& end, std::string* last_comment_header) {
  end = false;
  for (;;) {
    LineStatus state = LineStatus::kEnd;
    RELIEF_RETURN_IF_ERROR(next_line(src_, kMaxLine, line, state));
    if (state == LineStatus::kEnd) {
      end = true;
      return Status::ok();
    }
    ++line_no_;
    if (state == LineStatus::kTooLong) {
      return line_error(line_no_, "line longer than " + std::to_string(kMaxLine) + " bytes");
    }
    if (line_no_ == 1 && line.starts_with("\xEF\xBB\xBF")) line.remove_prefix(3);
    if (is_blank_line(line)) continue;
    if (is_comment(line)) {
      if (last_comment_header != nullptr && plan_from_header(line)) last_comment_header->assign(line);
      continue;
    }
    return Status::ok();
  }
}

Status XyzPointReader::start(std::optional<ColumnPlan> explicit_plan) {
  std::string comment_header;
  std::string_view line;
  bool end = false;
  RELIEF_RETURN_IF_ERROR(next_content_line(line, end, &comment_header));
  std::optional<ColumnPlan> header_plan;
  if (!end) {
    double value = 0;
    const std::string_view first = first_column(line);
    if (!parse_number(first, value)) {
      header_plan = plan_from_header(line);  // a header such as "x,y,z,red,green,blue"
      RELIEF_RETURN_IF_ERROR(next_content_line(line, end, nullptr));
    } else if (is_point_count(line, first)) {
      // A Leica PTS file starts with its point count alone on a line.
      RELIEF_RETURN_IF_ERROR(next_content_line(line, end, nullptr));
    }
  }
  if (!end) {
    pending_.assign(line);
    pending_line_no_ = line_no_;
    has_pending_ = true;
  }
  if (!header_plan && !comment_header.empty()) header_plan = plan_from_header(comment_header);
  if (explicit_plan) {
    plan_ = std::move(*explicit_plan);  // the caller's columns win over a header
  } else if (header_plan) {
    plan_ = std::move(*header_plan);
    if (!plan_.unread.empty()) {
      std::string names;
      for (const std::string& n : plan_.unread) names += (names.empty() ? "" : ", ") + quoted(n);
      info_.warnings.push_back(name() + ": header column" + (plan_.unread.size() > 1 ? "s " : " ") + names +
                               (plan_.unread.size() > 1 ? " are" : " is") +
                               " not kept (text inputs keep x, y, z, colour, intensity and classification; "
                               "PLY, PCD and LAS keep every per-point value)");
    }
  } else {
    RELIEF_ASSIGN_OR_RETURN(plan_, parse_columns("x,y,z", name()));
  }
  info_.has_colors = plan_.colors;
  info_.has_intensity = plan_.intensity;
  info_.las_attributes = plan_.classification ? std::uint32_t{kLasClassification} : 0u;
  wide_colors_ = plan_.colors;  // levels may be 16-bit (see the top of the file)
  return Status::ok();
}

Status XyzPointReader::parse_point(std::string_view line, std::uint64_t line_no, PointCloud& out,
                                   std::vector<std::uint16_t>* wide) {
  double v[kRoleCount] = {};
  std::size_t pos = 0;
  while (pos < line.size() && is_blank(line[pos])) ++pos;
  const std::size_t columns = plan_.roles.size();
  for (std::size_t c = 0; c < columns; ++c) {
    if (pos >= line.size()) {
      return line_error(line_no, "expected at least " + std::to_string(columns) + " columns but found " +
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
      return line_error(line_no, "column " + std::to_string(c + 1) + " " +
                                     (tok.empty() ? std::string("is empty") : quoted(tok) + " is not a number"));
    }
    v[static_cast<std::size_t>(role)] = value;
  }
  const Vec3d p{v[static_cast<std::size_t>(Role::kX)], v[static_cast<std::size_t>(Role::kY)],
                v[static_cast<std::size_t>(Role::kZ)]};
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
    return line_error(line_no, "non-finite coordinate (" + format_double(p.x) + ", " + format_double(p.y) + ", " +
                                   format_double(p.z) + ")");
  }
  std::uint16_t levels[3] = {};
  if (plan_.colors) {
    const Role roles[3] = {Role::kRed, Role::kGreen, Role::kBlue};
    for (int k = 0; k < 3; ++k) {
      const double level = v[static_cast<std::size_t>(roles[k])];
      if (!(level >= 0 && level <= kMaxWideLevel)) {
        return line_error(line_no, "colour level " + format_double(level) + " is outside 0..65535");
      }
      levels[k] = static_cast<std::uint16_t>(std::lround(level));
    }
  }
  float intensity = 0;
  if (plan_.intensity) {
    const double raw = v[static_cast<std::size_t>(Role::kIntensity)];
    // Converting a double beyond the float range is undefined; reject it first.
    if (!std::isfinite(raw) || std::abs(raw) > std::numeric_limits<float>::max()) {
      return line_error(line_no, "intensity " + format_double(raw) + " is not a finite float");
    }
    intensity = static_cast<float>(raw);
  }
  std::uint8_t cls = 0;
  if (plan_.classification) {
    const double raw = v[static_cast<std::size_t>(Role::kClass)];
    if (!(raw >= 0 && raw <= kMaxClass) || raw != std::floor(raw)) {
      return line_error(line_no, "classification " + format_double(raw) + " is not a whole number from 0 to 255");
    }
    cls = static_cast<std::uint8_t>(raw);
  }
  out.positions.push_back(p);
  if (plan_.classification) out.las.classification.push_back(cls);
  if (plan_.colors) {
    if (wide != nullptr) {
      wide->insert(wide->end(), levels, levels + 3);
    } else {
      out.colors.push_back({narrow_level(levels[0], color_shift_), narrow_level(levels[1], color_shift_),
                            narrow_level(levels[2], color_shift_)});
    }
  }
  if (plan_.intensity) out.intensities.push_back(intensity);
  return Status::ok();
}

Result<std::size_t> XyzPointReader::read_into(PointCloud& out, std::vector<std::uint16_t>* wide, std::size_t at,
                                              std::size_t max_points) {
  const bool to_wide = wide != nullptr && plan_.colors;
  out.positions.resize(at);
  out.colors.resize(plan_.colors && !to_wide ? at : 0);
  out.intensities.resize(plan_.intensity ? at : 0);
  out.las.classification.resize(plan_.classification ? at : 0);
  if (to_wide) wide->resize(3 * at);
  std::vector<std::uint16_t>* levels = to_wide ? wide : nullptr;
  std::size_t got = 0;
  while (got < max_points) {
    std::string_view line;
    std::uint64_t line_no = 0;
    if (has_pending_) {
      has_pending_ = false;
      line = pending_;
      line_no = pending_line_no_;
    } else {
      bool end = false;
      RELIEF_RETURN_IF_ERROR(next_content_line(line, end, nullptr));
      if (end) break;
      line_no = line_no_;
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
    RELIEF_RETURN_IF_ERROR(parse_point(line, line_no, out, levels));
    ++got;
  }
  return got;
}

}  // namespace

Result<std::unique_ptr<PointReader>> open_xyz_reader(const InputSpec& input, const ReaderOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<XyzPointReader> reader, XyzPointReader::open(input, options));
  return std::unique_ptr<PointReader>(std::move(reader));
}

}  // namespace relief
