// GeoJSON areas: a JSON reader that keeps arrays of positions compact (16
// bytes a vertex, so a large outline costs little more than its text), and
// the walk from FeatureCollection to rings.
#include "geojson.h"

#include <array>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <tuple>
#include <utility>

namespace relief::geojson {

namespace {

constexpr int kMaxDepth = 256;

struct Value {
  enum class Kind : std::uint8_t { kNull, kBool, kNumber, kString, kArray, kObject, kPositions };
  Kind kind = Kind::kNull;
  double number = 0;
  std::string text;
  std::vector<Value> items;                            // kArray
  std::vector<std::string> keys;                       // kObject: member names
  std::vector<Value> values;                           // and their values
  // kPositions: an array whose every item is an array of at least two
  // numbers (x, y of each kept).
  std::vector<std::array<double, 2>> positions;
  std::size_t at = 0;  // character offset, for messages

  const Value* member(std::string_view key) const {
    for (std::size_t i = 0; i < keys.size(); ++i) {
      if (keys[i] == key) return &values[i];
    }
    return nullptr;
  }
  // Either form of array.
  bool is_array() const { return kind == Kind::kArray || kind == Kind::kPositions; }
};

const char* kind_name(Value::Kind k) {
  switch (k) {
    case Value::Kind::kNull: return "null";
    case Value::Kind::kBool: return "a boolean";
    case Value::Kind::kNumber: return "a number";
    case Value::Kind::kString: return "a string";
    case Value::Kind::kObject: return "an object";
    default: return "an array";
  }
}

bool all_numbers(const std::vector<Value>& items) {
  for (const Value& v : items) {
    if (v.kind != Value::Kind::kNumber) return false;
  }
  return true;
}

class Parser {
 public:
  Parser(std::string_view text, const std::string& source) : s_(text), source_(source) {}

  Status parse(Value& out) {
    if (s_.size() >= 3 && s_.substr(0, 3) == "\xEF\xBB\xBF") pos_ = 3;
    RELIEF_RETURN_IF_ERROR(value(out, 0));
    skip_space();
    if (pos_ != s_.size()) return fail("unexpected text after the JSON value");
    return Status::ok();
  }

 private:
  Status value(Value& out, int depth) {
    if (depth > kMaxDepth) return fail("nested deeper than 256 levels");
    skip_space();
    out.at = pos_;
    if (pos_ >= s_.size()) return fail("the text ends where a value should be");
    const char c = s_[pos_];
    if (c == '{') return object(out, depth);
    if (c == '[') return array(out, depth);
    if (c == '"') {
      out.kind = Value::Kind::kString;
      return string(out.text);
    }
    if (c == '-' || (c >= '0' && c <= '9')) {
      out.kind = Value::Kind::kNumber;
      return number(out.number);
    }
    for (const auto& [word, kind, flag] : {std::tuple{"true", Value::Kind::kBool, 1.0},
                                           std::tuple{"false", Value::Kind::kBool, 0.0},
                                           std::tuple{"null", Value::Kind::kNull, 0.0}}) {
      const std::string_view w = word;
      if (s_.substr(pos_, w.size()) == w) {
        pos_ += w.size();
        out.kind = kind;
        out.number = flag;
        return Status::ok();
      }
    }
    return fail(std::string("unexpected character '") + c + "'");
  }

  Status object(Value& out, int depth) {
    out.kind = Value::Kind::kObject;
    ++pos_;
    if (accept('}')) return Status::ok();
    do {
      skip_space();
      if (pos_ >= s_.size() || s_[pos_] != '"') return fail("expected a member name in quotes");
      std::string key;
      RELIEF_RETURN_IF_ERROR(string(key));
      RELIEF_RETURN_IF_ERROR(expect(':'));
      out.keys.push_back(std::move(key));
      out.values.emplace_back();
      RELIEF_RETURN_IF_ERROR(value(out.values.back(), depth + 1));
    } while (accept(','));
    return expect('}');
  }

