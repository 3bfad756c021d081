#include "box_arg.h"

#include <charconv>
#include <cmath>
#include <cstddef>
#include <vector>

#include "relief/query.h"

namespace relief::cli {

namespace {

bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

std::string trimmed(const std::string& s) {
  std::size_t b = 0, e = s.size();
  while (b < e && is_space(s[b])) ++b;
  while (e > b && is_space(s[e - 1])) --e;
  return s.substr(b, e - b);
}

// std::from_chars does not take a leading '+', which people do type.
bool parse_number(const std::string& token, double& out) {
  std::string t = token;
  if (!t.empty() && t[0] == '+') t.erase(0, 1);
  if (t.empty()) return false;
  const char* end = t.data() + t.size();
  const auto r = std::from_chars(t.data(), end, out);
  return r.ec == std::errc() && r.ptr == end && std::isfinite(out);
}

}  // namespace

bool parse_box(const std::string& text, relief::Box3d& out, std::string& error) {
  std::vector<std::string> tokens;
  std::size_t start = 0;
  while (true) {
    const std::size_t comma = text.find(',', start);
    tokens.push_back(trimmed(text.substr(start, comma == std::string::npos ? std::string::npos : comma - start)));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  if (tokens.size() != 4 && tokens.size() != 6) {
    error = "box '" + text + "': expected 4 numbers (xmin,ymin,xmax,ymax) or 6 (xmin,ymin,zmin,xmax,ymax,zmax), got " +
            std::to_string(tokens.size()) + " comma-separated value" + (tokens.size() == 1 ? "" : "s");
    return false;
  }
  std::vector<double> v(tokens.size());
  for (std::size_t i = 0; i < tokens.size(); ++i) {
    if (!parse_number(tokens[i], v[i])) {
      error = "box '" + text + "': value " + std::to_string(i + 1) + " ('" + tokens[i] + "') is not a finite number";
      return false;
    }
  }
  Box3d box;
  if (v.size() == 4) {
    box = box_2d(v[0], v[1], v[2], v[3]);
  } else {
    box.min = {v[0], v[1], v[2]};
    box.max = {v[3], v[4], v[5]};
  }
  const char* axis_names[3] = {"x", "y", "z"};
  const double mins[3] = {box.min.x, box.min.y, box.min.z};
  const double maxs[3] = {box.max.x, box.max.y, box.max.z};
  for (int a = 0; a < 3; ++a) {
    if (mins[a] > maxs[a]) {
      error = "box '" + text + "' is empty: " + axis_names[a] + "min > " + axis_names[a] + "max";
      return false;
    }
  }
  out = box;
  return true;
}

}  // namespace relief::cli
