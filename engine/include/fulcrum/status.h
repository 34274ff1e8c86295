// Errors are values. Functions that can fail on user input return a Status (or a Result<T>)
// whose message names the offending field and the reason; nothing throws across the engine's
// boundary and nothing aborts on bad input.
#pragma once

#include <cassert>
#include <optional>
#include <string>
#include <utility>

namespace fulcrum {

enum class StatusCode {
  kOk = 0,
  kInvalidArgument,     // a field has a value outside its documented range
  kNotFound,            // an unknown or stale handle
  kFailedPrecondition,  // the request does not fit the object's current state
  kResourceExhausted,   // a configured limit would be exceeded
  kDataLoss,            // corrupt or truncated input data
  kInternal,
  // Why a long call stopped early (servers): its caller cancelled it, its deadline passed, or
  // the server is shutting down.
  kCancelled,
  kDeadlineExceeded,
  kUnavailable,
  kPermissionDenied,  // the caller may not do this (servers: a player acting for another)
};

const char* status_code_name(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;
  Status(StatusCode code, std::string message) : code_(code), message_(std::move(message)) {}

  static Status ok_status() { return Status(); }
  bool ok() const { return code_ == StatusCode::kOk; }
  StatusCode code() const { return code_; }
  const std::string& message() const { return message_; }
  // "INVALID_ARGUMENT: shape.density: must be > 0 (got -1)".
  std::string to_string() const;
  // Prefixes the message with a location, e.g. "bodies[3].".
  Status with_prefix(const std::string& prefix) const {
    return ok() ? *this : Status(code_, prefix + message_);
  }

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string message_;
};

inline Status invalid_argument(std::string message) {
  return Status(StatusCode::kInvalidArgument, std::move(message));
}
inline Status not_found(std::string message) {
  return Status(StatusCode::kNotFound, std::move(message));
}
inline Status data_loss(std::string message) {
  return Status(StatusCode::kDataLoss, std::move(message));
}
inline Status failed_precondition(std::string message) {
  return Status(StatusCode::kFailedPrecondition, std::move(message));
}
inline Status resource_exhausted(std::string message) {
  return Status(StatusCode::kResourceExhausted, std::move(message));
}

// A value or the Status that explains why there is none.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : value_(std::move(value)) {}  // NOLINT: implicit by design
  Result(Status status) : status_(std::move(status)) { assert(!status_.ok()); }  // NOLINT

  bool ok() const { return value_.has_value(); }
  const Status& status() const { return status_; }
  const T& value() const& { return *value_; }
  T& value() & { return *value_; }
  T&& value() && { return std::move(*value_); }
  const T& operator*() const& { return *value_; }
  T& operator*() & { return *value_; }
  const T* operator->() const { return &*value_; }
  T* operator->() { return &*value_; }

 private:
  Status status_;
  std::optional<T> value_;
};

}  // namespace fulcrum

// Returns the Status of `expr` from the enclosing function when it is an error.
#define FULCRUM_RETURN_IF_ERROR(expr)                  \
  do {                                                 \
    ::fulcrum::Status fulcrum_status_ = (expr);        \
    if (!fulcrum_status_.ok()) return fulcrum_status_; \
  } while (false)
