// JoinStream: the room's state on its way to one late joiner, paced by the joiner's reliable
// budget instead of queued at once. A room's stored spawns can add up to far more than one
// connection's reliable queue (ConnectionConfig::max_pending_reliable_bytes); queuing them all
// at join overflowed it and disconnected every joiner. The stream sends the Spawn of each
// entity that existed at join time, parents before children (spawn order), a few at a time
// while the joiner's queue has room, resuming on later calls; reliable broadcasts to the joiner
// during the stream are held and sent after it, so the joiner sees one ordered history.
//
// An entity removed before its turn is skipped (its Despawn, held, still follows; clients
// ignore a Despawn of an unknown id). Spawns are read from the room at send time, so an owner
// change (a leaver's Persistent entity passing to the room) is current.
//
// Thread-safety: none (the room's thread). Memory: the ids at join plus the held broadcasts.
#pragma once

#include <cstdint>
#include <deque>
#include <span>
#include <vector>

#include "relay/entity.h"
#include "relay/member_link.h"

namespace edgephys {

class JoinStream {
 public:
  // The entities of `entities` to send, in spawn order.
  explicit JoinStream(const EntityTable& entities);
  bool done() const { return next_ == ids_.size() && held_.empty(); }
  // A reliable message for the joiner while the stream runs: sent after it. False (nothing
  // held) when the held messages would exceed `capacity` bytes (the joiner's reliable queue
  // capacity): the joiner is that far behind and must be dropped.
  bool Hold(std::span<const uint8_t> message, size_t capacity) {
    if (held_bytes_ + message.size() > capacity) return false;
    held_bytes_ += message.size();
    held_.emplace_back(message.begin(), message.end());
    return true;
  }
  // Sends what fits in the joiner's reliable queue now, keeping half of its capacity free for
  // the room's live traffic (at least one message per call when the queue is empty). False
  // when the link overflowed (it has disconnected the member).
  bool Pump(MemberLink& link, const EntityTable& entities);
  size_t sent() const { return sent_; }

 private:
  bool Fits(const MemberLink& link, size_t bytes) const;
  std::vector<uint32_t> ids_;
  size_t next_ = 0;
  size_t sent_ = 0;
  std::deque<std::vector<uint8_t>> held_;
  size_t held_bytes_ = 0;
};

}  // namespace edgephys
