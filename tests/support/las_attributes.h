// Seeded LAS attributes for codec tests: fills the LasAttributes vectors a
// bit set names, either survey-like (runs of classes, pulses of returns, a few
// flight lines, slowly growing GPS times) or uniformly random over each
// field's whole range (every bit pattern a decoder must round-trip).
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "relief/types.h"
#include "support/synthetic.h"

namespace relief::test {

inline void add_las_attributes(PointCloud& c, std::uint32_t bits, std::uint32_t extra_bytes_size, std::uint64_t seed,
                               bool uniform) {
  Rng rng(seed);
  const std::size_t n = c.size();
  LasAttributes& a = c.las;
  a = LasAttributes{};
  const auto pick = [&](std::uint64_t m) { return rng.next() % m; };
  const auto u8 = [&] { return static_cast<std::uint8_t>(rng.next()); };
  if (bits & kLasClassification) {
    static constexpr std::uint8_t kClasses[] = {1, 2, 3, 4, 5, 6, 65};
    std::uint8_t cur = 2;
    for (std::size_t i = 0; i < n; ++i) {
      if (uniform) {
        cur = u8();
      } else if (pick(10) == 0) {
        cur = kClasses[pick(7)];
      }
      a.classification.push_back(cur);
    }
  }
  if (bits & kLasClassFlags) {
    for (std::size_t i = 0; i < n; ++i) a.class_flags.push_back(uniform ? u8() : (pick(20) == 0 ? 4 : 0));
  }
  std::uint8_t rn = 1, nr = 1;
  for (std::size_t i = 0; i < n; ++i) {
    if (uniform) {
      rn = u8();
      nr = u8();
    } else if (rn >= nr) {
      nr = static_cast<std::uint8_t>(1 + pick(4));
      rn = 1;
    } else {
      ++rn;
    }
    if (bits & kLasReturnNumber) a.return_number.push_back(rn);
    if (bits & kLasNumberOfReturns) a.number_of_returns.push_back(nr);
  }
  if (bits & kLasScanFlags) {
    for (std::size_t i = 0; i < n; ++i) a.scan_flags.push_back(uniform ? u8() : static_cast<std::uint8_t>(pick(30) == 0 ? 2 : (i / 50) & 1));
  }
  if (bits & kLasScanAngle) {
    for (std::size_t i = 0; i < n; ++i) {
      a.scan_angle.push_back(uniform ? static_cast<std::int32_t>(static_cast<std::uint32_t>(rng.next()))
                                     : static_cast<std::int32_t>((static_cast<int>(i % 400) - 200) * 6 * (1 + static_cast<int>(pick(2)))));
    }
  }
  if (bits & kLasUserData) {
    for (std::size_t i = 0; i < n; ++i) a.user_data.push_back(uniform ? u8() : static_cast<std::uint8_t>(pick(8) == 0 ? 7 : 0));
  }
  if (bits & kLasPointSourceId) {
    static constexpr std::uint16_t kLines[] = {7, 8, 9, 12, 300};
    for (std::size_t i = 0; i < n; ++i) {
      a.point_source_id.push_back(uniform ? static_cast<std::uint16_t>(rng.next()) : kLines[pick(pick(3) == 0 ? 5 : 2)]);
    }
  }
  if (bits & kLasGpsTime) {
    double t = 3.0e8 + static_cast<double>(seed % 1000);
    for (std::size_t i = 0; i < n; ++i) {
      if (uniform) {
        // Any finite double: random bit patterns with NaN/Inf exponents replaced.
        std::uint64_t b = rng.next();
        if (((b >> 52) & 0x7FF) == 0x7FF) b &= ~(std::uint64_t{1} << 62);
        double d;
        std::memcpy(&d, &b, 8);
        a.gps_time.push_back(d);
      } else {
        if (pick(3) != 0) t += 1e-5 * static_cast<double>(1 + pick(100));
        if (pick(200) == 0) t -= 40.0;  // another flight line
        a.gps_time.push_back(t);
      }
    }
  }
  if (bits & kLasNir) {
    for (std::size_t i = 0; i < n; ++i) {
      a.nir.push_back(static_cast<std::uint16_t>(uniform ? rng.next() : 20000 + 50 * (i % 7) + pick(30)));
    }
  }
  if (bits & kLasColorLow) {
    if (c.colors.empty()) c.colors.assign(n, Rgb8{10, 20, 30});
    for (std::size_t i = 0; i < n; ++i) a.color_low.push_back(uniform ? Rgb8{u8(), u8(), u8()} : Rgb8{u8(), 0, 255});
  }
  if (bits & kLasExtraBytes) {
    a.extra_bytes_size = extra_bytes_size;
    for (std::size_t i = 0; i < n; ++i) {
      for (std::uint32_t j = 0; j < extra_bytes_size; ++j) {
        a.extra_bytes.push_back(uniform ? u8() : static_cast<std::uint8_t>(j % 4 == 0 ? i + pick(3) : (j % 4 == 1 ? i >> 8 : 0)));
      }
    }
  }
}

// make_airborne_scan with the LAS attributes `bits` names: its returns and
// GPS times where asked for, the others survey-like as add_las_attributes
// makes them.
inline PointCloud make_scan_with_las(const SceneOptions& o, double size, std::uint32_t bits,
                                     std::uint32_t extra_bytes_size) {
  PointCloud c = make_airborne_scan(o, size);
  const LasAttributes scanned = c.las;
  add_las_attributes(c, bits, extra_bytes_size, o.seed, false);
  if (bits & kLasReturnNumber) c.las.return_number = scanned.return_number;
  if (bits & kLasNumberOfReturns) c.las.number_of_returns = scanned.number_of_returns;
  if (bits & kLasGpsTime) c.las.gps_time = scanned.gps_time;
  return c;
}

// One point's every field as bytes: records compare as multisets this way.
inline std::string point_record(const PointCloud& c, std::size_t i) {
  std::string r;
  const auto put = [&r](const void* p, std::size_t size) { r.append(static_cast<const char*>(p), size); };
  put(&c.positions[i], sizeof(Vec3d));
  if (!c.colors.empty()) put(&c.colors[i], sizeof(Rgb8));
  if (!c.intensities.empty()) put(&c.intensities[i], sizeof(float));
  const LasAttributes& a = c.las;
  const auto col = [&](const auto& v, char tag) {
    r.push_back(tag);
    if (!v.empty()) put(&v[i], sizeof v[i]);
  };
  col(a.classification, 'c');
  col(a.class_flags, 'f');
  col(a.return_number, 'r');
  col(a.number_of_returns, 'n');
  col(a.scan_flags, 's');
  col(a.scan_angle, 'a');
  col(a.user_data, 'u');
  col(a.point_source_id, 'p');
  col(a.gps_time, 'g');
  col(a.nir, 'i');
  col(a.color_low, 'l');
  r.push_back('e');
  if (!a.extra_bytes.empty()) put(a.extra_bytes.data() + i * a.extra_bytes_size, a.extra_bytes_size);
  return r;
}

// Every point's record (point_record), sorted: clouds compare as multisets.
inline std::vector<std::string> sorted_records(const PointCloud& c) {
  std::vector<std::string> out;
  for (std::size_t i = 0; i < c.size(); ++i) out.push_back(point_record(c, i));
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace relief::test
