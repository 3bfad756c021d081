#include "core/host.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <filesystem>
#include <string>
#include <unordered_set>

namespace relief::core {

std::string host_tag() {
  char host[256] = {};
  if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
  std::string tag;
  for (const char* c = host; *c != '\0' && tag.size() < 64; ++c) {
    const bool keep = (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') || (*c >= '0' && *c <= '9') ||
                      *c == '.' || *c == '_' || *c == '-';
    tag.push_back(keep ? *c : '_');
  }
  return tag.empty() ? std::string("host") : tag;
}

std::string temp_path_beside(const std::string& path) {
  return path + ".tmp-" + host_tag() + "-" + std::to_string(::getpid());
}

LeadingPid leading_pid(std::string_view text) {
  std::uint64_t pid = 0;
  std::size_t k = 0;
  for (; k < text.size() && text[k] >= '0' && text[k] <= '9'; ++k) {
    pid = pid * 10 + static_cast<std::uint64_t>(text[k] - '0');
    if (pid >= (1u << 30)) return {0, k + 1};
  }
  return {static_cast<pid_t>(pid), k};
}

bool pid_gone(pid_t pid) { return ::kill(pid, 0) != 0 && errno == ESRCH; }

void remove_stale_temps_in(const std::string& directory, const std::unordered_set<std::string>& names) {
  namespace fs = std::filesystem;
  if (names.empty()) return;
  const fs::path dir = directory.empty() ? fs::path(".") : fs::path(directory);
  const std::string marker = ".tmp-" + host_tag() + "-";
  std::error_code ec;
  fs::directory_iterator it(dir, ec);
  if (ec) return;
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    if (ec) return;
    const std::string name = it->path().filename().string();
    // NAME.tmp-HOST-PID[(.|-)...] for a NAME of the set: every place the
    // marker occurs may end NAME (a name may hold the marker itself).
    bool stale = false;
    for (std::size_t at = name.find(marker); at != std::string::npos && !stale; at = name.find(marker, at + 1)) {
      if (at == 0 || names.count(name.substr(0, at)) == 0) continue;
      const std::size_t start = at + marker.size();
      const LeadingPid owner = leading_pid(std::string_view(name).substr(start));
      const std::size_t k = start + owner.digits;
      if (owner.pid == 0 || (k < name.size() && name[k] != '.' && name[k] != '-')) continue;
      stale = owner.pid != ::getpid() && pid_gone(owner.pid);
    }
    if (!stale || !fs::is_regular_file(it->symlink_status(ec)) || ec) continue;
    std::error_code ignored;
    fs::remove(it->path(), ignored);
  }
}

void remove_stale_temps_beside(const std::string& path) {
  const std::filesystem::path target(path);
  remove_stale_temps_in(target.has_parent_path() ? target.parent_path().string() : std::string("."),
                        {target.filename().string()});
}

}  // namespace relief::core
