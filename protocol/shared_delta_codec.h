// State format 9, "shared delta" (docs/protocol.md §5e): format 2's quantised prediction
// residuals, arranged so that a room encodes each (entity, baseline) delta ONCE per tick for
// every receiver that holds that baseline; per receiver only selection and bit-appending remain.
//
// What changes against format 2 (protocol/delta_codec.h):
//  * Versions are named by the ROOM TICK (32 bits on the wire) instead of a per-receiver payload
//    counter: every receiver sent entity e in tick T gets the same state under the same name
//    (e, T), with the same sample time (the tick's time).
//  * A delta's prediction input ("baseline key") is the referenced version and the two versions
//    in its history, all named by ticks. Receivers sent an entity in the same ticks (same send
//    phase, similar RTT) hold the same keys, so their residuals are identical: the room encodes
//    the record body once per (entity, key) per tick (SharedEntity's cache) and every such
//    receiver appends that bit string. Histories heal: two receivers whose chains diverged (a
//    loss) share keys again three sends later.
//  * Coding parameters (Exp-Golomb k, mask, order) are the room's, chosen per tick from decayed
//    statistics of the bodies it encoded (weighted by how many receivers used each), carried in
//    each payload header (every payload carries records of one tick only).
//  * The per-record fields that depend on the receiver's payload (id gap, reference distance
//    relative to the previous record) stay per receiver, coded as in format 2; the cached body
//    (keyframe body, or mask bits + residuals) follows them and is appended by bit copy.
//
// Baselines: per receiver the relay keeps, per entity, the ticks of the last
// kDeltaBaselineWindow versions it sent (no states: those live once per room), learns acks per
// packet and references the newest acknowledged one (<= kMaxReferenceDistance ticks old), else a
// keyframe. The client keeps per entity the kDeltaBaselineWindow versions with the highest ticks
// (the format-2 argument: an acknowledged version is always held). The room keeps per entity
// the last SharedVersionWindowFor(tick rate) versions and the times of the last kSharedTickWindow ticks; a
// key whose versions it no longer holds is sent as a keyframe instead.
//
// Thread-safety: SharedDeltaRoom::BeginTick / PrepareEntity on one thread (the room's) before
// the receivers' ticks; during them, SharedDeltaRoom::Body may be called concurrently from any
// threads (the cache claims slots with atomics; a body never changes once published).
// SharedDeltaStream and SharedDeltaDecoder: one owner thread each.
// Memory: room ~7 KiB per entity at 60 Hz (versions) + ~0.9 KiB (cache) + 32 KiB per room (tick
// times); stream 68 bytes per (receiver, entity) (a 64-byte record and its id) plus 24 KiB per
// receiver (its payload ring);
// decoder ~2 KiB per entity, bounded by max_entities.
// Cost (bench/shared_codec_bench, 100 receivers x 200 entities, all sent each tick): ~130-160 ns
// per (receiver, entity) including the room's share, against ~340-410 ns for format 2; a body
// encode (cache miss) costs about what a format-2 Add does.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "protocol/bit_stream.h"
#include "protocol/delta_codec.h"
#include "protocol/flat_id_map.h"
#include "protocol/quantize.h"
#include "protocol/state_codec.h"
#include "protocol/status.h"

