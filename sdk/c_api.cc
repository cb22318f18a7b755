// The C API (include/edgephys/edgephys.h) over the C++ client (client/client.h).
//
// Every exported function: checks the handle against the registry of live clients, checks its
// arguments (sdk/c_api_validate.h), calls the C++ client inside a try block, and records the
// outcome in the thread's last-error string. Events reach the caller through a fixed-capacity
// ring filled by the client's listener callbacks.
#include <time.h>

#include <cmath>
#include <cstddef>
#include <cstring>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "client/client.h"
#include "client/interpolation.h"
#include "client/snapshot_buffer.h"
#include "edgephys/schema/control_generated.h"
#include "edgephys/edgephys.h"
#include "protocol/endpoint.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"
#include "sdk/c_api_client.h"
#include "sdk/c_api_validate.h"

#ifndef EDGEPHYS_VERSION_STRING
#define EDGEPHYS_VERSION_STRING "0.0.0"
#endif

using edgephys::Status;
using edgephys::capi::CopyDetail;
using edgephys::capi::Guarded;
using edgephys::capi::ToC;

namespace {

thread_local std::string g_last_error;

edgephys_status Fail(edgephys_status code, std::string_view message) {
  g_last_error.assign(message);
  return code;
}
edgephys_status FailStatus(const Status& st) {
  // StatusCode values 1..11 are edgephys_status values 1..11 (checked below).
  return Fail(static_cast<edgephys_status>(static_cast<int>(st.code())), st.ToString());
}
edgephys_status Ok() {
  g_last_error.clear();
  return EDGEPHYS_OK;
}
static_assert(static_cast<int>(edgephys::StatusCode::kResourceExhausted) == EDGEPHYS_E_RESOURCE_EXHAUSTED);
static_assert(static_cast<int>(edgephys::StatusCode::kNotFound) == EDGEPHYS_E_NOT_FOUND);

}  // namespace

namespace {

// edgephys_client_set_max_playout_delay's upper bound, seconds.
constexpr double kMaxPlayoutDelayLimitS = 4.0;

std::mutex g_registry_mutex;
std::unordered_set<const edgephys_client*>& Registry() {
  static auto* set = new std::unordered_set<const edgephys_client*>();
  return *set;
}

// EDGEPHYS_OK if `c` is a live, open client.
edgephys_status Check(const edgephys_client* c) {
  if (c == nullptr) return Fail(EDGEPHYS_E_INVALID_HANDLE, "client handle is NULL");
  {
    std::lock_guard lock(g_registry_mutex);
    if (Registry().count(c) == 0) {
      return Fail(EDGEPHYS_E_INVALID_HANDLE, "not a live client handle (destroyed or never created)");
    }
  }
  if (c->closed) return Fail(EDGEPHYS_E_CLOSED, "client is closed");
  return EDGEPHYS_OK;
}

#define EDGEPHYS_CHECK(c)                           \
  do {                                              \
    if (edgephys_status s_ = Check(c); s_ != EDGEPHYS_OK) return s_; \
  } while (0)

edgephys_status CheckNow(edgephys_client* c, double now_s) {
  if (!std::isfinite(now_s)) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "now_s must be finite");
  if (now_s < c->last_now) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "now_s went backwards");
  c->last_now = now_s;
  return EDGEPHYS_OK;
}

}  // namespace

namespace edgephys::capi {
edgephys_status CheckHandle(const edgephys_client* c) { return Check(c); }
edgephys_status SetError(edgephys_status code, std::string_view message) {
  return Fail(code, message);
}
edgephys_status SetStatus(const Status& st) { return st.ok() ? Ok() : FailStatus(st); }
}  // namespace edgephys::capi

