// ASCII XYZ / CSV / PTS reader: one point per line, columns as
// ReaderOptions::xyz_columns says, or else as a header line names them, or
// else x y z and, when the first data line has more columns: a Leica PTS
// file's (below) of 4 or 7 columns as x y z intensity [red green blue], any
// other file's kept as extra bytes named column_4 ... (as header names would
// be, below), with a warning that says so: never dropped unseen.
//
// Header names: the first non-comment line when its first column is not a
// number, or else the last comment line before the data (CloudCompare writes
// "//X,Y,Z,R,G,B") when it names x, y and z. Names match as
// text_column_of_name() says (io/text_columns.h): x y z, colours, intensity
// and the LAS dimensions under their LAS and PDAL names (PDAL's writers.text
// header "X,Y,Z,Intensity,ReturnNumber,NumberOfReturns,...,GpsTime" reads
// whole, and so does Relief's own text output). Each LAS dimension becomes
// that LasAttributes field, checked against its LAS range. Any other named
// column whose value on the first data line is a number
// (normals, times, scalar fields ...) is kept as a float64 field of LAS
// extra bytes under its header name (io/extra_fields.h), unless
// ReaderOptions::extra_bytes is off: text declares no types, and a double
// holds every value a decimal text gives to 15 significant digits (PDAL reads
// text columns as doubles too). An empty value there is a NaN; a later value
// that is not a number, or an integer a double would round (beyond 2^53), is
// an error. A column whose first value is an integer beyond 2^53 in magnitude
// (nanosecond timestamps, 64-bit IDs) is an int64 field instead (uint64 above
// INT64_MAX), whose later values must be integers in range: rounding them
// would change the data silently. Columns that are not kept (not numbers on
// the first line, a name seen twice) are listed in a warning; a partial
// colour set is kept as extra bytes.
// A header that does not name x, y and z leaves the columns at x y z.
//
// ReaderOptions::xyz_columns may name a column `name:type` (type u8 i8 u16
// i16 u32 i32 u64 i64 f32 f64): kept as extra bytes of that type, every
// value checked to fit it (typed_value_problem below). The stream parser
// TextLineParser takes the same columns.
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
// single integer). A PTS file repeats the count before each further block of
// points (one per scan): those lines are skipped too, and each block must
// hold the points its count announces. Columns after the last one the plan
// uses (a header's or --columns') are ignored.

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <cctype>

#include "io/byte_source.h"
#include "io/extra_fields.h"
#include "io/readers.h"
#include "io/stream_support.h"
#include "io/text_columns.h"
#include "io/text_scan.h"
#include "relief/io.h"

