// The name of the machine, as it goes into temporary file names. Internal.
#pragma once

#include <sys/types.h>

#include <cstddef>
#include <string>
#include <string_view>
#include <unordered_set>

namespace relief::core {

// gethostname(), every character outside [A-Za-z0-9._-] replaced by '_' and
// cut at 64 characters ("host" if it cannot be read or is empty). Temporary
// names carry it beside the pid, so that processes on several machines that
// share a directory never take each other's files for their own.
std::string host_tag();

// path + ".tmp-<host>-<pid>": the temporary name a file is written under
// beside its destination. Two processes writing the same destination, even on
// two hosts sharing the directory (where pids repeat), never share it.
std::string temp_path_beside(const std::string& path);

// The decimal process id that `text` starts with: its value (below 2^30,
// past which no pid runs here) and how many digits it took; {0, 0} when
// `text` does not start with a digit, a value of 0 when the digits spell 0 or
// run on past 2^30.
struct LeadingPid {
  pid_t pid = 0;
  std::size_t digits = 0;
};
LeadingPid leading_pid(std::string_view text);

// True when no process `pid` runs on this host (kill(pid, 0) says ESRCH; a
// process we may not signal, EPERM, is alive).
bool pid_gone(pid_t pid);

// Removes what a process of this host killed while writing `path` left
// beside it: files named temp_path_beside(path) for another pid, followed by
// nothing or by '.' or '-' and more (SQLite's -journal and -wal, a temporary
// name made from a temporary name), whose pid no longer runs here. Names of
// other hosts are left alone (their pids mean nothing here), and so is
// anything not a regular file. Best effort: errors are ignored. One listing
// of the directory, so not for directories written file by file by the
// thousand.
void remove_stale_temps_beside(const std::string& path);

// The same for many destinations in one directory, with one listing: what a
// killed process of this host left there while writing any of `names` (file
// names, without the directory). For directories a task writes file by file
// (a shard partition's files).
void remove_stale_temps_in(const std::string& directory, const std::unordered_set<std::string>& names);

}  // namespace relief::core