extern "C" {

uint32_t edgephys_abi_version(void) { return EDGEPHYS_ABI_VERSION; }
const char* edgephys_version_string(void) { return EDGEPHYS_VERSION_STRING; }

const char* edgephys_status_name(int32_t status) {
  switch (status) {
    case EDGEPHYS_OK: return "ok";
    case EDGEPHYS_E_INVALID_HANDLE: return "invalid handle";
    case EDGEPHYS_E_CLOSED: return "closed";
    case EDGEPHYS_E_BUFFER_TOO_SMALL: return "buffer too small";
    case EDGEPHYS_E_INTERNAL: return "internal error";
    default: break;
  }
  if (status > 0 && status <= EDGEPHYS_E_RESOURCE_EXHAUSTED) {
    return edgephys::StatusCodeName(static_cast<edgephys::StatusCode>(status)).data();
  }
  return "unknown";
}

const char* edgephys_last_error(void) { return g_last_error.c_str(); }

double edgephys_now_s(void) {
  timespec ts{};
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

edgephys_status edgephys_spawn_desc_init(edgephys_spawn_desc* desc) {
  if (desc == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "desc is NULL");
  std::memset(desc, 0, sizeof(*desc));
  desc->struct_size = sizeof(*desc);
  desc->transform.rotation.w = 1;
  desc->scale = {1, 1, 1};
  return Ok();
}

edgephys_status edgephys_collider_init(edgephys_collider* c) {
  if (c == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "collider is NULL");
  std::memset(c, 0, sizeof(*c));
  c->shape = EDGEPHYS_SHAPE_BOX;
  c->half_extents = {0.5f, 0.5f, 0.5f};
  c->radius = 0.5f;
  c->height = 1.0f;
  c->local_rotation.w = 1;
  return Ok();
}

edgephys_status edgephys_rigid_body_init(edgephys_rigid_body* b) {
  if (b == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "rigid body is NULL");
  std::memset(b, 0, sizeof(*b));
  b->mass = 1;
  b->friction = 0.5f;
  b->use_gravity = 1;
  return Ok();
}

edgephys_status edgephys_joint_init(edgephys_joint* j) {
  if (j == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "joint is NULL");
  std::memset(j, 0, sizeof(*j));
  j->axis = {0, 0, 1};
  return Ok();
}

edgephys_status edgephys_client_config_init(edgephys_client_config* config) {
  if (config == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "config is NULL");
  std::memset(config, 0, sizeof(*config));
  config->struct_size = sizeof(*config);
  config->publish_rate_hz = 30;
  config->handshake_timeout_s = 5;
  config->event_queue_capacity = 4096;
  config->queue_state_events = 0;
  config->snapshot_capacity = 32;
  config->require_packet_auth = 1;
  return Ok();
}

edgephys_status edgephys_client_create(const edgephys_client_config* config, edgephys_client** out) {
  return Guarded([&]() -> edgephys_status {
    if (config == nullptr || out == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "config or out is NULL");
    const edgephys_client_config& c = *config;
    if (c.struct_size != sizeof(edgephys_client_config)) {
      return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "config.struct_size is not sizeof(edgephys_client_config): call edgephys_client_config_init");
    }
    if (!std::isfinite(c.publish_rate_hz) || c.publish_rate_hz <= 0 || c.publish_rate_hz > 1000) {
      return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "publish_rate_hz must be in (0, 1000]");
    }
    if (!std::isfinite(c.handshake_timeout_s) || c.handshake_timeout_s <= 0 || c.handshake_timeout_s > 600) {
      return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "handshake_timeout_s must be in (0, 600]");
    }
    if (c.event_queue_capacity < 16 || c.event_queue_capacity > (1u << 20)) {
      return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "event_queue_capacity must be 16 .. 1<<20");
    }
    if (c.queue_state_events > 1) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "queue_state_events must be 0 or 1");
    if (c.require_packet_auth > 1) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "require_packet_auth must be 0 or 1");
    if (c.snapshot_capacity < 2 || c.snapshot_capacity > 1024) {
      return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "snapshot_capacity must be 2 .. 1024");
    }
    auto bind = edgephys::ParseEndpoint(c.bind_address ? c.bind_address : "0.0.0.0:0");
    if (!bind.ok()) return Fail(EDGEPHYS_E_MALFORMED, "bind_address: " + bind.status().ToString());
    auto socket = edgephys::UdpSocket::Open(*bind);
    if (!socket.ok()) return Fail(EDGEPHYS_E_IO, "cannot open UDP socket: " + socket.status().ToString());

    auto handle = std::make_unique<edgephys_client>();
    handle->config = c;
    handle->config.bind_address = nullptr;  // not kept past the call
    handle->socket = std::move(*socket);
    handle->ring.resize(c.event_queue_capacity);
    handle->snapshot_config.capacity = c.snapshot_capacity;
    handle->room_config.capacity = c.snapshot_capacity;
    edgephys::ClientConfig cc;
    cc.publish_rate_hz = c.publish_rate_hz;
    cc.handshake_timeout_s = c.handshake_timeout_s;
    cc.require_packet_auth = c.require_packet_auth != 0;
    handle->client = std::make_unique<edgephys::Client>(cc, handle->socket.get(), handle.get());
    {
      std::lock_guard lock(g_registry_mutex);
      Registry().insert(handle.get());
    }
    *out = handle.release();
    return Ok();
  });
}

