// libFuzzer target: the streaming PCD reader (ascii and binary) from memory.
#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz/fuzz_support.h"
#include "io/readers.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  auto reader = relief::open_pcd_reader(relief::InputSpec{"fuzz.pcd", bytes}, relief::ReaderOptions{});
  if (reader.is_ok()) relief::fuzz::drain(**reader, size, "pcd reader");
  return 0;
}