namespace relief {

namespace {

// A point line is short; a line this long is not one (binary junk, say).
constexpr std::size_t kMaxLine = std::size_t{1} << 20;

using Role = TextColumn;
constexpr std::size_t kRoleCount = kTextColumnKinds;
constexpr std::size_t at_role(Role r) { return static_cast<std::size_t>(r); }

struct ColumnPlan {
  std::vector<Role> roles;               // up to the last used column
  std::vector<std::string> extra_names;  // of the kExtra columns, in order
  std::vector<int> extra_types;          // their LAS Extra Bytes data types (1..10), once settled
  bool colors = false;
  bool intensity = false;
  std::uint32_t las = 0;  // the LasAttributeBits the LAS columns fill (kLasExtraBytes apart)
  // Header names of the columns not read (a warning lists them).
  std::vector<std::string> unread;
};

// Colour, intensity and LAS flags from the roles present.
void summarise(ColumnPlan& plan, const std::array<bool, kRoleCount>& seen) {
  auto has = [&](Role r) { return seen[at_role(r)]; };
  plan.colors = has(Role::kRed) && has(Role::kGreen) && has(Role::kBlue);
  plan.intensity = has(Role::kIntensity);
  plan.las = 0;
  for (const LasTextColumn& c : las_text_columns()) plan.las |= has(c.column) ? c.bit : 0u;
}

void drop_trailing_skips(ColumnPlan& plan) {
  while (!plan.roles.empty() && plan.roles.back() == Role::kSkip) plan.roles.pop_back();
}

// An extra bytes field's type: the LAS Extra Bytes data types 1..10 by the
// names relief/io.h gives them, with their sizes.
struct ExtraType {
  const char* name;
  int data_type;
  std::size_t size;
};
constexpr ExtraType kExtraTypes[] = {{"u8", 1, 1},  {"i8", 2, 1},  {"u16", 3, 2}, {"i16", 4, 2}, {"u32", 5, 4},
                                     {"i32", 6, 4}, {"u64", 7, 8}, {"i64", 8, 8}, {"f32", 9, 4}, {"f64", 10, 8}};

// An Extra Bytes descriptor's name field.
constexpr std::size_t kMaxExtraName = 32;
// The descriptors one Extra Bytes VLR holds (its payload is below 2^16 bytes).
constexpr std::size_t kMaxExtraColumns = 65535 / 192;

// The type named `type` (u8 ... f64), or null.
const ExtraType* extra_type_named(std::string_view type) {
  const auto t = std::find_if(std::begin(kExtraTypes), std::end(kExtraTypes),
                              [&](const ExtraType& e) { return type == e.name; });
  return t == std::end(kExtraTypes) ? nullptr : t;
}
std::size_t extra_type_size(int data_type) {
  return data_type >= 1 && data_type <= 10 ? kExtraTypes[data_type - 1].size : 8;
}

// Checks the `name:type` token `tok` of a spec (text --columns or binary
// fields): a known type and a name that is new, is no point attribute's and
// fits an Extra Bytes descriptor. Returns the type, or an error after `where`.
Result<const ExtraType*> named_extra_field(const std::string& where, std::string_view tok,
                                          const std::vector<std::string>& taken) {
  const std::size_t colon = tok.find(':');
  const std::string field(tok.substr(0, colon));
  const ExtraType* t = extra_type_named(tok.substr(colon + 1));
  if (t == nullptr) {
    return invalid_argument(where + quoted(tok) + ": the type of an extra field is one of u8 i8 u16 i16 u32 i32 " +
                            "u64 i64 f32 f64");
  }
  if (field.empty() || text_column_of_name(field) || field[0] == '_' || field == "c" || field == "C" ||
      field == "rgb") {
    return invalid_argument(where + quoted(tok) + ": an extra field needs a name that is not a point attribute's");
  }
  if (field.size() > kMaxExtraName) {
    return invalid_argument(where + quoted(tok) + ": an extra field's name has at most " +
                            std::to_string(kMaxExtraName) + " bytes (an Extra Bytes descriptor's)");
  }
  if (std::find(taken.begin(), taken.end(), field) != taken.end()) {
    return invalid_argument(where + quoted(field) + " appears twice");
  }
  return t;
}

Result<ColumnPlan> parse_columns(const std::string& spec, const std::string& name) {
  const std::string where = name + ": column spec '" + spec + "': ";
  ColumnPlan plan;
  std::array<bool, kRoleCount> seen{};
  std::size_t pos = 0;
  for (;;) {
    const std::size_t comma = std::min(spec.find(',', pos), spec.size());
    std::string_view tok(spec.data() + pos, comma - pos);
    while (!tok.empty() && is_blank(tok.front())) tok.remove_prefix(1);
    while (!tok.empty() && is_blank(tok.back())) tok.remove_suffix(1);
    Role role = Role::kSkip;
    if (tok == "c" || tok == "C") {
      role = Role::kClass;
    } else if (tok.find(':') != std::string_view::npos) {
      // name:type, a column kept as LAS extra bytes.
      RELIEF_ASSIGN_OR_RETURN(const ExtraType* t, named_extra_field(where, tok, plan.extra_names));
      if (plan.extra_names.size() == kMaxExtraColumns) {
        return invalid_argument(where + "more than " + std::to_string(kMaxExtraColumns) +
                                " extra fields (what one Extra Bytes VLR describes)");
      }
      plan.extra_names.emplace_back(tok.substr(0, tok.find(':')));
      plan.extra_types.push_back(t->data_type);
      plan.roles.push_back(Role::kExtra);
      if (comma == spec.size()) break;
      pos = comma + 1;
      continue;
    } else if (tok != "_") {
      const std::optional<Role> named = text_column_of_name(tok);
      if (!named) {
        return invalid_argument(where + "unknown column " + quoted(tok) +
                                " (use x y z r g b i c, a LAS dimension such as gps_time, return_number or "
                                "point_source_id, name:type to keep a column as extra bytes (type u8 i8 u16 i16 "
                                "u32 i32 u64 i64 f32 f64), or _ to skip; comma separated)");
      }
      role = *named;
    }
    if (role != Role::kSkip) {
      if (seen[at_role(role)]) return invalid_argument(where + "column " + quoted(tok) + " appears twice");
      seen[at_role(role)] = true;
    }
    plan.roles.push_back(role);
    if (comma == spec.size()) break;
    pos = comma + 1;
  }
  if (!seen[at_role(Role::kX)] || !seen[at_role(Role::kY)] || !seen[at_role(Role::kZ)]) {
    return invalid_argument(where + "it must name the x, y and z columns");
  }
  const int rgb = static_cast<int>(seen[at_role(Role::kRed)]) + static_cast<int>(seen[at_role(Role::kGreen)]) +
                  static_cast<int>(seen[at_role(Role::kBlue)]);
  if (rgb != 0 && rgb != 3) return invalid_argument(where + "r, g and b go together (all or none)");
  summarise(plan, seen);
  drop_trailing_skips(plan);
  return plan;
}

// Columns from a header line, when it names x, y and z. Separators: blanks,
// ',' and ';'. A comment marker before the names ('#' or '//', as in
// "# x y z" or "//X,Y,Z") is not a column. A name seen twice keeps its first
// column; other names are candidates for extra bytes, settled by
// XyzPointReader::start().
std::optional<ColumnPlan> plan_from_header(std::string_view line) {
  ColumnPlan plan;
  std::vector<std::string> names;  // per column, as the header gives it
  std::array<bool, kRoleCount> seen{};
  std::size_t pos = 0;
  for (;;) {
    while (pos < line.size() && is_blank(line[pos])) ++pos;
    if (line.substr(pos).starts_with('#')) {
      ++pos;
    } else if (line.substr(pos).starts_with("//")) {
      pos += 2;
    } else {
      break;
    }
  }
  while (pos < line.size()) {
    while (pos < line.size() && is_blank(line[pos])) ++pos;
    if (pos == line.size()) break;
    std::size_t end = pos;
    while (end < line.size() && !is_blank(line[end]) && line[end] != ',' && line[end] != ';') ++end;
    const std::string_view name = line.substr(pos, end - pos);
    const std::optional<Role> role = text_column_of_name(name);
    Role r = Role::kSkip;
    if (role && !seen[at_role(*role)]) {
      r = *role;
      seen[at_role(r)] = true;
    } else if (!role && !text_display_name(name).empty()) {
      r = Role::kExtra;
    }
    plan.roles.push_back(r);
    names.push_back(text_display_name(name));
    pos = end;
    while (pos < line.size() && is_blank(line[pos])) ++pos;
    if (pos < line.size() && (line[pos] == ',' || line[pos] == ';')) ++pos;
  }
  if (!seen[at_role(Role::kX)] || !seen[at_role(Role::kY)] || !seen[at_role(Role::kZ)]) return std::nullopt;
  summarise(plan, seen);
  for (std::size_t c = 0; c < names.size(); ++c) {
    Role& r = plan.roles[c];
    // A partial colour set is kept like any other values.
    if (!plan.colors && (r == Role::kRed || r == Role::kGreen || r == Role::kBlue)) r = Role::kExtra;
    if (r == Role::kExtra) {
      // Names of kept columns are unique ("t", "t_2" ...).
      std::string unique = names[c];
      for (int k = 2; std::find(plan.extra_names.begin(), plan.extra_names.end(), unique) != plan.extra_names.end();
           ++k) {
        unique = names[c] + "_" + std::to_string(k);
      }
      plan.extra_names.push_back(std::move(unique));
    } else if (r == Role::kSkip && !names[c].empty()) {
      plan.unread.push_back(names[c]);
    }
  }
  drop_trailing_skips(plan);
  return plan;
}

// The column of `line` at `pos` (past leading blanks), advancing `pos` past it
// and its separator; `more` says whether another column follows (a delimiter
// at the end of the line is followed by an empty one). `delimiter` ' ' means
// blanks only.
std::string_view take_column(std::string_view line, std::size_t& pos, char delimiter, bool& more) {
  const std::size_t start = pos;
  while (pos < line.size() && !is_blank(line[pos]) && line[pos] != delimiter) ++pos;
  const std::string_view tok = line.substr(start, pos - start);
  while (pos < line.size() && is_blank(line[pos])) ++pos;
  bool delimited = false;
  if (pos < line.size() && line[pos] == delimiter) {
    delimited = true;
    ++pos;
    while (pos < line.size() && is_blank(line[pos])) ++pos;
  }
  more = pos < line.size() || delimited;
  return tok;
}

std::size_t skip_blanks(std::string_view line) {
  std::size_t pos = 0;
  while (pos < line.size() && is_blank(line[pos])) ++pos;
  return pos;
}

bool is_comment(std::string_view line) {
  const std::string_view rest = line.substr(skip_blanks(line));
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

// The delimiter the first data line picks (see the top of the file).
char delimiter_of(std::string_view first_data_line) {
  if (first_data_line.find(';') != std::string_view::npos) return ';';
  if (first_data_line.find(',') != std::string_view::npos) return ',';
  return ' ';
}

// What is wrong with one line's values (`v` by role), or empty: a coordinate
// that is not finite, a colour level outside 0..max_level, an intensity no
// float holds, a LAS dimension out of its range.
std::string text_point_problem(const double* v, const ColumnPlan& plan,
                               const std::vector<const LasTextColumn*>& las_columns, double max_level) {
  const Vec3d p{v[at_role(Role::kX)], v[at_role(Role::kY)], v[at_role(Role::kZ)]};
  if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
    return "non-finite coordinate (" + format_double(p.x) + ", " + format_double(p.y) + ", " + format_double(p.z) +
           ")";
  }
  if (plan.colors) {
    for (const Role r : {Role::kRed, Role::kGreen, Role::kBlue}) {
      const double level = v[at_role(r)];
      if (!(level >= 0 && level <= max_level)) {
        return "colour level " + format_double(level) + " is outside 0.." + format_double(max_level);
      }
    }
  }
  if (plan.intensity) {
    const double raw = v[at_role(Role::kIntensity)];
    // Converting a double beyond the float range is undefined; reject it first.
    if (!std::isfinite(raw) || std::abs(raw) > std::numeric_limits<float>::max()) {
      return "intensity " + format_double(raw) + " is not a finite float";
    }
  }
  for (const LasTextColumn* c : las_columns) {
    std::string error = las_column_error(*c, v[at_role(c->column)]);
    if (!error.empty()) return error;
  }
  return "";
}

// The plan's LAS dimensions.
std::vector<const LasTextColumn*> las_columns_of(const ColumnPlan& plan) {
  std::vector<const LasTextColumn*> out;
  for (const LasTextColumn& c : las_text_columns()) {
    if (std::find(plan.roles.begin(), plan.roles.end(), c.column) != plan.roles.end()) out.push_back(&c);
  }
  return out;
}

// The Extra Bytes VLR describing a plan's kept columns, in order; `file`
// names the input in messages.
Result<std::string> extras_vlr(const ColumnPlan& plan, const std::string& file, std::vector<std::string>& warnings) {
  std::vector<KeptField> fields;
  for (std::size_t e = 0; e < plan.extra_names.size(); ++e) fields.push_back({plan.extra_names[e], plan.extra_types[e]});
  return kept_fields_vlr(fields, file, "column", "text column", warnings);
}
std::uint32_t extras_size(const ColumnPlan& plan) {
  std::size_t size = 0;
  for (const int t : plan.extra_types) size += extra_type_size(t);
  return static_cast<std::uint32_t>(size);
}

// Appends the low `size` bytes of `bits`, little-endian.
void put_le(std::vector<std::uint8_t>& out, std::uint64_t bits, std::size_t size) {
  for (std::size_t k = 0; k < size; ++k) out.push_back(static_cast<std::uint8_t>(bits >> (8 * k)));
}

// LAS Extra Bytes data types of the kept text columns (see the top of the file).
constexpr int kUInt64 = 7;
constexpr int kInt64 = 8;
constexpr int kFloat32 = 9;
constexpr int kFloat64 = 10;
// Integers up to 2^53 in magnitude are exact as doubles.
constexpr std::uint64_t kExactInDouble = std::uint64_t{1} << 53;

// `tok` is an integer literal: an optional sign, then digits only.
bool is_integer_literal(std::string_view tok) {
  if (!tok.empty() && (tok[0] == '+' || tok[0] == '-')) tok.remove_prefix(1);
  return !tok.empty() && std::all_of(tok.begin(), tok.end(), [](char c) { return c >= '0' && c <= '9'; });
}

// An integer literal's value in the column type `type` (kInt64 or kUInt64)
// as its 64-bit pattern; false when it is none or out of the type's range.
bool parse_integer(std::string_view tok, int type, std::uint64_t& bits) {
  if (!is_integer_literal(tok)) return false;
  const char* first = tok.data() + (tok[0] == '+' ? 1 : 0);
  const char* const last = tok.data() + tok.size();
  if (type == kUInt64) {
    if (*first == '-') {  // only a zero ("-0", "-00") is in range
      bits = 0;
      return std::all_of(first + 1, last, [](char c) { return c == '0'; });
    }
    const auto [p, ec] = std::from_chars(first, last, bits);
    return ec == std::errc{} && p == last;
  }
  std::int64_t v = 0;
  const auto [p, ec] = std::from_chars(first, last, v);
  bits = static_cast<std::uint64_t>(v);
  return ec == std::errc{} && p == last;
}

// The type a kept column takes from its first value: a 64-bit integer type
// when that value is an integer literal a double cannot hold exactly (beyond
// 2^53 in magnitude: nanosecond timestamps, 64-bit IDs), else float64.
int column_type_of(std::string_view first_value) {
  if (!is_integer_literal(first_value)) return kFloat64;
  std::uint64_t bits = 0;
  if (parse_integer(first_value, kInt64, bits)) {
    const auto v = static_cast<std::int64_t>(bits);
    const std::uint64_t magnitude = v < 0 ? std::uint64_t{0} - bits : bits;
    return magnitude > kExactInDouble ? kInt64 : kFloat64;
  }
  return parse_integer(first_value, kUInt64, bits) ? kUInt64 : kFloat64;
}

// Whether the double `value` read from `tok` is the number `tok` writes. Only
// an integer literal of 16 digits or more can fail (a decimal fraction is
// rounded to the nearest double by design, as PDAL reads text); glibc's %.0f
// prints a double's integer value exactly.
bool holds_integer_exactly(std::string_view tok, double value) {
  if (tok.size() < 16 || !is_integer_literal(tok)) return true;
  std::string_view digits = tok;
  if (digits[0] == '+' || digits[0] == '-') digits.remove_prefix(1);
  while (digits.size() > 1 && digits[0] == '0') digits.remove_prefix(1);
  if (digits.size() < 16) return true;  // below 10^15 < 2^53
  char printed[400];
  const int len = std::snprintf(printed, sizeof printed, "%.0f", std::abs(value));
  return len > 0 && static_cast<std::size_t>(len) < sizeof printed &&
         std::string_view(printed, static_cast<std::size_t>(len)) == digits;
}

const char* type_name(int type) {
  constexpr const char* kNames[] = {"uint8",  "int8",  "uint16", "int16",   "uint32",
                                    "int32",  "uint64", "int64", "float32", "float64"};
  return type >= 1 && type <= 10 ? kNames[type - 1] : "float64";
}

// Parses the text `tok` as a value of LAS Extra Bytes data type `type`
// (1..10) into `bits` (its little-endian pattern in the low bytes); else
// says why. Floats: any number (an empty value is a NaN, the missing value);
// an integer literal a float64 would round is refused, and float32 takes the
// nearest float of a value within its range. Integers: an integer literal,
// or a number with no fraction (CloudCompare writes "12.000000") up to 2^53,
// within the type's range; an empty value is refused (no missing value).
std::string typed_value_problem(std::string_view tok, int type, std::uint64_t& bits) {
  if (type == kFloat64 || type == kFloat32) {
    double value = std::numeric_limits<double>::quiet_NaN();
    if (!tok.empty() && !parse_number(tok, value)) return quoted(tok) + " is not a number";
    if (type == kFloat64) {
      if (!tok.empty() && !holds_integer_exactly(tok, value)) {
        return quoted(tok) + " is an integer a float64 cannot hold exactly";
      }
      bits = std::bit_cast<std::uint64_t>(value);
      return "";
    }
    if (std::isfinite(value) && std::abs(value) > std::numeric_limits<float>::max()) {
      return quoted(tok) + " is outside the float32 range";
    }
    bits = std::bit_cast<std::uint32_t>(static_cast<float>(value));
    return "";
  }
  if (tok.empty()) return "is empty, which an integer field cannot hold (it has no missing value)";
  const bool is_unsigned = type % 2 == 1;
  const std::size_t size = extra_type_size(type);
  if (!parse_integer(tok, is_unsigned ? kUInt64 : kInt64, bits)) {
    double value = 0;
    if (is_integer_literal(tok)) return quoted(tok) + " is out of range";
    if (!parse_number(tok, value) || !std::isfinite(value) || value != std::trunc(value)) {
      return quoted(tok) + " is not an integer";
    }
    if (std::abs(value) > static_cast<double>(kExactInDouble)) {
      return quoted(tok) + " is not an integer written in digits, as one beyond 2^53 must be";
    }
    if (is_unsigned && value < 0) return quoted(tok) + " is out of range";
    const auto v = static_cast<std::int64_t>(value);
    bits = static_cast<std::uint64_t>(v);
  }
  if (size < 8) {
    const auto v = static_cast<std::int64_t>(bits);
    const int width = static_cast<int>(8 * size);
    const bool fits = is_unsigned ? bits < (std::uint64_t{1} << width)
                                  : v >= -(std::int64_t{1} << (width - 1)) && v < (std::int64_t{1} << (width - 1));
    if (!fits) return quoted(tok) + " is out of range";
    bits &= (std::uint64_t{1} << width) - 1;
  }
  return "";
}

// Points a text reader looks at when it opens a file with colours (above).
constexpr std::uint64_t kOpenColorSample = std::uint64_t{1} << 16;

class XyzPointReader final : public BatchPointReader {
 public:
  // Reads up to the first data line and settles the columns.
  // `probe`: a second reader that only samples the colour levels for the
  // first (reopen()), which decides nothing itself.
  static Result<std::unique_ptr<XyzPointReader>> open(const InputSpec& input, const ReaderOptions& options,
                                                      bool probe = false) {
    std::optional<ColumnPlan> explicit_plan;
    if (options.xyz_columns) {
      RELIEF_ASSIGN_OR_RETURN(ColumnPlan p, parse_columns(*options.xyz_columns, input.name));
      explicit_plan = std::move(p);
    }
    RELIEF_ASSIGN_OR_RETURN(ByteSource src, input.open());
    std::unique_ptr<XyzPointReader> r(new XyzPointReader(input, options, std::move(src)));
    r->probe_ = probe;
    RELIEF_RETURN_IF_ERROR(r->start(std::move(explicit_plan)));
    return r;
  }

