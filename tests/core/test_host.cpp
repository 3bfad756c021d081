// core/host.h: temporary names carry the host, and what a killed writer of
// this host left beside a destination is removed, nothing else.
#include <catch2/catch.hpp>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "core/host.h"
#include "support/dead_pid.h"
#include "support/temp_dir.h"

namespace fs = std::filesystem;
using relief::test::TempDir;

TEST_CASE("host_tag and temp_path_beside", "[core][host]") {
  const std::string tag = relief::core::host_tag();
  REQUIRE_FALSE(tag.empty());
  CHECK(tag.size() <= 64);
  CHECK(std::all_of(tag.begin(), tag.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '.' || c == '_' ||
           c == '-';
  }));
  CHECK(relief::core::temp_path_beside("d/out.las") ==
        "d/out.las.tmp-" + tag + "-" + std::to_string(::getpid()));
}

TEST_CASE("leading_pid reads the decimal pid a name starts with", "[core][host]") {
  using relief::core::leading_pid;
  CHECK(leading_pid("4321-journal").pid == 4321);
  CHECK(leading_pid("4321-journal").digits == 4);
  CHECK(leading_pid("77").pid == 77);
  CHECK(leading_pid("x12").digits == 0);
  CHECK(leading_pid("").pid == 0);
  CHECK(leading_pid("0").pid == 0);
  CHECK(leading_pid("1073741823").pid == 1073741823);  // 2^30 - 1
  CHECK(leading_pid("1073741824").pid == 0);           // 2^30: no pid here
  CHECK(leading_pid("99999999999999999999").pid == 0);
}

TEST_CASE("remove_stale_temps_beside removes a killed writer's files of this host only", "[core][host]") {
  TempDir dir;
  const std::string dead = relief::test::dead_pid();
  REQUIRE_FALSE(dead.empty());
  const std::string alive = std::to_string(::getppid());
  const std::string own = std::to_string(::getpid());
  const std::string here = relief::core::host_tag();
  const std::string other = here == "other-host" ? "another-host" : "other-host";
  const std::string out = dir.file("out.relief");
  const std::vector<std::string> removed = {
      "out.relief.tmp-" + here + "-" + dead,
      "out.relief.tmp-" + here + "-" + dead + "-journal",
      "out.relief.tmp-" + here + "-" + dead + ".tmp-" + here + "-" + dead + "-wal",
  };
  const std::vector<std::string> kept = {
      "out.relief",                                        // the destination itself
      "out.relief.tmp-" + here + "-" + alive,              // its writer runs
      "out.relief.tmp-" + here + "-" + own,                // ours
      "out.relief.tmp-" + other + "-" + dead,              // another host's pid means nothing here
      "out.relief.tmp-" + here + "-" + dead + "x",         // not our pattern
      "out.relief.tmp-" + here + "-",                      // no pid
      "other.relief.tmp-" + here + "-" + dead,             // another destination
  };
  for (const auto& n : removed) std::ofstream(dir.file(n)) << "partial";
  for (const auto& n : kept) std::ofstream(dir.file(n)) << "keep";
  // A directory under a stale name is not a file we wrote: kept.
  fs::create_directory(dir.file("out.relief.tmp-" + here + "-" + dead + ".d"));
  relief::core::remove_stale_temps_beside(out);
  for (const auto& n : removed) CHECK_FALSE(fs::exists(dir.file(n)));
  for (const auto& n : kept) CHECK(fs::exists(dir.file(n)));
  CHECK(fs::is_directory(dir.file("out.relief.tmp-" + here + "-" + dead + ".d")));
}

TEST_CASE("remove_stale_temps_in sweeps the stale temporaries of many destinations with one listing", "[core][host]") {
  TempDir dir;
  const std::string dead = relief::test::dead_pid();
  REQUIRE_FALSE(dead.empty());
  const std::string alive = std::to_string(::getppid());
  const std::string here = relief::core::host_tag();
  const std::string marker = ".tmp-" + here + "-";
  const std::vector<std::string> removed = {
      "a.rpart" + marker + dead,
      "b.rpart" + marker + dead,
      "b.rpart" + marker + dead + "-journal",
      // A destination whose own name holds the marker.
      "c" + marker + "7.rpart" + marker + dead,
  };
  const std::vector<std::string> kept = {
      "a.rpart",                             // a destination
      "a.rpart" + marker + alive,            // its writer runs
      "z.rpart" + marker + dead,             // not one of the names
      "c" + marker + "7.rpart",              // a destination, though it looks like a temporary
      "a.rpart.tmp-other-host-" + dead,      // another host
      marker + dead,                         // no destination name before the marker
  };
  for (const auto& n : removed) std::ofstream(dir.file(n)) << "partial";
  for (const auto& n : kept) std::ofstream(dir.file(n)) << "keep";
  relief::core::remove_stale_temps_in(dir.path().string(), {"a.rpart", "b.rpart", "c" + marker + "7.rpart"});
  for (const auto& n : removed) CHECK_FALSE(fs::exists(dir.file(n)));
  for (const auto& n : kept) CHECK(fs::exists(dir.file(n)));
  // No names, or a directory that is not there: nothing happens.
  relief::core::remove_stale_temps_in(dir.path().string(), {});
  relief::core::remove_stale_temps_in(dir.file("missing"), {"a.rpart"});
  for (const auto& n : kept) CHECK(fs::exists(dir.file(n)));
}