edgephys_status edgephys_client_destroy(edgephys_client* client) {
  if (client == nullptr) return Fail(EDGEPHYS_E_INVALID_HANDLE, "client handle is NULL");
  {
    std::lock_guard lock(g_registry_mutex);
    if (Registry().erase(client) == 0) {
      return Fail(EDGEPHYS_E_INVALID_HANDLE, "not a live client handle (destroyed or never created)");
    }
  }
  return Guarded([&]() -> edgephys_status {
    if (!client->closed) client->client->Disconnect();
    delete client;
    return Ok();
  });
}

edgephys_status edgephys_client_close(edgephys_client* client) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    client->client->Disconnect();
    client->closed = true;
    client->tracks.clear();
    return Ok();
  });
}

edgephys_status edgephys_client_connect(edgephys_client* client, const char* relay_address,
                                        const char* token, double now_s) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    if (relay_address == nullptr || token == nullptr) {
      return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "relay_address or token is NULL");
    }
    if (client->client->state() != edgephys::ClientState::kIdle) {
      return Fail(EDGEPHYS_E_ALREADY_EXISTS, "connect was already called on this client");
    }
    if (strnlen(token, 4096) >= 4096) return Fail(EDGEPHYS_E_TOO_LARGE, "token longer than 4095 bytes");
    auto server = edgephys::ParseRelayAddress(relay_address);
    if (!server.ok()) return Fail(EDGEPHYS_E_MALFORMED, "relay_address: " + server.status().ToString());
    auto bytes = edgephys::Base64UrlDecode(token);
    if (!bytes.ok() || bytes->empty() || bytes->size() > edgephys::kMaxClientTokenSize) {
      return Fail(EDGEPHYS_E_MALFORMED, "token is not a base64url client token");
    }
    if (edgephys_status s = CheckNow(client, now_s); s != EDGEPHYS_OK) return s;
    Status st = client->client->Connect(*server, *bytes, now_s);
    return st.ok() ? Ok() : FailStatus(st);
  });
}

edgephys_status edgephys_client_update(edgephys_client* client, double now_s) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    if (edgephys_status s = CheckNow(client, now_s); s != EDGEPHYS_OK) return s;
    const edgephys::ClientState before = client->client->state();
    client->client->Update(now_s);
    if (const edgephys::ConnectionStats* stats = client->client->stats()) {
      if (stats != client->rates_source) client->rates.Reset();  // a new connection
      client->rates_source = stats;
      client->rates.Sample(now_s, edgephys::ConnectionRates::From(*stats));
    }
    if (before == edgephys::ClientState::kHandshaking &&
        client->client->state() == edgephys::ClientState::kFailed) {
      // The C++ client has no callback for this; the C API reports it as documented.
      if (edgephys_event* ev = client->Push(EDGEPHYS_EVENT_DISCONNECTED)) {
        CopyDetail("handshake timeout: no answer from the relay", ev);
      }
    }
    return Ok();
  });
}

edgephys_status edgephys_client_join(edgephys_client* client, const char* room) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    if (room == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "room is NULL");
    const size_t n = strnlen(room, edgephys::kMaxRoomNameSize + 1);
    if (n == 0 || n > edgephys::kMaxRoomNameSize) {
      return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "room name must be 1..64 bytes");
    }
    Status st = client->client->JoinRoom(std::string_view(room, n));
    return st.ok() ? Ok() : FailStatus(st);
  });
}

edgephys_status edgephys_client_leave(edgephys_client* client) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    if (!client->client->joined()) return Fail(EDGEPHYS_E_NOT_CONNECTED, "not in a room");
    Status st = client->client->LeaveRoom();
    return st.ok() ? Ok() : FailStatus(st);
  });
}

edgephys_status edgephys_client_disconnect(edgephys_client* client) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    auto state = client->client->state();
    if (state != edgephys::ClientState::kConnected && state != edgephys::ClientState::kHandshaking) {
      return Fail(EDGEPHYS_E_NOT_CONNECTED, "not connected");
    }
    client->client->Disconnect();
    return Ok();
  });
}

