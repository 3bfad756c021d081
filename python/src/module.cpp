// relief._relief: the C++ side of the Python package (python/relief/__init__.py
// holds the public API). Every library call runs without the GIL; a failed
// Status becomes the relief.Error subclass of its code (made by the factory
// the package registers), never a crash.
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <atomic>
#include <cmath>
#include <cstring>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "arrays.h"
#include "batch_stream.h"
#include "reader.h"
#include "writer.h"
#include "relief/archive.h"
#include "relief/ingest.h"
#include "relief/image.h"
#include "relief/polygon.h"
#include "relief/query.h"
#include "relief/render.h"
#include "relief/status.h"

namespace py = pybind11;

namespace relief::python {

namespace {

// relief._make_error(code, code_name, message) -> an exception instance.
// Leaked on purpose: destroying a Python object at exit, after the
// interpreter is gone, would crash.
py::object* error_factory = nullptr;

[[noreturn]] void raise_status(const Status& s) {
  if (error_factory == nullptr) throw std::runtime_error(s.to_string());
  py::object e = (*error_factory)(static_cast<int>(s.code()), status_code_name(s.code()), s.message());
  PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(e.ptr())), e.ptr());
  throw py::error_already_set();
}

IngestOptionSet option_set(const std::string& command) {
  if (command == "compress") return IngestOptionSet::kCompress;
  if (command == "append") return IngestOptionSet::kAppend;
  throw py::value_error("unknown command '" + command + "'");
}

py::dict progress_dict(const IngestProgress& p) {
  py::dict d;
  d["points_read"] = p.points_read;
  d["points_total"] = p.points_total;
  d["points_encoded"] = p.points_encoded;
  d["chunks_written"] = p.chunks_written;
  d["bytes_written"] = p.bytes_written;
  d["seconds"] = p.seconds;
  d["phase"] = std::string(p.phase);
  return d;
}

py::dict result_dict(const IngestResult& r) {
  py::dict d;
  d["points_read"] = r.points_read;
  d["points_decoded"] = r.points_decoded;
  d["chunks_written"] = r.chunks_written;
  d["blob_bytes"] = r.blob_bytes;
  d["seconds"] = r.seconds;
  d["cell_size"] = r.cell_size;
  d["chunk_edge"] = r.chunk_edge;
  d["scan_id"] = r.scan_id;
  d["spooled_bytes"] = r.spooled_bytes;
  d["points_skipped"] = r.points_skipped;
  py::dict pyramid;
  pyramid["levels"] = r.pyramid.levels;
  pyramid["top_level"] = r.pyramid.top_level;
  pyramid["chunks"] = r.pyramid.chunks;
  pyramid["points"] = r.pyramid.points;
  pyramid["blob_bytes"] = r.pyramid.blob_bytes;
  pyramid["seconds"] = r.pyramid.seconds;
  d["pyramid"] = pyramid;
  d["warnings"] = r.warnings;
  return d;
}

// compress / append: `options` are (name, text) pairs already checked against
// option_names by the package; the library checks their values.
py::dict ingest(const std::string& command, const std::vector<std::string>& inputs,
                const std::string& archive, const std::vector<std::pair<std::string, std::string>>& options,
                const py::object& progress) {
  const IngestOptionSet set = option_set(command);
  IngestOptions o;
  std::vector<NamedOption> given;
  for (const auto& [name, value] : options) given.push_back({name, value});
  if (Status s = apply_ingest_options(set, given, OptionSpelling::kPython, o); !s) raise_status(s);
  o.creator = std::string("relief ") + RELIEF_VERSION + " (python)";

  // The progress callable, and Ctrl-C, are seen at the ingest's progress
  // calls (about twice a second): an exception there cancels the ingest and
  // is raised once it has stopped.
  std::atomic<bool> cancel{false};
  std::unique_ptr<py::error_already_set> pending;
  o.cancel = &cancel;
  o.progress = [&](const IngestProgress& p) {
    if (cancel.load()) return;
    py::gil_scoped_acquire gil;
    try {
      if (PyErr_CheckSignals() != 0) throw py::error_already_set();
      if (!progress.is_none()) progress(progress_dict(p));
    } catch (py::error_already_set& e) {
      pending = std::make_unique<py::error_already_set>(std::move(e));
      cancel.store(true);
    }
  };
  std::optional<Result<IngestResult>> r;
  {
    py::gil_scoped_release release;
    r.emplace(set == IngestOptionSet::kCompress ? compress_files(inputs, archive, o)
                                                : append_files(archive, inputs, o));
  }
  if (pending) {
    pending->restore();
    pending.reset();
    throw py::error_already_set();
  }
  if (!*r) raise_status(r->status());
  return result_dict(r->value());
}

