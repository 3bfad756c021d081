// Runs a program (the relief CLI) as a child process and measures it: wall
// time from fork to exit, exit code, and the child's peak RSS. Shared by the
// bench programs that time the CLI end to end.
#pragma once

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <vector>

namespace relief::bench {

struct ChildRun {
  int code = -1;  // exit code; -1 when the child could not start or did not exit normally
  double seconds = 0;
  long peak_rss_kib = 0;
};

inline ChildRun run_child(const std::vector<std::string>& argv) {
  ChildRun r;
  const auto t0 = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid < 0) return r;
  if (pid == 0) {
    std::vector<char*> args;
    for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    ::execv(args[0], args.data());
    ::_exit(127);
  }
  int status = 0;
  struct rusage usage {};
  ::wait4(pid, &status, 0, &usage);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.peak_rss_kib = usage.ru_maxrss;
  return r;
}

}  // namespace relief::bench
