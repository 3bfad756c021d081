// A point reader that holds its file open only while it is being read.
// An ingest opens every input up front (a missing or unsupported file fails
// before anything is created) and then reads them one after the other; a
// survey delivered as thousands of tiles would otherwise keep thousands of
// files open, each with its read buffer (~1 MiB): past the process's file
// limit (often 1024) the ingest failed, and the buffers alone outgrew the
// memory budget. Internal to ingest.
#pragma once

#include <memory>
#include <string>

#include "relief/io.h"

namespace relief::ingest {

// Opens `path` to check it and take its info(), then closes it again; the
// first read() opens it anew and reads on from its first point; the read that
// finds its end (returns 0) keeps the final info() (counts of skipped points,
// warnings, the colour-level rule, which only reading settles) and closes it.
// Later reads return 0. Only regular files are reopened: standard input
// ("-"), a named pipe or a /dev/fd/N cannot be read twice and stay open.
Result<std::unique_ptr<PointReader>> open_lazy_reader(const std::string& path, const ReaderOptions& options);

}  // namespace relief::ingest
