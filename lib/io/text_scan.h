// Line and token scanning for the text formats (PLY headers and ascii bodies,
// PCD headers and ascii bodies, XYZ/CSV). Internal to lib/io.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "io/byte_source.h"
#include "relief/status.h"

namespace relief {

enum class LineStatus { kLine, kEnd, kTooLong };

// Reads the next line without its "\n" (and a "\r" before it). `line` stays
// valid until the next call on `src`. A last line without "\n" still counts.
// A line longer than `max_len` gives kTooLong and consumes nothing.
Status next_line(ByteSource& src, std::size_t max_len, std::string_view& line, LineStatus& state);

// Blank characters of the text formats; "\n" never reaches the tokenisers.
inline bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// The next blank-separated token of `line` from `pos` (advanced past it), or
// an empty view when none is left.
std::string_view next_token(std::string_view line, std::size_t& pos);

// Every blank-separated token of `line`.
std::vector<std::string_view> split_tokens(std::string_view line);

// `s` in single quotes, cut to a short printable form: error messages must
// stay readable when the input is binary junk.
std::string quoted(std::string_view s);

// Shortest round-trip text, so messages show the value actually read.
std::string format_double(double v);

// Parses all of `tok` as a number; from_chars rejects the '+' printf may emit.
bool parse_number(std::string_view tok, double& out);

// Significant digits of a number's text: the mantissa's digits after any
// leading zeros, the exponent not counted ("0.1234": 4, "1234.5678901": 11;
// trailing zeros count, which only errs towards comparing).
int significant_digits(std::string_view text);

// Adds to `warnings`, once per input (`noted` says it was), the warning for
// the first intensity whose text (of significant_digits `digits`, value
// `text_value`, on line `line_no`) a 32-bit float does not give back.
void note_intensity_rounding(const std::string& input, double text_value, int digits, std::uint64_t line_no,
                             bool& noted, std::vector<std::string>& warnings);

}  // namespace relief
