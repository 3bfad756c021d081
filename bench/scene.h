// A seeded synthetic aerial survey, generated point by point as LAS 1.2
// point format 3 records (never held whole in memory): bench/ingest --billion
// streams it to `relief compress` through a pipe.
//
// The scene is a square of rolling terrain with buildings (flat and gabled
// roofs) and trees, flown in parallel strips of kSwath metres; each strip is
// scanned line by line (zigzag) across its swath with one pulse every
// kPulseSpacing metres in both directions, as an airborne scanner records
// them. A pulse that hits a tree gives two returns (canopy, then ground).
// Every record carries intensity, return numbers, scan direction and edge
// flags, classification (2 ground, 5 high vegetation, 6 building), scan
// angle, the strip as point source ID, GPS time and RGB. The density is fixed,
// so the extent grows with the point count and every size is the same kind
// of data.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace relief::bench {

class AerialScene {
 public:
  static constexpr std::size_t kRecordBytes = 34;   // LAS point format 3
  static constexpr std::size_t kHeaderBytes = 227;  // LAS 1.2 header, no VLRs
  static constexpr double kScale = 0.01;            // LAS scale: 1 cm (the bounded mode's grid)
  static constexpr double kOffsetX = 500000, kOffsetY = 4000000, kOffsetZ = 0;
  static constexpr double kPulseSpacing = 0.25;     // 16 pulses per square metre
  static constexpr double kSwath = 400;             // strip width, metres

  AerialScene(std::uint64_t points, std::uint64_t seed);

  // The LAS header for exactly `points` records.
  std::vector<unsigned char> header() const;
  // Writes up to `n` records to `out` (n * kRecordBytes bytes); returns how
  // many (0 once all points are out).
  std::size_t next(unsigned char* out, std::size_t n);
  std::uint64_t points() const { return points_; }
  // The scene's side in metres (strips x swath by the strip length).
  double side() const { return side_; }

 private:
  struct Hit {
    double z;
    std::uint8_t cls;
    std::uint8_t rgb[3];
    std::uint16_t intensity;
  };
  double ground(double x, double y) const;
  // The first surface a vertical pulse at (x, y) meets, and whether it is a
  // tree canopy (then the ground return follows).
  Hit surface(double x, double y, double g, bool* tree) const;
  std::uint64_t hash(std::uint64_t a, std::uint64_t b) const;
  void put(unsigned char* p, double x, double y, const Hit& h, int ret, int returns, bool edge) const;
  void start_line();

  std::uint64_t points_;
  std::uint64_t seed_;
  double side_;
  std::uint64_t line_pulses_;   // pulses per scan line (swath / spacing)
  std::uint64_t strip_lines_;   // lines per strip (side / spacing)
  std::uint64_t strips_;        // strips across the scene
  // Position of the next pulse.
  std::uint64_t emitted_ = 0;
  std::uint64_t strip_ = 0, line_ = 0, pulse_ = 0;
  std::uint64_t pulse_count_ = 0;  // GPS time base
  // Per scan line: the terms of ground() that depend on y only.
  double line_y_ = 0, cy1_ = 0, sy3_ = 0;
};

}  // namespace relief::bench
