#include "io/text_scan.h"

#include <array>
#include <charconv>
#include <cmath>
#include <cstring>

namespace relief {

Status next_line(ByteSource& src, std::size_t max_len, std::string_view& line, LineStatus& state) {
  std::span<const std::uint8_t> view;
  RELIEF_RETURN_IF_ERROR(src.fill(1, view));
  if (view.empty()) {
    state = LineStatus::kEnd;
    return Status::ok();
  }
  // Bytes already searched for "\n"; refills only look at what is new.
  std::size_t searched = 0;
  for (;;) {
    const void* hit = std::memchr(view.data() + searched, '\n', view.size() - searched);
    std::size_t len = 0;
    std::size_t used = 0;
    if (hit != nullptr) {
      len = static_cast<std::size_t>(static_cast<const std::uint8_t*>(hit) - view.data());
      used = len + 1;
    } else if (view.size() > max_len) {
      state = LineStatus::kTooLong;
      return Status::ok();
    } else {
      const std::size_t have = view.size();
      RELIEF_RETURN_IF_ERROR(src.fill(have + 1, view));
      if (view.size() > have) {
        searched = have;
        continue;
      }
      len = used = have;  // the input ends without a final "\n"
    }
    if (len > max_len) {
      state = LineStatus::kTooLong;
      return Status::ok();
    }
    if (len > 0 && view[len - 1] == '\r') --len;
    line = std::string_view(reinterpret_cast<const char*>(view.data()), len);
    src.consume(used);  // consume() never moves the buffer, so `line` stays valid
    state = LineStatus::kLine;
    return Status::ok();
  }
}

std::string_view next_token(std::string_view line, std::size_t& pos) {
  while (pos < line.size() && is_blank(line[pos])) ++pos;
  const std::size_t start = pos;
  while (pos < line.size() && !is_blank(line[pos])) ++pos;
  return line.substr(start, pos - start);
}

std::vector<std::string_view> split_tokens(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t pos = 0;
  for (std::string_view t = next_token(line, pos); !t.empty(); t = next_token(line, pos)) {
    out.push_back(t);
  }
  return out;
}

std::string quoted(std::string_view s) {
  constexpr std::size_t kMaxShown = 40;
  std::string out = "'";
  for (const char c : s.substr(0, kMaxShown)) out += (c >= 0x20 && c < 0x7f) ? c : '?';
  if (s.size() > kMaxShown) out += "...";
  return out + "'";
}

std::string format_double(double v) {
  std::array<char, 64> buf{};
  const auto [end, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return ec == std::errc{} ? std::string(buf.data(), end) : std::string("?");
}

bool parse_number(std::string_view tok, double& out) {
  const char* first = tok.data();
  const char* const last = tok.data() + tok.size();
  if (last - first > 1 && *first == '+' && first[1] != '-' && first[1] != '+') ++first;
  const auto [p, ec] = std::from_chars(first, last, out);
  return ec == std::errc{} && p == last && first != last;
}

int significant_digits(std::string_view text) {
  int n = 0;
  for (const char c : text) {
    if (c == 'e' || c == 'E') break;
    if (c < '0' || c > '9' || (n == 0 && c == '0')) continue;
    ++n;
  }
  return n;
}

namespace {

// The warning for the first intensity whose text (of significant_digits
// `digits`) a 32-bit float does not give back, or "" when it does. A decimal
// of at most 6 significant digits always comes back (FLT_DIG), and so do
// whole numbers up to 2^24 (every LAS intensity): neither costs a comparison.
std::string intensity_rounding_warning(const std::string& input, double text_value, int digits,
                                       std::uint64_t line_no) {
  if (digits <= 6) return {};
  if (std::fabs(text_value) <= 16777216.0 && text_value == std::nearbyint(text_value)) return {};
  // The float's shortest text, read back as a double, against the input's.
  const float kept = static_cast<float>(text_value);
  char text[32];
  const auto printed = std::to_chars(text, text + sizeof text, kept);
  double back = 0;
  std::from_chars(text, printed.ptr, back);
  if (back == text_value) return {};
  return input + ": line " + std::to_string(line_no) + ": intensity " + format_double(text_value) +
         " is kept as the 32-bit float " + std::string(text, printed.ptr) +
         " (intensities are 32-bit floats: about 7 significant digits, integers exact up to 2^24); later ones are "
         "not listed";
}

}  // namespace

void note_intensity_rounding(const std::string& input, double text_value, int digits, std::uint64_t line_no,
                             bool& noted, std::vector<std::string>& warnings) {
  if (noted) return;
  std::string warning = intensity_rounding_warning(input, text_value, digits, line_no);
  if (warning.empty()) return;
  noted = true;
  warnings.push_back(std::move(warning));
}

}  // namespace relief
