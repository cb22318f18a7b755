// Lockstep receivers (issue 11, docs/protocol.md §5e "Lockstep"): in a format-9 room, receivers
// on the room's common baseline are not walked entity by entity. The room runs ONE canonical
// replicator per tick, a virtual receiver that owns nothing and acknowledges every payload it
// sends; a receiver "in lockstep" is sent copies of the canonical payloads (its own entities'
// records included: clients ignore states of entities they own), so its tick costs O(payloads):
// a copy, a seal and a send, and no walk of its views or stream records.
//
// Why a copy is decodable: every stream of a lockstep room (the canonical's and each
// receiver's own) takes in an acknowledgement of a payload sent in tick T only from tick
// T + L on (SharedDeltaStreamOptions::ack_delay_ticks, L = ReplicationConfig::
// lockstep_ack_ticks). The canonical stream references only versions of payloads sent L or more
// ticks ago; at the start of every tick, before anything is sent, a lockstep receiver that has
// not acknowledged every canonical payload of tick (now - L) leaves lockstep: its replicator
// becomes a copy of the canonical one as it stood before the tick (whose references so far
// were all to payloads this receiver acknowledged), with the canonical payloads of the last L
// ticks marked as this receiver's acknowledgements have them, and it continues on the normal
// per-receiver path. So a lockstep receiver is never sent a reference it does not hold.
// An out-of-lockstep receiver rejoins when, entity by entity, its stream makes the same
// references as the canonical one (SharedDeltaStream::SameBaselines), or differs on at most a
// budget of entities, which the canonical stream then forgets (its next send of each is a
// keyframe, to every lockstep receiver: entities at rest, acknowledged by each stream in a tick
// of its own, never match otherwise); its own packets still in flight then stand for the
// canonical payloads of their ticks and are checked the same way.
// New receivers start out of lockstep.
//
// Applies to rooms where UsesLockstep(config): format 9 without a bandwidth budget. Soft
// bodies are replicated per receiver as before.
// Thread-safety: BeginTick (and in it the members' leaves and rejoins) on the room's thread
// (the relay's) before the receivers' ticks; during the receivers' ticks (which may run in
// parallel) payloads() and tick() are read-only and each receiver touches only its own
// LockstepMember. Register (a receiver's first tick) and Unregister (its destruction) take a
// mutex; neither runs during BeginTick.
// Cost per tick: the canonical replicator's walk (one receiver's worth), O(lockstep members)
// for the leave checks, and one rejoin check of O(entities) for a bounded number of
// out-of-lockstep members (kRejoinChecksPerTick, each at most every kRejoinEvery ticks); a
// leave copies the canonical replicator's per-entity state (~100 bytes per entity).
// Memory: the canonical replicator (one receiver's) + this tick's payloads (<= MTU each).
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <utility>
#include <vector>

#include "protocol/shared_delta_codec.h"
#include "relay/relay_counters.h"
#include "relay/replication.h"

namespace edgephys {

struct Entity;
struct ReplicationFrame;

// One receiver's lockstep state (held by its ClientReplicator): whether it is in lockstep, and
// which of its packets stand for which canonical payloads, by room tick.
struct LockstepMember {
  bool in = false;
  uint32_t since = 0;      // room tick it (re)joined lockstep
  bool ticked = false;     // its replicator ticked at least once
  uint32_t last_tick = 0;  // the room tick of its last replication tick
  uint32_t next_check = 0; // earliest room tick of its next rejoin check
  struct Sent {
    bool valid = false;
    bool acked = false;
    uint16_t sequence = 0;
    uint32_t tick = 0;
    uint32_t payload = 0;  // the canonical payload it copies; 0: its own packet (before a rejoin)
  };
  struct TickAcks {
    uint32_t tick = 0;
    uint16_t need = 0;  // packets sent in `tick` that stand for canonical payloads
    uint16_t got = 0;   // of which acknowledged
  };
  std::array<Sent, 256> sent{};        // by packet sequence % 256
  std::array<TickAcks, 64> ticks{};    // by room tick % 64 (> any lockstep_ack_ticks)
  // Records `sequence`, sent in room tick `tick` for canonical payload `payload` (0: own), as
  // one packet the tick needs acknowledged (`acked`: already). Without `has_sequence` its
  // acknowledgement cannot be learnt (the tick stays incomplete).
  void Expect(uint32_t tick, uint16_t sequence, uint32_t payload, bool acked,
              bool has_sequence = true);
  // An acknowledgement of one of its packets: true if it was one recorded by Expect (then
  // counted), false otherwise (unknown or stale sequences: ignored). O(1).
  bool OnAcked(uint16_t sequence);
  TickAcks* At(uint32_t tick) {
    TickAcks& t = ticks[tick % ticks.size()];
    return t.tick == tick ? &t : nullptr;
  }
};

class LockstepGroup {
 public:
  // At most this many rejoin checks per tick, each member at most every kRejoinEvery ticks.
  static constexpr size_t kRejoinChecksPerTick = 4;
  static constexpr uint32_t kRejoinEvery = 8;
  // A rejoin may make the canonical stream forget (and so keyframe) up to this many entities,
  // or an eighth of the room's if more, whose records differ from the joiner's.
  static constexpr size_t kMinForcedKeyframes = 16;

