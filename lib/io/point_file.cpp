// Format dispatch by file extension. The comparison ignores case because
// exports from Windows tools often arrive as ".PLY" or ".LAS".

#include <algorithm>
#include <array>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>

#include <sys/stat.h>

#include "io/point_writers.h"
#include "io/readers.h"
#include "io/stream_support.h"
#include "relief/io.h"

namespace relief {

namespace {

enum class Kind { kPly, kLas, kXyz, kPcd, kPtx, kE57 };

struct Extension {
  std::string_view extension;  // lower case, with the dot
  Kind kind;
};

constexpr std::array<Extension, 10> kExtensions = {{
    {".ply", Kind::kPly},
    {".las", Kind::kLas},
    {".laz", Kind::kLas},  // LASzip-compressed LAS (COPC too): the LAS reader decompresses it
    {".xyz", Kind::kXyz},
    {".txt", Kind::kXyz},
    {".csv", Kind::kXyz},
    {".pts", Kind::kXyz},
    {".pcd", Kind::kPcd},
    {".ptx", Kind::kPtx},
    {".e57", Kind::kE57},
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

// A reader whose points carry only some attributes: ReaderOptions::attributes,
// without the extra bytes when ReaderOptions::extra_bytes is off (LAS/LAZ
// extra bytes and the properties PLY and PCD keep as extra bytes).
class WithAttributes final : public PointReader {
 public:
  WithAttributes(std::unique_ptr<PointReader> inner, const AttributeSet& keep) : inner_(std::move(inner)), keep_(keep) {
    sync();
  }
  const PointStreamInfo& info() const override { return info_; }
  Result<std::size_t> read(PointCloud& batch, std::size_t max_points) override {
    Result<std::size_t> n = inner_->read(batch, max_points);
    keep_attributes(batch, keep_);
    sync();
    return n;
  }

 private:
  // The inner reader's info learns things while reading (warnings, the colour rule).
  void sync() {
    info_ = inner_->info();
    info_.has_colors = info_.has_colors && keep_.colors;
    info_.has_intensity = info_.has_intensity && keep_.intensity;
    info_.las_attributes &= keep_.las_kept();
    if ((info_.las_attributes & kLasExtraBytes) == 0) {
      info_.extra_bytes_vlr.clear();
      info_.extra_bytes_size = 0;
    }
  }

  std::unique_ptr<PointReader> inner_;
  AttributeSet keep_;
  PointStreamInfo info_;
};

Result<std::unique_ptr<PointReader>> open_by_kind(const std::string& path, const ReaderOptions& options) {
  const std::string ext = lower(std::filesystem::path(path).extension().string());
  const auto it = std::find_if(kExtensions.begin(), kExtensions.end(),
                               [&](const Extension& e) { return e.extension == ext; });
  if (it == kExtensions.end()) {
    const std::string shown = ext.empty() ? "no extension" : "extension '" + ext + "'";
    return unsupported(path + ": unsupported point file format (" + shown +
                       "); supported formats: " + supported_list());
  }
  const InputSpec input{path, std::nullopt};
  std::unique_ptr<PointReader> reader;
  switch (it->kind) {
    case Kind::kPly: {
      RELIEF_ASSIGN_OR_RETURN(reader, open_ply_reader(input, options));
      break;
    }
    case Kind::kLas: {
      RELIEF_ASSIGN_OR_RETURN(reader, open_las_reader(input, options.positions_only, options.decode_threads));
      break;
    }
    case Kind::kXyz: {
      RELIEF_ASSIGN_OR_RETURN(reader, open_xyz_reader(input, options));
      break;
    }
    case Kind::kPcd:
      return open_pcd_reader(input, options);
    case Kind::kPtx:
      return open_ptx_reader(input);
    case Kind::kE57:
      return open_e57_reader(input, options);
  }
  if (!reader) return internal_error(path + ": unhandled point file kind");
  if (auto* batch = dynamic_cast<BatchPointReader*>(reader.get())) batch->hold_sample_up_to(options.color_sample_memory);
  return reader;
}

}  // namespace

Result<std::unique_ptr<PointReader>> open_point_reader(const std::string& path,
                                                       const ReaderOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> reader, open_by_kind(path, options));
  AttributeSet keep = options.attributes;
  if (!options.extra_bytes) keep.las &= ~std::uint32_t{kLasExtraBytes};
  // Nothing to drop: the reader as it is.
  const PointStreamInfo& info = reader->info();
  if ((!info.has_colors || keep.colors) && (!info.has_intensity || keep.intensity) &&
      (info.las_attributes & ~keep.las_kept()) == 0) {
    return reader;
  }
  return std::unique_ptr<PointReader>(std::make_unique<WithAttributes>(std::move(reader), keep));
}

bool is_point_file_name(const std::string& path) {
  const std::string ext = lower(std::filesystem::path(path).extension().string());
  return std::any_of(kExtensions.begin(), kExtensions.end(), [&](const Extension& e) { return e.extension == ext; });
}

Result<std::vector<std::string>> expand_inputs(const std::vector<std::string>& inputs) {
  std::vector<std::string> out;
  for (const std::string& input : inputs) {
    std::error_code ec;
    if (!std::filesystem::is_directory(input, ec)) {
      out.push_back(input);  // a file, or a path the reader will name as missing
      continue;
    }
    std::vector<std::string> found;
    std::filesystem::directory_iterator it(input, ec);
    if (ec) return io_error(input + ": cannot list the directory: " + ec.message());
    for (; it != std::filesystem::directory_iterator(); it.increment(ec)) {
      const std::filesystem::path& p = it->path();
      const std::string name = p.filename().string();
      const bool point_file = is_point_file_name(name);
      std::error_code file_ec;
      if (point_file && !name.starts_with(".") && std::filesystem::is_regular_file(p, file_ec)) {
        found.push_back(p.string());
      }
    }
    if (ec) return io_error(input + ": cannot list the directory: " + ec.message());
    if (found.empty()) {
      return invalid_argument(input + ": a directory without point files (" + supported_list() + ")");
    }
    std::sort(found.begin(), found.end());
    out.insert(out.end(), found.begin(), found.end());
  }
  return out;
}

Result<std::vector<std::string>> read_input_list(const std::string& path) {
  std::ifstream in(path);
  if (!in) return io_error(path + ": cannot open the input list: " + std::strerror(errno));
  std::vector<std::string> out;
  std::string line;
  while (std::getline(in, line)) {
    if (!line.empty() && line.back() == '\r') line.pop_back();
    const std::size_t first = line.find_first_not_of(" \t");
    if (first == std::string::npos || line[first] == '#') continue;
    const std::size_t last = line.find_last_not_of(" \t");
    out.push_back(line.substr(first, last + 1 - first));
  }
  if (in.bad()) return io_error(path + ": cannot read the input list: " + std::strerror(errno));
  if (out.empty()) return invalid_argument(path + ": the input list names no file");
  return out;
}

Status refuse_output_onto_input(const std::string& output, const std::string& input) {
  struct stat out {};
  struct stat in {};
  if (::stat(output.c_str(), &out) == 0 && ::stat(input.c_str(), &in) == 0 && out.st_dev == in.st_dev &&
      out.st_ino == in.st_ino) {
    return invalid_argument(output + ": is " + input +
                            ", the file being read; writing the output there would replace it");
  }
  return Status::ok();
}

Result<std::unique_ptr<PointWriter>> open_point_writer(const std::string& path, const WriterOptions& options) {
  if (path == "-") return open_xyz_writer(path, options, ' ');
  if (!options.read_from.empty()) RELIEF_RETURN_IF_ERROR(refuse_output_onto_input(path, options.read_from));
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
    cloud.append_points(batch);
  }
  return cloud;
}

}  // namespace relief
