// Issue 35 item 4, live: 500 sealed connections on loopback (from 8 addresses, as the probe
// did) each hold a partial reliable message (a run of units without its last one, then units
// of the window beyond a gap). The relay's held partial-message bytes stay under
// --max-reassembly-bytes (the largest holders are ended and counted), its resident memory
// stays under the documented bound, and an honest pair in another room keeps its rate.
#include <gtest/gtest.h>

#include <fstream>
#include <string>

#include "tests/integration/harness.h"
#include "tests/integration/raw_peer.h"

namespace edgephys::testing {
namespace {

// Resident set of this process (relay, clients and test), bytes; 0 if unreadable.
size_t ResidentBytes() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmRSS:", 0) == 0) return std::stoull(line.substr(6)) * 1024;
  }
  return 0;
}

struct Watch : ClientListener {
  uint32_t entity = 0;
  uint64_t updates = 0;
  void OnEntityUpdated(const RemoteEntity& e) override { updates += e.id == entity; }
};

TEST(ReassemblyMemory, FiveHundredPartialHoldersStayUnderTheCapAndAnotherRoomKeepsItsRate) {
  constexpr size_t kPeers = 500;
  constexpr int kAddresses = 8;        // 127.0.0.2-9: 63 each, under 64 per address
  constexpr uint16_t kInOrder = 160;   // units of a message without its last one (160 KiB)
  constexpr uint16_t kAhead = 160;     // then units beyond a one-unit gap (160 KiB)
  constexpr size_t kCap = 32u << 20;   // --max-reassembly-bytes for this test
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.limits.max_reassembly_bytes = kCap;
  config.limits.handshakes_per_s = 0;  // 500 handshakes at once: admission is not under test
  config.limits.join_timeout_s = 0;    // the holders join no room
  LoopbackWorld world(config);

  Watch watch;
  Client& sender = world.AddClient(MintToken("honest", 1));
  Client& receiver = world.AddClient(MintToken("honest", 2), &watch);
  ASSERT_TRUE(world.RunUntil([&] {
    return sender.state() == ClientState::kConnected && receiver.state() == ClientState::kConnected;
  }, 5.0));
  ASSERT_TRUE(sender.JoinRoom("honest").ok());
  ASSERT_TRUE(receiver.JoinRoom("honest").ok());
  ASSERT_TRUE(world.RunUntil([&] { return sender.joined() && receiver.joined(); }, 5.0));
  auto id = sender.Spawn({.position = {0, 1, 0}});
  ASSERT_TRUE(id.ok());
  watch.entity = *id;
  auto publish = [&](double now) {
    (void)sender.PublishTransform(*id, {static_cast<float>(std::sin(3 * now)), 1, 0}, {});
  };

  // The holders connect (bounded: 15 s).
  std::vector<std::unique_ptr<RawPeer>> peers;
  for (size_t i = 0; i < kPeers; ++i) {
    auto address = asio::ip::make_address("127.0.0." + std::to_string(2 + i % kAddresses));
    peers.push_back(std::make_unique<RawPeer>(address, world.relay_endpoint(),
                                              MintToken("attack", static_cast<uint32_t>(100 + i))));
  }
  size_t connected = 0;
  const double handshake_end = world.Now() + 15.0;
  for (int round = 0; connected < kPeers && world.Now() < handshake_end; ++round) {
    connected = 0;
    for (auto& p : peers) {
      p->Poll();
      if (round % 50 == 0) p->SendHello(), p->SendConnect();
      connected += p->state() == RawPeer::State::kConnected;
    }
    publish(world.Now());
    world.Step();
  }
  ASSERT_EQ(connected, kPeers);
  const size_t rss_before = ResidentBytes();
  ASSERT_GT(rss_before, 0u);

  // Baseline rate of the honest pair, then the attack, paced so the relay's socket buffer
  // keeps up (64 datagrams per step); bounded: 60 s.
  uint64_t updates_before = watch.updates;
  double t0 = world.Now();
  world.RunFor(1.0, publish);
  const double base_rate = static_cast<double>(watch.updates - updates_before) / (world.Now() - t0);
  ASSERT_GT(base_rate, 10.0) << "no steady stream before the attack";

  updates_before = watch.updates;
  t0 = world.Now();
  int64_t held_peak = 0;
  size_t rss_peak = rss_before;
  std::vector<uint16_t> next(kPeers, 0);
  const uint16_t kEnd = kInOrder + 1 + kAhead;
  size_t cursor = 0, done = 0;
  const double attack_end = world.Now() + 60.0;
  while (done < kPeers && world.Now() < attack_end) {
    for (int k = 0; k < 64 && done < kPeers; ++k, cursor = (cursor + 1) % kPeers) {
      uint16_t& u = next[cursor];
      if (u == kEnd) continue;
      if (u == kInOrder) ++u;  // the gap: the message's last unit never comes
      (void)peers[cursor]->SendUnit(u, /*last=*/false);
      if (++u == kEnd) ++done;
    }
    publish(world.Now());
    world.Step();
    for (auto& p : peers) p->Poll();
    held_peak = std::max(held_peak, world.counters().reassembly_held_bytes.load());
    if (cursor % 64 == 0) rss_peak = std::max(rss_peak, ResidentBytes());
  }
  ASSERT_EQ(done, kPeers);
  world.RunFor(0.5, publish);
  held_peak = std::max(held_peak, world.counters().reassembly_held_bytes.load());
  rss_peak = std::max(rss_peak, ResidentBytes());
  const double attack_rate =
      static_cast<double>(watch.updates - updates_before) / (world.Now() - t0);

  // Each holder alone stays under its bound; together they would hold ~190 MB: the cap ended
  // the largest ones.
  const uint64_t evicted = world.counters().reassembly_evictions.load();
  RecordProperty("held_peak_bytes", static_cast<int>(held_peak));
  RecordProperty("rss_growth_bytes", static_cast<int>(rss_peak - rss_before));
  RecordProperty("evictions", static_cast<int>(evicted));
  EXPECT_LE(held_peak, static_cast<int64_t>(kCap + kMaxPacketSize));
  EXPECT_GT(held_peak, static_cast<int64_t>(kCap / 2)) << "the attack held little: not a test";
  EXPECT_GT(evicted, 0u);
  EXPECT_EQ(world.relay().session_count(), kPeers + 2 - evicted);
  EXPECT_EQ(world.counters().disconnects[static_cast<size_t>(DisconnectReason::kKicked)].load(),
            evicted);
  // Resident growth (the idle sessions are already in rss_before): the cap plus allocator
  // slack. Without the cap it is ~190 MB.
  EXPECT_LT(rss_peak - rss_before, kCap + (48u << 20));
  // The honest pair: never ended, and still at its rate (half of it is a generous floor).
  EXPECT_EQ(sender.state(), ClientState::kConnected);
  EXPECT_EQ(receiver.state(), ClientState::kConnected);
  EXPECT_GT(attack_rate, 0.5 * base_rate) << "before " << base_rate << "/s, during " << attack_rate;
  EXPECT_LE(world.counters().reassembly_held_bytes.load(), static_cast<int64_t>(kCap));
}

}  // namespace
}  // namespace edgephys::testing
