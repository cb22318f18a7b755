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
  edgephys_status Release(uint32_t entity) { return edgephys_client_release(handle_, entity); }

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
  // The payload of the MESSAGE event Poll returned last (edgephys_client_get_message); false
  // if that event was not a MESSAGE.
  bool Message(std::string* out) {
    size_t size = 0;
    if (edgephys_client_get_message(handle_, nullptr, 0, &size) == EDGEPHYS_E_NOT_FOUND) return false;
    out->resize(size);
    return edgephys_client_get_message(handle_, out->data(), out->size(), &size) == EDGEPHYS_OK;
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
  edgephys_client* handle_ = nullptr;
  edgephys_status status_ = EDGEPHYS_OK;
};

}  // namespace edgephys::sdk
