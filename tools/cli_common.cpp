#include "cli_common.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <signal.h>
#include <unistd.h>

namespace relief::cli {

int exit_code_for(const Status& status) {
  if (status.is_ok()) return kExitOk;
  return 10 + static_cast<int>(status.code());
}

int fail(const std::string& command, const Status& status) {
  std::cerr << "relief " << command << ": " << status.message() << " ["
            << status_code_name(status.code()) << "]\n";
  return exit_code_for(status);
}

int usage_error(const std::string& command, const std::string& message) {
  // The error and where to look, not the whole help: the one line that
  // matters would otherwise scroll away under it.
  std::cerr << "relief " << command << ": " << message << "\n"
            << "see 'relief " << command << " --help'\n";
  return kExitUsage;
}

std::string memory_option(const std::string& text, std::uint64_t& budget) {
  IngestOptions parsed;
  if (Status st =
          apply_ingest_options(IngestOptionSet::kAppend, {{"memory", text}}, OptionSpelling::kCli, parsed);
      !st) {
    return st.message();
  }
  budget = parsed.memory_budget;
  return {};
}

int interrupted(const std::string& command, const std::string& what) {
  std::cerr << "relief " << command << ": interrupted" << what << "\n";
  return kExitInterrupted;
}

Args::Args(int argc, char** argv, std::vector<std::string> flags, std::vector<std::string> options) {
  const auto is_in = [](const std::vector<std::string>& v, const std::string& s) {
    for (const auto& x : v) {
      if (x == s) return true;
    }
    return false;
  };
  // A number right after an option's numeric value is the user's second
  // number for it (`--box 1 2 3 4`): said as such, not as a stray argument.
  const auto is_number = [](const std::string& t) {
    double v = 0;
    const char* end = t.data() + t.size();
    const auto [p, ec] = std::from_chars(t.data(), end, v);
    return !t.empty() && ec == std::errc() && p == end;
  };
  std::string numeric_option;  // the option whose numeric value came last
  for (int i = 0; i < argc; ++i) {
    std::string a = argv[i];
    // "--" ends the options, as POSIX utilities have it: what follows is
    // positional, even when it starts with '-' (a file named "-x.ply").
    if (a == "--") {
      positional_.insert(positional_.end(), argv + i + 1, argv + argc);
      return;
    }
    const std::string after = numeric_option;
    numeric_option.clear();
    if (!after.empty() && is_number(a)) {
      error_ = "option " + after + " takes one value, but '" + a +
               "' follows it: separate several numbers with commas (" + after + " 1,2,3,4)";
      return;
    }
    if (a.size() > 1 && a[0] == '-' && !(a.size() > 1 && (std::isdigit(static_cast<unsigned char>(a[1])) || a[1] == '.'))) {
      std::string name = a, value;
      bool has_value = false;
      const auto eq = a.find('=');
      if (a.rfind("--", 0) == 0 && eq != std::string::npos) {
        name = a.substr(0, eq);
        value = a.substr(eq + 1);
        has_value = true;
      }
      if (is_in(flags, name)) {
        if (has_value) {
          error_ = "option " + name + " takes no value";
          return;
        }
        values_[name] = "";
      } else if (is_in(options, name)) {
        if (!has_value) {
          if (i + 1 >= argc) {
            error_ = "option " + name + " needs a value";
            return;
          }
          value = argv[++i];
          if (is_number(value)) numeric_option = name;
        }
        values_[name] = value;
      } else {
        error_ = "unknown option " + name;
        return;
      }
    } else {
      positional_.push_back(a);
    }
  }
}

bool Args::has(const std::string& name) const { return values_.count(name) != 0; }

std::optional<std::string> Args::get(const std::string& name) const {
  const auto it = values_.find(name);
  if (it == values_.end()) return std::nullopt;
  return it->second;
}

double Args::get_double(const std::string& name, double fallback) {
  const auto v = get(name);
  if (!v) return fallback;
  double out = 0;
  const auto* end = v->data() + v->size();
  const auto res = std::from_chars(v->data(), end, out);
  if (res.ec != std::errc() || res.ptr != end || !std::isfinite(out)) {
    if (error_.empty()) error_ = "option " + name + " expects a number, got '" + *v + "'";
    return fallback;
  }
  return out;
}

long long Args::get_int(const std::string& name, long long fallback, long long lo, long long hi) {
  const auto v = get(name);
  if (!v) return fallback;
  long long out = 0;
  const auto* end = v->data() + v->size();
  const auto res = std::from_chars(v->data(), end, out);
  if (res.ec != std::errc() || res.ptr != end || out < lo || out > hi) {
    if (error_.empty()) {
      error_ = "option " + name + " expects a whole number from " + std::to_string(lo) + " to " +
               std::to_string(hi) + ", got '" + *v + "'";
    }
    return fallback;
  }
  return out;
}

const char* const kEncodeOptionsHelp =
    "Encoding options:\n"
    "  --cell SIZE            patch cell edge in coordinate units (default: from point density)\n"
    "  --decomposition voxel|octree   patch decomposition (default voxel)\n"
    "  --max-points N         octree: split leaves holding more than N points (default 1024)\n"
    "  --resolution R         map resolution, multiple of 8 in 8..64 (default 16)\n"
    "  --codec jpeg|jpeg2000  image codec for height/colour/intensity maps (default jpeg)\n"
    "  --quality Q            height map quality 1..100 (default 75)\n"
    "  --color-quality Q      colour map quality 1..100 (default 70)\n"
    "  --intensity-quality Q  intensity map quality 1..100 (default 70)\n"
    "  --height-bits 8|16     bits per height sample; 16 needs --codec jpeg2000 (default 8)\n"
    "  --fill project|pushpull|box   fill of empty map pixels (default project: push-pull, then\n"
    "                         low-frequency projection per JPEG block; box = the paper's)\n";

std::vector<std::string> encode_option_names() { return cli_names(relief::encode_option_names()); }

const char* const kBoundOptionsHelp =
    "Error-bounded blob (without --tolerance: the paper's maps alone, as above):\n"
    "  --tolerance T          every point back within T per coordinate (grid step 2T)\n"
    "  --color-tolerance C    largest error per colour channel, 0..127 (default 0 = exact)\n"
    "  --intensity-tolerance I  largest error of a 16-bit intensity, 0..32767 (default 0 = exact)\n"
    "  --keep-order           code and return the points in the order they were read\n"
    "  --fast-geometry        octree geometry without plane and near classes (chunk format 13):\n"
    "                         ~2.3x faster, ~4 % more geometry bytes\n";

std::vector<std::string> bound_option_names() { return cli_names(relief::bound_option_names()); }

std::string parse_bound_options(Args& args, EncodeParams& params) {
  std::vector<std::string> names = relief::bound_option_names();
  for (const std::string& f : relief::bound_flag_names()) names.push_back(f);
  const Status s = apply_bound_options(given_options(args, names), OptionSpelling::kCli, params);
  return s.is_ok() ? "" : s.message();
}

std::string parse_encode_params(Args& args, EncodeParams& p) {
  const Status s = apply_encode_options(given_options(args, relief::encode_option_names()), OptionSpelling::kCli, p);
  return s.is_ok() ? "" : s.message();
}

std::vector<std::string> cli_names(const std::vector<std::string>& names) {
  std::vector<std::string> out;
  out.reserve(names.size());
  for (const std::string& n : names) out.push_back("--" + n);
  return out;
}

std::vector<NamedOption> given_options(const Args& args, const std::vector<std::string>& names) {
  std::vector<NamedOption> given;
  for (const std::string& n : names) {
    if (auto v = args.get("--" + n)) given.push_back({n, *v});
  }
  return given;
}

Status check_chunk_coordinates(const PointCloud& cloud, const std::string& path) {
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const Vec3d& p = cloud.positions[i];
    for (const double v : {p.x, p.y, p.z}) {
      if (!(std::abs(v) <= kMaxCoordinateMagnitude)) {
        char value[32];
        std::snprintf(value, sizeof value, "%.9g", v);
        return invalid_argument(path + ": point " + std::to_string(i) + " has a coordinate " + value +
                                " beyond the limit of +-2^50 (README, \"Limits\")");
      }
    }
  }
  return Status::ok();
}