  // Arrays of positions ([[x, y], [x, y, z], ...]) are kept as pairs; any
  // other array as its items.
  Status array(Value& out, int depth) {
    out.kind = Value::Kind::kPositions;
    ++pos_;
    if (accept(']')) {
      out.kind = Value::Kind::kArray;
      return Status::ok();
    }
    do {
      Value item;
      RELIEF_RETURN_IF_ERROR(value(item, depth + 1));
      const bool position = item.kind == Value::Kind::kArray && item.items.size() >= 2 &&
                            all_numbers(item.items);
      if (out.kind == Value::Kind::kPositions && position) {
        out.positions.push_back({item.items[0].number, item.items[1].number});
        continue;
      }
      if (out.kind == Value::Kind::kPositions) {
        // Not an array of positions after all: the pairs become items again.
        out.kind = Value::Kind::kArray;
        for (const auto& p : out.positions) {
          Value v;
          v.kind = Value::Kind::kArray;
          v.items.resize(2);
          for (int k = 0; k < 2; ++k) {
            v.items[static_cast<std::size_t>(k)].kind = Value::Kind::kNumber;
            v.items[static_cast<std::size_t>(k)].number = p[static_cast<std::size_t>(k)];
          }
          out.items.push_back(std::move(v));
        }
        out.positions.clear();
        out.positions.shrink_to_fit();
      }
      out.items.push_back(std::move(item));
    } while (accept(','));
    return expect(']');
  }

  Status string(std::string& out) {
    ++pos_;  // the opening quote
    for (;;) {
      if (pos_ >= s_.size()) return fail("a string is not closed");
      const unsigned char c = static_cast<unsigned char>(s_[pos_++]);
      if (c == '"') return Status::ok();
      if (c < 0x20) return fail("a control character inside a string");
      if (c != '\\') {
        out.push_back(static_cast<char>(c));
        continue;
      }
      if (pos_ >= s_.size()) return fail("a string is not closed");
      const char e = s_[pos_++];
      switch (e) {
        case '"': case '\\': case '/': out.push_back(e); break;
        case 'b': out.push_back('\b'); break;
        case 'f': out.push_back('\f'); break;
        case 'n': out.push_back('\n'); break;
        case 'r': out.push_back('\r'); break;
        case 't': out.push_back('\t'); break;
        case 'u': {
          std::uint32_t code = 0;
          RELIEF_RETURN_IF_ERROR(hex4(code));
          if (code >= 0xD800 && code < 0xDC00 && s_.substr(pos_, 2) == "\\u") {
            pos_ += 2;
            std::uint32_t low = 0;
            RELIEF_RETURN_IF_ERROR(hex4(low));
            if (low < 0xDC00 || low >= 0xE000) return fail("a lone UTF-16 surrogate in a string");
            code = 0x10000 + ((code - 0xD800) << 10) + (low - 0xDC00);
          } else if (code >= 0xD800 && code < 0xE000) {
            return fail("a lone UTF-16 surrogate in a string");
          }
          append_utf8(out, code);
          break;
        }
        default: return fail(std::string("the escape '\\") + e + "' in a string");
      }
    }
  }

  Status hex4(std::uint32_t& out) {
    if (s_.size() - pos_ < 4) return fail("a \\u escape needs four hexadecimal digits");
    const auto [end, ec] = std::from_chars(s_.data() + pos_, s_.data() + pos_ + 4, out, 16);
    if (ec != std::errc() || end != s_.data() + pos_ + 4) return fail("a \\u escape needs four hexadecimal digits");
    pos_ += 4;
    return Status::ok();
  }

