#include "summary.h"

#include "relief/codec.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

std::vector<CurvePoint> pareto_front(std::vector<CurvePoint> points) {
  std::erase_if(points, [](const CurvePoint& p) {
    return !std::isfinite(p.bpp) || !std::isfinite(p.rmse) || p.bpp < 0 || p.rmse < 0;
  });
  // stable_sort: among equal (bpp, rmse) the first measured row is kept.
  std::stable_sort(points.begin(), points.end(), [](const CurvePoint& a, const CurvePoint& b) {
    return a.bpp != b.bpp ? a.bpp < b.bpp : a.rmse < b.rmse;
  });
  std::vector<CurvePoint> front;
  for (CurvePoint& p : points) {
    // Scanning by increasing rate, a point is on the front iff it is more
    // accurate than everything cheaper.
    if (front.empty() || p.rmse < front.back().rmse) front.push_back(std::move(p));
  }
  return front;
}

std::optional<double> bpp_at_rmse(const std::vector<CurvePoint>& front, double rmse) {
  // Logarithms need positive values; a lossless (rmse 0) or free point cannot
  // take part in a log-log interpolation.
  std::vector<const CurvePoint*> usable;
  for (const CurvePoint& p : front) {
    if (p.bpp > 0 && p.rmse > 0) usable.push_back(&p);
  }
  if (usable.empty() || !(rmse > 0)) return std::nullopt;
  // The front runs from high rmse (cheap) to low rmse (expensive).
  if (rmse > usable.front()->rmse || rmse < usable.back()->rmse) return std::nullopt;
  if (usable.size() == 1) return usable.front()->bpp;  // rmse equals the only point's
  for (std::size_t i = 0; i + 1 < usable.size(); ++i) {
    const CurvePoint& hi = *usable[i];      // larger rmse, fewer bits
    const CurvePoint& lo = *usable[i + 1];  // smaller rmse, more bits
    if (rmse <= hi.rmse && rmse >= lo.rmse) {
      const double t = (std::log(rmse) - std::log(hi.rmse)) / (std::log(lo.rmse) - std::log(hi.rmse));
      return std::exp(std::log(hi.bpp) + t * (std::log(lo.bpp) - std::log(hi.bpp)));
    }
  }
  return std::nullopt;  // unreachable for a proper front
}

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        fields.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        fields.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      fields.emplace_back();
    } else if (c != '\r') {
      fields.back() += c;
    }
  }
  return fields;
}

namespace {

std::optional<double> parse_double(const std::string& s) {
  if (s.empty()) return std::nullopt;
  char* end = nullptr;
  const double v = std::strtod(s.c_str(), &end);
  if (end != s.c_str() + s.size()) return std::nullopt;
  return v;
}

}  // namespace

relief::Result<std::vector<CurvePoint>> read_anchor_curve(const std::string& csv_path, const std::string& codec) {
  std::ifstream in(csv_path);
  if (!in) return relief::io_error(csv_path + ": cannot open");
  std::string line;
  if (!std::getline(in, line)) return relief::format_error(csv_path + ": empty");
  const std::vector<std::string> header = split_csv_line(line);
  auto column = [&header](const std::string& name) -> int {
    const auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? -1 : static_cast<int>(it - header.begin());
  };
  const int c_codec = column("codec");
  const int c_bpp = column("bpp");
  const int c_rmse = column("rmse_snn");
  const int c_setting = column("setting");
  const int c_points_dec = column("points_dec");
  const int c_rgb = column("rmse_rgb_snn");
  if (c_codec < 0 || c_bpp < 0 || c_rmse < 0) {
    return relief::format_error(csv_path + ": header lacks codec, bpp or rmse_snn");
  }
  std::vector<CurvePoint> points;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    const std::vector<std::string> f = split_csv_line(line);
    auto field = [&f](int c) -> std::string { return c >= 0 && c < static_cast<int>(f.size()) ? f[c] : ""; };
    if (field(c_codec) != codec) continue;
    const auto bpp = parse_double(field(c_bpp));
    const auto rmse = parse_double(field(c_rmse));
    if (!bpp || !rmse) {
      return relief::format_error(csv_path + ":" + std::to_string(line_no) + ": bad bpp or rmse_snn");
    }
    CurvePoint p;
    p.bpp = *bpp;
    p.rmse = *rmse;
    if (auto n = parse_double(field(c_points_dec))) p.points_out = static_cast<std::size_t>(*n);
    if (auto rgb = parse_double(field(c_rgb))) p.rmse_rgb = *rgb;
    p.label = codec + " " + field(c_setting);
    points.push_back(std::move(p));
  }
  return points;
}

