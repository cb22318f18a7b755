// MemberLink: the only way a RoomHost reaches one of its members. The relay's Session
// implements it; room rule tests implement it with a recorder (relay/room_host_test.cc).
//
// Thread-safety: the room's thread, except Replicate(), which the relay may run for several
// members of several rooms in parallel (each call touches only its own member).
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

#include "edgephys/schema/control_generated.h"
#include "relay/entity.h"
#include "relay/relay_counters.h"
#include "relay/replication.h"

namespace edgephys {

class MemberLink {
 public:
  virtual ~MemberLink() = default;

  virtual uint32_t player_id() const = 0;
  // Join token permissions (kPermissionSpawn, ...).
  virtual uint32_t permissions() const = 0;
  // Spawn rate limit: false when the member must slow down. Takes a token when true.
  virtual bool AllowSpawn(double now) = 0;

  // Queues a reliable-ordered message. False when the member's reliable queue overflowed: the
  // link has then disconnected the member (kReliableOverflow) and will be removed by its owner.
  virtual bool SendReliable(std::span<const uint8_t> message) = 0;
  // Sends `payload` (1 .. kMaxUnreliablePayload bytes) to the member as one unreliable
  // datagram now (an unreliable application message; it may be lost, and a receiver drops it
  // if a later unreliable datagram arrived first). False, nothing sent, when the member is not
  // ready for states (ReadyForStates) or the connection refused it. `now`: the relay's clock.
  virtual bool SendUnreliable(std::span<const uint8_t> payload, double now) {
    (void)payload, (void)now;
    return false;
  }
  // The member's reliable queue: bytes queued or unacknowledged, and the most it may hold
  // (SendReliable beyond it overflows). Used to pace a late join (relay/join_stream.h).
  virtual size_t ReliablePending() const = 0;
  virtual size_t ReliableCapacity() const = 0;
  // The member fell a whole reliable queue behind: disconnect it (kReliableOverflow), as an
  // overflowing SendReliable would; its owner removes it later.
  virtual void Overflow() = 0;
  // Refuses one of the member's requests: counts `reason` (requests_rejected), logs at a
  // bounded rate and sends Error{reason, entity_id, detail}.
  virtual void SendError(schema::RejectReason reason, uint32_t entity_id,
                         std::string_view detail) = 0;

  // Untrusted input from the member that failed a check: counted by reason (a whole state
  // payload as a rejected packet, one state as a rejected update) and logged at a bounded rate.
  virtual void DropPayload(DropReason reason) = 0;
  virtual void DropUpdate(DropReason reason) = 0;

  // Replication. StartReplication: a fresh view of the room (called on every join, after
  // Joined is queued); states wait until everything queued so far is acknowledged.
  virtual void StartReplication(const ReplicationConfig& config) = 0;
  // Whether the member may be sent states now (connected, and Joined acknowledged).
  virtual bool ReadyForStates() const = 0;
  // One replication tick for this member over the room's `frame` (Room::BuildFrame). With
  // `buffered`, the datagrams are held until FlushReplication() (parallel ticks), else sent
  // at once.
  virtual void Replicate(const ReplicationFrame& frame, double now, RelayCounters& counters,
                         bool buffered) = 0;
  virtual void FlushReplication() = 0;
  // The entity is gone: drop what replication holds for it.
  virtual void Forget(uint32_t entity_id) = 0;
};

}  // namespace edgephys
