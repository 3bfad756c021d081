// A/B tool for the integer coding under the error-bounded codec's sections
// (not registered with CTest; built beside the tests because it needs the
// codec's internal range coder). It answers one question with numbers: how
// much faster could the signed residuals that colours, intensities and
// scan-order geometry spend most of their decoding time on (bench/README.md,
// "Where the decoding time goes") be coded, and at what cost in bytes?
//
// Three coders of the same residual streams, each stream cut into blocks of
// --block values (a chunk's section), models reset per block:
//   binary  the codec's own: encode_sint / decode_sint (range_coder.h), an
//           adaptive Exp-Golomb code of two-speed binary models, one model set
//           per context: 2n + 3 binary decisions for a magnitude of n + 1 bits;
//   cdf16   a prototype: the magnitude class (0 for zero, 1 + n for n + 1
//           bits, 15 = escape) as one symbol of an adaptive 16-symbol
//           cumulative distribution on the same range coder, then the sign
//           and the top two bits below the leading one as binary decisions,
//           the rest raw in one step;
//   rans    a prototype: the same classes (32 of them) coded by static rANS
//           (32-bit state, byte renormalisation, 12-bit frequencies, a table
//           per context and block counted at 2 bytes per used class), the
//           sign and the bits below the leading one written raw to a
//           separate bit stream.
// Each coder's output is decoded and compared with the input.
//
// Streams: the intensities of each shared LAS/LAZ/PLY file in file order
// (deltas, the context from the previous delta's size, as §11.5 codes
// them), the green channel of each coloured file (deltas from the previous
// point, contexts as §11.4), and Laplacian noise at three scales.
//
//   build/tests/codec/integer_coder_ab [--data DIR] [--block N] [--repeat N]
#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "codec/range_coder.h"
#include "relief/io.h"

namespace {

using relief::codec::BitModel;
using relief::codec::RangeDecoder;
using relief::codec::RangeEncoder;
using relief::codec::SIntModel;

struct Stream {
  std::string name;
  std::vector<std::int64_t> values;
  std::vector<std::uint8_t> contexts;
  int context_count = 1;
};

// ---- binary: the codec's coder.

std::vector<std::uint8_t> binary_encode(const Stream& s, std::size_t b, std::size_t e) {
  RangeEncoder enc;
  auto models = std::make_unique<SIntModel[]>(static_cast<std::size_t>(s.context_count));
  for (std::size_t i = b; i < e; ++i) relief::codec::encode_sint(enc, models[s.contexts[i]], s.values[i]);
  return enc.finish();
}

bool binary_decode(const Stream& s, std::size_t b, std::size_t e, const std::vector<std::uint8_t>& bytes) {
  RangeDecoder dec(bytes);
  auto models = std::make_unique<SIntModel[]>(static_cast<std::size_t>(s.context_count));
  bool ok = true;
  for (std::size_t i = b; i < e; ++i) {
    std::int64_t v = 0;
    ok &= relief::codec::decode_sint(dec, models[s.contexts[i]], v) && v == s.values[i];
  }
  return ok;
}

// ---- Magnitude classes shared by the prototypes: 0 for zero, 1 + n for a
// magnitude of n + 1 bits.
int magnitude_class(std::int64_t v, std::uint64_t& mag) {
  mag = v < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(v) : static_cast<std::uint64_t>(v);
  return mag == 0 ? 0 : static_cast<int>(std::bit_width(mag));
}

// ---- cdf16: an adaptive 16-symbol distribution on a carry-less range coder
// (the codec's, with a multi-symbol step added).
constexpr int kSymbols = 16;
constexpr int kTotalBits = 15;
constexpr std::uint32_t kTotal = 1u << kTotalBits;
constexpr std::uint32_t kSpread = kTotal - kSymbols;  // each symbol gets 1 more

struct Cdf {
  std::array<std::uint16_t, kSymbols + 1> c{};
  std::uint8_t seen = 0;
  Cdf() {
    for (int i = 0; i <= kSymbols; ++i) c[static_cast<std::size_t>(i)] = static_cast<std::uint16_t>(kSpread * i / kSymbols);
  }
  std::uint32_t low(int s) const { return c[static_cast<std::size_t>(s)] + static_cast<std::uint32_t>(s); }
  void update(int s) {
    const int rate = 4 + (seen > 15) + (seen > 31);
    seen = static_cast<std::uint8_t>(seen + (seen < 255));
    for (int i = 1; i < kSymbols; ++i) {
      auto& v = c[static_cast<std::size_t>(i)];
      v = static_cast<std::uint16_t>(i > s ? v + ((kSpread - v) >> rate) : v - (v >> rate));
    }
  }
};

struct CdfModel {
  Cdf classes;
  BitModel sign;
  BitModel top[kSymbols][2];
};

class CdfEncoder {
 public:
  void bit(BitModel& m, int b) {
    const std::uint32_t bound = (range_ >> 16) * m.p0();
    low_ += b ? bound : 0;
    range_ = b ? range_ - bound : bound;
    m.update(b);
    normalise();
  }
  void symbol(Cdf& m, int s) {
    const std::uint32_t r = range_ >> kTotalBits;
    const std::uint32_t a = m.low(s);
    low_ += static_cast<std::uint64_t>(r) * a;
    range_ = s == kSymbols - 1 ? range_ - r * a : r * (m.low(s + 1) - a);
    m.update(s);
    normalise();
  }
  void raw(std::uint64_t v, int k) {  // k <= 16
    const std::uint32_t r = range_ >> k;
    const auto top = static_cast<std::uint32_t>((1u << k) - 1);
    low_ += static_cast<std::uint64_t>(r) * v;
    range_ = v == top ? range_ - r * static_cast<std::uint32_t>(v) : r;
    normalise();
  }
  std::vector<std::uint8_t> finish() {
    for (int i = 0; i < 5; ++i) shift_low();
    return {out_.begin() + 1, out_.end()};
  }