std::vector<std::string> option_names(const std::string& command, bool flags) {
  const IngestOptionSet set = option_set(command);
  return flags ? ingest_flag_names(set) : ingest_option_names(set);
}

QueryOptions query_options(std::uint32_t lod, unsigned threads, bool skip_corrupt, std::uint64_t max_points,
                           const std::string& attributes, const std::string& polygon = "",
                           const std::string& polygon_crs = "") {
  if (lod < 1 || lod > kMaxQueryLod) {
    raise_status(invalid_argument("lod must be a whole number from 1 to " + std::to_string(kMaxQueryLod) +
                                  ", got " + std::to_string(lod)));
  }
  QueryOptions q;
  if (max_points > 0 && lod != 1) raise_status(invalid_argument("give lod or max_points, not both"));
  q.lod = lod;
  q.threads = threads;
  q.skip_corrupt = skip_corrupt;
  q.max_points = max_points;
  Result<AttributeSet> set = parse_attribute_set(attributes);
  if (!set) raise_status(set.status());
  q.attributes = *set;
  if (polygon.empty() && !polygon_crs.empty()) raise_status(invalid_argument("polygon_crs needs polygon"));
  if (!polygon.empty()) {
    Result<Polygon2D> area = Polygon2D::from_arg(polygon);
    if (!area) raise_status(area.status());
    if (!polygon_crs.empty()) {
      // An argument, not a file: a CRS that does not parse is a bad value (as the CLI's usage error).
      if (Status s = area->set_crs(polygon_crs, "polygon_crs"); !s)
        raise_status(invalid_argument(s.message()));
    }
    q.polygon = std::make_shared<const Polygon2D>(std::move(area).value());
  }
  return q;
}

// A box from the package: None, or 6 (3-D) or 4 (2-D: every height) numbers.
std::optional<Box3d> to_box(const std::optional<std::vector<double>>& b) {
  if (!b) return std::nullopt;
  for (const double v : *b) {
    if (!std::isfinite(v)) raise_status(invalid_argument("box values must be finite numbers"));
  }
  if (b->size() == 4) return box_2d((*b)[0], (*b)[1], (*b)[2], (*b)[3]);
  if (b->size() != 6) {
    raise_status(invalid_argument(
        "box must be (xmin, ymin, zmin, xmax, ymax, zmax) or (xmin, ymin, xmax, ymax), got " +
        std::to_string(b->size()) + " numbers"));
  }
  Box3d box;
  box.min = {(*b)[0], (*b)[1], (*b)[2]};
  box.max = {(*b)[3], (*b)[4], (*b)[5]};
  return box;
}

// The fields every array of the archive has (what its info says); batches
// may add LAS attributes the archive-level info does not list.
FieldSet archive_fields(const ArchiveInfo& info, const AttributeSet& asked) {
  FieldSet f;
  f.colors = info.has_colors && asked.colors;
  f.intensity = info.has_intensity && asked.intensity;
  f.levels_8bit = info.las_colors_8bit;
  return f;
}

// What a batch iterator's next() returns: (array, warnings) for a batch;
// at the end, the error raised in its place, else (None, warnings) when the
// last call said something, else StopIteration.
py::tuple batch_result(PointCloud batch, const FieldSet& fields, const std::vector<std::string>& warnings) {
  std::vector<PointCloud> one;
  one.push_back(std::move(batch));
  return py::make_tuple(to_array(one, fields), warnings);
}
py::tuple end_of_batches(const Status& status, const std::vector<std::string>& warnings) {
  if (!status) raise_status(status);
  if (!warnings.empty()) return py::make_tuple(py::none(), warnings);
  throw py::stop_iteration();
}

