#include "bench_common.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdarg>
#include <cstring>

const char* csv_header() {
  return "file,codec,decomposition,image,fill,cell,quality,height_bits,points_in,points_out,bytes,bpp,"
         "rmse_snn,psnr,rmse_rgb_snn,hausdorff,enc_mpts_s,dec_mpts_s,dec_in_mpts_s,dec_lod4_mpts_s,section_bytes";
}

std::string format_number(double v) {
  if (std::isnan(v)) return "";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

std::string csv_line(const BenchRow& r) {
  // No field can contain a comma or a quote (names are fixed identifiers and
  // section_bytes uses ';' and ':'), so no CSV quoting is needed.
  std::string s;
  s.reserve(256);
  s += r.file;
  s += ',' + r.codec;
  s += ',' + r.decomposition;
  s += ',' + r.image;
  s += ',' + r.fill;
  s += ',' + format_number(r.cell);
  s += ',' + (r.quality >= 0 ? std::to_string(r.quality) : std::string());
  s += ',' + (r.height_bits > 0 ? std::to_string(r.height_bits) : std::string());
  s += ',' + std::to_string(r.points_in);
  s += ',' + std::to_string(r.points_out);
  s += ',' + std::to_string(r.bytes);
  s += ',' + format_number(r.bpp);
  s += ',' + format_number(r.rmse_snn);
  s += ',' + format_number(r.psnr);
  s += ',' + format_number(r.rmse_rgb_snn);
  s += ',' + format_number(r.hausdorff);
  s += ',' + format_number(r.enc_mpts_s);
  s += ',' + format_number(r.dec_mpts_s);
  s += ',' + format_number(r.dec_in_mpts_s);
  s += ',' + format_number(r.dec_lod4_mpts_s);
  s += ',' + r.section_bytes;
  return s;
}

std::string row_label(const BenchRow& r) {
  char buf[128];
  if (r.codec == "relief") {
    std::string image = r.height_bits == 16 ? r.image + "/16bit" : r.image;
    if (r.fill == "box") image += "/boxfill";
    if (r.fill == "pushpull") image += "/pushpull";
    std::snprintf(buf, sizeof buf, "%s/%s %.2gxc0 q%d", r.decomposition.c_str(), image.c_str(),
                  r.cell_multiplier, r.quality);
  } else {
    std::snprintf(buf, sizeof buf, "%s qp=%d", r.codec.c_str(), r.quality);
  }
  return buf;
}

Output::~Output() {
  if (copy_ != nullptr) std::fclose(copy_);
}

bool Output::open_copy(const std::string& path, std::string& error) {
  copy_ = std::fopen(path.c_str(), "w");
  if (copy_ == nullptr) {
    error = path + ": " + std::strerror(errno);
    return false;
  }
  return true;
}

void Output::line(const std::string& text) {
  std::fputs(text.c_str(), stdout);
  std::fputc('\n', stdout);
  std::fflush(stdout);
  if (copy_ != nullptr) {
    std::fputs(text.c_str(), copy_);
    std::fputc('\n', copy_);
    std::fflush(copy_);
  }
}

void Output::linef(const char* format, ...) {
  char buf[1024];
  va_list args;
  va_start(args, format);
  std::vsnprintf(buf, sizeof buf, format, args);
  va_end(args);
  line(buf);
}

void note(const char* format, ...) {
  va_list args;
  va_start(args, format);
  std::vfprintf(stderr, format, args);
  va_end(args);
  std::fputc('\n', stderr);
  std::fflush(stderr);
}

double median(std::vector<double> values) {
  if (values.empty()) return std::nan("");
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

double mpts_per_s(std::size_t points, double seconds) {
  if (!(seconds > 0)) return std::nan("");
  return static_cast<double>(points) / seconds * 1e-6;
}
