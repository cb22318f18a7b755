// edgephys C++ SDK: a header-only RAII wrapper over the C API (edgephys/edgephys.h), so that a
// C++ engine links only the stable C ABI of libedgephys and needs no Asio, FlatBuffers or
// compiler match. Semantics, units, ownership and threading are the C API's (read that header);
// this adds ownership of the handle and C++ types.
//
//   edgephys::sdk::Client client;                       // check client.ok()
//   client.Connect("127.0.0.1:7777", token, edgephys_now_s());
//   edgephys_event ev;
//   while (client.Poll(&ev)) { ... }
//
// Thread-safety: as edgephys_client (one thread at a time per Client). No exceptions: calls
// return the edgephys_status; Client::LastError() is the message of the last failure on this
// thread.
#pragma once

#include <cstdint>
#include <string>
#include <utility>

#include "edgephys/edgephys.h"

namespace edgephys::sdk {

// The name of an event's reason code ("Kicked", "BadToken", ...; edgephys_reason_name), for
// REJECTED, ERROR and DISCONNECTED events; "unknown" for any other event or code.
inline const char* ReasonName(const edgephys_event& ev) { return edgephys_reason_name(ev.type, ev.code); }

// Property values (edgephys_property_value) from C++ types. String and Bytes point into `text`,
// which must outlive the call they are passed to.
namespace detail {
// A value of `type` whose member `kField` holds `v` (the others zero).
template <auto kField, typename T>
edgephys_property_value TypedValue(uint32_t type, const T& v) {
  edgephys_property_value p{};
  p.type = type;
  p.*kField = v;
  return p;
}
}  // namespace detail
inline edgephys_property_value BoolValue(bool v) {
  return detail::TypedValue<&edgephys_property_value::int_value>(EDGEPHYS_PROPERTY_BOOL,
                                                                 int64_t{v ? 1 : 0});
}
inline edgephys_property_value Int64Value(int64_t v) {
  return detail::TypedValue<&edgephys_property_value::int_value>(EDGEPHYS_PROPERTY_INT64, v);
}
inline edgephys_property_value DoubleValue(double v) {
  return detail::TypedValue<&edgephys_property_value::double_value>(EDGEPHYS_PROPERTY_DOUBLE, v);
}
inline edgephys_property_value Vec3Value(edgephys_vec3 v) {
  return detail::TypedValue<&edgephys_property_value::vec3>(EDGEPHYS_PROPERTY_VEC3, v);
}
inline edgephys_property_value QuatValue(edgephys_quat q) {
  return detail::TypedValue<&edgephys_property_value::quat>(EDGEPHYS_PROPERTY_QUAT, q);
}
inline edgephys_property_value StringValue(const std::string& text, bool bytes = false) {
  edgephys_property_value p{};
  p.type = bytes ? EDGEPHYS_PROPERTY_BYTES : EDGEPHYS_PROPERTY_STRING;
  p.data = text.data();
  p.size = text.size();
  return p;
}

// A property read back: `info` as edgephys_property (its value.data points into `bytes` for
// String and Bytes values).
struct Property {
  edgephys_property info{};
  std::string bytes;
};

class Client {
 public:
  // Creates the client with `config` (nullptr: edgephys_client_config_init defaults).
  explicit Client(const edgephys_client_config* config = nullptr) {
    edgephys_client_config defaults;
    if (config == nullptr) {
      edgephys_client_config_init(&defaults);
      config = &defaults;
    }
    status_ = edgephys_client_create(config, &handle_);
  }
  ~Client() {
    if (handle_ != nullptr) edgephys_client_destroy(handle_);
  }
  Client(Client&& other) noexcept
      : handle_(std::exchange(other.handle_, nullptr)), status_(other.status_) {}
  Client& operator=(Client&& other) noexcept {
    if (this != &other) {
      if (handle_ != nullptr) edgephys_client_destroy(handle_);
      handle_ = std::exchange(other.handle_, nullptr);
      status_ = other.status_;
    }
    return *this;
  }
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  // False if creation failed (create_status() says why).
  bool ok() const { return handle_ != nullptr; }
  edgephys_status create_status() const { return status_; }
  edgephys_client* handle() const { return handle_; }
  static std::string LastError() { return edgephys_last_error(); }