namespace edgephys {

inline constexpr uint8_t kSharedDeltaStateFormat = 9;
// format, tick time (ms), tick, params; then a varint count.
inline constexpr size_t kSharedDeltaHeaderSize = 1 + 4 + 4 + 2;
// Versions the room keeps per entity (at least; see SharedVersionWindowFor), and tick times
// per room (relay side only).
inline constexpr size_t kSharedVersionWindow = 64;
// Versions per entity for a room ticking at `tick_rate_hz`: two seconds of ticks, as a power
// of two (an entity that changes every tick still has the versions its receivers' keys name
// when they are sent at a few Hz, with losses and round trips), at least
// kSharedVersionWindow, at most 2048. ~56 bytes each: 7 KiB per entity at 60 Hz.
inline size_t SharedVersionWindowFor(double tick_rate_hz) {
  const double n = tick_rate_hz > 0 ? 2.0 * tick_rate_hz : 0;
  size_t w = kSharedVersionWindow;
  while (w < n && w < 2048) w *= 2;
  return w;
}
inline constexpr size_t kSharedTickWindow = 8192;
// Cached bodies per entity per tick; a receiver whose key finds no slot encodes privately.
inline constexpr size_t kSharedCacheSlots = 6;
inline constexpr size_t kSharedBodyMaxBytes = 48;  // >= the largest body (~350 bits)

// The prediction input of a delta: the referenced version and its history's two older samples
// (ticks), and the history depth 1..3. depth 0 = keyframe (no reference).
struct SharedBaselineKey {
  uint32_t ref = 0, s1 = 0, s2 = 0;
  uint8_t depth = 0;
  bool operator==(const SharedBaselineKey&) const = default;
};

struct SharedDeltaParams {
  int k[2] = {2, 1};
  bool mask[2] = {true, true};
  int order[2] = {2, 2};
};

struct SharedDeltaRoomStats {
  // Bodies served from the cache are counted by the streams (SharedDeltaStreamStats::
  // cache_hits): a room-wide counter would be one contended cache line for every receiver.
  std::atomic<uint64_t> encodes{0};        // bodies encoded into the cache
  std::atomic<uint64_t> uncached{0};       // encoded privately (no free slot)
  std::atomic<uint64_t> missing_versions{0};  // keys whose versions are gone: keyframe instead
};

class SharedDeltaRoom;

// One entity's room-side state: its recent versions and this tick's cached record bodies.
// Owned by the room's entity; held by pointer (not copyable: atomics).
class SharedEntity {
 public:
  SharedEntity() = default;
  SharedEntity(const SharedEntity&) = delete;
  SharedEntity& operator=(const SharedEntity&) = delete;

  const SharedDeltaRoom* room() const { return room_; }
  // Tick of the newest version (the current state); 0 before the first PrepareEntity.
  uint32_t current_tick() const { return versions_.empty() ? 0 : Newest().tick; }

  // The entity's room-local slot (a dense index the room reuses once the entity is gone) and
  // the serial naming this occupancy of the slot (unique within the room, never 0).
  // Receivers (SharedDeltaStream) keep their per-entity records in arrays indexed by slot and
  // trust a record only while its serial matches, so a stale slot never aliases another
  // entity, and an entity respawned under the same id starts afresh. The relay's Room binds
  // each entity to its own slot (BindSlot) before the first PrepareEntity; an entity still
  // unbound then gets a fresh slot from its SharedDeltaRoom (never reused: tests, benchmarks).
  uint32_t slot() const { return slot_; }
  uint32_t serial() const { return serial_; }
  void BindSlot(uint32_t slot, uint32_t serial) {
    slot_ = slot;
    serial_ = serial;
  }

 private:
  friend class SharedDeltaRoom;
  struct Version {
    uint32_t tick = 0;  // the tick it was prepared in (became the entity's state)
    QuantizedState q;
    std::array<int32_t, 4> rot4{};
    // q dequantised once when recorded, for selective sync. Named and mutable as
    // delta_internal::WithinThresholds expects of a held state; has_float is always true, so
    // it never writes them.
    mutable bool has_float = true;
    mutable Vec3f position;
    mutable Quatf rotation;
  };
  struct Slot {
    std::atomic<uint8_t> state{0};  // 0 empty, 1 being built, 2 ready
    std::atomic<uint32_t> uses{0};
    SharedBaselineKey key;
    uint16_t bits = 0;
    bool sampled = false;  // residuals of every order kept for the room's statistics
    std::array<uint8_t, kSharedBodyMaxBytes> body{};
    int32_t pos_res[3][3] = {};
    int32_t rot_res[3][3] = {};
    bool rot_same[3] = {};
  };
  const Version& Newest() const {
    return versions_[static_cast<size_t>((next_ - 1) % versions_.size())];
  }
  // The version current at `tick` (the newest prepared at or before it), null if not held.
  const Version* At(uint32_t tick) const;

