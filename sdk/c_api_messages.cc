// The C API's application messages (include/edgephys/edgephys_app_state.h, "application
// messages") over Client::SendMessage and the message the last polled event carried.
#include <cstring>
#include <vector>

#include "client/client.h"
#include "edgephys/edgephys.h"
#include "sdk/c_api_client.h"

using edgephys::capi::CheckHandle;
using edgephys::capi::SetError;
using edgephys::capi::SetStatus;

extern "C" {

edgephys_status edgephys_client_get_message(edgephys_client* client, void* buffer,
                                            size_t capacity, size_t* out_size) {
  if (edgephys_status s = CheckHandle(client); s != EDGEPHYS_OK) return s;
  if (out_size == nullptr) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "out_size is NULL");
  if (!client->has_polled_message) {
    return SetError(EDGEPHYS_E_NOT_FOUND, "the event polled last is not a MESSAGE");
  }
  const std::vector<uint8_t>& m = client->polled_message;
  *out_size = m.size();
  if (capacity < m.size()) {
    return SetError(EDGEPHYS_E_BUFFER_TOO_SMALL, "buffer smaller than the message");
  }
  if (!m.empty()) {
    if (buffer == nullptr) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "buffer is NULL");
    std::memcpy(buffer, m.data(), m.size());
  }
  return SetStatus(edgephys::Status::Ok());
}

edgephys_status edgephys_client_send_message(edgephys_client* client, uint32_t target,
                                             uint32_t to_player, const void* data, size_t size) {
  if (edgephys_status s = CheckHandle(client); s != EDGEPHYS_OK) return s;
  return edgephys::capi::Guarded([&]() -> edgephys_status {
    if (data == nullptr && size > 0) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "data is NULL");
    if (target > EDGEPHYS_TO_PLAYER) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "unknown target");
    if (size > EDGEPHYS_MAX_MESSAGE_BYTES) {
      return SetError(EDGEPHYS_E_TOO_LARGE, "message payload over EDGEPHYS_MAX_MESSAGE_BYTES");
    }
    const auto* bytes = static_cast<const uint8_t*>(data);
    return SetStatus(client->client->SendMessage(static_cast<edgephys::MessageTarget>(target),
                                                 to_player, {bytes, size}));
  });
}

}  // extern "C"
