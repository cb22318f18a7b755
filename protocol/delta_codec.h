// State format 2, "quantized delta" (docs/protocol.md §5b): the bandwidth-optimised
// relay -> client entity stream.
//
// One DeltaEncoder per receiving client on the sender side, one DeltaDecoder per stream on the
// receiving side. Transforms are quantised (protocol/quantize.h) and each entity is coded as a
// residual against a prediction from a baseline the client has ACKNOWLEDGED, or as a keyframe.
//
// Baselines (why the decoder can always resolve a reference):
//  * Every payload carries a 16-bit payload counter P (the encoder's own, +1 per payload).
//    The state of entity e sent in payload P is named (e, P).
//  * The encoder keeps, per entity, the last kDeltaBaselineWindow states it put in payloads.
//    It learns which payload went out in which connection packet (OnSent) and which packets the
//    client acknowledged (OnPacketAcked). It references only states that are acknowledged, still
//    in its window and at most kMaxReferenceDistance payloads old; otherwise it sends a keyframe.
//  * The decoder keeps, per entity, the kDeltaBaselineWindow states with the highest P it has
//    decoded. A state the encoder still holds has fewer than kDeltaBaselineWindow newer sent
//    states, hence fewer newer received ones, so an acknowledged (= received and decoded) state
//    is still held by the decoder. Each stored state also carries copies of the two states it was
//    predicted from, so the prediction depends on the referenced state alone.
//  * A reference the decoder cannot resolve (only possible if an acknowledged payload was never
//    given to Decode, or on forged input) is detected by the exact P match and that entity is
//    skipped and counted (stats().unresolved_references); it never yields a wrong state.
//
// INTEGRATION REQUIREMENT: every payload whose packet the receiver acknowledges must be passed
// to DeltaDecoder::Decode, including payloads older than one already decoded (the decoder
// sequences per entity and outputs only states newer than what it has output). Connection
// meets it for the packets SendUnreliable() makes (they carry nothing but the payload, and a
// packet whose only content is a stale payload is not acknowledged: connection.h). A transport
// that acknowledges a payload it drops breaks that entity's baseline chain until its next
// keyframe (bounded by DeltaEncoderOptions::keyframe_refresh_sends). See docs/protocol.md §5b.
//
// Thread-safety: none; each instance is owned by one thread (the room's thread on the relay).
// Memory: encoder ~2.3 KiB per (client, entity) plus 128 packet records of reused capacity;
// decoder ~2 KiB per entity. No allocation per packet in steady state (new entities and the
// first packets of a stream grow containers once).
// Cost: O(1) per entity: the encoder quantises and predicts at the orders in use (all three
// orders on one record in 4, for the adaptive parameters); the decoder predicts each field
// once, at the order the payload names. Timings: bench/codec_bench.cc.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "protocol/bit_stream.h"
#include "protocol/flat_id_map.h"
#include "protocol/quantize.h"
#include "protocol/state_codec.h"
#include "protocol/state_stream.h"
#include "protocol/status.h"

