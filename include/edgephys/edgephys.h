/* edgephys C API: the client SDK ("GHost" side) as a flat C interface, for engines and
 * languages that cannot use C++ (C, C# P/Invoke, Python ctypes, Unreal/Godot plugins).
 * This header is the manual, with its two parts that it includes: edgephys_reasons.h (every
 * reason code an event carries) and edgephys_app_state.h (messages, properties, ownership).
 *
 *   edgephys_client_config cfg;
 *   edgephys_client_config_init(&cfg);
 *   edgephys_client* c = NULL;
 *   if (edgephys_client_create(&cfg, &c) != EDGEPHYS_OK) puts(edgephys_last_error());
 *   edgephys_client_connect(c, "127.0.0.1:7777", token_text, edgephys_now_s());
 *   for (;;) {                                   // every frame
 *     edgephys_client_update(c, edgephys_now_s());
 *     edgephys_event ev;
 *     while (edgephys_client_poll_event(c, &ev) == EDGEPHYS_OK && ev.type != EDGEPHYS_EVENT_NONE) {
 *       if (ev.type == EDGEPHYS_EVENT_CONNECTED) edgephys_client_join(c, "lobby");
 *       ...
 *     }
 *   }
 *   edgephys_client_destroy(c);
 *
 * Conventions (they hold for every function below unless its comment says otherwise):
 *  - Every function returns an edgephys_status. EDGEPHYS_OK (0) is success; anything else is an
 *    error, and edgephys_last_error() describes it. A failing call changes nothing: out-params
 *    are left as they were, except list functions, which report the required count.
 *  - Bad arguments never crash: NULL pointers, NaN or infinite floats, out-of-range sizes or
 *    enum values, a struct_size that does not match this header, an unknown or destroyed
 *    handle and a closed handle each return an error code.
 *  - Units: metres, seconds, kilograms, radians per second; rotations are unit quaternions
 *    (x, y, z, w); all in the room frame unless a field says "local".
 *  - Time: functions taking `now_s` want a monotonic clock in seconds (edgephys_now_s() is
 *    one); it must not decrease between calls on one client.
 *  - Ownership: the library never keeps a pointer the caller passed in past the call; strings
 *    and arrays are copied. Pointers the library returns (edgephys_last_error,
 *    edgephys_status_name, edgephys_version_string) point to storage the library owns; do not
 *    free them.
 *  - Threading: the free functions (edgephys_abi_version, edgephys_now_s, ...) are thread-safe.
 *    An edgephys_client is not: call the functions of one client from one thread at a time
 *    (different clients may be used on different threads). edgephys_last_error() is per thread.
 *  - Memory: a client's memory is O(entities in its room + event queue capacity); the receive
 *    path (update + poll_event + get_entity) allocates nothing per received state in steady
 *    state.
 */
#ifndef EDGEPHYS_EDGEPHYS_H_
#define EDGEPHYS_EDGEPHYS_H_

#include <stddef.h>
#include <stdint.h>

#if defined(_WIN32)
#define EDGEPHYS_API __declspec(dllexport)
#else
#define EDGEPHYS_API __attribute__((visibility("default")))
#endif

