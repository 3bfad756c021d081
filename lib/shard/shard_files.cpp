#include "shard/shard_files.h"

#include "core/host.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

namespace relief::shard {

std::string escape_field(const std::string& text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '\\': out += "\\\\"; break;
      case '\t': out += "\\t"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      default: out += c;
    }
  }
  return out;
}

Result<std::vector<TextLine>> split_lines(const std::string& path, const std::string& text) {
  std::vector<TextLine> lines;
  std::size_t pos = 0;
  std::size_t number = 0;
  while (pos < text.size()) {
    ++number;
    std::size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    TextLine line;
    std::string field;
    bool first = true;
    for (std::size_t i = pos; i < end; ++i) {
      const char c = text[i];
      if (c == '\t') {
        (first ? line.key : line.fields.emplace_back()) = std::move(field);
        field.clear();
        first = false;
      } else if (c == '\\') {
        const char next = i + 1 < end ? text[i + 1] : '\0';
        const char* const kFrom = "\\tnr";
        const char* const kTo = "\\\t\n\r";
        const char* hit = next != '\0' ? std::strchr(kFrom, next) : nullptr;
        if (hit == nullptr) {
          return format_error(path + ": line " + std::to_string(number) + ": a bad escape");
        }
        field += kTo[hit - kFrom];
        ++i;
      } else {
        field += c;
      }
    }
    (first ? line.key : line.fields.emplace_back()) = std::move(field);
    lines.push_back(std::move(line));
    pos = end + 1;
  }
  return lines;
}

Result<std::string> read_text(const std::string& path, std::uint64_t max_bytes) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) return io_error(path + ": cannot open: " + std::strerror(errno));
  std::string text;
  char buf[1 << 16];
  for (;;) {
    const std::size_t got = std::fread(buf, 1, sizeof buf, f);
    text.append(buf, got);
    if (text.size() > max_bytes) {
      std::fclose(f);
      return limit_exceeded(path + ": larger than " + std::to_string(max_bytes) + " bytes");
    }
    if (got < sizeof buf) break;
  }
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed) return io_error(path + ": read failed");
  return text;
}

Status sync_and_rename(int fd, const std::string& from, const std::string& to) {
  if (::fsync(fd) != 0) {
    const int err = errno;
    ::close(fd);
    ::unlink(from.c_str());
    return io_error(to + ": cannot flush to disk: " + std::strerror(err));
  }
  if (::close(fd) != 0) {
    const int err = errno;
    ::unlink(from.c_str());
    return io_error(to + ": write failed: " + std::strerror(err));
  }
  if (std::rename(from.c_str(), to.c_str()) != 0) {
    const int err = errno;
    ::unlink(from.c_str());
    return io_error(to + ": cannot rename into place: " + std::strerror(err));
  }
  return Status::ok();
}

Status write_text_atomic(const std::string& path, const std::string& text) {
  const std::string tmp = core::temp_path_beside(path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return io_error(path + ": cannot create: " + std::strerror(errno));
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int err = errno;
      ::close(fd);
      ::unlink(tmp.c_str());
      return io_error(path + ": write failed: " + std::strerror(err));
    }
    done += static_cast<std::size_t>(n);
  }
  return sync_and_rename(fd, tmp, path);
}

std::uint64_t fnv1a64(const std::string& text) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : text) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  return h;
}

std::string hex64(std::uint64_t v) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(v));
  return buf;
}

}  // namespace relief::shard
