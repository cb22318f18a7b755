// edgephys_reason_name and the detail text of REJECTED, ERROR and DISCONNECTED events: one
// table per code family, checked against the wire schema's enums at compile time.
#include "sdk/c_api_reasons.h"

#include <array>

#include "edgephys/edgephys.h"
#include "edgephys/schema/control_generated.h"

namespace edgephys::capi {
namespace {

struct Reason {
  const char* name;
  const char* text;
};

constexpr std::array<Reason, 24> kReject = {{
    {"None", "no reason given"},
    {"BadToken", "the join token's MAC does not match, or it does not parse"},
    {"ExpiredToken", "the join token has expired"},
    {"ReplayedToken", "the join token was used already"},
    {"RoomFull", "the room has its maximum of players"},
    {"ServerFull", "the relay has its maximum of connections"},
    {"WrongRoom", "the join token does not grant this room"},
    {"NotOwner", "the entity is not owned by this player"},
    {"UnknownEntity", "the room holds no entity with this id"},
    {"DuplicateEntity", "an entity with this id exists already"},
    {"InvalidMessage", "the message failed verification or carried out-of-range values"},
    {"NotJoined", "not in a room"},
    {"EntityLimit", "this player's entity id block is used up"},
    {"BadCookie", "the handshake cookie did not verify"},
    {"InvalidContainer", "PhyS refused the physics components"},
    {"GrabRefused", "not interactable, not hovered by the hand, or grabbed by another"},
    {"RateLimited", "too many connections, spawns or bytes from this peer"},
    {"OverBudget", "a room or player budget is used up"},
    {"AuthRequired", "packet authentication is required and was not offered"},
    {"UnknownPlayer", "no player with this id is in the room"},
    {"NotPermitted", "the join token does not grant this"},
    {"TakeoverRefused", "the entity's owner does not allow taking it over"},
    {"BadVersion", "the relay speaks another handshake version (update the SDK or the relay)"},
    {"BadProof", "the relay and this client could not prove the token's session secret to each "
                 "other: a man in the middle, or an altered token"},
}};

constexpr std::array<Reason, 7> kDisconnect = {{
    {"None", "the handshake timed out: no answer from the relay"},
    {"Timeout", "the relay stopped answering"},
    {"ClientLeft", "this client disconnected"},
    {"ServerShutdown", "the relay shut down or was drained"},
    {"Kicked", "removed by the relay: an operator's kick or room close, the same player "
                "connecting again, or no room joined in time"},
    {"ProtocolError", "the relay received something it could not accept"},
    {"ReliableOverflow", "too many reliable bytes were waiting for acknowledgement"},
}};

// The C enums, the wire enums and the tables agree.
static_assert(kReject.size() == static_cast<size_t>(schema::RejectReason::MAX) + 1);
static_assert(kDisconnect.size() == static_cast<size_t>(schema::DisconnectReason::MAX) + 1);
static_assert(EDGEPHYS_REJECT_AUTH_REQUIRED ==
              static_cast<int>(schema::RejectReason::AuthRequired));
static_assert(EDGEPHYS_REJECT_NOT_PERMITTED ==
              static_cast<int>(schema::RejectReason::NotPermitted));
static_assert(EDGEPHYS_REJECT_TAKEOVER_REFUSED ==
              static_cast<int>(schema::RejectReason::TakeoverRefused));
static_assert(EDGEPHYS_REJECT_OVER_BUDGET == static_cast<int>(schema::RejectReason::OverBudget));
static_assert(EDGEPHYS_REJECT_BAD_VERSION == static_cast<int>(schema::RejectReason::BadVersion));
static_assert(EDGEPHYS_REJECT_BAD_PROOF == static_cast<int>(schema::RejectReason::BadProof));
static_assert(EDGEPHYS_DISCONNECT_RELIABLE_OVERFLOW ==
              static_cast<int>(schema::DisconnectReason::ReliableOverflow));
static_assert(EDGEPHYS_DISCONNECT_KICKED == static_cast<int>(schema::DisconnectReason::Kicked));

const Reason* Find(uint32_t event_type, uint32_t code) {
  switch (event_type) {
    case EDGEPHYS_EVENT_REJECTED:
    case EDGEPHYS_EVENT_ERROR:
      return code < kReject.size() ? &kReject[code] : nullptr;
    case EDGEPHYS_EVENT_DISCONNECTED:
      return code < kDisconnect.size() ? &kDisconnect[code] : nullptr;
    default:
      return nullptr;
  }
}

}  // namespace

const char* ReasonName(uint32_t event_type, uint32_t code) {
  const Reason* r = Find(event_type, code);
  return r != nullptr ? r->name : "unknown";
}

std::string_view ReasonText(uint32_t event_type, uint32_t code) {
  const Reason* r = Find(event_type, code);
  return r != nullptr ? r->text : "unknown reason";
}

}  // namespace edgephys::capi

extern "C" const char* edgephys_reason_name(uint32_t event_type, uint32_t code) {
  return edgephys::capi::ReasonName(event_type, code);
}
