// Tests of the C# binding, run by a console runner under Mono (ctest: sdk_csharp_test, started
// by tests/with_relay.sh, which provides a real relay in EDGEPHYS_RELAY and two tokens).
//   ClientTests.exe            the tests (bad arguments; reasons; zero allocation per state)
//   ClientTests.exe --bench N  the per-state cost of Client.Update with N moving entities
using System;
using System.Diagnostics;
using System.Runtime.InteropServices;
using Edgephys;

static class ClientTests {
  static int failures = 0;

  static void Expect(bool ok, string what) {
    if (!ok) { Console.WriteLine("  FAIL: " + what); ++failures; }
  }

  static void ExpectStatus(Status expected, Action call, string what) {
    try {
      call();
      Expect(false, what + ": no exception, expected " + expected);
    } catch (EdgephysException e) {
      Expect(e.Status == expected, what + ": got " + e.Status + ", expected " + expected + " (" + e.Message + ")");
    }
  }

  static void BadArgumentsThrowWithTheirStatus() {
    Expect(Native.edgephys_abi_version() == Native.AbiVersion, "ABI version");
    using (var c = new Client(true, "127.0.0.1:0")) {
      ExpectStatus(Status.Malformed, () => c.Connect("nowhere", "AAAA"), "connect to a bad address");
      ExpectStatus(Status.NotConnected, () => c.Join("lobby"), "join before connecting");
      ExpectStatus(Status.InvalidArgument, () => c.Join(""), "empty room");
      ExpectStatus(Status.InvalidArgument, () => c.Publish(65537, new Transform(float.NaN, 0, 0)), "NaN publish");
      ExpectStatus(Status.InvalidArgument,
                   () => c.Spawn(new Transform(0, 1, 0), EntityFlags.Offloaded, RigidBody.Dynamic(float.NaN)), "NaN mass");
      ExpectStatus(Status.InvalidArgument,
                   () => c.Spawn(new Transform(0, 1, 0), EntityFlags.None, null, new[] { Collider.Box(-1, 1, 1) }), "negative box");
      ExpectStatus(Status.InvalidArgument,
                   () => c.Spawn(new Transform(new Vec3(0, 0, 0), new Quat(0, 0, 0, 0)), EntityFlags.None), "zero quaternion");
      ExpectStatus(Status.NotConnected, () => c.Spawn(new Transform(0, 1, 0), EntityFlags.None), "valid spawn, not joined");
      ExpectStatus(Status.InvalidArgument, () => c.Grab(0, 1), "grab entity 0");
      ExpectStatus(Status.InvalidArgument, () => c.SpawnStatic(new Transform(0, 0, 0), new Collider[0]), "scenery without colliders");
      ExpectStatus(Status.NotConnected, () => c.SpawnStatic(new Transform(0, -0.5f, 0), new[] { Collider.Box(5, 0.5f, 5) }, "ground"),
                   "valid scenery, not joined");
      Entity e;
      Expect(!c.TryGetEntity(1, out e), "unknown entity");
      Expect(c.StateFormat == 0, "state format before a join");
      Transform pose;
      Expect(!c.TrySamplePose(1, Interpolator.Auto, out pose), "Auto pose of an unknown entity");
      ExpectStatus(Status.InvalidArgument, () => c.SetMaxPlayoutDelay(double.NaN), "NaN playout limit");
      ExpectStatus(Status.InvalidArgument, () => c.SetMaxPlayoutDelay(-0.1), "negative playout limit");
      ExpectStatus(Status.InvalidArgument, () => c.SetMaxPlayoutDelay(4.5), "playout limit over 4 s");
      c.SetMaxPlayoutDelay(0.1);
      c.SetMaxPlayoutDelay(0);
      double delay;
      Expect(!c.TryGetPlayoutDelay(1, out delay), "playout delay of an unknown entity");
      c.Dispose();
      ExpectStatus(Status.InvalidHandle, () => c.Join("lobby"), "use after Dispose");
    }
    ExpectStatus(Status.Malformed, () => new Client(true, "garbage"), "bad bind address");
  }

