// libFuzzer target: the streaming LAS reader behind open_point_reader, fed
// from memory (the same reader code the path entry point uses), read whole and
// then positions only (ReaderOptions::positions_only: a layered LAZ file then
// decodes only its XY and Z layers).
#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz/fuzz_support.h"
#include "io/readers.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  for (const bool positions_only : {false, true}) {
    auto reader = relief::open_las_reader(relief::InputSpec{"fuzz.las", bytes}, positions_only);
    if (!reader.is_ok()) return 0;
    relief::fuzz::drain(**reader, size, positions_only ? "las reader, positions only" : "las reader");
  }
  return 0;
}