  const SharedDeltaRoom* room_ = nullptr;
  uint32_t slot_ = 0;
  uint32_t serial_ = 0;  // 0: not bound to a slot yet
  std::vector<Version> versions_;  // ring of the room's window (allocated on first use)
  uint64_t next_ = 0;  // versions ever recorded
  uint32_t cache_tick_ = 0;
  std::array<Slot, kSharedCacheSlots> slots_;
  // Selective-sync answers of this tick, shared by the room's receivers, by the reference's
  // age in ticks (tick - reference tick, below kWithinAges): word = (tick & 2^30-1) << 2 |
  // answer (1 not within, 2 within; 0 none). Receivers hold a handful of references per entity
  // (their acknowledged and in-flight sends), so one threshold test serves all that share one,
  // and no two ages evict each other. Relaxed atomics: a lost write only costs a retest.
  static constexpr uint32_t kWithinAges = 64;
  mutable std::array<std::atomic<uint32_t>, kWithinAges> within_memo_{};
};

// The room side: tick clock, tick times, coding parameters and the body cache.
class SharedDeltaRoom {
 public:
  // `versions_per_entity`: the window of versions kept per entity (SharedVersionWindowFor).
  explicit SharedDeltaRoom(const QuantizationParams& params,
                           size_t versions_per_entity = kSharedVersionWindow);

  // Starts tick tick()+1 sampled at `time_ms` (room clock, ms, wraps) and picks this tick's
  // coding parameters from the statistics folded so far. Room thread. O(1).
  void BeginTick(uint32_t time_ms);
  // After BeginTick, for every entity of the room: folds the entity's previous-tick cache into
  // the statistics, empties it, and records `state` as the version of this tick if it differs
  // from the entity's newest version. Room thread. O(1) (allocates once per entity).
  void PrepareEntity(SharedEntity& entity, const PreparedState& state);

  uint32_t tick() const { return tick_; }
  uint32_t time_ms() const { return time_ms_; }
  const SharedDeltaParams& params() const { return params_; }
  const QuantizationParams& quantization() const { return q_; }
  // Time of tick `t` if still held (within kSharedTickWindow ticks and after the first tick).
  bool TickTime(uint32_t t, uint32_t* time_ms) const;

  // The record body coding `entity`'s current version against `key` (keyframe if depth 0) for
  // this tick: from the cache (*hit = true), or encoded and cached (or, without a free slot,
  // encoded into `scratch`). False if the key's versions (or tick times) are no longer held:
  // send a keyframe. Thread-safe between BeginTick calls. `*bits` points into the cache or
  // `scratch`.
  bool Body(SharedEntity& entity, const SharedBaselineKey& key,
            std::array<uint8_t, kSharedBodyMaxBytes>& scratch, const uint8_t** bits,
            size_t* nbits, bool* hit) const;

  // Selective sync against the room's versions: whether the version of `entity` current at
  // `ref_tick` (a version some receiver holds) is within the thresholds of `truth` (the
  // entity's state this tick). `pos2`, `min_dot`, `reach2`, `lattice_min_dot` as
  // delta_internal::WithinThresholds; every caller in one tick must pass the same thresholds
  // (the answer is memoised per (entity, tick, ref_tick)). False when the version is no longer
  // held. Thread-safe between BeginTick calls. O(log window) on a memo miss, O(1) on a hit.
  bool HeldWithin(const SharedEntity& entity, uint32_t ref_tick, const EntityState& truth,
                  double pos2, double min_dot, double reach2, double lattice_min_dot) const;

  const SharedDeltaRoomStats& stats() const { return stats_; }