Result<std::vector<std::uint8_t>> read_file(const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return io_error(path + ": cannot open: " + std::strerror(errno));
  std::vector<std::uint8_t> data;
  std::uint8_t buf[1 << 16];
  std::size_t got = 0;
  while ((got = std::fread(buf, 1, sizeof buf, f)) > 0) data.insert(data.end(), buf, buf + got);
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) return io_error(path + ": read error");
  return data;
}

Status write_decoded_cloud(const char* command, const std::string& path, const PointCloud& cloud, bool ascii_ply) {
  WriterOptions w;
  w.colors = cloud.has_colors();
  w.intensity = cloud.has_intensity();
  w.las_attributes = cloud.las.carried();
  w.extra_bytes_size = cloud.las.extra_bytes_size;
  if (ascii_ply) w.ply_encoding = PlyEncoding::kAscii;
  auto writer = open_point_writer(path, w);
  if (!writer) return writer.status();
  RELIEF_RETURN_IF_ERROR((*writer)->write(cloud));
  RELIEF_RETURN_IF_ERROR((*writer)->finish());
  for (const std::string& said : (*writer)->take_warnings()) {
    std::cerr << "relief " << command << ": warning: " << said << "\n";
  }
  return Status::ok();
}

std::int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

double seconds_since(std::int64_t start_ns) { return static_cast<double>(now_ns() - start_ns) * 1e-9; }

