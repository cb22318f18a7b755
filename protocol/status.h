// Status and Result: error values for the hot path instead of exceptions (LevelDB style).
// A Status is cheap to copy when OK (no allocation); an error carries a code and a short
// static message. Thread-safety: values, no shared state.
#pragma once

#include <cassert>
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

class Status {
 public:
  constexpr Status() = default;
  // `message` must outlive the Status (use string literals).
  constexpr Status(StatusCode code, std::string_view message) : code_(code), message_(message) {}

  static constexpr Status Ok() { return Status(); }

  constexpr bool ok() const { return code_ == StatusCode::kOk; }
  constexpr StatusCode code() const { return code_; }
  constexpr std::string_view message() const { return message_; }

 private:
  StatusCode code_ = StatusCode::kOk;
  std::string_view message_;
};

// Either a value or an error Status. Accessing value() of an error is a programming error.
template <typename T>
class Result {
 public:
  Result(T value) : data_(std::move(value)) {}  // NOLINT(google-explicit-constructor)
  Result(Status status) : data_(status) {       // NOLINT(google-explicit-constructor)
    assert(!status.ok());
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