 private:
  bool Encode(const SharedEntity& e, const SharedBaselineKey& key, SharedEntity::Slot* slot,
              uint8_t* out, size_t* nbits) const;
  void ChooseParams();

  QuantizationParams q_;
  size_t versions_per_entity_;
  uint32_t tick_ = 0;
  uint32_t time_ms_ = 0;
  // Slots for entities nobody bound (SharedEntity::slot): high, never reused.
  uint32_t auto_slots_ = 0;
  uint32_t auto_serials_ = 0;
  std::vector<uint32_t> tick_times_;  // ring of kSharedTickWindow
  SharedDeltaParams params_;
  // Statistics per field (0 position, 1 rotation), order, k: decayed, and this tick's.
  double full_[2][3][8] = {};
  double masked_[2][3][8] = {};
  double tick_full_[2][3][8] = {};
  double tick_masked_[2][3][8] = {};
  mutable SharedDeltaRoomStats stats_;
};

struct SharedDeltaStreamOptions {
  // As DeltaEncoderOptions::keyframe_refresh_sends (keyframes are cached like deltas); at most
  // 65,535 (larger values are capped).
  uint32_t keyframe_refresh_sends = 120;
};

struct SharedDeltaStreamStats {
  uint64_t payloads = 0;
  uint64_t entities = 0;
  uint64_t keyframes = 0;
  uint64_t refresh_keyframes = 0;
  uint64_t acks_unmatched = 0;
  uint64_t cache_hits = 0;  // record bodies appended from the room's cache
};

// The relay side of one receiver: which versions it was sent and acknowledged, the choice of
// key per entity, and the payload assembly (per record: id gap, reference symbol, then the
// room's body appended by bit copy). Usage per payload: Begin(buffer); while (Add(...)) ...;
// size = Finish(); OnSent(sequence, now). All records of a payload come from one room tick.
class SharedDeltaStream final : public StateEncoder {
 public:
  explicit SharedDeltaStream(const QuantizationParams& params,
                             const SharedDeltaStreamOptions& options = {});

  void Begin(std::span<uint8_t> out, uint32_t time_ms) override;
  // Format 9 needs the room's entity: this overload always returns false.
  bool Add(const EntityState& /*truth*/) override { return false; }
  // Appends entity `id`'s current version (`entity`, prepared this tick by its room). False
  // (nothing written) if it does not fit, ids are not increasing, or the entity belongs to
  // another room or tick than the payload's first record.
  bool Add(uint32_t id, SharedEntity& entity);
  size_t count() const override { return count_; }
  size_t Finish() override;
  void OnSent(uint16_t packet_sequence, double now);
  // O(1): marks the packet's payload acknowledged. Each entity's record learns it the next
  // time the entity is considered (Need, Add), from the sends it remembers (kRememberedSends):
  // an acknowledgement is one flag per payload, not one entry per entity.
  void OnPacketAcked(uint16_t packet_sequence);
  // Drops the record of entity `id` (despawned). O(1). Not needed for correctness (a slot's
  // next occupant has another serial) but frees the id's mapping and the live count.
  void Forget(uint32_t id);
  // Entities with a live record, and the slots the record array spans (bounded by the most
  // entities the room held at once, as the room reuses slots). For tests. O(1).
  size_t tracked_entities() const { return live_tracks_; }
  size_t track_slots() const { return tracks_.size(); }
  // Hint: the entity in room slot `slot` is considered soon (Need, Add): starts loading its
  // record into the cache. The relay walks a room's entities for every receiver each tick, so
  // the records come from beyond the core's cache; no effect on behaviour. O(1).
  void Prefetch(uint32_t slot) const {
    if (slot < tracks_.size()) {
      __builtin_prefetch(&tracks_[slot]);  // one line (Track is 64 bytes, aligned)
    }
  }

