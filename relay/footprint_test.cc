// What an idle room member and an idle room cost in heap, as bounds that fail when a fixed-size
// ring or pool creeps back into every connection or every room (memory per user).
// Heap bytes are glibc's own count (mallinfo2: in-use bytes of the main arena plus
// mmapped blocks); the test allocates on the main thread only, so nothing else is counted.
#include <gtest/gtest.h>
#include <malloc.h>

#include <memory>
#include <vector>

#include "physics_backend/room_physics.h"
#include "protocol/connection.h"
#include "relay/replication.h"

namespace edgephys {
namespace {

size_t HeapInUse() {
  const struct mallinfo2 m = mallinfo2();
  return m.uordblks + m.hblkhd;
}

// Heap bytes per object made by `make` (n of them, kept alive while measuring).
template <typename Make>
double BytesEach(int n, Make make) {
  std::vector<decltype(make())> kept;
  kept.reserve(static_cast<size_t>(n));
  const size_t before = HeapInUse();
  for (int i = 0; i < n; ++i) kept.push_back(make());
  const size_t after = HeapInUse();
  return static_cast<double>(after - before) / n;
}

ReplicationConfig SharedEncodingConfig() {
  ReplicationConfig config;
  config.shared_encoding = true;
  return config;
}

// A member's connection as the relay makes it: packet ledgers, reliable channels. The
// reliable send ring grows with what is queued instead of being reserved for the whole window.
TEST(Footprint, AnIdleConnectionStaysUnder64KB) {
  const double each = BytesEach(64, [] {
    return std::make_unique<Connection>(7, ConnectionConfig{}, 0.0);
  });
  RecordProperty("bytes_each", static_cast<int>(each));
  EXPECT_LT(each, 64.0 * 1024);
}

// A receiver's replicator in each edgephys mode. The float/emulation ack tracker and the soft
// body rings are made on first use, so a member of a room without soft bodies pays neither.
TEST(Footprint, AnIdleReplicatorStaysUnder24KBInEveryEdgephysMode) {
  for (bool shared : {false, true}) {
    ReplicationConfig config = SharedEncodingConfig();
    config.shared_encoding = shared;
    const double each = BytesEach(64, [&] { return std::make_unique<ClientReplicator>(config); });
    RecordProperty(shared ? "bytes_each_format9" : "bytes_each_format2", static_cast<int>(each));
    EXPECT_LT(each, 24.0 * 1024) << "shared_encoding=" << shared;
  }
}

// Every room gets a PhyS world (hands and spawned bodies live there). Bullet preallocates its
// contact pools per world; at its own default (4,096) that was ~3.6 MB per room before a
// single body existed.
TEST(Footprint, AnEmptyRoomWorldStaysUnder1MB) {
  const double each = BytesEach(8, [] {
    return std::make_unique<RoomPhysics>(physics::PhysicsConfig{}, 0.0);
  });
  RecordProperty("bytes_each", static_cast<int>(each));
  EXPECT_LT(each, 1024.0 * 1024);
}

// The pool is a setting: asking for Bullet's default still gets it (and the bound above is
// about the default, not about Bullet ignoring the setting).
TEST(Footprint, TheContactPoolSettingIsWhatSizesTheWorld) {
  physics::PhysicsConfig big;
  big.contact_pool_size = 4096;
  const double small_each = BytesEach(4, [] {
    return std::make_unique<RoomPhysics>(physics::PhysicsConfig{}, 0.0);
  });
  const double big_each = BytesEach(4, [&] { return std::make_unique<RoomPhysics>(big, 0.0); });
  EXPECT_GT(big_each, small_each + 2.0 * 1024 * 1024);
}

}  // namespace
}  // namespace edgephys
