// libFuzzer target: the PLY readers from memory, both the whole-file one
// (read_ply_memory, public) and the streaming one behind open_point_reader.
#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz/fuzz_support.h"
#include "io/readers.h"
#include "relief/io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  auto cloud = relief::read_ply_memory(bytes, "fuzz.ply");
  if (cloud.is_ok()) relief::fuzz::check_points_bounded(cloud->size(), size, "read_ply_memory");
  auto reader = relief::open_ply_reader(relief::InputSpec{"fuzz.ply", bytes}, relief::ReaderOptions{});
  if (reader.is_ok()) relief::fuzz::drain(**reader, size, "ply reader");
  return 0;
}
