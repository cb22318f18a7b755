"""edgephys Python binding: ctypes over the C API of libedgephys (include/edgephys/edgephys.h).

For tools, bots and tests. The C header is the manual: units (metres, seconds, unit quaternions
x, y, z, w), ownership and threading are its. A call that fails raises EdgephysError with the
C status and edgephys_last_error()'s message.

    import edgephys as ep
    c = ep.Client()
    c.connect("127.0.0.1:7777", token)
    while True:
        c.update()
        for ev in c.events():
            if ev.type == ep.EVENT_CONNECTED: c.join("lobby")

The library is found through $EDGEPHYS_LIBRARY (a path, to override), then the install it came
with (`cmake --install` writes its library's path into edgephys/_install.py, which
`pip install <prefix>/share/edgephys/python` carries along), then the system loader (the .deb). A Client is not thread-safe (one thread at a time).
"""
import ctypes
import ctypes.util
import os

ABI_VERSION = 1

# ---- status and event codes (edgephys.h) -------------------------------------------------
OK = 0
E_INVALID_ARGUMENT, E_MALFORMED, E_TOO_LARGE, E_QUEUE_FULL, E_NOT_CONNECTED, E_IO = 1, 2, 3, 4, 5, 6
E_UNAUTHENTICATED, E_PERMISSION_DENIED, E_NOT_FOUND, E_ALREADY_EXISTS = 7, 8, 9, 10
E_RESOURCE_EXHAUSTED, E_INVALID_HANDLE, E_CLOSED, E_BUFFER_TOO_SMALL, E_INTERNAL = 11, 12, 13, 14, 15

FLAG_PERSISTENT, FLAG_KINEMATIC, FLAG_INTERACTABLE, FLAG_AVATAR = 1, 2, 4, 8
FLAG_HAND, FLAG_OFFLOADED, FLAG_REPORT_CONTACTS = 16, 32, 64

SHAPE_BOX, SHAPE_SPHERE, SHAPE_CAPSULE, SHAPE_CYLINDER, SHAPE_CONVEX_HULL, SHAPE_TRIANGLE_MESH = range(6)
JOINT_FIXED, JOINT_HINGE, JOINT_SPRING = range(3)
# INTERP_AUTO: the recommended method (Hermite)
INTERP_LERP_SLERP, INTERP_DQ_DLB, INTERP_DQ_SCLERP, INTERP_HERMITE, INTERP_NONE, INTERP_AUTO = range(6)

(EVENT_NONE, EVENT_CONNECTED, EVENT_REJECTED, EVENT_DISCONNECTED, EVENT_JOINED, EVENT_PLAYER_JOINED,
 EVENT_PLAYER_LEFT, EVENT_SPAWNED, EVENT_DESPAWNED, EVENT_STATE, EVENT_SOFT_BODY,
 EVENT_COLLISION_ENTER, EVENT_COLLISION_EXIT, EVENT_TRIGGER_ENTER, EVENT_TRIGGER_EXIT,
 EVENT_GUARD_RESET, EVENT_GRABBED, EVENT_RELEASED, EVENT_ERROR, EVENT_MESSAGE,
 EVENT_PROPERTY_CHANGED, EVENT_PROPERTY_CONFLICT, EVENT_OWNERSHIP_CHANGED) = range(23)

# Properties (edgephys.h, "properties"): value types and who may write a property.
(PROPERTY_NONE, PROPERTY_BOOL, PROPERTY_INT64, PROPERTY_DOUBLE, PROPERTY_STRING, PROPERTY_BYTES,
 PROPERTY_VEC3, PROPERTY_QUAT) = range(8)
AUTHORITY_OWNER, AUTHORITY_ANYONE = 0, 1
MAX_PROPERTY_KEY_BYTES = 64
MAX_PROPERTY_VALUE_BYTES = 65536

# Application messages (edgephys_client_send_message): whom a message is for.
TO_ROOM, TO_OTHERS, TO_PLAYER = 0, 1, 2
MAX_MESSAGE_BYTES = 65536

