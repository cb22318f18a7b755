// edgephys C# binding: P/Invoke over the C API of libedgephys (include/edgephys/edgephys.h,
// the manual for units, ownership and threading), written the way a Unity package is: blittable
// [StructLayout(LayoutKind.Sequential)] structs, a Client class with C# events, and no managed
// allocation per received state (the event struct is reused and passed by ref; state handlers
// get the transform by ref).
//
//   using (var c = new Edgephys.Client()) {
//     c.Connected += id => c.Join("lobby");
//     c.StateReceived += (uint id, ref Edgephys.Transform t) => Render(id, t);
//     c.Connect("127.0.0.1:7777", token);
//     while (running) c.Update();              // every frame
//   }
//
// Build: mcs -unsafe -target:library Edgephys.cs. At run time the loader must find
// libedgephys.so (installed, LD_LIBRARY_PATH, or a Mono dllmap / Unity Plugins folder).
// Thread-safety: a Client is used from one thread at a time (Unity: the main thread); its
// events are raised inside Update() on that thread.
using System;
using System.Runtime.InteropServices;
using System.Text;

namespace Edgephys {

public enum Status : int {
  Ok = 0, InvalidArgument = 1, Malformed = 2, TooLarge = 3, QueueFull = 4, NotConnected = 5,
  IoError = 6, Unauthenticated = 7, PermissionDenied = 8, NotFound = 9, AlreadyExists = 10,
  ResourceExhausted = 11, InvalidHandle = 12, Closed = 13, BufferTooSmall = 14, Internal = 15,
}

public enum EventType : uint {
  None = 0, Connected, Rejected, Disconnected, Joined, PlayerJoined, PlayerLeft, Spawned,
  Despawned, State, SoftBody, CollisionEnter, CollisionExit, TriggerEnter, TriggerExit,
  GuardReset, Grabbed, Released, Error, Message, PropertyChanged, PropertyConflict,
  OwnershipChanged,
}

// Properties (edgephys_app_state.h, "properties"): value types, and who may write a property.
public enum PropertyType : uint { None = 0, Bool, Int64, Double, String, Bytes, Vec3, Quat }
public enum PropertyAuthority : uint { Owner = 0, Anyone = 1 }

// Whom an application message is for (edgephys_client_send_message).
public enum MessageTarget : uint { Room = 0, Others = 1, Player = 2 }

// Reason codes (edgephys_reasons.h): Rejected and Error events carry a RejectReason,
// Disconnected events a DisconnectReason. Native.ReasonName names either.
public enum RejectReason : uint {
  None = 0, BadToken, ExpiredToken, ReplayedToken, RoomFull, ServerFull, WrongRoom, NotOwner,
  UnknownEntity, DuplicateEntity, InvalidMessage, NotJoined, EntityLimit, BadCookie,
  InvalidContainer, GrabRefused, RateLimited, OverBudget, AuthRequired, UnknownPlayer, NotPermitted,
  TakeoverRefused, BadVersion, BadProof,
}
public enum DisconnectReason : uint {
  None = 0, Timeout, ClientLeft, ServerShutdown, Kicked, ProtocolError, ReliableOverflow,
}

[Flags]
public enum EntityFlags : uint {
  None = 0, Persistent = 1, Kinematic = 2, Interactable = 4, Avatar = 8, Hand = 16,
  Offloaded = 32, ReportContacts = 64,
}

public enum ColliderShape : uint { Box = 0, Sphere, Capsule, Cylinder, ConvexHull, TriangleMesh }
// Auto: the recommended method (Hermite).
public enum Interpolator : uint { LerpSlerp = 0, DualQuatDlb, DualQuatSclerp, Hermite, None, Auto }

[StructLayout(LayoutKind.Sequential)]
public struct Vec3 {
  public float X, Y, Z;  // metres (m/s, rad/s where a field says)
  public Vec3(float x, float y, float z) { X = x; Y = y; Z = z; }
  public override string ToString() { return string.Format("({0:F3}, {1:F3}, {2:F3})", X, Y, Z); }
}

[StructLayout(LayoutKind.Sequential)]
public struct Quat {
  public float X, Y, Z, W;  // unit quaternion
  public Quat(float x, float y, float z, float w) { X = x; Y = y; Z = z; W = w; }
  public static readonly Quat Identity = new Quat(0, 0, 0, 1);
}

// edgephys_property_value. String and Bytes values are passed with Client.SetProperty's
// string/byte[] overloads (Data and Size are set there).
[StructLayout(LayoutKind.Sequential)]
public struct PropertyValue {
  public uint Type;
  uint reserved_;
  public long IntValue;       // Bool (0/1), Int64
  public double DoubleValue;  // Double
  public Vec3 Vec3;
  public Quat Quat;
  public IntPtr Data;         // String, Bytes
  public UIntPtr Size;
  public static PropertyValue Bool(bool v) { var p = new PropertyValue(); p.Type = (uint)PropertyType.Bool; p.IntValue = v ? 1 : 0; return p; }
  public static PropertyValue Int64(long v) { var p = new PropertyValue(); p.Type = (uint)PropertyType.Int64; p.IntValue = v; return p; }
  public static PropertyValue Double(double v) { var p = new PropertyValue(); p.Type = (uint)PropertyType.Double; p.DoubleValue = v; return p; }
  public static PropertyValue FromVec3(Vec3 v) { var p = new PropertyValue(); p.Type = (uint)PropertyType.Vec3; p.Vec3 = v; return p; }
  public static PropertyValue FromQuat(Quat q) { var p = new PropertyValue(); p.Type = (uint)PropertyType.Quat; p.Quat = q; return p; }
}

[StructLayout(LayoutKind.Sequential)]
public struct NativeProperty {
  public uint StructSize, EntityId, Version, Writer, Owner, Authority, RequestId, Reserved;
  public PropertyValue Value;
}

// A property as the relay announced it (Client.GetProperty, PropertyChanged, PropertyConflict).
public sealed class Property {
  public uint EntityId;          // 0: a room property
  public string Key;
  public PropertyType Type;      // None: it does not exist (a conflict's current state)
  public uint Version, Writer, Owner, RequestId;
  public PropertyAuthority Authority;
  public long IntValue;          // Bool (0/1), Int64
  public double DoubleValue;
  public Vec3 Vec3;
  public Quat Quat;
  public byte[] Bytes;           // String (UTF-8), Bytes; null otherwise
  public bool BoolValue { get { return IntValue != 0; } }
  public string StringValue { get { return Bytes == null ? null : Encoding.UTF8.GetString(Bytes); } }
}

[StructLayout(LayoutKind.Sequential)]
public struct Transform {
  public Vec3 Position;
  public Quat Rotation;
  public Transform(Vec3 p, Quat r) { Position = p; Rotation = r; }
  public Transform(float x, float y, float z) { Position = new Vec3(x, y, z); Rotation = Quat.Identity; }
}

[StructLayout(LayoutKind.Sequential)]
public struct Collider {
  public uint Shape;
  public Vec3 HalfExtents;
  public float Radius, Height;
  public Vec3 LocalPosition;
  public Quat LocalRotation;
  public IntPtr Vertices;
  public uint VertexFloatCount;
  public IntPtr Indices;
  public uint IndexCount;
  public uint IsTrigger;

