// Streaming XYZ/CSV writer: one line "x y z [r g b] [i]" per point, with
// shortest round-trip doubles, so the XYZ reader gets every coordinate back
// bit for bit. Standard output ("-") is written through the same buffer and
// flushed by finish(); nothing there can be taken back after an error.

#include <memory>
#include <string>

#include "io/output_file.h"
#include "io/point_writers.h"

namespace relief {

namespace {

class XyzStreamWriter final : public StreamPointWriter {
 public:
  XyzStreamWriter(std::unique_ptr<OutputFile> out, const WriterOptions& options, char separator)
      : StreamPointWriter(std::move(out), options), separator_(separator) {}

 protected:
  Status write_points(const PointCloud& batch) override {
    return write_text_points(*out_, batch, options_, separator_);
  }
  Status complete() override { return Status::ok(); }

 private:
  char separator_;
};

}  // namespace

Result<std::unique_ptr<PointWriter>> open_xyz_writer(const std::string& path, const WriterOptions& options,
                                                     char separator) {
  RELIEF_ASSIGN_OR_RETURN(std::unique_ptr<OutputFile> out, OutputFile::create(path));
  return std::unique_ptr<PointWriter>(std::make_unique<XyzStreamWriter>(std::move(out), options, separator));
}

}  // namespace relief
