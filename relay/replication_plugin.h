// Replication plug-ins: state formats the relay does not carry itself.
//
// The relay's own formats are built in: format 9 (shared delta, the default) and format 2 (the
// previous default, kept decodable for one release; ReplicationConfig::shared_encoding false).
// A plug-in (ReplicationConfig::plugin) replaces them in the rooms of a relay that is given
// one: the benchmark emulations of loadgen/emulation/ (Photon-style, the paper's relay, exact
// floats), which only the load generator, bench/ and tests link. The ClientReplicator keeps
// the schedule (priority classes and send intervals, the bandwidth budget, datagram assembly,
// acknowledgement routing); a stream decides, per receiver, whether an entity is worth sending
// and writes it. Soft bodies always go as format 11.
//
// Thread-safety: a ReplicationPlugin is immutable and shared by every room of a relay (any
// thread); a PluginStream belongs to one receiver and is used on its room's thread only.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string_view>

namespace edgephys {

struct Entity;
struct ReplicationConfig;

// Field bits a stream may be asked to write (Want decides which; the paper's format writes
// only the significant ones).
inline constexpr uint8_t kFieldPosition = 1u << 0;
inline constexpr uint8_t kFieldRotation = 1u << 1;

// One receiver's encoder and acknowledgement state for a plug-in format. Per tick the
// replicator calls Want for every entity due by its class's interval, then Begin, Add for the
// chosen ones (in id order), Finish; OnSent when the payload went out; OnAcked for every
// acknowledged packet the soft-body sender does not claim.
class PluginStream {
 public:
  virtual ~PluginStream() = default;
  // Whether `e` should be sent now (`resend_after_s`: when an unacknowledged copy counts as
  // lost). `fields` comes in with both bits set; a stream may clear some. O(1).
  virtual bool Want(const Entity& e, double now, double resend_after_s, uint8_t* fields) = 0;
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
  virtual std::unique_ptr<PluginStream> NewStream(const ReplicationConfig& config) const = 0;
};

}  // namespace edgephys