namespace edgephys {

inline constexpr uint8_t kDeltaStateFormat = static_cast<uint8_t>(StateFormat::kQuantizedDelta);
// States kept per entity on both ends (protocol constant: both ends must agree).
inline constexpr size_t kDeltaBaselineWindow = 16;
// Largest distance, in payload counters, between a state and its reference.
inline constexpr uint32_t kMaxReferenceDistance = 4096;
// Fixed part of the payload header: format, time, counter, params (then a varint count).
inline constexpr size_t kDeltaHeaderSize = 1 + 4 + 2 + 2;

struct DeltaEncoderOptions {
  // Force a keyframe after this many sends of an entity since its last keyframe (staggered by
  // entity id). Bounds how long a broken baseline chain can last (see the header comment);
  // 0 disables. Cost: each refresh is a keyframe instead of a delta record.
  uint32_t keyframe_refresh_sends = 120;
};

// Parts of an entity record (DeltaEncoderStats::record_part_bits): the id gap, the reference
// symbol, a keyframe's body, the mask bits, the position residuals, the rotation (index bits
// and residuals).
enum DeltaRecordPart : size_t {
  kRecordPartId = 0, kRecordPartReference, kRecordPartKeyframe, kRecordPartMask,
  kRecordPartPosition, kRecordPartRotation, kRecordPartCount
};

struct DeltaEncoderStats {
  uint64_t payloads = 0;           // payloads finished with >= 1 entity
  uint64_t entities = 0;           // entity records written
  uint64_t keyframes = 0;          // of which keyframes (incl. refreshes)
  uint64_t refresh_keyframes = 0;  // keyframes forced by keyframe_refresh_sends
  uint64_t positions_clamped = 0;  // truth outside the room bounds (or not finite)
  uint64_t rotations_invalid = 0;  // truth rotation not finite / zero (identity sent)
  uint64_t acks_unmatched = 0;     // OnPacketAcked for a packet without (or a forgotten) record
  // Residual coding, for the record: bits spent with adaptive Exp-Golomb, and what a
  // per-packet fixed width per field (widest zigzag residual of the packet, +5 bits per
  // field per packet to send the width) would have cost for the same residuals.
  uint64_t residual_bits_exp_golomb = 0;
  uint64_t residual_bits_fixed_width = 0;
  // Bits of the committed records by part (kRecordPart*), for the record: where a state costs
  // what it costs. Payload headers are not included.
  std::array<uint64_t, kRecordPartCount> record_part_bits{};
};

// The receiver-independent part of adding one state to a DeltaEncoder: the state quantised,
// its rotation expanded for prediction and, optionally, what a client reconstructs from it.
// It is the same for every encoder whose QuantizationParams are equal, so a sender with many
// receivers prepares each entity version once (PrepareState) and hands it to every receiver's
// Add, instead of each encoder quantising the same truth again (relay: once per room tick
// for the entities that changed). Plain value, ~90 bytes; no ownership, no thread-safety
// needs (read-only once made).
struct PreparedState {
  QuantizedState q;
  std::array<int32_t, 4> rot4{};  // RotationToInt4(q.rotation)
  bool position_exact = false;    // false: clamped to the bounds or not finite
  bool rotation_ok = false;       // false: not finite or zero (identity used)
  bool has_float = false;         // position/rotation below are set
  Vec3f position;                 // q dequantised (metres)
  Quatf rotation;
  // The lattice it was made on; Add ignores a PreparedState made with other parameters.
  double step = 0;
  double origin[3] = {0, 0, 0};
  int32_t rotation_max = 0;
};
// Cost: O(1), the quantisation (and with `with_float` the dequantisation) of one state; no
// allocation.
PreparedState PrepareState(const QuantizationParams& params, const EntityState& truth,
                           bool with_float = true);

// Sender side, one per receiving client. Implements StateEncoder so the relay can fill
// datagrams dynamically: Begin(buffer of kMaxUnreliablePayload, now_ms); while (Add(...)) ...;
// size = Finish(); sequence = connection.SendUnreliable(...); OnSent(sequence, now).
class DeltaEncoder final : public StateEncoder {
 public:
  explicit DeltaEncoder(const QuantizationParams& params, const DeltaEncoderOptions& options = {});

  // Starts a payload in `out` (not owned; must stay valid until Finish()). `time_ms` is the
  // sender clock in ms (wraps); it must be the time the added states were sampled at, and
  // non-decreasing between payloads for good prediction. A previous payload that was
  // finished but not reported through OnSent() counts as never sent.
  void Begin(std::span<uint8_t> out, uint32_t time_ms) override;
  // Appends `truth`, quantised; false (and nothing written, no state changed) if it does not
  // fit, or if its id is not greater than the previous id in this payload (ids must be added
  // in increasing order; start a new payload otherwise). Out-of-bounds positions are clamped
  // and counted in stats(). Cost O(1); allocates only for an entity never seen before.
  bool Add(const EntityState& truth) override { return Add(truth, nullptr); }
  // Add with the quantisation already done: `prepared` = PrepareState(params(), truth) (it
  // must describe `truth`; one made with other parameters, or nullptr, is ignored and the
  // encoder quantises `truth` itself). Saves the quantisation and rotation expansion, and
  // with has_float the dequantisation NeedsUpdate would otherwise do per receiver.
  bool Add(const EntityState& truth, const PreparedState* prepared);
  size_t count() const override { return count_; }
  // Completes the payload; returns its size in bytes (0 if nothing was added).
  size_t Finish() override;