  // `config` must satisfy UsesLockstep. `tick_rate_hz`: the room's.
  LockstepGroup(const ReplicationConfig& config, double tick_rate_hz);
  ~LockstepGroup();
  LockstepGroup(const LockstepGroup&) = delete;
  LockstepGroup& operator=(const LockstepGroup&) = delete;

  // Once per room tick, after Room::PrepareStates (which started `room`'s tick) and
  // BuildFrame, before the receivers' ticks: the leave checks, a few rejoin checks, then the
  // canonical replicator's tick (this tick's payloads). Room thread.
  void BeginTick(const ReplicationFrame& frame, const SharedDeltaRoom& room, double now,
                 RelayCounters& counters);

  // This tick's canonical payloads (valid until the next BeginTick) and their room tick.
  struct Payload {
    uint32_t number = 0;  // the canonical stream's payload number
    size_t entities = 0;
    std::vector<uint8_t> bytes;
    std::vector<std::pair<uint32_t, uint32_t>> owners;  // (owner, records), by owner
    // Records of entities `player` owns (sent but ignored by that client).
    uint32_t OwnedBy(uint32_t player) const;
  };
  std::span<const Payload> payloads() const { return {payloads_.data(), payload_count_}; }
  uint32_t tick() const { return tick_; }
  uint32_t ack_ticks() const { return ack_ticks_; }

  // Receivers of the room (their ClientReplicator registers on its first tick and unregisters
  // when destroyed). Thread-safe against each other (a mutex), not against BeginTick.
  void Register(ClientReplicator* r);
  void Unregister(ClientReplicator* r);
  size_t members() const { return members_.size(); }
  size_t in_lockstep() const;

  // The canonical replicator's sink (ClientReplicator::Flush): keeps a copy of the payload and
  // returns the sequence the canonical stream records it under.
  uint16_t Capture(std::span<const uint8_t> payload, size_t entities, uint32_t number,
                   std::span<const uint32_t> owners);

 private:
  void Leave(ClientReplicator& r, uint32_t due_tick, RelayCounters& counters);
  bool TryRejoin(ClientReplicator& r, const ReplicationFrame& frame, RelayCounters& counters);
  bool DueAcked(ClientReplicator& r, uint32_t due_tick);

  struct TickPayloads {
    uint32_t tick = 0;
    std::vector<uint32_t> numbers;  // the canonical payload numbers sent in `tick`
  };
  const TickPayloads* PayloadsOf(uint32_t tick) const {
    const TickPayloads& t = tick_payloads_[tick % tick_payloads_.size()];
    return t.tick == tick && !t.numbers.empty() ? &t : nullptr;
  }

  uint32_t ack_ticks_;
  double resend_after_s_;
  std::unique_ptr<ClientReplicator> canonical_;
  std::vector<ClientReplicator*> members_;
  size_t rejoin_cursor_ = 0;
  uint32_t tick_ = 0;
  bool ticked_ = false;
  std::vector<Payload> payloads_;
  size_t payload_count_ = 0;
  std::array<TickPayloads, 64> tick_payloads_{};
  uint16_t next_sequence_ = 0;
  std::vector<uint32_t> owner_scratch_;
  std::vector<SharedDeltaStream::PayloadFix> fixes_;
  std::vector<SharedDeltaStream::SentPayloadInfo> in_flight_;
  std::vector<const Entity*> forced_;
};

}  // namespace edgephys