# Reason codes (edgephys.h, "reasons"): REJECTED and ERROR events carry a reject reason,
# DISCONNECTED events a disconnect reason; reason_name(event) names either.
(REJECT_NONE, REJECT_BAD_TOKEN, REJECT_EXPIRED_TOKEN, REJECT_REPLAYED_TOKEN, REJECT_ROOM_FULL,
 REJECT_SERVER_FULL, REJECT_WRONG_ROOM, REJECT_NOT_OWNER, REJECT_UNKNOWN_ENTITY, REJECT_DUPLICATE_ENTITY,
 REJECT_INVALID_MESSAGE, REJECT_NOT_JOINED, REJECT_ENTITY_LIMIT, REJECT_BAD_COOKIE, REJECT_INVALID_CONTAINER,
 REJECT_GRAB_REFUSED, REJECT_RATE_LIMITED, REJECT_OVER_BUDGET, REJECT_AUTH_REQUIRED, REJECT_UNKNOWN_PLAYER,
 REJECT_NOT_PERMITTED, REJECT_TAKEOVER_REFUSED) = range(22)
(DISCONNECT_NONE, DISCONNECT_TIMEOUT, DISCONNECT_CLIENT_LEFT, DISCONNECT_SERVER_SHUTDOWN, DISCONNECT_KICKED,
 DISCONNECT_PROTOCOL_ERROR, DISCONNECT_RELIABLE_OVERFLOW) = range(7)

EVENT_NAMES = {
    EVENT_COLLISION_ENTER: "collision_enter", EVENT_COLLISION_EXIT: "collision_exit",
    EVENT_TRIGGER_ENTER: "trigger_enter", EVENT_TRIGGER_EXIT: "trigger_exit",
    EVENT_GUARD_RESET: "guard_reset", EVENT_GRABBED: "grabbed", EVENT_RELEASED: "released",
}


# ---- plain structs ------------------------------------------------------------------------
class Vec3(ctypes.Structure):
    _fields_ = [("x", ctypes.c_float), ("y", ctypes.c_float), ("z", ctypes.c_float)]


class Quat(ctypes.Structure):
    _fields_ = [("x", ctypes.c_float), ("y", ctypes.c_float), ("z", ctypes.c_float), ("w", ctypes.c_float)]


class Transform(ctypes.Structure):
    _fields_ = [("position", Vec3), ("rotation", Quat)]


class Collider(ctypes.Structure):
    _fields_ = [("shape", ctypes.c_uint32), ("half_extents", Vec3), ("radius", ctypes.c_float),
                ("height", ctypes.c_float), ("local_position", Vec3), ("local_rotation", Quat),
                ("vertices", ctypes.POINTER(ctypes.c_float)), ("vertex_float_count", ctypes.c_uint32),
                ("indices", ctypes.POINTER(ctypes.c_uint32)), ("index_count", ctypes.c_uint32),
                ("is_trigger", ctypes.c_uint32)]


class RigidBody(ctypes.Structure):
    _fields_ = [("mass", ctypes.c_float), ("linear_damping", ctypes.c_float),
                ("angular_damping", ctypes.c_float), ("friction", ctypes.c_float),
                ("restitution", ctypes.c_float), ("kinematic", ctypes.c_uint32),
                ("use_gravity", ctypes.c_uint32), ("linear_velocity", Vec3), ("angular_velocity", Vec3)]


class Joint(ctypes.Structure):
    _fields_ = [("kind", ctypes.c_uint32), ("connected_entity", ctypes.c_uint32), ("anchor", Vec3),
                ("axis", Vec3), ("stiffness", ctypes.c_float), ("damping", ctypes.c_float)]


class SoftBody(ctypes.Structure):
    _fields_ = [("particles", ctypes.POINTER(ctypes.c_float)), ("masses", ctypes.POINTER(ctypes.c_float)),
                ("particle_count", ctypes.c_uint32), ("springs", ctypes.POINTER(ctypes.c_uint32)),
                ("spring_count", ctypes.c_uint32), ("stiffness", ctypes.c_float), ("damping", ctypes.c_float)]


class SpawnDesc(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_uint32), ("transform", Transform), ("scale", Vec3),
                ("parent_id", ctypes.c_uint32), ("flags", ctypes.c_uint32), ("name", ctypes.c_char_p),
                ("rigid_body", ctypes.POINTER(RigidBody)), ("colliders", ctypes.POINTER(Collider)),
                ("collider_count", ctypes.c_uint32), ("joints", ctypes.POINTER(Joint)),
                ("joint_count", ctypes.c_uint32), ("soft_body", ctypes.POINTER(SoftBody))]