  // Selective synchronisation, as DeltaEncoder::Need, with the held states looked up in the
  // room's versions of `entity` (SharedDeltaRoom::HeldWithin, shared by all receivers) rather
  // than kept per receiver. `entity` must have been prepared this tick by its room.
  using UpdateNeed = DeltaEncoder::UpdateNeed;
  // Not const: it first takes in the acknowledgements of the entity's remembered sends.
  UpdateNeed Need(uint32_t id, const SharedEntity& entity, const EntityState& truth,
                  float pos_threshold_m, float rot_threshold_deg, double now,
                  double resend_after_s);

  const SharedDeltaStreamStats& stats() const { return stats_; }
  // The number of the open (or last) payload: unique per stream, never 0 once Begin ran.
  uint32_t open_payload() const { return payload_no_; }

 private:
  static_assert(2 * kMaxReferenceDistance <= 0xFFFF);
  static constexpr uint32_t kRememberedSends = 4;
  // One per entity slot (SharedEntity::slot), valid while `serial` equals the entity's: one
  // cache line (64 bytes, aligned), everything selection, Add and an ack touch. The relay walks
  // every receiver's records of a room's entities each tick, beyond what the core's cache
  // holds, so the walk costs one line per (receiver, entity) (the entity's id, needed only
  // by Forget, is in track_ids_ beside it). No ring of sent states: a send is named by its
  // send number, and its record carries the key it was sent with (the room's versions hold
  // its state; the tick it was sent in is its payload's, PayloadRecord::tick). A send stays
  // usable as a reference while it is among the last kDeltaBaselineWindow sends of the entity
  // (the client keeps that many versions with the highest ticks, so an acknowledged one in
  // that window is always held); an acknowledgement is learnt only for the last
  // kRememberedSends (older ones are superseded by newer sends, or treated as lost).
  struct alignas(64) Track {
    uint32_t serial = 0;  // 0: free
    uint32_t next = 0;    // sends so far (send numbers 0..next-1)
    uint32_t acked_no = 0;  // send number + 1 of the newest acknowledged send; 0: none
    uint32_t acked_ref = 0;  // the tick it was sent in (its key's ref once acknowledged)
    // Its key's two older samples, as ticks before acked_ref, and the key's depth.
    uint16_t acked_back1 = 0, acked_back2 = 0;
    // Sends since the last keyframe (saturates; options are capped at 0xFFFF).
    uint16_t sends_since_keyframe = 0;
    uint8_t acked_depth = 0;
    // The stream's acknowledgement count when Resolve last looked (nothing to take in while
    // no payload was acknowledged since: it runs once per entity and tick, not in Add too).
    uint32_t resolved_epoch = 0;
    // The last kRememberedSends sends, by send number % kRememberedSends: the payload each
    // went in (0: none), and the key an acknowledgement makes its baseline (its two older
    // samples as ticks before the send's tick, <= 2 x kMaxReferenceDistance; depth).
    std::array<uint32_t, kRememberedSends> sent_payload{};
    std::array<uint16_t, kRememberedSends> sent_back1{}, sent_back2{};
    std::array<uint8_t, kRememberedSends> sent_depth{};
    bool Usable(uint32_t no) const { return no != 0 && next - (no - 1) <= kDeltaBaselineWindow; }
    SharedBaselineKey acked_key() const {
      return {acked_ref, acked_ref - acked_back1, acked_ref - acked_back2, acked_depth};
    }
  };
  static_assert(sizeof(Track) == 64, "one cache line per (receiver, entity)");
  // A payload: its number (0: none), when it was sent and whether it was acknowledged. A ring
  // by payload number (kPayloadRing): a send whose payload was overwritten counts as lost.
  struct PayloadRecord {
    uint32_t number = 0;
    uint32_t tick = 0;  // the room tick of its records (every payload holds one tick's)
    bool acked = false;
    double sent_at = 0;
  };
  static constexpr uint32_t kPayloadRing = 1024;
  static constexpr size_t kPacketRecords = 128;
  // Packet sequence -> payload number, for acknowledgements (a ring of kPacketRecords).
  struct PacketRecord {
    bool valid = false;
    uint16_t sequence = 0;
    uint32_t payload = 0;
  };
  // The entity's track, made afresh if its slot holds none or another occupant's.
  Track& ClaimTrack(uint32_t id, const SharedEntity& entity, bool* created);
  void FreeTrack(uint32_t slot);
  // Takes in the acknowledgements of `t`'s remembered sends newer than its acknowledged one
  // (`tick`: the room tick it is resolved at).
  void Resolve(Track& t, uint32_t tick) const;
  // Whether payload `p` was acknowledged (its sends are baselines).
  static bool AckDue(const PayloadRecord& p, uint32_t /*tick*/) { return p.acked; }
  const PayloadRecord* SentPayload(uint32_t payload) const {
    const PayloadRecord& p = payloads_[payload & (kPayloadRing - 1)];
    return payload != 0 && p.number == payload ? &p : nullptr;
  }
  // Bit appends into the open payload (the record's header codes, then the room's body).
  void WriteBits(uint64_t value, int bits);

