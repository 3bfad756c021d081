// Relief error model: every fallible operation returns a Status or a Result<T>.
// Codes are stable: they are part of the public API and mapped to CLI exit codes
// (see README "Exit codes"). Never renumber; only append.
#pragma once

#include <cassert>
#include <optional>
#include <string>
#include <utility>

namespace relief {

enum class StatusCode : int {
  kOk = 0,
  kInvalidArgument = 1,  // the caller passed parameters that cannot work
  kIoError = 2,          // a file could not be opened, read or written
  kFormatError = 3,      // an input file is malformed (truncated, lying header, bad value)
  kCorruptData = 4,      // a compressed blob failed validation or its checksum
  kUnsupported = 5,      // well-formed but uses a feature or version this build lacks
  kLimitExceeded = 6,    // a safety limit on sizes was hit
  kInternal = 7,         // a dependency failed in a way the inputs do not explain
};

// Short stable name of a code, e.g. "corrupt-data".
const char* status_code_name(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status ok() { return Status(); }

  bool is_ok() const { return code_ == StatusCode::kOk; }
  explicit operator bool() const { return is_ok(); }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "corrupt-data: height section: ..." for logs and CLI output.
  std::string to_string() const;
  // Returns a copy whose message is prefixed with `context: `.
  Status with_context(const std::string& context) const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

inline Status invalid_argument(std::string m) { return {StatusCode::kInvalidArgument, std::move(m)}; }
inline Status io_error(std::string m) { return {StatusCode::kIoError, std::move(m)}; }
inline Status format_error(std::string m) { return {StatusCode::kFormatError, std::move(m)}; }
inline Status corrupt_data(std::string m) { return {StatusCode::kCorruptData, std::move(m)}; }
inline Status unsupported(std::string m) { return {StatusCode::kUnsupported, std::move(m)}; }
inline Status limit_exceeded(std::string m) { return {StatusCode::kLimitExceeded, std::move(m)}; }
inline Status internal_error(std::string m) { return {StatusCode::kInternal, std::move(m)}; }

// Either a value or a non-ok Status.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}  // NOLINT: implicit by design
  Result(Status status) : status_(std::move(status)) {  // NOLINT: implicit by design
    assert(!status_.is_ok() && "a Result built from a Status must carry an error");
  }

  bool is_ok() const { return value_.has_value(); }
  explicit operator bool() const { return is_ok(); }
  const Status& status() const { return status_; }

  T& value() & {
    assert(is_ok());
    return *value_;
  }
  const T& value() const& {
    assert(is_ok());
    return *value_;
  }
  T&& value() && {
    assert(is_ok());
    return std::move(*value_);
  }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() & { return value(); }
  const T& operator*() const& { return value(); }

 private:
  std::optional<T> value_;
  Status status_;
};

}  // namespace relief

#define RELIEF_CONCAT_INNER_(a, b) a##b
#define RELIEF_CONCAT_(a, b) RELIEF_CONCAT_INNER_(a, b)

// Returns the Status from the enclosing function when `expr` is not ok.
#define RELIEF_RETURN_IF_ERROR(expr)                 \
  do {                                               \
    ::relief::Status relief_status_ = (expr);        \
    if (!relief_status_.is_ok()) return relief_status_; \
  } while (0)

// `RELIEF_ASSIGN_OR_RETURN(auto x, f());` declares x from a Result or returns its Status.
#define RELIEF_ASSIGN_OR_RETURN(lhs, expr) \
  RELIEF_ASSIGN_OR_RETURN_IMPL_(RELIEF_CONCAT_(relief_result_, __LINE__), lhs, expr)
#define RELIEF_ASSIGN_OR_RETURN_IMPL_(tmp, lhs, expr) \
  auto tmp = (expr);                                  \
  if (!tmp.is_ok()) return tmp.status();              \
  lhs = std::move(tmp).value()
