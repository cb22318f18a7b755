// The edgephys SDK example in C# (bindings/csharp, as a Unity script would use it): the same
// program as examples/c/stack_and_grab.c. Join, spawn a local-physics head and two hands,
// offload a stack of three boxes, wait until they fall and settle, grab the top box, carry it
// aside, release it, print every physics event, and end with the settled poses of the boxes.
//   mono StackAndGrab.exe <relay host:port> <join token> <room>
using System;
using System.Collections.Generic;
using System.Threading;
using Edgephys;

static class StackAndGrab {
  struct Ev { public EventType Type; public uint A, B; }
  static Client c;
  static readonly List<Ev> log = new List<Ev>();
  static bool connected, joined;
  static uint otherPlayer;  // the latest other player who joined

  static void Fail(string why) { Console.WriteLine("FAIL: " + why); Environment.Exit(1); }

  static void Pump() { c.Update(); Thread.Sleep(10); }
  static void RunFor(double s) { double end = Native.Now() + s; while (Native.Now() < end) Pump(); }
  static void WaitFor(Func<bool> done, double timeout, string what) {
    double end = Native.Now() + timeout;
    while (!done()) { if (Native.Now() > end) Fail(what); Pump(); }
  }
  static int Find(EventType type, uint a, uint b) {
    for (int i = 0; i < log.Count; ++i) if (log[i].Type == type && log[i].A == a && log[i].B == b) return i;
    return -1;
  }
  static bool State(uint id, out Transform t) {
    Entity e;
    t = default(Transform);
    if (!c.TryGetEntity(id, out e) || e.HasState == 0) return false;
    t = e.Transform;
    return true;
  }
  static bool Settled(uint[] ids) {
    var before = new Transform[ids.Length];
    for (int i = 0; i < ids.Length; ++i) if (!State(ids[i], out before[i])) return false;
    RunFor(0.5);
    for (int i = 0; i < ids.Length; ++i) {
      Transform a;
      if (!State(ids[i], out a)) return false;
      float dx = a.Position.X - before[i].Position.X, dy = a.Position.Y - before[i].Position.Y, dz = a.Position.Z - before[i].Position.Z;
      if (Math.Sqrt(dx * dx + dy * dy + dz * dz) > 0.001) return false;
    }
    return true;
  }
  static void WaitSettled(uint[] ids) {
    double end = Native.Now() + 10;
    while (!Settled(ids)) { if (Native.Now() > end) Fail("the boxes did not settle"); Pump(); }
  }

