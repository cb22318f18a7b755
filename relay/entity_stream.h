// Entity streams: one receiver's rigid-body state format, behind one interface.
//
// The ClientReplicator (relay/replication.h) is the scheduler: priority classes and send
// intervals, the bandwidth budget, datagram assembly, acknowledgement routing. An EntityStream
// is the format: per receiver it decides whether an entity is worth sending (selective
// synchronisation against what the receiver holds), writes it, and keeps the acknowledgement
// state that decision needs. The relay's formats are rows of relay/entity_streams.cc: 9 (shared
// delta, the default) and 2 (the previous default, kept for one release). A ReplicationPlugin
// (ReplicationConfig::plugin) supplies streams of a format the relay does not carry: the
// benchmark emulations of loadgen/emulation/, which only the load generator, bench/ and tests
// link. Soft bodies always go as format 11, beside the stream.
//
// Thread-safety: a ReplicationPlugin is immutable and shared by every room of a relay (any
// thread); an EntityStream belongs to one receiver and is used on its room's thread only.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string_view>

#include "relay/relay_counters.h"

namespace edgephys {

struct Entity;
struct ReplicationConfig;

// Field bits a stream may be asked to write (Want decides which; the paper's format writes
// only the significant ones).
inline constexpr uint8_t kFieldPosition = 1u << 0;
inline constexpr uint8_t kFieldRotation = 1u << 1;

// Want's answer. kSettled: the receiver acknowledged a state of this entity version within the
// thresholds; nothing to send until the version changes (the scheduler stops asking).
enum class StreamNeed : uint8_t { kSkip, kSend, kSettled };

// One receiver's encoder and acknowledgement state for a format. Per tick the replicator calls
// Want for every entity due by its class's interval, then Begin, Add for the chosen ones (in
// id order), Finish; OnSent when the payload went out, Count once per finished payload;
// OnAcked for every acknowledged packet the soft-body sender does not claim.
class EntityStream {
 public:
  virtual ~EntityStream() = default;
  // Whether `e` should be sent now (`resend_after_s`: when an unacknowledged copy counts as
  // lost). `fields` comes in with both bits set; a stream may clear some. O(1).
  virtual StreamNeed Want(const Entity& e, double now, double resend_after_s,
                          uint8_t* fields) = 0;
  // Hint: the entity in room slot `slot` is asked about soon (start loading its record).
  virtual void Prefetch(uint32_t /*slot*/) const {}
  // Starts a payload in `out` (not owned; valid until Finish).
  virtual void Begin(std::span<uint8_t> out, uint32_t time_ms) = 0;
  // Appends `fields` of `e`; false (nothing written) when it does not fit.
  virtual bool Add(const Entity& e, uint8_t fields) = 0;
  // Entities in the open payload.
  virtual size_t count() const = 0;
  // Completes the payload: its size in bytes (0 if nothing was added).
  virtual size_t Finish() = 0;
  // The payload just finished went out as packet `sequence` at `now`.
  virtual void OnSent(uint16_t sequence, double now) = 0;
  // Once per finished payload (`sent`: whether it went out): adds the stream's own figures to
  // the relay's counters.
  virtual void Count(bool /*sent*/, RelayCounters& /*counters*/) {}
  // The receiver acknowledged packet `sequence` (unknown sequences are ignored).
  virtual void OnAcked(uint16_t sequence) = 0;
  // The entity is gone: drop what is held for it.
  virtual void Forget(uint32_t entity_id) = 0;
};

class ReplicationPlugin {
 public:
  virtual ~ReplicationPlugin() = default;
  virtual std::string_view name() const = 0;
  // The first byte of its payloads, announced to clients in Joined (the SDK refuses and counts
  // a format it does not decode unless the client was given a matching decoder,
  // client/state_decoder_plugin.h).
  virtual uint8_t state_format() const = 0;
  virtual std::unique_ptr<EntityStream> NewStream(const ReplicationConfig& config) const = 0;
};

}  // namespace edgephys
