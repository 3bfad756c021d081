#include "io/text_scan.h"

#include <array>
#include <charconv>
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

}  // namespace relief