  // A sender moves `entities` entities every frame; the receiver's Update() (receive, poll,
  // raise StateReceived) is measured after a warm-up: managed bytes allocated and CPU time.
  static void Stream(int entities, double warmup_s, double measure_s, out long states, out long bytes, out double ns_per_state) {
    string relay = Environment.GetEnvironmentVariable("EDGEPHYS_RELAY");
    string room = Environment.GetEnvironmentVariable("EDGEPHYS_ROOM");
    using (var sender = new Client(false))
    using (var receiver = new Client(true)) {
      bool sConnected = false, rConnected = false, sJoined = false, rJoined = false;
      sender.Connected += id => sConnected = true;
      receiver.Connected += id => rConnected = true;
      sender.Joined += (r, b) => sJoined = true;
      receiver.Joined += (r, b) => rJoined = true;
      long received = 0;
      receiver.StateReceived += (uint id, ref Transform t) => { received++; };
      ConnectionStatus cs;
      Expect(!receiver.TryGetConnectionStatus(out cs), "no connection status before connecting");
      Expect(Marshal.SizeOf(typeof(ConnectionStatus)) == 144, "ConnectionStatus matches the C struct's 144 bytes");
      Expect(Marshal.SizeOf(typeof(ClientInfo)) == 64, "ClientInfo matches the C struct's 64 bytes");
      Expect(receiver.Info().StatePayloadsRefused == 0, "no state payload refused before connecting");
      sender.Connect(relay, Environment.GetEnvironmentVariable("EDGEPHYS_TOKEN_1"));
      receiver.Connect(relay, Environment.GetEnvironmentVariable("EDGEPHYS_TOKEN_2"));
      double end = Native.Now() + 5;
      while (!(sConnected && rConnected) && Native.Now() < end) { sender.Update(); receiver.Update(); System.Threading.Thread.Sleep(5); }
      if (!(sConnected && rConnected)) throw new Exception("no connection to " + relay);
      sender.Join(room);
      receiver.Join(room);
      while (!(sJoined && rJoined) && Native.Now() < end) { sender.Update(); receiver.Update(); System.Threading.Thread.Sleep(5); }
      if (!(sJoined && rJoined)) throw new Exception("no join");
      Expect(receiver.StateFormat == 9, "the relay's default state format (9), got " + receiver.StateFormat);
      uint[] ids = new uint[entities];
      for (int i = 0; i < entities; ++i) ids[i] = sender.Spawn(new Transform(i, 1, 0), EntityFlags.None);

      double start = Native.Now();
      long allocated = 0, received0 = 0;
      double cpu = 0;
      bool measuring = false;
      var watch = new Stopwatch();
      for (;;) {
        double now = Native.Now();
        if (now - start > warmup_s + measure_s) break;
        if (!measuring && now - start > warmup_s) {
          measuring = true;
          received0 = received;
          allocated = 0;
          cpu = 0;
        }
        float phase = (float)(now - start);
        for (int i = 0; i < entities; ++i) {
          sender.Publish(ids[i], new Transform(i + 0.5f * (float)Math.Sin(phase + i), 1, 0));
        }
        sender.Update(now);
        long before = GC.GetAllocatedBytesForCurrentThread();
        watch.Restart();
        receiver.Update(now);
        watch.Stop();
        long after = GC.GetAllocatedBytesForCurrentThread();
        // Only the receiver's Update() is counted (bracketed call by call), not the sender's.
        allocated += after - before;
        cpu += watch.Elapsed.TotalMilliseconds * 1e6;
        System.Threading.Thread.Sleep(2);
      }
      Expect(receiver.TryGetConnectionStatus(out cs), "connection status while connected");
      Expect(cs.State == 2 && cs.ReceiveBytesPerS > 0 && cs.ReceivePacketsPerS > 0 && cs.RttS > 0 && cs.RttS < 1,
             "connection status: receiving, with a round trip (" + cs.ReceiveBytesPerS + " B/s, rtt " + cs.RttS + " s)");
      double delay;
      Expect(receiver.TryGetPlayoutDelay(ids[0], out delay) && delay > 0 && delay <= 0.3,
             "a fixed-rate room's entity plays out at the adaptive delay (0, 0.3] s, got " + delay);
      states = received - received0;
      bytes = allocated;
      ns_per_state = states > 0 ? cpu / states : 0;
    }
  }

