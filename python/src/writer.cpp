#include "writer.h"

#include <algorithm>
#include <cstring>
#include <iterator>
#include <memory>
#include <optional>
#include <vector>

#include "relief/io.h"

namespace py = pybind11;

namespace relief::python {

namespace {

// Points per batch handed to the writer.
constexpr std::size_t kBatch = std::size_t{1} << 18;

// A column's data: its pointer and length, read while the GIL is held.
struct Column {
  const void* data = nullptr;
  std::size_t size = 0;
  std::size_t itemsize = 0;
};

// Copies values [first, first + n) of column `c` (elements of T) onto `out`.
template <typename T>
void append(const Column& c, std::size_t first, std::size_t n, std::vector<T>& out) {
  const T* p = static_cast<const T*>(c.data) + first;
  out.insert(out.end(), p, p + n);
}

}  // namespace

Status write_points(const std::string& path, const py::dict& columns, const py::object& extra,
                    const py::bytes& extra_vlr, const std::string& crs, double scale, std::uint64_t& written,
                    std::vector<std::string>& warnings) {
  written = 0;
  // `size`: the element size the copy below reads (colours: 1 or 2), so a
  // column of another type is refused rather than read past its end.
  const auto column = [&](const char* name, std::size_t size) -> std::optional<Column> {
    if (!columns.contains(name)) return std::nullopt;
    const auto a = py::reinterpret_borrow<py::array>(columns[name]);
    const auto itemsize = static_cast<std::size_t>(a.itemsize());
    if (a.ndim() != 1 || !(a.flags() & py::array::c_style) || (size != 0 && itemsize != size) ||
        (size == 0 && itemsize != 1 && itemsize != 2)) {
      throw py::value_error(std::string("column ") + name + " must be a 1-D C-contiguous array of its type");
    }
    return Column{a.data(), static_cast<std::size_t>(a.shape(0)), itemsize};
  };
  const std::optional<Column> x = column("x", 8), y = column("y", 8), z = column("z", 8);
  if (!x || !y || !z) return invalid_argument(path + ": the points need x, y and z");
  const std::size_t n = x->size;
  const std::optional<Column> red = column("red", 0), green = column("green", 0), blue = column("blue", 0);
  const std::optional<Column> intensity = column("intensity", 4);
  const struct {
    std::uint32_t bit;
    const char* name;
    std::size_t size;
  } las_names[] = {
      {kLasClassification, "classification", 1}, {kLasClassFlags, "class_flags", 1},
      {kLasReturnNumber, "return_number", 1},     {kLasNumberOfReturns, "number_of_returns", 1},
      {kLasScanFlags, "scan_flags", 1},           {kLasScanAngle, "scan_angle", 4},
      {kLasUserData, "user_data", 1},             {kLasPointSourceId, "point_source_id", 2},
      {kLasGpsTime, "gps_time", 8},               {kLasNir, "nir", 2},
  };
  std::optional<Column> las[std::size(las_names)];
  WriterOptions o;
  for (std::size_t k = 0; k < std::size(las_names); ++k) {
    las[k] = column(las_names[k].name, las_names[k].size);
    if (las[k]) o.las_attributes |= las_names[k].bit;
  }
  Column extra_column;
  std::uint32_t extra_size = 0;
  if (!extra.is_none()) {
    const auto a = py::reinterpret_borrow<py::array>(extra);
    if (a.ndim() != 2 || a.itemsize() != 1 || !(a.flags() & py::array::c_style)) {
      throw py::value_error("extra bytes must be an (n, size) C-contiguous uint8 array");
    }
    extra_size = static_cast<std::uint32_t>(a.shape(1));
    extra_column = {a.data(), static_cast<std::size_t>(a.shape(0)), 1};
    if (extra_size > 0) {
      o.las_attributes |= kLasExtraBytes;
      o.extra_bytes_size = extra_size;
      o.extra_bytes_vlr = std::string(extra_vlr);
    }
  }
  // Every column the same length (the package checks; a mismatch here
  // would read past an array).
  std::vector<std::size_t> sizes = {y->size, z->size};
  for (const auto* c : {&red, &green, &blue, &intensity}) {
    if (*c) sizes.push_back((*c)->size);
  }
  for (const auto& c : las) {
    if (c) sizes.push_back(c->size);
  }
  if (extra_size > 0) sizes.push_back(extra_column.size);
  if (std::any_of(sizes.begin(), sizes.end(), [&](std::size_t s) { return s != n; })) {
    return invalid_argument(path + ": the columns differ in length");
  }
  o.colors = red && green && blue;
  if (o.colors && (green->itemsize != red->itemsize || blue->itemsize != red->itemsize)) {
    throw py::value_error("red, green and blue must be of one type");
  }
  const bool wide = o.colors && red->itemsize == 2;
  if (wide) o.las_attributes |= kLasColorLow;
  o.intensity = intensity.has_value();
  o.crs = crs;
  o.scale = scale;

  py::gil_scoped_release release;
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointWriter> writer, open_point_writer(path, o));
  PointCloud batch;
  for (std::size_t first = 0; first < n; first += kBatch) {
    const std::size_t m = std::min(kBatch, n - first);
    batch = PointCloud();
    batch.positions.resize(m);
    const auto* xs = static_cast<const double*>(x->data) + first;
    const auto* ys = static_cast<const double*>(y->data) + first;
    const auto* zs = static_cast<const double*>(z->data) + first;
    for (std::size_t i = 0; i < m; ++i) batch.positions[i] = {xs[i], ys[i], zs[i]};
    if (o.colors) {
      batch.colors.resize(m);
      if (wide) {
        batch.las.color_low.resize(m);
        const auto* r = static_cast<const std::uint16_t*>(red->data) + first;
        const auto* g = static_cast<const std::uint16_t*>(green->data) + first;
        const auto* b = static_cast<const std::uint16_t*>(blue->data) + first;
        const auto hi = [](std::uint16_t v) { return static_cast<std::uint8_t>(v >> 8); };
        const auto lo = [](std::uint16_t v) { return static_cast<std::uint8_t>(v & 0xFF); };
        for (std::size_t i = 0; i < m; ++i) {
          batch.colors[i] = {hi(r[i]), hi(g[i]), hi(b[i])};
          batch.las.color_low[i] = {lo(r[i]), lo(g[i]), lo(b[i])};
        }
      } else {
        const auto* r = static_cast<const std::uint8_t*>(red->data) + first;
        const auto* g = static_cast<const std::uint8_t*>(green->data) + first;
        const auto* b = static_cast<const std::uint8_t*>(blue->data) + first;
        for (std::size_t i = 0; i < m; ++i) batch.colors[i] = {r[i], g[i], b[i]};
      }
    }
    if (intensity) append<float>(*intensity, first, m, batch.intensities);
    LasAttributes& a = batch.las;
    if (las[0]) append(*las[0], first, m, a.classification);
    if (las[1]) append(*las[1], first, m, a.class_flags);
    if (las[2]) append(*las[2], first, m, a.return_number);
    if (las[3]) append(*las[3], first, m, a.number_of_returns);
    if (las[4]) append(*las[4], first, m, a.scan_flags);
    if (las[5]) append(*las[5], first, m, a.scan_angle);
    if (las[6]) append(*las[6], first, m, a.user_data);
    if (las[7]) append(*las[7], first, m, a.point_source_id);
    if (las[8]) append(*las[8], first, m, a.gps_time);
    if (las[9]) append(*las[9], first, m, a.nir);
    if (extra_size > 0) {
      a.extra_bytes_size = extra_size;
      const auto* p = static_cast<const std::uint8_t*>(extra_column.data) + first * extra_size;
      a.extra_bytes.assign(p, p + m * extra_size);
    }
    RELIEF_RETURN_IF_ERROR(writer->write(batch));
  }
  RELIEF_RETURN_IF_ERROR(writer->finish());
  written = writer->points_written();
  warnings = writer->take_warnings();
  return Status::ok();
}

}  // namespace relief::python