  edgephys_status Connect(const std::string& relay, const std::string& token, double now_s) {
    return edgephys_client_connect(handle_, relay.c_str(), token.c_str(), now_s);
  }
  edgephys_status Update(double now_s) { return edgephys_client_update(handle_, now_s); }
  edgephys_status Join(const std::string& room) { return edgephys_client_join(handle_, room.c_str()); }
  edgephys_status Leave() { return edgephys_client_leave(handle_); }
  edgephys_status Disconnect() { return edgephys_client_disconnect(handle_); }

  // Returns the id, or 0 on failure (LastError() says why).
  uint32_t Spawn(const edgephys_spawn_desc& desc) {
    uint32_t id = 0;
    return edgephys_client_spawn(handle_, &desc, &id) == EDGEPHYS_OK ? id : 0;
  }
  edgephys_status Despawn(uint32_t id) { return edgephys_client_despawn(handle_, id); }
  edgephys_status Publish(uint32_t id, const edgephys_transform& t) {
    return edgephys_client_publish_transform(handle_, id, &t);
  }
  edgephys_status Grab(uint32_t entity, uint32_t hand) { return edgephys_client_grab(handle_, entity, hand); }
  // Grab with the hand's pose now (edgephys_client_grab_at).
  edgephys_status GrabAt(uint32_t entity, uint32_t hand, const edgephys_transform& hand_pose) {
    return edgephys_client_grab_at(handle_, entity, hand, &hand_pose);
  }
  edgephys_status Release(uint32_t entity) { return edgephys_client_release(handle_, entity); }

  // Ownership (edgephys_app_state.h, "ownership"); OWNERSHIP_CHANGED events tell the outcome.
  edgephys_status RequestOwnership(uint32_t entity) {
    return edgephys_client_request_ownership(handle_, entity);
  }
  edgephys_status HandOver(uint32_t entity, uint32_t player) {
    return edgephys_client_hand_over(handle_, entity, player);
  }
  edgephys_status ReleaseOwnership(uint32_t entity) {
    return edgephys_client_release_ownership(handle_, entity);
  }
  edgephys_status Offload(uint32_t entity, const edgephys_vec3& linear, const edgephys_vec3& angular) {
    return edgephys_client_offload(handle_, entity, &linear, &angular);
  }
  edgephys_status SetTakeoverAllowed(uint32_t entity, bool allowed) {
    return edgephys_client_set_takeover_allowed(handle_, entity, allowed ? 1 : 0);
  }
  // choice: EDGEPHYS_OWNER_LEAVE_* (what the relay does with it when its owner leaves).
  edgephys_status SetOwnerLeave(uint32_t entity, uint32_t choice) {
    return edgephys_client_set_owner_leave(handle_, entity, choice);
  }
  // The entity's owner as this client knows it; 0 also when unknown (LastError() says so).
  uint32_t Owner(uint32_t entity) const {
    uint32_t owner = 0;
    return edgephys_client_get_owner(handle_, entity, &owner) == EDGEPHYS_OK ? owner : 0;
  }

  // An application message to the room, the others or one player
  // (edgephys_client_send_message).
  edgephys_status SendMessage(edgephys_message_target target, uint32_t to_player,
                              const void* data, size_t size) {
    return edgephys_client_send_message(handle_, target, to_player, data, size);
  }
  edgephys_status SendMessage(edgephys_message_target target, const std::string& text,
                              uint32_t to_player = 0) {
    return SendMessage(target, to_player, text.data(), text.size());
  }
  // An unreliable message, one datagram (edgephys_client_send_message_unreliable); the
  // receiver's MESSAGE event has EDGEPHYS_MESSAGE_UNRELIABLE in its flags.
  edgephys_status SendMessageUnreliable(edgephys_message_target target, uint32_t to_player,
                                        const void* data, size_t size) {
    return edgephys_client_send_message_unreliable(handle_, target, to_player, data, size);
  }
  edgephys_status SendMessageUnreliable(edgephys_message_target target, const std::string& text,
                                        uint32_t to_player = 0) {
    return SendMessageUnreliable(target, to_player, text.data(), text.size());
  }
  // The payload of the MESSAGE event Poll returned last (edgephys_client_get_message); false
  // if that event was not a MESSAGE.
  bool Message(std::string* out) {
    size_t size = 0;
    if (edgephys_client_get_message(handle_, nullptr, 0, &size) == EDGEPHYS_E_NOT_FOUND) return false;
    out->resize(size);
    return edgephys_client_get_message(handle_, out->data(), out->size(), &size) == EDGEPHYS_OK;
  }

