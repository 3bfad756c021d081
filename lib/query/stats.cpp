// Statistics of an archive's points (relief/query.h archive_stats): a query
// that decodes only the attributes asked for, summarised batch by batch.
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "query/json_text.h"
#include "relief/query.h"

namespace relief {

void ValueSummary::add(double v) {
  if (!std::isfinite(v)) {
    ++non_finite;
    return;
  }
  if (count == 0 || v < min) min = v;
  if (count == 0 || v > max) max = v;
  const long double x = v;
  const long double t = sum + x;
  sum_error += std::abs(sum) >= std::abs(x) ? (sum - t) + x : (x - t) + sum;
  sum = t;
  ++count;
}

namespace {

// A scalar extra bytes field (LAS data types 1-10) and where it lies.
struct ExtraScalar {
  std::size_t offset = 0;
  int data_type = 0;
  double scale = 1, offset_value = 0;
};

double read_scalar(const std::uint8_t* p, int type) {
  const auto le = [&](std::size_t n) {
    std::uint64_t v = 0;
    for (std::size_t k = 0; k < n; ++k) v |= std::uint64_t{p[k]} << (8 * k);
    return v;
  };
  switch (type) {
    case 1: return static_cast<double>(p[0]);
    case 2: return static_cast<double>(static_cast<std::int8_t>(p[0]));
    case 3: return static_cast<double>(static_cast<std::uint16_t>(le(2)));
    case 4: return static_cast<double>(static_cast<std::int16_t>(le(2)));
    case 5: return static_cast<double>(static_cast<std::uint32_t>(le(4)));
    case 6: return static_cast<double>(static_cast<std::int32_t>(le(4)));
    case 7: return static_cast<double>(le(8));
    case 8: return static_cast<double>(static_cast<std::int64_t>(le(8)));
    case 9: return static_cast<double>(std::bit_cast<float>(static_cast<std::uint32_t>(le(4))));
    default: return std::bit_cast<double>(le(8));
  }
}

// What a source of points carries: an archive's info or a point file's.
struct Carried {
  bool colors = false, intensity = false;
  std::uint32_t las = 0;
  std::vector<ExtraBytesField> extra;
  std::uint32_t extra_size = 0;
};

class Summariser {
 public:
  Summariser(const Carried& info, const AttributeSet& asked) {
    s_.has_colors = info.colors && asked.colors;
    s_.has_intensity = info.intensity && asked.intensity;
    s_.las = info.las & asked.las & ~std::uint32_t{kLasColorLow};
    if ((s_.las & kLasExtraBytes) != 0) {
      for (const ExtraBytesField& f : info.extra) {
        if (f.data_type < 1 || f.data_type > 10 || f.offset + f.size > info.extra_size) continue;
        const bool scaled = (f.options & 0x08) != 0, offset = (f.options & 0x10) != 0;
        scalars_.push_back({f.offset, f.data_type, scaled ? f.scale : 1.0, offset ? f.value_offset : 0.0});
        s_.extra.emplace_back(f.name, ValueSummary{});
      }
    }
  }

