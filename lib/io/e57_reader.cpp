// ASTM E57 reader (E2807, format version 1.0): the 3D scans of a file, each
// in the file's frame, read scan by scan and packet by packet.
//
// The file (E2807 §6-§9):
//
//   header, 48 bytes at 0: "ASTM-E57", u32 major (1), u32 minor, u64
//     filePhysicalLength, u64 xmlPhysicalOffset, u64 xmlLogicalLength,
//     u64 pageSize, little-endian.
//   pages of pageSize bytes: pageSize - 4 "logical" bytes, then the CRC-32C
//     (Castagnoli) of them, stored most significant byte first (as the
//     reference implementation, libE57Format, writes it: it byte-swaps the
//     CRC before a little-endian store). Offsets in the file are physical;
//     the sections are runs of logical bytes that skip the CRCs.
//   the XML section: <e57Root> with data3D, a Vector of scans. A scan's
//     `points` is a CompressedVector (attributes fileOffset, the physical
//     offset of its binary section, and recordCount) with a `prototype`, the
//     fields of a point (Integer, ScaledInteger, Float), and `codecs`.
//   a binary section: u8 sectionId (1), 7 reserved bytes, u64
//     sectionLogicalLength, u64 dataPhysicalOffset, u64 indexPhysicalOffset,
//     then packets: data packets (u8 type 1, u8 flags, u16 length - 1, u16
//     bytestreamCount, u16 length of each bytestream's buffer, the buffers),
//     index packets (type 0) and empty ones (type 2), skipped by length.
//     Field k's values are the concatenation of buffer k of the data
//     packets, packed by the default "bitpack" codec: an Integer or
//     ScaledInteger as value - minimum in bit_width(maximum - minimum) bits
//     (none when minimum == maximum), least significant bit first, a Float as
//     4 or 8 little-endian bytes.
//
// What is read: cartesianX/Y/Z, or else sphericalRange/Azimuth/Elevation
// (x = r cos(el) cos(az), y = r cos(el) sin(az), z = r sin(el)); the scan's
// pose (a unit quaternion w x y z, then a translation) is applied in double
// precision. A point whose cartesianInvalidState (or sphericalInvalidState
// for spherical scans) is 1 (a direction without a range) or 2 (no return)
// is skipped and counted in PointStreamInfo::skipped_points, before any of
// its other values is looked at (a NaN, or a value above its field's
// maximum, in a skipped point is no error). intensity becomes
// PointCloud::intensities, 0 for a point whose isIntensityInvalid is not 0;
// timeStamp the LAS GPS time, 0 for a point whose isTimeStampInvalid is not
// 0 (an intensity or time that is not finite is an error on any other
// point). colorRed/Green/Blue (Integer, levels in 0..65535) have the range
// of the scan's colorLimits (colorRedMinimum .. colorRedMaximum and so on),
// else of each field's minimum .. maximum: when every range lies in 0..255
// (and every field's maximum too) the levels are kept as 8-bit levels;
// when every range is 0..65535, as 16-bit levels, exactly; else a level v
// of range lo..hi becomes the 16-bit level round((v - lo) * 65535 / (hi -
// lo)), clamped to 0..65535 (0 when lo == hi). 16-bit levels are kept as
// colour and LasAttributes::color_low. returnIndex (from 0) and
// returnCount become the LAS return number and number of returns when
// their declared ranges fit LAS's 4 bits. Every other field (rowIndex,
// columnIndex, colour or intensity invalid flags, a lone colour channel,
// extension fields ...) is kept as LAS extra bytes under its name
// (ReaderOptions::extra_bytes; else skipped with one warning), of the
// narrowest type that holds its declared range in every scan. A scan whose
// recordCount is 0 is not read at all (neither its section, whose
// fileOffset may be 0, nor its prototype). Images (images2D) and other
// metadata are ignored.
//
// Errors: another major version, a page whose CRC does not match, offsets
// or lengths outside the file, a scan whose bytestreams end before its
// recordCount, a value outside its field's declared range, String or nested
// fields, any codec but bitpack (kUnsupported), scans with points that
// carry different attributes. Memory is bounded by the XML section (at most
// kMaxXml bytes, parsed in one piece, and kMaxXmlElements elements of at
// most kMaxXmlAttributes attributes, only the few the reader uses kept, and
// names, attribute values and text of at most kMaxXmlToken bytes each) plus
// a buffer per field (a bytestream buffer is at most 64 KiB), never by a
// count the file states; every loop over packets is bounded by the
// section's bytes.

#include <expat.h>

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "io/byte_source.h"
#include "io/extra_fields.h"
#include "io/readers.h"
#include "io/stream_support.h"
#include "io/text_scan.h"
#include "relief/io.h"

namespace relief {

namespace {

constexpr std::size_t kHeaderSize = 48;
constexpr std::size_t kCrcSize = 4;
// The standard's page size is 1024; other sizes are read, within bounds that
// keep the page cache small.
constexpr std::uint64_t kMinPageSize = 64;
constexpr std::uint64_t kMaxPageSize = std::uint64_t{1} << 16;
constexpr std::size_t kCachedPages = 16;
// The XML section is metadata (a few KB for a scan); this bounds its memory.
constexpr std::uint64_t kMaxXml = std::uint64_t{64} << 20;
constexpr int kMaxXmlDepth = 64;
// A scan's XML is some fifty elements; this bounds the tree built from a
// hostile section (an element costs about 150 bytes in it, however short
// its text).
constexpr std::size_t kMaxXmlElements = std::size_t{1} << 20;
// An element of E57 has a handful of attributes (and its names, values and
// text are short): these bound what one element may hold.
constexpr std::size_t kMaxXmlAttributes = 1024;
constexpr std::size_t kMaxXmlToken = std::size_t{1} << 20;
// Far above the fields of a real prototype (a dozen), and a buffer of up to
// 64 KiB each.
constexpr std::size_t kMaxFields = 256;
constexpr std::size_t kSectionHeaderSize = 32;
constexpr std::size_t kDataPacketHeaderSize = 6;
constexpr std::size_t kPacketPrefixSize = 4;  // type, flags, length - 1: every packet starts so
constexpr std::uint8_t kIndexPacket = 0;
constexpr std::uint8_t kDataPacket = 1;
constexpr std::uint8_t kEmptyPacket = 2;

// ---- CRC-32C (Castagnoli, reflected polynomial 0x82F63B78), table driven.
constexpr std::array<std::uint32_t, 256> make_crc_table() {
  std::array<std::uint32_t, 256> t{};
  for (std::uint32_t i = 0; i < 256; ++i) {
    std::uint32_t c = i;
    for (int k = 0; k < 8; ++k) c = (c & 1) ? (c >> 1) ^ 0x82F63B78u : c >> 1;
    t[i] = c;
  }
  return t;
}
constexpr std::array<std::uint32_t, 256> kCrcTable = make_crc_table();

std::uint32_t crc32c(const std::uint8_t* p, std::size_t n) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < n; ++i) c = kCrcTable[(c ^ p[i]) & 0xFF] ^ (c >> 8);
  return c ^ 0xFFFFFFFFu;
}

// ---- A tiny DOM of the XML section: names, attributes, text, children.

// The attributes the reader reads (XmlNode::attribute); the others are dropped.
constexpr std::array<std::string_view, 8> kKeptAttributes = {
    "type", "minimum", "maximum", "scale", "offset", "precision", "fileOffset", "recordCount"};

struct XmlNode {
  std::string name;
  // The kept attributes packed: for each, 1 + the index of its name in
  // kKeptAttributes as one byte, its value, a NUL (which XML text cannot hold).
  std::string attributes;
  std::string text;
  std::vector<XmlNode> children;