  Result<std::size_t> read_into(PointCloud& out, std::vector<std::uint16_t>* wide, std::size_t at,
                                std::size_t max_points) override;

 protected:
  Result<std::unique_ptr<BatchPointReader>> reopen() const override {
    // A pipe cannot be read twice; a regular file or memory can.
    if (!input_.memory && !src_.size()) return std::unique_ptr<BatchPointReader>();
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<XyzPointReader> again, open(input_, options_, true));
    return std::unique_ptr<BatchPointReader>(std::move(again));
  }

 private:
  XyzPointReader(InputSpec input, ReaderOptions options, ByteSource src)
      : input_(std::move(input)), options_(std::move(options)), src_(std::move(src)) {
    info_.path = input_.name;
    info_.format = "xyz";
    info_.text_body = true;
  }

  const std::string& name() const { return info_.path; }
  Status line_error(std::uint64_t line_no, const std::string& what) const {
    return format_error(name() + ": line " + std::to_string(line_no) + ": " + what);
  }
  Status start(std::optional<ColumnPlan> explicit_plan);
  // The columns of a file that names none (see the top of the file).
  Status plan_without_header();
  // A PTS point count `count` on line `line_no`: checks the block before
  // (its count against its points) and starts the next.
  Status open_pts_block(std::string_view count, std::uint64_t line_no);
  // The check of the block read last, at the end of the file.
  Status check_last_pts_block() const;
  // Settles the candidate extra columns of a header plan (see the top of the file).
  Status settle_extras();
  // The Extra Bytes VLR and size of the plan's kept columns.
  Status settle_vlr();
  // Next line that is neither blank nor a comment; `line` empty at the end.
  Status next_content_line(std::string_view& line, bool& end, std::string* last_comment_header);
  Status parse_point(std::string_view line, std::uint64_t line_no, PointCloud& out,
                     std::vector<std::uint16_t>* wide);
  // Reads kept column `extra` (column c of the line) into extra_values_.
  Status parse_extra(std::string_view tok, std::size_t c, std::size_t extra, std::uint64_t line_no);