  public static Collider Box(float hx, float hy, float hz) {
    Collider c = Default(); c.HalfExtents = new Vec3(hx, hy, hz); return c;
  }
  public static Collider Sphere(float radius, bool trigger = false) {
    Collider c = Default(); c.Shape = (uint)ColliderShape.Sphere; c.Radius = radius;
    c.IsTrigger = trigger ? 1u : 0u; return c;
  }
  public static Collider Default() { Collider c; Native.edgephys_collider_init(out c); return c; }
}

[StructLayout(LayoutKind.Sequential)]
public struct RigidBody {
  public float Mass, LinearDamping, AngularDamping, Friction, Restitution;
  public uint Kinematic, UseGravity;
  public Vec3 LinearVelocity, AngularVelocity;
  public static RigidBody Dynamic(float mass) { RigidBody b; Native.edgephys_rigid_body_init(out b); b.Mass = mass; return b; }
  public static RigidBody KinematicBody() {
    RigidBody b; Native.edgephys_rigid_body_init(out b); b.Kinematic = 1; b.Mass = 0; return b;
  }
}

[StructLayout(LayoutKind.Sequential)]
public struct Joint {
  public uint Kind, ConnectedEntity;
  public Vec3 Anchor, Axis;
  public float Stiffness, Damping;
}

[StructLayout(LayoutKind.Sequential)]
public struct SoftBody {
  public IntPtr Particles, Masses;
  public uint ParticleCount;
  public IntPtr Springs;
  public uint SpringCount;
  public float Stiffness, Damping;
}

[StructLayout(LayoutKind.Sequential)]
public struct NativeSpawnDesc {
  public uint StructSize;
  public Transform Transform;
  public Vec3 Scale;
  public uint ParentId, Flags;
  public IntPtr Name;
  public IntPtr RigidBody, Colliders;
  public uint ColliderCount;
  public IntPtr Joints; public uint JointCount;
  public IntPtr SoftBody;
  public uint OnOwnerLeave;  // appended (edgephys.h on_owner_leave); 0: Default
}

[StructLayout(LayoutKind.Sequential)]
public struct ClientConfig {
  public uint StructSize;
  public IntPtr BindAddress;
  public double PublishRateHz, HandshakeTimeoutS;
  public uint EventQueueCapacity, QueueStateEvents, SnapshotCapacity, RequirePacketAuth;
}

[StructLayout(LayoutKind.Sequential)]
public unsafe struct Event {
  public uint Type, Code, PlayerId, EntityId, OtherId, ParentId, Flags, Reserved;
  public Transform Transform;
  public fixed byte Detail[128];
  public string DetailString() {  // allocates: call only for rare events
    fixed (byte* p = Detail) {
      int n = 0;
      while (n < 128 && p[n] != 0) ++n;
      return Encoding.UTF8.GetString(p, n);
    }
  }
}

[StructLayout(LayoutKind.Sequential)]
public struct ClientInfo {
  public uint StructSize, State, Joined, PlayerId, EntityIdBase, EntityCount, RejectReason, DisconnectReason;
  public ulong DroppedEvents, StatesReceived, StateBytesReceived, StatePayloadsRefused;
}

[StructLayout(LayoutKind.Sequential)]
public struct ConnectionStatus {
  public uint StructSize, State, Reserved, Reserved2;
  public double RttS, RttVarS, Loss, SendBytesPerS, ReceiveBytesPerS, SendPacketsPerS, ReceivePacketsPerS;
  public ulong PacketsSent, PacketsReceived, BytesSent, BytesReceived, ReliableResends, ReliableDelivered,
      StaleDropped, DuplicatesDropped, PendingReliableBytes;
}

[StructLayout(LayoutKind.Sequential)]
public struct Entity {
  public uint Id, Owner, ParentId, Flags, HasState, StateTimeMs, SoftBodyParticles, Reserved;
  public Transform Transform;
}

public class EdgephysException : Exception {
  public readonly Status Status;
  public EdgephysException(Status status, string message) : base(message + " (" + status + ")") { Status = status; }
}

public static class Native {
  const string Lib = "edgephys";
  public const uint AbiVersion = 1;
  [DllImport(Lib)] public static extern uint edgephys_abi_version();
  [DllImport(Lib)] public static extern IntPtr edgephys_version_string();
  [DllImport(Lib)] public static extern IntPtr edgephys_last_error();
  [DllImport(Lib)] public static extern IntPtr edgephys_reason_name(uint eventType, uint code);
  [DllImport(Lib)] public static extern double edgephys_now_s();
  [DllImport(Lib)] public static extern Status edgephys_spawn_desc_init(out NativeSpawnDesc d);
  [DllImport(Lib)] public static extern Status edgephys_collider_init(out Collider c);
  [DllImport(Lib)] public static extern Status edgephys_rigid_body_init(out RigidBody b);
  [DllImport(Lib)] public static extern Status edgephys_joint_init(out Joint j);
  [DllImport(Lib)] public static extern Status edgephys_client_config_init(out ClientConfig c);
  [DllImport(Lib)] public static extern Status edgephys_client_create(ref ClientConfig c, out IntPtr client);
  [DllImport(Lib)] public static extern Status edgephys_client_destroy(IntPtr client);
  [DllImport(Lib)] public static extern Status edgephys_client_close(IntPtr client);
  [DllImport(Lib)] public static extern Status edgephys_client_connect(IntPtr client, byte[] relay, byte[] token, double now);
  [DllImport(Lib)] public static extern Status edgephys_client_update(IntPtr client, double now);
  [DllImport(Lib)] public static extern Status edgephys_client_join(IntPtr client, byte[] room);
  [DllImport(Lib)] public static extern Status edgephys_client_leave(IntPtr client);
  [DllImport(Lib)] public static extern Status edgephys_client_disconnect(IntPtr client);
  [DllImport(Lib)] public static extern Status edgephys_client_spawn(IntPtr client, ref NativeSpawnDesc d, out uint id);
  [DllImport(Lib)] public static extern Status edgephys_client_despawn(IntPtr client, uint id);
  [DllImport(Lib)] public static extern Status edgephys_client_spawn_static(IntPtr client, ref Transform t, Collider[] colliders, uint count, byte[] name, out uint id);
  [DllImport(Lib)] public static extern Status edgephys_client_send_message(IntPtr client, uint target, uint toPlayer, byte[] data, UIntPtr size);
  [DllImport(Lib)] public static extern Status edgephys_client_send_message_unreliable(IntPtr client, uint target, uint toPlayer, byte[] data, UIntPtr size);
  [DllImport(Lib)] public static extern Status edgephys_client_get_message(IntPtr client, byte[] buffer, UIntPtr capacity, out UIntPtr size);
  public const int MaxMessageBytes = 65536;
  public const int MaxUnreliableMessageBytes = 1165;  // EDGEPHYS_MAX_UNRELIABLE_MESSAGE_BYTES
  public const uint MessageUnreliableFlag = 1;         // EDGEPHYS_MESSAGE_UNRELIABLE
  [DllImport(Lib)] public static extern Status edgephys_client_set_property(IntPtr client, uint entity, byte[] key, ref PropertyValue v, uint authority, out uint requestId);
  [DllImport(Lib)] public static extern Status edgephys_client_compare_and_set_property(IntPtr client, uint entity, byte[] key, ref PropertyValue v, uint expectedVersion, uint authority, out uint requestId);
  [DllImport(Lib)] public static extern Status edgephys_client_get_property(IntPtr client, uint entity, byte[] key, ref NativeProperty p, byte[] buffer, UIntPtr capacity);
  [DllImport(Lib)] public static extern Status edgephys_client_get_event_property(IntPtr client, ref NativeProperty p, byte[] buffer, UIntPtr capacity);
  [DllImport(Lib)] public static extern Status edgephys_client_publish_transform(IntPtr client, uint id, ref Transform t);
  [DllImport(Lib)] public static extern Status edgephys_client_grab(IntPtr client, uint entity, uint hand);
  [DllImport(Lib)] public static extern Status edgephys_client_release(IntPtr client, uint entity);
  [DllImport(Lib)] public static extern Status edgephys_client_request_ownership(IntPtr client, uint entity);
  [DllImport(Lib)] public static extern Status edgephys_client_hand_over(IntPtr client, uint entity, uint player);
  [DllImport(Lib)] public static extern Status edgephys_client_release_ownership(IntPtr client, uint entity);
  [DllImport(Lib)] public static extern Status edgephys_client_set_takeover_allowed(IntPtr client, uint entity, uint allowed);
  [DllImport(Lib)] public static extern Status edgephys_client_get_owner(IntPtr client, uint entity, out uint owner);
  [DllImport(Lib)] public static extern Status edgephys_client_poll_event(IntPtr client, ref Event e);
  [DllImport(Lib)] public static extern Status edgephys_client_get_info(IntPtr client, ref ClientInfo info);
  [DllImport(Lib)] public static extern Status edgephys_client_get_connection_status(IntPtr client, ref ConnectionStatus s);
  [DllImport(Lib)] public static extern Status edgephys_client_get_entity(IntPtr client, uint id, out Entity e);
  [DllImport(Lib)] public static extern Status edgephys_client_sample_pose(IntPtr client, uint id, double now, uint method, out Transform t);
  [DllImport(Lib)] public static extern Status edgephys_client_get_state_format(IntPtr client, out uint format);
  [DllImport(Lib)] public static extern Status edgephys_client_set_max_playout_delay(IntPtr client, double maxDelayS);
  [DllImport(Lib)] public static extern Status edgephys_client_get_playout_delay(IntPtr client, uint id, out double delayS);