std::uint64_t parse_size(const std::string& text) { return parse_byte_size(text); }

namespace {

std::atomic<bool> g_interrupted{false};

extern "C" void on_sigint(int) {
  if (g_interrupted.exchange(true)) {
    // Second Ctrl-C: the user insists.
    signal(SIGINT, SIG_DFL);
    raise(SIGINT);
  }
}

bool g_progress_drawn = false;

}  // namespace

const std::atomic<bool>* install_interrupt_flag() {
  struct sigaction sa {};
  sa.sa_handler = on_sigint;
  sigemptyset(&sa.sa_mask);
  sa.sa_flags = 0;  // no SA_RESTART: a blocked read returns EINTR
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
  return &g_interrupted;
}

std::string format_bytes(std::uint64_t bytes) {
  char buf[32];
  const double b = static_cast<double>(bytes);
  if (b >= 1e9) {
    std::snprintf(buf, sizeof buf, "%.2f GB", b / 1e9);
  } else if (b >= 1e6) {
    std::snprintf(buf, sizeof buf, "%.1f MB", b / 1e6);
  } else if (b >= 1e3) {
    std::snprintf(buf, sizeof buf, "%.1f kB", b / 1e3);
  } else {
    std::snprintf(buf, sizeof buf, "%llu B", static_cast<unsigned long long>(bytes));
  }
  return buf;
}

