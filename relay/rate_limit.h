// Rate limits for untrusted peers: a token bucket per session, and a fixed table of buckets
// keyed by source address for handshake packets (bounded memory whatever the number of
// addresses: addresses that hash together share a bucket, which can only make the limit
// stricter for them).
//
// Thread-safety: none (the relay's thread). Cost: O(1), no allocation.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>

#include "protocol/datagram_socket.h"

namespace edgephys {

class TokenBucket {
 public:
  TokenBucket() = default;
  TokenBucket(double rate_per_s, double burst) : rate_(rate_per_s), burst_(burst), tokens_(burst) {}
  // Takes `cost` tokens if available at `now` (seconds); false (nothing taken) otherwise.
  bool Take(double now, double cost = 1.0) {
    if (rate_ <= 0) return true;  // unlimited
    if (last_ >= 0) tokens_ = std::min(burst_, tokens_ + (now - last_) * rate_);
    last_ = now;
    if (tokens_ < cost) return false;
    tokens_ -= cost;
    return true;
  }

 private:
  double rate_ = 0;
  double burst_ = 0;
  double tokens_ = 0;
  double last_ = -1;
};

class AddressRateLimiter {
 public:
  static constexpr size_t kSlots = 4096;
  AddressRateLimiter(double rate_per_s, double burst) {
    slots_.fill(TokenBucket(rate_per_s, burst));
  }
  bool Allow(const Endpoint& from, double now) {
    return slots_[Slot(from)].Take(now);
  }

 private:
  static size_t Slot(const Endpoint& e) {
    // The address only (a spoofer can vary ports freely).
    size_t h = e.address().is_v4() ? std::hash<uint32_t>()(e.address().to_v4().to_uint())
                                    : std::hash<std::string>()(e.address().to_string());
    return h % kSlots;
  }
  std::array<TokenBucket, kSlots> slots_;
};

}  // namespace edgephys