class ClientConfig(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_uint32), ("bind_address", ctypes.c_char_p),
                ("publish_rate_hz", ctypes.c_double), ("handshake_timeout_s", ctypes.c_double),
                ("event_queue_capacity", ctypes.c_uint32), ("queue_state_events", ctypes.c_uint32),
                ("snapshot_capacity", ctypes.c_uint32), ("require_packet_auth", ctypes.c_uint32)]


class Event(ctypes.Structure):
    _fields_ = [("type", ctypes.c_uint32), ("code", ctypes.c_uint32), ("player_id", ctypes.c_uint32),
                ("entity_id", ctypes.c_uint32), ("other_id", ctypes.c_uint32), ("parent_id", ctypes.c_uint32),
                ("flags", ctypes.c_uint32), ("reserved", ctypes.c_uint32), ("transform", Transform),
                ("detail", ctypes.c_char * 128)]


class ClientInfo(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_uint32), ("state", ctypes.c_uint32), ("joined", ctypes.c_uint32),
                ("player_id", ctypes.c_uint32), ("entity_id_base", ctypes.c_uint32),
                ("entity_count", ctypes.c_uint32), ("reject_reason", ctypes.c_uint32),
                ("disconnect_reason", ctypes.c_uint32), ("dropped_events", ctypes.c_uint64),
                ("states_received", ctypes.c_uint64), ("state_bytes_received", ctypes.c_uint64)]


class ConnectionStatus(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_uint32), ("state", ctypes.c_uint32), ("reserved", ctypes.c_uint32),
                ("reserved2", ctypes.c_uint32)] + \
               [(n, ctypes.c_double) for n in ("rtt_s", "rtt_var_s", "loss", "send_bytes_per_s",
                                               "receive_bytes_per_s", "send_packets_per_s",
                                               "receive_packets_per_s")] + \
               [(n, ctypes.c_uint64) for n in ("packets_sent", "packets_received", "bytes_sent",
                                               "bytes_received", "reliable_resends", "reliable_delivered",
                                               "stale_dropped", "duplicates_dropped",
                                               "pending_reliable_bytes")]


class Entity(ctypes.Structure):
    _fields_ = [("id", ctypes.c_uint32), ("owner", ctypes.c_uint32), ("parent_id", ctypes.c_uint32),
                ("flags", ctypes.c_uint32), ("has_state", ctypes.c_uint32), ("state_time_ms", ctypes.c_uint32),
                ("soft_body_particles", ctypes.c_uint32), ("reserved", ctypes.c_uint32),
                ("transform", Transform)]


class PropertyValue(ctypes.Structure):
    _fields_ = [("type", ctypes.c_uint32), ("reserved", ctypes.c_uint32), ("int_value", ctypes.c_int64),
                ("double_value", ctypes.c_double), ("vec3", Vec3), ("quat", Quat),
                ("data", ctypes.c_void_p), ("size", ctypes.c_size_t)]


class PropertyStruct(ctypes.Structure):
    _fields_ = [("struct_size", ctypes.c_uint32), ("entity_id", ctypes.c_uint32), ("version", ctypes.c_uint32),
                ("writer", ctypes.c_uint32), ("owner", ctypes.c_uint32), ("authority", ctypes.c_uint32),
                ("request_id", ctypes.c_uint32), ("reserved", ctypes.c_uint32), ("value", PropertyValue)]


