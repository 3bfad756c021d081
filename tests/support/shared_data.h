// ../shared/data beside the checkout (RELIEF_SHARED_DATA_DIR, set for every
// test suite): optional real point clouds. Tests that use them skip, with a
// warning, when a file is absent.
#pragma once

#include <catch2/catch.hpp>

#include <filesystem>
#include <optional>
#include <string>

namespace relief::test {

// The path of shared/data/`rel`, or nullopt (after a WARN) when it is absent.
inline std::optional<std::string> shared_file(const std::string& rel) {
  const std::string path = std::string(RELIEF_SHARED_DATA_DIR) + "/" + rel;
  if (!std::filesystem::exists(path)) {
    WARN("skipped: " << path << " is absent (optional real-data tests)");
    return std::nullopt;
  }
  return path;
}

}  // namespace relief::test
