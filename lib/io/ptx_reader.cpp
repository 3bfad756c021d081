// Leica PTX reader: the scans of a terrestrial laser scanner, each a header
// of ten lines and then the points of its grid, one a line.
//
// A scan's header (Leica's description of the format):
//
//   columns
//   rows
//   st1 st2 st3          the scanner's registered position
//   sx1 sx2 sx3          its registered X axis
//   sy1 sy2 sy3          its Y axis
//   sz1 sz2 sz3          its Z axis
//   r11 r12 r13 0        a rotation and translation M, 4 x 4, by rows: the
//   r21 r22 r23 0        point (x, y, z) of a line is at (x, y, z, 1) M in
//   r31 r32 r33 0        the file's frame
//   tr1 tr2 tr3 1
//
// then columns x rows lines "x y z intensity [red green blue]" in the
// scanner's frame (intensities 0..1, colour levels 0..255). A line whose x, y
// and z are all 0 is a direction without a return: skipped and counted in
// PointStreamInfo::skipped_points. Files hold one scan after another.
//
// The reader applies each scan's M in double precision, so every scan comes
// out in the file's frame, as the format asks (an identity gives the values as
// written: x * 1 + y * 0 + z * 0 + 0 is x exactly). The position and axes lines
// must be numbers but are not used: M carries the registration. M's fourth
// column must be 0 0 0 1. Every point line of the file has the columns of its
// first one (4 or 7). What is not so, a scan that ends early, colour levels
// that are not whole numbers 0..255 and non-finite values are errors naming
// the line; nothing is read past a malformed line, and the counts bound no
// allocation (points are read a line at a time).

#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <string_view>

#include "io/byte_source.h"
#include "io/readers.h"
#include "io/text_scan.h"
#include "relief/io.h"

namespace relief {

namespace {

// A point line is short; a line this long is not one (binary junk, say).
constexpr std::size_t kMaxPtxLine = std::size_t{1} << 16;

class PtxPointReader final : public PointReader {
 public:
  PtxPointReader(std::string name, ByteSource src) : src_(std::move(src)) {
    info_.path = std::move(name);
    info_.format = "ptx";
    info_.text_body = true;
  }

  const PointStreamInfo& info() const override { return info_; }

  // Reads up to the first point line, which settles the columns.
  Status start() {
    bool end = false;
    std::string_view line;
    RELIEF_RETURN_IF_ERROR(next_point_line(line, end));
    if (end) return Status::ok();
    const std::size_t n = split_tokens(line).size();
    if (n != 4 && n != 7) {
      return line_error("a PTX point has 4 columns (x y z intensity) or 7 (with red green blue), not " +
                        std::to_string(n));
    }
    colors_ = n == 7;
    info_.has_colors = colors_;
    info_.has_intensity = true;
    pending_.assign(line);
    has_pending_ = true;
    return Status::ok();
  }

  Result<std::size_t> read(PointCloud& batch, std::size_t max_points) override {
    batch.clear_points();  // keeps the capacity
    std::size_t got = 0;
    while (got < max_points) {
      std::string_view line;
      if (has_pending_) {
        has_pending_ = false;
        line = pending_;
      } else {
        bool end = false;
        RELIEF_RETURN_IF_ERROR(next_point_line(line, end));
        if (end) break;
      }
      bool kept = false;
      RELIEF_RETURN_IF_ERROR(parse_point(line, batch, kept));
      got += kept ? 1 : 0;
    }
    return got;
  }

 private:
  Status line_error(const std::string& what) const {
    return format_error(info_.path + ": line " + std::to_string(line_no_) + ": " + what);
  }

  // The next non-blank line, or `end` at the end of the file.
  Status next_line_of_file(std::string_view& line, bool& end) {
    for (;;) {
      LineStatus state = LineStatus::kEnd;
      RELIEF_RETURN_IF_ERROR(next_line(src_, kMaxPtxLine, line, state));
      if (state == LineStatus::kEnd) {
        end = true;
        return Status::ok();
      }
      ++line_no_;
      if (state == LineStatus::kTooLong) {
        return line_error("longer than " + std::to_string(kMaxPtxLine) + " bytes: not a PTX file");
      }
      std::size_t pos = 0;
      if (!next_token(line, pos).empty()) return Status::ok();
    }
  }

  // The next point line, past the headers of scans that begin (and any
  // scan without points); `end` at the end of the file between scans.
  Status next_point_line(std::string_view& line, bool& end) {
    end = false;
    while (left_ == 0) {
      RELIEF_RETURN_IF_ERROR(next_line_of_file(line, end));
      if (end) return Status::ok();
      RELIEF_RETURN_IF_ERROR(read_header(line));
    }
    RELIEF_RETURN_IF_ERROR(next_line_of_file(line, end));
    if (end) {
      return format_error(info_.path + ": the scan whose header is on line " + std::to_string(header_line_) +
                          " has " + std::to_string(scan_points_) + " points (" + std::to_string(columns_) + " x " +
                          std::to_string(rows_) + ") but the file ends after " +
                          std::to_string(scan_points_ - left_) + " of them (a truncated file)");
    }
    --left_;
    return Status::ok();
  }

  // A header line of exactly `n` numbers into `out`.
  Status numbers(std::string_view line, std::size_t n, double* out, const char* what) {
    std::size_t pos = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const std::string_view tok = next_token(line, pos);
      if (tok.empty() || !parse_number(tok, out[k]) || !std::isfinite(out[k])) {
        return line_error("expected " + std::string(what) + " (" + std::to_string(n) + " numbers) in the scan header");
      }
    }
    if (!next_token(line, pos).empty()) {
      return line_error("expected " + std::string(what) + " (" + std::to_string(n) +
                        " numbers) in the scan header, found more");
    }
    return Status::ok();
  }