  std::optional<std::string_view> attribute(std::string_view key) const {
    std::string_view rest = attributes;
    while (!rest.empty()) {
      const std::size_t end = rest.find('\0', 1);
      if (kKeptAttributes[static_cast<std::size_t>(rest[0] - 1)] == key) return rest.substr(1, end - 1);
      rest.remove_prefix(end + 1);
    }
    return std::nullopt;
  }
  void keep_attribute(std::string_view key, std::string_view value) {
    const auto at = std::find(kKeptAttributes.begin(), kKeptAttributes.end(), key);
    if (at == kKeptAttributes.end()) return;
    attributes += static_cast<char>(at - kKeptAttributes.begin() + 1);
    attributes += value;
    attributes += '\0';
  }
  const XmlNode* child(std::string_view key) const {
    for (const XmlNode& c : children) {
      if (c.name == key) return &c;
    }
    return nullptr;
  }
  std::string type() const { return std::string(attribute("type").value_or(std::string_view())); }
};

// The name of the first start tag of `xml` with more than kMaxXmlAttributes
// attributes (counted as the '=' outside quoted values), if any: expat reads
// all of a tag's attributes (some 100 bytes of its memory each) before it
// hands them over, so an absurd tag is refused before it is parsed.
std::optional<std::string_view> overfull_tag(std::string_view xml) {
  std::size_t i = 0;
  const auto skip_past = [&](std::string_view end) {
    const std::size_t at = xml.find(end, i);
    i = at == std::string_view::npos ? xml.size() : at + end.size();
  };
  while ((i = xml.find('<', i)) != std::string_view::npos) {
    const std::string_view rest = xml.substr(i);
    if (rest.starts_with("<!--")) {
      skip_past("-->");
    } else if (rest.starts_with("<![CDATA[")) {
      skip_past("]]>");
    } else if (rest.starts_with("<?")) {
      skip_past("?>");
    } else if (rest.starts_with("<!")) {
      skip_past(">");
    } else {
      const std::size_t start = ++i;
      std::size_t name_end = std::string_view::npos;
      std::size_t equals = 0;
      char quote = 0;
      for (; i < xml.size(); ++i) {
        const char c = xml[i];
        if (quote != 0) {
          if (c == quote) quote = 0;
        } else if (c == '"' || c == '\'') {
          quote = c;
        } else if (c == '>') {
          break;
        } else if (c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '/' || c == '=') {
          name_end = std::min(name_end, i);
          if (c == '=' && ++equals > kMaxXmlAttributes)
            return xml.substr(start, std::min<std::size_t>(name_end - start, 64));
        }
      }
    }
  }
  return std::nullopt;
}

struct XmlBuilder {
  XML_Parser parser = nullptr;
  XmlNode root;
  std::vector<XmlNode*> stack;  // open elements; empty before the root and after it
  bool have_root = false;
  std::size_t elements = 0;
  std::string error;

  void fail(std::string what) {
    if (error.empty()) error = std::move(what);
    XML_StopParser(parser, XML_FALSE);
  }

  static void on_start(void* self, const XML_Char* name, const XML_Char** attrs) {
    auto* b = static_cast<XmlBuilder*>(self);
    if (!b->error.empty()) return;
    if (b->stack.size() >= static_cast<std::size_t>(kMaxXmlDepth)) {
      b->fail("elements nested deeper than " + std::to_string(kMaxXmlDepth));
      return;
    }
    if (++b->elements > kMaxXmlElements) {
      b->fail("more than " + std::to_string(kMaxXmlElements) + " elements");
      return;
    }
    const std::size_t name_length = std::strlen(name);
    if (name_length > kMaxXmlToken) {
      b->fail("an element name of " + std::to_string(name_length) + " bytes; at most " +
              std::to_string(kMaxXmlToken) + " are read");
      return;
    }
    std::size_t count = 0;
    while (attrs[2 * count] != nullptr) {
      if (++count > kMaxXmlAttributes) {
        b->fail("element " + quoted(std::string_view(name, std::min<std::size_t>(name_length, 64))) +
                " has more than " + std::to_string(kMaxXmlAttributes) + " attributes");
        return;
      }
    }
    XmlNode* node = nullptr;
    if (b->stack.empty()) {
      if (b->have_root) return b->fail("more than one root element");
      b->have_root = true;
      node = &b->root;
    } else {
      b->stack.back()->children.emplace_back();
      node = &b->stack.back()->children.back();
    }
    node->name.assign(name, name_length);
    for (std::size_t i = 0; attrs[i] != nullptr; i += 2) {
      const std::size_t value_length = std::strlen(attrs[i + 1]);
      if (value_length > kMaxXmlToken) {
        b->fail("attribute " +
                quoted(std::string_view(attrs[i], std::min<std::size_t>(std::strlen(attrs[i]), 64))) +
                " of element " + quoted(std::string_view(name, std::min<std::size_t>(name_length, 64))) +
                " is " + std::to_string(value_length) + " bytes long; at most " +
                std::to_string(kMaxXmlToken) + " are read");
        return;
      }
      // Only the attributes the reader looks at are kept: the tree stays a
      // small multiple of the section's size whatever else elements carry.
      node->keep_attribute(attrs[i], std::string_view(attrs[i + 1], value_length));
    }
    b->stack.push_back(node);
  }
  static void on_end(void* self, const XML_Char*) {
    auto* b = static_cast<XmlBuilder*>(self);
    if (!b->stack.empty()) b->stack.pop_back();
  }
  static void on_text(void* self, const XML_Char* s, int len) {
    auto* b = static_cast<XmlBuilder*>(self);
    if (!b->error.empty() || b->stack.empty() || len <= 0) return;
    std::string& text = b->stack.back()->text;
    if (text.size() + static_cast<std::size_t>(len) > kMaxXmlToken) {
      b->fail("element " + quoted(std::string_view(b->stack.back()->name).substr(0, 64)) + " has more than " +
              std::to_string(kMaxXmlToken) + " bytes of text");
      return;
    }
    text.append(s, static_cast<std::size_t>(len));
  }
  // E57 has no use for entities; refusing their declarations keeps entity
  // expansion (the "billion laughs") out of the question.
  static void on_entity(void* self, const XML_Char*, int, const XML_Char*, int, const XML_Char*, const XML_Char*,
                        const XML_Char*, const XML_Char*) {
    static_cast<XmlBuilder*>(self)->fail("the XML declares entities, which E57 does not use");
  }
};

// ---- Numbers in the XML.
std::string_view trim(std::string_view s) {
  const auto blank = [](char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; };
  while (!s.empty() && blank(s.front())) s.remove_prefix(1);
  while (!s.empty() && blank(s.back())) s.remove_suffix(1);
  return s;
}

template <typename T>
bool parse_whole(std::string_view s, T& out) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return !s.empty() && r.ec == std::errc() && r.ptr == s.data() + s.size();
}

bool parse_real(std::string_view s, double& out) {
  s = trim(s);
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
  return !s.empty() && r.ec == std::errc() && r.ptr == s.data() + s.size() && std::isfinite(out);
}

// ---- Fields of a prototype and what the reader makes of them.
enum class FieldType { kInteger, kScaledInteger, kFloat };

enum class Role {
  kExtra,
  kSkip,  // an extra field when extra bytes are off
  kX,
  kY,
  kZ,
  kRange,
  kAzimuth,
  kElevation,
  kInvalidState,
  kIntensity,
  kRed,
  kGreen,
  kBlue,
  kTime,
  kReturnIndex,
  kReturnCount,
};

