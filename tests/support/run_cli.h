// Runs the relief CLI (RELIEF_CLI, set by the test's CMake target) through the
// shell and captures its exit code and output, for CLI tests.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <string>

namespace relief::test {

struct CliRun {
  int code = -1;       // exit code; -1 when the process did not exit normally
  std::string output;  // stdout and stderr together
};

inline CliRun run_cli(const std::string& cli, const std::string& args) {
  const std::string cmd = cli + " " + args + " 2>&1";
  CliRun r;
  FILE* p = ::popen(cmd.c_str(), "r");
  if (p == nullptr) return r;
  std::array<char, 4096> buf{};
  std::size_t n = 0;
  while ((n = std::fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int status = ::pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

}  // namespace relief::test
