// RelayShards on real loopback UDP: rooms on one shard each, clients of a room meeting across
// shards' handshakes, garbage dropped and counted, clean shutdown. Every wait is bounded; no
// assertion is about speed.
#include "relay/relay_shards.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/packet.h"
#include "protocol/udp_socket.h"
#include "relay/spsc_ring.h"
#include "tests/integration/harness.h"

namespace edgephys {
namespace {

constexpr char kSecret[] = "shard-test-secret";

// A join token for `player` in `room`, valid for an hour, signed with the relay's secret.
std::vector<uint8_t> MintToken(const std::string& room, uint32_t player) {
  return testing::MintToken(room, player, 3600, kDefaultPermissions, kSecret);
}

Endpoint At(const std::string& address, uint16_t port) {
  return Endpoint(asio::ip::make_address(address), port);
}

uint64_t Sum(const std::array<RelayCounters::Counter, static_cast<size_t>(DropReason::kCount)>& a) {
  uint64_t total = 0;
  for (const auto& c : a) total += c.load();
  return total;
}

// A relay of `shards` shards on 127.0.0.1 and clients pumped from the test thread.
class ShardedWorld : public testing::LoopbackWorldBase, public testing::Pumped<ShardedWorld> {
 public:
  // `tweak` may adjust the relay configuration and shard options before the start.
  explicit ShardedWorld(
      size_t shards,
      const std::function<void(RelayConfig&, RelayShardsOptions&)>& tweak = nullptr)
      : LoopbackWorldBase(asio::ip::make_address("127.0.0.1")) {
    RelayConfig config;
    config.secret = kSecret;
    config.physics_threads = 1;
    config.room_defaults.tick_rate_hz = 30;
    RelayShardsOptions options;
    options.shards = shards;
    if (tweak) tweak(config, options);
    auto started = RelayShards::Start(config, socket_.get(), &counters_, options);
    EXPECT_TRUE(started.ok());
    shards_ = std::move(*started);
    RestartClock();
  }
  ~ShardedWorld() { shards_->Stop(); }

  // A client bound to `address` (any 127.0.0.0/8 address is loopback on Linux).
  Client& AddClient(const std::vector<uint8_t>& token, const std::string& address = "127.0.0.1") {
    return Connect(ClientConfig{}, nullptr, asio::ip::make_address(address), token);
  }

  // The shards run on their own threads: a step updates the clients only.
  void Step() {
    UpdateClients(Now());
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }

  // Shards (by index) that hold room `name`.
  std::vector<size_t> ShardsHolding(const std::string& name) {
    std::vector<size_t> holding;
    for (size_t i = 0; i < shards_->shard_count(); ++i) {
      bool found = false;
      EXPECT_TRUE(
          shards_->RunOnShard(i, [&](Relay& r, double) { found = r.FindRoom(name) != nullptr; }));
      if (found) holding.push_back(i);
    }
    return holding;
  }

  RelayShards& shards() { return *shards_; }