struct Field {
  std::string name;
  FieldType type = FieldType::kInteger;
  std::int64_t minimum = std::numeric_limits<std::int64_t>::min();
  std::int64_t maximum = std::numeric_limits<std::int64_t>::max();
  double scale = 1;
  double offset = 0;
  bool single = false;  // Float precision "single"
  unsigned bits = 0;    // bits per value in the bytestream
  Role role = Role::kExtra;
  int extra_type = 0;  // LAS Extra Bytes data type of a kept field
  std::size_t extra_at = 0;
  std::size_t extra_size = 0;
};

// LAS Extra Bytes data types (LAS 1.4 table 24) and their sizes.
constexpr int kU8 = 1, kI8 = 2, kU16 = 3, kI16 = 4, kU32 = 5, kI32 = 6, kU64 = 7, kI64 = 8, kF32 = 9, kF64 = 10;
std::size_t extra_type_size(int t) {
  switch (t) {
    case kU8:
    case kI8:
      return 1;
    case kU16:
    case kI16:
      return 2;
    case kU32:
    case kI32:
    case kF32:
      return 4;
    default:
      return 8;
  }
}

// The narrowest LAS type that holds every value the fields declare: the
// field of one name in every scan, so that each scan's values fit.
int extra_type_of(const std::vector<const Field*>& fields) {
  bool integers = false, floats = false, doubles = false;
  std::int64_t lo = std::numeric_limits<std::int64_t>::max(), hi = std::numeric_limits<std::int64_t>::min();
  for (const Field* f : fields) {
    if (f->type == FieldType::kInteger) {
      integers = true;
      lo = std::min(lo, f->minimum);
      hi = std::max(hi, f->maximum);
    } else {
      floats = true;
      doubles = doubles || f->type == FieldType::kScaledInteger || !f->single;
    }
  }
  if (floats) return doubles || integers ? kF64 : kF32;
  if (lo >= 0) {
    if (hi <= 0xFF) return kU8;
    if (hi <= 0xFFFF) return kU16;
    if (hi <= 0xFFFFFFFFll) return kU32;
    return kU64;
  }
  if (lo >= -128 && hi <= 127) return kI8;
  if (lo >= -32768 && hi <= 32767) return kI16;
  if (lo >= std::numeric_limits<std::int32_t>::min() && hi <= std::numeric_limits<std::int32_t>::max()) return kI32;
  return kI64;
}

// One scan: where its points are, how many, its fields and its pose.
struct Scan {
  std::size_t index = 0;  // its place in data3D
  std::uint64_t file_offset = 0;
  std::uint64_t record_count = 0;
  std::vector<Field> fields;
  bool spherical = false;
  bool colors = false;
  bool wide_colors = false;  // 16-bit levels
  bool scaled_colors = false;  // 16-bit levels scaled from [color_lo, color_hi]
  std::array<double, 3> color_lo{}, color_hi{};
  std::uint32_t las = 0;     // LasAttributeBits
  std::array<double, 9> rotation{1, 0, 0, 0, 1, 0, 0, 0, 1};  // row major
  std::array<double, 3> translation{0, 0, 0};
  bool has_pose = false;
  // Indices in fields (SIZE_MAX when absent): the state that marks a point
  // invalid, the flags that mark its intensity or its time invalid.
  std::size_t invalid_state = std::numeric_limits<std::size_t>::max();
  std::size_t intensity_invalid = std::numeric_limits<std::size_t>::max();
  std::size_t time_invalid = std::numeric_limits<std::size_t>::max();
};

// A field's bytestream: its buffer of the current data packet and the bits
// not yet used.
struct Channel {
  std::uint64_t next_packet = 0;  // logical offset of the packet after the current one
  std::vector<std::uint8_t> buffer;
  std::size_t used = 0;  // bytes of buffer moved into acc
  std::uint64_t acc = 0;
  unsigned acc_bits = 0;
  std::uint64_t values = 0;  // decoded so far, for messages
};

class E57PointReader final : public PointReader {
 public:
  E57PointReader(std::string name, ByteSource src, const ReaderOptions& options)
      : src_(std::move(src)), keep_extras_(options.extra_bytes) {
    info_.path = std::move(name);
    info_.format = "e57";
  }

  const PointStreamInfo& info() const override { return info_; }

  Status start() {
    if (!src_.size()) {
      return unsupported(name() + ": an E57 file is read out of order, so it must be a regular file, not a pipe");
    }
    file_size_ = *src_.size();
    RELIEF_RETURN_IF_ERROR(read_header());
    XmlNode root;
    RELIEF_RETURN_IF_ERROR(parse_xml(root));
    RELIEF_RETURN_IF_ERROR(read_scans(root));
    return Status::ok();
  }

  Result<std::size_t> read(PointCloud& batch, std::size_t max_points) override {
    batch.clear_points();  // keeps the capacity
    batch.las.extra_bytes_size = static_cast<std::uint32_t>(extra_size_);
    std::size_t got = 0;
    while (got < max_points) {
      if (left_ == 0) {
        if (next_scan_ == scans_.size()) break;
        RELIEF_RETURN_IF_ERROR(open_scan(next_scan_++));
        continue;
      }
      bool kept = false;
      RELIEF_RETURN_IF_ERROR(read_record(batch, kept));
      --left_;
      got += kept ? 1 : 0;
    }
    return got;
  }

 private:
  const std::string& name() const { return info_.path; }

  Status error(const std::string& what) const { return format_error(name() + ": " + what); }
  std::string scan_name(std::size_t s) const { return "scan " + std::to_string(s) + " (data3D child " + std::to_string(s) + ")"; }

  // ---- Pages.

  Status read_header() {
    std::array<std::uint8_t, kHeaderSize> h{};
    std::size_t got = 0;
    RELIEF_RETURN_IF_ERROR(src_.read_at(0, h, got));
    if (got < 8 || std::memcmp(h.data(), "ASTM-E57", 8) != 0) {
      return error("not an E57 file (no \"ASTM-E57\" signature)");
    }
    if (got < kHeaderSize) return error("truncated: the file ends inside its 48-byte header");
    const std::uint32_t major = load_le<std::uint32_t>(h.data() + 8);
    const std::uint64_t physical_length = load_le<std::uint64_t>(h.data() + 16);
    xml_offset_ = load_le<std::uint64_t>(h.data() + 24);
    xml_length_ = load_le<std::uint64_t>(h.data() + 32);
    page_size_ = load_le<std::uint64_t>(h.data() + 40);
    if (major != 1) {
      return unsupported(name() + ": E57 format version " + std::to_string(major) + "; Relief reads version 1");
    }
    if (page_size_ < kMinPageSize || page_size_ > kMaxPageSize || page_size_ % 4 != 0) {
      return error("page size " + std::to_string(page_size_) + " is not a multiple of 4 in " +
                   std::to_string(kMinPageSize) + ".." + std::to_string(kMaxPageSize));
    }
    if (physical_length != file_size_) {
      return error("the header gives the file's length as " + std::to_string(physical_length) + " bytes but it has " +
                   std::to_string(file_size_) + (physical_length > file_size_ ? " (a truncated file)" : ""));
    }
    if (file_size_ % page_size_ != 0) {
      return error("the file's length " + std::to_string(file_size_) + " is not a whole number of " +
                   std::to_string(page_size_) + "-byte pages");
    }
    logical_page_ = page_size_ - kCrcSize;
    logical_size_ = file_size_ / page_size_ * logical_page_;
    cache_.assign(kCachedPages, CachedPage{});
    // The header's own page carries a CRC too.
    const std::uint8_t* unused = nullptr;
    return page(0, unused);
  }

  struct CachedPage {
    std::uint64_t index = std::numeric_limits<std::uint64_t>::max();
    std::vector<std::uint8_t> bytes;
  };

