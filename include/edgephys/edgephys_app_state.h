/* edgephys C API, application state: messages, shared properties and ownership. Part of the
 * manual that starts in edgephys.h (its conventions hold here: status codes, units, threading,
 * ownership of memory). Include edgephys.h; it includes this file.
 */
#ifndef EDGEPHYS_EDGEPHYS_APP_STATE_H_
#define EDGEPHYS_EDGEPHYS_APP_STATE_H_

#include "edgephys/edgephys.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- application messages ---------------------------------------------------------------- */

/* Whom a message is for. */
typedef enum edgephys_message_target {
  EDGEPHYS_TO_ROOM = 0,    /* every member of the room, the sender included */
  EDGEPHYS_TO_OTHERS = 1,  /* every member but the sender */
  EDGEPHYS_TO_PLAYER = 2   /* the member `to_player` only */
} edgephys_message_target;

/* Largest message payload (bytes). A room's budget may allow less (then ERROR OverBudget). */
#define EDGEPHYS_MAX_MESSAGE_BYTES 65536u

/* Sends `size` bytes of `data` (copied; opaque to edgephys; size 0 allowed) to `target`
 * (`to_player` with EDGEPHYS_TO_PLAYER, else ignored) on the reliable channel: the relay
 * delivers it once to each addressed member, in the order this client sent its messages, as
 * EDGEPHYS_EVENT_MESSAGE with this player's id; large payloads are fragmented and
 * reassembled. Needs the join token's message permission (the default). The relay refuses a
 * message with EDGEPHYS_EVENT_ERROR and counts it: NotPermitted (20), OverBudget (17, larger
 * than the room allows), RateLimited (16, the player's or the room's message or byte rate,
 * RoomBudgets in relay/room_budget.h), UnknownPlayer (19, `to_player` not in the room).
 * EDGEPHYS_E_NOT_CONNECTED before EDGEPHYS_EVENT_JOINED; EDGEPHYS_E_TOO_LARGE over
 * EDGEPHYS_MAX_MESSAGE_BYTES; EDGEPHYS_E_INVALID_ARGUMENT for an unknown target, a
 * EDGEPHYS_TO_PLAYER target of 0, or NULL data with a size; EDGEPHYS_E_RESOURCE_EXHAUSTED
 * when the reliable queue is full (send less). */
EDGEPHYS_API edgephys_status edgephys_client_send_message(edgephys_client* client,
                                                          uint32_t target, uint32_t to_player,
                                                          const void* data, size_t size);
/* Copies the payload of the EDGEPHYS_EVENT_MESSAGE that edgephys_client_poll_event returned
 * last into `buffer` (`capacity` bytes) and sets *out_size to its size (also when the buffer is
 * too small: EDGEPHYS_E_BUFFER_TOO_SMALL, nothing copied; the event's `code` holds the size as
 * well). EDGEPHYS_E_NOT_FOUND when the last edgephys_client_poll_event call did not return a
 * MESSAGE (an empty poll included): read the payload right after polling its event. */
EDGEPHYS_API edgephys_status edgephys_client_get_message(edgephys_client* client, void* buffer,
                                                         size_t capacity, size_t* out_size);

/* ---- properties --------------------------------------------------------------------------- */

/* Shared state of the room: properties, each a key (1..64 bytes, no NUL) of the room
 * (entity_id 0) or of one entity, with a typed value, a version (1 on creation, +1 per accepted
 * write) and an authority (who may write it). The relay holds them: every member, and every
 * player who joins later, is told each property (EDGEPHYS_EVENT_PROPERTY_CHANGED), reliably
 * and in the order the relay accepted the writes; they survive a relay failover in a cluster.
 * An entity's properties go when it is despawned (no event for them: the DESPAWNED event says
 * it). docs/protocol.md, "Properties". */
typedef enum edgephys_property_type {
  EDGEPHYS_PROPERTY_NONE = 0,    /* no value (a conflict on a property that does not exist) */
  EDGEPHYS_PROPERTY_BOOL = 1,    /* int_value 0 or 1 */
  EDGEPHYS_PROPERTY_INT64 = 2,   /* int_value */
  EDGEPHYS_PROPERTY_DOUBLE = 3,  /* double_value, finite */
  EDGEPHYS_PROPERTY_STRING = 4,  /* data, size: UTF-8 (no terminating NUL counted) */
  EDGEPHYS_PROPERTY_BYTES = 5,   /* data, size */
  EDGEPHYS_PROPERTY_VEC3 = 6,    /* vec3, finite */
  EDGEPHYS_PROPERTY_QUAT = 7     /* quat, finite (not normalised by edgephys) */
} edgephys_property_type;

