// JSON text pieces shared by the query module's JSON writers (info, stats).
// Internal to lib/query.
#pragma once

#include <string>

namespace relief::json {

// A JSON string: quotes, backslashes and control characters escaped, and
// anything that is not valid UTF-8 replaced by U+FFFD.
std::string json_string(const std::string& s);
// A number with every digit a double holds; null for NaN and infinities.
std::string json_number(double v);

}  // namespace relief::json