  // The payload last finished went out in connection packet `packet_sequence` at `now`
  // (seconds, the clock NeedsUpdate uses). Call before the next Begin(); skip it if the
  // payload was not sent.
  void OnSent(uint16_t packet_sequence, double now);
  // The client acknowledged packet `packet_sequence` (ConnectionHandler::OnPacketAcked):
  // the states it carried become usable baselines. Unknown or old sequences are ignored.
  void OnPacketAcked(uint16_t packet_sequence);
  // Drops all state of entity `id` (despawned); its next Add is a keyframe.
  void Forget(uint32_t id);

  // Selective synchronisation. True if entity `id` was never sent, or `truth` differs from
  // the state the client last acknowledged (or nothing is acknowledged) by more than
  // `pos_threshold_m` (Euclidean) or `rot_threshold_deg` (rotation angle), unless the newest
  // state in flight (sent less than `resend_after_s` before `now` and not yet acknowledged)
  // is itself within the thresholds of `truth`. A field whose quantised truth equals the
  // compared state's counts as within (sending it again could not bring the client closer),
  // so thresholds below the lattice's own error never resend a resting entity.
  // Cost O(1) (a hash lookup, at most two quantisations), no allocation.
  bool NeedsUpdate(uint32_t id, const EntityState& truth, float pos_threshold_m,
                   float rot_threshold_deg, double now, double resend_after_s) const {
    return Need(id, truth, pos_threshold_m, rot_threshold_deg, now, resend_after_s) ==
           UpdateNeed::kSend;
  }
  // NeedsUpdate with the reason for "no". kAckedWithin is sticky: it stays the answer for the
  // same `truth` until the entity is sent or forgotten (acknowledgements only make newer states
  // the reference), so a caller may skip asking again while `truth` is unchanged.
  enum class UpdateNeed { kSend, kAckedWithin, kInFlightWithin };
  UpdateNeed Need(uint32_t id, const EntityState& truth, float pos_threshold_m,
                  float rot_threshold_deg, double now, double resend_after_s) const;

  const DeltaEncoderStats& stats() const { return stats_; }
  // The bits by part of the record the last successful Add wrote (DeltaRecordPart).
  const std::array<uint32_t, kRecordPartCount>& last_record_bits() const { return last_bits_; }
  const QuantizationParams& params() const { return params_; }

  // Implementation types (public for the shared prediction code in delta_codec.cc).
  struct Sample {
    std::array<int32_t, 3> pos{};  // lattice indices
    std::array<int32_t, 4> rot{};  // RotationToInt4
    uint32_t time_ms = 0;
  };
  struct History {
    std::array<Sample, 3> s;  // s[0] = this state, s[1] its reference, s[2] the reference's
    uint8_t depth = 0;        // valid samples (1..3)
  };