  InputSpec input_;
  ReaderOptions options_;
  ByteSource src_;
  ColumnPlan plan_;
  std::vector<const LasTextColumn*> las_columns_;  // the plan's LAS dimensions
  std::vector<std::uint64_t> extra_values_;    // one point's kept columns, as 64-bit patterns
  std::uint64_t line_no_ = 0;
  std::string pending_;  // the first data line, read by start()
  std::uint64_t pending_line_no_ = 0;
  bool has_pending_ = false;
  // Intensities are 32-bit floats. The first one whose text the float does
  // not give back (more than about 7 significant digits: 1234.5678901 comes
  // back as 1234.5679) becomes a warning in info().warnings, read when the
  // input is done (as the PLY reader's extra vertices); PLY and PCD say it
  // from their header's types.
  bool intensity_rounding_noted_ = false;
  bool explicit_columns_ = false;  // ReaderOptions::xyz_columns, not a header, gave the plan
  bool probe_ = false;             // samples colour levels for another reader (open)
  char delimiter_ = ' ';  // ' ' means blanks only
  // Leica PTS: a point count alone on the first line, and again before each
  // further block of points (one per scan). Each block must hold the points
  // its count announces: fewer is a truncated file, more a damaged one.
  bool pts_ = false;
  std::uint64_t pts_count_ = 0;   // the current block's count
  std::uint64_t pts_points_ = 0;  // the points read in it
  std::uint64_t pts_line_ = 0;    // its count's line
};

Status XyzPointReader::open_pts_block(std::string_view count, std::uint64_t line_no) {
  std::uint64_t n = 0;
  const auto [end, ec] = std::from_chars(count.data(), count.data() + count.size(), n);
  if (ec != std::errc{} || end != count.data() + count.size()) {
    return line_error(line_no, "the PTS point count " + quoted(count) + " is out of range");
  }
  if (pts_ && pts_points_ != pts_count_) {
    return line_error(line_no, "the PTS block whose count is on line " + std::to_string(pts_line_) + " announces " +
                                   std::to_string(pts_count_) + " points but holds " + std::to_string(pts_points_) +
                                   " (a damaged file)");
  }
  pts_ = true;
  pts_count_ = n;
  pts_points_ = 0;
  pts_line_ = line_no;
  return Status::ok();
}

Status XyzPointReader::check_last_pts_block() const {
  if (!pts_ || pts_points_ == pts_count_) return Status::ok();
  return format_error(name() + ": the PTS block whose count is on line " + std::to_string(pts_line_) + " announces " +
                      std::to_string(pts_count_) + " points but the file " +
                      (pts_points_ < pts_count_ ? "ends after " : "holds ") + std::to_string(pts_points_) +
                      (pts_points_ < pts_count_ ? " of them (a truncated file)" : " (a damaged file)"));
}

Status XyzPointReader::plan_without_header() {
  // The first data line's columns; empty ones at its end (a delimiter
  // closing the line) do not count.
  std::size_t columns = 3;
  if (has_pending_) {
    std::size_t pos = skip_blanks(pending_), n = 0;
    for (bool more = pos < pending_.size(); more;) {
      const std::string_view tok = take_column(pending_, pos, delimiter_, more);
      ++n;
      if (!tok.empty()) columns = std::max(columns, n);
    }
  }
  if (columns == 3 || (pts_ && (columns == 4 || columns == 7))) {
    // Leica's PTS columns: x y z intensity [red green blue].
    const char* spec = columns == 4 ? "x,y,z,i" : columns == 7 ? "x,y,z,i,r,g,b" : "x,y,z";
    RELIEF_ASSIGN_OR_RETURN(plan_, parse_columns(spec, name()));
    return Status::ok();
  }
  // Any other columns are kept as extra bytes named by their place, as a
  // header would name them, rather than dropped unseen.
  const std::size_t named = std::min(columns, 3 + kMaxExtraColumns);
  std::string header = "x,y,z";
  for (std::size_t c = 4; c <= named; ++c) header += ",column_" + std::to_string(c);
  plan_ = *plan_from_header(header);  // it names x, y and z
  RELIEF_RETURN_IF_ERROR(settle_extras());
  std::string what = name() + ": no header line names its " + std::to_string(columns) + " columns, so ";
  if (!plan_.extra_names.empty()) {
    what += "after x, y and z " + std::string(plan_.extra_names.size() > 1 ? "columns " : "column ");
    for (std::size_t e = 0; e < plan_.extra_names.size(); ++e) {
      what += (e == 0 ? "" : e + 1 == plan_.extra_names.size() ? " and " : ", ") + plan_.extra_names[e].substr(7);
    }
    what += std::string(plan_.extra_names.size() > 1 ? " are" : " is") + " kept as extra bytes (" +
            plan_.extra_names.front() + (plan_.extra_names.size() > 1 ? " ...)" : ")");
    if (!plan_.unread.empty() || named < columns) what += " and the others are not kept";
  } else {
    what += "only x, y and z are kept" +
            std::string(options_.extra_bytes ? " (the others are not numbers)" : " (--no-extra-bytes)");
  }
  info_.warnings.push_back(what + "; --columns names them (x,y,z,i,r,g,b reads intensity and colour" +
                           std::string(pts_ ? ", as in a PTS file of 7 columns)" : ")"));
  return Status::ok();
}

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

Status XyzPointReader::settle_extras() {
  std::size_t k = 0;  // index into extra_names
  std::vector<std::string> kept;
  std::vector<std::size_t> columns;  // of the candidates
  for (std::size_t c = 0; c < plan_.roles.size(); ++c) {
    if (plan_.roles[c] == Role::kExtra) columns.push_back(c);
  }
  // The first data line's value of each column, when it has one.
  std::vector<std::string_view> first;
  if (has_pending_) {
    std::size_t pos = skip_blanks(pending_);
    for (bool more = pos < pending_.size(); more;) first.push_back(take_column(pending_, pos, delimiter_, more));
  }
  std::vector<std::string> not_numbers;
  plan_.extra_types.clear();
  for (const std::size_t c : columns) {
    const std::string& extra_name = plan_.extra_names[k++];
    double value = 0;
    const bool numeric = !has_pending_ || (c < first.size() && (first[c].empty() || parse_number(first[c], value)));
    if (!options_.extra_bytes || !numeric) {
      plan_.roles[c] = Role::kSkip;
      if (options_.extra_bytes) not_numbers.push_back(extra_name);
      continue;
    }
    kept.push_back(extra_name);
    plan_.extra_types.push_back(has_pending_ ? column_type_of(first[c]) : kFloat64);
  }
  plan_.extra_names = std::move(kept);
  if (!not_numbers.empty()) plan_.unread.insert(plan_.unread.begin(), not_numbers.begin(), not_numbers.end());
  drop_trailing_skips(plan_);
  return settle_vlr();
}

Status XyzPointReader::settle_vlr() {
  if (plan_.extra_names.empty()) return Status::ok();
  RELIEF_ASSIGN_OR_RETURN(info_.extra_bytes_vlr, extras_vlr(plan_, name(), info_.warnings));
  info_.extra_bytes_size = extras_size(plan_);
  extra_values_.assign(plan_.extra_names.size(), 0);
  return Status::ok();
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
      RELIEF_RETURN_IF_ERROR(open_pts_block(first, line_no_));
      RELIEF_RETURN_IF_ERROR(next_content_line(line, end, nullptr));
    }
  }
  if (!end) {
    pending_.assign(line);
    pending_line_no_ = line_no_;
    has_pending_ = true;
    delimiter_ = delimiter_of(pending_);
  }
  if (!header_plan && !comment_header.empty()) header_plan = plan_from_header(comment_header);
  if (explicit_plan) {
    plan_ = std::move(*explicit_plan);  // the caller's columns win over a header
    explicit_columns_ = true;
    if (!plan_.extra_names.empty() && !options_.extra_bytes) {
      return invalid_argument(name() + ": the columns name extra fields (" + quoted(plan_.extra_names[0]) +
                              " ...) but extra bytes are not kept (--no-extra-bytes)");
    }
    RELIEF_RETURN_IF_ERROR(settle_vlr());
  } else if (header_plan) {
    plan_ = std::move(*header_plan);
    RELIEF_RETURN_IF_ERROR(settle_extras());
    if (!plan_.unread.empty()) {
      std::string names;
      for (const std::string& n : plan_.unread) names += (names.empty() ? "" : ", ") + quoted(n);
      info_.warnings.push_back(name() + ": header column" + (plan_.unread.size() > 1 ? "s " : " ") + names +
                               (plan_.unread.size() > 1 ? " are" : " is") +
                               " not kept (text columns are kept when their first value is a number and "
                               "their name is new)");
    }
  } else {
    RELIEF_RETURN_IF_ERROR(plan_without_header());
  }
  las_columns_ = las_columns_of(plan_);
  info_.has_colors = plan_.colors;
  info_.has_intensity = plan_.intensity;
  info_.las_attributes = plan_.las | (plan_.extra_names.empty() ? 0u : std::uint32_t{kLasExtraBytes});
  wide_colors_ = plan_.colors;  // levels may be 16-bit (see the top of the file)
  if (plan_.colors && !probe_) {
    // 16-bit levels keep their low bytes (LasAttributes::color_low), which
    // info() must name, so the rule is decided now where a short look
    // settles it: a level above 255 among the first kOpenColorSample points
    // (a 16-bit file shows one at once), or a file no longer than that.
    // Otherwise (or from a pipe) the first read decides, keeping no low bytes.
    RELIEF_ASSIGN_OR_RETURN(const bool decided, decide_color_shift_now(kOpenColorSample));
    if (decided && color_shift_ != 0) {
      color_low_ = true;
      info_.las_attributes |= kLasColorLow;
    }
  }
  return Status::ok();
}

