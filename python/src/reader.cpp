#include "reader.h"

#include <cstdint>
#include <memory>
#include <span>
#include <utility>

#include "arrays.h"

namespace py = pybind11;

namespace relief::python {

namespace {

// Points per batch read: large enough to amortise a reader's call, small
// enough that a batch is not a second copy of a large file.
constexpr std::size_t kBatch = std::size_t{1} << 20;

}  // namespace

Status read_points(const std::string& path, const std::string& attributes, const std::string& columns,
                   bool extra_bytes, ReadPoints& out) {
  ReaderOptions options;
  RELIEF_ASSIGN_OR_RETURN(options.attributes, parse_attribute_set(attributes));
  if (!columns.empty()) options.xyz_columns = columns;
  options.extra_bytes = extra_bytes;
  std::vector<PointCloud> batches;
  FieldSet fields;
  PointStreamInfo info;
  {
    py::gil_scoped_release release;
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> reader, open_point_reader(path, options));
    for (;;) {
      PointCloud batch;
      RELIEF_ASSIGN_OR_RETURN(const std::size_t n, reader->read(batch, kBatch));
      if (n == 0) break;
      batches.push_back(std::move(batch));
    }
    info = reader->info();  // complete once read() has returned 0
  }
  // The fields the file announces, even when it holds no point.
  fields.colors = info.has_colors;
  fields.intensity = info.has_intensity;
  fields.las = info.las_attributes;
  fields.extra_bytes_size = info.extra_bytes_size;
  fields.levels_8bit = info.las_colors_8bit;
  for (const PointCloud& b : batches) fields.add(b);
  out.points = to_array(batches, fields);
  out.warnings = std::move(info.warnings);
  if (!info.extra_bytes_vlr.empty()) {
    const std::span<const std::uint8_t> vlr(reinterpret_cast<const std::uint8_t*>(info.extra_bytes_vlr.data()),
                                            info.extra_bytes_vlr.size());
    RELIEF_ASSIGN_OR_RETURN(out.extra, parse_extra_bytes_vlr(vlr, info.extra_bytes_size, path));
  }
  return Status::ok();
}

}  // namespace relief::python