 private:
  struct Entry {
    bool valid = false;
    bool acked = false;
    bool sent = false;
    uint32_t counter = 0;  // payload counter (32-bit internally, 16 bits on the wire)
    double sent_at = 0;
    QuantizedState q;
    // q dequantised (what the client reconstructs), computed on NeedsUpdate's first look.
    mutable bool has_float = false;
    mutable Vec3f position;
    mutable Quatf rotation;
    History hist;
  };
  static constexpr int8_t kNoSlot = -1;
  struct Track {
    std::array<Entry, kDeltaBaselineWindow> ring;
    uint32_t next = 0;
    uint32_t sends_since_keyframe = 0;
    int8_t newest_acked = kNoSlot;  // ring slot of the acked entry with the highest counter
    uint32_t acked_counter = 0;     // its counter
    // A copy of that entry's state, so that NeedsUpdate reads this header only (the ring
    // entry itself would be one more cache miss per entity and receiver).
    struct AckedCopy {
      QuantizedState q;
      mutable bool has_float = false;
      mutable Vec3f position;
      mutable Quatf rotation;
    } acked;
    int8_t newest_sent = kNoSlot;   // ring slot of the sent entry with the highest counter
  };
  struct PacketRecord {
    bool valid = false;
    uint16_t sequence = 0;
    uint32_t counter = 0;
    std::vector<std::pair<uint32_t, uint8_t>> ids;  // (entity id, ring slot)
  };
  // Adaptive parameter statistics, per field (0 position, 1 rotation), order (0..2) and k.
  struct CostTable {
    double full[2][3][8] = {};
    double masked[2][3][8] = {};
  };

  const Entry* NewestAcked(const Track& t) const;
  void ChooseParams();

  QuantizationParams params_;
  DeltaEncoderOptions options_;
  FlatIdMap<Track> tracks_;
  std::vector<PacketRecord> records_;
  std::vector<std::pair<uint32_t, uint8_t>> pending_ids_;  // (entity id, ring slot)
  uint64_t records_added_ = 0;  // delta records ever added (samples the statistics)
  // Beyond these, a truth cannot quantise to the compared state (see Need).
  double lattice_reach2_ = 0;   // squared metres
  double lattice_min_dot_ = 1;  // |quaternion dot product|
  // cos(threshold / 2) for the last rotation threshold Need was given (a cache).
  mutable float min_dot_for_deg_ = -1.f;
  mutable double min_dot_ = 1;
  size_t max_packet_ids_ = 0;  // most entities seen in one payload (record capacity)
  DeltaEncoderStats stats_;
  std::array<uint32_t, kRecordPartCount> last_bits_{};
  CostTable costs_;
  CostTable packet_costs_;
  uint32_t packet_max_zigzag_[2] = {0, 0};
  uint64_t packet_residuals_[2] = {0, 0};

  // Current payload.
  std::span<uint8_t> out_;
  uint32_t time_ms_ = 0;
  uint32_t counter_ = 0;
  bool payload_used_ = false;
  enum class Phase { kIdle, kOpen, kFinished, kSent };
  Phase phase_ = Phase::kIdle;
  size_t count_ = 0;
  uint32_t last_id_ = 0;
  uint32_t prev_distance_ = 1;
  // Params of the current payload.
  int k_[2] = {2, 1};
  bool mask_[2] = {true, true};
  int order_[2] = {2, 2};
  BitWriter writer_;  // over the current payload's bit stream
};

// Format 2 as one receiver's StateStream: quantized deltas against its own acknowledged
// baselines. Add uses the entity's PreparedState when it has one.
class DeltaStateStream final : public CodecStateStream<DeltaEncoder> {
 public:
  using CodecStateStream::CodecStateStream;  // (params, thresholds)
  StreamNeed Want(const StreamEntity& e, double now, double resend_after_s,
                  uint8_t* fields) override;
  bool Add(const StreamEntity& e, uint8_t fields) override;
};

// The StreamNeed of an encoder's UpdateNeed (formats 2 and 9).
inline StreamNeed ToStreamNeed(DeltaEncoder::UpdateNeed need) {
  switch (need) {
    case DeltaEncoder::UpdateNeed::kSend: return StreamNeed::kSend;
    case DeltaEncoder::UpdateNeed::kAckedWithin: return StreamNeed::kSettled;
    case DeltaEncoder::UpdateNeed::kInFlightWithin: return StreamNeed::kSkip;
  }
  return StreamNeed::kSend;
}

struct DeltaDecoderStats {
  uint64_t payloads = 0;               // accepted payloads
  uint64_t malformed = 0;              // rejected payloads
  uint64_t entities = 0;               // states output
  uint64_t keyframes = 0;              // keyframe records accepted
  // Records skipped because their reference is not held (never decoded into a guess):
  uint64_t unresolved_references = 0;  // all of the below
  uint64_t unknown_entity = 0;         // no version of the entity held
  uint64_t stale_references = 0;       // older than every version held
  uint64_t future_references = 0;      // newer than every version held
  uint64_t missing_references = 0;     // within the held range, but not held
  uint64_t stale_skipped = 0;          // decoded, but older than the state output
  uint64_t capacity_dropped = 0;       // keyframes of new entities beyond max_entities
};

// The receiver of formats 2 and 9, one per stream. Both formats carry the same records
// (docs/protocol.md §5b) and differ only in their header: where the payload's version (format
// 2's 16-bit payload counter, format 9's 32-bit room tick) and the params field stand. A
// record's reference is a version of its entity this receiver decoded: a delta whose reference
// is not held is skipped and counted by kind, never guessed.
class DeltaStreamDecoder : public StateDecoder {
 public:
  // Decodes one payload of this decoder's format (untrusted). On success sets out->time_ms and
  // APPENDS the decoded states that are newer than any state output before for their entity (in
  // increasing id order). Malformed input (truncation, trailing bits, bad header, values out of
  // range, references beyond kMaxReferenceDistance): kMalformed, `out` and the decoder
  // unchanged. Cost O(payload); no allocation in steady state (new entities allocate once).
  Status Decode(std::span<const uint8_t> payload, StateBatch* out) override;
  // Drops entity `id` (despawned).
  void Forget(uint32_t id) override;

