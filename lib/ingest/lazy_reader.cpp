#include "ingest/lazy_reader.h"

#include <sys/stat.h>

#include <utility>

namespace relief::ingest {

namespace {

class LazyReader final : public PointReader {
 public:
  LazyReader(std::string path, ReaderOptions options, PointStreamInfo info)
      : path_(std::move(path)), options_(std::move(options)), info_(std::move(info)) {}

  const PointStreamInfo& info() const override { return open_ ? open_->info() : info_; }

  Result<std::size_t> read(PointCloud& batch, std::size_t max_points) override {
    if (done_) {
      batch = PointCloud();
      return std::size_t{0};
    }
    if (!open_) {
      RELIEF_ASSIGN_OR_RETURN(open_, open_point_reader(path_, options_));
    }
    RELIEF_ASSIGN_OR_RETURN(const std::size_t got, open_->read(batch, max_points));
    if (got == 0) {
      info_ = open_->info();
      open_.reset();
      done_ = true;
    }
    return got;
  }

 private:
  std::string path_;
  ReaderOptions options_;
  PointStreamInfo info_;  // as opened, then as at the end
  std::unique_ptr<PointReader> open_;
  bool done_ = false;
};

}  // namespace

Result<std::unique_ptr<PointReader>> open_lazy_reader(const std::string& path, const ReaderOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<PointReader> reader, open_point_reader(path, options));
  // Only a regular file reads the same the second time: standard input, a
  // named pipe or a process substitution (/dev/fd/N) is read once, so it
  // stays open.
  struct stat st {};
  if (path == "-" || ::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return reader;
  PointStreamInfo info = reader->info();
  reader.reset();
  return std::unique_ptr<PointReader>(new LazyReader(path, options, std::move(info)));
}

}  // namespace relief::ingest
