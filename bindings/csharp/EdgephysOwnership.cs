// edgephys C# binding, ownership beyond hand over and request (edgephys_app_state.h,
// "ownership"): switching a body this client simulates to PhyS (Offload), reading where an
// owned entity is and moves (GetOwnedMotion: after a reclaim from PhyS, PhyS's pose and
// velocities), and what happens to an entity when its owner leaves (SetOwnerLeave). A partial
// of Client (Edgephys.cs); compiled with it into Edgephys.dll.
using System;
using System.Runtime.InteropServices;

namespace Edgephys {

// EDGEPHYS_OWNER_LEAVE_*: Default follows the Persistent flag (stay) or its absence (despawn);
// Stay: the room takes it over at rest; PhyS: PhyS simulates a dynamic body this client
// simulated on from its last pose and velocity (else as Stay); Despawn.
public enum OwnerLeave : uint { Default = 0, Stay = 1, PhyS = 2, Despawn = 3 }

internal static class OwnershipNative {
  const string Lib = "edgephys";
  [DllImport(Lib)] public static extern Status edgephys_client_offload(IntPtr client, uint entity, ref Vec3 linear, ref Vec3 angular);
  [DllImport(Lib)] public static extern Status edgephys_client_get_owned_motion(IntPtr client, uint entity, out Transform pose, out Vec3 linear, out Vec3 angular);
  [DllImport(Lib)] public static extern Status edgephys_client_set_owner_leave(IntPtr client, uint entity, uint choice);
  [DllImport(Lib)] public static extern Status edgephys_client_grab_at(IntPtr client, uint entity, uint hand, ref Transform handPose);
}

public sealed partial class Client {
  // Gives a body this client simulates locally to the room; PhyS carries it on from its last
  // published pose with these velocities (m/s, rad/s, room frame). InvalidArgument for a
  // non-finite one; NotFound if not owned.
  public void Offload(uint entity, Vec3 linear, Vec3 angular) {
    Native.Check(OwnershipNative.edgephys_client_offload(handle_, entity, ref linear, ref angular), "offload");
  }
  // An owned entity's pose and velocities (after a reclaim from PhyS: where PhyS had it, and
  // its velocities, for this client's physics to carry on from). NotFound if not owned.
  public void GetOwnedMotion(uint entity, out Transform pose, out Vec3 linear, out Vec3 angular) {
    Native.Check(OwnershipNative.edgephys_client_get_owned_motion(handle_, entity, out pose, out linear, out angular),
                 "get owned motion");
  }
  // Grab with the hand's pose now: published as the hand's transform and judged there by the
  // relay (a pose over 0.5 m from the hand's last transform is refused: Error GrabRefused).
  public void GrabAt(uint entity, uint hand, Transform handPose) {
    Native.Check(OwnershipNative.edgephys_client_grab_at(handle_, entity, hand, ref handPose), "grab at");
  }
  // What the relay does with an owned entity when its owner leaves or times out.
  public void SetOwnerLeave(uint entity, OwnerLeave choice) {
    Native.Check(OwnershipNative.edgephys_client_set_owner_leave(handle_, entity, (uint)choice), "set owner leave");
  }
}

}  // namespace Edgephys
