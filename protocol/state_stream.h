// State streams: one receiver's sending end of a rigid-body state format, behind one interface.
//
// The relay's ClientReplicator (relay/replication.h) is the scheduler: priority classes and send
// intervals, the bandwidth budget, datagram assembly, acknowledgement routing. A StateStream is
// the format: per receiver it decides whether an entity is worth sending (selective
// synchronisation against what the receiver holds), writes it, and keeps the acknowledgement
// state that decision needs. The formats the relay carries are rows of protocol/state_formats.cc
// (9, shared delta, the default; 2, the previous default, for one release), each with its
// StateStream in its codec file; a plug-in (relay/entity_stream.h) supplies others.
//
// Thread-safety: a StateStream belongs to one receiver and is used on its room's thread only.
#pragma once

#include <cstdint>
#include <span>

#include "protocol/quantize.h"
#include "protocol/types.h"

namespace edgephys {

struct PreparedState;  // protocol/delta_codec.h
class SharedEntity;    // protocol/shared_delta_codec.h

// Field bits a stream may be asked to write (Want decides which; the paper's format writes
// only the significant ones).
inline constexpr uint8_t kFieldPosition = 1u << 0;
inline constexpr uint8_t kFieldRotation = 1u << 1;

// Want's answer. kSettled: the receiver acknowledged a state of this entity version within the
// thresholds; nothing to send until the version changes (the scheduler stops asking).
enum class StreamNeed : uint8_t { kSkip, kSend, kSettled };

// What a stream reads of an entity: a view the sender builds per call (nothing owned).
struct StreamEntity {
  uint32_t id = 0;
  uint32_t version = 0;                        // bumped on every accepted state change
  const EntityState* state = nullptr;          // its latest state (never null)
  const PreparedState* prepared = nullptr;     // `state` quantised once for all receivers, or null
  SharedEntity* shared = nullptr;              // format 9: its room-coded versions, or null
};

// What a stream adds to its sender's counters once per finished payload.
struct StreamCounts {
  uint64_t shared_bodies_cached = 0;  // record bodies taken from the room's cache
  uint64_t shared_bodies_coded = 0;   // record bodies this stream coded itself
};

// Selective sync: an entity whose receiver copy is within these of the truth is not resent.
struct StreamThresholds {
  float position_m = 0.001f;
  float rotation_deg = 0.1f;
};

// One receiver's encoder and acknowledgement state for a format. Per tick the sender calls Want
// for every entity due by its class's interval, then Begin, Add for the chosen ones (in id
// order), Finish; OnSent when the payload went out, Count once per finished payload; OnAcked
// for every acknowledged packet the soft-body sender does not claim.
class StateStream {
 public:
  virtual ~StateStream() = default;
  // Whether `e` should be sent now (`resend_after_s`: when an unacknowledged copy counts as
  // lost). `fields` comes in with both bits set; a stream may clear some. O(1).
  virtual StreamNeed Want(const StreamEntity& e, double now, double resend_after_s,
                          uint8_t* fields) = 0;
  // Hint: the entity in room slot `slot` is asked about soon (start loading its record).
  virtual void Prefetch(uint32_t /*slot*/) const {}
  // Starts a payload in `out` (not owned; valid until Finish).
  virtual void Begin(std::span<uint8_t> out, uint32_t time_ms) = 0;
  // Appends `fields` of `e`; false (nothing written) when it does not fit.
  virtual bool Add(const StreamEntity& e, uint8_t fields) = 0;
  // Entities in the open payload.
  virtual size_t count() const = 0;
  // Completes the payload: its size in bytes (0 if nothing was added).
  virtual size_t Finish() = 0;
  // The payload just finished went out as packet `sequence` at `now`.
  virtual void OnSent(uint16_t sequence, double now) = 0;
  // Once per finished payload (`sent`: whether it went out): adds the stream's own figures.
  virtual void Count(bool /*sent*/, StreamCounts& /*counts*/) {}
  // The receiver acknowledged packet `sequence` (unknown sequences are ignored).
  virtual void OnAcked(uint16_t sequence) = 0;
  // The entity is gone: drop what is held for it.
  virtual void Forget(uint32_t entity_id) = 0;
};

// What the codec-backed streams share: the selective-sync thresholds and a codec whose payload
// and acknowledgement calls they forward (DeltaEncoder and SharedDeltaStream name them alike).
template <typename Codec>
class CodecStateStream : public StateStream {
 public:
  CodecStateStream(const QuantizationParams& params, const StreamThresholds& thresholds)
      : thresholds_(thresholds), codec_(params) {}
  void Begin(std::span<uint8_t> out, uint32_t time_ms) override { codec_.Begin(out, time_ms); }
  size_t count() const override { return codec_.count(); }
  size_t Finish() override { return codec_.Finish(); }
  void OnSent(uint16_t sequence, double now) override { codec_.OnSent(sequence, now); }
  void OnAcked(uint16_t sequence) override { codec_.OnPacketAcked(sequence); }
  void Forget(uint32_t entity_id) override { codec_.Forget(entity_id); }

 protected:
  StreamThresholds thresholds_;
  Codec codec_;
};

}  // namespace edgephys