Status XyzPointReader::parse_extra(std::string_view tok, std::size_t c, std::size_t extra, std::uint64_t line_no) {
  const int type = plan_.extra_types[extra];
  const std::string problem = typed_value_problem(tok, type, extra_values_[extra]);
  if (problem.empty()) return Status::ok();
  std::string why = " (kept as " + std::string(type_name(type)) + " extra bytes " + quoted(plan_.extra_names[extra]);
  if (explicit_columns_) {
    why += " as the columns say)";
  } else {
    why += "; --no-extra-bytes skips such columns): the column's type comes from its first value";
    if (type == kFloat64) why += ", and a column whose first value is an integer beyond 2^53 is kept as a 64-bit integer";
  }
  return line_error(line_no, "column " + std::to_string(c + 1) + " " + problem + why);
}

Status XyzPointReader::parse_point(std::string_view line, std::uint64_t line_no, PointCloud& out,
                                   std::vector<std::uint16_t>* wide) {
  double v[kRoleCount] = {};
  std::size_t extra = 0;
  int intensity_digits = 0;  // significant digits of the intensity's text
  std::size_t pos = skip_blanks(line);
  const std::size_t columns = plan_.roles.size();
  bool more = pos < line.size();
  for (std::size_t c = 0; c < columns; ++c) {
    if (!more) {
      return line_error(line_no, "expected at least " + std::to_string(columns) + " columns but found " +
                                     std::to_string(c));
    }
    const std::string_view tok = take_column(line, pos, delimiter_, more);
    const Role role = plan_.roles[c];
    if (role == Role::kSkip) continue;
    double value = 0;
    if (role == Role::kExtra) {
      RELIEF_RETURN_IF_ERROR(parse_extra(tok, c, extra, line_no));
      ++extra;
      continue;
    }
    if (!parse_number(tok, value)) {
      return line_error(line_no, "column " + std::to_string(c + 1) + " " +
                                     (tok.empty() ? std::string("is empty") : quoted(tok) + " is not a number"));
    }
    v[at_role(role)] = value;
    if (role == Role::kIntensity) intensity_digits = significant_digits(tok);
  }
  if (const std::string problem = text_point_problem(v, plan_, las_columns_, kMaxWideLevel); !problem.empty()) {
    return line_error(line_no, problem);
  }
  const Vec3d p{v[at_role(Role::kX)], v[at_role(Role::kY)], v[at_role(Role::kZ)]};
  std::uint16_t levels[3] = {};
  if (plan_.colors) {
    const Role roles[3] = {Role::kRed, Role::kGreen, Role::kBlue};
    for (int k = 0; k < 3; ++k) levels[k] = static_cast<std::uint16_t>(std::lround(v[at_role(roles[k])]));
  }
  const float intensity = plan_.intensity ? static_cast<float>(v[at_role(Role::kIntensity)]) : 0.0f;
  if (plan_.intensity) {
    note_intensity_rounding(name(), v[at_role(Role::kIntensity)], intensity_digits, line_no, intensity_rounding_noted_,
                            info_.warnings);
  }
  out.positions.push_back(p);
  push_las_columns(v, plan_.las, out.las);
  for (std::size_t e = 0; e < extra_values_.size(); ++e) {
    put_le(out.las.extra_bytes, extra_values_[e], extra_type_size(plan_.extra_types[e]));
  }
  if (plan_.colors) {
    if (wide != nullptr) {
      wide->insert(wide->end(), levels, levels + 3);
    } else {
      if (color_low_) {
        Rgb8 low;
        out.colors.push_back(split_levels(levels[0], levels[1], levels[2], color_shift_, low));
        out.las.color_low.push_back(low);
      } else {
        out.colors.push_back({narrow_level(levels[0], color_shift_), narrow_level(levels[1], color_shift_),
                              narrow_level(levels[2], color_shift_)});
        note_level_above_255(line_no, std::max({levels[0], levels[1], levels[2]}), "line");
      }
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
  size_las_columns(out.las, plan_.las, at);
  out.las.color_low.resize(color_low_ && !to_wide ? at : 0);
  out.las.extra_bytes_size = info_.extra_bytes_size;
  out.las.extra_bytes.resize(at * info_.extra_bytes_size);
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
      if (end) {
        RELIEF_RETURN_IF_ERROR(check_last_pts_block());
        break;
      }
      line_no = line_no_;
      if (pts_) {
        // The next block's count: not a point (a point has three columns).
        const std::string_view first = first_column(line);
        if (is_point_count(line, first)) {
          RELIEF_RETURN_IF_ERROR(open_pts_block(first, line_no));
          continue;
        }
      }
    }
    RELIEF_RETURN_IF_ERROR(parse_point(line, line_no, out, levels));
    pts_points_ += pts_ ? 1 : 0;
    ++got;
  }
  return got;
}