 private:
  void normalise() {
    while (range_ < (1u << 24)) {
      range_ <<= 8;
      shift_low();
    }
  }
  void shift_low() {
    if (low_ < 0xFF000000ull || low_ >= (1ull << 32)) {
      const auto carry = static_cast<std::uint8_t>(low_ >> 32);
      std::uint8_t t = cache_;
      do {
        out_.push_back(static_cast<std::uint8_t>(t + carry));
        t = 0xFF;
      } while (--pending_ != 0);
      cache_ = static_cast<std::uint8_t>(low_ >> 24);
    }
    ++pending_;
    low_ = (low_ & 0x00FFFFFFull) << 8;
  }
  std::uint64_t low_ = 0;
  std::uint32_t range_ = 0xFFFFFFFFu;
  std::uint8_t cache_ = 0;
  std::uint64_t pending_ = 1;
  std::vector<std::uint8_t> out_;
};

class CdfDecoder {
 public:
  explicit CdfDecoder(const std::vector<std::uint8_t>& d) : p_(d.data()), end_(d.data() + d.size()) {
    for (int i = 0; i < 4; ++i) code_ = (code_ << 8) | next();
  }
  int bit(BitModel& m) {
    const std::uint32_t bound = (range_ >> 16) * m.p0();
    const int b = code_ >= bound ? 1 : 0;
    code_ -= b ? bound : 0;
    range_ = b ? range_ - bound : bound;
    m.update(b);
    normalise();
    return b;
  }
  int symbol(Cdf& m) {
    const std::uint32_t r = range_ >> kTotalBits;
    const std::uint32_t v = std::min(code_ / r, kTotal - 1);
    int s = 0;
    for (int i = 1; i < kSymbols; ++i) s += m.low(i) <= v ? 1 : 0;
    const std::uint32_t a = m.low(s);
    code_ -= r * a;
    range_ = s == kSymbols - 1 ? range_ - r * a : r * (m.low(s + 1) - a);
    m.update(s);
    normalise();
    return s;
  }
  std::uint64_t raw(int k) {
    const std::uint32_t r = range_ >> k;
    const auto top = static_cast<std::uint32_t>((1u << k) - 1);
    const std::uint32_t v = std::min(code_ / r, top);
    code_ -= r * v;
    range_ = v == top ? range_ - r * v : r;
    normalise();
    return v;
  }

