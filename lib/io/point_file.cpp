// Format dispatch by file extension. New readers (LAS, XYZ, PCD) register
// here; the extension comparison ignores case because exports from Windows
// tools often arrive as ".PLY".

#include <algorithm>
#include <array>
#include <cctype>
#include <filesystem>
#include <string>

#include "relief/io.h"

namespace relief {

namespace {

using Reader = Result<PointCloud> (*)(const std::string& path);

struct Format {
  const char* extension;  // lower case, with the dot
  Reader read;
};

constexpr std::array<Format, 1> kFormats = {{
    {".ply", read_ply},
}};

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string supported_list() {
  std::string out;
  for (const Format& f : kFormats) {
    if (!out.empty()) out += ", ";
    out += f.extension;
  }
  return out;
}

}  // namespace

Result<PointCloud> read_point_file(const std::string& path) {
  const std::string ext = lower(std::filesystem::path(path).extension().string());
  for (const Format& f : kFormats) {
    if (ext == f.extension) return f.read(path);
  }
  const std::string shown = ext.empty() ? "no extension" : "extension '" + ext + "'";
  return unsupported(path + ": unsupported point file format (" + shown +
                     "); supported formats: " + supported_list());
}

}  // namespace relief