// Appends one checked point (`v` by role, text_point_problem passed) to
// `batch`: colour levels rounded to the nearest.
void append_point(const double* v, const ColumnPlan& plan, PointCloud& batch) {
  batch.positions.push_back({v[at_role(Role::kX)], v[at_role(Role::kY)], v[at_role(Role::kZ)]});
  if (plan.colors) {
    const auto level = [&](Role r) { return static_cast<std::uint8_t>(std::lround(v[at_role(r)])); };
    batch.colors.push_back({level(Role::kRed), level(Role::kGreen), level(Role::kBlue)});
  }
  if (plan.intensity) batch.intensities.push_back(static_cast<float>(v[at_role(Role::kIntensity)]));
  push_las_columns(v, plan.las, batch.las);
}

// What both stream parsers (TextLineParser, BinaryRecordParser) say of the
// points they append: the plan's attributes and the extra fields' VLR.
template <typename Parser>
class StreamFields : public Parser {
 public:
  StreamFields(ColumnPlan plan, std::string name, std::string extra_vlr, std::uint32_t extra_size)
      : plan_(std::move(plan)), las_columns_(las_columns_of(plan_)), name_(std::move(name)),
        extra_vlr_(std::move(extra_vlr)), extra_size_(extra_size) {}

  bool colors() const override { return plan_.colors; }
  bool intensity() const override { return plan_.intensity; }
  std::uint32_t las_attributes() const override {
    return plan_.las | (extra_size_ > 0 ? std::uint32_t{kLasExtraBytes} : 0u);
  }
  const std::string& extra_bytes_vlr() const override { return extra_vlr_; }
  std::uint32_t extra_bytes_size() const override { return extra_size_; }