  QuantizationParams params_;
  SharedDeltaStreamOptions options_;
  std::vector<Track> tracks_;     // by entity slot
  std::vector<uint32_t> track_ids_;  // by entity slot: the id of its track's entity (Forget)
  uint32_t ack_epoch_ = 0;        // payloads acknowledged so far (Track::resolved_epoch)
  FlatIdMap<uint32_t> slot_of_;   // entity id -> slot of its live track (Forget)
  size_t live_tracks_ = 0;
  std::vector<PacketRecord> records_;
  std::vector<PayloadRecord> payloads_;  // kPayloadRing, allocated once
  uint32_t payload_no_ = 0;              // the open (or last) payload's number
  double lattice_reach2_ = 0;
  double lattice_min_dot_ = 1;
  mutable float min_dot_for_deg_ = -1.f;
  mutable double min_dot_ = 1;
  SharedDeltaStreamStats stats_;
  std::array<uint8_t, kSharedBodyMaxBytes> scratch_{};

  // Current payload.
  std::span<uint8_t> out_;
  const SharedDeltaRoom* room_ = nullptr;
  uint32_t tick_ = 0;
  enum class Phase { kIdle, kOpen, kFinished, kSent };
  Phase phase_ = Phase::kIdle;
  size_t count_ = 0;
  uint32_t last_id_ = 0;
  uint32_t prev_distance_ = 1;
  uint8_t* bits_ = nullptr;  // the open payload's record stream (after header and count)
  size_t bits_size_ = 0;     // its bytes
  size_t bit_pos_ = 0;
};

// Format 9 as one receiver's StateStream: records reference versions the room coded once for
// all receivers (StreamEntity::shared, prepared by its SharedDeltaRoom this tick); per receiver
// only the choice of reference and a bit copy. An entity without `shared` is not sent.
class SharedDeltaStateStream final : public CodecStateStream<SharedDeltaStream> {
 public:
  using CodecStateStream::CodecStateStream;  // (params, thresholds)
  StreamNeed Want(const StreamEntity& e, double now, double resend_after_s,
                  uint8_t* fields) override;
  void Prefetch(uint32_t slot) const override { codec_.Prefetch(slot); }
  bool Add(const StreamEntity& e, uint8_t fields) override;
  // The bodies this stream's sent payloads took from the room's cache and coded itself.
  void Count(bool sent, StreamCounts& counts) override;

 private:
  uint64_t hits_counted_ = 0;  // codec_'s stats already counted
  uint64_t entities_counted_ = 0;
};

using SharedDeltaDecoderStats = DeltaDecoderStats;

// Receiver side of format 9, one per stream (DeltaStreamDecoder, protocol/delta_codec.h):
// references are room ticks. Untrusted input.
class SharedDeltaDecoder final : public DeltaStreamDecoder {
 public:
  explicit SharedDeltaDecoder(const QuantizationParams& params,
                              size_t max_entities = 1 << 16);
};

}  // namespace edgephys
