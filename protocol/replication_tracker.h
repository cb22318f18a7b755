// ReplicationTracker: which entity versions one peer has acknowledged, so that state sent on
// the unreliable channel converges under loss. The sender bumps an entity's version on every
// change; an entity needs sending while the peer has not acknowledged its current version,
// and is re-sent (with its latest state) when the copy in flight is presumed lost.
//
// Used by the relay (one tracker per client) and by the client SDK (one for its own entities).
// Thread-safety: none; owned by the connection's thread. Memory: one entry per entity seen
// plus a ring of kPacketRecords packet records (about 32 KB, allocated by the first OnSent, so
// a tracker that is never used costs nothing), each reusing its capacity (no per-packet
// allocation in steady state).
#pragma once

#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace edgephys {

class ReplicationTracker {
 public:
  static constexpr size_t kPacketRecords = 1024;

  ReplicationTracker();

  // True if `version` of entity `id` is newer than what the peer acknowledged and either was
  // never sent or its last send is older than `resend_after_s`.
  bool NeedsSend(uint32_t id, uint32_t version, double now, double resend_after_s) const;

  // Records that packet `sequence` carried `version` of entity `id`, sent at `now`.
  void OnSent(uint16_t sequence, uint32_t id, uint32_t version, double now);

  // The peer acknowledged packet `sequence`: every version it carried counts as received.
  void OnAcked(uint16_t sequence);

  // Records that the peer already has `version` of `id` by other means (e.g. the spawn message
  // carried it), so it is not sent.
  void MarkAcked(uint32_t id, uint32_t version);

  // Forget an entity (despawned); its next version starts from scratch.
  void Forget(uint32_t id);

  // Highest version of `id` the peer acknowledged (0: none).
  uint32_t AckedVersion(uint32_t id) const;

 private:
  struct EntityView {
    uint32_t acked = 0;
    uint32_t sent = 0;
    double sent_at = -1e9;
  };
  struct PacketRecord {
    bool valid = false;
    uint16_t sequence = 0;
    std::vector<std::pair<uint32_t, uint32_t>> entries;  // (id, version)
  };
  std::unordered_map<uint32_t, EntityView> views_;
  std::vector<PacketRecord> records_;
};

}  // namespace edgephys
