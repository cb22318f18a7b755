"""The binding's constants and plain structs: status, event, reason and property codes as the C
header defines them, the ctypes mirrors of its structs, and the property value conversion.
Internal: import them from `edgephys`."""
import ctypes

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

# Properties (edgephys_app_state.h, "properties"): value types and who may write a property.
(PROPERTY_NONE, PROPERTY_BOOL, PROPERTY_INT64, PROPERTY_DOUBLE, PROPERTY_STRING, PROPERTY_BYTES,
 PROPERTY_VEC3, PROPERTY_QUAT) = range(8)
AUTHORITY_OWNER, AUTHORITY_ANYONE = 0, 1
# What the relay does with an entity when its owner leaves (edgephys_app_state.h,
# EDGEPHYS_OWNER_LEAVE_*): DEFAULT follows the Persistent flag (stay) or its absence (despawn).
OWNER_LEAVE_DEFAULT, OWNER_LEAVE_STAY, OWNER_LEAVE_PHYS, OWNER_LEAVE_DESPAWN = range(4)
MAX_PROPERTY_KEY_BYTES = 64
MAX_PROPERTY_VALUE_BYTES = 65536

# Application messages (edgephys_client_send_message): whom a message is for.
TO_ROOM, TO_OTHERS, TO_PLAYER = 0, 1, 2
MAX_MESSAGE_BYTES = 65536
MAX_UNRELIABLE_MESSAGE_BYTES = 1165  # send_message_unreliable: one datagram
MESSAGE_UNRELIABLE = 1  # bit of a MESSAGE event's flags: it came unreliably

# Reason codes (edgephys_reasons.h): REJECTED and ERROR events carry a reject reason,
# DISCONNECTED events a disconnect reason; reason_name(event) names either.
(REJECT_NONE, REJECT_BAD_TOKEN, REJECT_EXPIRED_TOKEN, REJECT_REPLAYED_TOKEN, REJECT_ROOM_FULL,
 REJECT_SERVER_FULL, REJECT_WRONG_ROOM, REJECT_NOT_OWNER, REJECT_UNKNOWN_ENTITY, REJECT_DUPLICATE_ENTITY,
 REJECT_INVALID_MESSAGE, REJECT_NOT_JOINED, REJECT_ENTITY_LIMIT, REJECT_BAD_COOKIE, REJECT_INVALID_CONTAINER,
 REJECT_GRAB_REFUSED, REJECT_RATE_LIMITED, REJECT_OVER_BUDGET, REJECT_AUTH_REQUIRED, REJECT_UNKNOWN_PLAYER,
 REJECT_NOT_PERMITTED, REJECT_TAKEOVER_REFUSED, REJECT_BAD_VERSION, REJECT_BAD_PROOF) = range(24)
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
                ("states_received", ctypes.c_uint64), ("state_bytes_received", ctypes.c_uint64),
                ("state_payloads_refused", ctypes.c_uint64)]


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