  // The logical bytes of page `index`, its CRC checked.
  Status page(std::uint64_t index, const std::uint8_t*& out) {
    CachedPage& c = cache_[index % kCachedPages];
    if (c.index != index) {
      c.index = std::numeric_limits<std::uint64_t>::max();
      c.bytes.resize(page_size_);
      std::size_t got = 0;
      RELIEF_RETURN_IF_ERROR(src_.read_at(index * page_size_, c.bytes, got));
      if (got != page_size_) return error("truncated: page " + std::to_string(index) + " is cut short");
      const std::uint8_t* p = c.bytes.data();
      const std::uint32_t stored = static_cast<std::uint32_t>(p[logical_page_]) << 24 |
                                   static_cast<std::uint32_t>(p[logical_page_ + 1]) << 16 |
                                   static_cast<std::uint32_t>(p[logical_page_ + 2]) << 8 | p[logical_page_ + 3];
      const std::uint32_t computed = crc32c(p, logical_page_);
      if (stored != computed) {
        return error("page " + std::to_string(index) + " (bytes " + std::to_string(index * page_size_) + ".." +
                     std::to_string((index + 1) * page_size_ - 1) + ") fails its CRC-32C check: a damaged file");
      }
      c.index = index;
    }
    out = c.bytes.data();
    return Status::ok();
  }

  // Copies logical bytes [at, at + n), which must lie inside the file.
  Status read_logical(std::uint64_t at, std::size_t n, std::uint8_t* out, const std::string& what) {
    if (at > logical_size_ || n > logical_size_ - at) {
      return error(what + " (logical bytes " + std::to_string(at) + "+" + std::to_string(n) +
                   ") lies past the end of the file");
    }
    while (n > 0) {
      const std::uint64_t index = at / logical_page_;
      const std::size_t in = static_cast<std::size_t>(at % logical_page_);
      const std::size_t take = std::min<std::size_t>(n, static_cast<std::size_t>(logical_page_) - in);
      const std::uint8_t* p = nullptr;
      RELIEF_RETURN_IF_ERROR(page(index, p));
      std::memcpy(out, p + in, take);
      out += take;
      at += take;
      n -= take;
    }
    return Status::ok();
  }

  // The logical offset of physical offset `physical`, which must be inside
  // the file and not inside a page's CRC.
  Status to_logical(std::uint64_t physical, std::uint64_t& logical, const std::string& what) const {
    if (physical >= file_size_) {
      return error(what + " " + std::to_string(physical) + " is beyond the end of the file (" +
                   std::to_string(file_size_) + " bytes)");
    }
    if (physical % page_size_ >= logical_page_) {
      return error(what + " " + std::to_string(physical) + " points into a page's CRC");
    }
    logical = physical / page_size_ * logical_page_ + physical % page_size_;
    return Status::ok();
  }

  // ---- XML.

  Status parse_xml(XmlNode& root) {
    std::uint64_t at = 0;
    RELIEF_RETURN_IF_ERROR(to_logical(xml_offset_, at, "the XML section's offset"));
    if (xml_length_ > logical_size_ - at) {
      return error("the XML section (" + std::to_string(xml_length_) + " bytes from " + std::to_string(xml_offset_) +
                   ") runs past the end of the file");
    }
    if (xml_length_ > kMaxXml) {
      return unsupported(name() + ": an XML section of " + std::to_string(xml_length_) + " bytes; Relief reads up to " +
                         std::to_string(kMaxXml));
    }
    XmlBuilder b;
    std::unique_ptr<std::remove_pointer_t<XML_Parser>, decltype(&XML_ParserFree)> parser(XML_ParserCreate(nullptr),
                                                                                        &XML_ParserFree);
    if (!parser) return internal_error(name() + ": cannot create an XML parser");
    b.parser = parser.get();
    XML_SetUserData(b.parser, &b);
    XML_SetElementHandler(b.parser, &XmlBuilder::on_start, &XmlBuilder::on_end);
    XML_SetCharacterDataHandler(b.parser, &XmlBuilder::on_text);
    XML_SetEntityDeclHandler(b.parser, &XmlBuilder::on_entity);
    // The whole section in one buffer and one parse: fed in pieces, expat 2.5
    // rescans a token that spans them from its start at every piece
    // (CVE-2023-52425), quadratic in a long attribute or a long start tag.
    // Its own buffer (XML_GetBuffer) is the only copy of the section.
    if (xml_length_ == 0) return error("the XML section is empty");
    const int n = static_cast<int>(xml_length_);  // at most kMaxXml
    void* buffer = XML_GetBuffer(b.parser, n);
    if (buffer == nullptr) return internal_error(name() + ": cannot allocate the XML section's buffer");
    RELIEF_RETURN_IF_ERROR(read_logical(at, static_cast<std::size_t>(xml_length_),
                                        static_cast<std::uint8_t*>(buffer), "the XML section"));
    if (const auto tag = overfull_tag(std::string_view(static_cast<const char*>(buffer), xml_length_))) {
      return error("the XML section: element " + quoted(*tag) + " has more than " +
                   std::to_string(kMaxXmlAttributes) + " attributes");
    }
    const XML_Status st = XML_ParseBuffer(b.parser, n, XML_TRUE);
    if (!b.error.empty()) return error("the XML section: " + b.error);
    if (st != XML_STATUS_OK) {
      return error("the XML section is not well-formed XML: " +
                   std::string(XML_ErrorString(XML_GetErrorCode(b.parser))) + " at line " +
                   std::to_string(XML_GetCurrentLineNumber(b.parser)));
    }
    if (!b.have_root) return error("the XML section is empty");
    root = std::move(b.root);
    return Status::ok();
  }

  // A Float element's value (absent: `fallback`).
  Status float_value(const XmlNode* parent, std::string_view key, double fallback, double& out,
                     const std::string& where) const {
    out = fallback;
    const XmlNode* n = parent ? parent->child(key) : nullptr;
    if (n == nullptr || trim(n->text).empty()) return Status::ok();
    if (!parse_real(n->text, out)) {
      return error(where + ": " + std::string(key) + " " + quoted(trim(n->text)) + " is not a finite number");
    }
    return Status::ok();
  }

  Status read_pose(const XmlNode& scan_node, Scan& scan, const std::string& where) const {
    const XmlNode* pose = scan_node.child("pose");
    if (pose == nullptr) return Status::ok();
    scan.has_pose = true;
    if (const XmlNode* r = pose->child("rotation")) {
      double w = 0, x = 0, y = 0, z = 0;
      RELIEF_RETURN_IF_ERROR(float_value(r, "w", 0, w, where + " pose rotation"));
      RELIEF_RETURN_IF_ERROR(float_value(r, "x", 0, x, where + " pose rotation"));
      RELIEF_RETURN_IF_ERROR(float_value(r, "y", 0, y, where + " pose rotation"));
      RELIEF_RETURN_IF_ERROR(float_value(r, "z", 0, z, where + " pose rotation"));
      const double n = w * w + x * x + y * y + z * z;
      if (!(std::fabs(n - 1) <= 1e-3)) {
        return error(where + ": the pose rotation (" + format_double(w) + ", " + format_double(x) + ", " +
                     format_double(y) + ", " + format_double(z) + ") is not a unit quaternion");
      }
      // 2 / |q|^2 rather than 2: a unit quaternion as a file writes it (17
      // digits) is a hair off 1, and this keeps a quarter turn exact.
      const double s = 2 / n;
      scan.rotation = {1 - s * (y * y + z * z), s * (x * y - w * z),     s * (x * z + w * y),
                       s * (x * y + w * z),     1 - s * (x * x + z * z), s * (y * z - w * x),
                       s * (x * z - w * y),     s * (y * z + w * x),     1 - s * (x * x + y * y)};
    }
    if (const XmlNode* t = pose->child("translation")) {
      RELIEF_RETURN_IF_ERROR(float_value(t, "x", 0, scan.translation[0], where + " pose translation"));
      RELIEF_RETURN_IF_ERROR(float_value(t, "y", 0, scan.translation[1], where + " pose translation"));
      RELIEF_RETURN_IF_ERROR(float_value(t, "z", 0, scan.translation[2], where + " pose translation"));
    }
    return Status::ok();
  }

