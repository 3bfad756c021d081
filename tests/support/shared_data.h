// ../shared/data beside the checkout (RELIEF_SHARED_DATA_DIR, set for every
// test suite, or the RELIEF_SHARED_DATA environment variable, which wins):
// optional real point clouds. A test that finds none of the files it asks
// for is reported to ctest as skipped (support/skip.h), with a warning.
#pragma once

#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <optional>
#include <string>

#include "support/skip.h"

namespace relief::test {

// The shared data folder: $RELIEF_SHARED_DATA when set (e.g. /nonexistent to
// check the skips), else ../shared/data beside the checkout.
inline std::string shared_data_root() {
  const char* env = std::getenv("RELIEF_SHARED_DATA");
  return env != nullptr && *env != '\0' ? std::string(env) : std::string(RELIEF_SHARED_DATA_DIR);
}

// The path of shared/data/`rel`, or nullopt (after a WARN, and marking the
// test case skipped unless it finds another file) when it is absent.
inline std::optional<std::string> shared_file(const std::string& rel) {
  const std::string path = shared_data_root() + "/" + rel;
  if (!std::filesystem::exists(path)) {
    WARN("skipped: " << path << " is absent (optional real-data tests)");
    note_skipped();
    return std::nullopt;
  }
  note_present();
  return path;
}

}  // namespace relief::test
