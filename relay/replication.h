// Replication: what the relay sends one client each tick, and how (docs/protocol.md, state
// formats; docs/benchmarks.md, what it costs).
//
// Per client, per tick, ClientReplicator
//  1. picks candidates: entities the client does not own that are due by their priority
//     class's send interval (critical: avatars, hands, grabbed — default 48 Hz; normal —
//     default 12 Hz; ambient — simulated by PhyS and untouched by any user for
//     `interaction_linger_s` — `ambient_hz`; resting — nothing changed for `resting_after_s`:
//     only on change) and whose state differs from what the client ACKNOWLEDGED by more than
//     the thresholds (selective synchronisation; a plug-in stream decides for its own format);
//  2. orders them by a priority accumulator (class weight x time waiting) and takes them in
//     that order while the per-client bandwidth budget allows, so nothing starves;
//  3. encodes them into as few datagrams as fit the MTU.
//
// Formats: 9 (shared delta: the room encodes each entity's body once per tick for all
// receivers, Room::PrepareStates, Entity::shared; the default), 2 (quantized delta against
// acknowledged baselines, per receiver; ReplicationConfig::shared_encoding false, kept for one
// release), or a plug-in's (relay/entity_stream.h: the benchmark emulations). Soft bodies:
// format 11.
//
// Thread-safety: none; owned by the session, used on the room's thread.
// Cost: O(entities in room) per tick (a walk of the room's frame, Room::BuildFrame, with the
// views in an array indexed by the entities' room-local slots), plus O(k log k) for the k
// candidates only under a bandwidth budget; no allocation per packet once the views exist.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "protocol/connection.h"
#include "protocol/delta_codec.h"
#include "protocol/flat_id_map.h"
#include "protocol/packet_seal.h"
#include "protocol/shared_delta_codec.h"
#include "protocol/soft_delta_stream.h"
#include "protocol/state_codec.h"
#include "relay/relay_counters.h"
#include "relay/entity_streams.h"

namespace edgephys {

struct Entity;
struct ReplicationFrame;

// kAmbient: a PhyS-simulated entity that nothing reported touches (no open trigger overlap or
// reported contact) and that no event named for `interaction_linger_s` (grab, release, hand or
// reported contact): the background of a scene, sent at `ambient_hz`.
enum class PriorityClass : uint8_t { kCritical = 0, kNormal, kAmbient, kResting };

struct ReplicationConfig {
  // A state format the relay does not carry (relay/entity_stream.h); null: format 9 (or 2).
  std::shared_ptr<const ReplicationPlugin> plugin;
  double critical_hz = 48;            // avatars, hands, grabbed objects
  double normal_hz = 12;              // everything else that moves
  // PhyS-simulated entities no user interacts with. A receiver interpolates them over a longer
  // interval: the accuracy this costs (display error against the truth) is measured by
  // `edgephys-loadgen multiobject`. Equal to normal_hz: no ambient
  // class. Default 6 Hz: about the per-object rate Decoupled Edge Physics' PhyS table implies (its
  // throughput / 33 bytes per update: 4-5.5 updates per object per second).
  double ambient_hz = 6;
  // An entity counts as interacted with while a trigger overlap or a reported contact naming
  // it is open (Enter without Exit), and for this long after a grab, a release or any physics
  // event that names it (hand triggers and contacts, ReportContacts entities).
  double interaction_linger_s = 2.0;
  double resting_after_s = 1.0;       // unchanged this long: resting (sent only on change)
  double fixed_rate_hz = 0;           // > 0: every class at this rate (benchmarks)
  // Selective sync thresholds: an entity whose client copy is within these of the truth is
  // not resent. The defaults equal the quantisation's accuracy (position_step_m,
  // rotation_bound_deg): finer thresholds cannot bring a client closer than the lattice, and
  // resend slowly creeping entities for nothing.
  float position_threshold_m = 0.001f;
  float rotation_threshold_deg = 0.1f;
  double bandwidth_budget_bytes_per_s = 0;  // per client; 0 = unlimited
  // Quantisation of the edgephys format (see protocol/quantize.h); sent to clients in Joined.
  float position_step_m = 0.001f;
  float rotation_bound_deg = 0.1f;
  float bounds_half_extent_m = 1000.0f;  // room bounds: a cube centred on the origin
  // Send state format 9 ("shared delta", protocol/shared_delta_codec.h); false
  // sends format 2. The room quantises, predicts and codes each (entity, baseline) delta once per
  // tick for every receiver on that baseline; each receiver only appends bits. Clients learn the
  // format from Joined. The default: at 100 users in one room 4.9x less relay CPU per delivered
  // update than format 2, -4 % bytes per update, a fifth of the relay's peak RSS. Memory: ~7 KiB
  // per entity per room at 60 Hz (the room's version window) plus 68 bytes per (receiver,
  // entity), against ~2.3 KiB per (receiver, entity) for format 2
  // (protocol/shared_delta_codec.h, protocol/delta_codec.h).
  bool shared_encoding = true;
  // Soft bodies are sent as format 11 (residuals against acknowledged versions,
  // protocol/soft_delta_stream.h) at soft_touched_hz while a hand touches them (held, an open
  // touch event, or a Hand entity's centre within this distance of a particle: PhyS reports no
  // contact events for soft bodies), else at normal_hz. 24 Hz, not critical_hz: a poked bunny costs
  // ~4 bits a particle per version, and the display error during pokes it adds against 48 Hz
  // is measured by `edgephys-loadgen softbody --soft-touched-hz`.
  float soft_touch_margin_m = 0.1f;
  double soft_touched_hz = 24;
};

// True when rooms with `config` send format 9 (the default).
inline bool UsesSharedEncoding(const ReplicationConfig& config) {
  return config.plugin == nullptr && config.shared_encoding;
}


// The quantisation a room with `config` uses (format 2).
QuantizationConfig QuantizationOf(const ReplicationConfig& config);

class ClientReplicator {
 public:
  // `config`'s quantisation must be one MakeQuantizationParams accepts (the relay's flags and
  // the admin API refuse others); a refused one is replaced by the default quantisation.
  explicit ClientReplicator(const ReplicationConfig& config);
  ~ClientReplicator();

