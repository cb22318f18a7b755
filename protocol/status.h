// Status and Result: error values for the hot path instead of exceptions (LevelDB style).
//
// A Status is a code, a short static message (a string literal: what failed) and, for errors
// that need it, a detail string built at run time (which entity, which limit, which value).
// An OK Status, and an error without detail, allocate nothing and are cheap to copy; an error
// with detail allocates its string once and shares it between copies.
//
// Make one with a named factory (Status::InvalidArgument("room name must be 1..64 bytes")),
// test it with ok() or a predicate (IsNotFound()), and show it with ToString(). Both Status and
// Result are [[nodiscard]]: a call that can fail must be checked or explicitly dropped with
// `(void)`.
//
// Thread-safety: values; copies may be used on different threads.
#pragma once

#include <cassert>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <variant>

namespace edgephys {

enum class StatusCode : int {
  kOk = 0,
  kInvalidArgument,    // caller passed something out of contract
  kMalformed,          // untrusted input failed to parse or verify
  kTooLarge,           // exceeds a configured size limit
  kQueueFull,          // a bounded queue or window has no room; try again later
  kNotConnected,       // the connection is not (or no longer) established
  kIoError,            // the operating system refused a socket operation
  kUnauthenticated,    // bad MAC, cookie or token
  kPermissionDenied,   // authenticated, but not allowed (ownership, room)
  kNotFound,
  kAlreadyExists,
  kResourceExhausted,  // capacity or rate limit reached
};

// "ok", "invalid argument", ... (static strings).
std::string_view StatusCodeName(StatusCode code);

class [[nodiscard]] Status {
 public:
  Status() = default;
  // `message` must outlive the Status (use string literals); `detail` is copied.
  Status(StatusCode code, std::string_view message) : code_(code), message_(message) {}
  Status(StatusCode code, std::string_view message, std::string detail)
      : code_(code),
        message_(message),
        detail_(detail.empty() ? nullptr : std::make_shared<const std::string>(std::move(detail))) {}

  static Status Ok() { return Status(); }
  static Status InvalidArgument(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kInvalidArgument, msg, std::move(detail));
  }
  static Status Malformed(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kMalformed, msg, std::move(detail));
  }
  static Status TooLarge(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kTooLarge, msg, std::move(detail));
  }
  static Status QueueFull(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kQueueFull, msg, std::move(detail));
  }
  static Status NotConnected(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kNotConnected, msg, std::move(detail));
  }
  static Status IoError(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kIoError, msg, std::move(detail));
  }
  static Status Unauthenticated(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kUnauthenticated, msg, std::move(detail));
  }
  static Status PermissionDenied(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kPermissionDenied, msg, std::move(detail));
  }
  static Status NotFound(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kNotFound, msg, std::move(detail));
  }
  static Status AlreadyExists(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kAlreadyExists, msg, std::move(detail));
  }
  static Status ResourceExhausted(std::string_view msg, std::string detail = {}) {
    return Status(StatusCode::kResourceExhausted, msg, std::move(detail));
  }

  bool ok() const { return code_ == StatusCode::kOk; }
  bool IsInvalidArgument() const { return code_ == StatusCode::kInvalidArgument; }
  bool IsMalformed() const { return code_ == StatusCode::kMalformed; }
  bool IsTooLarge() const { return code_ == StatusCode::kTooLarge; }
  bool IsQueueFull() const { return code_ == StatusCode::kQueueFull; }
  bool IsNotConnected() const { return code_ == StatusCode::kNotConnected; }
  bool IsUnauthenticated() const { return code_ == StatusCode::kUnauthenticated; }
  bool IsPermissionDenied() const { return code_ == StatusCode::kPermissionDenied; }
  bool IsNotFound() const { return code_ == StatusCode::kNotFound; }
  bool IsAlreadyExists() const { return code_ == StatusCode::kAlreadyExists; }
  bool IsResourceExhausted() const { return code_ == StatusCode::kResourceExhausted; }

  StatusCode code() const { return code_; }
  // The static message: what failed.
  std::string_view message() const { return message_; }
  // The run-time detail, empty if none.
  std::string_view detail() const { return detail_ ? std::string_view(*detail_) : std::string_view(); }
  // The detail if any, else the message: what to tell a client in one line.
  std::string_view reason() const { return detail_ ? detail() : message_; }
  // "ok", or "<code name>: <message>[: <detail>]".
  std::string ToString() const;

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string_view message_;
  std::shared_ptr<const std::string> detail_;
};

inline std::string_view StatusCodeName(StatusCode code) {
  switch (code) {
    case StatusCode::kOk: return "ok";
    case StatusCode::kInvalidArgument: return "invalid argument";
    case StatusCode::kMalformed: return "malformed";
    case StatusCode::kTooLarge: return "too large";
    case StatusCode::kQueueFull: return "queue full";
    case StatusCode::kNotConnected: return "not connected";
    case StatusCode::kIoError: return "I/O error";
    case StatusCode::kUnauthenticated: return "unauthenticated";
    case StatusCode::kPermissionDenied: return "permission denied";
    case StatusCode::kNotFound: return "not found";
    case StatusCode::kAlreadyExists: return "already exists";
    case StatusCode::kResourceExhausted: return "resource exhausted";
  }
  return "unknown";
}

inline std::string Status::ToString() const {
  if (ok()) return "ok";
  std::string s(StatusCodeName(code_));
  s += ": ";
  s += message_;
  if (detail_) {
    s += ": ";
    s += *detail_;
  }
  return s;
}

// Either a value or an error Status. Accessing value() of an error is a programming error.
template <typename T>
class [[nodiscard]] Result {
 public:
  Result(T value) : data_(std::move(value)) {}  // NOLINT(google-explicit-constructor)
  Result(Status status) : data_(std::move(status)) {  // NOLINT(google-explicit-constructor)
    assert(!std::get<Status>(data_).ok());
  }

  bool ok() const { return std::holds_alternative<T>(data_); }
  Status status() const { return ok() ? Status::Ok() : std::get<Status>(data_); }
  T& value() { return std::get<T>(data_); }
  const T& value() const { return std::get<T>(data_); }
  T* operator->() { return &value(); }
  const T* operator->() const { return &value(); }
  T& operator*() { return value(); }
  const T& operator*() const { return value(); }

 private:
  std::variant<T, Status> data_;
};

}  // namespace edgephys
