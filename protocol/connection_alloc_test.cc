// Verifies the hot-path promise of connection.h: once buffers reached their steady-state size,
// SendReliable / SendUnreliable / Update / ProcessPacket allocate nothing. Counts every
// operator new in this test binary while a flag is set.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cstdlib>
#include <new>

#include "protocol/testing/allocation_counter_test_util.h"
#include "protocol/connection.h"

namespace edgephys {
namespace {

using testing_util::g_allocations;
using testing_util::g_counting;

class CountingHandler : public ConnectionHandler {
 public:
  void OnReliableMessage(std::span<const uint8_t>) override { ++reliable; }
  void OnUnreliablePayload(uint16_t, std::span<const uint8_t>) override { ++unreliable; }
  void OnPacketAcked(uint16_t) override { ++acked; }
  long reliable = 0, unreliable = 0, acked = 0;
};

// Packets from one end to the other, in fixed storage.
class Pipe : public PacketWriter {
 public:
  void WritePacket(std::span<const uint8_t> packet) override {
    ASSERT_LT(count_, slots_.size());
    std::copy(packet.begin(), packet.end(), slots_[count_].begin());
    sizes_[count_++] = packet.size();
  }
  void DeliverTo(Connection& to, double now, ConnectionHandler& handler) {
    for (size_t i = 0; i < count_; ++i) {
      // Drop every 7th packet so resends and out-of-order buffering are exercised too.
      if (++seen_ % 7 == 0) continue;
      // Results are not under test here: this test counts allocations.
      (void)to.ProcessPacket(std::span(slots_[i].data(), sizes_[i]), now, handler);
    }
    count_ = 0;
  }

 private:
  std::array<std::array<uint8_t, kMaxPacketSize>, 256> slots_{};
  std::array<size_t, 256> sizes_{};
  size_t count_ = 0;
  uint64_t seen_ = 0;
};

TEST(ConnectionAllocationTest, SteadyStateAllocatesNothing) {
  Connection a(1, ConnectionConfig{}, 0), b(1, ConnectionConfig{}, 0);
  CountingHandler ha, hb;
  auto pipes = std::make_unique<std::array<Pipe, 2>>();
  Pipe& ab = (*pipes)[0];
  Pipe& ba = (*pipes)[1];
  std::array<uint8_t, 3000> message{};
  std::array<uint8_t, 200> payload{};
  auto run = [&](int from, int to) {
    for (int step = from; step < to; ++step) {
      double now = step * 0.01;
      ASSERT_TRUE(a.SendReliable(std::span(message.data(), 1 + step % message.size())).ok());
      ASSERT_TRUE(a.SendUnreliable(payload, now, ab).ok());
      ASSERT_TRUE(b.SendUnreliable(payload, now, ba).ok());
      a.Update(now, ab);
      b.Update(now, ba);
      ab.DeliverTo(b, now, hb);
      ba.DeliverTo(a, now, ha);
    }
  };
  run(1, 6000);  // warm-up: buffers grow to their steady-state size
  long before_reliable = hb.reliable;
  g_allocations = 0;
  g_counting = true;
  run(6000, 8000);
  g_counting = false;
  EXPECT_EQ(g_allocations.load(), 0);
  EXPECT_GT(hb.reliable - before_reliable, 1900);
  EXPECT_TRUE(a.connected() && b.connected());
}

}  // namespace
}  // namespace edgephys