class Property:
    """A property as the relay announced it: entity_id (0: the room), key, value (bool, int,
    float, str, bytes, a (x, y, z) tuple for VEC3 or (x, y, z, w) for QUAT; None when it does
    not exist), type, version, writer, owner, authority, request_id."""

    def __init__(self, key, raw, data):
        self.key = key
        self.entity_id, self.version, self.writer = raw.entity_id, raw.version, raw.writer
        self.owner, self.authority, self.request_id = raw.owner, raw.authority, raw.request_id
        v = raw.value
        self.type = v.type
        self.value = {PROPERTY_BOOL: lambda: bool(v.int_value), PROPERTY_INT64: lambda: v.int_value,
                      PROPERTY_DOUBLE: lambda: v.double_value, PROPERTY_STRING: lambda: data.decode("utf-8", "replace"),
                      PROPERTY_BYTES: lambda: data, PROPERTY_VEC3: lambda: (v.vec3.x, v.vec3.y, v.vec3.z),
                      PROPERTY_QUAT: lambda: (v.quat.x, v.quat.y, v.quat.z, v.quat.w)}.get(v.type, lambda: None)()

    def __repr__(self):
        return (f"Property(entity_id={self.entity_id}, key={self.key!r}, value={self.value!r}, "
                f"version={self.version}, writer={self.writer})")


def _property_value(value, kind=None):
    """(PropertyValue, keep-alive buffer) for a Python value; `kind` forces a PROPERTY_* type."""
    v = PropertyValue()
    keep = None
    if kind is None:
        if isinstance(value, bool):
            kind = PROPERTY_BOOL
        elif isinstance(value, int):
            kind = PROPERTY_INT64
        elif isinstance(value, float):
            kind = PROPERTY_DOUBLE
        elif isinstance(value, str):
            kind = PROPERTY_STRING
        elif isinstance(value, (bytes, bytearray)):
            kind = PROPERTY_BYTES
        elif isinstance(value, Vec3) or (isinstance(value, (tuple, list)) and len(value) == 3):
            kind = PROPERTY_VEC3
        elif isinstance(value, Quat) or (isinstance(value, (tuple, list)) and len(value) == 4):
            kind = PROPERTY_QUAT
        else:
            raise TypeError(f"no property type for {type(value).__name__}")
    v.type = kind
    if kind in (PROPERTY_BOOL, PROPERTY_INT64):
        v.int_value = int(value)
    elif kind == PROPERTY_DOUBLE:
        v.double_value = float(value)
    elif kind == PROPERTY_VEC3:
        v.vec3 = value if isinstance(value, Vec3) else Vec3(*value)
    elif kind == PROPERTY_QUAT:
        v.quat = value if isinstance(value, Quat) else Quat(*value)
    elif kind in (PROPERTY_STRING, PROPERTY_BYTES):
        raw = value.encode() if isinstance(value, str) else bytes(value)
        keep = ctypes.create_string_buffer(raw, max(1, len(raw)))
        v.data = ctypes.cast(keep, ctypes.c_void_p)
        v.size = len(raw)
    return v, keep


class EdgephysError(RuntimeError):
    """A C API call failed: .status is the edgephys_status, the message edgephys_last_error()."""

    def __init__(self, status, message):
        super().__init__(f"{message} (status {status})")
        self.status = status


# ---- the library --------------------------------------------------------------------------
def _library_path():
    if os.environ.get("EDGEPHYS_LIBRARY"):
        return os.environ["EDGEPHYS_LIBRARY"]
    try:
        from . import _install  # written by cmake --install
        if os.path.exists(_install.LIBRARY):
            return _install.LIBRARY
    except ImportError:
        pass
    return ctypes.util.find_library("edgephys") or "libedgephys.so.1"