  public static string LastError() { return Marshal.PtrToStringAnsi(edgephys_last_error()); }
  public static string Version() { return Marshal.PtrToStringAnsi(edgephys_version_string()); }
  // "Kicked", "BadToken", ...: the name of a Rejected, Error or Disconnected event's code.
  public static string ReasonName(EventType type, uint code) {
    return Marshal.PtrToStringAnsi(edgephys_reason_name((uint)type, code));
  }
  public static double Now() { return edgephys_now_s(); }
  public static void Check(Status s, string what) {
    if (s != Status.Ok) throw new EdgephysException(s, what + ": " + LastError());
  }
  internal static byte[] Utf8Z(string s) {
    if (s == null) return null;
    byte[] b = new byte[Encoding.UTF8.GetByteCount(s) + 1];
    Encoding.UTF8.GetBytes(s, 0, s.Length, b, 0);
    return b;
  }
}

// One connection to a relay. Dispose() destroys it.
public sealed partial class Client : IDisposable {
  public delegate void StateHandler(uint entityId, ref Transform transform);
  public delegate void PhysicsHandler(EventType type, uint entityA, uint entityB);

  public event Action<uint> Connected;                // player id
  public event Action<RejectReason, string> Rejected;          // reason, detail (why, for a person)
  public event Action<DisconnectReason, string> Disconnected;  // reason, detail (a kick's or room
                                                               // close's text, else the meaning)
  public event Action<string, uint> Joined;           // room, entity id base
  public event Action<uint> PlayerJoined, PlayerLeft;
  public event Action<Event> Spawned;                 // entity id, owner, parent, flags, transform
  public event Action<uint> Despawned;
  public event StateHandler StateReceived;            // per state: no allocation
  public event PhysicsHandler Physics;                // collision / trigger / grab / guard events
  public event Action<RejectReason, uint, string> Error;  // reason, entity, detail
  public event Action<uint, byte[]> MessageReceived;     // sender, payload (allocates per message)
  public event Action<uint, byte[]> UnreliableMessageReceived;  // SendMessageUnreliable's; else MessageReceived
  public event Action<Property> PropertyChanged;         // the property now (writer, version, ...)
  public event Action<uint, uint, uint> OwnershipChanged;  // entity, new owner (0: the room), authority sequence
  public event Action<uint, Property> PropertyConflict;  // the refused request id, the property now

