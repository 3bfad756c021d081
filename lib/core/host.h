// The name of the machine, as it goes into temporary file names. Internal.
#pragma once

#include <string>

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

}  // namespace relief::core
