#include "arrays.h"

#include <cstring>
#include <string>

namespace py = pybind11;

namespace relief::python {

namespace {

// One field of the dtype: where it sits in a record and how it is filled.
struct Field {
  std::string name;
  std::string format;  // numpy type string
  std::size_t offset = 0;
};

std::vector<Field> field_list(const FieldSet& f) {
  std::vector<Field> out = {{"x", "<f8"}, {"y", "<f8"}, {"z", "<f8"}};
  if (f.colors) {
    // 16-bit LAS colours keep their low bytes (LasAttributes::color_low):
    // the fields then hold the LAS values, else the 8-bit colours.
    const char* type = (f.las & kLasColorLow) ? "<u2" : "u1";
    out.push_back({"red", type});
    out.push_back({"green", type});
    out.push_back({"blue", type});
  }
  if (f.intensity) out.push_back({"intensity", "<f4"});
  const struct {
    std::uint32_t bit;
    const char* name;
    const char* format;
  } las[] = {
      {kLasClassification, "classification", "u1"},
      {kLasClassFlags, "class_flags", "u1"},
      {kLasReturnNumber, "return_number", "u1"},
      {kLasNumberOfReturns, "number_of_returns", "u1"},
      {kLasScanFlags, "scan_flags", "u1"},
      {kLasScanAngle, "scan_angle", "<i4"},
      {kLasUserData, "user_data", "u1"},
      {kLasPointSourceId, "point_source_id", "<u2"},
      {kLasGpsTime, "gps_time", "<f8"},
      {kLasNir, "nir", "<u2"},
  };
  for (const auto& a : las) {
    if (f.las & a.bit) out.push_back({a.name, a.format});
  }
  // No Extra Bytes VLR parser yet: the bytes stay one opaque field per point.
  if ((f.las & kLasExtraBytes) && f.extra_bytes_size > 0) {
    out.push_back({"extra_bytes", "V" + std::to_string(f.extra_bytes_size)});
  }
  return out;
}

template <typename T>
void put(std::uint8_t* record, std::size_t offset, T value) {
  std::memcpy(record + offset, &value, sizeof value);
}

// Writes `values` (one per point, or empty = not carried: left 0) into the
// field at `offset` of records [0, n).
template <typename T>
void fill(std::uint8_t* base, std::size_t stride, std::size_t n, std::size_t offset,
          const std::vector<T>& values) {
  if (values.size() != n) return;
  for (std::size_t i = 0; i < n; ++i) put(base + i * stride, offset, values[i]);
}

void fill_cloud(const PointCloud& c, const FieldSet& fields, const std::vector<Field>& list,
                std::uint8_t* base, std::size_t stride) {
  const std::size_t n = c.size();
  const LasAttributes& las = c.las;
  const bool wide_colors = (fields.las & kLasColorLow) != 0;
  for (const Field& f : list) {
    const std::size_t o = f.offset;
    if (f.name == "x" || f.name == "y" || f.name == "z") {
      const int axis = f.name[0] - 'x';
      for (std::size_t i = 0; i < n; ++i) {
        const Vec3d& p = c.positions[i];
        put(base + i * stride, o, axis == 0 ? p.x : axis == 1 ? p.y : p.z);
      }
    } else if (f.name == "red" || f.name == "green" || f.name == "blue") {
      if (c.colors.size() != n) continue;
      const auto channel = [&](const Rgb8& v) {
        return f.name == "red" ? v.r : f.name == "green" ? v.g : v.b;
      };
      const bool has_low = las.color_low.size() == n;
      for (std::size_t i = 0; i < n; ++i) {
        const std::uint8_t hi = channel(c.colors[i]);
        if (!wide_colors) {
          put(base + i * stride, o, hi);
        } else {
          // The LAS value, as LAS output writes it. Without stored low bytes
          // the colour was 8-bit: hi * 257 spans the 16-bit range as the LAS
          // convention scales 8-bit colours (hi itself in an archive of 8-bit
          // levels).
          const std::uint8_t lo = has_low ? channel(las.color_low[i]) : hi;
          put(base + i * stride, o, las_color_level(hi, lo, fields.levels_8bit));
        }
      }
    } else if (f.name == "intensity") {
      fill(base, stride, n, o, c.intensities);
    } else if (f.name == "classification") {
      fill(base, stride, n, o, las.classification);
    } else if (f.name == "class_flags") {
      fill(base, stride, n, o, las.class_flags);
    } else if (f.name == "return_number") {
      fill(base, stride, n, o, las.return_number);
    } else if (f.name == "number_of_returns") {
      fill(base, stride, n, o, las.number_of_returns);
    } else if (f.name == "scan_flags") {
      fill(base, stride, n, o, las.scan_flags);
    } else if (f.name == "scan_angle") {
      fill(base, stride, n, o, las.scan_angle);
    } else if (f.name == "user_data") {
      fill(base, stride, n, o, las.user_data);
    } else if (f.name == "point_source_id") {
      fill(base, stride, n, o, las.point_source_id);
    } else if (f.name == "gps_time") {
      fill(base, stride, n, o, las.gps_time);
    } else if (f.name == "nir") {
      fill(base, stride, n, o, las.nir);
    } else if (f.name == "extra_bytes") {
      const std::size_t size = fields.extra_bytes_size;
      if (las.extra_bytes_size != size || las.extra_bytes.size() != n * size) continue;
      for (std::size_t i = 0; i < n; ++i)
        std::memcpy(base + i * stride + o, las.extra_bytes.data() + i * size, size);
    }
  }
}

}  // namespace

void FieldSet::add(const PointCloud& cloud) {
  if (cloud.has_colors()) colors = true;
  if (cloud.has_intensity()) intensity = true;
  const std::uint32_t carried = cloud.las.carried();
  // Extra bytes of different sizes cannot share a field: the first size wins
  // (fill_cloud leaves the others 0).
  if ((carried & kLasExtraBytes) && extra_bytes_size == 0) extra_bytes_size = cloud.las.extra_bytes_size;
  las |= carried;
}

py::dtype make_dtype(const FieldSet& fields) {
  py::list spec;
  for (const Field& f : field_list(fields)) spec.append(py::make_tuple(f.name, f.format));
  return py::dtype::from_args(spec);
}

py::array to_array(const std::vector<PointCloud>& clouds, const FieldSet& fields) {
  std::size_t total = 0;
  for (const PointCloud& c : clouds) total += c.size();
  const py::dtype dtype = make_dtype(fields);
  std::vector<Field> list = field_list(fields);
  const py::dict offsets = dtype.attr("fields");
  for (Field& f : list) f.offset = offsets[py::str(f.name)].cast<py::tuple>()[1].cast<std::size_t>();
  py::array out(dtype, std::vector<py::ssize_t>{static_cast<py::ssize_t>(total)});
  auto* base = static_cast<std::uint8_t*>(out.mutable_data());
  const auto stride = static_cast<std::size_t>(dtype.itemsize());
  {
    py::gil_scoped_release release;
    // Fields a cloud does not carry read 0, not leftover memory.
    if (total > 0) std::memset(base, 0, total * stride);
    std::size_t at = 0;
    for (const PointCloud& c : clouds) {
      fill_cloud(c, fields, list, base + at * stride, stride);
      at += c.size();
    }
  }
  return out;
}

}  // namespace relief::python