edgephys_status edgephys_client_spawn(edgephys_client* client, const edgephys_spawn_desc* desc,
                                      uint32_t* out_id) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    if (desc == nullptr || out_id == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "desc or out_id is NULL");
    edgephys::EntitySpec spec;
    if (Status st = edgephys::capi::ToEntitySpec(*desc, &spec); !st.ok()) return FailStatus(st);
    auto id = client->client->Spawn(spec);
    if (!id.ok()) return FailStatus(id.status());
    *out_id = *id;
    return Ok();
  });
}

edgephys_status edgephys_client_spawn_static(edgephys_client* client,
                                             const edgephys_transform* transform,
                                             const edgephys_collider* colliders,
                                             uint32_t collider_count, const char* name,
                                             uint32_t* out_id) {
  EDGEPHYS_CHECK(client);
  if (transform == nullptr || colliders == nullptr) {
    return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "transform or colliders is NULL");
  }
  if (collider_count == 0) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "scenery needs a collider");
  edgephys_spawn_desc desc;
  edgephys_spawn_desc_init(&desc);
  desc.transform = *transform;
  desc.flags = EDGEPHYS_FLAG_OFFLOADED | EDGEPHYS_FLAG_PERSISTENT;
  desc.name = name;
  desc.colliders = colliders;
  desc.collider_count = collider_count;
  return edgephys_client_spawn(client, &desc, out_id);
}

edgephys_status edgephys_client_despawn(edgephys_client* client, uint32_t entity_id) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    if (!client->client->joined()) return Fail(EDGEPHYS_E_NOT_CONNECTED, "not in a room");
    Status st = client->client->Despawn(entity_id);
    return st.ok() ? Ok() : FailStatus(st);
  });
}

edgephys_status edgephys_client_publish_transform(edgephys_client* client, uint32_t entity_id,
                                                  const edgephys_transform* t) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    if (t == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "transform is NULL");
    if (Status st = edgephys::capi::CheckTransform(*t, "bad transform"); !st.ok()) return FailStatus(st);
    if (!client->client->joined()) return Fail(EDGEPHYS_E_NOT_CONNECTED, "not in a room");
    Status st = client->client->PublishTransform(
        entity_id, {t->position.x, t->position.y, t->position.z},
        {t->rotation.x, t->rotation.y, t->rotation.z, t->rotation.w});
    return st.ok() ? Ok() : FailStatus(st);
  });
}

edgephys_status edgephys_client_grab(edgephys_client* client, uint32_t entity_id, uint32_t hand_id) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    if (entity_id == 0 || hand_id == 0) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "entity and hand ids must be non-zero");
    if (!client->client->joined()) return Fail(EDGEPHYS_E_NOT_CONNECTED, "not in a room");
    Status st = client->client->Grab(entity_id, hand_id);
    return st.ok() ? Ok() : FailStatus(st);
  });
}

edgephys_status edgephys_client_release(edgephys_client* client, uint32_t entity_id) {
  EDGEPHYS_CHECK(client);
  return Guarded([&]() -> edgephys_status {
    if (entity_id == 0) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "entity id must be non-zero");
    if (!client->client->joined()) return Fail(EDGEPHYS_E_NOT_CONNECTED, "not in a room");
    Status st = client->client->Release(entity_id);
    return st.ok() ? Ok() : FailStatus(st);
  });
}

edgephys_status edgephys_client_poll_event(edgephys_client* client, edgephys_event* out) {
  EDGEPHYS_CHECK(client);
  if (out == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "out is NULL");
  client->has_polled_message = false;
  client->has_polled_property = false;
  if (client->count == 0) {
    std::memset(out, 0, sizeof(*out));
    out->type = EDGEPHYS_EVENT_NONE;
    return Ok();
  }
  *out = client->ring[client->head];
  client->head = (client->head + 1) % client->ring.size();
  --client->count;
  client->has_polled_message = out->type == EDGEPHYS_EVENT_MESSAGE;
  if (client->has_polled_message) {
    client->polled_message = std::move(client->message_payloads.front());
    client->message_payloads.pop_front();
    client->message_bytes -= client->polled_message.size();
  }
  client->has_polled_property = out->type == EDGEPHYS_EVENT_PROPERTY_CHANGED ||
                                out->type == EDGEPHYS_EVENT_PROPERTY_CONFLICT;
  if (client->has_polled_property) {
    client->polled_property = std::move(client->event_properties.front());
    client->event_properties.pop_front();
    client->message_bytes -= client->polled_property.value.text.size();
  }
  return Ok();
}