 protected:
  ColumnPlan plan_;
  std::vector<const LasTextColumn*> las_columns_;
  std::string name_;
  std::string extra_vlr_;
  std::uint32_t extra_size_;
};

// TextLineParser (relief/io.h): one line at a time, columns separated by any
// run of blanks, ',' and ';' (a stream has no first line to pick one
// delimiter from), colour levels 0..255 (no file-wide 16-bit rule either).
class TextLineParserImpl final : public StreamFields<TextLineParser> {
 public:
  // `named`: the columns the spec names, trailing skips included.
  TextLineParserImpl(ColumnPlan plan, std::string name, std::string extra_vlr, std::size_t named)
      : StreamFields(plan, std::move(name), std::move(extra_vlr), extras_size(plan)), named_(named) {}

  Status parse(std::string_view line, std::uint64_t line_no, PointCloud& batch) const override {
    const auto error = [&](const std::string& what) {
      return format_error(name_ + ": line " + std::to_string(line_no) + ": " + what);
    };
    const auto separator = [](char c) { return is_blank(c) || c == ',' || c == ';'; };
    double v[kRoleCount] = {};
    // The extra fields' bytes, in the order listed (at most 8 each).
    std::uint8_t extra[8 * kMaxExtraColumns];
    std::size_t extra_at = 0, e = 0;
    int intensity_digits = 0;  // significant digits of the intensity's text
    std::size_t pos = 0;
    for (std::size_t c = 0; c < plan_.roles.size(); ++c) {
      while (pos < line.size() && separator(line[pos])) ++pos;
      if (pos >= line.size()) {
        return error("expected " + std::to_string(plan_.roles.size()) + " columns, found " + std::to_string(c));
      }
      const std::size_t start = pos;
      while (pos < line.size() && !separator(line[pos])) ++pos;
      const std::string_view tok = line.substr(start, pos - start);
      const Role role = plan_.roles[c];
      if (role == Role::kSkip) continue;
      if (role == Role::kExtra) {
        std::uint64_t bits = 0;
        const int type = plan_.extra_types[e];
        if (const std::string problem = typed_value_problem(tok, type, bits); !problem.empty()) {
          return error("column " + std::to_string(c + 1) + " " + problem + " (the " + type_name(type) + " field " +
                       quoted(plan_.extra_names[e]) + ")");
        }
        for (std::size_t k = 0; k < extra_type_size(type); ++k) extra[extra_at++] = static_cast<std::uint8_t>(bits >> (8 * k));
        ++e;
        continue;
      }
      double value = 0;
      if (!parse_number(tok, value)) return error("column " + std::to_string(c + 1) + " " + quoted(tok) + " is not a number");
      v[at_role(role)] = value;
      if (role == Role::kIntensity) intensity_digits = significant_digits(tok);
    }
    if (const std::string problem = text_point_problem(v, plan_, las_columns_, 255); !problem.empty()) {
      return error(problem);
    }
    if (plan_.intensity) {
      note_intensity_rounding(name_, v[at_role(Role::kIntensity)], intensity_digits, line_no, intensity_rounding_noted_,
                              warnings_);
    }
    if (pos < line.size() && !extra_columns_noted_) {
      // Columns beyond those the spec names are not kept: said once.
      std::size_t columns = plan_.roles.size();
      for (;;) {
        while (pos < line.size() && separator(line[pos])) ++pos;
        if (pos == line.size()) break;
        ++columns;
        while (pos < line.size() && !separator(line[pos])) ++pos;
      }
      if (columns > named_) {
        extra_columns_noted_ = true;
        warnings_.push_back(name_ + ": line " + std::to_string(line_no) + " has " + std::to_string(columns) +
                            " columns but --columns names " + std::to_string(named_) +
                            ": the others are not kept (name them, or _ to skip them; later lines are not listed)");
      }
    }
    append_point(v, plan_, batch);
    if (extra_size_ > 0) {
      batch.las.extra_bytes_size = extra_size_;
      batch.las.extra_bytes.insert(batch.las.extra_bytes.end(), extra, extra + extra_at);
    }
    return Status::ok();
  }

  std::vector<std::string> take_warnings() override { return std::exchange(warnings_, {}); }

 private:
  // parse() is const to its callers (a refused line changes nothing they
  // see); what it notes for take_warnings() is bookkeeping beside the batch.
  mutable bool intensity_rounding_noted_ = false;
  mutable bool extra_columns_noted_ = false;
  mutable std::vector<std::string> warnings_;
  std::size_t named_;
};

}  // namespace

Result<std::unique_ptr<TextLineParser>> TextLineParser::create(const std::string& spec, const std::string& name) {
  RELIEF_ASSIGN_OR_RETURN(ColumnPlan plan, parse_columns(spec, name));
  std::string vlr;
  if (!plan.extra_names.empty()) {
    std::vector<std::string> warnings;  // none: the names fit (parse_columns checked them)
    RELIEF_ASSIGN_OR_RETURN(vlr, extras_vlr(plan, name, warnings));
  }
  const auto named = static_cast<std::size_t>(std::count(spec.begin(), spec.end(), ',')) + 1;
  return std::unique_ptr<TextLineParser>(new TextLineParserImpl(std::move(plan), name, std::move(vlr), named));
}

namespace {

// BinaryRecordParser (relief/io.h): a field's kind in the record.
enum class BinaryType : std::uint8_t { kU8, kU16, kF32, kF64, kRgb, kSkip, kExtra };

// The bytes of a fixed-size field (a skip's and an extra field's are their own).
std::size_t binary_size(BinaryType t) {
  switch (t) {
    case BinaryType::kU8: return 1;
    case BinaryType::kU16: return 2;
    case BinaryType::kF32: return 4;
    case BinaryType::kF64: return 8;
    case BinaryType::kRgb: return 3;
    case BinaryType::kSkip:
    case BinaryType::kExtra: break;
  }
  return 0;
}

// The binary type of a LAS dimension (relief/io.h lists them).
BinaryType binary_type_of(Role r) {
  switch (r) {
    case Role::kGpsTime: return BinaryType::kF64;
    case Role::kScanAngle:
    case Role::kIntensity: return BinaryType::kF32;
    case Role::kPointSourceId:
    case Role::kNir: return BinaryType::kU16;
    default: return BinaryType::kU8;
  }
}

constexpr std::size_t kMaxBinarySkip = 1024;

class BinaryRecordParserImpl final : public StreamFields<BinaryRecordParser> {
 public:
  struct Field {
    Role role;  // kSkip for padding, kRed for the colour triple, kExtra for an extra bytes field
    BinaryType type;
    std::size_t offset;
    std::size_t size;
  };
  BinaryRecordParserImpl(ColumnPlan plan, std::vector<Field> fields, std::size_t size, std::string name,
                         std::string extra_vlr, std::uint32_t extra_size)
      : StreamFields(std::move(plan), std::move(name), std::move(extra_vlr), extra_size), fields_(std::move(fields)),
        size_(size) {}

