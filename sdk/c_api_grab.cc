// The C API's grab with the hand's pose (edgephys.h, edgephys_client_grab_at) over
// Client::GrabAt.
#include "client/client.h"
#include "edgephys/edgephys.h"
#include "sdk/c_api_client.h"

extern "C" {

edgephys_status edgephys_client_grab_at(edgephys_client* client, uint32_t entity_id,
                                        uint32_t hand_id, const edgephys_transform* hand_pose) {
  using edgephys::capi::SetError;
  if (edgephys_status s = edgephys::capi::CheckHandle(client); s != EDGEPHYS_OK) return s;
  return edgephys::capi::Guarded([&]() -> edgephys_status {
    if (hand_pose == nullptr) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "hand_pose is NULL");
    if (entity_id == 0 || hand_id == 0) {
      return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "entity and hand ids must be non-zero");
    }
    const edgephys_vec3& p = hand_pose->position;
    const edgephys_quat& q = hand_pose->rotation;
    return edgephys::capi::SetStatus(client->client->GrabAt(
        entity_id, hand_id, {p.x, p.y, p.z}, {q.x, q.y, q.z, q.w}));
  });
}

}  // extern "C"
