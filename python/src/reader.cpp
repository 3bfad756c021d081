#include "reader.h"

#include <cstdint>
#include <span>
#include <utility>

namespace py = pybind11;

namespace relief::python {

namespace {

// Points per batch of a whole read: large enough to amortise a reader's
// call, small enough that a batch is not a second copy of a large file.
constexpr std::size_t kWholeReadBatch = std::size_t{1} << 20;

}  // namespace

Result<std::unique_ptr<PointFileBatches>> PointFileBatches::open(const std::string& path,
                                                                 const std::string& attributes,
                                                                 const std::string& columns, bool extra_bytes,
                                                                 std::size_t batch_points) {
  if (batch_points == 0) return invalid_argument(path + ": batch_points must be at least 1");
  ReaderOptions options;
  RELIEF_ASSIGN_OR_RETURN(options.attributes, parse_attribute_set(attributes));
  if (!columns.empty()) options.xyz_columns = columns;
  options.extra_bytes = extra_bytes;
  auto b = std::unique_ptr<PointFileBatches>(new PointFileBatches());
  RELIEF_ASSIGN_OR_RETURN(b->reader_, open_point_reader(path, options));
  b->batch_points_ = batch_points;
  const PointStreamInfo& info = b->reader_->info();
  if (!info.extra_bytes_vlr.empty()) {
    const std::span<const std::uint8_t> vlr(reinterpret_cast<const std::uint8_t*>(info.extra_bytes_vlr.data()),
                                            info.extra_bytes_vlr.size());
    RELIEF_ASSIGN_OR_RETURN(b->extra_, parse_extra_bytes_vlr(vlr, info.extra_bytes_size, path));
  }
  return b;
}

Status PointFileBatches::next(PointCloud& batch, FieldSet& fields, std::vector<std::string>& said) {
  Result<std::size_t> n = reader_->read(batch, batch_points_);
  const PointStreamInfo& info = reader_->info();
  said.assign(info.warnings.begin() + static_cast<std::ptrdiff_t>(std::min(said_, info.warnings.size())),
              info.warnings.end());
  said_ = info.warnings.size();
  if (!n) return n.status();
  if (*n == 0) batch.clear_points();
  // The fields the file announces, even for a batch without points, and
  // how its 16-bit colour fields hold levels (settled once points are read).
  fields = FieldSet{};
  fields.colors = info.has_colors;
  fields.intensity = info.has_intensity;
  fields.las = info.las_attributes;
  fields.extra_bytes_size = info.extra_bytes_size;
  fields.levels_8bit = info.las_colors_8bit;
  fields.add(batch);
  return Status::ok();
}

Status read_points(const std::string& path, const std::string& attributes, const std::string& columns,
                   bool extra_bytes, ReadPoints& out) {
  std::vector<PointCloud> batches;
  FieldSet fields;
  {
    py::gil_scoped_release release;
    RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointFileBatches> file,
                            PointFileBatches::open(path, attributes, columns, extra_bytes, kWholeReadBatch));
    for (;;) {
      PointCloud batch;
      std::vector<std::string> said;
      RELIEF_RETURN_IF_ERROR(file->next(batch, fields, said));
      out.warnings.insert(out.warnings.end(), said.begin(), said.end());
      if (batch.empty()) break;
      batches.push_back(std::move(batch));
    }
    out.extra = file->extra();
  }
  out.points = to_array(batches, fields);
  return Status::ok();
}

}  // namespace relief::python
