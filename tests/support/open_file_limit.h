// Runs a library call in a child process whose soft limit on open files is
// lowered, as on machines with a small `ulimit -n`. Test support.
#pragma once

#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <functional>

#include "relief/status.h"

namespace relief::test {

// The child's exit code: 0 when `call` succeeded under at most `limit` open
// files, 1 when it failed (its status printed on stderr), 3 when the limit
// could not be set; -1 when the child did not exit.
inline int with_open_file_limit(rlim_t limit, const std::function<Status()>& call) {
  const pid_t pid = ::fork();
  if (pid < 0) return -1;
  if (pid == 0) {
    struct rlimit l {};
    if (::getrlimit(RLIMIT_NOFILE, &l) != 0) ::_exit(3);
    l.rlim_cur = limit;
    if (::setrlimit(RLIMIT_NOFILE, &l) != 0) ::_exit(3);
    const Status s = call();
    if (!s.is_ok()) std::fprintf(stderr, "failed under %llu open files: %s\n", static_cast<unsigned long long>(limit),
                                 s.to_string().c_str());
    ::_exit(s.is_ok() ? 0 : 1);
  }
  int status = 0;
  if (::waitpid(pid, &status, 0) != pid || !WIFEXITED(status)) return -1;
  return WEXITSTATUS(status);
}

}  // namespace relief::test