edgephys_status edgephys_client_get_state_format(edgephys_client* client, uint32_t* out) {
  EDGEPHYS_CHECK(client);
  if (out == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "out is NULL");
  *out = client->client->state_format();
  if (*out == 0) return Fail(EDGEPHYS_E_NOT_FOUND, "no room joined yet");
  return Ok();
}

edgephys_status edgephys_client_get_info(edgephys_client* client, edgephys_client_info* out) {
  EDGEPHYS_CHECK(client);
  if (out == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "out is NULL");
  // Callers built before state_payloads_refused pass the size that ended at state_bytes_received.
  constexpr uint32_t kWithoutRefused = offsetof(edgephys_client_info, state_payloads_refused);
  if (out->struct_size != sizeof(edgephys_client_info) && out->struct_size != kWithoutRefused) {
    return Fail(EDGEPHYS_E_INVALID_ARGUMENT,
                "out->struct_size is neither sizeof(edgephys_client_info) nor " +
                    std::to_string(kWithoutRefused) + " (the size before state_payloads_refused)");
  }
  const edgephys::Client& c = *client->client;
  out->state = static_cast<uint32_t>(c.state());
  out->joined = c.joined() ? 1 : 0;
  out->player_id = c.player_id();
  out->entity_id_base = c.entity_id_base();
  out->entity_count = static_cast<uint32_t>(c.entities().size());
  out->reject_reason = c.reject_reason();
  out->disconnect_reason = static_cast<uint32_t>(c.disconnect_reason());
  out->dropped_events = client->dropped;
  out->states_received = client->states_received;
  out->state_bytes_received = c.state_bytes_received();
  if (out->struct_size == sizeof(edgephys_client_info)) {
    out->state_payloads_refused = c.state_payloads_refused();
  }
  return Ok();
}

edgephys_status edgephys_client_get_connection_status(edgephys_client* client,
                                                     edgephys_connection_status* out) {
  EDGEPHYS_CHECK(client);
  if (out == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "out is NULL");
  if (out->struct_size != sizeof(edgephys_connection_status)) {
    return Fail(EDGEPHYS_E_INVALID_ARGUMENT,
                "out->struct_size is not sizeof(edgephys_connection_status)");
  }
  const edgephys::ConnectionStats* stats = client->client->stats();
  if (stats == nullptr) {
    return Fail(EDGEPHYS_E_NOT_CONNECTED, "no connection yet (the handshake has not completed)");
  }
  const edgephys::ConnectionRates::Rates rates = client->rates.Get();
  out->state = static_cast<uint32_t>(client->client->state());
  out->reserved = 0;
  out->rtt_s = stats->rtt_s;
  out->rtt_var_s = stats->rtt_var_s;
  out->loss = stats->loss;
  out->send_bytes_per_s = rates.send_bytes_per_s;
  out->receive_bytes_per_s = rates.receive_bytes_per_s;
  out->send_packets_per_s = rates.send_packets_per_s;
  out->receive_packets_per_s = rates.receive_packets_per_s;
  out->packets_sent = stats->packets_sent;
  out->packets_received = stats->packets_received;
  out->bytes_sent = stats->bytes_sent;
  out->bytes_received = stats->bytes_received;
  out->reliable_resends = stats->reliable_resends;
  out->reliable_delivered = stats->reliable_delivered;
  out->stale_dropped = stats->stale_dropped;
  out->duplicates_dropped = stats->duplicates_dropped;
  out->pending_reliable_bytes = stats->pending_reliable_bytes;
  return Ok();
}

edgephys_status edgephys_client_get_entity(edgephys_client* client, uint32_t entity_id,
                                           edgephys_entity* out) {
  EDGEPHYS_CHECK(client);
  if (out == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "out is NULL");
  const edgephys::RemoteEntity* e = client->client->FindEntity(entity_id);
  if (e == nullptr) return Fail(EDGEPHYS_E_NOT_FOUND, "unknown entity");
  out->id = e->id;
  out->owner = e->owner;
  out->parent_id = e->parent;
  out->flags = e->flags;
  out->has_state = e->has_state ? 1 : 0;
  out->state_time_ms = e->state_time_ms;
  out->soft_body_particles = static_cast<uint32_t>(e->nodes.size());
  out->reserved = 0;
  out->transform = ToC(e->state);
  return Ok();
}