  std::size_t record_size() const override { return size_; }

  Status parse(const std::uint8_t* record, std::uint64_t record_no, PointCloud& batch) const override {
    double v[kRoleCount] = {};
    v[at_role(Role::kX)] = load_le<double>(record);
    v[at_role(Role::kY)] = load_le<double>(record + 8);
    v[at_role(Role::kZ)] = load_le<double>(record + 16);
    for (const Field& f : fields_) {
      const std::uint8_t* p = record + f.offset;
      switch (f.type) {
        case BinaryType::kU8: v[at_role(f.role)] = p[0]; break;
        case BinaryType::kU16: v[at_role(f.role)] = load_le<std::uint16_t>(p); break;
        case BinaryType::kF32: v[at_role(f.role)] = load_le<float>(p); break;
        case BinaryType::kF64: v[at_role(f.role)] = load_le<double>(p); break;
        case BinaryType::kRgb:
          v[at_role(Role::kRed)] = p[0];
          v[at_role(Role::kGreen)] = p[1];
          v[at_role(Role::kBlue)] = p[2];
          break;
        case BinaryType::kSkip:
        case BinaryType::kExtra: break;
      }
    }
    if (const std::string problem = text_point_problem(v, plan_, las_columns_, 255); !problem.empty()) {
      return format_error(name_ + ": record " + std::to_string(record_no) + ": " + problem);
    }
    append_point(v, plan_, batch);
    if (extra_size_ > 0) {
      // The fields' little-endian bytes, in the order listed: the layout the
      // Extra Bytes VLR describes.
      batch.las.extra_bytes_size = extra_size_;
      for (const Field& f : fields_) {
        if (f.type != BinaryType::kExtra) continue;
        batch.las.extra_bytes.insert(batch.las.extra_bytes.end(), record + f.offset, record + f.offset + f.size);
      }
    }
    return Status::ok();
  }

 private:
  std::vector<Field> fields_;
  std::size_t size_;
};

}  // namespace

Result<std::unique_ptr<BinaryRecordParser>> BinaryRecordParser::create(const std::string& spec,
                                                                       const std::string& name) {
  const std::string where = name + ": binary fields '" + spec + "': ";
  ColumnPlan plan;
  plan.roles = {Role::kX, Role::kY, Role::kZ};
  std::array<bool, kRoleCount> seen{};
  seen[at_role(Role::kX)] = seen[at_role(Role::kY)] = seen[at_role(Role::kZ)] = true;
  std::vector<BinaryRecordParserImpl::Field> fields;
  std::vector<KeptField> kept;  // the extra bytes fields
  std::vector<std::string> kept_names;
  std::uint32_t extra_size = 0;
  std::size_t size = 24;
  std::size_t start = 0;
  while (!spec.empty() && start <= spec.size()) {
    const std::size_t comma = std::min(spec.find(',', start), spec.size());
    const std::string tok = spec.substr(start, comma - start);
    start = comma + 1;
    BinaryRecordParserImpl::Field f{Role::kSkip, BinaryType::kSkip, size, 0};
    if (const std::size_t colon = tok.find(':'); colon != std::string::npos) {
      // name:type, an extra bytes field.
      RELIEF_ASSIGN_OR_RETURN(const ExtraType* t, named_extra_field(where, tok, kept_names));
      kept_names.push_back(tok.substr(0, colon));
      kept.push_back({kept_names.back(), t->data_type});
      f.role = Role::kExtra;
      f.type = BinaryType::kExtra;
      f.size = t->size;
      extra_size += static_cast<std::uint32_t>(t->size);
    } else if (tok.size() > 1 && tok[0] == '_') {
      std::size_t skip = 0;
      const auto [p, ec] = std::from_chars(tok.data() + 1, tok.data() + tok.size(), skip);
      if (ec != std::errc{} || p != tok.data() + tok.size() || skip == 0 || skip > kMaxBinarySkip) {
        return invalid_argument(where + quoted(tok) + " is not _N with N bytes to skip, 1.." +
                                std::to_string(kMaxBinarySkip));
      }
      f.size = skip;
    } else if (tok == "rgb") {
      if (seen[at_role(Role::kRed)]) return invalid_argument(where + "rgb appears twice");
      seen[at_role(Role::kRed)] = seen[at_role(Role::kGreen)] = seen[at_role(Role::kBlue)] = true;
      f.role = Role::kRed;
      f.type = BinaryType::kRgb;
      f.size = binary_size(f.type);
    } else {
      const std::optional<Role> role = text_column_of_name(tok);
      const bool single_colour = role == Role::kRed || role == Role::kGreen || role == Role::kBlue;
      if (!role || single_colour) {
        return invalid_argument(where + "unknown field " + quoted(tok) +
                                " (rgb, intensity, the LAS dimensions by name, or _N to skip N bytes)");
      }
      if (*role == Role::kX || *role == Role::kY || *role == Role::kZ) {
        return invalid_argument(where + quoted(tok) + ": x, y and z are always the record's first 24 bytes");
      }
      if (seen[at_role(*role)]) return invalid_argument(where + quoted(tok) + " appears twice");
      seen[at_role(*role)] = true;
      f.role = *role;
      f.type = binary_type_of(*role);
      f.size = binary_size(f.type);
    }
    if (f.role == Role::kExtra) {
      fields.push_back(f);
    } else if (f.role != Role::kSkip) {
      plan.roles.push_back(f.role);
      if (f.type == BinaryType::kRgb) plan.roles.insert(plan.roles.end(), {Role::kGreen, Role::kBlue});
      fields.push_back(f);
    }
    size += f.size;
  }
  // Before rgb and intensity could be listed in any order, the record had
  // rgb first whatever the order: refuse the other order rather than read
  // such a stream differently.
  const auto offset_of = [&](Role r) {
    const auto it = std::find_if(fields.begin(), fields.end(), [&](const auto& f) { return f.role == r; });
    return it == fields.end() ? std::optional<std::size_t>() : it->offset;
  };
  const auto rgb_at = offset_of(Role::kRed), intensity_at = offset_of(Role::kIntensity);
  if (rgb_at && intensity_at && *intensity_at < *rgb_at) {
    return invalid_argument(where + "rgb must come before intensity in the record");
  }
  summarise(plan, seen);
  std::string vlr;
  if (!kept.empty()) {
    std::vector<std::string> warnings;  // none: the names fit (checked above)
    RELIEF_ASSIGN_OR_RETURN(vlr, kept_fields_vlr(kept, name, "binary field", "relief stream field", warnings));
  }
  return std::unique_ptr<BinaryRecordParser>(
      new BinaryRecordParserImpl(std::move(plan), std::move(fields), size, name, std::move(vlr), extra_size));
}

Result<std::unique_ptr<PointReader>> open_xyz_reader(const InputSpec& input, const ReaderOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<XyzPointReader> reader, XyzPointReader::open(input, options));
  return std::unique_ptr<PointReader>(std::move(reader));
}

}  // namespace relief