namespace {

// A reference codec curve for the comparison columns.
struct Reference {
  std::string name;    // "draco", "tmc13"
  std::string source;  // where the rows came from, for the reader
  std::vector<CurvePoint> front;
};

std::string describe(const Reference& ref) {
  if (ref.front.empty()) return ref.name + ": no rows (" + ref.source + ")";
  char buf[256];
  std::snprintf(buf, sizeof buf, "%s: %s, Pareto front of %zu points, rmse_snn %.4g..%.4g at %.4g..%.4g bpp",
                ref.name.c_str(), ref.source.c_str(), ref.front.size(), ref.front.back().rmse,
                ref.front.front().rmse, ref.front.back().bpp, ref.front.front().bpp);
  return buf;
}

Reference anchor_reference(const std::string& anchors_dir, const std::string& stem, const std::string& codec) {
  Reference ref;
  ref.name = codec;
  if (anchors_dir.empty()) {
    ref.source = "no anchors directory";
    return ref;
  }
  const std::string path = (std::filesystem::path(anchors_dir) / ("results-" + stem + ".csv")).string();
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) {
    ref.source = path + " absent";
    return ref;
  }
  auto curve = read_anchor_curve(path, codec);
  if (!curve) {
    note("error: %s", curve.status().to_string().c_str());
    ref.source = "unreadable anchors file";
    return ref;
  }
  ref.source = "anchors " + std::filesystem::path(path).filename().string();
  ref.front = pareto_front(std::move(*curve));
  return ref;
}

struct Comparison {
  int wins = 0;          // relief needs fewer bits than the reference
  int in_range = 0;      // Pareto points where the reference could be interpolated
  int out_of_range = 0;
  double best_ratio = std::numeric_limits<double>::quiet_NaN();
  double worst_ratio = std::numeric_limits<double>::quiet_NaN();
};

}  // namespace