  // For tests and diagnostics: the (id, payload version, reference version or -1 for a
  // keyframe) of every record resolved by the last successful Decode.
  struct Reference {
    uint32_t id;
    int64_t version;
    int64_t reference;
  };
  std::span<const Reference> last_references() const { return last_references_; }
  const DeltaDecoderStats& stats() const { return stats_; }

 protected:
  // Where a format's header keeps its fields (the format byte is at 0, the time at 1..4).
  struct Layout {
    uint8_t format;
    size_t header_size;     // bytes before the record count
    size_t version_offset;  // the payload's version, little-endian
    int version_bytes;      // 2 (wraps, extended against the highest seen) or 4
    size_t params_offset;   // the 16-bit params field
    const char* malformed;  // the error a malformed payload returns
  };
  DeltaStreamDecoder(const Layout& layout, const QuantizationParams& params, size_t max_entities);

 private:
  struct Entry {
    bool valid = false;
    int64_t version = 0;
    DeltaEncoder::History hist;
  };
  struct Track {
    std::array<Entry, kDeltaBaselineWindow> ring;
    int64_t newest_output = INT64_MIN;
  };
  enum class Unresolved : uint8_t { kNone, kUnknownEntity, kStale, kFuture, kMissing };
  struct Staged {
    bool keyframe = false;
    Unresolved unresolved = Unresolved::kNone;
    uint32_t id = 0;
    int64_t reference = -1;
    Track* track = nullptr;  // the entity's track if it existed when resolved (node-stable)
    QuantizedState q;
    DeltaEncoder::History hist;
  };
  // Resolves a delta record `s` against its entity's held versions, or says why not.
  const Entry* Resolve(Staged& s);
  // Applies the staged records of the payload with `version` at `time_ms` to the tracks and `out`.
  void Commit(int64_t version, uint32_t time_ms, StateBatch* out);

  Layout layout_;
  QuantizationParams params_;
  size_t max_entities_;
  std::unordered_map<uint32_t, Track> tracks_;
  std::vector<Staged> staged_;
  std::vector<Reference> last_references_;
  bool have_version_ = false;
  int64_t highest_version_ = 0;
  DeltaDecoderStats stats_;
};

// Receiver side of format 2.
class DeltaDecoder final : public DeltaStreamDecoder {
 public:
  explicit DeltaDecoder(const QuantizationParams& params, size_t max_entities = 1 << 16);
};

}  // namespace edgephys
