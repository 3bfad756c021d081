// libFuzzer target: the streaming LAS reader behind open_point_reader, fed
// from memory (the same reader code the path entry point uses).
#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz/fuzz_support.h"
#include "io/readers.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  auto reader = relief::open_las_reader(relief::InputSpec{"fuzz.las", bytes});
  if (reader.is_ok()) relief::fuzz::drain(**reader, size, "las reader");
  return 0;
}
