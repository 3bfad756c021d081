// libFuzzer target: the E57 reader (pages and their CRCs, the XML section,
// the CompressedVector sections and their bitpacked bytestreams) from memory.
// Each input is read twice: as it is, where a mutation rarely keeps a page's
// CRC right and the CRC check is what it must meet cleanly, and with every
// whole page's CRC-32C written anew, so that mutated XML, section headers,
// packets and bytestreams reach the parsers behind the check.
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "fuzz/fuzz_support.h"
#include "io/e57_writer.h"
#include "io/readers.h"

namespace {

void read_all(std::span<const std::uint8_t> bytes) {
  auto reader = relief::open_e57_reader(relief::InputSpec{"fuzz.e57", bytes}, relief::ReaderOptions{});
  // Bitpacking spends as little as one bit per field of a point (the reader
  // refuses records of 0 bits), so the bound is 8 points a byte, not 1.
  if (reader.is_ok()) relief::fuzz::drain(**reader, bytes.size() * 8, "e57 reader");
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  read_all({data, size});
  // The same bytes with each 1024-byte page's CRC made right (stored most
  // significant byte first, as the reader checks it).
  using relief::test::e57::kLogicalPage;
  using relief::test::e57::kPage;
  std::vector<std::uint8_t> fixed(data, data + size);
  for (std::size_t at = 0; at + kPage <= fixed.size(); at += kPage) {
    const std::uint32_t crc = relief::test::e57::crc32c(fixed.data() + at, kLogicalPage);
    for (int b = 0; b < 4; ++b) fixed[at + kLogicalPage + static_cast<std::size_t>(b)] = static_cast<std::uint8_t>(crc >> (24 - 8 * b));
  }
  read_all(fixed);
  return 0;
}