  IntPtr handle_;
  Event event_;  // reused for every poll

  // queueStateEvents: raise StateReceived for every received state (else read with TryGetEntity).
  public Client(bool queueStateEvents = true, string bindAddress = null) {
    if (Native.edgephys_abi_version() != Native.AbiVersion) {
      throw new EdgephysException(Status.Internal, "libedgephys ABI " + Native.edgephys_abi_version() + ", binding needs " + Native.AbiVersion);
    }
    ClientConfig cfg;
    Native.Check(Native.edgephys_client_config_init(out cfg), "config");
    cfg.QueueStateEvents = queueStateEvents ? 1u : 0u;
    IntPtr bind = bindAddress == null ? IntPtr.Zero : Marshal.StringToHGlobalAnsi(bindAddress);
    try {
      cfg.BindAddress = bind;
      Native.Check(Native.edgephys_client_create(ref cfg, out handle_), "create");
    } finally {
      if (bind != IntPtr.Zero) Marshal.FreeHGlobal(bind);
    }
  }

  public IntPtr Handle { get { return handle_; } }

  public void Dispose() {
    if (handle_ != IntPtr.Zero) {
      Native.edgephys_client_destroy(handle_);
      handle_ = IntPtr.Zero;
    }
    GC.SuppressFinalize(this);
  }
  ~Client() { if (handle_ != IntPtr.Zero) Native.edgephys_client_destroy(handle_); }