void print_file_summary(Output& out, const FileSummaryInput& in) {
  std::vector<CurvePoint> relief_points;
  std::vector<CurvePoint> draco_rows;
  for (const BenchRow& r : in.rows) {
    CurvePoint p;
    p.bpp = r.bpp;
    p.rmse = r.rmse_snn;
    p.points_out = r.points_out;
    p.rmse_rgb = r.rmse_rgb_snn;
    p.label = row_label(r);
    if (r.codec == "relief") relief_points.push_back(std::move(p));
    if (r.codec == "draco") draco_rows.push_back(std::move(p));
  }
  const std::size_t relief_configs = relief_points.size();
  const std::vector<CurvePoint> front = pareto_front(std::move(relief_points));

  std::vector<Reference> refs;
  if (in.draco_measured) {
    refs.push_back({"draco", "measured here", pareto_front(std::move(draco_rows))});
  } else {
    // Without a local Draco the anchors' Draco rows are the next best reference.
    refs.push_back(anchor_reference(in.anchors_dir, in.stem, "draco"));
    refs.back().source = "not measured here; " + refs.back().source;
  }
  refs.push_back(anchor_reference(in.anchors_dir, in.stem, "tmc13"));

  out.line("#");
  out.linef("# ==== summary %s: %zu points, %s ====", in.stem.c_str(), in.points,
            in.has_colour ? "colour" : "no colour");
  for (const Reference& ref : refs) out.linef("# reference %s", describe(ref).c_str());
  out.linef("# relief Pareto front (bpp vs rmse_snn): %zu of %zu configurations", front.size(), relief_configs);
  if (front.empty()) {
    out.linef("# verdict %s: no relief rows", in.stem.c_str());
    return;
  }
  // Fixed-width columns so the block reads as a table.
  std::string head = "#   relief_bpp    rmse_snn  points_out";
  if (in.has_colour) head += "  rmse_rgb";
  for (const Reference& ref : refs) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "  %12s  %12s", (ref.name + "_bpp").c_str(), ("relief/" + ref.name).c_str());
    head += buf;
  }
  head += "  config";
  out.line(head);

  std::vector<Comparison> comparisons(refs.size());
  for (const CurvePoint& p : front) {
    char buf[160];
    std::snprintf(buf, sizeof buf, "#   %10.4f  %10.4g  %10zu", p.bpp, p.rmse, p.points_out);
    std::string text = buf;
    if (in.has_colour) {
      std::snprintf(buf, sizeof buf, "  %8.3f", p.rmse_rgb);
      text += buf;
    }
    for (std::size_t k = 0; k < refs.size(); ++k) {
      const std::optional<double> ref_bpp = bpp_at_rmse(refs[k].front, p.rmse);
      Comparison& c = comparisons[k];
      if (!ref_bpp) {
        ++c.out_of_range;
        std::snprintf(buf, sizeof buf, "  %26s", "out of range");
      } else {
        ++c.in_range;
        const double ratio = *ref_bpp > 0 ? p.bpp / *ref_bpp : std::numeric_limits<double>::infinity();
        if (ratio < 1) ++c.wins;
        if (std::isnan(c.best_ratio) || ratio < c.best_ratio) c.best_ratio = ratio;
        if (std::isnan(c.worst_ratio) || ratio > c.worst_ratio) c.worst_ratio = ratio;
        std::snprintf(buf, sizeof buf, "  %12.4f  %12.3f", *ref_bpp, ratio);
      }
      text += buf;
    }
    text += "  " + p.label;
    out.line(text);
  }

  for (std::size_t k = 0; k < refs.size(); ++k) {
    const Comparison& c = comparisons[k];
    std::string extra;
    if (c.in_range > 0) {
      char buf[96];
      std::snprintf(buf, sizeof buf, "; relief/%s bpp ratio %.3g..%.3g", refs[k].name.c_str(), c.best_ratio,
                    c.worst_ratio);
      extra = buf;
    }
    out.linef("# verdict %s: relief beats %s at equal RMSE_SNN on %d of %d Pareto points (%d more out of %s's "
              "measured RMSE range)%s",
              in.stem.c_str(), refs[k].name.c_str(), c.wins, c.in_range, c.out_of_range, refs[k].name.c_str(),
              extra.c_str());
  }

  // (d) Speed of the fast path, voxel grid + JPEG, single thread: the library's
  // default configuration (cell = c0, default quality, push-pull) and the best row.
  const relief::EncodeParams defaults;
  const BenchRow* def = nullptr;
  const BenchRow* best_enc = nullptr;
  const BenchRow* best_dec = nullptr;
  for (const BenchRow& r : in.rows) {
    if (r.codec != "relief" || r.decomposition != "voxel" || r.image != "jpeg" || r.height_bits != 8) continue;
    if (r.fill == "project" && r.cell_multiplier == 1.0 && r.quality == defaults.height_quality) def = &r;
    if (std::isfinite(r.enc_mpts_s) && (best_enc == nullptr || r.enc_mpts_s > best_enc->enc_mpts_s)) best_enc = &r;
    if (std::isfinite(r.dec_mpts_s) && (best_dec == nullptr || r.dec_mpts_s > best_dec->dec_mpts_s)) best_dec = &r;
  }
  if (def != nullptr) {
    out.linef("# speed %s: default voxel+jpeg (%s): encode %.2f Mpts/s, decode %.2f M output pts/s = %.2f M input "
              "pts/s, lod 4 decode %.2fx faster, 1 thread",
              in.stem.c_str(), row_label(*def).c_str(), def->enc_mpts_s, def->dec_mpts_s, def->dec_in_mpts_s,
              def->dec_seconds / def->lod4_seconds);
  }
  if (best_enc != nullptr && best_dec != nullptr) {
    out.linef("# speed %s: best voxel+jpeg encode %.2f Mpts/s (%s), decode %.2f M output pts/s = %.2f M input pts/s "
              "(%s), 1 thread",
              in.stem.c_str(), best_enc->enc_mpts_s, row_label(*best_enc).c_str(), best_dec->dec_mpts_s,
              best_dec->dec_in_mpts_s, row_label(*best_dec).c_str());
  } else {
    out.linef("# speed %s: no voxel+jpeg rows", in.stem.c_str());
  }
  // (e) Fill: the default (block projection) against push-pull alone and the
  // paper's box filter at equal settings.
  for (const BenchRow& box : in.rows) {
    if (box.codec != "relief" || box.fill == "project") continue;
    for (const BenchRow& pp : in.rows) {
      if (pp.codec != "relief" || pp.fill != "project" || pp.decomposition != box.decomposition ||
          pp.image != box.image || pp.quality != box.quality || pp.height_bits != box.height_bits ||
          pp.cell_multiplier != box.cell_multiplier) {
        continue;
      }
      out.linef("# fill %s %s: projection %zu bytes rmse_snn %.5g rgb %.4g vs %s %zu bytes rmse_snn %.5g rgb %.4g "
                "(%+.1f%% bytes)",
                in.stem.c_str(), row_label(pp).c_str(), pp.bytes, pp.rmse_snn, pp.rmse_rgb_snn, box.fill.c_str(),
                box.bytes, box.rmse_snn, box.rmse_rgb_snn,
                100.0 * (static_cast<double>(pp.bytes) - static_cast<double>(box.bytes)) /
                    static_cast<double>(box.bytes));
    }
  }
  const BenchRow* draco_enc = nullptr;
  const BenchRow* draco_dec = nullptr;
  for (const BenchRow& r : in.rows) {
    if (r.codec != "draco") continue;
    if (draco_enc == nullptr || r.enc_mpts_s > draco_enc->enc_mpts_s) draco_enc = &r;
    if (draco_dec == nullptr || r.dec_mpts_s > draco_dec->dec_mpts_s) draco_dec = &r;
  }
  if (draco_enc != nullptr) {
    out.linef("# speed %s: best draco encode %.2f Mpts/s (qp=%d), decode %.2f Mpts/s (qp=%d), whole process",
              in.stem.c_str(), draco_enc->enc_mpts_s, draco_enc->quality, draco_dec->dec_mpts_s, draco_dec->quality);
  }
}
