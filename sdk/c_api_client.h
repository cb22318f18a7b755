// The C API's handle (struct edgephys_client): the C++ client, its socket, the event ring its
// listener callbacks fill, the per-entity jitter buffers behind edgephys_client_sample_pose and
// the connection's throughput meter. Internal to sdk/: the public header declares the type
// opaque. Not thread-safe (one thread per client at a time, as the C API says).
#pragma once

#include <cmath>
#include <cstring>
#include <deque>
#include <exception>
#include <new>
#include <string>
#include <span>
#include <memory>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "client/client.h"
#include "client/connection_rates.h"
#include "client/interpolation.h"
#include "client/snapshot_buffer.h"
#include "edgephys/edgephys.h"
#include "edgephys/schema/control_generated.h"
#include "protocol/udp_socket.h"
#include "sdk/c_api_reasons.h"

namespace edgephys::capi {

// Copies `text` into ev->detail, NUL-terminated, cut at a UTF-8 sequence boundary.
inline void CopyDetail(std::string_view text, edgephys_event* ev) {
  size_t n = std::min(text.size(), size_t{EDGEPHYS_EVENT_DETAIL_BYTES - 1});
  // Never cut a UTF-8 sequence: back up over continuation bytes.
  if (n < text.size()) {
    while (n > 0 && (static_cast<unsigned char>(text[n]) & 0xC0) == 0x80) --n;
  }
  std::memcpy(ev->detail, text.data(), n);
  ev->detail[n] = '\0';
}

inline edgephys_transform ToC(const EntityState& s) {
  return {{s.position.x, s.position.y, s.position.z},
          {s.rotation.x, s.rotation.y, s.rotation.z, s.rotation.w}};
}

// Shared with sdk/c_api_properties.cc (defined in c_api.cc): the handle check, and recording
// an outcome in the thread's last-error string.
edgephys_status CheckHandle(const edgephys_client* c);
edgephys_status SetError(edgephys_status code, std::string_view message);
edgephys_status SetStatus(const Status& st);  // Ok, or the error st names

// Runs `body` (returning edgephys_status), turning a C++ exception into EDGEPHYS_E_INTERNAL
// with its message recorded: no exception crosses the C boundary.
template <typename F>
edgephys_status Guarded(F&& body) {
  try {
    return body();
  } catch (const std::bad_alloc&) {
    return SetError(EDGEPHYS_E_INTERNAL, "out of memory");
  } catch (const std::exception& e) {
    return SetError(EDGEPHYS_E_INTERNAL, std::string("internal error: ") + e.what());
  } catch (...) {
    return SetError(EDGEPHYS_E_INTERNAL, "internal error");
  }
}

}  // namespace edgephys::capi

// The handle. Lives in the registry from create to destroy.
struct edgephys_client final : edgephys::ClientListener {
  edgephys_client_config config{};
  std::unique_ptr<edgephys::UdpSocket> socket;
  std::unique_ptr<edgephys::Client> client;
  bool closed = false;
  double last_now = -INFINITY;

  std::vector<edgephys_event> ring;  // fixed capacity
  size_t head = 0, count = 0;
  uint64_t dropped = 0;
  // Payloads of the queued MESSAGE events, oldest first (one per such event in the ring), at
  // most kMaxQueuedMessageBytes in all; the payload of the MESSAGE event polled last.
  static constexpr size_t kMaxQueuedMessageBytes = 16u << 20;
  std::deque<std::vector<uint8_t>> message_payloads;
  size_t message_bytes = 0;
  std::vector<uint8_t> polled_message;
  bool has_polled_message = false;
  // The properties of the queued PROPERTY_CHANGED / _CONFLICT events, oldest first (one per
  // such event in the ring; their string/bytes values count in message_bytes), and the one of
  // the event polled last.
  std::deque<edgephys::PropertyRecord> event_properties;
  edgephys::PropertyRecord polled_property;
  bool has_polled_property = false;
  uint64_t states_received = 0;

  struct Track {
    edgephys::SnapshotBuffer buffer;
    uint32_t last_ms = 0;
    double sender_time_s = 0;
    bool started = false;
  };
  // The joined room's playout, and what new tracks get: room_config held to the application's
  // max_playout_delay_s (CapPlayoutDelay; 0: no limit).
  edgephys::SnapshotBufferConfig room_config;
  edgephys::SnapshotBufferConfig snapshot_config;
  double max_playout_delay_s = 0;
  std::unordered_map<uint32_t, std::unique_ptr<Track>> tracks;