def _load():
    path = _library_path()
    try:
        lib = ctypes.CDLL(path)
    except OSError as e:
        raise OSError(f"edgephys: cannot load the native library {path!r}: {e}. Install the SDK "
                      "(cmake --install or the .deb) or set EDGEPHYS_LIBRARY to libedgephys.so.1") from e
    P = ctypes.POINTER
    c = ctypes.c_void_p
    u32, f64, sz = ctypes.c_uint32, ctypes.c_double, ctypes.c_size_t
    sigs = {
        "edgephys_abi_version": ([], u32),
        "edgephys_version_string": ([], ctypes.c_char_p),
        "edgephys_status_name": ([ctypes.c_int32], ctypes.c_char_p),
        "edgephys_reason_name": ([u32, u32], ctypes.c_char_p),
        "edgephys_last_error": ([], ctypes.c_char_p),
        "edgephys_now_s": ([], f64),
        "edgephys_spawn_desc_init": ([P(SpawnDesc)], ctypes.c_int),
        "edgephys_collider_init": ([P(Collider)], ctypes.c_int),
        "edgephys_rigid_body_init": ([P(RigidBody)], ctypes.c_int),
        "edgephys_joint_init": ([P(Joint)], ctypes.c_int),
        "edgephys_client_config_init": ([P(ClientConfig)], ctypes.c_int),
        "edgephys_client_create": ([P(ClientConfig), P(c)], ctypes.c_int),
        "edgephys_client_destroy": ([c], ctypes.c_int),
        "edgephys_client_close": ([c], ctypes.c_int),
        "edgephys_client_connect": ([c, ctypes.c_char_p, ctypes.c_char_p, f64], ctypes.c_int),
        "edgephys_client_update": ([c, f64], ctypes.c_int),
        "edgephys_client_join": ([c, ctypes.c_char_p], ctypes.c_int),
        "edgephys_client_leave": ([c], ctypes.c_int),
        "edgephys_client_disconnect": ([c], ctypes.c_int),
        "edgephys_client_spawn": ([c, P(SpawnDesc), P(u32)], ctypes.c_int),
        "edgephys_client_despawn": ([c, u32], ctypes.c_int),
        "edgephys_client_spawn_static": ([c, P(Transform), P(Collider), u32, ctypes.c_char_p, P(u32)],
                                         ctypes.c_int),
        "edgephys_client_publish_transform": ([c, u32, P(Transform)], ctypes.c_int),
        "edgephys_client_grab": ([c, u32, u32], ctypes.c_int),
        "edgephys_client_release": ([c, u32], ctypes.c_int),
        "edgephys_client_request_ownership": ([c, u32], ctypes.c_int),
        "edgephys_client_hand_over": ([c, u32, u32], ctypes.c_int),
        "edgephys_client_release_ownership": ([c, u32], ctypes.c_int),
        "edgephys_client_set_takeover_allowed": ([c, u32, u32], ctypes.c_int),
        "edgephys_client_get_owner": ([c, u32, P(u32)], ctypes.c_int),
        "edgephys_client_poll_event": ([c, P(Event)], ctypes.c_int),
        "edgephys_client_send_message": ([c, u32, u32, ctypes.c_char_p, sz], ctypes.c_int),
        "edgephys_client_get_message": ([c, ctypes.c_char_p, sz, P(sz)], ctypes.c_int),
        "edgephys_client_set_property": ([c, u32, ctypes.c_char_p, P(PropertyValue), u32, P(u32)], ctypes.c_int),
        "edgephys_client_compare_and_set_property": ([c, u32, ctypes.c_char_p, P(PropertyValue), u32, u32, P(u32)],
                                                     ctypes.c_int),
        "edgephys_client_get_property": ([c, u32, ctypes.c_char_p, P(PropertyStruct), ctypes.c_void_p, sz],
                                         ctypes.c_int),
        "edgephys_client_get_event_property": ([c, P(PropertyStruct), ctypes.c_void_p, sz], ctypes.c_int),
        "edgephys_client_get_info": ([c, P(ClientInfo)], ctypes.c_int),
        "edgephys_client_get_connection_status": ([c, P(ConnectionStatus)], ctypes.c_int),
        "edgephys_client_get_entity": ([c, u32, P(Entity)], ctypes.c_int),
        "edgephys_client_list_entities": ([c, P(u32), sz, P(sz)], ctypes.c_int),
        "edgephys_client_get_soft_body": ([c, u32, P(Vec3), sz, P(sz)], ctypes.c_int),
        "edgephys_client_sample_pose": ([c, u32, f64, u32, P(Transform)], ctypes.c_int),
        "edgephys_client_get_state_format": ([c, P(u32)], ctypes.c_int),
        "edgephys_client_set_max_playout_delay": ([c, f64], ctypes.c_int),
        "edgephys_client_get_playout_delay": ([c, u32, P(f64)], ctypes.c_int),
    }
    for name, (args, res) in sigs.items():
        fn = getattr(lib, name)
        fn.argtypes = args
        fn.restype = res
    if lib.edgephys_abi_version() != ABI_VERSION:
        raise ImportError(f"libedgephys ABI {lib.edgephys_abi_version()}, this binding needs {ABI_VERSION}")
    return lib


lib = _load()


def now_s():
    """Monotonic clock, seconds (edgephys_now_s)."""
    return lib.edgephys_now_s()


