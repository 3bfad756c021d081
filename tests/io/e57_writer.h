// A small ASTM E57 writer for tests, written from the standard's description
// (E2807): the 48-byte header, pages of 1020 logical bytes each followed by
// the CRC-32C of them (most significant byte first), one CompressedVector
// binary section per scan with its fields bitpacked into data packets, and
// the XML section last. Knobs let tests spread bytestreams over several
// packets (split at arbitrary bytes, so values straddle packets), add index
// and empty packets, and write the inconsistencies readers must refuse.
#pragma once

#include <bit>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <string>
#include <vector>

namespace relief::test::e57 {

constexpr std::uint64_t kPage = 1024;
constexpr std::uint64_t kLogicalPage = kPage - 4;

// Bitwise CRC-32C (Castagnoli, reflected 0x82F63B78): slow and obvious.
inline std::uint32_t crc32c(const std::uint8_t* p, std::size_t n) {
  std::uint32_t c = 0xFFFFFFFFu;
  for (std::size_t i = 0; i < n; ++i) {
    c ^= p[i];
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0x82F63B78u & (0u - (c & 1u)));
  }
  return ~c;
}

enum class Type { kInteger, kScaledInteger, kFloat };

struct Field {
  std::string name;
  Type type = Type::kInteger;
  std::int64_t minimum = 0, maximum = 0;
  double scale = 1, offset = 0;
  std::string precision = "double";  // Float: "single", "double" (or anything, to test refusals)
  std::vector<std::int64_t> ints;    // Integer, ScaledInteger: the raw integers
  std::vector<double> reals;         // Float

  static Field integer(std::string n, std::int64_t lo, std::int64_t hi, std::vector<std::int64_t> v) {
    Field f;
    f.name = std::move(n);
    f.minimum = lo;
    f.maximum = hi;
    f.ints = std::move(v);
    return f;
  }
  static Field scaled(std::string n, std::int64_t lo, std::int64_t hi, double s, double o, std::vector<std::int64_t> v) {
    Field f = integer(std::move(n), lo, hi, std::move(v));
    f.type = Type::kScaledInteger;
    f.scale = s;
    f.offset = o;
    return f;
  }
  static Field real(std::string n, std::vector<double> v, bool single = false) {
    Field f;
    f.name = std::move(n);
    f.type = Type::kFloat;
    f.precision = single ? "single" : "double";
    f.reals = std::move(v);
    return f;
  }
  std::size_t count() const { return type == Type::kFloat ? reals.size() : ints.size(); }
};

struct Pose {
  double w = 1, x = 0, y = 0, z = 0;  // rotation quaternion
  double tx = 0, ty = 0, tz = 0;
};

struct Scan {
  std::vector<Field> fields;
  std::optional<Pose> pose;
  int packets = 1;             // data packets the bytestreams are split over
  bool extra_packets = false;  // an index packet and an empty packet between data packets
  std::optional<std::uint64_t> record_count;  // instead of the fields' value count
  std::optional<std::uint64_t> file_offset;   // instead of the section's
  std::string codecs;                         // inner XML of <codecs>
  std::string extra_xml;                      // more children of the scan's element (colorLimits ...)
};