#ifdef __cplusplus
extern "C" {
#endif

/* The ABI this header describes. Bump on any incompatible change to a struct, enum value or
 * signature. Bindings compare it with edgephys_abi_version() at load time. */
#define EDGEPHYS_ABI_VERSION 1u

/* ---- status ---------------------------------------------------------------------------- */

typedef enum edgephys_status {
  EDGEPHYS_OK = 0,
  EDGEPHYS_E_INVALID_ARGUMENT = 1,    /* NULL, NaN, out of range, wrong struct_size */
  EDGEPHYS_E_MALFORMED = 2,           /* a token or address that does not parse */
  EDGEPHYS_E_TOO_LARGE = 3,           /* exceeds a size limit (e.g. the container) */
  EDGEPHYS_E_QUEUE_FULL = 4,          /* a bounded send window is full; try again later */
  EDGEPHYS_E_NOT_CONNECTED = 5,       /* not connected / not joined yet, or no longer */
  EDGEPHYS_E_IO = 6,                  /* the operating system refused a socket operation */
  EDGEPHYS_E_UNAUTHENTICATED = 7,
  EDGEPHYS_E_PERMISSION_DENIED = 8,
  EDGEPHYS_E_NOT_FOUND = 9,           /* unknown entity, or not owned by this client */
  EDGEPHYS_E_ALREADY_EXISTS = 10,     /* e.g. connect on a client already started */
  EDGEPHYS_E_RESOURCE_EXHAUSTED = 11, /* e.g. the entity id block is used up */
  EDGEPHYS_E_INVALID_HANDLE = 12,     /* NULL, never created, or already destroyed */
  EDGEPHYS_E_CLOSED = 13,             /* edgephys_client_close() was called on it */
  EDGEPHYS_E_BUFFER_TOO_SMALL = 14,   /* a list did not fit; *count holds the size needed */
  EDGEPHYS_E_INTERNAL = 15            /* out of memory or a bug; the message says which */
} edgephys_status;

/* The ABI version of the loaded library (EDGEPHYS_ABI_VERSION it was built with). */
EDGEPHYS_API uint32_t edgephys_abi_version(void);
/* "0.1.0": the package version. Static storage. */
EDGEPHYS_API const char* edgephys_version_string(void);
/* "ok", "invalid argument", ...; "unknown" for a value outside the enum. Static storage. */
EDGEPHYS_API const char* edgephys_status_name(int32_t status);
/* What the last call on this thread that returned an error was about ("" after a successful
 * call). Valid until the next edgephys call on this thread. Never NULL. */
EDGEPHYS_API const char* edgephys_last_error(void);
/* Monotonic clock, seconds since an arbitrary start (CLOCK_MONOTONIC). */
EDGEPHYS_API double edgephys_now_s(void);

/* ---- plain value types ----------------------------------------------------------------- */

typedef struct edgephys_vec3 {
  float x, y, z; /* metres (or m/s, rad/s where a field says) */
} edgephys_vec3;

typedef struct edgephys_quat {
  float x, y, z, w; /* unit quaternion; identity is (0, 0, 0, 1) */
} edgephys_quat;

typedef struct edgephys_transform {
  edgephys_vec3 position; /* metres, room frame */
  edgephys_quat rotation; /* unit quaternion (|q| within 1e-3 of 1) */
} edgephys_transform;

/* Entity flags (bits of edgephys_spawn_desc.flags; schema EntityFlags). */
#define EDGEPHYS_FLAG_PERSISTENT 1u       /* kept when its owner leaves */
#define EDGEPHYS_FLAG_KINEMATIC 2u
#define EDGEPHYS_FLAG_INTERACTABLE 4u     /* may be grabbed */
#define EDGEPHYS_FLAG_AVATAR 8u           /* a head / body: sent at the critical rate */
#define EDGEPHYS_FLAG_HAND 16u            /* a hand: may grab with its trigger collider */
#define EDGEPHYS_FLAG_OFFLOADED 32u       /* simulated by PhyS on the relay (dynamic bodies) */
#define EDGEPHYS_FLAG_REPORT_CONTACTS 64u /* collision Enter/Exit events for it */
#define EDGEPHYS_FLAG_ALL 127u

/* ---- dissection containers (Decoupled Edge Physics' algorithms 1-3) -------------------- */

typedef enum edgephys_collider_shape {
  EDGEPHYS_SHAPE_BOX = 0,        /* half_extents */
  EDGEPHYS_SHAPE_SPHERE = 1,     /* radius */
  EDGEPHYS_SHAPE_CAPSULE = 2,    /* radius, height (between cap centres) */
  EDGEPHYS_SHAPE_CYLINDER = 3,   /* half_extents */
  EDGEPHYS_SHAPE_CONVEX_HULL = 4,   /* vertices */
  EDGEPHYS_SHAPE_TRIANGLE_MESH = 5  /* vertices, indices */
} edgephys_collider_shape;

typedef struct edgephys_collider {
  uint32_t shape;              /* edgephys_collider_shape */
  edgephys_vec3 half_extents;  /* m */
  float radius;                /* m */
  float height;                /* m */
  edgephys_vec3 local_position;
  edgephys_quat local_rotation;
  const float* vertices;       /* x,y,z triples; vertex_float_count floats (multiple of 3) */
  uint32_t vertex_float_count; /* <= EDGEPHYS_MAX_MESH_FLOATS */
  const uint32_t* indices;     /* triangle corners; index_count (multiple of 3) */
  uint32_t index_count;        /* <= EDGEPHYS_MAX_MESH_FLOATS */
  uint32_t is_trigger;         /* 0 or 1: reports Trigger Enter/Exit instead of colliding */
} edgephys_collider;

typedef struct edgephys_rigid_body {
  float mass;             /* kg, >= 0 (0 or kinematic: not moved by forces) */
  float linear_damping;   /* >= 0 */
  float angular_damping;  /* >= 0 */
  float friction;         /* >= 0 */
  float restitution;      /* >= 0 */
  uint32_t kinematic;     /* 0 or 1: follows edgephys_client_publish_transform */
  uint32_t use_gravity;   /* 0 or 1 */
  edgephys_vec3 linear_velocity;  /* m/s, initial */
  edgephys_vec3 angular_velocity; /* rad/s, initial */
} edgephys_rigid_body;

typedef enum edgephys_joint_kind {
  EDGEPHYS_JOINT_FIXED = 0,
  EDGEPHYS_JOINT_HINGE = 1,
  EDGEPHYS_JOINT_SPRING = 2
} edgephys_joint_kind;

typedef struct edgephys_joint {
  uint32_t kind;             /* edgephys_joint_kind */
  uint32_t connected_entity; /* entity id, 0: the world */
  edgephys_vec3 anchor;      /* local to this entity, m */
  edgephys_vec3 axis;        /* hinge axis, local */
  float stiffness;           /* spring, N/m, >= 0 */
  float damping;             /* >= 0 */
} edgephys_joint;

typedef struct edgephys_soft_body {
  const float* particles;    /* x,y,z triples, room frame; particle_count * 3 floats */
  const float* masses;       /* particle_count floats, kg, > 0 */
  uint32_t particle_count;   /* 1 .. EDGEPHYS_MAX_SOFT_BODY_PARTICLES */
  const uint32_t* springs;   /* index pairs; spring_count * 2 uint32 (< particle_count) */
  uint32_t spring_count;     /* <= EDGEPHYS_MAX_SOFT_BODY_SPRINGS */
  float stiffness;           /* N/m, >= 0 */
  float damping;             /* [0, 1] */
} edgephys_soft_body;

#define EDGEPHYS_MAX_COLLIDERS 64u
#define EDGEPHYS_MAX_JOINTS 64u
#define EDGEPHYS_MAX_MESH_FLOATS (1u << 18)
#define EDGEPHYS_MAX_SOFT_BODY_PARTICLES (1u << 16)
#define EDGEPHYS_MAX_SOFT_BODY_SPRINGS (1u << 18)
#define EDGEPHYS_MAX_NAME_BYTES 64u

/* One entity and its physics components. Fill with edgephys_spawn_desc_init() first (sets
 * struct_size and the defaults: identity rotation, unit scale, nothing else). Pointer fields
 * may be NULL when their count is 0 (rigid_body and soft_body: NULL means "none"). */
typedef struct edgephys_spawn_desc {
  uint32_t struct_size;               /* sizeof(edgephys_spawn_desc) */
  edgephys_transform transform;
  edgephys_vec3 scale;                /* > 0 */
  uint32_t parent_id;                 /* 0: none; parents without physics carry a transform */
  uint32_t flags;                     /* EDGEPHYS_FLAG_* bits */
  const char* name;                   /* NULL or UTF-8, <= EDGEPHYS_MAX_NAME_BYTES bytes */
  const edgephys_rigid_body* rigid_body;
  const edgephys_collider* colliders;
  uint32_t collider_count;            /* <= EDGEPHYS_MAX_COLLIDERS */
  const edgephys_joint* joints;
  uint32_t joint_count;               /* <= EDGEPHYS_MAX_JOINTS */
  const edgephys_soft_body* soft_body;
  /* EDGEPHYS_OWNER_LEAVE_* (edgephys_app_state.h): what happens to it when its owner leaves.
   * Appended: a desc whose struct_size ends before it (older callers) spawns with DEFAULT. */
  uint32_t on_owner_leave;
} edgephys_spawn_desc;

/* Defaults for the component structs (a box collider of half extents 0.5 m; a 1 kg dynamic
 * body with gravity, friction 0.5; a fixed joint on the z axis). Each returns
 * EDGEPHYS_E_INVALID_ARGUMENT on NULL. */
EDGEPHYS_API edgephys_status edgephys_spawn_desc_init(edgephys_spawn_desc* desc);
EDGEPHYS_API edgephys_status edgephys_collider_init(edgephys_collider* collider);
EDGEPHYS_API edgephys_status edgephys_rigid_body_init(edgephys_rigid_body* body);
EDGEPHYS_API edgephys_status edgephys_joint_init(edgephys_joint* joint);

/* ---- client ----------------------------------------------------------------------------- */

typedef struct edgephys_client edgephys_client; /* opaque */

typedef struct edgephys_client_config {
  uint32_t struct_size;        /* sizeof(edgephys_client_config) */
  const char* bind_address;    /* local UDP "host:port"; NULL: "0.0.0.0:0" (any, ephemeral) */
  double publish_rate_hz;      /* owned transforms sent at most this often; (0, 1000] */
  double handshake_timeout_s;  /* give up connecting after this long; (0, 600] */
  uint32_t event_queue_capacity; /* events kept until polled; 16 .. 1<<20. When full, new
                                    events are dropped and counted (dropped_events) */
  uint32_t queue_state_events; /* 0 or 1: also queue an EDGEPHYS_EVENT_STATE per received
                                  state (off: read states with edgephys_client_get_entity) */
  uint32_t snapshot_capacity;  /* states buffered per entity for interpolation; 2 .. 1024 */
  uint32_t require_packet_auth; /* 0 or 1: refuse a relay that does not seal packets (its
                                   handshake carries no key: run with --packet-auth false, or
                                   stripped on path to downgrade): EDGEPHYS_EVENT_REJECTED with
                                   code AuthRequired (18) instead of connecting unauthenticated */
} edgephys_client_config;

/* Defaults: any local address, 30 Hz, 5 s, 4096 events, no state events, 32 snapshots,
 * packet authentication required. */
EDGEPHYS_API edgephys_status edgephys_client_config_init(edgephys_client_config* config);

/* Creates a client and its UDP socket. On success *out is a new handle the caller owns; free it
 * with edgephys_client_destroy(). EDGEPHYS_E_IO if the socket cannot be bound. */
EDGEPHYS_API edgephys_status edgephys_client_create(const edgephys_client_config* config,
                                                    edgephys_client** out);
/* Sends a disconnect if connected, closes the socket and frees the client. The handle is
 * invalid afterwards: later calls with it return EDGEPHYS_E_INVALID_HANDLE (unless a new
 * client happens to get the same address). */
EDGEPHYS_API edgephys_status edgephys_client_destroy(edgephys_client* client);
/* Sends a disconnect if connected and closes the socket, but keeps the handle: every later call
 * except edgephys_client_destroy returns EDGEPHYS_E_CLOSED. Closing twice is an error too. */
EDGEPHYS_API edgephys_status edgephys_client_close(edgephys_client* client);

/* Starts the handshake with the relay at `relay_address` ("127.0.0.1:7777") using the client
 * token `token` (base64url text, as your backend or `edgephys-relay token` hands it out: the
 * part the relay reads and a session secret the SDK keeps, never sends, and uses to
 * authenticate the relay; docs/protocol.md §6). EDGEPHYS_E_MALFORMED on an unparsable address
 * or token (the last error's text names the cause, e.g. a token of an older format),
 * EDGEPHYS_E_ALREADY_EXISTS if already started. The result comes later as
 * EDGEPHYS_EVENT_CONNECTED, _REJECTED (reason BadProof: the relay could not prove the session
 * secret, a man in the middle; BadVersion: the relay speaks another handshake version) or
 * _DISCONNECTED (handshake timeout). */
EDGEPHYS_API edgephys_status edgephys_client_connect(edgephys_client* client,
                                                     const char* relay_address,
                                                     const char* token, double now_s);
/* Receives everything pending, advances the handshake, resends, publishes due transforms and
 * queues the resulting events. Call every frame. */
EDGEPHYS_API edgephys_status edgephys_client_update(edgephys_client* client, double now_s);
/* Joins `room` (1..64 bytes; the room the token grants). EDGEPHYS_E_NOT_CONNECTED before
 * EDGEPHYS_EVENT_CONNECTED. EDGEPHYS_EVENT_JOINED follows. */
EDGEPHYS_API edgephys_status edgephys_client_join(edgephys_client* client, const char* room);
EDGEPHYS_API edgephys_status edgephys_client_leave(edgephys_client* client);
/* Sends a disconnect (reason ClientLeft); the client can not be reconnected. */
EDGEPHYS_API edgephys_status edgephys_client_disconnect(edgephys_client* client);

/* Spawns an entity this client owns and writes its id to *out_id. With
 * EDGEPHYS_FLAG_OFFLOADED a dynamic rigid body (mass > 0, not kinematic) or a soft body is
 * handed to PhyS on the relay, which then owns and simulates it (its states arrive like any
 * other entity's). Without it, bodies and colliders are mirrored into PhyS as kinematic bodies
 * that follow edgephys_client_publish_transform (local physics pushes PhyS objects).
 * EDGEPHYS_E_NOT_CONNECTED before EDGEPHYS_EVENT_JOINED; EDGEPHYS_E_INVALID_ARGUMENT on any
 * non-finite or out-of-range field; EDGEPHYS_E_TOO_LARGE over the message size limit. PhyS may
 * still refuse the components later (EDGEPHYS_EVENT_ERROR, reason 14 InvalidContainer).
 * A spawn is queued on the reliable channel: if the relay is lost before it arrives, this
 * client ends in EDGEPHYS_EVENT_DISCONNECTED (the C API does not resume sessions) and the
 * entity is gone with the connection. (The C++ SDK's session resume, ClientConfig::resume,
 * spawns such entities again on the relay that restores the room, or reports each one it
 * cannot as an ERROR whose detail starts "lost in failover: "; docs/protocol.md, "Failover
 * and resume".) */
EDGEPHYS_API edgephys_status edgephys_client_spawn(edgephys_client* client,
                                                   const edgephys_spawn_desc* desc,
                                                   uint32_t* out_id);
/* EDGEPHYS_E_NOT_FOUND if this client does not own the entity. */
EDGEPHYS_API edgephys_status edgephys_client_despawn(edgephys_client* client, uint32_t entity_id);
/* Static scenery in one call: ground, walls, a mesh (EDGEPHYS_SHAPE_TRIANGLE_MESH is meant for
 * this). Spawns an entity at `transform` (scale 1) with `collider_count` colliders (1 ..
 * EDGEPHYS_MAX_COLLIDERS; copied, checked as edgephys_client_spawn checks them) and no rigid
 * body, flagged EDGEPHYS_FLAG_OFFLOADED | EDGEPHYS_FLAG_PERSISTENT: PhyS holds it as an
 * immovable collider that its simulated bodies rest on and bounce off, and it stays with the
 * room when this player leaves (edgephys_client_despawn removes it). Without it a room's PhyS
 * has no ground: an offloaded body falls until the stability guard resets it. `name`: NULL or
 * UTF-8. Errors and out_id: as edgephys_client_spawn. */
EDGEPHYS_API edgephys_status edgephys_client_spawn_static(edgephys_client* client,
                                                         const edgephys_transform* transform,
                                                         const edgephys_collider* colliders,
                                                         uint32_t collider_count,
                                                         const char* name, uint32_t* out_id);
/* Records the latest transform of an owned entity; it is sent at the publish rate (Decoupled Edge Physics'
 * MoveToTransform for mirrored kinematic bodies and hands). */
EDGEPHYS_API edgephys_status edgephys_client_publish_transform(edgephys_client* client,
                                                               uint32_t entity_id,
                                                               const edgephys_transform* transform);
/* Asks PhyS to attach `entity_id` to this client's hand `hand_id` (the hand's trigger collider
 * must hover it). EDGEPHYS_EVENT_GRABBED or EDGEPHYS_EVENT_ERROR (reason 15 GrabRefused)
 * follows. */
EDGEPHYS_API edgephys_status edgephys_client_grab(edgephys_client* client, uint32_t entity_id,
                                                  uint32_t hand_id);
/* As edgephys_client_grab, with the hand's pose now (metres, unit quaternion, room frame): it is
 * published as the hand's transform and sent with the grab, so the relay judges the hover where
 * the hand is, even when this frame's move has not reached it yet. The relay refuses
 * (EDGEPHYS_EVENT_ERROR, reason 15 GrabRefused, counted) a pose more than
 * EDGEPHYS_MAX_GRAB_POSE_OFFSET_M from the hand's last transform it holds. EDGEPHYS_E_NOT_FOUND
 * if this client does not own `hand_id`; EDGEPHYS_E_INVALID_ARGUMENT for a NULL, non-finite or
 * non-unit pose. */
#define EDGEPHYS_MAX_GRAB_POSE_OFFSET_M 0.5f
EDGEPHYS_API edgephys_status edgephys_client_grab_at(edgephys_client* client, uint32_t entity_id,
                                                     uint32_t hand_id,
                                                     const edgephys_transform* hand_pose);
/* Lets go of `entity_id`: it leaves at the velocity the hand showed over its last ~0.1 s of
 * published transforms (so publish the hand's transform every frame while it carries, to throw),
 * spinning as the hand turned. EDGEPHYS_EVENT_RELEASED follows. */
EDGEPHYS_API edgephys_status edgephys_client_release(edgephys_client* client, uint32_t entity_id);

/* ---- events ------------------------------------------------------------------------------ */

typedef enum edgephys_event_type {
  EDGEPHYS_EVENT_NONE = 0,            /* the queue is empty */
  EDGEPHYS_EVENT_CONNECTED = 1,       /* player_id */
  EDGEPHYS_EVENT_REJECTED = 2,        /* code: reject reason, detail (edgephys_reasons.h) */
  EDGEPHYS_EVENT_DISCONNECTED = 3,    /* code: disconnect reason, detail (edgephys_reasons.h) */
  EDGEPHYS_EVENT_JOINED = 4,          /* detail: room; entity_id: this player's id block base */
  EDGEPHYS_EVENT_PLAYER_JOINED = 5,   /* player_id; also one per member already in the room
                                         when this client joins */
  EDGEPHYS_EVENT_PLAYER_LEFT = 6,     /* player_id */
  EDGEPHYS_EVENT_SPAWNED = 7,         /* entity_id, player_id (owner, 0: PhyS), parent_id, flags,
                                         transform */
  EDGEPHYS_EVENT_DESPAWNED = 8,       /* entity_id */
  EDGEPHYS_EVENT_STATE = 9,           /* entity_id, player_id (owner), transform, code: relay
                                         time of the state in ms (wraps); only with
                                         queue_state_events */
  EDGEPHYS_EVENT_SOFT_BODY = 10,      /* entity_id, code: particle count; read the particles with
                                         edgephys_client_get_soft_body */
  EDGEPHYS_EVENT_COLLISION_ENTER = 11, /* entity_id < other_id */
  EDGEPHYS_EVENT_COLLISION_EXIT = 12,
  EDGEPHYS_EVENT_TRIGGER_ENTER = 13,  /* entity_id: the trigger's entity, other_id: inside it */
  EDGEPHYS_EVENT_TRIGGER_EXIT = 14,
  EDGEPHYS_EVENT_GUARD_RESET = 15,    /* entity_id: restored by the stability guard */
  EDGEPHYS_EVENT_GRABBED = 16,        /* entity_id, other_id: the hand */
  EDGEPHYS_EVENT_RELEASED = 17,       /* entity_id, other_id: the hand */
  EDGEPHYS_EVENT_ERROR = 18,          /* code: reject reason, entity_id (0: none), detail
                                         (edgephys_reasons.h) */
  EDGEPHYS_EVENT_MESSAGE = 19,        /* player_id: the sender, code: payload size, flags:
                                         EDGEPHYS_MESSAGE_UNRELIABLE if sent unreliably; read
                                         the payload with edgephys_client_get_message */
  EDGEPHYS_EVENT_PROPERTY_CHANGED = 20, /* entity_id (0: the room), detail: key, player_id: the
                                         writer, code: the new version, other_id: the write's
                                         request id, flags: the value's type; read the value
                                         with edgephys_client_get_event_property. Also one per
                                         property the room holds when this client joins */
  EDGEPHYS_EVENT_PROPERTY_CONFLICT = 21, /* this client's compare-and-set lost: other_id: its
                                         request id, entity_id, detail: key, code: the current
                                         version (0: none), player_id: its writer, flags: its
                                         type; the current value with
                                         edgephys_client_get_event_property */
  EDGEPHYS_EVENT_OWNERSHIP_CHANGED = 22 /* entity_id, player_id: its new owner (0: the room),
                                         code: the authority sequence (+1 per change). Also one
                                         per entity whose owner changed before this client
                                         joined (after its SPAWNED) */
} edgephys_event_type;

#define EDGEPHYS_EVENT_DETAIL_BYTES 128u

/* One event. Plain data, no pointers: copy it freely. Fields an event type does not list are 0. */
typedef struct edgephys_event {
  uint32_t type;       /* edgephys_event_type */
  uint32_t code;       /* reason code (see the type) */
  uint32_t player_id;
  uint32_t entity_id;
  uint32_t other_id;
  uint32_t parent_id;
  uint32_t flags;
  uint32_t reserved;
  edgephys_transform transform;
  char detail[EDGEPHYS_EVENT_DETAIL_BYTES]; /* NUL-terminated UTF-8, truncated */
} edgephys_event;

/* Takes the oldest queued event into *out, or sets out->type = EDGEPHYS_EVENT_NONE when none
 * is queued. Events are queued in the order the SDK learnt them: physics events are reliable
 * and in step order. No allocation. */
EDGEPHYS_API edgephys_status edgephys_client_poll_event(edgephys_client* client,
                                                        edgephys_event* out);

/* ---- state ------------------------------------------------------------------------------- */

typedef enum edgephys_connection_state {
  EDGEPHYS_STATE_IDLE = 0,
  EDGEPHYS_STATE_HANDSHAKING = 1,
  EDGEPHYS_STATE_CONNECTED = 2,
  EDGEPHYS_STATE_REJECTED = 3,
  EDGEPHYS_STATE_DISCONNECTED = 4,
  EDGEPHYS_STATE_FAILED = 5
} edgephys_connection_state;

typedef struct edgephys_client_info {
  uint32_t struct_size;       /* set to sizeof(edgephys_client_info) before the call; 56, the
                               * size before state_payloads_refused, is accepted too (that field
                               * is then not written) */
  uint32_t state;             /* edgephys_connection_state */
  uint32_t joined;            /* 0 or 1 */
  uint32_t player_id;
  uint32_t entity_id_base;    /* first id of this player's block (valid once joined) */
  uint32_t entity_count;      /* others' entities known in the room */
  uint32_t reject_reason;
  uint32_t disconnect_reason;
  uint64_t dropped_events;    /* events lost to a full queue */
  uint64_t states_received;   /* entity states received */
  uint64_t state_bytes_received;
  uint64_t state_payloads_refused; /* state payloads of a format the SDK does not decode, or not
                                    * the room's: refused and counted, nothing applied (a relay
                                    * sending an emulation format, a client without its plug-in) */
} edgephys_client_info;

EDGEPHYS_API edgephys_status edgephys_client_get_info(edgephys_client* client,
                                                      edgephys_client_info* out);

/* Real-time status of the connection to the relay (per-connection, as a game's network HUD or
 * an operator's client-side probe wants it). The counters are cumulative since the connection
 * began; the rates are means over about the last second of edgephys_client_update calls (the
 * span reaches further back after a pause in updates longer than that: see
 * client/connection_rates.h). O(1); allocates nothing. */
typedef struct edgephys_connection_status {
  uint32_t struct_size;            /* set to sizeof(edgephys_connection_status) before the call */
  uint32_t state;                  /* edgephys_connection_state */
  uint32_t reserved;               /* 0 */
  uint32_t reserved2;              /* 0 (keeps the doubles 8-byte aligned in every binding) */
  double rtt_s;                    /* smoothed round trip. Includes how long the relay held its
                                    * acknowledgement (up to its --ack-delay, 20 ms by default):
                                    * reads 0-20 ms above the network's round trip */
  double rtt_var_s;                /* round-trip variation */
  double loss;                     /* smoothed fraction of our packets not acknowledged, 0..1 */
  double send_bytes_per_s;         /* UDP payload bytes, both directions, per second */
  double receive_bytes_per_s;
  double send_packets_per_s;
  double receive_packets_per_s;
  uint64_t packets_sent;
  uint64_t packets_received;
  uint64_t bytes_sent;
  uint64_t bytes_received;
  uint64_t reliable_resends;       /* reliable units sent more than once */
  uint64_t reliable_delivered;     /* reliable messages delivered to this client */
  uint64_t stale_dropped;          /* state payloads dropped as older than one delivered */
  uint64_t duplicates_dropped;     /* packets or reliable units received twice */
  uint64_t pending_reliable_bytes; /* reliable bytes queued or not yet acknowledged: a growing
                                    * figure means the relay is not acknowledging (congestion or a
                                    * dead path) */
} edgephys_connection_status;

/* EDGEPHYS_E_NOT_CONNECTED while there is no connection to describe: before the handshake
 * completes, and while the client re-handshakes after losing its relay. After a disconnect it
 * still describes the connection that ended. */
EDGEPHYS_API edgephys_status edgephys_client_get_connection_status(edgephys_client* client,
                                                                   edgephys_connection_status* out);

typedef struct edgephys_entity {
  uint32_t id;
  uint32_t owner;        /* player id; 0: the room / PhyS */
  uint32_t parent_id;
  uint32_t flags;
  uint32_t has_state;    /* 0 until a state arrived after the spawn */
  uint32_t state_time_ms; /* relay clock (wraps) of that state */
  uint32_t soft_body_particles;
  uint32_t reserved;
  edgephys_transform transform; /* latest received */
} edgephys_entity;

/* The latest known state of a remote (or PhyS-owned) entity. EDGEPHYS_E_NOT_FOUND if unknown. */
EDGEPHYS_API edgephys_status edgephys_client_get_entity(edgephys_client* client,
                                                        uint32_t entity_id, edgephys_entity* out);
/* Writes up to `capacity` entity ids (in no particular order) to `ids` and the total to *count.
 * EDGEPHYS_E_BUFFER_TOO_SMALL (with *count = total) if they do not fit; `ids` may be NULL when
 * capacity is 0 (to ask for the count). */
EDGEPHYS_API edgephys_status edgephys_client_list_entities(edgephys_client* client, uint32_t* ids,
                                                           size_t capacity, size_t* count);
/* A soft body's latest particles, as get_entity: up to `capacity` vec3 into `out`, total into
 * *count, EDGEPHYS_E_BUFFER_TOO_SMALL if they do not fit. */
EDGEPHYS_API edgephys_status edgephys_client_get_soft_body(edgephys_client* client,
                                                           uint32_t entity_id, edgephys_vec3* out,
                                                           size_t capacity, size_t* count);

typedef enum edgephys_interpolator {
  EDGEPHYS_INTERP_LERP_SLERP = 0,
  EDGEPHYS_INTERP_DQ_DLB = 1,
  EDGEPHYS_INTERP_DQ_SCLERP = 2, /* dual-quaternion screw interpolation (Decoupled Edge
                                    Physics') */
  EDGEPHYS_INTERP_HERMITE = 3,
  EDGEPHYS_INTERP_NONE = 4,      /* hold the latest snapshot */
  /* The recommended method: HERMITE (finite-difference tangents; the most accurate at send
   * rates up to 30 Hz, docs/benchmarks.md "Interpolation"). */
  EDGEPHYS_INTERP_AUTO = 5
} edgephys_interpolator;

/* The state format of the joined room, from its Joined message (docs/protocol.md §5): 9 (the
 * relay's default) or 2 (the previous default); the SDK decodes these two (and format 11, soft
 * bodies) and refuses others (a benchmark relay's emulations, 3 and 4). EDGEPHYS_E_NOT_FOUND before
 * the client first joined a room (then *out is 0); after a leave, the last room's until the next
 * join. Cost O(1). */
EDGEPHYS_API edgephys_status edgephys_client_get_state_format(edgephys_client* client,
                                                              uint32_t* out);

/* The pose to render for entity `entity_id` at local time `now_s`: received states are kept in
 * a jitter buffer and played out with an adaptive delay, interpolated by `method`
 * (client/interpolation.h explains each). Call once per rendered frame per entity with
 * non-decreasing now_s. EDGEPHYS_E_NOT_FOUND if no state of that entity has arrived. */
EDGEPHYS_API edgephys_status edgephys_client_sample_pose(edgephys_client* client,
                                                         uint32_t entity_id, double now_s,
                                                         uint32_t method,
                                                         edgephys_transform* out);

/* Holds the playout delay of edgephys_client_sample_pose to at most `max_delay_s` seconds (an
 * application's latency limit), for every entity, at once and in later rooms; 0 (the default)
 * removes the limit. EDGEPHYS_E_INVALID_ARGUMENT unless 0 or in (0, 4] (NaN and infinities
 * too). Rooms play out adaptively (1.5 send intervals plus jitter, at most 0.3 s), so a limit
 * only matters below that; its price is accuracy, since the render time then runs ahead of the
 * newest state and the SDK extrapolates for up to 0.1 s (ambient bodies at 6 Hz held to 0.1 s:
 * 1.1-1.3x the display error's p99, `edgephys-loadgen multiobject --display-playout-limit`).
 * A lower limit moves the render clock forward by at most 10 % of real time (it catches up
 * over a few seconds) or jumps past 1 s of difference. Cost O(entities). */
EDGEPHYS_API edgephys_status edgephys_client_set_max_playout_delay(edgephys_client* client,
                                                                   double max_delay_s);
/* The playout delay entity `entity_id` is drawn at now (seconds behind the relay's clock as this
 * client estimates it; before its first sample_pose, the delay it will start at).
 * EDGEPHYS_E_NOT_FOUND (and *out_s 0) if no state of that entity has arrived. Cost O(1). */
EDGEPHYS_API edgephys_status edgephys_client_get_playout_delay(edgephys_client* client,
                                                               uint32_t entity_id, double* out_s);

#ifdef __cplusplus
} /* extern "C" */
#endif

/* Reason codes: edgephys_reasons.h. Messages, properties and ownership: edgephys_app_state.h. */
#include "edgephys/edgephys_reasons.h"
#include "edgephys/edgephys_app_state.h"

#endif /* EDGEPHYS_EDGEPHYS_H_ */
