#include "external_codec.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <random>
#include <sstream>
#include <system_error>

extern char** environ;

namespace fs = std::filesystem;

std::optional<fs::path> find_on_path(const std::string& name) {
  const char* path_env = std::getenv("PATH");
  if (path_env == nullptr) return std::nullopt;
  std::stringstream dirs(path_env);
  std::string dir;
  while (std::getline(dirs, dir, ':')) {
    // An empty PATH entry means the current directory (POSIX).
    const fs::path candidate = (dir.empty() ? fs::path(".") : fs::path(dir)) / name;
    std::error_code ec;
    if (fs::is_regular_file(candidate, ec) && ::access(candidate.c_str(), X_OK) == 0) return candidate;
  }
  return std::nullopt;
}

relief::Result<ScratchDir> ScratchDir::create(const std::string& prefix) {
  std::error_code ec;
  const fs::path base = fs::temp_directory_path(ec);
  if (ec) return relief::io_error("no temporary directory: " + ec.message());
  // pid + random suffix: unique across concurrent benchmark runs; create_directory
  // reports an existing name, so a collision just draws again.
  std::random_device rd;
  for (int attempt = 0; attempt < 16; ++attempt) {
    char suffix[32];
    std::snprintf(suffix, sizeof suffix, "%d-%08x", static_cast<int>(::getpid()), static_cast<unsigned>(rd()));
    fs::path p = base / (prefix + suffix);
    if (fs::create_directory(p, ec)) return ScratchDir(std::move(p));
    if (ec) return relief::io_error("cannot create " + p.string() + ": " + ec.message());
  }
  return relief::io_error("cannot find an unused scratch directory name under " + base.string());
}

ScratchDir::ScratchDir(ScratchDir&& other) noexcept : path_(std::move(other.path_)) { other.path_.clear(); }

ScratchDir::~ScratchDir() {
  if (path_.empty()) return;
  std::error_code ec;  // best effort: a destructor must not throw
  fs::remove_all(path_, ec);
}

namespace {

// The last few lines of a tool's log, for an error message.
std::string log_tail(const fs::path& log_path) {
  std::ifstream in(log_path);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  constexpr std::size_t kMax = 400;
  if (text.size() > kMax) text = "..." + text.substr(text.size() - kMax);
  while (!text.empty() && (text.back() == '\n' || text.back() == '\r')) text.pop_back();
  for (char& c : text) {
    if (c == '\n') c = '|';
  }
  return text;
}

}  // namespace

relief::Result<double> run_timed(const std::vector<std::string>& argv, const fs::path& log_path) {
  if (argv.empty()) return relief::invalid_argument("run_timed: empty command");
  std::vector<char*> args;
  args.reserve(argv.size() + 1);
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, log_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);

  // The clock covers spawn to reap: what a command-line user pays, as the
  // anchors measured it (process start, PLY parsing and writing included).
  const auto t0 = std::chrono::steady_clock::now();
  pid_t pid = 0;
  const int rc = posix_spawn(&pid, args[0], &actions, nullptr, args.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) return relief::io_error("cannot start " + argv[0] + ": " + std::strerror(rc));
  int wstatus = 0;
  while (::waitpid(pid, &wstatus, 0) < 0) {
    if (errno != EINTR) return relief::internal_error("waitpid(" + argv[0] + "): " + std::strerror(errno));
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (WIFSIGNALED(wstatus)) {
    return relief::internal_error(argv[0] + " killed by signal " + std::to_string(WTERMSIG(wstatus)) + ": " +
                                  log_tail(log_path));
  }
  if (!WIFEXITED(wstatus) || WEXITSTATUS(wstatus) != 0) {
    return relief::internal_error(argv[0] + " exited with status " + std::to_string(WEXITSTATUS(wstatus)) +
                                  ": " + log_tail(log_path));
  }
  return seconds;
}