 private:
  std::unique_ptr<RelayShards> shards_;
};

// The first room name "<prefix><k>" that the shards route to `shard`.
std::string RoomOnShard(const RelayShards& shards, size_t shard, const std::string& prefix) {
  for (int k = 0; k < 10000; ++k) {
    std::string name = prefix + std::to_string(k);
    if (shards.ShardOfRoom(name) == shard) return name;
  }
  ADD_FAILURE() << "no room name for shard " << shard;
  return prefix;
}

// A Hello-typed datagram: routed by source address only.
size_t HelloShard(const RelayShards& shards, const Endpoint& from) {
  std::vector<uint8_t> hello(kMinHelloPacketSize, 0);
  WritePacketPrefix(PacketType::kHello, 0, hello);
  return shards.Route(from, hello);
}

// Holds shard `shard`'s thread inside a RunOnShard task (run from a helper thread) until
// Release() or destruction, so that the test controls when the shard drains its ring.
class ShardBlocker {
 public:
  ShardBlocker(RelayShards& shards, size_t shard) {
    thread_ = std::thread([this, &shards, shard] {
      ran_ = shards.RunOnShard(shard, [this](Relay&, double) {
        started_.store(true);
        const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
        while (!released_.load() && std::chrono::steady_clock::now() < deadline) {
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
      });
    });
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!started_.load() && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  }
  ~ShardBlocker() { Release(); }
  bool started() const { return started_.load(); }
  void Release() {
    released_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  bool ran() const { return ran_; }  // after Release()

 private:
  std::atomic<bool> started_{false};
  std::atomic<bool> released_{false};
  bool ran_ = false;
  std::thread thread_;
};

// Sends `count` data datagrams from a fresh socket, for unknown connections whose ids all route
// to shard `shard` of `n`; each is rejected (kUnknownConnection) by that shard.
void SendUnknownSessionData(const Endpoint& relay, size_t count, size_t shard, size_t n) {
  auto raw = UdpSocket::Open(At("127.0.0.4", 0));
  ASSERT_TRUE(raw.ok());
  for (size_t k = 0; k < count; ++k) {
    std::vector<uint8_t> data(kPacketPrefixSize + 8, 0);
    WritePacketPrefix(PacketType::kData, static_cast<uint32_t>(n * (k + 1) + shard), data);
    ASSERT_TRUE((*raw)->SendTo(relay, data).ok());
  }
}

uint64_t QueuedOrDropped(const RelayShards& shards, size_t shard) {
  const RelayShards::ShardStats st = shards.stats(shard);
  return st.datagrams_queued + st.queue_drops;
}

// While `blocker` holds shard 0: sends `count` datagrams of unknown sessions routed to shard 0
// of `n` (SendUnknownSessionData) and pumps until `arrived()`, for at most 5 s. Fails fatally
// at the first step that does not succeed.
void FloodHeldShard(ShardedWorld& world, const ShardBlocker& blocker, size_t count, size_t n,
                    const std::function<bool()>& arrived) {
  ASSERT_TRUE(blocker.started());
  ASSERT_NO_FATAL_FAILURE(SendUnknownSessionData(world.relay_endpoint(), count, 0, n));
  ASSERT_TRUE(world.RunUntil(arrived, 5.0));
}

TEST(SpscRing, FillsDrainsAndRefusesWhenFull) {
  SpscRing<int> ring(3);  // rounded up to 4
  EXPECT_EQ(ring.capacity(), 4u);
  EXPECT_TRUE(ring.Empty());
  EXPECT_EQ(ring.Front(), nullptr);
  for (int i = 0; i < 4; ++i) {
    int* slot = ring.Claim();
    ASSERT_NE(slot, nullptr);
    *slot = i;
    ring.Publish();
  }
  EXPECT_EQ(ring.Claim(), nullptr);
  for (int i = 0; i < 4; ++i) {
    ASSERT_NE(ring.Front(), nullptr);
    EXPECT_EQ(*ring.Front(), i);
    ring.Pop();
  }
  EXPECT_TRUE(ring.Empty());
  EXPECT_NE(ring.Claim(), nullptr);
}

TEST(SpscRing, TwoThreadsTransferEveryItemInOrder) {
  SpscRing<uint64_t> ring(64);
  constexpr uint64_t kItems = 200000;
  std::thread producer([&] {
    for (uint64_t i = 0; i < kItems;) {
      if (uint64_t* slot = ring.Claim()) {
        *slot = i++;
        ring.Publish();
      } else {
        std::this_thread::yield();
      }
    }
  });
  uint64_t expected = 0;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (expected < kItems && std::chrono::steady_clock::now() < deadline) {
    if (uint64_t* v = ring.Front()) {
      ASSERT_EQ(*v, expected);
      ++expected;
      ring.Pop();
    } else {
      std::this_thread::yield();
    }
  }
  producer.join();
  EXPECT_EQ(expected, kItems);
}

// Multi-word slots, as the relay's queued datagrams: every field the producer wrote before
// Publish() is what the consumer reads after Front(), and the producer only reuses a slot after
// the consumer's Pop() (ThreadSanitizer checks both orderings).
TEST(SpscRing, TwoThreadsSeeWholeSlotsWrittenBeforePublish) {
  struct Item {
    uint64_t seq = 0;
    std::array<uint64_t, 15> payload{};
  };
  SpscRing<Item> ring(8);
  constexpr uint64_t kItems = 50000;
  std::thread producer([&] {
    for (uint64_t i = 0; i < kItems;) {
      if (Item* slot = ring.Claim()) {
        slot->seq = i;
        for (size_t k = 0; k < slot->payload.size(); ++k) slot->payload[k] = i * 31 + k;
        ring.Publish();
        ++i;
      } else {
        std::this_thread::yield();
      }
    }
  });
  uint64_t expected = 0;
  bool intact = true;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
  while (expected < kItems && std::chrono::steady_clock::now() < deadline) {
    if (Item* item = ring.Front()) {
      intact = intact && item->seq == expected;
      for (size_t k = 0; k < item->payload.size(); ++k) {
        intact = intact && item->payload[k] == expected * 31 + k;
      }
      // Scribble on the slot before giving it back: the producer must not see this half-done.
      item->payload.fill(0);
      ring.Pop();
      ++expected;
    } else {
      std::this_thread::yield();
    }
  }
  producer.join();
  EXPECT_EQ(expected, kItems);
  EXPECT_TRUE(intact);
  EXPECT_TRUE(ring.Empty());
}

TEST(RelayShards, RejectsInvalidOptions) {
  auto socket = UdpSocket::Open(At("127.0.0.1", 0));
  ASSERT_TRUE(socket.ok());
  RelayCounters counters;
  RelayShardsOptions options;
  options.shards = 0;
  EXPECT_FALSE(RelayShards::Start(RelayConfig{}, socket->get(), &counters, options).ok());
  options.shards = RelayShards::kMaxShards + 1;
  EXPECT_FALSE(RelayShards::Start(RelayConfig{}, socket->get(), &counters, options).ok());
  options.shards = 2;
  EXPECT_FALSE(RelayShards::Start(RelayConfig{}, nullptr, &counters, options).ok());
}

TEST(RelayShards, RoutesSessionsByConnectionIdAndConnectsByRoom) {
  ShardedWorld world(3);
  RelayShards& shards = world.shards();
  const Endpoint from = At("127.0.0.9", 4000);
  for (uint32_t id : {1u, 2u, 3u, 7u, 0xfffffffeu}) {
    std::vector<uint8_t> data(kPacketPrefixSize + 8, 0);
    WritePacketPrefix(PacketType::kData, id, data);
    EXPECT_EQ(shards.Route(from, data), id % 3);
    WritePacketPrefix(PacketType::kDisconnect, id, data);
    EXPECT_EQ(shards.Route(from, data), id % 3);
  }
  // Connects go by the token's room, whatever their source (and whatever connection id).
  std::set<size_t> seen;
  for (int k = 0; k < 12; ++k) {
    const std::string room = "r" + std::to_string(k);
    flatbuffers::FlatBufferBuilder fbb(256);
    const auto client_token = MintToken(room, 5);
    const auto relay_part = SplitClientToken(client_token)->relay_token;  // what Connect carries
    std::array<uint8_t, kCookieSize> cookie{};
    FinishControl(fbb, schema::CreateConnect(fbb, fbb.CreateVector(cookie.data(), cookie.size()),
                                             fbb.CreateVector(relay_part.data(), relay_part.size()), 1));
    auto packet = BuildHandshakePacket(PacketType::kConnect, fbb);
    for (const char* address : {"127.0.0.1", "127.0.0.2", "127.0.0.3"}) {
      EXPECT_EQ(shards.Route(At(address, 5000), packet), shards.ShardOfRoom(room));
    }
    packet[6] = 7;  // a non-zero connection id does not divert a Connect
    EXPECT_EQ(shards.Route(At("127.0.0.1", 5000), packet), shards.ShardOfRoom(room));
    seen.insert(shards.ShardOfRoom(room));
  }
  EXPECT_EQ(seen.size(), 3u) << "12 rooms all hashed onto fewer than 3 shards";
}

struct Pair {
  std::string room;
  Client* a;
  Client* b;
  uint32_t entity_a = 0;
  uint32_t entity_b = 0;
};

TEST(RelayShards, RoomsLiveOnOneShardAndMembersSeeEachOtherWhateverTheirAddress) {
  ShardedWorld world(3);
  RelayShards& shards = world.shards();
  // One room per shard; each room's two clients come from different loopback addresses, so
  // their Hellos land on various shards (the shared cookie key makes that work).
  std::vector<Pair> pairs;
  const std::vector<std::string> addresses = {"127.0.0.1", "127.0.0.2", "127.0.0.3",
                                              "127.0.0.4", "127.0.0.5", "127.0.0.6"};
  size_t hello_elsewhere = 0;
  uint32_t player = 1;
  for (size_t s = 0; s < 3; ++s) {
    Pair p;
    p.room = RoomOnShard(shards, s, "room-");
    const std::string& addr_a = addresses[2 * s];
    const std::string& addr_b = addresses[2 * s + 1];
    p.a = &world.AddClient(MintToken(p.room, player++), addr_a);
    p.b = &world.AddClient(MintToken(p.room, player++), addr_b);
    hello_elsewhere += HelloShard(shards, At(addr_a, 1)) != s;
    hello_elsewhere += HelloShard(shards, At(addr_b, 1)) != s;
    pairs.push_back(p);
  }
  EXPECT_GT(hello_elsewhere, 0u)
      << "every Hello landed on its room's shard: cookie sharing untested";

  ASSERT_TRUE(world.RunUntil(
      [&] {
        for (const Pair& p : pairs) {
          if (p.a->state() != ClientState::kConnected || p.b->state() != ClientState::kConnected) {
            return false;
          }
        }
        return true;
      },
      5.0))
      << "handshakes did not finish";
  for (Pair& p : pairs) {
    ASSERT_TRUE(p.a->JoinRoom(p.room).ok());
    ASSERT_TRUE(p.b->JoinRoom(p.room).ok());
  }
  ASSERT_TRUE(world.RunUntil(
      [&] {
        for (const Pair& p : pairs) {
          if (!p.a->joined() || !p.b->joined()) return false;
        }
        return true;
      },
      5.0))
      << "joins did not finish";

  for (size_t s = 0; s < pairs.size(); ++s) {
    Pair& p = pairs[s];
    EXPECT_EQ(world.ShardsHolding(p.room), std::vector<size_t>{s}) << p.room;
    auto ea = p.a->Spawn({.position = {1, 1, 1}, .rotation = {0, 0, 0, 1}});
    auto eb = p.b->Spawn({.position = {2, 2, 2}, .rotation = {0, 0, 0, 1}});
    ASSERT_TRUE(ea.ok() && eb.ok());
    p.entity_a = *ea;
    p.entity_b = *eb;
  }
  for (size_t s = 0; s < 3; ++s) {
    EXPECT_EQ(shards.stats(s).sessions, 2u) << "shard " << s;
  }

  // Each publishes a pose distinct per room; the other member sees it, no one else does.
  auto pose_of = [](size_t room, int who) {
    return Vec3f{static_cast<float>(room) + 0.25f * static_cast<float>(who), 1.5f, -2.0f};
  };
  const double publish_until = world.Now() + 0.5;
  world.RunUntil(
      [&] {
        for (size_t s = 0; s < pairs.size(); ++s) {
          (void)pairs[s].a->PublishTransform(pairs[s].entity_a, pose_of(s, 1), {0, 0, 0, 1});
          (void)pairs[s].b->PublishTransform(pairs[s].entity_b, pose_of(s, 2), {0, 0, 0, 1});
        }
        return world.Now() > publish_until;
      },
      2.0);
  auto sees = [](Client* c, uint32_t id, const Vec3f& at) {
    const RemoteEntity* e = c->FindEntity(id);
    return e != nullptr && e->spawned && std::fabs(e->state.position.x - at.x) < 0.01f &&
           std::fabs(e->state.position.z - at.z) < 0.01f;
  };
  EXPECT_TRUE(world.RunUntil(
      [&] {
        for (size_t s = 0; s < pairs.size(); ++s) {
          if (!sees(pairs[s].b, pairs[s].entity_a, pose_of(s, 1))) return false;
          if (!sees(pairs[s].a, pairs[s].entity_b, pose_of(s, 2))) return false;
        }
        return true;
      },
      5.0));
  // Nothing leaks between rooms: each client knows its room's other entity and two players.
  for (const Pair& p : pairs) {
    for (Client* c : {p.a, p.b}) {
      EXPECT_EQ(c->entities().size(), 1u)
          << p.room;  // the other member's (own ones are not listed)
      EXPECT_EQ(c->players().size(), 2u) << p.room;
    }
  }

  // The exporter's totals are the shards' sums.
  EXPECT_TRUE(world.RunUntil([&] { return world.counters().clients.load() == 6; }, 2.0));
  EXPECT_EQ(world.counters().rooms.load(), 3);
  EXPECT_EQ(world.counters().entities.load(), 6);
  EXPECT_EQ(world.counters().connections_accepted.load(), 6u);
  EXPECT_EQ(world.counters().io_queue_drops.load(), 0u);
}

TEST(RelayShards, OperatorRoomsAreCreatedOnTheirShard) {
  ShardedWorld world(2);
  RoomConfig config;
  config.capacity = 4;
  for (const std::string name : {"ops-a", "ops-b", "ops-c", "ops-d"}) {
    ASSERT_TRUE(world.shards().CreateRoom(name, config).ok()) << name;
    EXPECT_EQ(world.ShardsHolding(name), std::vector<size_t>{world.shards().ShardOfRoom(name)})
        << name;
  }
  EXPECT_FALSE(world.shards().CreateRoom("", config).ok());
  // A player of that room joins it, on that shard, with its capacity.
  Client& c = world.AddClient(MintToken("ops-a", 3), "127.0.0.7");
  ASSERT_TRUE(world.RunUntil([&] { return c.state() == ClientState::kConnected; }, 5.0));
  ASSERT_TRUE(c.JoinRoom("ops-a").ok());
  ASSERT_TRUE(world.RunUntil([&] { return c.joined(); }, 5.0));
  uint32_t capacity = 0;
  world.shards().RunOnShard(world.shards().ShardOfRoom("ops-a"), [&](Relay& r, double) {
    if (const Room* room = r.FindRoom("ops-a")) capacity = room->config().capacity;
  });
  EXPECT_EQ(capacity, 4u);
}

TEST(RelayShards, GarbageIsDroppedAndCountedAndRoomsKeepWorking) {
  ShardedWorld world(3);
  const std::string room = "steady";
  Client& a = world.AddClient(MintToken(room, 1), "127.0.0.2");
  Client& b = world.AddClient(MintToken(room, 2), "127.0.0.3");
  ASSERT_TRUE(world.RunUntil(
      [&] { return a.state() == ClientState::kConnected && b.state() == ClientState::kConnected; },
      5.0));
  ASSERT_TRUE(a.JoinRoom(room).ok() && b.JoinRoom(room).ok());
  ASSERT_TRUE(world.RunUntil([&] { return a.joined() && b.joined(); }, 5.0));
  const uint64_t received_before = world.counters().packets_received.load();
  const uint64_t rejected_before = Sum(world.counters().packets_rejected);

  // Garbage from a raw socket: random bytes, valid prefixes with random connection ids (zero
  // and not), Connects with truncated and random tokens (no valid cookie), Hellos too small or
  // with a junk body, an oversized datagram and empty datagrams (discarded uncounted).
  auto raw = UdpSocket::Open(At("127.0.0.4", 0));
  ASSERT_TRUE(raw.ok());
  std::mt19937 rng(11);
  std::vector<std::vector<uint8_t>> garbage;
  auto random_bytes = [&](size_t n) {
    std::vector<uint8_t> v(n);
    for (auto& x : v) x = static_cast<uint8_t>(rng());
    return v;
  };
  for (int i = 0; i < 40; ++i) garbage.push_back(random_bytes(1 + rng() % 300));
  for (int i = 0; i < 40; ++i) {
    auto v = random_bytes(kPacketPrefixSize + rng() % 100);
    const auto type = i % 2 == 0 ? PacketType::kData : PacketType::kDisconnect;
    WritePacketPrefix(type, i % 4 == 0 ? 0 : static_cast<uint32_t>(rng()), v);
    garbage.push_back(v);
  }
  auto token = MintToken(room, 9);
  for (int i = 0; i < 20; ++i) {
    std::vector<uint8_t> bad_token =
        i % 2 == 0 ? std::vector<uint8_t>(token.begin(), token.begin() + rng() % token.size())
                   : random_bytes(rng() % 150);
    if (i % 5 == 0 && !bad_token.empty()) bad_token[25 % bad_token.size()] = 200;  // room length
    flatbuffers::FlatBufferBuilder fbb(256);
    std::array<uint8_t, kCookieSize> cookie{};
    FinishControl(fbb, schema::CreateConnect(fbb, fbb.CreateVector(cookie.data(), cookie.size()),
                                             fbb.CreateVector(bad_token), rng()));
    auto packet = BuildHandshakePacket(PacketType::kConnect, fbb);
    if (i % 3 == 0) packet[6] = static_cast<uint8_t>(rng() | 1);  // non-zero connection id
    if (i % 4 == 0) packet.resize(packet.size() / 2);             // truncated message
    garbage.push_back(packet);
  }
  for (int i = 0; i < 10; ++i) {
    std::vector<uint8_t> hello = random_bytes(i % 2 == 0 ? 200 : kMinHelloPacketSize);
    WritePacketPrefix(PacketType::kHello, 0, hello);
    garbage.push_back(hello);
  }
  garbage.push_back(std::vector<uint8_t>(2000, 0x45));
  for (const auto& g : garbage) ASSERT_TRUE((*raw)->SendTo(world.relay_endpoint(), g).ok());
  for (int i = 0; i < 3; ++i) (void)(*raw)->SendTo(world.relay_endpoint(), {});

  // Every non-empty datagram reaches a relay and is rejected there exactly once.
  const uint64_t n = garbage.size();
  EXPECT_TRUE(world.RunUntil(
      [&] { return Sum(world.counters().packets_rejected) - rejected_before >= n; }, 5.0));
  EXPECT_EQ(world.counters().io_queue_drops.load(), 0u);
  EXPECT_GE(world.counters().packets_received.load() - received_before, n);
  EXPECT_EQ(Sum(world.counters().packets_rejected) - rejected_before, n);
  EXPECT_GT(
      world.counters().packets_rejected[static_cast<size_t>(DropReason::kUnknownConnection)].load(),
      0u);
  EXPECT_GT(world.counters().packets_rejected[static_cast<size_t>(DropReason::kTooLarge)].load(),
            0u);

  // Connects that pass the cookie check but carry bad tokens are refused with BadToken.
  // (A truncated token's MAC: the relay part's last byte altered, as the SDK refuses a client
  // token of the wrong length before sending.)
  auto cut = MintToken(room, 10);
  cut[cut.size() - kSessionSecretSize - 1] ^= 0x01;
  Client& truncated = world.AddClient(cut, "127.0.0.5");
  // A client token whose relay part was altered (the SDK refuses bytes that are no client
  // token before sending; the relay refuses this one by its MAC).
  auto altered = MintToken(room, 11);
  altered[5] ^= 0x40;
  Client& random = world.AddClient(altered, "127.0.0.6");
  EXPECT_TRUE(world.RunUntil(
      [&] {
        return truncated.state() == ClientState::kRejected &&
               random.state() == ClientState::kRejected;
      },
      5.0));
  EXPECT_EQ(truncated.reject_reason(), static_cast<uint16_t>(schema::RejectReason::BadToken));
  EXPECT_EQ(random.reject_reason(), static_cast<uint16_t>(schema::RejectReason::BadToken));

  // The room still works.
  auto id = a.Spawn({.position = {0, 1, 0}, .rotation = {0, 0, 0, 1}});
  ASSERT_TRUE(id.ok());
  EXPECT_TRUE(world.RunUntil(
      [&] {
        const RemoteEntity* e = b.FindEntity(*id);
        return e != nullptr && e->spawned;
      },
      5.0));
}

TEST(RelayShards, StopDisconnectsEveryClientCleanly) {
  ShardedWorld world(2);
  std::vector<Client*> clients;
  for (uint32_t i = 0; i < 6; ++i) {
    const std::string room = "stop-" + std::to_string(i % 3);
    clients.push_back(&world.AddClient(MintToken(room, i + 1), "127.0.0." + std::to_string(i + 1)));
  }
  ASSERT_TRUE(world.RunUntil(
      [&] {
        return std::all_of(clients.begin(), clients.end(),
                           [](Client* c) { return c->state() == ClientState::kConnected; });
      },
      5.0));
  for (uint32_t i = 0; i < clients.size(); ++i) {
    ASSERT_TRUE(clients[i]->JoinRoom("stop-" + std::to_string(i % 3)).ok());
  }
  ASSERT_TRUE(world.RunUntil(
      [&] {
        return std::all_of(clients.begin(), clients.end(), [](Client* c) { return c->joined(); });
      },
      5.0));

  world.shards().Stop();
  world.shards().Stop();  // idempotent
  EXPECT_TRUE(world.RunUntil(
      [&] {
        return std::all_of(clients.begin(), clients.end(),
                           [](Client* c) { return c->state() == ClientState::kDisconnected; });
      },
      5.0));
  for (Client* c : clients) EXPECT_EQ(c->disconnect_reason(), DisconnectReason::kServerShutdown);
  EXPECT_EQ(world.counters().clients.load(), 0);
  EXPECT_EQ(
      world.counters().disconnects[static_cast<size_t>(DisconnectReason::kServerShutdown)].load(),
      clients.size());
  EXPECT_FALSE(world.shards().RunOnShard(0, [](Relay&, double) {}));
  EXPECT_EQ(world.shards().CreateRoom("late", RoomConfig{}).code(), StatusCode::kNotConnected);
}

// The receive thread keeps routing while a shard is busy: what does not fit in the shard's ring
// is dropped and counted (io_queue_drops, the shard's queue_drops), what fits is handled once
// the shard is free again.
TEST(RelayShards, FullRingDropsAndCountsWhileTheShardIsBusy) {
  ShardedWorld world(2,
                     [](RelayConfig&, RelayShardsOptions& options) { options.queue_capacity = 4; });
  RelayShards& shards = world.shards();
  const uint64_t rejected_before = Sum(world.counters().packets_rejected);
  constexpr size_t kSent = 20;
  {
    ShardBlocker blocker(shards, 0);
    ASSERT_NO_FATAL_FAILURE(FloodHeldShard(world, blocker, kSent, 2,
                                           [&] { return QueuedOrDropped(shards, 0) == kSent; }));
    EXPECT_EQ(shards.stats(0).datagrams_queued, 4u);
    EXPECT_EQ(shards.stats(0).queue_drops, kSent - 4);
    EXPECT_EQ(world.counters().io_queue_drops.load(), kSent - 4);
    blocker.Release();
    EXPECT_TRUE(blocker.ran());
  }
  EXPECT_TRUE(world.RunUntil(
      [&] { return Sum(world.counters().packets_rejected) - rejected_before == 4; }, 5.0));
  EXPECT_EQ(shards.stats(1).datagrams_queued + shards.stats(1).queue_drops, 0u);
}

// Stop() lets each shard handle everything already in its ring, even when one Update takes
// only part of it (max_datagrams_per_update), before the shards say goodbye.
TEST(RelayShards, StopHandlesEverythingQueued) {
  ShardedWorld world(
      1, [](RelayConfig& config, RelayShardsOptions&) { config.max_datagrams_per_update = 1; });
  RelayShards& shards = world.shards();
  const uint64_t rejected_before = Sum(world.counters().packets_rejected);
  constexpr size_t kSent = 30;
  ShardBlocker blocker(shards, 0);
  ASSERT_NO_FATAL_FAILURE(FloodHeldShard(world, blocker, kSent, 1,
                                         [&] { return shards.stats(0).datagrams_queued == kSent; }));
  // Stop while the shard is still busy: it finds the whole batch queued when it stops.
  std::thread stopper([&] { shards.Stop(); });
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  blocker.Release();
  stopper.join();
  EXPECT_TRUE(blocker.ran());
  EXPECT_EQ(Sum(world.counters().packets_rejected) - rejected_before, kSent);
}

// stats(), RunOnShard() and CreateRoom() from other threads while clients talk to the shards
// and while the controlling thread stops them: each call either runs (before the shard's
// final tasks) or is refused, none hangs, and nothing races (ThreadSanitizer build).
TEST(RelayShards, StatsAndTasksFromOtherThreadsWhileRunningAndStopping) {
  ShardedWorld world(3);
  RelayShards& shards = world.shards();
  std::vector<Client*> clients;
  for (uint32_t i = 0; i < 4; ++i) {
    clients.push_back(&world.AddClient(MintToken("busy-" + std::to_string(i % 2), i + 1),
                                       "127.0.0." + std::to_string(i + 1)));
  }
  ASSERT_TRUE(world.RunUntil(
      [&] {
        return std::all_of(clients.begin(), clients.end(),
                           [](Client* c) { return c->state() == ClientState::kConnected; });
      },
      5.0));

  std::atomic<bool> stopped_seen{false};
  std::atomic<uint64_t> calls_run{0};
  std::atomic<uint64_t> fns_run{0};
  std::vector<std::thread> helpers;
  for (int h = 0; h < 2; ++h) {
    helpers.emplace_back([&, h] {
      const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(20);
      for (uint64_t k = 0; std::chrono::steady_clock::now() < deadline; ++k) {
        size_t refused = 0;
        for (size_t i = 0; i < shards.shard_count(); ++i) {
          (void)shards.stats(i);
          size_t rooms = 0;
          if (shards.RunOnShard(i, [&](Relay& r, double) {
                rooms = r.room_count();
                fns_run.fetch_add(1);
              })) {
            calls_run.fetch_add(1);
            EXPECT_LE(rooms, 1000u);
          } else {
            ++refused;
          }
        }
        const std::string room = "helper-" + std::to_string(h) + "-" + std::to_string(k % 50);
        const Status created = shards.CreateRoom(room, RoomConfig{});
        if (refused == shards.shard_count() && created.code() == StatusCode::kNotConnected) {
          stopped_seen.store(true);
          return;
        }
      }
    });
  }
  for (size_t i = 0; i < clients.size(); ++i) {
    ASSERT_TRUE(clients[i]->JoinRoom("busy-" + std::to_string(i % 2)).ok());
  }
  (void)world.RunUntil([] { return false; }, 0.3);  // clients keep talking meanwhile
  shards.Stop();
  for (auto& t : helpers) t.join();
  EXPECT_TRUE(stopped_seen.load());
  EXPECT_GT(calls_run.load(), 0u);
  EXPECT_EQ(calls_run.load(), fns_run.load());
  EXPECT_EQ(world.counters().clients.load(), 0);
}

}  // namespace
}  // namespace edgephys