  public void Connect(string relay, string token) {
    Native.Check(Native.edgephys_client_connect(handle_, Native.Utf8Z(relay), Native.Utf8Z(token), Native.Now()), "connect");
  }
  public void Join(string room) { Native.Check(Native.edgephys_client_join(handle_, Native.Utf8Z(room)), "join"); }
  public void Leave() { Native.Check(Native.edgephys_client_leave(handle_), "leave"); }
  public void Disconnect() { Native.Check(Native.edgephys_client_disconnect(handle_), "disconnect"); }
  // Static scenery (ground, walls, a mesh) for PhyS in one call (edgephys_client_spawn_static).
  public uint SpawnStatic(Transform transform, Collider[] colliders, string name = null) {
    if (colliders == null) throw new EdgephysException(Status.InvalidArgument, "colliders is null");
    uint id;
    Native.Check(Native.edgephys_client_spawn_static(handle_, ref transform, colliders, (uint)colliders.Length,
                                                     name == null ? null : Native.Utf8Z(name), out id), "spawn_static");
    return id;
  }
  // Sends `data` reliably to the room, the others or one player (edgephys_client_send_message);
  // MessageReceived raises it at each addressed member with this player's id.
  public void SendMessage(byte[] data, MessageTarget target = MessageTarget.Room, uint toPlayer = 0) {
    if (data == null) throw new EdgephysException(Status.InvalidArgument, "data is null");
    Native.Check(Native.edgephys_client_send_message(handle_, (uint)target, toPlayer, data, (UIntPtr)data.Length), "send_message");
  }