  // A whole number alone on its line.
  Status count(std::string_view line, const char* what, std::uint64_t& out) {
    double v = 0;
    RELIEF_RETURN_IF_ERROR(numbers(line, 1, &v, what));
    if (!(v >= 0 && v <= 4294967295.0) || v != std::floor(v)) {
      return line_error("the scan's " + std::string(what) + " " + format_double(v) +
                        " is not a whole number 0..4294967295");
    }
    out = static_cast<std::uint64_t>(v);
    return Status::ok();
  }

  // The scan header whose first line is `line`.
  Status read_header(std::string_view line) {
    header_line_ = line_no_;
    RELIEF_RETURN_IF_ERROR(count(line, "number of columns", columns_));
    bool end = false;
    const auto next = [&](const char* what) -> Status {
      RELIEF_RETURN_IF_ERROR(next_line_of_file(line, end));
      if (end) {
        return format_error(info_.path + ": the scan header on line " + std::to_string(header_line_) +
                            " ends before its " + what + " (a truncated file)");
      }
      return Status::ok();
    };
    RELIEF_RETURN_IF_ERROR(next("number of rows"));
    RELIEF_RETURN_IF_ERROR(count(line, "number of rows", rows_));
    double unused[3];
    for (const char* what : {"the scanner position", "the scanner's X axis", "the scanner's Y axis",
                             "the scanner's Z axis"}) {
      RELIEF_RETURN_IF_ERROR(next(what));
      RELIEF_RETURN_IF_ERROR(numbers(line, 3, unused, what));
    }
    for (int r = 0; r < 4; ++r) {
      const char* what = "a row of the transformation matrix";
      RELIEF_RETURN_IF_ERROR(next(what));
      RELIEF_RETURN_IF_ERROR(numbers(line, 4, m_[r].data(), what));
      if (m_[r][3] != (r == 3 ? 1.0 : 0.0)) {
        return line_error("the transformation matrix's fourth column must be 0 0 0 1 (a rotation and translation)");
      }
    }
    scan_points_ = columns_ * rows_;
    left_ = scan_points_;
    return Status::ok();
  }

  Status parse_point(std::string_view line, PointCloud& batch, bool& kept) {
    double v[7] = {};
    const std::size_t want = colors_ ? 7 : 4;
    std::size_t pos = 0;
    std::size_t n = 0;
    int intensity_digits = 0;
    for (std::string_view tok = next_token(line, pos); !tok.empty(); tok = next_token(line, pos)) {
      if (n == want) {
        return line_error("a point of this file has " + std::to_string(want) + " columns, this line more");
      }
      if (!parse_number(tok, v[n])) return line_error("column " + std::to_string(n + 1) + " " + quoted(tok) +
                                                      " is not a number");
      if (!std::isfinite(v[n])) return line_error("column " + std::to_string(n + 1) + " is not finite");
      if (n == 3) intensity_digits = significant_digits(tok);
      ++n;
    }
    if (n != want) {
      return line_error("a point of this file has " + std::to_string(want) + " columns, this line " +
                        std::to_string(n));
    }
    kept = false;
    if (v[0] == 0 && v[1] == 0 && v[2] == 0) {
      ++info_.skipped_points;  // no return in this direction
      return Status::ok();
    }
    if (std::fabs(v[3]) > 3.4028234663852886e38) return line_error("intensity " + format_double(v[3]) + " is not a float");
    std::array<std::uint8_t, 3> rgb{};
    for (std::size_t c = 0; c < (colors_ ? 3u : 0u); ++c) {
      const double level = v[4 + c];
      if (!(level >= 0 && level <= 255) || level != std::floor(level)) {
        return line_error("colour level " + format_double(level) + " is not a whole number 0..255");
      }
      rgb[c] = static_cast<std::uint8_t>(level);
    }
    Vec3d p;
    p.x = v[0] * m_[0][0] + v[1] * m_[1][0] + v[2] * m_[2][0] + m_[3][0];
    p.y = v[0] * m_[0][1] + v[1] * m_[1][1] + v[2] * m_[2][1] + m_[3][1];
    p.z = v[0] * m_[0][2] + v[1] * m_[1][2] + v[2] * m_[2][2] + m_[3][2];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      return line_error("the point is not finite once the scan's matrix is applied");
    }
    note_intensity_rounding(info_.path, v[3], intensity_digits, line_no_, intensity_rounding_noted_, info_.warnings);
    batch.positions.push_back(p);
    batch.intensities.push_back(static_cast<float>(v[3]));
    if (colors_) batch.colors.push_back({rgb[0], rgb[1], rgb[2]});
    kept = true;
    return Status::ok();
  }

  ByteSource src_;
  PointStreamInfo info_;
  bool colors_ = false;
  std::string pending_;  // the first point line, read by start()
  bool has_pending_ = false;
  std::uint64_t line_no_ = 0;
  // The current scan: its header's line, grid, points and points left.
  std::uint64_t header_line_ = 0;
  std::uint64_t columns_ = 0, rows_ = 0, scan_points_ = 0, left_ = 0;
  std::array<std::array<double, 4>, 4> m_{};
  bool intensity_rounding_noted_ = false;
};

}  // namespace

Result<std::unique_ptr<PointReader>> open_ptx_reader(const InputSpec& input) {
  RELIEF_ASSIGN_OR_RETURN(ByteSource src, input.open());
  auto reader = std::make_unique<PtxPointReader>(input.name, std::move(src));
  RELIEF_RETURN_IF_ERROR(reader->start());
  return std::unique_ptr<PointReader>(std::move(reader));
}

}  // namespace relief