  static void NoAllocationPerReceivedState() {
    long states, bytes;
    double ns;
    Stream(40, 1.5, 3.0, out states, out bytes, out ns);
    Console.WriteLine("  steady state: {0} states received, {1} managed bytes allocated in Update() ({2:F4} bytes/state), {3:F0} ns/state",
                      states, bytes, states > 0 ? (double)bytes / states : 0, ns);
    Expect(states > 500, "too few states received: " + states);
    Expect(bytes == 0, "Update() allocated " + bytes + " bytes over " + states + " states");
  }

  // A token with one character changed: the relay's REJECTED reaches the Rejected event with
  // its reason and a detail for a person; ReasonName names the codes of both families.
  static void RejectionCarriesReasonAndDetail() {
    Expect(Native.ReasonName(EventType.Rejected, 4) == "RoomFull", "reject code 4 is RoomFull");
    Expect(Native.ReasonName(EventType.Disconnected, 4) == "Kicked", "disconnect code 4 is Kicked");
    Expect(Native.ReasonName(EventType.Error, (uint)RejectReason.GrabRefused) == "GrabRefused", "GrabRefused");
    Expect(Native.ReasonName(EventType.Joined, 1) == "unknown", "a JOINED event has no reason");
    string token = Environment.GetEnvironmentVariable("EDGEPHYS_TOKEN_1");
    char[] bad = token.ToCharArray();
    bad[bad.Length / 2] = bad[bad.Length / 2] == 'A' ? 'B' : 'A';
    using (var c = new Client(false)) {
      bool rejected = false;
      RejectReason reason = RejectReason.None;
      string detail = null;
      c.Rejected += (r, d) => { rejected = true; reason = r; detail = d; };
      c.Connect(Environment.GetEnvironmentVariable("EDGEPHYS_RELAY"), new string(bad));
      double end = Native.Now() + 5;
      while (!rejected && Native.Now() < end) { c.Update(); System.Threading.Thread.Sleep(5); }
      Expect(rejected, "a tampered token is rejected");
      Expect(reason == RejectReason.BadToken, "reason BadToken, got " + reason);
      Expect(detail != null && detail.Contains("token"), "the detail explains: '" + detail + "'");
    }
  }

  // Updates a and b once each, then sleeps 5 ms.
  static void Pump(Client a, Client b) { a.Update(); b.Update(); System.Threading.Thread.Sleep(5); }

  // Connects a and b to EDGEPHYS_RELAY with the tokens EDGEPHYS_TOKEN_<tokenA> and
  // EDGEPHYS_TOKEN_<tokenB>, joins both to EDGEPHYS_ROOM on Connected and pumps until both have
  // joined (the caller's handlers are live meanwhile). Returns the deadline (10 s from the
  // call) the test goes on with; fails the test when they have not both joined by then.
  static double ConnectBothAndJoin(Client a, Client b, int tokenA, int tokenB) {
    string relay = Environment.GetEnvironmentVariable("EDGEPHYS_RELAY");
    string room = Environment.GetEnvironmentVariable("EDGEPHYS_ROOM");
    int joined = 0;
    a.Connected += id => a.Join(room);
    b.Connected += id => b.Join(room);
    a.Joined += (r, x) => ++joined;
    b.Joined += (r, x) => ++joined;
    a.Connect(relay, Environment.GetEnvironmentVariable("EDGEPHYS_TOKEN_" + tokenA));
    b.Connect(relay, Environment.GetEnvironmentVariable("EDGEPHYS_TOKEN_" + tokenB));
    double end = Native.Now() + 10;
    while (joined < 2 && Native.Now() < end) Pump(a, b);
    Expect(joined == 2, "both joined");
    return end;
  }