def version():
    return lib.edgephys_version_string().decode()


def reason_name(event_or_type, code=None):
    """The name ("Kicked", "BadToken", ...) of a REJECTED, ERROR or DISCONNECTED event's code:
    reason_name(event) or reason_name(event_type, code); "unknown" otherwise."""
    if code is None:
        event_or_type, code = event_or_type.type, event_or_type.code
    return lib.edgephys_reason_name(event_or_type, code).decode()


def detail(event):
    """An event's detail text (str): for REJECTED, ERROR and DISCONNECTED, why (the operator's
    kick or close text when there was one)."""
    return event.detail.decode("utf-8", "replace")


def _check(status, what=""):
    if status != OK:
        raise EdgephysError(status, (what + ": " if what else "") + lib.edgephys_last_error().decode())


def transform(x=0.0, y=0.0, z=0.0, rotation=(0.0, 0.0, 0.0, 1.0)):
    return Transform(Vec3(x, y, z), Quat(*rotation))


def collider(shape=SHAPE_BOX, **fields):
    """A Collider with the C defaults, then `fields` (half_extents=(x, y, z), radius=..., is_trigger=1)."""
    c = Collider()
    _check(lib.edgephys_collider_init(ctypes.byref(c)))
    for k, v in fields.items():
        setattr(c, k, Vec3(*v) if k in ("half_extents", "local_position") else v)
    c.shape = shape
    return c


def rigid_body(**fields):
    b = RigidBody()
    _check(lib.edgephys_rigid_body_init(ctypes.byref(b)))
    for k, v in fields.items():
        setattr(b, k, Vec3(*v) if k.endswith("velocity") else v)
    return b