/* Who may write a property; fixed when the property is created. */
typedef enum edgephys_property_authority {
  EDGEPHYS_AUTHORITY_OWNER = 0,  /* the entity's owner (or the creator of an entity the room or
                                    PhyS owns); for a room property, the player who created it */
  EDGEPHYS_AUTHORITY_ANYONE = 1  /* any member of the room */
} edgephys_property_authority;

#define EDGEPHYS_MAX_PROPERTY_KEY_BYTES 64u
/* Largest string/bytes value the protocol carries; a room's budget allows less by default
 * (16 KiB; then ERROR OverBudget "property_value_bytes"). */
#define EDGEPHYS_MAX_PROPERTY_VALUE_BYTES 65536u

/* A typed value. Fields the type does not use are ignored on input and 0 on output. */
typedef struct edgephys_property_value {
  uint32_t type;         /* edgephys_property_type */
  uint32_t reserved;     /* 0 */
  int64_t int_value;     /* BOOL, INT64 */
  double double_value;   /* DOUBLE */
  edgephys_vec3 vec3;    /* VEC3 */
  edgephys_quat quat;    /* QUAT */
  const void* data;      /* STRING, BYTES: `size` bytes (copied when writing; when reading,
                            points into the caller's buffer) */
  size_t size;
} edgephys_property_value;

/* A property as the relay last announced it. */
typedef struct edgephys_property {
  uint32_t struct_size;  /* set to sizeof(edgephys_property) before the call */
  uint32_t entity_id;    /* 0: a room property */
  uint32_t version;      /* 0: the property does not exist (a conflict's current state) */
  uint32_t writer;       /* the player whose write this value is */
  uint32_t owner;        /* room properties: the creator; entity properties: 0 */
  uint32_t authority;    /* edgephys_property_authority */
  uint32_t request_id;   /* the write's request id (the writer's out_request_id) */
  uint32_t reserved;
  edgephys_property_value value;
} edgephys_property;

/* Writes `*value` under `key` (NUL-terminated, 1..64 bytes) of the room (`entity_id` 0) or of
 * an entity. The relay stores it and every member, this client included, gets
 * EDGEPHYS_EVENT_PROPERTY_CHANGED with the new version and this player as the writer.
 * `authority` (edgephys_property_authority) applies when the write creates the property;
 * later writes keep the property's. *out_request_id (may be NULL) receives the request id the
 * events of this write carry. The relay refuses a write with EDGEPHYS_EVENT_ERROR (detail
 * names the property) and counts it: NotPermitted (20, the join token lacks the property
 * permission), RateLimited (16, over the player's write rate), NotOwner (7, an owner-only
 * property of another, or an owner-only property created on another's entity), UnknownEntity
 * (8), OverBudget (17, detail "over budget: room_properties", "room_property_bytes" or
 * "property_value_bytes"), InvalidMessage (10). Errors here: EDGEPHYS_E_NOT_CONNECTED before
 * EDGEPHYS_EVENT_JOINED; EDGEPHYS_E_INVALID_ARGUMENT for a NULL, empty or over-long key, an
 * unknown type or authority, a NaN or infinite double/vec3/quat, a bool other than 0/1, NULL
 * data with a size; EDGEPHYS_E_TOO_LARGE for string/bytes over
 * EDGEPHYS_MAX_PROPERTY_VALUE_BYTES; EDGEPHYS_E_NOT_FOUND for an entity this client does not
 * know; EDGEPHYS_E_RESOURCE_EXHAUSTED when the reliable queue is full. */
EDGEPHYS_API edgephys_status edgephys_client_set_property(edgephys_client* client,
                                                          uint32_t entity_id, const char* key,
                                                          const edgephys_property_value* value,
                                                          uint32_t authority,
                                                          uint32_t* out_request_id);
/* As edgephys_client_set_property, but the relay applies the write only if the property's
 * version is `expected_version` (0: only if it does not exist yet). Otherwise this client gets
 * EDGEPHYS_EVENT_PROPERTY_CONFLICT carrying the request id and the property's current value
 * and version (read it with edgephys_client_get_event_property). Of several writers expecting
 * the same version exactly one wins. */
EDGEPHYS_API edgephys_status edgephys_client_compare_and_set_property(
    edgephys_client* client, uint32_t entity_id, const char* key,
    const edgephys_property_value* value, uint32_t expected_version, uint32_t authority,
    uint32_t* out_request_id);
/* Copies the property (entity_id, key) as this client last heard of it into *out; a STRING or
 * BYTES value's bytes go to `buffer` (`capacity` bytes; out->value.data points there) and
 * out->value.size holds their length (also when EDGEPHYS_E_BUFFER_TOO_SMALL, nothing else
 * copied then). EDGEPHYS_E_NOT_FOUND when this client knows no such property;
 * EDGEPHYS_E_INVALID_ARGUMENT for a NULL key or out, or a wrong out->struct_size. */
EDGEPHYS_API edgephys_status edgephys_client_get_property(edgephys_client* client,
                                                          uint32_t entity_id, const char* key,
                                                          edgephys_property* out, void* buffer,
                                                          size_t capacity);
