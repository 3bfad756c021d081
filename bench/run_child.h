// Runs a program (the relief CLI) as a child process and measures it: wall
// time from fork to exit, exit code, and the child's peak RSS. Shared by the
// bench programs that time the CLI end to end.
#pragma once

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <functional>
#include <string>
#include <thread>
#include <vector>

namespace relief::bench {

struct ChildRun {
  int code = -1;  // exit code; -1 when the child could not start or did not exit normally
  double seconds = 0;
  long peak_rss_kib = 0;
  double cpu_seconds = 0;  // user + system time of the child
};

// `while_running`, when given, is called about every `interval_s` seconds
// until the child exits (e.g. to sample its temporary files).
inline ChildRun run_child(const std::vector<std::string>& argv,
                          const std::function<void()>& while_running = nullptr, double interval_s = 0.25) {
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
  if (while_running) {
    // The wait runs on its own thread, so the sampling does not round the
    // child's wall time up to the sampling interval.
    std::atomic<bool> done{false};
    std::thread waiter([&] {
      ::wait4(pid, &status, 0, &usage);
      r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      done.store(true);
    });
    while (!done.load()) {
      while_running();
      std::this_thread::sleep_for(std::chrono::duration<double>(interval_s));
    }
    waiter.join();
  } else {
    ::wait4(pid, &status, 0, &usage);
    r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.peak_rss_kib = usage.ru_maxrss;
  const auto secs = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) + 1e-6 * static_cast<double>(t.tv_usec);
  };
  r.cpu_seconds = secs(usage.ru_utime) + secs(usage.ru_stime);
  return r;
}

}  // namespace relief::bench