  Status read_field(const XmlNode& node, Field& f, const std::string& where) const {
    f.name = node.name;
    const std::string type = node.type();
    const std::string what = where + ": field " + quoted(f.name);
    const auto whole_attr = [&](const char* key, std::int64_t& out) -> Status {
      const std::optional<std::string_view> v = node.attribute(key);
      if (v && !parse_whole(*v, out)) {
        return error(what + ": " + key + " " + quoted(*v) + " is not a 64-bit integer");
      }
      return Status::ok();
    };
    const auto real_attr = [&](const char* key, double& out) -> Status {
      const std::optional<std::string_view> v = node.attribute(key);
      if (v && !parse_real(*v, out)) return error(what + ": " + key + " " + quoted(*v) + " is not a number");
      return Status::ok();
    };
    if (type == "Integer" || type == "ScaledInteger") {
      f.type = type == "Integer" ? FieldType::kInteger : FieldType::kScaledInteger;
      RELIEF_RETURN_IF_ERROR(whole_attr("minimum", f.minimum));
      RELIEF_RETURN_IF_ERROR(whole_attr("maximum", f.maximum));
      if (f.minimum > f.maximum) {
        return error(what + ": minimum " + std::to_string(f.minimum) + " is above maximum " + std::to_string(f.maximum));
      }
      if (f.type == FieldType::kScaledInteger) {
        RELIEF_RETURN_IF_ERROR(real_attr("scale", f.scale));
        RELIEF_RETURN_IF_ERROR(real_attr("offset", f.offset));
        if (f.scale == 0) return error(what + ": scale 0");
      }
      const std::uint64_t span = static_cast<std::uint64_t>(f.maximum) - static_cast<std::uint64_t>(f.minimum);
      f.bits = static_cast<unsigned>(std::bit_width(span));
      return Status::ok();
    }
    if (type == "Float") {
      f.type = FieldType::kFloat;
      const std::optional<std::string_view> p = node.attribute("precision");
      if (p && *p != "single" && *p != "double") {
        return error(what + ": precision " + quoted(*p) + " is neither \"single\" nor \"double\"");
      }
      f.single = p.has_value() && *p == "single";
      f.bits = f.single ? 32 : 64;
      return Status::ok();
    }
    if (type == "String") return unsupported(name() + ": " + what + " is a String; Relief reads numeric fields only");
    return unsupported(name() + ": " + what + " has type " + quoted(type) +
                       "; Relief reads Integer, ScaledInteger and Float fields");
  }

  // Gives each field of `scan` its role (see the top of the file).
  Status assign_roles(const XmlNode& scan_node, Scan& scan, const std::string& where) {
    const auto find = [&](std::string_view key) -> Field* {
      for (Field& f : scan.fields) {
        if (f.name == key) return &f;
      }
      return nullptr;
    };
    Field* x = find("cartesianX");
    Field* y = find("cartesianY");
    Field* z = find("cartesianZ");
    if (x && y && z) {
      x->role = Role::kX;
      y->role = Role::kY;
      z->role = Role::kZ;
      if (Field* s = find("cartesianInvalidState")) s->role = Role::kInvalidState;
    } else {
      Field* r = find("sphericalRange");
      Field* a = find("sphericalAzimuth");
      Field* e = find("sphericalElevation");
      if (!(r && a && e)) {
        return error(where + ": its points have neither cartesianX, Y and Z nor sphericalRange, Azimuth and Elevation");
      }
      scan.spherical = true;
      r->role = Role::kRange;
      a->role = Role::kAzimuth;
      e->role = Role::kElevation;
      if (Field* s = find("sphericalInvalidState")) s->role = Role::kInvalidState;
    }
    if (Field* i = find("intensity")) {
      i->role = Role::kIntensity;
      const bool wide = i->type == FieldType::kFloat ? !i->single
                                                      : static_cast<std::uint64_t>(i->maximum) -
                                                                static_cast<std::uint64_t>(i->minimum) >
                                                            (std::uint64_t{1} << 24);
      if (wide && !intensity_noted_) {
        intensity_noted_ = true;
        info_.warnings.push_back(name() + ": field 'intensity' holds " +
                                 (i->type == FieldType::kFloat ? std::string("doubles") : "integers wider than 24 bits") +
                                 "; intensities are kept as 32-bit floats (about 7 significant digits, integers "
                                 "exact up to 2^24)");
      }
    }
    Field* red = find("colorRed");
    Field* green = find("colorGreen");
    Field* blue = find("colorBlue");
    if (red && green && blue) {
      // The levels' range: the scan's colorLimits, else each field's own.
      const XmlNode* limits = scan_node.child("colorLimits");
      static constexpr std::array<const char*, 3> kMinimum = {"colorRedMinimum", "colorGreenMinimum",
                                                              "colorBlueMinimum"};
      static constexpr std::array<const char*, 3> kMaximum = {"colorRedMaximum", "colorGreenMaximum",
                                                              "colorBlueMaximum"};
      const std::array<Field*, 3> channels = {red, green, blue};
      bool bytes = true, words = true;  // 0..255 levels, 0..65535 levels, as stored
      for (std::size_t c = 0; c < 3; ++c) {
        const Field* f = channels[c];
        if (f->type != FieldType::kInteger || f->minimum < 0 || f->maximum > 65535) {
          return error(where + ": colour field " + quoted(f->name) +
                       " is not an Integer with levels in 0..255 or 0..65535");
        }
        double& lo = scan.color_lo[c];
        double& hi = scan.color_hi[c];
        lo = static_cast<double>(f->minimum);
        hi = static_cast<double>(f->maximum);
        if (limits != nullptr) {
          RELIEF_RETURN_IF_ERROR(float_value(limits, kMinimum[c], lo, lo, where + " colorLimits"));
          RELIEF_RETURN_IF_ERROR(float_value(limits, kMaximum[c], hi, hi, where + " colorLimits"));
          if (!(lo < hi)) {
            return error(where + ": colorLimits " + kMinimum[c] + " " + format_double(lo) + " is not below " +
                         kMaximum[c] + " " + format_double(hi));
          }
        }
        bytes = bytes && lo >= 0 && hi <= 255 && f->maximum <= 255;
        words = words && lo == 0 && hi == 65535;
      }
      red->role = Role::kRed;
      green->role = Role::kGreen;
      blue->role = Role::kBlue;
      scan.colors = true;
      scan.wide_colors = !bytes;
      scan.scaled_colors = !bytes && !words;
      if (scan.wide_colors) scan.las |= kLasColorLow;
    }
    if (Field* t = find("timeStamp")) {
      t->role = Role::kTime;
      scan.las |= kLasGpsTime;
    }
    // LAS holds a return number 1..15 and a count 0..15 (4 bits each).
    if (Field* r = find("returnIndex"); r && r->type == FieldType::kInteger && r->minimum >= 0 && r->maximum <= 14) {
      r->role = Role::kReturnIndex;
      scan.las |= kLasReturnNumber;
    }
    if (Field* r = find("returnCount"); r && r->type == FieldType::kInteger && r->minimum >= 0 && r->maximum <= 15) {
      r->role = Role::kReturnCount;
      scan.las |= kLasNumberOfReturns;
    }
    const auto index_of = [&](std::string_view key, Role role) {
      for (std::size_t k = 0; k < scan.fields.size(); ++k) {
        if (scan.fields[k].name == key && scan.fields[k].role == role) return k;
      }
      return std::numeric_limits<std::size_t>::max();
    };
    scan.invalid_state =
        index_of(scan.spherical ? "sphericalInvalidState" : "cartesianInvalidState", Role::kInvalidState);
    scan.intensity_invalid = index_of("isIntensityInvalid", Role::kExtra);
    scan.time_invalid = index_of("isTimeStampInvalid", Role::kExtra);
    // The extra fields' types are decided over every scan (read_scans).
    for (Field& f : scan.fields) {
      if (f.role != Role::kExtra) continue;
      if (!keep_extras_) {
        f.role = Role::kSkip;
        continue;
      }
      scan.las |= kLasExtraBytes;
    }
    return Status::ok();
  }

