// Running another codec's command-line tools (Draco) from the benchmark:
// finding them on PATH, a private scratch directory, and timed child processes.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "relief/status.h"

// The first executable file called `name` in the directories of $PATH.
std::optional<std::filesystem::path> find_on_path(const std::string& name);

// A fresh directory under std::filesystem::temp_directory_path(), removed with
// everything in it when the object goes away.
class ScratchDir {
 public:
  static relief::Result<ScratchDir> create(const std::string& prefix);
  ScratchDir(ScratchDir&& other) noexcept;
  ScratchDir& operator=(ScratchDir&&) = delete;
  ScratchDir(const ScratchDir&) = delete;
  ScratchDir& operator=(const ScratchDir&) = delete;
  ~ScratchDir();

  const std::filesystem::path& path() const { return path_; }

 private:
  explicit ScratchDir(std::filesystem::path p) : path_(std::move(p)) {}
  std::filesystem::path path_;
};

// Runs `argv` (argv[0] = the program's path; no shell, so no quoting issues)
// with stdin from /dev/null and stdout+stderr into `log_path`, and waits for it.
// Returns the whole-process wall time in seconds, or an error that quotes the
// end of the log when the program fails to start or exits non-zero.
relief::Result<double> run_timed(const std::vector<std::string>& argv, const std::filesystem::path& log_path);