edgephys_status edgephys_client_list_entities(edgephys_client* client, uint32_t* ids,
                                              size_t capacity, size_t* count) {
  EDGEPHYS_CHECK(client);
  if (count == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "count is NULL");
  if (ids == nullptr && capacity > 0) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "ids is NULL with a non-zero capacity");
  const auto& entities = client->client->entities();
  *count = entities.size();
  if (entities.size() > capacity) return Fail(EDGEPHYS_E_BUFFER_TOO_SMALL, "more entities than capacity");
  size_t i = 0;
  for (const auto& [id, e] : entities) ids[i++] = id;
  return Ok();
}

edgephys_status edgephys_client_get_soft_body(edgephys_client* client, uint32_t entity_id,
                                              edgephys_vec3* out, size_t capacity, size_t* count) {
  EDGEPHYS_CHECK(client);
  if (count == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "count is NULL");
  if (out == nullptr && capacity > 0) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "out is NULL with a non-zero capacity");
  const edgephys::RemoteEntity* e = client->client->FindEntity(entity_id);
  if (e == nullptr) return Fail(EDGEPHYS_E_NOT_FOUND, "unknown entity");
  *count = e->nodes.size();
  if (e->nodes.size() > capacity) return Fail(EDGEPHYS_E_BUFFER_TOO_SMALL, "more particles than capacity");
  for (size_t i = 0; i < e->nodes.size(); ++i) out[i] = {e->nodes[i].x, e->nodes[i].y, e->nodes[i].z};
  return Ok();
}

edgephys_status edgephys_client_sample_pose(edgephys_client* client, uint32_t entity_id, double now_s,
                                            uint32_t method, edgephys_transform* out) {
  EDGEPHYS_CHECK(client);
  if (out == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "out is NULL");
  if (method > EDGEPHYS_INTERP_AUTO) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "method out of range");
  if (!std::isfinite(now_s)) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "now_s must be finite");
  auto it = client->tracks.find(entity_id);
  if (it == client->tracks.end() || it->second->buffer.empty()) {
    return Fail(EDGEPHYS_E_NOT_FOUND, "no state of that entity has arrived");
  }
  edgephys::SnapshotBuffer& buffer = it->second->buffer;
  const edgephys::Interpolator how = method == EDGEPHYS_INTERP_AUTO
                                         ? edgephys::Interpolator::kHermite
                                         : static_cast<edgephys::Interpolator>(method);
  const edgephys::Pose pose = edgephys::Sample(buffer, buffer.RenderTime(now_s), how);
  *out = {{pose.position.x, pose.position.y, pose.position.z},
          {pose.rotation.x, pose.rotation.y, pose.rotation.z, pose.rotation.w}};
  return Ok();
}

edgephys_status edgephys_client_set_max_playout_delay(edgephys_client* client, double max_delay_s) {
  EDGEPHYS_CHECK(client);
  if (!std::isfinite(max_delay_s) || max_delay_s < 0 || max_delay_s > kMaxPlayoutDelayLimitS) {
    return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "max_delay_s must be 0 (no limit) or in (0, 4] seconds");
  }
  client->max_playout_delay_s = max_delay_s;
  client->ApplyPlayoutLimit();
  return Ok();
}

edgephys_status edgephys_client_get_playout_delay(edgephys_client* client, uint32_t entity_id,
                                                  double* out_s) {
  EDGEPHYS_CHECK(client);
  if (out_s == nullptr) return Fail(EDGEPHYS_E_INVALID_ARGUMENT, "out_s is NULL");
  *out_s = 0;
  auto it = client->tracks.find(entity_id);
  if (it == client->tracks.end() || it->second->buffer.empty()) {
    return Fail(EDGEPHYS_E_NOT_FOUND, "no state of that entity has arrived");
  }
  const edgephys::SnapshotBuffer& buffer = it->second->buffer;
  // Before the first sample_pose the playout clock has not started: report where it will start.
  *out_s = buffer.current_delay_s() > 0 ? buffer.current_delay_s() : buffer.target_delay_s();
  return Ok();
}

}  // extern "C"
