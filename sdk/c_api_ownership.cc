// The C API's ownership calls (include/edgephys/edgephys.h, "ownership") over
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
  try {
    if (entity_id == 0) return SetError(EDGEPHYS_E_INVALID_ARGUMENT, "entity id must be non-zero");
    return SetStatus(body(*client->client));
  } catch (const std::bad_alloc&) {
    return SetError(EDGEPHYS_E_INTERNAL, "out of memory");
  } catch (const std::exception& e) {
    return SetError(EDGEPHYS_E_INTERNAL, std::string("internal error: ") + e.what());
  } catch (...) {
    return SetError(EDGEPHYS_E_INTERNAL, "internal error");
  }
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