  Status read_scans(const XmlNode& root) {
    if (root.name != "e57Root") return error("the XML section's root is " + quoted(root.name) + ", not e57Root");
    const XmlNode* data3d = root.child("data3D");
    std::uint64_t total = 0;
    for (std::size_t s = 0; data3d != nullptr && s < data3d->children.size(); ++s) {
      const XmlNode& node = data3d->children[s];
      const std::string where = scan_name(s);
      const XmlNode* points = node.child("points");
      if (points == nullptr) return error(where + " has no points");
      if (points->type() != "CompressedVector") {
        return error(where + ": its points are a " + quoted(points->type()) + ", not a CompressedVector");
      }
      Scan scan;
      scan.index = s;
      const std::optional<std::string_view> offset = points->attribute("fileOffset");
      const std::optional<std::string_view> count = points->attribute("recordCount");
      if (!offset || !parse_whole(*offset, scan.file_offset)) {
        return error(where + ": its points have no valid fileOffset");
      }
      if (!count || !parse_whole(*count, scan.record_count)) {
        return error(where + ": its points have no valid recordCount");
      }
      // A scan without points is not read at all: neither its section
      // (libE57Format gives fileOffset 0 to one never written) nor its
      // prototype, which need not match the other scans'.
      if (scan.record_count == 0) continue;
      if (const XmlNode* codecs = points->child("codecs"); codecs != nullptr && !codecs->children.empty()) {
        std::string names;
        for (const XmlNode& codec : codecs->children) {
          for (const XmlNode& part : codec.children) {
            if (part.name == "inputs") continue;
            names += (names.empty() ? "" : ", ") + quoted(part.name);
          }
        }
        return unsupported(name() + ": " + where + " is compressed with the codec " +
                           (names.empty() ? std::string("(unnamed)") : names) +
                           "; Relief reads the default bitpack codec only");
      }
      const XmlNode* prototype = points->child("prototype");
      if (prototype == nullptr || prototype->children.empty()) return error(where + ": its points have no prototype");
      if (prototype->children.size() > kMaxFields) {
        return error(where + ": " + std::to_string(prototype->children.size()) + " fields per point; at most " +
                     std::to_string(kMaxFields) + " are read");
      }
      for (const XmlNode& f : prototype->children) {
        scan.fields.emplace_back();
        RELIEF_RETURN_IF_ERROR(read_field(f, scan.fields.back(), where));
      }
      RELIEF_RETURN_IF_ERROR(assign_roles(node, scan, where));
      RELIEF_RETURN_IF_ERROR(read_pose(node, scan, where));
      if (scan.record_count > std::numeric_limits<std::uint64_t>::max() - total) {
        return error(where + ": the scans' recordCounts add up past 2^64");
      }
      total += scan.record_count;
      scans_.push_back(std::move(scan));
    }
    RELIEF_RETURN_IF_ERROR(same_attributes());
    info_.point_count = total;
    info_.has_colors = first_colors_;
    info_.has_intensity = first_intensity_;
    info_.las_attributes = first_las_;
    if (!extra_names_.empty()) {
      RELIEF_ASSIGN_OR_RETURN(info_.extra_bytes_vlr,
                              kept_fields_vlr(extra_names_, name(), "field", "E57 field", info_.warnings));
      for (const KeptField& k : extra_names_) extra_size_ += extra_type_size(k.data_type);
      info_.extra_bytes_size = static_cast<std::uint32_t>(extra_size_);
      scratch_.assign(extra_size_, 0);
    }
    return Status::ok();
  }

  // Attributes: the same in every scan read (a stream has one set), the
  // first scan's. An extra field takes the narrowest type that holds its
  // values in every scan (rowIndex and columnIndex of grids of other sizes).
  Status same_attributes() {
    if (scans_.empty()) return Status::ok();
    const Scan& first = scans_.front();
    first_las_ = first.las;
    first_colors_ = first.colors;
    first_intensity_ = has_role(first, Role::kIntensity);
    std::vector<std::string> skipped;
    std::vector<std::vector<const Field*>> extras;  // [kept field][scan]
    for (const Field& f : first.fields) {
      if (f.role == Role::kExtra) {
        extra_names_.push_back({f.name, 0});
        extras.push_back({&f});
      }
      if (f.role == Role::kSkip) skipped.push_back(f.name);
    }
    for (std::size_t s = 1; s < scans_.size(); ++s) {
      const Scan& scan = scans_[s];
      std::size_t kept = 0;
      bool same_extras = true;
      for (const Field& f : scan.fields) {
        if (f.role != Role::kExtra) continue;
        same_extras = same_extras && kept < extras.size() && f.name == extra_names_[kept].name;
        if (same_extras) extras[kept].push_back(&f);
        ++kept;
      }
      if (scan.las != first_las_ || scan.colors != first_colors_ ||
          has_role(scan, Role::kIntensity) != first_intensity_ || !same_extras || kept != extras.size()) {
        return error(scan_name(scan.index) + " carries other attributes than " + scan_name(first.index) +
                     ": its colours, intensity, times, returns or other fields differ; every scan of a file "
                     "must carry the same (scans without points aside)");
      }
    }
    for (std::size_t k = 0; k < extras.size(); ++k) extra_names_[k].data_type = extra_type_of(extras[k]);
    for (Scan& scan : scans_) {
      std::size_t kept = 0, at = 0;
      for (Field& f : scan.fields) {
        if (f.role != Role::kExtra) continue;
        f.extra_type = extra_names_[kept++].data_type;
        f.extra_size = extra_type_size(f.extra_type);
        f.extra_at = at;  // the kept fields in prototype order
        at += f.extra_size;
      }
    }
    if (!skipped.empty()) {
      std::string list;
      for (const std::string& n : skipped) list += (list.empty() ? "" : ", ") + quoted(n);
      info_.warnings.push_back(name() + ": fields " + list + " are not read (extra bytes are off)");
    }
    return Status::ok();
  }

  static bool has_role(const Scan& scan, Role r) {
    return std::any_of(scan.fields.begin(), scan.fields.end(), [&](const Field& f) { return f.role == r; });
  }

  // ---- Binary sections.