 private:
  std::uint8_t next() { return p_ < end_ ? *p_++ : 0; }
  void normalise() {
    while (range_ < (1u << 24)) {
      range_ <<= 8;
      code_ = (code_ << 8) | next();
    }
  }
  const std::uint8_t* p_;
  const std::uint8_t* end_;
  std::uint32_t range_ = 0xFFFFFFFFu;
  std::uint32_t code_ = 0;
};

// Raw bits below the modelled ones, at most 16 a step.
void cdf_raw(CdfEncoder& e, std::uint64_t v, int k) {
  for (; k > 16; k -= 16) e.raw((v >> (k - 16)) & 0xFFFF, 16);
  if (k > 0) e.raw(v & ((std::uint64_t{1} << k) - 1), k);
}
std::uint64_t cdf_raw(CdfDecoder& d, int k) {
  std::uint64_t v = 0;
  for (; k > 16; k -= 16) v = (v << 16) | d.raw(16);
  if (k > 0) v = (v << k) | d.raw(k);
  return v;
}

std::vector<std::uint8_t> cdf_encode(const Stream& s, std::size_t b, std::size_t e) {
  CdfEncoder enc;
  auto models = std::make_unique<CdfModel[]>(static_cast<std::size_t>(s.context_count));
  for (std::size_t i = b; i < e; ++i) {
    CdfModel& m = models[s.contexts[i]];
    std::uint64_t mag = 0;
    const int cls = magnitude_class(s.values[i], mag);
    enc.symbol(m.classes, std::min(cls, kSymbols - 1));
    if (cls == 0) continue;
    if (cls >= kSymbols - 1) enc.raw(static_cast<std::uint64_t>(cls - (kSymbols - 1)), 6);  // escape: 15..64
    enc.bit(m.sign, s.values[i] < 0 ? 1 : 0);
    const int n = cls - 1;  // bits below the leading one
    const int modelled = std::min(n, 2);
    const int slot = std::min(cls, kSymbols - 1);
    for (int k = 0; k < modelled; ++k) enc.bit(m.top[slot][k], static_cast<int>((mag >> (n - 1 - k)) & 1));
    cdf_raw(enc, mag, n - modelled);
  }
  return enc.finish();
}

bool cdf_decode(const Stream& s, std::size_t b, std::size_t e, const std::vector<std::uint8_t>& bytes) {
  CdfDecoder dec(bytes);
  auto models = std::make_unique<CdfModel[]>(static_cast<std::size_t>(s.context_count));
  bool ok = true;
  for (std::size_t i = b; i < e; ++i) {
    CdfModel& m = models[s.contexts[i]];
    int cls = dec.symbol(m.classes);
    if (cls == 0) {
      ok &= s.values[i] == 0;
      continue;
    }
    const int slot = cls;
    if (cls == kSymbols - 1) cls += static_cast<int>(dec.raw(6));
    const int negative = dec.bit(m.sign);
    const int n = cls - 1;
    const int modelled = std::min(n, 2);
    std::uint64_t mag = 1;
    for (int k = 0; k < modelled; ++k) mag = (mag << 1) | static_cast<std::uint64_t>(dec.bit(m.top[slot][k]));
    const int rest = n - modelled;
    mag = rest > 0 ? (mag << rest) | cdf_raw(dec, rest) : mag;
    const auto v = negative ? -static_cast<std::int64_t>(mag) : static_cast<std::int64_t>(mag);
    ok &= v == s.values[i];
  }
  return ok;
}

// ---- rans: static tables, classes by rANS, sign and low bits raw.
constexpr int kRansClasses = 32;  // magnitudes below 2^31
constexpr int kScaleBits = 12;
constexpr std::uint32_t kScale = 1u << kScaleBits;
constexpr std::uint32_t kRansLow = 1u << 23;

struct RansTable {
  std::array<std::uint16_t, kRansClasses> freq{};
  std::array<std::uint16_t, kRansClasses + 1> cum{};
  std::vector<std::uint8_t> slot;  // kScale entries: the class of each slot
};

// Frequencies summing to kScale, every used class at least 1.
RansTable make_table(const std::array<std::uint64_t, kRansClasses>& counts) {
  RansTable t;
  std::uint64_t total = 0;
  for (const auto c : counts) total += c;
  if (total == 0) return t;
  std::uint32_t sum = 0;
  int largest = 0;
  for (int s = 0; s < kRansClasses; ++s) {
    const auto c = counts[static_cast<std::size_t>(s)];
    if (c == 0) continue;
    const auto f = static_cast<std::uint32_t>(std::max<std::uint64_t>(1, c * kScale / total));
    t.freq[static_cast<std::size_t>(s)] = static_cast<std::uint16_t>(f);
    sum += f;
    if (c > counts[static_cast<std::size_t>(largest)]) largest = s;
  }
  // Give or take the rounding from the most frequent class.
  auto& top = t.freq[static_cast<std::size_t>(largest)];
  top = static_cast<std::uint16_t>(static_cast<std::int64_t>(top) + static_cast<std::int64_t>(kScale) - sum);
  for (int s = 0; s < kRansClasses; ++s) {
    t.cum[static_cast<std::size_t>(s) + 1] = static_cast<std::uint16_t>(t.cum[static_cast<std::size_t>(s)] + t.freq[static_cast<std::size_t>(s)]);
  }
  t.slot.resize(kScale);
  for (int s = 0; s < kRansClasses; ++s) {
    for (std::uint32_t k = t.cum[static_cast<std::size_t>(s)]; k < t.cum[static_cast<std::size_t>(s) + 1]; ++k) t.slot[k] = static_cast<std::uint8_t>(s);
  }
  return t;
}

class BitWriter {
 public:
  void put(std::uint64_t v, int k) {  // k <= 32
    acc_ |= (v & ((std::uint64_t{1} << k) - 1)) << fill_;
    fill_ += k;
    while (fill_ >= 8) {
      out_.push_back(static_cast<std::uint8_t>(acc_));
      acc_ >>= 8;
      fill_ -= 8;
    }
  }
  std::vector<std::uint8_t> finish() {
    if (fill_ > 0) out_.push_back(static_cast<std::uint8_t>(acc_));
    for (int i = 0; i < 8; ++i) out_.push_back(0);  // the reader's look-ahead
    return std::move(out_);
  }