  // A (player 3) sends to the room and to the others, B (player 4) to player 3: each arrives where addressed, with
  // the sender's id, in order.
  static void MessagesReachTheAddressedPlayers() {
    using (var a = new Client(false))
    using (var b = new Client(false)) {
      var gotA = new System.Collections.Generic.List<string>();
      var gotB = new System.Collections.Generic.List<string>();
      a.MessageReceived += (from, p) => gotA.Add(from + ":" + System.Text.Encoding.UTF8.GetString(p));
      b.MessageReceived += (from, p) => gotB.Add(from + ":" + (p.Length > 1000 ? "big" + p.Length : System.Text.Encoding.UTF8.GetString(p)));
      var unreliableB = new System.Collections.Generic.List<string>();
      b.UnreliableMessageReceived += (from, p) => unreliableB.Add(from + ":" + System.Text.Encoding.UTF8.GetString(p));
      double end = ConnectBothAndJoin(a, b, 3, 4);
      double settle = Native.Now() + 0.3;  // both acknowledge their Joined (unreliable sends)
      while (Native.Now() < settle) Pump(a, b);
      a.SendMessageUnreliable(System.Text.Encoding.UTF8.GetBytes("ray"), MessageTarget.Others);
      ExpectStatus(Status.TooLarge, () => a.SendMessageUnreliable(new byte[Native.MaxUnreliableMessageBytes + 1]),
                   "oversized unreliable message");
      a.SendMessage(System.Text.Encoding.UTF8.GetBytes("hello, room"));
      a.SendMessage(new byte[40000], MessageTarget.Others);
      b.SendMessage(System.Text.Encoding.UTF8.GetBytes("just for 3"), MessageTarget.Player, 3);
      ExpectStatus(Status.TooLarge, () => a.SendMessage(new byte[Native.MaxMessageBytes + 1]), "oversized message");
      while ((gotA.Count < 2 || gotB.Count < 2) && Native.Now() < end) Pump(a, b);
      gotA.Sort();  // in order per sender; different senders' messages may interleave
      Expect(string.Join("|", gotA) == "3:hello, room|4:just for 3", "A got: " + string.Join("|", gotA));
      Expect(string.Join("|", gotB) == "3:hello, room|3:big40000", "B got: " + string.Join("|", gotB));
      Expect(string.Join("|", unreliableB) == "3:ray", "B got unreliably: " + string.Join("|", unreliableB));
    }
  }