// Archive.query(batches=True) on the C++ side: next() -> (array, warnings),
// StopIteration at the end, the query's error raised in its place; once the
// archive is closed, ValueError (as a query of the closed archive raises).
class BatchIterator {
 public:
  BatchIterator(std::shared_ptr<BatchStream> stream, FieldSet fields, std::string path)
      : stream_(std::move(stream)), fields_(fields), path_(std::move(path)) {}
  ~BatchIterator() {
    py::gil_scoped_release release;
    stream_.reset();
  }

  py::tuple next() {
    if (!stream_) throw py::stop_iteration();
    // Held while the GIL is released: a close() from another thread then
    // stops the stream but does not destroy it under this call.
    const std::shared_ptr<BatchStream> stream = stream_;
    refuse_closed_archive(*stream);
    PointCloud batch;
    Status status;
    bool more = false;
    {
      py::gil_scoped_release release;
      more = stream->next(batch, status);
    }
    refuse_closed_archive(*stream);  // closed while this call waited
    std::vector<std::string> warnings = stream->take_warnings();
    if (!more) {
      close();
      return end_of_batches(status, warnings);
    }
    FieldSet f = fields_;
    f.add(batch);
    return batch_result(std::move(batch), f, warnings);
  }

  void close() {
    if (!stream_) return;
    const std::shared_ptr<BatchStream> stream = std::move(stream_);
    py::gil_scoped_release release;
    stream->close();
  }

 private:
  void refuse_closed_archive(const BatchStream& stream) const {
    if (stream.archive_closed()) throw py::value_error("the archive " + path_ + " is closed");
  }

  std::shared_ptr<BatchStream> stream_;
  FieldSet fields_;
  std::string path_;
};

// relief.read(batches=True) on the C++ side: next() -> (array, warnings),
// StopIteration at the end, the reader's error raised in its place.
class FileBatchIterator {
 public:
  explicit FileBatchIterator(std::unique_ptr<PointFileBatches> file) : file_(std::move(file)) {}
  ~FileBatchIterator() {
    py::gil_scoped_release release;
    file_.reset();
  }

  py::tuple next() {
    if (!file_) throw py::stop_iteration();
    PointCloud batch;
    FieldSet fields;
    std::vector<std::string> said;
    Status status;
    {
      py::gil_scoped_release release;
      status = file_->next(batch, fields, said);
    }
    if (!status || batch.empty()) {
      close();
      return end_of_batches(status, said);
    }
    return batch_result(std::move(batch), fields, said);
  }

  py::list extra_fields() const {
    py::list out;
    if (file_) {
      for (const ExtraBytesField& f : file_->extra()) out.append(py::make_tuple(f.name, f.type_name, f.offset, f.size));
    }
    return out;
  }

  void close() {
    py::gil_scoped_release release;
    file_.reset();
  }

 private:
  std::unique_ptr<PointFileBatches> file_;
};

// An open archive. One query at a time uses its reader (the mutex); batch
// queries open their own reader so they can run beside it.
class Reader {
 public:
  explicit Reader(const std::string& path) : path_(path) {
    Result<std::unique_ptr<ArchiveReader>> r = [&] {
      py::gil_scoped_release release;
      return ArchiveReader::open(path);
    }();
    if (!r) raise_status(r.status());
    reader_ = std::move(r).value();
  }

  std::string info_json() {
    const std::lock_guard<std::mutex> lock(mutex_);
    return archive_info_json(reader().info(), path_);
  }

  // archive_sections as JSON: every blob read, through a connection of its own.
  std::string sections_json() {
    reader();  // refuses a closed archive while the GIL is held
    Result<ArchiveSections> r = Status(internal_error("sections did not run"));
    {
      py::gil_scoped_release release;
      Result<std::unique_ptr<Archive>> archive = Archive::open(path_, Archive::Mode::kReadOnly);
      r = archive ? archive_sections(**archive) : Result<ArchiveSections>(archive.status());
    }
    if (!r) raise_status(r.status());
    return archive_sections_json(*r);
  }