class Client:
    """One connection to a relay (edgephys_client). Close it with close() or a with-block."""

    def __init__(self, bind_address=None, queue_state_events=False, event_queue_capacity=4096):
        cfg = ClientConfig()
        _check(lib.edgephys_client_config_init(ctypes.byref(cfg)))
        if bind_address:
            cfg.bind_address = bind_address.encode()
        cfg.queue_state_events = 1 if queue_state_events else 0
        cfg.event_queue_capacity = event_queue_capacity
        self._h = ctypes.c_void_p()
        _check(lib.edgephys_client_create(ctypes.byref(cfg), ctypes.byref(self._h)), "create")
        self._event = Event()
        self._entity = Entity()

    def close(self):
        if self._h:
            lib.edgephys_client_destroy(self._h)
            self._h = ctypes.c_void_p()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        self.close()

    def connect(self, relay, token, now=None):
        _check(lib.edgephys_client_connect(self._h, relay.encode(), token.encode(), now_s() if now is None else now), "connect")

    def update(self, now=None):
        _check(lib.edgephys_client_update(self._h, now_s() if now is None else now), "update")

    def join(self, room):
        _check(lib.edgephys_client_join(self._h, room.encode()), "join")

    def leave(self):
        _check(lib.edgephys_client_leave(self._h), "leave")

    def disconnect(self):
        _check(lib.edgephys_client_disconnect(self._h), "disconnect")

    def spawn(self, position=(0, 0, 0), rotation=(0, 0, 0, 1), flags=0, name=None, rigid_body=None,
              colliders=(), joints=(), parent_id=0, scale=(1, 1, 1)):
        """Spawns an entity (see edgephys_client_spawn); returns its id."""
        d = SpawnDesc()
        _check(lib.edgephys_spawn_desc_init(ctypes.byref(d)))
        d.transform = transform(*position, rotation=rotation)
        d.scale = Vec3(*scale)
        d.parent_id = parent_id
        d.flags = flags
        if name is not None:
            d.name = name.encode()
        if rigid_body is not None:
            d.rigid_body = ctypes.pointer(rigid_body)
        cols = (Collider * len(colliders))(*colliders) if colliders else None
        if cols is not None:
            d.colliders = cols
            d.collider_count = len(colliders)
        jts = (Joint * len(joints))(*joints) if joints else None
        if jts is not None:
            d.joints = jts
            d.joint_count = len(joints)
        out = ctypes.c_uint32()
        _check(lib.edgephys_client_spawn(self._h, ctypes.byref(d), ctypes.byref(out)), "spawn")
        return out.value

    def spawn_static(self, colliders, position=(0, 0, 0), rotation=(0, 0, 0, 1), name=None):
        """Static scenery (ground, walls, a mesh) for PhyS in one call; returns its id
        (edgephys_client_spawn_static: Offloaded | Persistent, no rigid body)."""
        t = transform(*position, rotation=rotation)
        cols = (Collider * len(colliders))(*colliders) if colliders else None
        out = ctypes.c_uint32()
        _check(lib.edgephys_client_spawn_static(self._h, ctypes.byref(t), cols, len(colliders),
                                                name.encode() if name is not None else None,
                                                ctypes.byref(out)), "spawn_static")
        return out.value

    def despawn(self, entity_id):
        _check(lib.edgephys_client_despawn(self._h, entity_id), "despawn")

    def publish(self, entity_id, position, rotation=(0, 0, 0, 1)):
        t = transform(*position, rotation=rotation)
        _check(lib.edgephys_client_publish_transform(self._h, entity_id, ctypes.byref(t)), "publish")

    def grab(self, entity_id, hand_id):
        _check(lib.edgephys_client_grab(self._h, entity_id, hand_id), "grab")

    def release(self, entity_id):
        _check(lib.edgephys_client_release(self._h, entity_id), "release")

    # Ownership (edgephys.h, "ownership"): OWNERSHIP_CHANGED events (ev.entity_id, ev.player_id:
    # the new owner, 0 the room; ev.code: the authority sequence) tell the outcome; refusals
    # come as ERROR events (e.g. REJECT_TAKEOVER_REFUSED).
    def request_ownership(self, entity_id):
        _check(lib.edgephys_client_request_ownership(self._h, entity_id), "request_ownership")

    def hand_over(self, entity_id, player_id):
        _check(lib.edgephys_client_hand_over(self._h, entity_id, player_id), "hand_over")

    def release_ownership(self, entity_id):
        _check(lib.edgephys_client_release_ownership(self._h, entity_id), "release_ownership")

    def set_takeover_allowed(self, entity_id, allowed):
        _check(lib.edgephys_client_set_takeover_allowed(self._h, entity_id, 1 if allowed else 0),
               "set_takeover_allowed")

    def owner(self, entity_id):
        """The entity's owner as this client knows it (0: the room)."""
        out = ctypes.c_uint32(0)
        _check(lib.edgephys_client_get_owner(self._h, entity_id, ctypes.byref(out)), "owner")
        return out.value

    def events(self):
        """Yields queued events (copies) until the queue is empty. A MESSAGE event carries its
        payload as ev.payload (bytes) and its sender as ev.player_id."""
        while True:
            _check(lib.edgephys_client_poll_event(self._h, ctypes.byref(self._event)), "poll")
            if self._event.type == EVENT_NONE:
                return
            ev = Event()
            ctypes.pointer(ev)[0] = self._event
            if ev.type == EVENT_MESSAGE:
                buf = ctypes.create_string_buffer(max(1, ev.code))
                n = ctypes.c_size_t(0)
                _check(lib.edgephys_client_get_message(self._h, buf, len(buf), ctypes.byref(n)), "get_message")
                ev.payload = buf.raw[:n.value]
            if ev.type in (EVENT_PROPERTY_CHANGED, EVENT_PROPERTY_CONFLICT):
                ev.property = self._read_property(ev.detail.decode("utf-8", "replace"),
                                                  lambda p, b, n: lib.edgephys_client_get_event_property(self._h, p, b, n))
            yield ev

    def _read_property(self, key, get):
        raw = PropertyStruct()
        raw.struct_size = ctypes.sizeof(PropertyStruct)
        st = get(ctypes.byref(raw), None, 0)
        data = b""
        if st == E_BUFFER_TOO_SMALL:
            buf = ctypes.create_string_buffer(max(1, raw.value.size))
            st = get(ctypes.byref(raw), ctypes.cast(buf, ctypes.c_void_p), len(buf))
            data = buf.raw[:raw.value.size]
        if st == E_NOT_FOUND:
            return None
        _check(st, "get_property")
        return Property(key, raw, data)

    def set_property(self, key, value, entity_id=0, authority=AUTHORITY_OWNER, kind=None):
        """Writes a property of the room (entity_id 0) or of an entity; returns the request id
        (edgephys_client_set_property). The type follows the value (bool, int, float, str,
        bytes, 3-tuple VEC3, 4-tuple QUAT) unless `kind` (a PROPERTY_*) says."""
        v, keep = _property_value(value, kind)
        out = ctypes.c_uint32()
        _check(lib.edgephys_client_set_property(self._h, entity_id, key.encode(), ctypes.byref(v), authority,
                                                ctypes.byref(out)), "set_property")
        del keep
        return out.value

    def compare_and_set_property(self, key, value, expected_version, entity_id=0, authority=AUTHORITY_OWNER,
                                 kind=None):
        """As set_property, applied only if the property's version is `expected_version` (0: it
        must not exist); otherwise an EVENT_PROPERTY_CONFLICT with the current value follows."""
        v, keep = _property_value(value, kind)
        out = ctypes.c_uint32()
        _check(lib.edgephys_client_compare_and_set_property(self._h, entity_id, key.encode(), ctypes.byref(v),
                                                            expected_version, authority, ctypes.byref(out)),
               "compare_and_set_property")
        del keep
        return out.value

    def get_property(self, key, entity_id=0):
        """The Property as this client knows it, or None."""
        k = key.encode()
        return self._read_property(key, lambda p, b, n: lib.edgephys_client_get_property(self._h, entity_id, k, p, b, n))

    def send_message(self, data, target=TO_ROOM, to_player=0):
        """Sends `data` (bytes, up to MAX_MESSAGE_BYTES) reliably to the room (TO_ROOM), the others
        (TO_OTHERS) or one player (TO_PLAYER, to_player); edgephys_client_send_message."""
        data = bytes(data)
        _check(lib.edgephys_client_send_message(self._h, target, to_player, data, len(data)), "send_message")

    def entity(self, entity_id):
        """The latest Entity, or None if unknown."""
        st = lib.edgephys_client_get_entity(self._h, entity_id, ctypes.byref(self._entity))
        if st == E_NOT_FOUND:
            return None
        _check(st, "get_entity")
        e = Entity()
        ctypes.pointer(e)[0] = self._entity
        return e

    def sample_pose(self, entity_id, method=INTERP_DQ_SCLERP, now=None):
        t = Transform()
        _check(lib.edgephys_client_sample_pose(self._h, entity_id, now_s() if now is None else now, method,
                                               ctypes.byref(t)), "sample_pose")
        return t

    def set_max_playout_delay(self, seconds):
        """Latency limit for sample_pose in seconds: 0 (none) or (0, 4]. A limit below the
        room's adaptive playout costs accuracy (edgephys.h explains)."""
        _check(lib.edgephys_client_set_max_playout_delay(self._h, float(seconds)), "set_max_playout_delay")

    def playout_delay(self, entity_id):
        """The delay (s) the entity is drawn at; None if no state of it has arrived."""
        d = ctypes.c_double(0)
        st = lib.edgephys_client_get_playout_delay(self._h, entity_id, ctypes.byref(d))
        if st == E_NOT_FOUND:
            return None
        _check(st, "get_playout_delay")
        return d.value

    def state_format(self):
        """The joined room's state format (2, 9, 12, 13, 14); None before the first join."""
        f = ctypes.c_uint32(0)
        st = lib.edgephys_client_get_state_format(self._h, ctypes.byref(f))
        if st == E_NOT_FOUND:
            return None
        _check(st, "get_state_format")
        return f.value

    def info(self):
        i = ClientInfo()
        i.struct_size = ctypes.sizeof(ClientInfo)
        _check(lib.edgephys_client_get_info(self._h, ctypes.byref(i)), "get_info")
        return i

    def connection_status(self):
        """The connection's real-time status (rtt_s, loss, *_per_s rates, pending_reliable_bytes...);
        raises EdgephysError(E_NOT_CONNECTED) while there is no connection."""
        st = ConnectionStatus()
        st.struct_size = ctypes.sizeof(ConnectionStatus)
        _check(lib.edgephys_client_get_connection_status(self._h, ctypes.byref(st)), "get_connection_status")
        return st