  Status open_scan(std::size_t s) {
    scan_ = &scans_[s];
    scan_index_ = scans_[s].index;
    const std::string where = scan_name(scan_index_);
    std::uint64_t start = 0;
    RELIEF_RETURN_IF_ERROR(to_logical(scan_->file_offset, start, where + ": the points' fileOffset"));
    std::array<std::uint8_t, kSectionHeaderSize> h{};
    RELIEF_RETURN_IF_ERROR(read_logical(start, h.size(), h.data(), where + ": the points' section header"));
    if (h[0] != 1) return error(where + ": the section at fileOffset " + std::to_string(scan_->file_offset) +
                                " is not a CompressedVector section (id " + std::to_string(h[0]) + ", not 1)");
    const std::uint64_t length = load_le<std::uint64_t>(h.data() + 8);
    const std::uint64_t data_physical = load_le<std::uint64_t>(h.data() + 16);
    if (length < kSectionHeaderSize || length > logical_size_ - start) {
      return error(where + ": its section's length " + std::to_string(length) + " runs past the end of the file");
    }
    section_end_ = start + length;
    std::uint64_t data = 0;
    if (scan_->record_count > 0) {
      RELIEF_RETURN_IF_ERROR(to_logical(data_physical, data, where + ": the section's dataPhysicalOffset"));
      if (data < start + kSectionHeaderSize || data >= section_end_) {
        return error(where + ": the section's data offset " + std::to_string(data_physical) + " is outside the section");
      }
    }
    // Every record takes the bits of its fields: a recordCount the section
    // cannot hold is refused now (and no count is trusted further: a
    // bytestream that ends early is an error where it ends).
    std::uint64_t record_bits = 0;
    for (const Field& f : scan_->fields) record_bits += f.bits;
    const std::uint64_t section_bits = (section_end_ - data) * 8;  // < 2^64: the file is far smaller
    if (scan_->record_count > 0 && record_bits == 0) {
      return error(where + ": every field of its points is constant (0 bits), so its recordCount " +
                   std::to_string(scan_->record_count) + " is not bounded by any data");
    }
    if (record_bits > 0 && scan_->record_count > section_bits / record_bits) {
      return error(where + ": recordCount " + std::to_string(scan_->record_count) + " needs " +
                   std::to_string(record_bits) + " bits a record but its section holds " +
                   std::to_string(section_end_ - data) + " bytes of packets");
    }
    channels_.assign(scan_->fields.size(), Channel{});
    for (Channel& c : channels_) c.next_packet = data;
    values_.assign(scan_->fields.size(), 0);
    ints_.assign(scan_->fields.size(), 0);
    left_ = scan_->record_count;
    return Status::ok();
  }

  // Moves channel k to its buffer in the next data packet that has bytes for it.
  Status next_buffer(std::size_t k) {
    Channel& c = channels_[k];
    const std::string where = scan_name(scan_index_);
    for (;;) {
      const std::uint64_t at = c.next_packet;
      if (at >= section_end_) {
        return error(where + ": the bytestream of field " + quoted(scan_->fields[k].name) + " ends after " +
                     std::to_string(c.values) + " values but recordCount is " + std::to_string(scan_->record_count));
      }
      if (section_end_ - at < kPacketPrefixSize) return error(where + ": a packet is cut short by its section's end");
      std::array<std::uint8_t, kPacketPrefixSize> prefix{};
      RELIEF_RETURN_IF_ERROR(read_logical(at, prefix.size(), prefix.data(), where + ": a packet header"));
      const std::uint64_t length = std::uint64_t{load_le<std::uint16_t>(prefix.data() + 2)} + 1;
      if (length > section_end_ - at) {
        return error(where + ": the packet at logical byte " + std::to_string(at) + " (" + std::to_string(length) +
                     " bytes) runs past its section's end");
      }
      c.next_packet = at + length;
      if (prefix[0] == kIndexPacket || prefix[0] == kEmptyPacket) continue;
      if (prefix[0] != kDataPacket) {
        return error(where + ": packet type " + std::to_string(prefix[0]) + " at logical byte " + std::to_string(at) +
                     " is none of index (0), data (1) and empty (2)");
      }
      const std::size_t n = scan_->fields.size();
      const std::uint64_t header = kDataPacketHeaderSize + 2 * std::uint64_t{n};
      if (length < header) return error(where + ": a data packet is shorter than its own header");
      std::array<std::uint8_t, 2> count_bytes{};
      RELIEF_RETURN_IF_ERROR(read_logical(at + 4, 2, count_bytes.data(), where + ": a packet header"));
      const std::uint16_t count = load_le<std::uint16_t>(count_bytes.data());
      if (count != n) {
        return error(where + ": a data packet has " + std::to_string(count) + " bytestreams for the prototype's " +
                     std::to_string(n) + " fields");
      }
      lengths_.resize(2 * n);
      RELIEF_RETURN_IF_ERROR(read_logical(at + kDataPacketHeaderSize, lengths_.size(), lengths_.data(),
                                          where + ": a packet header"));
      std::uint64_t before = 0, total = 0;
      for (std::size_t j = 0; j < n; ++j) {
        const std::uint16_t len = load_le<std::uint16_t>(lengths_.data() + 2 * j);
        if (j < k) before += len;
        total += len;
      }
      if (header + total > length) {
        return error(where + ": a data packet's bytestream buffers (" + std::to_string(total) +
                     " bytes) overrun the packet (" + std::to_string(length) + " bytes)");
      }
      const std::uint16_t mine = load_le<std::uint16_t>(lengths_.data() + 2 * k);
      if (mine == 0) continue;
      c.buffer.resize(mine);
      RELIEF_RETURN_IF_ERROR(read_logical(at + header + before, mine, c.buffer.data(), where + ": a bytestream buffer"));
      c.used = 0;
      return Status::ok();
    }
  }

  // The next `bits` (at most 56) bits of channel k, least significant first.
  Status take_bits(std::size_t k, unsigned bits, std::uint64_t& out) {
    Channel& c = channels_[k];
    while (c.acc_bits < bits) {
      if (c.used == c.buffer.size()) RELIEF_RETURN_IF_ERROR(next_buffer(k));
      c.acc |= std::uint64_t{c.buffer[c.used++]} << c.acc_bits;
      c.acc_bits += 8;
    }
    out = bits == 0 ? 0 : c.acc & (~std::uint64_t{0} >> (64 - bits));
    c.acc = bits == 64 ? 0 : c.acc >> bits;
    c.acc_bits -= bits;
    return Status::ok();
  }

  Status take_value(std::size_t k, std::uint64_t& out) {
    const unsigned bits = scan_->fields[k].bits;
    if (bits <= 56) return take_bits(k, bits, out);
    std::uint64_t low = 0, high = 0;
    RELIEF_RETURN_IF_ERROR(take_bits(k, 32, low));
    RELIEF_RETURN_IF_ERROR(take_bits(k, bits - 32, high));
    out = low | high << 32;
    return Status::ok();
  }

  Status above_maximum(const Field& f) const {
    return record_error("field " + quoted(f.name) + " holds a value above its maximum " +
                        std::to_string(f.maximum));
  }

  Status record_error(const std::string& what) const {
    const std::uint64_t record = scan_->record_count - left_;
    return error(scan_name(scan_index_) + ": record " + std::to_string(record) + ": " + what);
  }