  void add(const PointCloud& c) {
    s_.points += c.size();
    for (const Vec3d& p : c.positions) {
      s_.x.add(p.x);
      s_.y.add(p.y);
      s_.z.add(p.z);
    }
    if (s_.has_colors) {
      for (const Rgb8& v : c.colors) {
        s_.red.add(v.r);
        s_.green.add(v.g);
        s_.blue.add(v.b);
      }
    }
    if (s_.has_intensity) {
      for (const float v : c.intensities) s_.intensity.add(v);
    }
    const LasAttributes& a = c.las;
    for (const std::uint8_t v : a.classification) ++s_.classification[v];
    for (const std::uint8_t v : a.class_flags) {
      s_.synthetic += v & 1;
      s_.key_point += (v >> 1) & 1;
      s_.withheld += (v >> 2) & 1;
      s_.overlap += (v >> 3) & 1;
    }
    for (const std::uint8_t v : a.scan_flags) {
      s_.scan_direction += v & 1;
      s_.edge_of_flight_line += (v >> 1) & 1;
      ++s_.scanner_channel[(v >> 2) & 3];
    }
    for (const std::uint8_t v : a.return_number) ++s_.return_number[v & 15];
    for (const std::uint8_t v : a.number_of_returns) ++s_.number_of_returns[v & 15];
    for (const std::int32_t v : a.scan_angle) s_.scan_angle.add(v / 1000.0);
    for (const std::uint8_t v : a.user_data) s_.user_data.add(v);
    for (const std::uint16_t v : a.point_source_id) {
      s_.point_source_id.add(v);
      if (!seen_source_[v]) {
        seen_source_[v] = true;
        ++s_.point_sources;
      }
    }
    for (const double v : a.gps_time) s_.gps_time.add(v);
    for (const std::uint16_t v : a.nir) s_.nir.add(v);
    const std::size_t width = a.extra_bytes_size;
    if (!scalars_.empty() && width > 0 && a.extra_bytes.size() == width * c.size()) {
      for (std::size_t i = 0; i < c.size(); ++i) {
        const std::uint8_t* point = a.extra_bytes.data() + i * width;
        for (std::size_t k = 0; k < scalars_.size(); ++k) {
          const ExtraScalar& f = scalars_[k];
          s_.extra[k].second.add(read_scalar(point + f.offset, f.data_type) * f.scale + f.offset_value);
        }
      }
    }
  }

  ArchiveStats take() { return std::move(s_); }

 private:
  ArchiveStats s_;
  std::vector<ExtraScalar> scalars_;
  std::vector<bool> seen_source_ = std::vector<bool>(65536, false);
};

std::string summary_json(const ValueSummary& v) {
  std::string out = "{\"count\": " + std::to_string(v.count);
  if (v.count > 0) {
    out += ", \"min\": " + json::json_number(v.min) + ", \"max\": " + json::json_number(v.max) +
           ", \"mean\": " + json::json_number(v.mean());
  }
  if (v.non_finite > 0) out += ", \"non_finite\": " + std::to_string(v.non_finite);
  return out + "}";
}

template <std::size_t N>
std::string histogram_json(const std::array<std::uint64_t, N>& h) {
  std::string out = "{";
  for (std::size_t k = 0; k < N; ++k) {
    if (h[k] == 0) continue;
    out += (out.size() > 1 ? ", \"" : "\"") + std::to_string(k) + "\": " + std::to_string(h[k]);
  }
  return out + "}";
}

}  // namespace

Result<ArchiveStats> archive_stats(ArchiveReader& reader, const Box3d* box, const QueryOptions& options,
                                   const std::function<void(std::uint64_t points)>& progress) {
  if (options.lod != 1 || options.max_points != 0) {
    return invalid_argument("statistics are of every point: no level of detail or maximum number of points");
  }
  const ArchiveInfo& info = reader.info();
  Summariser sum({info.has_colors, info.has_intensity, info.las_attributes, archive_extra_bytes_fields(info),
                  info.extra_bytes_size},
                 options.attributes);
  const PointSink sink = [&](const PointCloud& batch) {
    sum.add(batch);
    if (progress) progress(batch.size());
    return Status::ok();
  };
  RELIEF_RETURN_IF_ERROR((box != nullptr ? reader.query(*box, options, sink) : reader.query_all(options, sink)).status());
  return sum.take();
}

Result<ArchiveStats> point_file_stats(const std::string& path, const ReaderOptions& options,
                                      const std::function<void(std::uint64_t points)>& progress) {
  // Read in batches smaller than the colour rule's sample: held, the sample
  // is decoded once (for LAZ, its first 2^20 points are not decompressed twice).
  ReaderOptions read_options = options;
  read_options.color_sample_memory = std::max<std::uint64_t>(read_options.color_sample_memory, std::uint64_t{128} << 20);
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> reader, open_point_reader(path, read_options));
  // A reader knows some things only once it has read (a PLY's extra
  // properties do not change, but a text file's colour rule may): the
  // summary is set up from the first batch's info.
  PointCloud batch;
  std::optional<Summariser> sum;
  for (;;) {
    RELIEF_ASSIGN_OR_RETURN(const std::size_t n, reader->read(batch, std::size_t{1} << 16));
    if (!sum) {
      const PointStreamInfo& i = reader->info();
      Carried c{i.has_colors, i.has_intensity, i.las_attributes, {}, i.extra_bytes_size};
      if (!i.extra_bytes_vlr.empty()) {
        const std::span<const std::uint8_t> vlr(reinterpret_cast<const std::uint8_t*>(i.extra_bytes_vlr.data()),
                                                i.extra_bytes_vlr.size());
        if (auto fields = parse_extra_bytes_vlr(vlr, i.extra_bytes_size, path)) c.extra = std::move(fields).value();
      }
      sum.emplace(c, options.attributes);
    }
    if (n == 0) break;
    sum->add(batch);
    if (progress) progress(n);
  }
  return sum->take();
}

