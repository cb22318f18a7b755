// Rate limits for untrusted peers: a token bucket per session, and a bounded table of buckets
// keyed by source address for handshake packets (AddressRateLimiter).
//
// Thread-safety: none (the relay's thread). Cost: O(1), no allocation after construction.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>

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

// Takes one token at `now` from `key`'s bucket in `buckets`, made on the key's first request
// with `rate_per_s` and a burst of two seconds' worth (e.g. a room's per-player request rates).
// False (nothing taken) when the bucket is empty. Allocates once per new key.
template <typename Map>
bool TakeKeyedToken(Map& buckets, const typename Map::key_type& key, double rate_per_s,
                    double now) {
  auto [it, fresh] = buckets.try_emplace(key);
  if (fresh) it->second = TokenBucket(rate_per_s, 2 * rate_per_s);
  return it->second.Take(now);
}

// Token buckets keyed by source address, for handshake packets: IPv4 by the whole address
// (/32), IPv6 by its /64 (one host's addresses), IPv4-mapped IPv6 as IPv4. Every address has a
// bucket of its own: one address draining its bucket never limits another.
//
// Bounded: a fixed open-addressed table of kSlots entries (~0.75 MB), probed over kProbe slots
// from a keyed hash (per-process random key, so a sender cannot aim at a victim's slots). An
// address not in the table takes a free slot, else the least recently seen entry of its probe
// window. Under a flood from more than kSlots spoofed sources the evicted entries are the
// flood's own, or an honest address that then starts again with a full bucket: eviction makes
// the limit more lenient, never stricter, so no source can make another's handshakes fail.
// The cost of such a flood is bounded by the relay's other limits (cookies are stateless, a
// Connect needs a valid token), not by this table (docs/operations.md, "Handshake limits").
class AddressRateLimiter {
 public:
  static constexpr size_t kSlots = 16384;
  static constexpr size_t kProbe = 16;
  AddressRateLimiter(double rate_per_s, double burst)
      : rate_(rate_per_s), burst_(burst), seed_(RandomSeed()),
        slots_(std::make_unique<Slot[]>(kSlots)) {}

  bool Allow(const Endpoint& from, double now) {
    if (rate_ <= 0) return true;
    const Key key = KeyOf(from);
    const size_t start = Hash(key) % kSlots;
    Slot* victim = nullptr;
    for (size_t i = 0; i < kProbe; ++i) {
      Slot& s = slots_[(start + i) % kSlots];
      if (s.used && s.key == key) {
        s.last = now;
        return s.bucket.Take(now);
      }
      if (!s.used) {
        if (victim == nullptr || victim->used) victim = &s;
      } else if (victim == nullptr || (victim->used && s.last < victim->last)) {
        victim = &s;
      }
    }
    if (victim->used) ++evictions_;
    *victim = Slot{key, TokenBucket(rate_, burst_), now, true};
    return victim->bucket.Take(now);
  }
  // Entries replaced to make room for another address (a flood of distinct sources).
  uint64_t evictions() const { return evictions_; }

 private:
  struct Key {
    uint64_t hi = 0, lo = 0;
    bool operator==(const Key&) const = default;
  };
  struct Slot {
    Key key;
    TokenBucket bucket;
    double last = 0;
    bool used = false;
  };
  static Key KeyOf(const Endpoint& e) {
    const auto& a = e.address();
    if (a.is_v4()) return Key{0, a.to_v4().to_uint()};
    const auto v6 = a.to_v6();
    if (v6.is_v4_mapped()) {
      return Key{0, asio::ip::make_address_v4(asio::ip::v4_mapped, v6).to_uint()};
    }
    const auto bytes = v6.to_bytes();
    uint64_t prefix = 0;
    for (int i = 0; i < 8; ++i) prefix = prefix << 8 | bytes[i];
    return Key{1, prefix};  // the /64
  }
  size_t Hash(const Key& k) const {
    uint64_t h = seed_ ^ (k.hi * 0x9e3779b97f4a7c15ULL);
    h ^= k.lo + 0x9e3779b97f4a7c15ULL + (h << 6) + (h >> 2);
    h ^= h >> 33;
    h *= 0xff51afd7ed558ccdULL;
    h ^= h >> 33;
    return static_cast<size_t>(h);
  }
  static uint64_t RandomSeed() {
    std::random_device rd;
    return (uint64_t{rd()} << 32) ^ rd();
  }
  double rate_, burst_;
  uint64_t seed_;
  std::unique_ptr<Slot[]> slots_;
  uint64_t evictions_ = 0;
};

}  // namespace edgephys