 private:
  std::uint64_t acc_ = 0;
  int fill_ = 0;
  std::vector<std::uint8_t> out_;
};

class BitReader {
 public:
  explicit BitReader(const std::uint8_t* p) : p_(p) {}
  std::uint64_t get(int k) {  // k <= 32
    std::uint64_t w;
    std::memcpy(&w, p_ + (pos_ >> 3), 8);
    const std::uint64_t v = (w >> (pos_ & 7)) & ((std::uint64_t{1} << k) - 1);
    pos_ += static_cast<std::size_t>(k);
    return v;
  }

 private:
  const std::uint8_t* p_;
  std::size_t pos_ = 0;
};

struct RansBlock {
  std::vector<RansTable> tables;
  std::size_t table_bytes = 0;
  std::vector<std::uint8_t> rans;  // read forwards by the decoder
  std::vector<std::uint8_t> bits;
  std::size_t bytes() const { return table_bytes + rans.size() + bits.size() - 8; }
};

void put_raw(BitWriter& w, std::uint64_t v, int k) {
  for (; k > 32; k -= 32) w.put(v >> (k - 32), 32);
  if (k > 0) w.put(v, k);
}
std::uint64_t get_raw(BitReader& r, int k) {
  std::uint64_t v = 0;
  for (; k > 32; k -= 32) v = (v << 32) | r.get(32);
  if (k > 0) v = (v << k) | r.get(k);
  return v;
}

RansBlock rans_encode(const Stream& s, std::size_t b, std::size_t e) {
  RansBlock out;
  const auto contexts = static_cast<std::size_t>(s.context_count);
  std::vector<std::array<std::uint64_t, kRansClasses>> counts(contexts);
  std::vector<std::uint8_t> cls(e - b);
  BitWriter bits;
  for (std::size_t i = b; i < e; ++i) {
    std::uint64_t mag = 0;
    const int c = magnitude_class(s.values[i], mag);
    cls[i - b] = static_cast<std::uint8_t>(c);
    ++counts[s.contexts[i]][static_cast<std::size_t>(c)];
    if (c > 0) {
      bits.put(s.values[i] < 0 ? 1 : 0, 1);
      put_raw(bits, mag, c - 1);
    }
  }
  out.tables.reserve(contexts);
  for (const auto& c : counts) {
    out.tables.push_back(make_table(c));
    for (const auto n : c) out.table_bytes += n > 0 ? 2 : 0;
  }
  // rANS codes backwards; the bytes are then reversed for a forward decoder.
  std::vector<std::uint8_t> rev;
  std::uint32_t x = kRansLow;
  for (std::size_t i = e; i-- > b;) {
    const RansTable& t = out.tables[s.contexts[i]];
    const std::size_t c = cls[i - b];
    const std::uint32_t f = t.freq[c];
    const std::uint32_t x_max = ((kRansLow >> kScaleBits) << 8) * f;
    while (x >= x_max) {
      rev.push_back(static_cast<std::uint8_t>(x));
      x >>= 8;
    }
    x = ((x / f) << kScaleBits) + (x % f) + t.cum[c];
  }
  for (int k = 0; k < 4; ++k) {
    rev.push_back(static_cast<std::uint8_t>(x));
    x >>= 8;
  }
  out.rans.assign(rev.rbegin(), rev.rend());
  out.bits = bits.finish();
  return out;
}

bool rans_decode(const Stream& s, std::size_t b, std::size_t e, const RansBlock& in) {
  const std::uint8_t* p = in.rans.data();
  const std::uint8_t* const end = p + in.rans.size();
  std::uint32_t x = 0;
  for (int k = 0; k < 4; ++k) x = (x << 8) | *p++;
  BitReader bits(in.bits.data());
  bool ok = true;
  for (std::size_t i = b; i < e; ++i) {
    const RansTable& t = in.tables[s.contexts[i]];
    const std::uint32_t slot = x & (kScale - 1);
    const std::size_t c = t.slot[slot];
    x = t.freq[c] * (x >> kScaleBits) + slot - t.cum[c];
    while (x < kRansLow && p < end) x = (x << 8) | *p++;
    std::int64_t v = 0;
    if (c > 0) {
      const bool negative = bits.get(1) != 0;
      const std::uint64_t mag = (std::uint64_t{1} << (c - 1)) | get_raw(bits, static_cast<int>(c) - 1);
      v = negative ? -static_cast<std::int64_t>(mag) : static_cast<std::int64_t>(mag);
    }
    ok &= v == s.values[i];
  }
  return ok;
}

// ---- Streams.

int value_class(std::int64_t r) {  // §11.5's context of intensity deltas
  std::uint64_t m = r < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(r) : static_cast<std::uint64_t>(r);
  int c = 0;
  for (; m != 0 && c < 11; m >>= 2) ++c;
  return c;
}

int colour_class(std::int64_t q) {  // §11.4's classes of colour residuals
  const std::uint64_t m = q < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(q) : static_cast<std::uint64_t>(q);
  return m == 0 ? 0 : m == 1 ? 1 : m <= 3 ? 2 : m <= 7 ? 3 : 4;
}

void add_file_streams(const std::string& path, std::vector<Stream>& out) {
  auto reader = relief::open_point_reader(path);
  if (!reader) return;
  relief::PointCloud batch;
  Stream intensity{std::filesystem::path(path).filename().string() + " intensity", {}, {}, 12};
  Stream green{std::filesystem::path(path).filename().string() + " green", {}, {}, 5};
  std::int64_t prev_i = 0, prev_g = 0;
  int ci = 0, cg = 0;
  for (;;) {
    auto got = (*reader)->read(batch, 1 << 16);
    if (!got || *got == 0) break;
    for (std::size_t k = 0; k < batch.size(); ++k) {
      if (batch.has_intensity()) {
        const auto v = static_cast<std::int64_t>(batch.intensities[k]);
        intensity.values.push_back(v - prev_i);
        intensity.contexts.push_back(static_cast<std::uint8_t>(ci));
        ci = value_class(v - prev_i);
        prev_i = v;
      }
      if (batch.has_colors()) {
        const std::int64_t g = batch.colors[k].g;
        green.values.push_back(g - prev_g);
        green.contexts.push_back(static_cast<std::uint8_t>(cg));
        cg = colour_class(g - prev_g);
        prev_g = g;
      }
    }
  }
  if (!intensity.values.empty()) out.push_back(std::move(intensity));
  if (!green.values.empty()) out.push_back(std::move(green));
}

Stream laplace(double scale, std::size_t n) {
  Stream s{"laplace scale " + std::to_string(static_cast<int>(scale)), {}, {}, 4};
  std::mt19937_64 rng(7);
  for (std::size_t i = 0; i < n; ++i) {
    const int c = static_cast<int>(rng() % 4);
    std::exponential_distribution<double> d(1.0 / (scale * (1 + c)));
    const auto m = static_cast<std::int64_t>(d(rng));
    s.values.push_back((rng() & 1) ? m : -m);
    s.contexts.push_back(static_cast<std::uint8_t>(c));
  }
  return s;
}

double now() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

int main(int argc, char** argv) {
  std::string data = "../shared/data";
  std::size_t block = 1 << 16;
  int repeat = 3;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string a = argv[i];
    if (a == "--data") data = argv[i + 1];
    else if (a == "--block") block = std::max<std::size_t>(1, std::strtoull(argv[i + 1], nullptr, 10));
    else if (a == "--repeat") repeat = std::max(1, std::atoi(argv[i + 1]));
  }
  std::vector<Stream> streams;
  std::error_code ec;
  std::vector<std::string> files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(data, ec)) {
    const std::string p = entry.path().string();
    if (p.find("/orig/") != std::string::npos) continue;
    const std::string ext = entry.path().extension().string();
    if (ext == ".ply" || ext == ".laz") files.push_back(p);
  }
  std::sort(files.begin(), files.end());
  for (const std::string& f : files) add_file_streams(f, streams);
  for (const double scale : {1.0, 8.0, 60.0}) streams.push_back(laplace(scale, 2000000));
  std::printf("stream,values,coder,bits_per_value,encode_ns_per_value,decode_ns_per_value,decoded_ok\n");
  for (const Stream& s : streams) {
    if (s.values.size() < 1000) continue;
    const std::size_t n = s.values.size();
    std::uint64_t widest = 0;
    for (const std::int64_t v : s.values) widest = std::max(widest, v < 0 ? std::uint64_t{0} - static_cast<std::uint64_t>(v) : static_cast<std::uint64_t>(v));
    for (const char* coder : {"binary", "cdf16", "rans"}) {
      if (std::string(coder) == "rans" && std::bit_width(widest) >= kRansClasses) continue;  // beyond its classes
      std::vector<double> enc_t, dec_t;
      std::size_t bytes = 0;
      bool ok = true;
      for (int r = 0; r < repeat; ++r) {
        bytes = 0;
        double te = 0, td = 0;
        for (std::size_t b = 0; b < n; b += block) {
          const std::size_t e = std::min(n, b + block);
          const std::string c = coder;
          const double t0 = now();
          if (c == "rans") {
            const RansBlock out = rans_encode(s, b, e);
            const double t1 = now();
            ok &= rans_decode(s, b, e, out);
            td += now() - t1;
            te += t1 - t0;
            bytes += out.bytes();
          } else {
            const std::vector<std::uint8_t> out = c == "binary" ? binary_encode(s, b, e) : cdf_encode(s, b, e);
            const double t1 = now();
            ok &= c == "binary" ? binary_decode(s, b, e, out) : cdf_decode(s, b, e, out);
            td += now() - t1;
            te += t1 - t0;
            bytes += out.size();
          }
        }
        enc_t.push_back(te);
        dec_t.push_back(td);
      }
      std::sort(enc_t.begin(), enc_t.end());
      std::sort(dec_t.begin(), dec_t.end());
      const double per = 1e9 / static_cast<double>(n);
      std::printf("%s,%zu,%s,%.3f,%.1f,%.1f,%s\n", s.name.c_str(), n, coder, 8.0 * static_cast<double>(bytes) / static_cast<double>(n),
                  enc_t[enc_t.size() / 2] * per, dec_t[dec_t.size() / 2] * per, ok ? "yes" : "NO");
      std::fflush(stdout);
    }
  }
  return 0;
}