  // Decodes one record of every field into values_ (and ints_ for integer
  // fields), then makes it a point of `batch` unless it is marked invalid:
  // an invalid point is skipped before any of its other values is checked.
  Status read_record(PointCloud& batch, bool& kept) {
    kept = false;
    const std::vector<Field>& fields = scan_->fields;
    std::size_t above = fields.size();  // the first field above its maximum
    for (std::size_t k = 0; k < fields.size(); ++k) {
      const Field& f = fields[k];
      std::uint64_t raw = 0;
      RELIEF_RETURN_IF_ERROR(take_value(k, raw));
      ++channels_[k].values;
      if (f.type == FieldType::kFloat) {
        values_[k] = f.single ? static_cast<double>(std::bit_cast<float>(static_cast<std::uint32_t>(raw)))
                              : std::bit_cast<double>(raw);
        continue;
      }
      if (raw > static_cast<std::uint64_t>(f.maximum) - static_cast<std::uint64_t>(f.minimum)) {
        if (f.role == Role::kInvalidState) return above_maximum(f);
        above = std::min(above, k);
      }
      ints_[k] = static_cast<std::int64_t>(static_cast<std::uint64_t>(f.minimum) + raw);
      values_[k] = f.type == FieldType::kScaledInteger ? static_cast<double>(ints_[k]) * f.scale + f.offset
                                                        : static_cast<double>(ints_[k]);
    }
    if (scan_->invalid_state < fields.size()) {
      const double state = values_[scan_->invalid_state];
      if (state == 1 || state == 2) {  // a direction without a range, or no return
        ++info_.skipped_points;
        return Status::ok();
      }
    }
    if (above < fields.size()) return above_maximum(fields[above]);
    const auto flagged = [&](std::size_t k) { return k < fields.size() && values_[k] != 0; };
    const bool intensity_invalid = flagged(scan_->intensity_invalid);
    const bool time_invalid = flagged(scan_->time_invalid);
    double p[3] = {0, 0, 0};
    double sph[3] = {0, 0, 0};
    float intensity = 0;
    std::array<std::int64_t, 3> levels{};
    double time = 0;
    std::uint8_t return_number = 0, returns = 0;
    for (std::size_t k = 0; k < fields.size(); ++k) {
      const Field& f = fields[k];
      const double v = values_[k];
      switch (f.role) {
        case Role::kX:
        case Role::kY:
        case Role::kZ:
          p[static_cast<int>(f.role) - static_cast<int>(Role::kX)] = v;
          break;
        case Role::kRange:
        case Role::kAzimuth:
        case Role::kElevation:
          sph[static_cast<int>(f.role) - static_cast<int>(Role::kRange)] = v;
          break;
        case Role::kInvalidState:
          break;
        case Role::kIntensity:
          if (intensity_invalid) break;  // 0
          if (!(std::fabs(v) <= static_cast<double>(std::numeric_limits<float>::max()))) {
            return record_error("intensity " + format_double(v) + " is not a finite float");
          }
          intensity = static_cast<float>(v);
          break;
        case Role::kRed:
        case Role::kGreen:
        case Role::kBlue:
          levels[static_cast<std::size_t>(static_cast<int>(f.role) - static_cast<int>(Role::kRed))] =
              ints_[k];
          break;
        case Role::kTime:
          if (time_invalid) break;  // 0
          if (!std::isfinite(v))
            return record_error("timeStamp " + format_double(v) + " is not a finite number");
          time = v;
          break;
        case Role::kReturnIndex:
          return_number = static_cast<std::uint8_t>(ints_[k] + 1);
          break;
        case Role::kReturnCount:
          returns = static_cast<std::uint8_t>(ints_[k]);
          break;
        case Role::kExtra:
          put_extra(f, k);
          break;
        case Role::kSkip:
          break;
      }
    }
    if (scan_->spherical) {
      const double r = sph[0], az = sph[1], el = sph[2];
      p[0] = r * std::cos(el) * std::cos(az);
      p[1] = r * std::cos(el) * std::sin(az);
      p[2] = r * std::sin(el);
    }
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) {
      return record_error("a coordinate is not finite");
    }
    Vec3d out{p[0], p[1], p[2]};
    if (scan_->has_pose) {
      const auto& m = scan_->rotation;
      const auto& t = scan_->translation;
      out.x = m[0] * p[0] + m[1] * p[1] + m[2] * p[2] + t[0];
      out.y = m[3] * p[0] + m[4] * p[1] + m[5] * p[2] + t[1];
      out.z = m[6] * p[0] + m[7] * p[1] + m[8] * p[2] + t[2];
      if (!std::isfinite(out.x) || !std::isfinite(out.y) || !std::isfinite(out.z)) {
        return record_error("the point is not finite once the scan's pose is applied");
      }
    }
    batch.positions.push_back(out);
    if (scan_->colors) {
      if (scan_->scaled_colors) {
        for (std::size_t c = 0; c < 3; ++c) {
          const double lo = scan_->color_lo[c], hi = scan_->color_hi[c];
          const double level = hi > lo ? (static_cast<double>(levels[c]) - lo) * 65535 / (hi - lo) : 0;
          levels[c] = std::lround(std::clamp(level, 0.0, 65535.0));
        }
      }
      if (scan_->wide_colors) {
        batch.colors.push_back({static_cast<std::uint8_t>(levels[0] >> 8), static_cast<std::uint8_t>(levels[1] >> 8),
                                static_cast<std::uint8_t>(levels[2] >> 8)});
        batch.las.color_low.push_back({static_cast<std::uint8_t>(levels[0] & 0xFF),
                                       static_cast<std::uint8_t>(levels[1] & 0xFF),
                                       static_cast<std::uint8_t>(levels[2] & 0xFF)});
      } else {
        batch.colors.push_back({static_cast<std::uint8_t>(levels[0]), static_cast<std::uint8_t>(levels[1]),
                                static_cast<std::uint8_t>(levels[2])});
      }
    }
    if (first_intensity_) batch.intensities.push_back(intensity);
    if (scan_->las & kLasGpsTime) batch.las.gps_time.push_back(time);
    if (scan_->las & kLasReturnNumber) batch.las.return_number.push_back(return_number);
    if (scan_->las & kLasNumberOfReturns) batch.las.number_of_returns.push_back(returns);
    batch.las.extra_bytes.insert(batch.las.extra_bytes.end(), scratch_.begin(), scratch_.end());
    kept = true;
    return Status::ok();
  }

  // Field k's value of this record into scratch_, little-endian, as its type.
  void put_extra(const Field& f, std::size_t k) {
    std::uint8_t* at = scratch_.data() + f.extra_at;
    std::uint64_t bits = 0;
    switch (f.extra_type) {
      case kF32:
        bits = std::bit_cast<std::uint32_t>(static_cast<float>(values_[k]));
        break;
      case kF64:
        bits = std::bit_cast<std::uint64_t>(values_[k]);
        break;
      default:
        bits = static_cast<std::uint64_t>(ints_[k]);  // two's complement: the low bytes are the value
        break;
    }
    for (std::size_t b = 0; b < f.extra_size; ++b) at[b] = static_cast<std::uint8_t>(bits >> (8 * b));
  }

  ByteSource src_;
  bool keep_extras_ = true;
  PointStreamInfo info_;
  std::uint64_t file_size_ = 0;
  std::uint64_t page_size_ = 0, logical_page_ = 0, logical_size_ = 0;
  std::uint64_t xml_offset_ = 0, xml_length_ = 0;
  std::vector<CachedPage> cache_;

  std::vector<Scan> scans_;
  std::uint32_t first_las_ = 0;
  bool first_colors_ = false;
  bool first_intensity_ = false;
  bool intensity_noted_ = false;
  std::vector<KeptField> extra_names_;
  std::size_t extra_size_ = 0;
  std::vector<std::uint8_t> scratch_;  // one record's extra bytes

  // The scan being read.
  std::size_t next_scan_ = 0;
  std::size_t scan_index_ = 0;
  const Scan* scan_ = nullptr;
  std::uint64_t section_end_ = 0;  // logical
  std::uint64_t left_ = 0;         // records of the scan not yet read
  std::vector<Channel> channels_;
  std::vector<double> values_;
  std::vector<std::int64_t> ints_;
  std::vector<std::uint8_t> lengths_;
};

}  // namespace

Result<std::unique_ptr<PointReader>> open_e57_reader(const InputSpec& input, const ReaderOptions& options) {
  RELIEF_ASSIGN_OR_RETURN(ByteSource src, input.open());
  auto reader = std::make_unique<E57PointReader>(input.name, std::move(src), options);
  RELIEF_RETURN_IF_ERROR(reader->start());
  return std::unique_ptr<PointReader>(std::move(reader));
}

}  // namespace relief