inline std::string real_text(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

// Field values as their bytestream: integers (value - minimum) in the fewest
// bits that hold maximum - minimum, least significant bit first; floats as
// little-endian IEEE bytes.
inline std::vector<std::uint8_t> bytestream(const Field& f) {
  std::vector<std::uint8_t> out;
  if (f.type == Type::kFloat) {
    const bool single = f.precision == "single";
    for (double v : f.reals) {
      const std::uint64_t bits = single ? std::bit_cast<std::uint32_t>(static_cast<float>(v)) : std::bit_cast<std::uint64_t>(v);
      for (int b = 0; b < (single ? 4 : 8); ++b) out.push_back(static_cast<std::uint8_t>(bits >> (8 * b)));
    }
    return out;
  }
  const std::uint64_t span = static_cast<std::uint64_t>(f.maximum) - static_cast<std::uint64_t>(f.minimum);
  const int width = static_cast<int>(std::bit_width(span));
  std::uint8_t cur = 0;
  int filled = 0;
  for (std::int64_t v : f.ints) {
    const std::uint64_t raw = static_cast<std::uint64_t>(v) - static_cast<std::uint64_t>(f.minimum);
    for (int b = 0; b < width; ++b) {
      cur = static_cast<std::uint8_t>(cur | (((raw >> b) & 1u) << filled));
      if (++filled == 8) {
        out.push_back(cur);
        cur = 0;
        filled = 0;
      }
    }
  }
  if (filled > 0) out.push_back(cur);
  return out;
}

inline void put_le(std::vector<std::uint8_t>& out, std::uint64_t v, int bytes) {
  for (int b = 0; b < bytes; ++b) out.push_back(static_cast<std::uint8_t>(v >> (8 * b)));
}

inline std::uint64_t physical(std::uint64_t logical) {
  return logical / kLogicalPage * kPage + logical % kLogicalPage;
}

inline std::string field_xml(const Field& f) {
  switch (f.type) {
    case Type::kInteger:
      return "<" + f.name + " type=\"Integer\" minimum=\"" + std::to_string(f.minimum) + "\" maximum=\"" +
             std::to_string(f.maximum) + "\"/>";
    case Type::kScaledInteger:
      return "<" + f.name + " type=\"ScaledInteger\" minimum=\"" + std::to_string(f.minimum) + "\" maximum=\"" +
             std::to_string(f.maximum) + "\" scale=\"" + real_text(f.scale) + "\" offset=\"" + real_text(f.offset) +
             "\"/>";
    case Type::kFloat:
      return "<" + f.name + " type=\"Float\" precision=\"" + f.precision + "\"/>";
  }
  return {};
}

// The whole file.
inline std::vector<std::uint8_t> write(const std::vector<Scan>& scans) {
  std::vector<std::uint8_t> L(48, 0);  // logical bytes; the header is filled in last
  std::string scans_xml;
  for (const Scan& s : scans) {
    while (L.size() % 4 != 0) L.push_back(0);
    const std::uint64_t section = L.size();
    std::vector<std::vector<std::uint8_t>> streams;
    for (const Field& f : s.fields) streams.push_back(bytestream(f));
    // Section header, length patched below.
    L.push_back(1);
    L.insert(L.end(), 7, 0);
    const std::size_t length_at = L.size();
    put_le(L, 0, 8);
    put_le(L, physical(section + 32), 8);  // data right after the header
    put_le(L, 0, 8);                        // no index
    const auto prefix_packet = [&](std::uint8_t type, std::size_t length) {
      L.push_back(type);
      L.push_back(0);
      put_le(L, length - 1, 2);
      L.insert(L.end(), length - 4, 0);
    };
    for (int p = 0; p < s.packets; ++p) {
      if (s.extra_packets && p == 1) {
        prefix_packet(0, 16);  // index packet (its entries are not read)
        prefix_packet(2, 8);   // empty packet
      }
      const std::size_t start = L.size();
      L.push_back(1);
      L.push_back(0);
      const std::size_t len_at = L.size();
      put_le(L, 0, 2);
      put_le(L, s.fields.size(), 2);
      std::vector<std::pair<std::size_t, std::size_t>> ranges;
      for (const auto& bs : streams) {
        const std::size_t a = bs.size() * static_cast<std::size_t>(p) / static_cast<std::size_t>(s.packets);
        const std::size_t b = bs.size() * static_cast<std::size_t>(p + 1) / static_cast<std::size_t>(s.packets);
        ranges.push_back({a, b});
        put_le(L, b - a, 2);
      }
      for (std::size_t k = 0; k < streams.size(); ++k) {
        L.insert(L.end(), streams[k].begin() + static_cast<std::ptrdiff_t>(ranges[k].first),
                 streams[k].begin() + static_cast<std::ptrdiff_t>(ranges[k].second));
      }
      while ((L.size() - start) % 4 != 0) L.push_back(0);
      const std::size_t length = L.size() - start;
      L[len_at] = static_cast<std::uint8_t>((length - 1) & 0xFF);
      L[len_at + 1] = static_cast<std::uint8_t>((length - 1) >> 8);
    }
    const std::uint64_t section_length = L.size() - section;
    for (int b = 0; b < 8; ++b) L[length_at + static_cast<std::size_t>(b)] = static_cast<std::uint8_t>(section_length >> (8 * b));

    const std::uint64_t records = s.record_count ? *s.record_count : (s.fields.empty() ? 0 : s.fields[0].count());
    std::string xml = "<vectorChild type=\"Structure\"><guid type=\"String\"><![CDATA[test]]></guid>";
    if (s.pose) {
      const Pose& q = *s.pose;
      xml += "<pose type=\"Structure\"><rotation type=\"Structure\"><w type=\"Float\">" + real_text(q.w) +
             "</w><x type=\"Float\">" + real_text(q.x) + "</x><y type=\"Float\">" + real_text(q.y) +
             "</y><z type=\"Float\">" + real_text(q.z) + "</z></rotation><translation type=\"Structure\"><x type=\"Float\">" +
             real_text(q.tx) + "</x><y type=\"Float\">" + real_text(q.ty) + "</y><z type=\"Float\">" + real_text(q.tz) +
             "</z></translation></pose>";
    }
    xml += "<points type=\"CompressedVector\" fileOffset=\"" +
           std::to_string(s.file_offset ? *s.file_offset : physical(section)) + "\" recordCount=\"" +
           std::to_string(records) + "\"><prototype type=\"Structure\">";
    for (const Field& f : s.fields) xml += field_xml(f);
    xml += "</prototype><codecs type=\"Vector\" allowHeterogeneousChildren=\"1\">" + s.codecs + "</codecs></points>";
    xml += s.extra_xml + "<images2D type=\"Vector\"/></vectorChild>\n";
    scans_xml += xml;
  }
  const std::string xml = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n"
                          "<e57Root type=\"Structure\" xmlns=\"http://www.astm.org/COMMIT/E57/2010-e57-v1.0\">\n"
                          "<formatName type=\"String\"><![CDATA[ASTM E57 3D Imaging Data File]]></formatName>\n"
                          "<data3D type=\"Vector\" allowHeterogeneousChildren=\"1\">\n" +
                          scans_xml + "</data3D>\n<images2D type=\"Vector\" allowHeterogeneousChildren=\"1\"/>\n</e57Root>\n";
  while (L.size() % 4 != 0) L.push_back(0);
  const std::uint64_t xml_at = L.size();
  L.insert(L.end(), xml.begin(), xml.end());
  const std::uint64_t pages = (L.size() + kLogicalPage - 1) / kLogicalPage;
  L.resize(pages * kLogicalPage, 0);
  // Header.
  std::vector<std::uint8_t> h;
  const char sig[] = "ASTM-E57";
  h.insert(h.end(), sig, sig + 8);
  put_le(h, 1, 4);
  put_le(h, 0, 4);
  put_le(h, pages * kPage, 8);
  put_le(h, physical(xml_at), 8);
  put_le(h, xml.size(), 8);
  put_le(h, kPage, 8);
  std::copy(h.begin(), h.end(), L.begin());
  // Pages.
  std::vector<std::uint8_t> file;
  for (std::uint64_t p = 0; p < pages; ++p) {
    const std::uint8_t* page = L.data() + p * kLogicalPage;
    file.insert(file.end(), page, page + kLogicalPage);
    const std::uint32_t crc = crc32c(page, kLogicalPage);
    for (int b = 3; b >= 0; --b) file.push_back(static_cast<std::uint8_t>(crc >> (8 * b)));
  }
  return file;
}

// Rewrites the CRC of every page (after a test edits the logical bytes).
inline void reseal(std::vector<std::uint8_t>& file) {
  for (std::size_t at = 0; at + kPage <= file.size(); at += kPage) {
    const std::uint32_t crc = crc32c(file.data() + at, kLogicalPage);
    for (int b = 0; b < 4; ++b) file[at + kLogicalPage + static_cast<std::size_t>(b)] = static_cast<std::uint8_t>(crc >> (8 * (3 - b)));
  }
}

}  // namespace relief::test::e57