  // Sends `data` (at most Native.MaxUnreliableMessageBytes) unreliably in one datagram: it may be
  // lost, never arrives twice nor after a later one of this player's unreliable messages
  // (edgephys_client_send_message_unreliable). Status.TooLarge over the limit.
  public void SendMessageUnreliable(byte[] data, MessageTarget target = MessageTarget.Room, uint toPlayer = 0) {
    if (data == null) throw new EdgephysException(Status.InvalidArgument, "data is null");
    Native.Check(Native.edgephys_client_send_message_unreliable(handle_, (uint)target, toPlayer, data, (UIntPtr)data.Length), "send_message_unreliable");
  }
  // Receives, then raises the events of everything that arrived. Call every frame.
  public void Update() { Update(Native.Now()); }
  public void Update(double now) {
    Native.Check(Native.edgephys_client_update(handle_, now), "update");
    for (;;) {
      Native.Check(Native.edgephys_client_poll_event(handle_, ref event_), "poll");
      if (event_.Type == (uint)EventType.None) return;
      Dispatch();
    }
  }

  void Dispatch() {
    switch ((EventType)event_.Type) {
      case EventType.State:
        if (StateReceived != null) StateReceived(event_.EntityId, ref event_.Transform);
        break;
      case EventType.Connected: if (Connected != null) Connected(event_.PlayerId); break;
      case EventType.Rejected: if (Rejected != null) Rejected((RejectReason)event_.Code, event_.DetailString()); break;
      case EventType.Disconnected:
        if (Disconnected != null) Disconnected((DisconnectReason)event_.Code, event_.DetailString());
        break;
      case EventType.Joined: if (Joined != null) Joined(event_.DetailString(), event_.EntityId); break;
      case EventType.PlayerJoined: if (PlayerJoined != null) PlayerJoined(event_.PlayerId); break;
      case EventType.PlayerLeft: if (PlayerLeft != null) PlayerLeft(event_.PlayerId); break;
      case EventType.Spawned: if (Spawned != null) Spawned(event_); break;
      case EventType.Despawned: if (Despawned != null) Despawned(event_.EntityId); break;
      case EventType.Message:
        {
          bool unreliable = (event_.Flags & Native.MessageUnreliableFlag) != 0 && UnreliableMessageReceived != null;
          Action<uint, byte[]> handler = unreliable ? UnreliableMessageReceived : MessageReceived;
          if (handler == null) break;
          byte[] payload = new byte[event_.Code];
          UIntPtr n;
          Native.Check(Native.edgephys_client_get_message(handle_, payload, (UIntPtr)payload.Length, out n), "get_message");
          handler(event_.PlayerId, payload);
        }
        break;
      case EventType.PropertyChanged:
        if (PropertyChanged != null) PropertyChanged(EventProperty());
        break;
      case EventType.OwnershipChanged:
        if (OwnershipChanged != null) OwnershipChanged(event_.EntityId, event_.PlayerId, event_.Code);
        break;
      case EventType.PropertyConflict:
        if (PropertyConflict != null) PropertyConflict(event_.OtherId, EventProperty());
        break;
      case EventType.Error: if (Error != null) Error((RejectReason)event_.Code, event_.EntityId, event_.DetailString()); break;
      case EventType.CollisionEnter: case EventType.CollisionExit: case EventType.TriggerEnter:
      case EventType.TriggerExit: case EventType.GuardReset: case EventType.Grabbed: case EventType.Released:
        if (Physics != null) Physics((EventType)event_.Type, event_.EntityId, event_.OtherId);
        break;
      default: break;
    }
  }