  // Applies max_playout_delay_s to the room's playout, for new tracks and the existing ones.
  void ApplyPlayoutLimit() {
    snapshot_config = edgephys::CapPlayoutDelay(room_config, max_playout_delay_s);
    for (auto& [id, track] : tracks) track->buffer.Reconfigure(snapshot_config);
  }

  // Sampled on every edgephys_client_update while connected; read by get_connection_status.
  edgephys::ConnectionRates rates;
  const edgephys::ConnectionStats* rates_source = nullptr;  // the connection `rates` describes

  edgephys_event* Push(uint32_t type) {
    if (count == ring.size()) {
      ++dropped;
      return nullptr;
    }
    edgephys_event* ev = &ring[(head + count) % ring.size()];
    ++count;
    std::memset(ev, 0, sizeof(*ev));
    ev->type = type;
    return ev;
  }

  void OnConnected(uint32_t player_id) override {
    if (auto* ev = Push(EDGEPHYS_EVENT_CONNECTED)) ev->player_id = player_id;
  }
  void OnRejected(uint16_t reason) override {
    auto* ev = Push(EDGEPHYS_EVENT_REJECTED);
    if (ev == nullptr) return;
    ev->code = reason;
    if (reason == static_cast<uint16_t>(edgephys::schema::RejectReason::AuthRequired)) {
      edgephys::capi::CopyDetail("no packet authentication: the relay's handshake carried no key "
                 "(require_packet_auth)", ev);
    } else {
      edgephys::capi::CopyDetail(edgephys::capi::ReasonText(EDGEPHYS_EVENT_REJECTED, reason), ev);
    }
  }
  // Detail: the relay's text for the end (an operator's kick, room close or drain reason), else
  // the reason's meaning.
  void OnDisconnected(edgephys::DisconnectReason reason) override {
    auto* ev = Push(EDGEPHYS_EVENT_DISCONNECTED);
    if (ev == nullptr) return;
    ev->code = static_cast<uint32_t>(reason);
    const std::string& said = client->disconnect_detail();
    edgephys::capi::CopyDetail(
        said.empty() ? edgephys::capi::ReasonText(EDGEPHYS_EVENT_DISCONNECTED, ev->code)
                     : std::string_view(said),
        ev);
  }
  void OnJoined(std::string_view room, uint32_t entity_id_base) override {
    tracks.clear();
    room_config = edgephys::SnapshotBufferConfig{.capacity = snapshot_config.capacity};
    ApplyPlayoutLimit();
    if (auto* ev = Push(EDGEPHYS_EVENT_JOINED)) {
      ev->player_id = client->player_id();
      ev->entity_id = entity_id_base;
      edgephys::capi::CopyDetail(room, ev);
    }
  }
  void OnPlayerJoined(uint32_t player_id) override {
    if (auto* ev = Push(EDGEPHYS_EVENT_PLAYER_JOINED)) ev->player_id = player_id;
  }
  void OnPlayerLeft(uint32_t player_id) override {
    if (auto* ev = Push(EDGEPHYS_EVENT_PLAYER_LEFT)) ev->player_id = player_id;
  }
  void OnEntitySpawned(const edgephys::RemoteEntity& e) override {
    if (auto* ev = Push(EDGEPHYS_EVENT_SPAWNED)) {
      ev->entity_id = e.id;
      ev->player_id = e.owner;
      ev->parent_id = e.parent;
      ev->flags = e.flags;
      ev->transform = edgephys::capi::ToC(e.state);
    }
  }
  void OnEntityUpdated(const edgephys::RemoteEntity& e) override {
    ++states_received;
    Track* track = nullptr;
    if (auto it = tracks.find(e.id); it != tracks.end()) {
      track = it->second.get();
    } else {
      auto made = std::make_unique<Track>(Track{edgephys::SnapshotBuffer(snapshot_config)});
      track = made.get();
      tracks.emplace(e.id, std::move(made));
    }
    // Unwrap the relay's u32 millisecond clock into monotonic seconds.
    if (!track->started) {
      track->started = true;
      track->sender_time_s = 0;
    } else {
      track->sender_time_s += static_cast<int32_t>(e.state_time_ms - track->last_ms) / 1000.0;
    }
    track->last_ms = e.state_time_ms;
    edgephys::Snapshot snap;
    snap.sender_time_s = track->sender_time_s;
    snap.position = e.state.position;
    snap.rotation = e.state.rotation;
    (void)track->buffer.Insert(snap, last_now);
    if (config.queue_state_events) {
      if (auto* ev = Push(EDGEPHYS_EVENT_STATE)) {
        ev->entity_id = e.id;
        ev->player_id = e.owner;
        ev->code = e.state_time_ms;
        ev->transform = edgephys::capi::ToC(e.state);
      }
    }
  }
  void OnEntityDespawned(uint32_t entity_id) override {
    tracks.erase(entity_id);
    if (auto* ev = Push(EDGEPHYS_EVENT_DESPAWNED)) ev->entity_id = entity_id;
  }
  void OnPhysicsEvent(uint8_t kind, uint32_t a, uint32_t b) override {
    if (kind > 6) return;  // a kind newer than this SDK
    if (auto* ev = Push(EDGEPHYS_EVENT_COLLISION_ENTER + kind)) {
      ev->code = kind;
      ev->entity_id = a;
      ev->other_id = b;
    }
  }
  void OnSoftBodyUpdated(const edgephys::RemoteEntity& e) override {
    if (auto* ev = Push(EDGEPHYS_EVENT_SOFT_BODY)) {
      ev->entity_id = e.id;
      ev->code = static_cast<uint32_t>(e.nodes.size());
    }
  }
  void OnMessage(uint32_t sender, std::span<const uint8_t> payload) override {
    QueueMessage(sender, payload, 0);
  }
  void OnUnreliableMessage(uint32_t sender, std::span<const uint8_t> payload) override {
    QueueMessage(sender, payload, EDGEPHYS_MESSAGE_UNRELIABLE);
  }
  void QueueMessage(uint32_t sender, std::span<const uint8_t> payload, uint32_t flags) {
    if (message_bytes + payload.size() > kMaxQueuedMessageBytes) {
      ++dropped;
      return;
    }
    if (auto* ev = Push(EDGEPHYS_EVENT_MESSAGE)) {
      ev->player_id = sender;
      ev->flags = flags;
      ev->code = static_cast<uint32_t>(payload.size());
      message_payloads.emplace_back(payload.begin(), payload.end());
      message_bytes += payload.size();
    }
  }
  void QueueProperty(uint32_t type, const edgephys::PropertyRecord& p) {
    if (message_bytes + p.value.text.size() > kMaxQueuedMessageBytes) {
      ++dropped;
      return;
    }
    if (auto* ev = Push(type)) {
      ev->entity_id = p.entity_id;
      ev->player_id = p.writer;
      ev->code = p.version;
      ev->other_id = p.request_id;
      ev->flags = static_cast<uint32_t>(p.value.type);
      edgephys::capi::CopyDetail(p.key, ev);
      event_properties.push_back(p);
      message_bytes += p.value.text.size();
    }
  }
  void OnPropertyChanged(const edgephys::PropertyRecord& p) override {
    QueueProperty(EDGEPHYS_EVENT_PROPERTY_CHANGED, p);
  }
  void OnPropertyConflict(const edgephys::PropertyRecord& p) override {
    QueueProperty(EDGEPHYS_EVENT_PROPERTY_CONFLICT, p);
  }
  void OnOwnershipChanged(uint32_t entity_id, uint32_t new_owner, uint32_t seq) override {
    if (auto* ev = Push(EDGEPHYS_EVENT_OWNERSHIP_CHANGED)) {
      ev->entity_id = entity_id;
      ev->player_id = new_owner;
      ev->code = seq;
    }
  }
  void OnError(uint16_t reason, uint32_t entity_id, std::string_view detail) override {
    if (auto* ev = Push(EDGEPHYS_EVENT_ERROR)) {
      ev->code = reason;
      ev->entity_id = entity_id;
      edgephys::capi::CopyDetail(
          detail.empty() ? edgephys::capi::ReasonText(EDGEPHYS_EVENT_ERROR, reason) : detail, ev);
    }
  }
};