  static void PropertiesConvergeAndOneCompareAndSetWins() {
    using (var a = new Client(false))
    using (var b = new Client(false)) {
      var changedAtB = new System.Collections.Generic.List<Property>();
      var conflicts = new System.Collections.Generic.List<string>();
      var errors = new System.Collections.Generic.List<RejectReason>();
      b.PropertyChanged += p => changedAtB.Add(p);
      a.PropertyConflict += (req, p) => conflicts.Add("a:" + req + ":" + p.Version + ":" + p.IntValue);
      b.PropertyConflict += (req, p) => conflicts.Add("b:" + req + ":" + p.Version + ":" + p.IntValue);
      b.Error += (reason, entity, detail) => errors.Add(reason);
      double end = ConnectBothAndJoin(a, b, 5, 6);
      Action pump = () => Pump(a, b);
      a.SetProperty(0, "cs.step", PropertyValue.Int64(1), PropertyAuthority.Anyone);
      a.SetProperty(0, "cs.title", "step one");
      a.SetProperty(0, "cs.blob", new byte[] { 0, 255 });
      a.SetProperty(0, "cs.where", PropertyValue.FromVec3(new Vec3(1, 2, 3)));
      a.SetProperty(0, "cs.lit", PropertyValue.Bool(true));
      ExpectStatus(Status.InvalidArgument, () => a.SetProperty(0, "cs.bad", PropertyValue.Double(double.NaN)), "NaN property");
      ExpectStatus(Status.InvalidArgument, () => a.SetProperty(0, new string('k', 65), PropertyValue.Int64(1)), "long key");
      while (changedAtB.Count < 5 && Native.Now() < end) pump();
      Expect(changedAtB.Count == 5, "B told of 5 properties, got " + changedAtB.Count);
      Property title = b.GetProperty(0, "cs.title");
      Expect(title != null && title.StringValue == "step one" && title.Writer == 5, "title at B");
      Property where = b.GetProperty(0, "cs.where");
      Expect(where != null && where.Vec3.Y == 2, "vec3 at B");
      Property blob = b.GetProperty(0, "cs.blob");
      Expect(blob != null && blob.Bytes.Length == 2 && blob.Bytes[1] == 255, "bytes at B");
      Expect(b.GetProperty(0, "cs.none") == null, "unknown property");
      uint ra = a.CompareAndSetProperty(0, "cs.step", PropertyValue.Int64(10), 1);
      uint rb = b.CompareAndSetProperty(0, "cs.step", PropertyValue.Int64(20), 1);
      while (conflicts.Count < 1 && Native.Now() < end) pump();
      for (int i = 0; i < 20; ++i) pump();
      Expect(conflicts.Count == 1, "one conflict: " + string.Join("|", conflicts));
      if (conflicts.Count == 1) {
        bool aLost = conflicts[0].StartsWith("a:");
        Expect(conflicts[0] == (aLost ? "a:" + ra + ":2:20" : "b:" + rb + ":2:10"), "the loser sees the winner: " + conflicts[0]);
      }
      Property step = b.GetProperty(0, "cs.step");
      Expect(step != null && step.Version == 2 && a.GetProperty(0, "cs.step").IntValue == step.IntValue, "both agree on the step");
      b.SetProperty(0, "cs.title", "hijacked");  // owner only: refused
      while (errors.Count < 1 && Native.Now() < end) pump();
      Expect(errors.Count == 1 && errors[0] == RejectReason.NotOwner, "NotOwner for another's property");
    }
  }