  // Sends this tick's updates for the client `self` (player id) through `connection`.
  // `frame` is the room's offer for this tick (Room::BuildFrame): its entities by id, soft
  // bodies and hands, so the replicator neither walks the room's table nor sorts by id.
  void Tick(const ReplicationFrame& frame, uint32_t self, double now, Connection& connection,
            PacketWriter& out, RelayCounters& counters);

  void OnPacketAcked(uint16_t sequence);
  // Drops everything held for `entity_id` (despawned): its view, its record in the entity
  // stream (format 2: ~2.3 KiB), and its soft body view. The relay calls it for every member left in
  // the room whenever an entity goes, whether despawned by its owner or with its owner.
  void Forget(uint32_t entity_id);
  // How many entities this replicator holds per-entity state for: its views (which cover the
  // entity stream's records: Tick makes the view first, Forget erases all) or its soft body
  // views if more. For tests and diagnostics. O(1).
  size_t tracked_entities() const;

 private:
  static constexpr double kEpsilon = 1e-6;
  // Bytes a datagram costs on the wire beyond its state payload: connection header, chunk
  // header and the seal (the budget is counted as the sealed datagrams go out).
  static constexpr double kPacketOverhead =
      static_cast<double>(kConnectionHeaderSize + 3 + kSealOverhead);

  // One per entity slot (Entity::slot), valid while `serial` equals the entity's. 32 bytes:
  // every receiver reads one per entity each tick (the walk is bound by loading them).
  struct View {
    uint32_t serial = 0;  // 0: free
    uint32_t id = 0;
    double last_sent = -1e9;
    double next_due = -1e9;
    // The entity version whose state the client has acknowledged within the thresholds
    // (nothing to send until the version changes); 0 = none.
    uint32_t settled_version = 0;
  };
  void ResetView(uint32_t slot);
  struct Candidate {
    double priority;
    uint32_t id;
    const Entity* entity;
    uint8_t fields;
  };
  // The view of `e` (a slot of views_), made afresh if the slot holds none or another
  // occupant's. May grow views_ (invalidating references to other views).
  View& ViewOf(const Entity& e);
  PriorityClass ClassOf(const Entity& e, double now) const;
  double IntervalOf(PriorityClass c) const;
  // The entity walk, selection and encoding of Tick.
  void TickEntities(const ReplicationFrame& frame, uint32_t self, double now, double resend_after,
                    Connection& connection, PacketWriter& out, RelayCounters& counters);
  void Flush(double now, Connection& connection, PacketWriter& out, RelayCounters& counters);
  void BeginPayload();  // starts a payload in payload_ with this receiver's stream
  // Soft bodies (format 11, soft_): residuals of each due soft body's particles against what
  // the client acknowledged.
  struct SoftView {
    double sent_at = -1e9;
    double next_due = -1e9;
  };
  void TickSoftBodies(const ReplicationFrame& frame, uint32_t self, double now,
                      double resend_after, Connection& connection, PacketWriter& out,
                      RelayCounters& counters);
  bool FlushSoft(double now, Connection& connection, PacketWriter& out, RelayCounters& counters);
  bool SoftTouched(const Entity& e) const;
  // The body's first particles after a failover (Entity::resumed_nodes) are not yet sent to
  // this receiver: they go out at once.
  static bool Resumed(const Entity& e, const SoftView& v, double now);
  std::unordered_map<uint32_t, SoftView> soft_views_;
  std::unique_ptr<SoftDeltaSender> soft_;            // format 11
  std::vector<std::pair<uint32_t, const Entity*>> soft_due_;
  const std::vector<Vec3f>* hands_ = nullptr;        // this tick's Hand entity positions

  ReplicationConfig config_;
  std::vector<uint8_t> payload_;
  // The receiver's rigid-body format (relay/entity_streams.h: format 9, 2 or a plug-in's).
  std::unique_ptr<StateStream> stream_;
  std::vector<View> views_;            // by entity slot: walked densely, no lookups
  FlatIdMap<uint32_t> view_slot_of_;   // entity id -> slot of its live view (Forget)
  size_t live_views_ = 0;
  std::vector<Candidate> candidates_;
  std::vector<Candidate> selected_;
  double budget_bytes_ = 0;
  double bytes_per_entity_ = 16;  // running estimate of one encoded entity
  double last_tick_ = -1;
  uint32_t time_ms_ = 0;
};

}  // namespace edgephys
