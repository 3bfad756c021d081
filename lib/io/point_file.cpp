// Format dispatch by file extension. The comparison ignores case because
// exports from Windows tools often arrive as ".PLY" or ".LAS".

#include <algorithm>
#include <array>
#include <cctype>
#include <filesystem>
#include <string>
#include <string_view>

#include "io/point_writers.h"
#include "io/readers.h"
#include "relief/io.h"

namespace relief {

namespace {

enum class Kind { kPly, kLas, kXyz, kPcd };

struct Extension {
  std::string_view extension;  // lower case, with the dot
  Kind kind;
};

constexpr std::array<Extension, 8> kExtensions = {{
    {".ply", Kind::kPly},
    {".las", Kind::kLas},
    {".laz", Kind::kLas},  // LASzip-compressed LAS (COPC too): the LAS reader decompresses it
    {".xyz", Kind::kXyz},
    {".txt", Kind::kXyz},
    {".csv", Kind::kXyz},
    {".pts", Kind::kXyz},
    {".pcd", Kind::kPcd},
}};

// Batches for read_point_file: large enough to amortise the per-call work,
// small enough that the batch buffer is not a second copy of the cloud.
constexpr std::size_t kWholeFileBatch = std::size_t{1} << 20;

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

std::string supported_list() {
  std::string out;
  for (const Extension& e : kExtensions) {
    if (!out.empty()) out += ", ";
    out += e.extension;
  }
  return out;
}

// Output formats. .csv gets commas so spreadsheets split the columns; the
// other text extensions get spaces.
enum class WriterKind { kPly, kLas, kLaz, kXyz, kCsv };

struct WriterExtension {
  std::string_view extension;  // lower case, with the dot
  WriterKind kind;
};

constexpr std::array<WriterExtension, 6> kWriterExtensions = {{
    {".ply", WriterKind::kPly},
    {".las", WriterKind::kLas},
    {".laz", WriterKind::kLaz},
    {".xyz", WriterKind::kXyz},
    {".txt", WriterKind::kXyz},
    {".csv", WriterKind::kCsv},
}};

std::string supported_writer_list() {
  std::string out;
  for (const WriterExtension& e : kWriterExtensions) {
    if (!out.empty()) out += ", ";
    out += e.extension;
  }
  return out + " (or - for XYZ text on standard output)";
}

template <typename T>
void append(std::vector<T>& to, const std::vector<T>& from) {
  to.insert(to.end(), from.begin(), from.end());
}

}  // namespace

Result<std::unique_ptr<PointReader>> open_point_reader(const std::string& path,
                                                       const ReaderOptions& options) {
  const std::string ext = lower(std::filesystem::path(path).extension().string());
  const auto it = std::find_if(kExtensions.begin(), kExtensions.end(),
                               [&](const Extension& e) { return e.extension == ext; });
  if (it == kExtensions.end()) {
    const std::string shown = ext.empty() ? "no extension" : "extension '" + ext + "'";
    return unsupported(path + ": unsupported point file format (" + shown +
                       "); supported formats: " + supported_list());
  }
  const InputSpec input{path, std::nullopt};
  switch (it->kind) {
    case Kind::kPly:
      return open_ply_reader(input);
    case Kind::kLas:
      return open_las_reader(input);
    case Kind::kXyz:
      return open_xyz_reader(input, options);
    case Kind::kPcd:
      return open_pcd_reader(input);
  }
  return internal_error(path + ": unhandled point file kind");
}

Result<std::unique_ptr<PointWriter>> open_point_writer(const std::string& path, const WriterOptions& options) {
  if (path == "-") return open_xyz_writer(path, options, ' ');
  const std::string ext = lower(std::filesystem::path(path).extension().string());
  const auto it = std::find_if(kWriterExtensions.begin(), kWriterExtensions.end(),
                               [&](const WriterExtension& e) { return e.extension == ext; });
  if (it == kWriterExtensions.end()) {
    const std::string shown = ext.empty() ? "no extension" : "extension '" + ext + "'";
    return unsupported(path + ": unsupported output format (" + shown +
                       "); supported output formats: " + supported_writer_list());
  }
  switch (it->kind) {
    case WriterKind::kPly:
      return open_ply_writer(path, options);
    case WriterKind::kLas:
      return open_las_writer(path, options);
    case WriterKind::kLaz:
      return open_las_writer(path, options, /*laz=*/true);
    case WriterKind::kXyz:
      return open_xyz_writer(path, options, ' ');
    case WriterKind::kCsv:
      return open_xyz_writer(path, options, ',');
  }
  return internal_error(path + ": unhandled output kind");
}

Result<PointCloud> read_point_file(const std::string& path) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> reader, open_point_reader(path));
  // The first batch becomes the cloud itself; later ones are appended.
  PointCloud cloud;
  RELIEF_ASSIGN_OR_RETURN(std::size_t n, reader->read(cloud, kWholeFileBatch));
  if (n == 0) return cloud;
  PointCloud batch;
  for (;;) {
    RELIEF_ASSIGN_OR_RETURN(n, reader->read(batch, kWholeFileBatch));
    if (n == 0) break;
    append(cloud.positions, batch.positions);
    append(cloud.colors, batch.colors);
    append(cloud.intensities, batch.intensities);
  }
  return cloud;
}

}  // namespace relief
