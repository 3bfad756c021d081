// libFuzzer target: the XYZ/CSV/PTS text reader and the PTX reader from
// memory. The first byte picks the reader and the column layout
// (ReaderOptions::xyz_columns, or none: a header's, PTS's or the default's);
// the rest is the file.
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

#include "fuzz/fuzz_support.h"
#include "io/readers.h"

namespace {

// Layouts the CLI's --columns accepts, including skipped and reordered ones,
// typed extra columns (name:type), and the malformed kinds the option parser
// must reject.
constexpr std::array<const char*, 10> kColumns = {
    "x,y,z",     "x,y,z,r,g,b", "x,y,z,i", "x,y,z,r,g,b,i", "_,x,_,y,z", "i,z,y,x", "x,y", "x,y,z,q",
    "x,y,z,a:u16,amp:f32", "x,y,z,id:i64,_,t:f64,u:u8,s:i8"};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::span<const std::uint8_t> bytes(data + 1, size - 1);
  const std::size_t pick = data[0] % (kColumns.size() + 2);
  if (pick == kColumns.size() + 1) {
    auto reader = relief::open_ptx_reader(relief::InputSpec{"fuzz.ptx", bytes});
    if (reader.is_ok()) relief::fuzz::drain(**reader, bytes.size(), "ptx reader");
    return 0;
  }
  relief::ReaderOptions options;
  if (pick < kColumns.size()) options.xyz_columns = kColumns[pick];
  auto reader = relief::open_xyz_reader(relief::InputSpec{"fuzz.xyz", bytes}, options);
  if (reader.is_ok()) relief::fuzz::drain(**reader, bytes.size(), "xyz reader");
  return 0;
}
