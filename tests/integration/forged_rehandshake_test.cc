// Issue 35 item 6: a Connect with another valid token from an address that holds a session.
// An attacker that can send from the victim's exact address and read what the relay sends
// there (the Challenge) must not end the victim's session: the relay refuses the Connect,
// counts it (session_held), and the victim stays, its entity too. A client that restarted on
// the same address gets in once its old session timed out.
#include <gtest/gtest.h>

#include <deque>

#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

// One UDP socket seen by two clients: both send from its exact address and port, and both
// receive every datagram that arrives on it (the attacker reads the victim's traffic).
class SharedSocket {
 public:
  explicit SharedSocket(std::unique_ptr<UdpSocket> inner) : inner_(std::move(inner)) {}

  class View final : public DatagramSocket {
   public:
    View(SharedSocket* hub, size_t index) : hub_(hub), index_(index) {}
    Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
      return hub_->inner_->SendTo(to, data);
    }
    size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
      hub_->Drain();
      auto& queue = hub_->queues_[index_];
      if (queue.empty()) return 0;
      auto [sender, bytes] = std::move(queue.front());
      queue.pop_front();
      *from = sender;
      const size_t n = std::min(bytes.size(), buffer.size());
      std::copy_n(bytes.begin(), n, buffer.begin());
      return n;
    }
    Endpoint LocalEndpoint() const override { return hub_->inner_->LocalEndpoint(); }

   private:
    SharedSocket* hub_;
    size_t index_;
  };

  View* Add() {
    queues_.emplace_back();
    views_.push_back(std::make_unique<View>(this, views_.size()));
    return views_.back().get();
  }

 private:
  void Drain() {
    Endpoint from;
    std::array<uint8_t, 2048> buffer{};
    while (size_t n = inner_->ReceiveFrom(&from, buffer)) {
      for (auto& q : queues_) q.emplace_back(from, std::vector<uint8_t>(buffer.begin(), buffer.begin() + n));
    }
  }

  std::unique_ptr<UdpSocket> inner_;
  std::deque<std::deque<std::pair<Endpoint, std::vector<uint8_t>>>> queues_;
  std::vector<std::unique_ptr<View>> views_;
};

TEST(ForgedRehandshake, AConnectFromTheVictimsAddressWithAnotherTokenChangesNothing) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.connection.timeout_s = 1.5;  // for the restart at the end
  LoopbackWorld world(config);
  SharedSocket shared(std::move(*UdpSocket::Open(Endpoint(world.relay_endpoint().address(), 0))));
  Client victim(ClientConfig{}, shared.Add());
  ASSERT_TRUE(victim.Connect(ToRelayAddress(world.relay_endpoint()), MintToken("r", 1), world.Now()).ok());
  Client& other = world.AddClient(MintToken("r", 2));
  bool victim_pumped = true;
  auto pump = [&](double seconds, const std::function<bool()>& done) {
    return world.RunUntil([&] {
      if (victim_pumped) victim.Update(world.Now());
      return done();
    }, seconds);
  };
  uint32_t id = 0;
  ASSERT_NO_FATAL_FAILURE(JoinVictimAndSpawn(pump, victim, other, "r", &id));

  // The attacker: a real SDK client on the victim's very socket, with its own valid token
  // (another player, another room). It reads the Challenge meant for that address and
  // answers it, exactly as the victim would.
  const uint64_t held_before = Rejected(world.counters(), DropReason::kSessionHeld);
  Client attacker(ClientConfig{}, shared.Add());
  ASSERT_TRUE(attacker.Connect(ToRelayAddress(world.relay_endpoint()), MintToken("elsewhere", 66),
                               world.Now()).ok());
  ASSERT_TRUE(pump(3.0, [&] {
    attacker.Update(world.Now());
    return attacker.state() != ClientState::kHandshaking;
  }));
  EXPECT_EQ(attacker.state(), ClientState::kRejected);
  EXPECT_EQ(attacker.reject_reason(), static_cast<uint16_t>(schema::RejectReason::RateLimited));
  EXPECT_GE(Rejected(world.counters(), DropReason::kSessionHeld) - held_before, 1u);
  pump(0.5, [] { return false; });
  EXPECT_EQ(victim.state(), ClientState::kConnected);
  EXPECT_EQ(world.relay().session_count(), 2u);
  EXPECT_EQ(world.relay().FindRoom("r")->entities().count(id), 1u);
  EXPECT_EQ(other.entities().count(id), 1u);
  EXPECT_EQ(world.counters().disconnects[static_cast<size_t>(DisconnectReason::kKicked)].load(), 0u);
  ASSERT_TRUE(victim.PublishTransform(id, {4, 5, 6}, {}).ok());
  EXPECT_TRUE(pump(3.0, [&] {
    auto it = other.entities().find(id);
    return it != other.entities().end() && std::abs(it->second.state.position.x - 4) < 0.01f;
  }));

  // A restart without a goodbye: the victim's client goes silent; once the relay timed its
  // session out, a new client on the same address and port is admitted.
  victim_pumped = false;
  ASSERT_TRUE(pump(5.0, [&] { return world.relay().session_count() == 1; }));
  Client restarted(ClientConfig{}, shared.Add());
  ASSERT_TRUE(restarted.Connect(ToRelayAddress(world.relay_endpoint()), MintToken("r", 3),
                                world.Now()).ok());
  EXPECT_TRUE(pump(3.0, [&] {
    restarted.Update(world.Now());
    return restarted.state() == ClientState::kConnected;
  }));
}

}  // namespace
}  // namespace edgephys::testing
