#include "core/host.h"

#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <filesystem>

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

void remove_stale_temps_beside(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
  const std::string prefix = target.filename().string() + ".tmp-" + host_tag() + "-";
  std::error_code ec;
  fs::directory_iterator it(dir, ec);
  if (ec) return;
  for (; it != fs::directory_iterator(); it.increment(ec)) {
    if (ec) return;
    const std::string name = it->path().filename().string();
    if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) continue;
    const LeadingPid owner = leading_pid(std::string_view(name).substr(prefix.size()));
    const std::size_t k = prefix.size() + owner.digits;
    if (owner.pid == 0 || (k < name.size() && name[k] != '.' && name[k] != '-')) continue;
    if (owner.pid == ::getpid()) continue;
    if (!fs::is_regular_file(it->symlink_status(ec)) || ec) continue;
    if (!pid_gone(owner.pid)) continue;
    std::error_code ignored;
    fs::remove(it->path(), ignored);
  }
}

}  // namespace relief::core