  // Spawns an entity (the dissected container: rigid body, colliders, joints); returns its id.
  public unsafe uint Spawn(Transform transform, EntityFlags flags, RigidBody? body = null,
                           Collider[] colliders = null, Joint[] joints = null, uint parentId = 0,
                           string name = null) {
    NativeSpawnDesc d;
    Native.Check(Native.edgephys_spawn_desc_init(out d), "spawn_desc_init");
    d.Transform = transform;
    d.Flags = (uint)flags;
    d.ParentId = parentId;
    RigidBody b = body.HasValue ? body.Value : default(RigidBody);
    byte[] nameBytes = Native.Utf8Z(name);
    Collider[] cs = colliders ?? new Collider[0];
    Joint[] js = joints ?? new Joint[0];
    fixed (Collider* pc = cs)
    fixed (Joint* pj = js)
    fixed (byte* pn = nameBytes) {
      d.RigidBody = body.HasValue ? (IntPtr)(&b) : IntPtr.Zero;
      d.Colliders = (IntPtr)pc;
      d.ColliderCount = (uint)cs.Length;
      d.Joints = (IntPtr)pj;
      d.JointCount = (uint)js.Length;
      d.Name = (IntPtr)pn;
      uint id;
      Native.Check(Native.edgephys_client_spawn(handle_, ref d, out id), "spawn");
      return id;
    }
  }
  // Properties. Writes a property of the room (entityId 0) or of an entity; returns the request
  // id its events carry (edgephys_client_set_property, _compare_and_set_property: expected
  // version 0 means it must not exist yet).
  public uint SetProperty(uint entityId, string key, PropertyValue value, PropertyAuthority authority = PropertyAuthority.Owner) {
    uint id;
    Native.Check(Native.edgephys_client_set_property(handle_, entityId, Native.Utf8Z(key), ref value, (uint)authority, out id), "set_property");
    return id;
  }
  public uint SetProperty(uint entityId, string key, string text, PropertyAuthority authority = PropertyAuthority.Owner) {
    return WriteBytes(entityId, key, PropertyType.String, text == null ? null : Encoding.UTF8.GetBytes(text), false, 0, authority);
  }
  public uint SetProperty(uint entityId, string key, byte[] data, PropertyAuthority authority = PropertyAuthority.Owner) {
    return WriteBytes(entityId, key, PropertyType.Bytes, data, false, 0, authority);
  }
  public uint CompareAndSetProperty(uint entityId, string key, PropertyValue value, uint expectedVersion,
                                    PropertyAuthority authority = PropertyAuthority.Owner) {
    uint id;
    Native.Check(Native.edgephys_client_compare_and_set_property(handle_, entityId, Native.Utf8Z(key), ref value, expectedVersion,
                                                                 (uint)authority, out id), "compare_and_set_property");
    return id;
  }
  public uint CompareAndSetProperty(uint entityId, string key, string text, uint expectedVersion,
                                    PropertyAuthority authority = PropertyAuthority.Owner) {
    return WriteBytes(entityId, key, PropertyType.String, text == null ? null : Encoding.UTF8.GetBytes(text), true, expectedVersion, authority);
  }
  // The property as this client knows it; null if unknown.
  public Property GetProperty(uint entityId, string key) {
    byte[] k = Native.Utf8Z(key);
    return ReadProperty(key, (ref NativeProperty p, byte[] b, UIntPtr n) => Native.edgephys_client_get_property(handle_, entityId, k, ref p, b, n));
  }

  unsafe uint WriteBytes(uint entityId, string key, PropertyType type, byte[] data, bool check, uint expected, PropertyAuthority authority) {
    if (data == null) throw new EdgephysException(Status.InvalidArgument, "value is null");
    var v = new PropertyValue();
    v.Type = (uint)type;
    uint id;
    fixed (byte* p = data) {
      v.Data = (IntPtr)p;
      v.Size = (UIntPtr)data.Length;
      Native.Check(check ? Native.edgephys_client_compare_and_set_property(handle_, entityId, Native.Utf8Z(key), ref v, expected, (uint)authority, out id)
                         : Native.edgephys_client_set_property(handle_, entityId, Native.Utf8Z(key), ref v, (uint)authority, out id),
                   "set_property");
    }
    return id;
  }