std::function<void(const IngestProgress&)> progress_printer(bool quiet) {
  if (quiet || !::isatty(STDERR_FILENO)) return {};
  // When the encoding phase began (seconds), for its own rate and ETA.
  return [encoding_since = -1.0](const IngestProgress& p) mutable {
    const double rate = p.seconds > 0 ? static_cast<double>(p.points_read) / p.seconds : 0;
    const std::string phase = p.phase;
    char eta[96] = "";
    if (p.points_total > 0 && rate > 0 && (phase == "reading" || phase == "scanning")) {
      const double left = static_cast<double>(p.points_total - std::min(p.points_total, p.points_read)) / rate;
      std::snprintf(eta, sizeof eta, " (%.0f%%, %s ETA %.0f s)",
                    100.0 * static_cast<double>(p.points_read) / static_cast<double>(p.points_total), p.phase, left);
    }
    if (phase == "encoding" && p.points_read > 0) {
      // Every point is read before the encoding phase: its total is points_read.
      if (encoding_since < 0) encoding_since = p.seconds;
      const double share = static_cast<double>(std::min(p.points_encoded, p.points_read)) /
                           static_cast<double>(p.points_read);
      const double spent = p.seconds - encoding_since;
      if (p.points_encoded > 0 && spent > 0) {
        std::snprintf(eta, sizeof eta, " (%.0f%% encoded, ETA %.0f s)", 100.0 * share,
                      spent * (1.0 - share) / share);
      } else {
        std::snprintf(eta, sizeof eta, " (%.0f%% encoded)", 100.0 * share);
      }
    }
    std::fprintf(stderr, "\r\033[K%s: %.2fM points%s, %llu chunks, %s, %.2f M points/s, %.0f s", p.phase,
                 static_cast<double>(p.points_read) * 1e-6, eta, static_cast<unsigned long long>(p.chunks_written),
                 format_bytes(p.bytes_written).c_str(), rate * 1e-6, p.seconds);
    std::fflush(stderr);
    g_progress_drawn = true;
  };
}

QueryProgress::QueryProgress(std::string out, std::uint64_t total, bool quiet)
    : out_(std::move(out)), total_(total), on_(!quiet && ::isatty(STDERR_FILENO)), start_ns_(now_ns()) {}

void QueryProgress::count(std::uint64_t points) {
  points_ += points;
  if (!on_) return;
  constexpr std::int64_t kRedrawNs = 250'000'000;
  const std::int64_t t = now_ns();
  if (t - drawn_ns_ < kRedrawNs) return;
  drawn_ns_ = t;
  const double secs = static_cast<double>(t - start_ns_) * 1e-9;
  char share[32] = "";
  if (total_ > 0) {
    std::snprintf(share, sizeof share, " (%.0f%%)",
                  100.0 * static_cast<double>(std::min(points_, total_)) / static_cast<double>(total_));
  }
  std::fprintf(stderr, "\r\033[K%s: %.2fM points%s, %.2f M points/s, %.0f s", out_.c_str(),
               static_cast<double>(points_) * 1e-6, share, secs > 0 ? static_cast<double>(points_) / secs * 1e-6 : 0.0,
               secs);
  std::fflush(stderr);
  g_progress_drawn = true;
}

CheckProgress check_progress_printer(const std::string& archive, bool quiet) {
  if (quiet || !::isatty(STDERR_FILENO)) return {};
  return [archive, start = now_ns(), drawn = std::int64_t{0}, last = std::string()](
             const char* stage, std::uint64_t done, std::uint64_t total) mutable {
    constexpr std::int64_t kRedrawNs = 250'000'000;
    const std::int64_t t = now_ns();
    if (stage == last && t - drawn < kRedrawNs) return;
    drawn = t;
    last = stage;
    char count[64] = "";
    if (total > 0) {
      std::snprintf(count, sizeof count, " %llu/%llu (%.0f%%)", static_cast<unsigned long long>(done),
                    static_cast<unsigned long long>(total),
                    100.0 * static_cast<double>(std::min(done, total)) / static_cast<double>(total));
    } else if (done > 0) {
      // Stages without a total count pages read (CheckProgress).
      std::snprintf(count, sizeof count, ", %llu pages read", static_cast<unsigned long long>(done));
    }
    std::fprintf(stderr, "\r\033[K%s: %s%s, %.0f s", archive.c_str(), stage, count,
                 static_cast<double>(t - start) * 1e-9);
    std::fflush(stderr);
    g_progress_drawn = true;
  };
}

void end_progress_line() {
  if (g_progress_drawn) std::fputc('\n', stderr);
  g_progress_drawn = false;
}

}  // namespace relief::cli