  static int Main(string[] args) {
    if (args.Length != 3) { Console.Error.WriteLine("usage: StackAndGrab.exe <relay host:port> <join token> <room>"); return 2; }
    Console.WriteLine("edgephys " + Native.Version() + ", ABI " + Native.edgephys_abi_version());
    c = new Client(false);
    c.Connected += id => connected = true;
    c.Joined += (room, b) => joined = true;
    c.PlayerJoined += id => otherPlayer = id;
    c.Rejected += (r, detail) => Fail("rejected " + r + ": " + detail);
    c.Disconnected += (r, detail) => Fail("disconnected " + r + ": " + detail);
    c.Error += (reason, id, detail) => Console.WriteLine("error reason " + reason + " entity " + id + ": " + detail);
    c.Physics += (type, a, b) => {
      Console.WriteLine("event " + Name(type) + " " + a + " " + b);
      log.Add(new Ev { Type = type, A = a, B = b });
    };
    c.Connect(args[0], args[1]);
    WaitFor(() => connected, 5, "no connection");
    c.Join(args[2]);
    WaitFor(() => joined, 5, "no join");
    // A chat line to everyone else in the room (reliable; they get it with our player id).
    c.SendMessage(System.Text.Encoding.UTF8.GetBytes("hello from the C# example"), MessageTarget.Others);
    // A shared "current step" (a room property anyone may write), proposed with compare-and-set,
    // expected version 0 (only if nobody set it yet). Another player may propose at the same
    // time: the relay takes exactly one proposal, the other writer gets PropertyConflict with the
    // winner's value, and both end on the same step.
    c.CompareAndSetProperty(0, "step", PropertyValue.Int64(1), 0, PropertyAuthority.Anyone);
    WaitFor(() => { var p = c.GetProperty(0, "step"); return p != null && p.Version >= 1; }, 5, "no agreed step");
    Property step = c.GetProperty(0, "step");
    Console.WriteLine("agreed step: " + step.IntValue + " (written by player " + step.Writer + ")");

    uint ground = c.Spawn(new Transform(0, -0.5f, 0), EntityFlags.Offloaded, null, new[] { Collider.Box(5, 0.5f, 5) }, name: "ground");
    RigidBody kinematic = RigidBody.KinematicBody();
    uint head = c.Spawn(new Transform(0, 1.6f, 1), EntityFlags.Avatar, kinematic, new[] { Collider.Sphere(0.1f) }, name: "head");
    uint[] hands = {
      c.Spawn(new Transform(-0.3f, 1.2f, 1), EntityFlags.Hand, kinematic, new[] { Collider.Sphere(0.15f, true) }, name: "left hand"),
      c.Spawn(new Transform(0.3f, 1.2f, 1), EntityFlags.Hand, kinematic, new[] { Collider.Sphere(0.15f, true) }, name: "right hand"),
    };
    var boxes = new uint[3];
    for (int i = 0; i < 3; ++i) {
      boxes[i] = c.Spawn(new Transform(0, 0.3f + 0.3f * i, 0),
                         EntityFlags.Offloaded | EntityFlags.Interactable | EntityFlags.ReportContacts,
                         RigidBody.Dynamic(1), new[] { Collider.Box(0.1f, 0.1f, 0.1f) }, name: "box");
    }
    Console.WriteLine("spawned ground {0} head {1} hands {2} {3} boxes {4} {5} {6}", ground, head, hands[0], hands[1], boxes[0], boxes[1], boxes[2]);

    WaitSettled(boxes);
    for (int i = 0; i < 3; ++i) {
      Transform t;
      State(boxes[i], out t);
      Console.WriteLine("settled box {0} at {1}", boxes[i], t.Position);
      if (Math.Abs(t.Position.Y - (0.1f + 0.2f * i)) > 0.03f) Fail("a box is not where the stack puts it");
    }

    uint top = boxes[2], below = boxes[1], hand = hands[1];
    Transform top0;
    State(top, out top0);
    float y0 = top0.Position.Y + 0.05f;
    c.Publish(hand, new Transform(top0.Position.X, y0, top0.Position.Z));
    WaitFor(() => Find(EventType.TriggerEnter, hand, top) >= 0, 3, "the hand's trigger never reported the box");
    c.Grab(top, hand);
    WaitFor(() => Find(EventType.Grabbed, top, hand) >= 0, 3, "no Grabbed event");
    double start = Native.Now();
    for (double t = 0; t < 1.0; t = Native.Now() - start) {
      c.Publish(hand, new Transform(0.6f * (float)t, y0 + 0.4f * (float)t, top0.Position.Z));
      Pump();
    }
    c.Release(top);
    c.Publish(hand, new Transform(0.3f, 1.2f, 1));
    WaitFor(() => Find(EventType.Released, top, hand) >= 0, 3, "no Released event");
    WaitSettled(boxes);

    int grabbed = Find(EventType.Grabbed, top, hand), leftStack = Find(EventType.CollisionExit, below, top),
        released = Find(EventType.Released, top, hand), landed = -1;
    for (int i = released + 1; i < log.Count && landed < 0; ++i) {
      if (log[i].Type == EventType.CollisionEnter && (log[i].A == top || log[i].B == top)) landed = i;
    }
    if (!(grabbed >= 0 && leftStack > grabbed && released > leftStack && landed > released)) {
      Fail(string.Format("event order grabbed {0} left_stack {1} released {2} landed {3}", grabbed, leftStack, released, landed));
    }
    Transform final;
    State(top, out final);
    if (final.Position.X < 0.4f || Math.Abs(final.Position.Y - 0.1f) > 0.03f) Fail("the released box is not on the ground");
    Transform smooth;
    if (!c.TrySamplePose(top, Interpolator.DualQuatSclerp, out smooth)) Fail("sample_pose");
    Console.WriteLine("interpolated top box at " + smooth.Position);
    foreach (uint id in boxes) {
      Transform t;
      State(id, out t);
      Console.WriteLine(string.Format(System.Globalization.CultureInfo.InvariantCulture,
          "pose {0} {1:F6} {2:F6} {3:F6} {4:F6} {5:F6} {6:F6} {7:F6}", id, t.Position.X, t.Position.Y,
          t.Position.Z, t.Rotation.X, t.Rotation.Y, t.Rotation.Z, t.Rotation.W));
    }
    // An ownership handoff of a local-physics object: a baton this client simulates itself (not
    // offloaded) goes to another player; once the relay announces it, the new owner's states
    // are the ones everyone gets.
    uint baton = c.Spawn(new Transform(2, 0.1f, 0), 0, RigidBody.Dynamic(1), new[] { Collider.Box(0.1f, 0.1f, 0.1f) }, name: "baton");
    RunFor(0.2);
    uint other = otherPlayer;
    if (other == 0) Fail("nobody to hand the baton to");
    c.HandOver(baton, other);
    WaitFor(() => c.Owner(baton) == other, 5, "the handoff was not announced");
    WaitFor(() => { Transform b; return State(baton, out b) && Math.Abs(b.Position.Y - 0.5f) < 0.01f; }, 5,
            "no state of the baton from its new owner");
    Console.WriteLine("handoff: entity " + baton + " to player " + other + ", its state now comes from player " + other);
    RunFor(1.0);  // let a watcher see the same settled poses before we leave
    c.Disconnect();
    c.Dispose();
    Console.WriteLine("ok");
    return 0;
  }

  static string Name(EventType t) {
    switch (t) {
      case EventType.CollisionEnter: return "collision_enter";
      case EventType.CollisionExit: return "collision_exit";
      case EventType.TriggerEnter: return "trigger_enter";
      case EventType.TriggerExit: return "trigger_exit";
      case EventType.Grabbed: return "grabbed";
      case EventType.Released: return "released";
      default: return "guard_reset";
    }
  }
}