  // A (player 7) spawns a box; B's (player 8) request is refused while A forbids takeover; A
  // hands it to B: both hear it, B may publish it and A may not; B releases it to the room.
  static void OwnershipHandOverAndRefusedRequest() {
    using (var a = new Client(false))
    using (var b = new Client(false)) {
      var spawnedAtB = new System.Collections.Generic.List<uint>();
      var changes = new System.Collections.Generic.List<string>();
      var errors = new System.Collections.Generic.List<RejectReason>();
      b.Spawned += e => spawnedAtB.Add(e.EntityId);
      a.OwnershipChanged += (entity, owner, seq) => changes.Add("a:" + owner + ":" + seq);
      b.OwnershipChanged += (entity, owner, seq) => changes.Add("b:" + owner + ":" + seq);
      b.Error += (reason, entity, detail) => errors.Add(reason);
      double end = ConnectBothAndJoin(a, b, 7, 8);
      Action pump = () => Pump(a, b);
      uint box = a.Spawn(new Transform(0, 1, 0), EntityFlags.None);
      while (!spawnedAtB.Contains(box) && Native.Now() < end) pump();
      Expect(b.Owner(box) == 7, "B sees A's box");
      b.RequestOwnership(box);
      while (errors.Count < 1 && Native.Now() < end) pump();
      Expect(errors.Count == 1 && errors[0] == RejectReason.TakeoverRefused, "TakeoverRefused");
      a.HandOver(box, 8);
      while (changes.Count < 2 && Native.Now() < end) pump();
      changes.Sort();
      Expect(string.Join("|", changes) == "a:8:1|b:8:1", "both told: " + string.Join("|", changes));
      b.Publish(box, new Transform(0.5f, 1, 0));
      ExpectStatus(Status.NotFound, () => a.Publish(box, new Transform(0.5f, 1, 0)), "A no longer owns it");
      b.ReleaseOwnership(box);
      while (changes.Count < 4 && Native.Now() < end) pump();
      Expect(a.Owner(box) == 0 && b.Owner(box) == 0, "released to the room");
      // A takes it back (the room's: granted), moves it and reads its motion; a bad leave choice
      // and a NaN velocity are refused; A offloads it; B takes it and starts from A's pose.
      a.RequestOwnership(box);
      while (changes.Count < 6 && Native.Now() < end) pump();
      Expect(a.Owner(box) == 7, "A owns it again");
      a.Publish(box, new Transform(0.25f, 1, 0));
      Transform pose;
      Vec3 lin, ang;
      a.GetOwnedMotion(box, out pose, out lin, out ang);
      Expect(pose.Position.X == 0.25f && lin.X == 0 && ang.Y == 0, "A's owned motion: " + pose.Position);
      ExpectStatus(Status.NotFound, () => b.GetOwnedMotion(box, out pose, out lin, out ang), "B does not own it");
      ExpectStatus(Status.InvalidArgument, () => a.SetOwnerLeave(box, (OwnerLeave)9), "unknown leave choice");
      a.SetOwnerLeave(box, OwnerLeave.Stay);
      ExpectStatus(Status.InvalidArgument, () => a.Offload(box, new Vec3(float.NaN, 0, 0), new Vec3(0, 0, 0)), "NaN velocity");
      for (int i = 0; i < 10; ++i) pump();  // A's pose reaches the relay
      a.Offload(box, new Vec3(1, 0, 0), new Vec3(0, 0, 0));
      while (changes.Count < 8 && Native.Now() < end) pump();
      Expect(a.Owner(box) == 0 && b.Owner(box) == 0, "offloaded to the room");
      b.RequestOwnership(box);
      while (changes.Count < 10 && Native.Now() < end) pump();
      Expect(b.Owner(box) == 8, "B owns it");
      b.GetOwnedMotion(box, out pose, out lin, out ang);
      Expect(pose.Position.X == 0.25f, "B starts where A left it: " + pose.Position);
      ExpectStatus(Status.NotFound, () => a.GrabAt(box, box, new Transform(0, 1, 0)), "grab at with another's hand");
      ExpectStatus(Status.InvalidArgument, () => b.GrabAt(box, box, new Transform(float.NaN, 1, 0)), "grab at a NaN pose");
    }
  }

  static int Main(string[] args) {
    Console.WriteLine("edgephys " + Native.Version() + " (C# binding, Mono)");
    if (args.Length == 2 && args[0] == "--bench") {
      long states, bytes;
      double ns;
      Stream(int.Parse(args[1]), 2.0, 10.0, out states, out bytes, out ns);
      Console.WriteLine("csharp entities={0} states={1} ns_per_state={2:F1} bytes_per_state={3:F4}",
                        args[1], states, ns, states > 0 ? (double)bytes / states : 0);
      return 0;
    }
    var tests = new Action[] { BadArgumentsThrowWithTheirStatus, RejectionCarriesReasonAndDetail,
                               MessagesReachTheAddressedPlayers, PropertiesConvergeAndOneCompareAndSetWins,
                               OwnershipHandOverAndRefusedRequest,
                               NoAllocationPerReceivedState };
    foreach (var t in tests) {
      Console.WriteLine("[ RUN  ] " + t.Method.Name);
      int before = failures;
      try { t(); } catch (Exception e) { Console.WriteLine("  FAIL: exception " + e); ++failures; }
      Console.WriteLine((failures == before ? "[  OK  ] " : "[FAILED] ") + t.Method.Name);
    }
    Console.WriteLine(failures == 0 ? "all C# tests passed" : failures + " failure(s)");
    return failures == 0 ? 0 : 1;
  }
}
