#include "core/host.h"

#include <unistd.h>

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

}  // namespace relief::core
