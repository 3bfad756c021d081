// A pid that no longer exists, for tests of the sweeps that remove what a
// killed process left: a child that has exited and been reaped (its pid is
// free until the system reuses it, which takes a wrap of the pid space).
#pragma once

#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <string>

namespace relief::test {

// The pid as text, or "" when fork or waitpid failed (the caller REQUIREs it).
inline std::string dead_pid() {
  const pid_t child = ::fork();
  if (child < 0) return {};
  if (child == 0) ::_exit(0);
  if (::waitpid(child, nullptr, 0) != child) return {};
  return std::to_string(child);
}

}  // namespace relief::test
