#include "io/extra_fields.h"

#include "io/text_scan.h"
#include "relief/io.h"

namespace relief {

Result<std::string> kept_fields_vlr(const std::vector<KeptField>& fields, const std::string& file,
                                    const std::string& kind, const std::string& description,
                                    std::vector<std::string>& warnings) {
  constexpr std::size_t kMaxName = 32;
  constexpr std::size_t kMaxFields = 65535 / 192;
  if (fields.size() > kMaxFields) {
    return unsupported(file + ": " + std::to_string(fields.size()) + " " + kind +
                       " values besides x, y, z, colour and intensity; LAS extra bytes hold at most " +
                       std::to_string(kMaxFields) + " (--no-extra-bytes drops them)");
  }
  std::vector<ExtraBytesField> described;
  described.reserve(fields.size());
  for (const KeptField& k : fields) {
    ExtraBytesField f;
    f.name = k.name.substr(0, kMaxName);
    f.description = description.substr(0, kMaxName);
    f.data_type = k.data_type;
    for (const ExtraBytesField& other : described) {
      if (other.name == f.name) {
        return format_error(file + ": " + kind + " " + quoted(k.name) + " and an earlier one share the name " +
                            quoted(f.name) + " as LAS extra bytes, whose names hold 32 characters (rename one, "
                            "or --no-extra-bytes drops them)");
      }
    }
    if (k.name.size() > kMaxName) {
      warnings.push_back(file + ": " + kind + " " + quoted(k.name) + " is kept as extra bytes named " +
                         quoted(f.name) + " (LAS field names hold 32 characters)");
    }
    described.push_back(std::move(f));
  }
  return make_extra_bytes_vlr(described);
}

}  // namespace relief