  static void append_utf8(std::string& out, std::uint32_t c) {
    if (c < 0x80) {
      out.push_back(static_cast<char>(c));
    } else if (c < 0x800) {
      out.push_back(static_cast<char>(0xC0 | (c >> 6)));
      out.push_back(static_cast<char>(0x80 | (c & 0x3F)));
    } else if (c < 0x10000) {
      out.push_back(static_cast<char>(0xE0 | (c >> 12)));
      out.push_back(static_cast<char>(0x80 | ((c >> 6) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | (c & 0x3F)));
    } else {
      out.push_back(static_cast<char>(0xF0 | (c >> 18)));
      out.push_back(static_cast<char>(0x80 | ((c >> 12) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | ((c >> 6) & 0x3F)));
      out.push_back(static_cast<char>(0x80 | (c & 0x3F)));
    }
  }

  // JSON's number grammar, checked here (from_chars alone would also take
  // "inf", "01" or "1."), and a finite value.
  Status number(double& out) {
    const std::size_t start = pos_;
    std::size_t p = pos_;
    const auto digits = [&] {
      const std::size_t from = p;
      while (p < s_.size() && s_[p] >= '0' && s_[p] <= '9') ++p;
      return p - from;
    };
    if (p < s_.size() && s_[p] == '-') ++p;
    const std::size_t int_start = p;
    const std::size_t n = digits();
    if (n == 0 || (n > 1 && s_[int_start] == '0')) return fail("a malformed number");
    if (p < s_.size() && s_[p] == '.') {
      ++p;
      if (digits() == 0) return fail("a malformed number");
    }
    if (p < s_.size() && (s_[p] == 'e' || s_[p] == 'E')) {
      ++p;
      if (p < s_.size() && (s_[p] == '+' || s_[p] == '-')) ++p;
      if (digits() == 0) return fail("a malformed number");
    }
    const auto [end, ec] = std::from_chars(s_.data() + start, s_.data() + p, out);
    if (ec != std::errc() || end != s_.data() + p || !std::isfinite(out)) return fail("a number out of range");
    pos_ = p;
    return Status::ok();
  }

  void skip_space() {
    while (pos_ < s_.size() && (s_[pos_] == ' ' || s_[pos_] == '\t' || s_[pos_] == '\n' || s_[pos_] == '\r')) ++pos_;
  }
  bool accept(char c) {
    skip_space();
    if (pos_ < s_.size() && s_[pos_] == c) {
      ++pos_;
      return true;
    }
    return false;
  }
  Status expect(char c) {
    if (accept(c)) return Status::ok();
    return fail(std::string("expected '") + c + "'");
  }
  Status fail(const std::string& what) const {
    return invalid_argument(source_ + ": not GeoJSON: " + what + " at character " + std::to_string(pos_ + 1));
  }

  std::string_view s_;
  const std::string& source_;
  std::size_t pos_ = 0;
};

// From a parsed document to rings.
class Walker {
 public:
  Walker(const std::string& source, Area& out) : source_(source), out_(out) {}

  Status object(const Value& v, const std::string& where, int depth) {
    if (depth > kMaxDepth) return fail(where, "nested deeper than 256 levels");
    if (v.kind != Value::Kind::kObject) return fail(where, std::string("is ") + kind_name(v.kind) + ", not an object");
    const Value* type = v.member("type");
    if (type == nullptr || type->kind != Value::Kind::kString) return fail(where, "has no \"type\" string");
    const std::string& t = type->text;
    if (t == "FeatureCollection") {
      const Value* features = array_member(v, "features");
      if (features == nullptr) return fail(where, "has no \"features\" array");
      for (std::size_t i = 0; i < features->items.size(); ++i) {
        RELIEF_RETURN_IF_ERROR(object(features->items[i], "feature " + std::to_string(i + 1), depth + 1));
      }
      return Status::ok();
    }
    if (t == "Feature") {
      const Value* g = v.member("geometry");
      if (g == nullptr) return fail(where, "has no \"geometry\"");
      if (g->kind == Value::Kind::kNull) return Status::ok();
      return object(*g, where, depth + 1);
    }
    if (t == "GeometryCollection") {
      const Value* geometries = array_member(v, "geometries");
      if (geometries == nullptr) return fail(where, "has no \"geometries\" array");
      for (std::size_t i = 0; i < geometries->items.size(); ++i) {
        RELIEF_RETURN_IF_ERROR(object(geometries->items[i], join(where, "geometry " + std::to_string(i + 1)), depth + 1));
      }
      return Status::ok();
    }
    if (t == "Polygon" || t == "MultiPolygon") {
      const Value* c = v.member("coordinates");
      if (c == nullptr || !c->is_array()) return fail(where, "is a " + t + " without a \"coordinates\" array");
      if (t == "Polygon") return polygon(*c, join(where, "polygon"));
      if (c->kind == Value::Kind::kPositions && !c->positions.empty()) {
        return fail(where, "is a MultiPolygon whose coordinates are positions, not polygons");
      }
      for (std::size_t i = 0; i < c->items.size(); ++i) {
        RELIEF_RETURN_IF_ERROR(polygon(c->items[i], join(where, "polygon " + std::to_string(i + 1))));
      }
      return Status::ok();
    }
    static constexpr const char* kOthers[] = {"Point", "MultiPoint", "LineString", "MultiLineString"};
    for (const char* o : kOthers) {
      if (t == o) return fail(where, "is a " + t + ", not a Polygon or MultiPolygon");
    }
    return fail(where, "has the type \"" + t + "\", which GeoJSON does not define");
  }

 private:
  // A polygon's coordinates: rings, each an array of positions. An empty
  // polygon adds nothing.
  Status polygon(const Value& v, const std::string& where) {
    if (v.kind == Value::Kind::kPositions && !v.positions.empty()) {
      return fail(where, "has positions where its rings should be (one more [ ] is needed)");
    }
    if (v.kind != Value::Kind::kArray && v.kind != Value::Kind::kPositions) {
      return fail(where, std::string("is ") + kind_name(v.kind) + ", not an array of rings");
    }
    for (std::size_t i = 0; i < v.items.size(); ++i) {
      const Value& r = v.items[i];
      const std::string label = join(where, "ring " + std::to_string(i + 1));
      if (r.kind == Value::Kind::kArray && !r.items.empty()) {
        return fail(label, "holds something other than positions of two or more numbers");
      }
      if (!r.is_array()) return fail(label, std::string("is ") + kind_name(r.kind) + ", not an array of positions");
      out_.rings.push_back(Ring{r.positions, label});
    }
    return Status::ok();
  }

  static const Value* array_member(const Value& v, std::string_view key) {
    const Value* m = v.member(key);
    if (m == nullptr || !m->is_array()) return nullptr;
    return m;
  }
  static std::string join(const std::string& where, const std::string& what) {
    return where.empty() ? what : where + ", " + what;
  }
  Status fail(const std::string& where, const std::string& what) const {
    return invalid_argument(source_ + ": " + (where.empty() ? "the GeoJSON" : where) + " " + what);
  }

  const std::string& source_;
  Area& out_;
};

// The CRS of a 2008-style "crs" member ({"type": "name", "properties":
// {"name": ...}}); RFC 7946's longitude and latitude without one.
Status read_crs(const Value& root, const std::string& source, std::string& crs) {
  crs = "OGC:CRS84";
  const Value* c = root.member("crs");
  if (c == nullptr || c->kind == Value::Kind::kNull) return Status::ok();
  const Value* type = c->kind == Value::Kind::kObject ? c->member("type") : nullptr;
  const Value* props = c->kind == Value::Kind::kObject ? c->member("properties") : nullptr;
  const Value* name = props != nullptr && props->kind == Value::Kind::kObject ? props->member("name") : nullptr;
  if (type == nullptr || type->kind != Value::Kind::kString || type->text != "name" || name == nullptr ||
      name->kind != Value::Kind::kString || name->text.empty()) {
    return invalid_argument(source + ": the \"crs\" member names no CRS (only {\"type\": \"name\", \"properties\": "
                                     "{\"name\": ...}} is read)");
  }
  crs = name->text;
  return Status::ok();
}

}  // namespace

bool looks_like(std::string_view text) {
  std::size_t p = text.size() >= 3 && text.substr(0, 3) == "\xEF\xBB\xBF" ? 3 : 0;
  while (p < text.size() && (text[p] == ' ' || text[p] == '\t' || text[p] == '\n' || text[p] == '\r')) ++p;
  return p < text.size() && text[p] == '{';
}

Status read(std::string_view text, const std::string& source, Area& out) {
  Value root;
  RELIEF_RETURN_IF_ERROR(Parser(text, source).parse(root));
  out = Area{};
  if (root.kind != Value::Kind::kObject) {
    return invalid_argument(source + ": the GeoJSON is " + kind_name(root.kind) + ", not an object");
  }
  RELIEF_RETURN_IF_ERROR(read_crs(root, source, out.crs));
  RELIEF_RETURN_IF_ERROR(Walker(source, out).object(root, "", 0));
  if (out.rings.empty()) return invalid_argument(source + ": the GeoJSON holds no polygon");
  return Status::ok();
}

}  // namespace relief::geojson