/* As edgephys_client_get_property, for the property the EDGEPHYS_EVENT_PROPERTY_CHANGED or
 * _PROPERTY_CONFLICT event that edgephys_client_poll_event returned last carries (the value at
 * that event, not a later one; its key is the event's detail). EDGEPHYS_E_NOT_FOUND when the
 * last poll returned another event (an empty poll included). */
EDGEPHYS_API edgephys_status edgephys_client_get_event_property(edgephys_client* client,
                                                                edgephys_property* out,
                                                                void* buffer, size_t capacity);

/* ---- ownership ---------------------------------------------------------------------------
 * Every entity has one owner whose transforms the relay accepts: a player, or the room (0).
 * A change takes effect when the relay announces it with EDGEPHYS_EVENT_OWNERSHIP_CHANGED (to
 * every member, this client included): from then on the new owner publishes the entity
 * (edgephys_client_publish_transform) and the old one gets NOT_FOUND doing so; states the old
 * owner sent after the change are dropped by the relay and counted
 * (edgephys_stale_owner_states_total). The relay refuses a request with EDGEPHYS_EVENT_ERROR:
 * TakeoverRefused (21: the owner forbids takeover, or PhyS simulates the entity), NotOwner (7),
 * UnknownEntity (8), UnknownPlayer (19), NotPermitted (20: a join token without the spawn
 * permission, this player's or the receiver's), RateLimited (16). Each call: EDGEPHYS_E_INVALID_ARGUMENT
 * for entity id 0; EDGEPHYS_E_NOT_CONNECTED before EDGEPHYS_EVENT_JOINED;
 * EDGEPHYS_E_RESOURCE_EXHAUSTED when the reliable queue is full. */

/* Asks for an entity this client knows: granted at once when the room owns it or its owner
 * allows takeover. EDGEPHYS_E_NOT_FOUND for an entity this client does not know. */
EDGEPHYS_API edgephys_status edgephys_client_request_ownership(edgephys_client* client,
                                                               uint32_t entity_id);
/* Gives an entity this client owns to `player_id`, a member of the room. EDGEPHYS_E_NOT_FOUND
 * if not owned; EDGEPHYS_E_INVALID_ARGUMENT for player 0 or this player. */
EDGEPHYS_API edgephys_status edgephys_client_hand_over(edgephys_client* client, uint32_t entity_id,
                                                       uint32_t player_id);
/* Gives an entity this client owns to the room (owner 0; it stays when this player leaves). A
 * dynamic body this client simulates locally (spawned without EDGEPHYS_FLAG_OFFLOADED) is handed
 * to PhyS at its last published pose, at rest, without a despawn. EDGEPHYS_E_NOT_FOUND if not
 * owned. */
EDGEPHYS_API edgephys_status edgephys_client_release_ownership(edgephys_client* client,
                                                               uint32_t entity_id);
/* As edgephys_client_release_ownership, for a body this client simulates locally: PhyS carries
 * on from its last published pose with these velocities (m/s and rad/s, room frame; NULL: 0).
 * EDGEPHYS_E_INVALID_ARGUMENT for a non-finite one. */
EDGEPHYS_API edgephys_status edgephys_client_offload(edgephys_client* client, uint32_t entity_id,
                                                     const edgephys_vec3* linear,
                                                     const edgephys_vec3* angular);
/* An entity this client owns: its pose as last published or, just gained from PhyS (a request
 * reclaims a PhyS-simulated body), PhyS's pose and velocities at the change, where this
 * client's physics carries on (velocities 0 otherwise). NULL outputs are skipped.
 * EDGEPHYS_E_NOT_FOUND if not owned. */
EDGEPHYS_API edgephys_status edgephys_client_get_owned_motion(edgephys_client* client,
                                                              uint32_t entity_id,
                                                              edgephys_transform* out_pose,
                                                              edgephys_vec3* out_linear,
                                                              edgephys_vec3* out_angular);
/* Lets others take an entity this client owns by request (allowed 1) or not (0, the default);
 * the setting stays with the entity across owners. EDGEPHYS_E_NOT_FOUND if not owned. */
EDGEPHYS_API edgephys_status edgephys_client_set_takeover_allowed(edgephys_client* client,
                                                                  uint32_t entity_id,
                                                                  uint32_t allowed);
/* The entity's owner as this client knows it (this player's id for its own). EDGEPHYS_E_NOT_FOUND
 * for an entity it does not know; EDGEPHYS_E_INVALID_ARGUMENT for a NULL out_owner. */
EDGEPHYS_API edgephys_status edgephys_client_get_owner(edgephys_client* client, uint32_t entity_id,
                                                       uint32_t* out_owner);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* EDGEPHYS_EDGEPHYS_APP_STATE_H_ */
