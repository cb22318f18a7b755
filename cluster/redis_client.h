// RedisClient: one blocking connection to a Redis server over hiredis (Debian libhiredis-dev),
// for the cluster thread only (cluster/directory.h); the relay's I/O thread never calls it.
//
// Every call is bounded by the timeout given to Connect (connect, send and receive). A failed
// call (I/O error, timeout, protocol error) closes the connection and returns kIoError; the
// next call reconnects first. A Redis error reply ("-WRONGTYPE ...") is not an I/O failure: it
// is returned as a Reply of kind kError and the connection stays open.
//
// Thread-safety: none; one owner thread. Cost: one round trip per Command, one per Pipeline.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "protocol/status.h"

struct redisContext;

namespace edgephys::cluster {

// A reply, converted out of hiredis' reply object (so callers never hold hiredis memory).
struct RedisReply {
  enum class Kind { kNil, kString, kInteger, kArray, kStatus, kError };
  Kind kind = Kind::kNil;
  std::string str;                 // kString, kStatus, kError
  int64_t integer = 0;             // kInteger
  std::vector<RedisReply> elements;  // kArray

  bool is_string() const { return kind == Kind::kString; }
  bool is_error() const { return kind == Kind::kError; }
};

class RedisClient {
 public:
  RedisClient(std::string host, uint16_t port, double timeout_s);
  ~RedisClient();
  RedisClient(const RedisClient&) = delete;
  RedisClient& operator=(const RedisClient&) = delete;

  // One command, arguments binary-safe. kIoError on connection or protocol failure.
  Result<RedisReply> Command(const std::vector<std::string>& argv);
  // Several commands in one round trip; one reply each, in order. kIoError as above.
  Result<std::vector<RedisReply>> Pipeline(const std::vector<std::vector<std::string>>& commands);
  bool connected() const { return ctx_ != nullptr; }

 private:
  Status EnsureConnected();
  void Close();

  std::string host_;
  uint16_t port_;
  double timeout_s_;
  redisContext* ctx_ = nullptr;
};

}  // namespace edgephys::cluster
