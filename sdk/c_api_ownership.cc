// The C API's ownership calls (include/edgephys/edgephys_app_state.h, "ownership") over
// Client::RequestOwnership, HandOver, ReleaseOwnership, SetTakeoverAllowed and OwnerOf.
#include <new>
#include <string>

#include "client/client.h"
#include "edgephys/edgephys.h"
#include "sdk/c_api_client.h"

using edgephys::capi::CheckHandle;
using edgephys::capi::SetError;
using edgephys::capi::SetStatus;

namespace {

template <typename F>
edgephys_status Call(edgephys_client* client, uint32_t entity_id, F&& body) {
  if (edgephys_status s = CheckHandle(client); s != EDGEPHYS_OK) return s;
  return edgephys::capi::Guarded([&]() -> edgephys_status {
    if (entity_id == 0) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "entity id must be non-zero");
    return SetStatus(body(*client->client));
  });
}

}  // namespace

extern "C" {

edgephys_status edgephys_client_request_ownership(edgephys_client* client, uint32_t entity_id) {
  return Call(client, entity_id, [&](edgephys::Client& c) { return c.RequestOwnership(entity_id); });
}

edgephys_status edgephys_client_hand_over(edgephys_client* client, uint32_t entity_id,
                                          uint32_t player_id) {
  return Call(client, entity_id,
              [&](edgephys::Client& c) { return c.HandOver(entity_id, player_id); });
}

edgephys_status edgephys_client_release_ownership(edgephys_client* client, uint32_t entity_id) {
  return Call(client, entity_id, [&](edgephys::Client& c) { return c.ReleaseOwnership(entity_id); });
}

edgephys_status edgephys_client_offload(edgephys_client* client, uint32_t entity_id,
                                        const edgephys_vec3* linear, const edgephys_vec3* angular) {
  return Call(client, entity_id, [&](edgephys::Client& c) {
    const edgephys::Vec3f lin = linear ? edgephys::Vec3f{linear->x, linear->y, linear->z}
                                       : edgephys::Vec3f{};
    const edgephys::Vec3f ang = angular ? edgephys::Vec3f{angular->x, angular->y, angular->z}
                                        : edgephys::Vec3f{};
    return c.ReleaseOwnership(entity_id, lin, ang);
  });
}

edgephys_status edgephys_client_get_owned_motion(edgephys_client* client, uint32_t entity_id,
                                                 edgephys_transform* out_pose,
                                                 edgephys_vec3* out_linear,
                                                 edgephys_vec3* out_angular) {
  return Call(client, entity_id, [&](edgephys::Client& c) {
    edgephys::EntityState state;
    edgephys::Vec3f lin, ang;
    edgephys::Status st = c.OwnedMotion(entity_id, &state, &lin, &ang);
    if (!st.ok()) return st;
    if (out_pose != nullptr) *out_pose = edgephys::capi::ToC(state);
    if (out_linear != nullptr) *out_linear = {lin.x, lin.y, lin.z};
    if (out_angular != nullptr) *out_angular = {ang.x, ang.y, ang.z};
    return edgephys::Status::Ok();
  });
}

edgephys_status edgephys_client_set_takeover_allowed(edgephys_client* client, uint32_t entity_id,
                                                     uint32_t allowed) {
  return Call(client, entity_id, [&](edgephys::Client& c) {
    if (allowed > 1) return edgephys::Status::InvalidArgument("allowed must be 0 or 1");
    return c.SetTakeoverAllowed(entity_id, allowed == 1);
  });
}

edgephys_status edgephys_client_get_owner(edgephys_client* client, uint32_t entity_id,
                                          uint32_t* out_owner) {
  return Call(client, entity_id, [&](edgephys::Client& c) {
    if (out_owner == nullptr) return edgephys::Status::InvalidArgument("out_owner is NULL");
    if (!c.Owns(entity_id) && c.FindEntity(entity_id) == nullptr) {
      return edgephys::Status::NotFound("no such entity known");
    }
    *out_owner = c.OwnerOf(entity_id);
    return edgephys::Status::Ok();
  });
}

}  // extern "C"