std::string archive_stats_json(const ArchiveStats& s) {
  std::string out = "{\"points\": " + std::to_string(s.points);
  out += ", \"x\": " + summary_json(s.x) + ", \"y\": " + summary_json(s.y) + ", \"z\": " + summary_json(s.z);
  if (s.has_colors) {
    out += ", \"red\": " + summary_json(s.red) + ", \"green\": " + summary_json(s.green) +
           ", \"blue\": " + summary_json(s.blue);
  }
  if (s.has_intensity) out += ", \"intensity\": " + summary_json(s.intensity);
  const auto has = [&](std::uint32_t bit) { return (s.las & bit) != 0; };
  if (has(kLasClassification)) out += ", \"classification\": " + histogram_json(s.classification);
  if (has(kLasClassFlags)) {
    out += ", \"class_flags\": {\"synthetic\": " + std::to_string(s.synthetic) +
           ", \"key_point\": " + std::to_string(s.key_point) + ", \"withheld\": " + std::to_string(s.withheld) +
           ", \"overlap\": " + std::to_string(s.overlap) + "}";
  }
  if (has(kLasReturnNumber)) out += ", \"return_number\": " + histogram_json(s.return_number);
  if (has(kLasNumberOfReturns)) out += ", \"number_of_returns\": " + histogram_json(s.number_of_returns);
  if (has(kLasScanFlags)) {
    out += ", \"scan_flags\": {\"scan_direction\": " + std::to_string(s.scan_direction) +
           ", \"edge_of_flight_line\": " + std::to_string(s.edge_of_flight_line) +
           ", \"scanner_channel\": " + histogram_json(s.scanner_channel) + "}";
  }
  if (has(kLasScanAngle)) out += ", \"scan_angle\": " + summary_json(s.scan_angle);
  if (has(kLasUserData)) out += ", \"user_data\": " + summary_json(s.user_data);
  if (has(kLasPointSourceId)) {
    out += ", \"point_source_id\": " + summary_json(s.point_source_id) +
           ", \"point_sources\": " + std::to_string(s.point_sources);
  }
  if (has(kLasGpsTime)) out += ", \"gps_time\": " + summary_json(s.gps_time);
  if (has(kLasNir)) out += ", \"nir\": " + summary_json(s.nir);
  if (has(kLasExtraBytes)) {
    out += ", \"extra_bytes\": {";
    for (std::size_t k = 0; k < s.extra.size(); ++k) {
      out += (k > 0 ? ", " : "") + json::json_string(s.extra[k].first) + ": " + summary_json(s.extra[k].second);
    }
    out += "}";
  }
  return out + "}\n";
}

}  // namespace relief