  // The whole answer as one array, plus the warnings of skipped chunks.
  py::tuple query(const std::optional<std::vector<double>>& box_values, std::uint32_t lod, unsigned threads,
                  bool skip_corrupt, std::uint64_t max_points, const std::string& attributes,
                  const std::string& polygon, const std::string& polygon_crs) {
    const std::optional<Box3d> box = to_box(box_values);
    std::vector<PointCloud> batches;
    std::vector<std::string> warnings;
    QueryOptions q = query_options(lod, threads, skip_corrupt, max_points, attributes, polygon, polygon_crs);
    q.on_warning = [&warnings](const std::string& w) { warnings.push_back(w); };
    FieldSet fields;
    Result<QueryStats> r = Status(internal_error("query did not run"));
    reader();  // refuses a closed archive while the GIL is held
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> lock(mutex_);
      ArchiveReader& rd = reader();
      fields = archive_fields(rd.info(), q.attributes);
      const PointSink sink = [&](const PointCloud& batch) {
        fields.add(batch);
        batches.push_back(batch);
        return Status::ok();
      };
      r = box ? rd.query(*box, q, sink) : rd.query_all(q, sink);
    }
    if (!r) raise_status(r.status());
    return py::make_tuple(to_array(batches, fields), warnings);
  }

  // archive_stats of the box (or everything) as JSON, for the package to
  // parse, and the query's warnings.
  py::tuple stats_json(const std::optional<std::vector<double>>& box_values, unsigned threads, bool skip_corrupt,
                       const std::string& attributes, const std::string& polygon, const std::string& polygon_crs) {
    const std::optional<Box3d> box = to_box(box_values);
    std::vector<std::string> warnings;
    QueryOptions q = query_options(1, threads, skip_corrupt, 0, attributes, polygon, polygon_crs);
    q.on_warning = [&warnings](const std::string& w) { warnings.push_back(w); };
    Result<ArchiveStats> r = Status(internal_error("stats did not run"));
    reader();  // refuses a closed archive while the GIL is held
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> lock(mutex_);
      r = archive_stats(reader(), box ? &*box : nullptr, q);
    }
    if (!r) raise_status(r.status());
    return py::make_tuple(archive_stats_json(*r), warnings);
  }

  std::unique_ptr<BatchIterator> batches(const std::optional<std::vector<double>>& box_values,
                                         std::uint32_t lod, unsigned threads, bool skip_corrupt,
                                         std::uint64_t max_points, const std::string& attributes,
                                         const std::string& polygon, const std::string& polygon_crs) {
    const std::optional<Box3d> box = to_box(box_values);
    QueryOptions q = query_options(lod, threads, skip_corrupt, max_points, attributes, polygon, polygon_crs);
    reader();  // refuses a closed archive
    Result<std::unique_ptr<ArchiveReader>> own = [&] {
      py::gil_scoped_release release;
      return ArchiveReader::open(path_);
    }();
    if (!own) raise_status(own.status());
    // Refused here, before any batch, as query() refuses it.
    if (Status s = check_attributes((*own)->info(), q.attributes, path_); !s) raise_status(s);
    const FieldSet fields = archive_fields((*own)->info(), q.attributes);
    auto stream = std::make_shared<BatchStream>(std::move(own).value(), box, std::move(q));
    bool closed = false;
    {
      const std::lock_guard<std::mutex> lock(streams_mutex_);
      // Forget the streams already gone, so a long-open archive's list stays short.
      std::erase_if(streams_, [](const std::weak_ptr<BatchStream>& s) { return s.expired(); });
      closed = closed_;  // by another thread while the stream's reader opened
      if (!closed) streams_.push_back(stream);
    }
    if (closed) {
      {
        py::gil_scoped_release release;
        stream->close();
      }
      throw py::value_error("the archive " + path_ + " is closed");
    }
    return std::make_unique<BatchIterator>(std::move(stream), fields, path_);
  }

  // A preview image as an (height, width, 3) uint8 array, the figures of
  // its drawing, and the image encoded as `encoding` ("png", "jpeg", or ""
  // for none) for the package to write.
  py::tuple preview(const std::optional<std::vector<double>>& box_values, std::uint32_t lod, int width,
                    const std::string& view, double azimuth, double elevation, unsigned threads,
                    const std::string& encoding) {
    PreviewRequest request;
    request.box = to_box(box_values);
    if (lod > 0) request.lod = lod;
    request.threads = threads;
    PreviewOptions& o = request.options;
    if (width < 16 || width > kMaxPreviewSide) {
      raise_status(invalid_argument("width must be from 16 to " + std::to_string(kMaxPreviewSide)));
    }
    o.width = width;
    if (view != "top" && view != "oblique") raise_status(invalid_argument("view must be 'top' or 'oblique', got '" + view + "'"));
    o.view = view == "top" ? PreviewView::kTop : PreviewView::kOblique;
    if (!(elevation >= 0 && elevation <= 90)) raise_status(invalid_argument("elevation must be from 0 to 90 degrees"));
    if (!(std::fabs(azimuth) <= 360)) raise_status(invalid_argument("azimuth must be from -360 to 360 degrees"));
    o.azimuth_deg = azimuth;
    o.elevation_deg = elevation;
    reader();  // refuses a closed archive while the GIL is held
    Result<PreviewResult> r = Status(internal_error("preview did not run"));
    Result<std::vector<std::uint8_t>> encoded = std::vector<std::uint8_t>();
    {
      py::gil_scoped_release release;
      const std::lock_guard<std::mutex> lock(mutex_);
      r = render_preview(reader(), request);
      if (r && encoding == "png") encoded = encode_png(r->image);
      if (r && encoding == "jpeg") encoded = encode_jpeg_rgb(r->image.rgb, r->image.width, r->image.height, 90);
    }
    if (!r) raise_status(r.status());
    if (!encoded) raise_status(encoded.status());
    const PreviewImage& image = r->image;
    py::array_t<std::uint8_t> pixels({image.height, image.width, 3});
    std::memcpy(pixels.mutable_data(), image.rgb.data(), image.rgb.size());
    py::dict figures;
    figures["lod"] = r->lod;
    figures["max_points"] = r->max_points;
    figures["points_drawn"] = r->points_drawn;
    figures["points_read"] = r->stats.points;
    figures["chunks_decoded"] = r->stats.chunks_decoded;
    figures["blob_bytes_read"] = r->stats.blob_bytes_read;
    figures["pyramid_level"] = r->stats.pyramid_level;
    figures["pixel_size"] = r->pixel_size;
    figures["detail_level"] = r->detail_level;
    py::object file = py::none();
    if (!encoding.empty()) file = py::bytes(reinterpret_cast<const char*>(encoded->data()), encoded->size());
    return py::make_tuple(pixels, figures, file);
  }

  // Also stops the batch queries still running (their worker threads end
  // here): their iterators raise ValueError from then on.
  void close() {
    py::gil_scoped_release release;
    std::vector<std::weak_ptr<BatchStream>> streams;
    {
      const std::lock_guard<std::mutex> lock(streams_mutex_);
      closed_ = true;
      streams.swap(streams_);
    }
    for (const std::weak_ptr<BatchStream>& s : streams) {
      if (const std::shared_ptr<BatchStream> stream = s.lock()) stream->close_for_archive();
    }
    const std::lock_guard<std::mutex> lock(mutex_);
    reader_.reset();
  }

  bool closed() const { return reader_ == nullptr; }
  const std::string& path() const { return path_; }

 private:
  ArchiveReader& reader() {
    if (!reader_) throw py::value_error("the archive " + path_ + " is closed");
    return *reader_;
  }

  std::string path_;
  std::mutex mutex_;
  std::unique_ptr<ArchiveReader> reader_;
  std::mutex streams_mutex_;
  bool closed_ = false;                              // close() was called (streams_mutex_)
  std::vector<std::weak_ptr<BatchStream>> streams_;  // the batch queries started, to stop on close()
};

