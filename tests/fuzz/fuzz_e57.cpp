// libFuzzer target: the E57 reader (pages and their CRCs, the XML section,
// the CompressedVector sections and their bitpacked bytestreams) from memory.
// Mutations rarely keep a page's CRC right; the seeds' XML and packets are
// still reached through the pages a mutation leaves alone, and the CRC check
// itself is what most mutated inputs must meet cleanly.
#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz/fuzz_support.h"
#include "io/readers.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> bytes(data, size);
  auto reader = relief::open_e57_reader(relief::InputSpec{"fuzz.e57", bytes}, relief::ReaderOptions{});
  // Bitpacking spends as little as one bit per field of a point (the reader
  // refuses records of 0 bits), so the bound is 8 points a byte, not 1.
  if (reader.is_ok()) relief::fuzz::drain(**reader, size * 8, "e57 reader");
  return 0;
}
