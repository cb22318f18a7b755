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

from ._types import *  # noqa: F401,F403 (the public constants and structs)
from ._types import _property_value


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

    # Ownership (edgephys_app_state.h, "ownership"): OWNERSHIP_CHANGED events (ev.entity_id, ev.player_id:
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