// A synthetic cloud carrying `las` (LasAttributeBits) with known values, for
// the tests of the array conversion while no reader or codec fills LAS
// attributes: point i has classification i % 32, gps_time i * 0.5, ...
py::array synthetic_las_batch(std::size_t n, std::uint32_t las, std::uint32_t extra_bytes_size) {
  PointCloud c;
  c.las.extra_bytes_size = (las & kLasExtraBytes) ? extra_bytes_size : 0;
  for (std::size_t i = 0; i < n; ++i) {
    const double v = static_cast<double>(i);
    c.positions.push_back({v, 2 * v, 3 * v});
    c.colors.push_back(
        {static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(i + 1), static_cast<std::uint8_t>(i + 2)});
    c.intensities.push_back(static_cast<float>(v) / 2);
    LasAttributes& a = c.las;
    const auto u8 = [&](std::uint32_t k) { return static_cast<std::uint8_t>((i + k) % 32); };
    if (las & kLasClassification) a.classification.push_back(u8(0));
    if (las & kLasClassFlags) a.class_flags.push_back(static_cast<std::uint8_t>(i % 16));
    if (las & kLasReturnNumber) a.return_number.push_back(u8(1) % 8);
    if (las & kLasNumberOfReturns) a.number_of_returns.push_back(7);
    if (las & kLasScanFlags) a.scan_flags.push_back(static_cast<std::uint8_t>(i % 4));
    if (las & kLasScanAngle) a.scan_angle.push_back(-1000 * static_cast<std::int32_t>(i % 90));
    if (las & kLasUserData) a.user_data.push_back(u8(5));
    if (las & kLasPointSourceId) a.point_source_id.push_back(static_cast<std::uint16_t>(1000 + i));
    if (las & kLasGpsTime) a.gps_time.push_back(v * 0.5);
    if (las & kLasNir) a.nir.push_back(static_cast<std::uint16_t>(65535 - i));
    if (las & kLasColorLow) a.color_low.push_back({0x11, 0x22, 0x33});
    if (las & kLasExtraBytes) {
      for (std::uint32_t k = 0; k < extra_bytes_size; ++k)
        a.extra_bytes.push_back(static_cast<std::uint8_t>(i + k));
    }
  }
  FieldSet f;
  f.add(c);
  return to_array({c}, f);
}

}  // namespace