  delegate Status PropertyGetter(ref NativeProperty p, byte[] buffer, UIntPtr capacity);
  Property ReadProperty(string key, PropertyGetter get) {
    var raw = new NativeProperty();
    raw.StructSize = (uint)Marshal.SizeOf(typeof(NativeProperty));
    byte[] buffer = null;
    Status s = get(ref raw, null, UIntPtr.Zero);
    if (s == Status.BufferTooSmall) {
      buffer = new byte[(int)raw.Value.Size];
      s = get(ref raw, buffer, (UIntPtr)buffer.Length);
    }
    if (s == Status.NotFound) return null;
    Native.Check(s, "get_property");
    var t = (PropertyType)raw.Value.Type;
    var prop = new Property {
      EntityId = raw.EntityId, Key = key, Type = t, Version = raw.Version, Writer = raw.Writer, Owner = raw.Owner,
      RequestId = raw.RequestId, Authority = (PropertyAuthority)raw.Authority, IntValue = raw.Value.IntValue,
      DoubleValue = raw.Value.DoubleValue, Vec3 = raw.Value.Vec3, Quat = raw.Value.Quat,
    };
    if (t == PropertyType.String || t == PropertyType.Bytes) prop.Bytes = buffer ?? new byte[0];
    return prop;
  }
  Property EventProperty() {
    return ReadProperty(event_.DetailString(), (ref NativeProperty p, byte[] b, UIntPtr n) => Native.edgephys_client_get_event_property(handle_, ref p, b, n));
  }

  public void Despawn(uint id) { Native.Check(Native.edgephys_client_despawn(handle_, id), "despawn"); }
  public void Publish(uint id, Transform t) { Native.Check(Native.edgephys_client_publish_transform(handle_, id, ref t), "publish"); }
  public void Grab(uint entity, uint hand) { Native.Check(Native.edgephys_client_grab(handle_, entity, hand), "grab"); }
  public void Release(uint entity) { Native.Check(Native.edgephys_client_release(handle_, entity), "release"); }

  // Ownership (edgephys_app_state.h, "ownership"): OwnershipChanged tells the outcome; refusals come as
  // Error (e.g. RejectReason.TakeoverRefused).
  public void RequestOwnership(uint entity) {
    Native.Check(Native.edgephys_client_request_ownership(handle_, entity), "request ownership");
  }
  public void HandOver(uint entity, uint player) {
    Native.Check(Native.edgephys_client_hand_over(handle_, entity, player), "hand over");
  }
  public void ReleaseOwnership(uint entity) {
    Native.Check(Native.edgephys_client_release_ownership(handle_, entity), "release ownership");
  }
  public void SetTakeoverAllowed(uint entity, bool allowed) {
    Native.Check(Native.edgephys_client_set_takeover_allowed(handle_, entity, allowed ? 1u : 0u), "set takeover");
  }
  // The entity's owner as this client knows it (0: the room).
  public uint Owner(uint entity) {
    uint owner;
    Native.Check(Native.edgephys_client_get_owner(handle_, entity, out owner), "owner");
    return owner;
  }

  public bool TryGetEntity(uint id, out Entity e) { return Native.edgephys_client_get_entity(handle_, id, out e) == Status.Ok; }
  public bool TrySamplePose(uint id, Interpolator method, out Transform t) {
    return Native.edgephys_client_sample_pose(handle_, id, Native.Now(), (uint)method, out t) == Status.Ok;
  }
  // Latency limit for TrySamplePose in seconds: 0 (no limit) or (0, 4]; see
  // edgephys_client_set_max_playout_delay for what it costs.
  public void SetMaxPlayoutDelay(double seconds) {
    Native.Check(Native.edgephys_client_set_max_playout_delay(handle_, seconds), "set_max_playout_delay");
  }
  // The delay entity `id` is drawn at, seconds; false if no state of it has arrived.
  public bool TryGetPlayoutDelay(uint id, out double seconds) {
    return Native.edgephys_client_get_playout_delay(handle_, id, out seconds) == Status.Ok;
  }
  // The joined room's state format (2, 9, 12, 13, 14); 0 before the first join.
  public uint StateFormat {
    get { uint f; return Native.edgephys_client_get_state_format(handle_, out f) == Status.Ok ? f : 0u; }
  }
  public ClientInfo Info() {
    ClientInfo info = new ClientInfo();
    info.StructSize = (uint)Marshal.SizeOf(typeof(ClientInfo));
    Native.Check(Native.edgephys_client_get_info(handle_, ref info), "get_info");
    return info;
  }
  // The connection's real-time status; false (and `s` zeroed) while there is no connection.
  public bool TryGetConnectionStatus(out ConnectionStatus s) {
    s = new ConnectionStatus();
    s.StructSize = (uint)Marshal.SizeOf(typeof(ConnectionStatus));
    return Native.edgephys_client_get_connection_status(handle_, ref s) == Status.Ok;
  }
}

}  // namespace Edgephys
