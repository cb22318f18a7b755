/* edgephys C API, reason codes: what REJECTED, ERROR and DISCONNECTED events carry. Part of
 * the manual that starts in edgephys.h. Include edgephys.h; it includes this file.
 */
#ifndef EDGEPHYS_EDGEPHYS_REASONS_H_
#define EDGEPHYS_EDGEPHYS_REASONS_H_

#include "edgephys/edgephys.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- reasons ----------------------------------------------------------------------------- */

/* Every reason code an event's `code` carries, in one table. REJECTED and ERROR events carry a
 * reject reason; DISCONNECTED events a disconnect reason. The two families share numbers, so
 * edgephys_reason_name takes the event type with the code. Numbers are stable (the wire carries
 * them, docs/protocol.md; operators see them in the relay's edgephys_rejected_total).
 *
 *  event               code  name              meaning
 *  REJECTED, ERROR        0  None              (no reason given)
 *                         1  BadToken          the join token's MAC does not match, or it does
 *                                              not parse
 *                         2  ExpiredToken      the join token's expiry has passed
 *                         3  ReplayedToken     the join token was used already
 *                         4  RoomFull          the room has its maximum of players
 *                         5  ServerFull        the relay has its maximum of connections
 *                         6  WrongRoom         the token does not grant the room asked for
 *                         7  NotOwner          a command on an entity this player does not own
 *                         8  UnknownEntity     a command on an entity id the room does not hold
 *                         9  DuplicateEntity   a spawn with an id already in use
 *                        10  InvalidMessage    a message failed verification or carried NaN /
 *                                              out-of-range values
 *                        11  NotJoined         a room command before joining a room
 *                        12  EntityLimit       the player's entity id block is used up
 *                        13  BadCookie         the handshake's cookie did not verify
 *                        14  InvalidContainer  PhyS refused the physics components (detail:
 *                                              why)
 *                        15  GrabRefused       not interactable, not hovered by the hand, or
 *                                              grabbed by another
 *                        16  RateLimited       too many connections, spawns or bytes from this
 *                                              peer
 *                        17  OverBudget        a room or player budget is used up (detail:
 *                                              which)
 *                        18  AuthRequired      packet authentication required but not offered
 *                        19  UnknownPlayer     a message addressed to a player not in the room
 *                        20  NotPermitted      the join token lacks the permission needed (e.g.
 *                                              to send messages)
 *                        21  TakeoverRefused   an ownership request for an entity whose owner
 *                                              does not allow takeover, or PhyS simulates
 *                        22  BadVersion        the relay speaks another handshake version
 *                                              (this SDK is older or newer than the relay)
 *                        23  BadProof          the handshake's proof of the token's session
 *                                              secret failed: a man in the middle, or a
 *                                              client token whose secret part was altered
 *  DISCONNECTED           0  None              the handshake timed out (detail says so)
 *                         1  Timeout           the relay stopped answering
 *                         2  ClientLeft        this client disconnected
 *                         3  ServerShutdown    the relay shut down or an operator drained it
 *                                              (detail: the operator's text)
 *                         4  Kicked            an operator kicked this player or closed its
 *                                              room (detail: the operator's text), the same
 *                                              player connected again, or no room was joined
 *                                              in time
 *                         5  ProtocolError     the relay received something it could not accept
 *                         6  ReliableOverflow  too many reliable bytes were waiting for
 *                                              acknowledgement
 *
 * Every REJECTED, ERROR and DISCONNECTED event's `detail` holds text for a person: the relay's
 * or operator's text when it sent one (an ERROR's detail, a kick's or room close's reason),
 * otherwise the meaning above. */
typedef enum edgephys_reject_reason {
  EDGEPHYS_REJECT_NONE = 0,
  EDGEPHYS_REJECT_BAD_TOKEN = 1,
  EDGEPHYS_REJECT_EXPIRED_TOKEN = 2,
  EDGEPHYS_REJECT_REPLAYED_TOKEN = 3,
  EDGEPHYS_REJECT_ROOM_FULL = 4,
  EDGEPHYS_REJECT_SERVER_FULL = 5,
  EDGEPHYS_REJECT_WRONG_ROOM = 6,
  EDGEPHYS_REJECT_NOT_OWNER = 7,
  EDGEPHYS_REJECT_UNKNOWN_ENTITY = 8,
  EDGEPHYS_REJECT_DUPLICATE_ENTITY = 9,
  EDGEPHYS_REJECT_INVALID_MESSAGE = 10,
  EDGEPHYS_REJECT_NOT_JOINED = 11,
  EDGEPHYS_REJECT_ENTITY_LIMIT = 12,
  EDGEPHYS_REJECT_BAD_COOKIE = 13,
  EDGEPHYS_REJECT_INVALID_CONTAINER = 14,
  EDGEPHYS_REJECT_GRAB_REFUSED = 15,
  EDGEPHYS_REJECT_RATE_LIMITED = 16,
  EDGEPHYS_REJECT_OVER_BUDGET = 17,
  EDGEPHYS_REJECT_AUTH_REQUIRED = 18,
  EDGEPHYS_REJECT_UNKNOWN_PLAYER = 19,
  EDGEPHYS_REJECT_NOT_PERMITTED = 20,
  EDGEPHYS_REJECT_TAKEOVER_REFUSED = 21,
  EDGEPHYS_REJECT_BAD_VERSION = 22,
  EDGEPHYS_REJECT_BAD_PROOF = 23
} edgephys_reject_reason;

typedef enum edgephys_disconnect_reason {
  EDGEPHYS_DISCONNECT_NONE = 0,
  EDGEPHYS_DISCONNECT_TIMEOUT = 1,
  EDGEPHYS_DISCONNECT_CLIENT_LEFT = 2,
  EDGEPHYS_DISCONNECT_SERVER_SHUTDOWN = 3,
  EDGEPHYS_DISCONNECT_KICKED = 4,
  EDGEPHYS_DISCONNECT_PROTOCOL_ERROR = 5,
  EDGEPHYS_DISCONNECT_RELIABLE_OVERFLOW = 6
} edgephys_disconnect_reason;

/* The name in the table above ("BadToken", "Kicked", ...) of `code` as carried by an event of
 * type `event_type` (EDGEPHYS_EVENT_REJECTED or _ERROR: a reject reason; _DISCONNECTED: a
 * disconnect reason). "unknown" for a code outside the table or another event type. Static
 * storage; never NULL. */
EDGEPHYS_API const char* edgephys_reason_name(uint32_t event_type, uint32_t code);

#ifdef __cplusplus
} /* extern "C" */
#endif

#endif /* EDGEPHYS_EDGEPHYS_REASONS_H_ */