PYBIND11_MODULE(_relief, m) {
  m.doc() = "C++ side of the relief package (use `import relief`).";
  m.attr("__version__") = RELIEF_VERSION;
  // pybind11 (2.10, Debian 12) looks numpy's C API up on first use inside a
  // function-local static whose guard it holds while it imports numpy, which
  // can let another thread take the GIL: two threads making their first
  // array at once then wait on each other for ever (the guard and the GIL;
  // fixed upstream in pybind11 2.12). Looked up here, while the module is
  // imported, so no query makes the first array.
  (void)py::array_t<std::uint8_t>(0);
  m.def("_set_error_factory", [](py::object f) { error_factory = new py::object(std::move(f)); });
  m.def("status_codes", [] {
    py::dict d;
    for (int c = static_cast<int>(StatusCode::kInvalidArgument); c <= static_cast<int>(StatusCode::kInternal);
         ++c) {
      d[py::int_(c)] = status_code_name(static_cast<StatusCode>(c));
    }
    return d;
  });
  m.def("retain_freed_memory", [] { retain_freed_memory(); });
  m.def("option_names", &option_names, py::arg("command"), py::arg("flags"));
  m.def("ingest", &ingest, py::arg("command"), py::arg("inputs"), py::arg("archive"), py::arg("options"),
        py::arg("progress"));
  m.def(
      "file_stats_json",
      [](const std::string& path, const std::string& attributes) {
        ReaderOptions options;
        Result<AttributeSet> set = parse_attribute_set(attributes);
        if (!set) raise_status(set.status());
        options.attributes = *set;
        Result<ArchiveStats> r = Status(internal_error("stats did not run"));
        {
          py::gil_scoped_release release;
          r = point_file_stats(path, options);
        }
        if (!r) raise_status(r.status());
        return archive_stats_json(*r);
      },
      py::arg("path"), py::arg("attributes"));

  m.def(
      "check",
      [](const std::string& path) {
        Result<ArchiveCheck> r = Status(internal_error("check did not run"));
        {
          py::gil_scoped_release release;
          r = check_archive(path, nullptr, chunk_row_check());
        }
        if (!r) raise_status(r.status());
        py::dict d;
        d["format_version"] = r->format_version;
        d["intact"] = r->problems.empty();
        d["checked"] = r->checked;
        d["problems"] = r->problems;
        return d;
      },
      py::arg("path"));

  py::class_<BatchIterator>(m, "BatchIterator")
      .def("__iter__", [](BatchIterator& it) -> BatchIterator& { return it; })
      .def("__next__", &BatchIterator::next)
      .def("close", &BatchIterator::close);

  py::class_<FileBatchIterator>(m, "FileBatchIterator")
      .def("__iter__", [](FileBatchIterator& it) -> FileBatchIterator& { return it; })
      .def("__next__", &FileBatchIterator::next)
      .def("extra_fields", &FileBatchIterator::extra_fields)
      .def("close", &FileBatchIterator::close);
  m.def(
      "read_batches",
      [](const std::string& path, const std::string& attributes, const std::string& columns, bool extra_bytes,
         std::size_t batch_points) {
        Result<std::unique_ptr<PointFileBatches>> file = Status(internal_error("not opened"));
        {
          py::gil_scoped_release release;
          file = PointFileBatches::open(path, attributes, columns, extra_bytes, batch_points);
        }
        if (!file) raise_status(file.status());
        return std::make_unique<FileBatchIterator>(std::move(file).value());
      },
      py::arg("path"), py::arg("attributes"), py::arg("columns"), py::arg("extra_bytes"), py::arg("batch_points"));

  py::class_<Reader>(m, "Reader")
      .def(py::init<const std::string&>(), py::arg("path"))
      .def("info_json", &Reader::info_json)
      .def("sections_json", &Reader::sections_json)
      .def("query", &Reader::query, py::arg("box"), py::arg("lod"), py::arg("threads"),
           py::arg("skip_corrupt"), py::arg("max_points"), py::arg("attributes"), py::arg("polygon"),
           py::arg("polygon_crs"))
      .def("stats_json", &Reader::stats_json, py::arg("box"), py::arg("threads"), py::arg("skip_corrupt"),
           py::arg("attributes"), py::arg("polygon"),
           py::arg("polygon_crs"))
      .def("batches", &Reader::batches, py::arg("box"), py::arg("lod"), py::arg("threads"),
           py::arg("skip_corrupt"), py::arg("max_points"), py::arg("attributes"), py::arg("polygon"),
           py::arg("polygon_crs"))
      .def("preview", &Reader::preview, py::arg("box"), py::arg("lod"), py::arg("width"), py::arg("view"),
           py::arg("azimuth"), py::arg("elevation"), py::arg("threads"), py::arg("encoding"))
      .def("close", &Reader::close)
      .def_property_readonly("closed", &Reader::closed)
      .def_property_readonly("path", &Reader::path);

  m.def(
      "read_points",
      [](const std::string& path, const std::string& attributes, const std::string& columns, bool extra_bytes) {
        ReadPoints r;
        if (const Status s = read_points(path, attributes, columns, extra_bytes, r); !s) raise_status(s);
        py::list extra;
        for (const ExtraBytesField& f : r.extra) extra.append(py::make_tuple(f.name, f.type_name, f.offset, f.size));
        return py::make_tuple(r.points, r.warnings, extra);
      },
      py::arg("path"), py::arg("attributes"), py::arg("columns"), py::arg("extra_bytes"));
  m.def(
      "write_points",
      [](const std::string& path, const py::dict& columns, const py::object& extra, const py::bytes& extra_vlr,
         const std::string& crs, double scale) {
        std::uint64_t written = 0;
        std::vector<std::string> warnings;
        if (const Status s = write_points(path, columns, extra, extra_vlr, crs, scale, written, warnings); !s) {
          raise_status(s);
        }
        return py::make_tuple(written, warnings);
      },
      py::arg("path"), py::arg("columns"), py::arg("extra"), py::arg("extra_vlr"), py::arg("crs"),
      py::arg("scale"));
  m.def("_synthetic_las_batch", &synthetic_las_batch, py::arg("n"), py::arg("las"),
        py::arg("extra_bytes_size"));
  m.attr("LAS_BITS") =
      py::dict(py::arg("classification") = static_cast<std::uint32_t>(kLasClassification),
               py::arg("class_flags") = static_cast<std::uint32_t>(kLasClassFlags),
               py::arg("return_number") = static_cast<std::uint32_t>(kLasReturnNumber),
               py::arg("number_of_returns") = static_cast<std::uint32_t>(kLasNumberOfReturns),
               py::arg("scan_flags") = static_cast<std::uint32_t>(kLasScanFlags),
               py::arg("scan_angle") = static_cast<std::uint32_t>(kLasScanAngle),
               py::arg("user_data") = static_cast<std::uint32_t>(kLasUserData),
               py::arg("point_source_id") = static_cast<std::uint32_t>(kLasPointSourceId),
               py::arg("gps_time") = static_cast<std::uint32_t>(kLasGpsTime),
               py::arg("nir") = static_cast<std::uint32_t>(kLasNir),
               py::arg("color_low") = static_cast<std::uint32_t>(kLasColorLow),
               py::arg("extra_bytes") = static_cast<std::uint32_t>(kLasExtraBytes));
}

}  // namespace relief::python