  // Properties (edgephys_client_set_property, _compare_and_set_property): the request id, or 0
  // on failure (LastError() says why).
  uint32_t SetProperty(uint32_t entity_id, const std::string& key,
                       const edgephys_property_value& value,
                       edgephys_property_authority authority = EDGEPHYS_AUTHORITY_OWNER) {
    uint32_t id = 0;
    return edgephys_client_set_property(handle_, entity_id, key.c_str(), &value, authority, &id) ==
                   EDGEPHYS_OK ? id : 0;
  }
  uint32_t CompareAndSetProperty(uint32_t entity_id, const std::string& key,
                                 const edgephys_property_value& value, uint32_t expected_version,
                                 edgephys_property_authority authority = EDGEPHYS_AUTHORITY_OWNER) {
    uint32_t id = 0;
    return edgephys_client_compare_and_set_property(handle_, entity_id, key.c_str(), &value,
                                                    expected_version, authority, &id) == EDGEPHYS_OK
               ? id : 0;
  }
  // The property as this client knows it (edgephys_client_get_property); false if unknown.
  bool GetProperty(uint32_t entity_id, const std::string& key, Property* out) const {
    return ReadProperty(out, [&](edgephys_property* p, void* b, size_t n) {
      return edgephys_client_get_property(handle_, entity_id, key.c_str(), p, b, n);
    });
  }
  // The property of the PROPERTY_CHANGED / _CONFLICT event Poll returned last
  // (edgephys_client_get_event_property); false if that event was another.
  bool EventProperty(Property* out) {
    return ReadProperty(out, [&](edgephys_property* p, void* b, size_t n) {
      return edgephys_client_get_event_property(handle_, p, b, n);
    });
  }

  // The next event into *out; false when none is queued (or on error).
  bool Poll(edgephys_event* out) {
    return edgephys_client_poll_event(handle_, out) == EDGEPHYS_OK && out->type != EDGEPHYS_EVENT_NONE;
  }
  // The latest state of a remote entity; false if unknown.
  bool Entity(uint32_t id, edgephys_entity* out) const {
    return edgephys_client_get_entity(handle_, id, out) == EDGEPHYS_OK;
  }
  bool SamplePose(uint32_t id, double now_s, edgephys_interpolator method, edgephys_transform* out) {
    return edgephys_client_sample_pose(handle_, id, now_s, method, out) == EDGEPHYS_OK;
  }
  // Latency limit for SamplePose (edgephys_client_set_max_playout_delay; 0: none).
  edgephys_status SetMaxPlayoutDelay(double max_delay_s) {
    return edgephys_client_set_max_playout_delay(handle_, max_delay_s);
  }
  // The delay entity `id` is drawn at (seconds); false if no state of it has arrived.
  bool PlayoutDelay(uint32_t id, double* out_s) const {
    return edgephys_client_get_playout_delay(handle_, id, out_s) == EDGEPHYS_OK;
  }
  edgephys_client_info Info() const {
    edgephys_client_info info{};
    info.struct_size = sizeof(info);
    edgephys_client_get_info(handle_, &info);
    return info;
  }
  // The connection's real-time status (rtt, loss, rates, pending reliable bytes); false while
  // there is no connection (see edgephys_client_get_connection_status).
  bool ConnectionStatus(edgephys_connection_status* out) const {
    out->struct_size = sizeof(*out);
    return edgephys_client_get_connection_status(handle_, out) == EDGEPHYS_OK;
  }

 private:
  template <typename Get>
  static bool ReadProperty(Property* out, Get get) {
    out->info = {};
    out->info.struct_size = sizeof(out->info);
    edgephys_status st = get(&out->info, nullptr, 0);
    if (st == EDGEPHYS_E_BUFFER_TOO_SMALL) {
      out->bytes.resize(out->info.value.size);
      st = get(&out->info, out->bytes.data(), out->bytes.size());
    } else {
      out->bytes.clear();
    }
    if (st == EDGEPHYS_OK && out->info.value.data != nullptr) out->info.value.data = out->bytes.data();
    return st == EDGEPHYS_OK;
  }

  edgephys_client* handle_ = nullptr;
  edgephys_status status_ = EDGEPHYS_OK;
};

}  // namespace edgephys::sdk
