// ClientReplicator over a real RoomHost: what a receiver is sent, datagram by datagram.
#include <gtest/gtest.h>

#include <vector>

#include "protocol/byte_io.h"
#include "relay/replication.h"
#include "relay/room_host_testing.h"

namespace edgephys::room_host_testing {
namespace {

struct Sends final : PacketWriter {
  std::vector<std::vector<uint8_t>> packets;
  void WritePacket(std::span<const uint8_t> p) override { packets.emplace_back(p.begin(), p.end()); }
};

// ---- Acknowledgements reach the encoder, in every edgephys format -----------------------------
// A player's box publishes one state and then stays still. Its receiver acknowledges every
// datagram it gets (or none): acknowledged, the box is sent once and never again; without
// acknowledgements it is resent. Fails if an acknowledgement stops short of the format's
// encoder (the box would then be resent as if every datagram had been lost).
class AckedStateTest : public RoomHostTest, public ::testing::WithParamInterface<bool> {
 protected:
  AckedStateTest() {
    config_.tick_rate_hz = 60;
    config_.replication.shared_encoding = GetParam();
    Rebuild();
  }

  // Sends of the box to one receiver over 3 s of 60 Hz ticks, acknowledging each if `ack`.
  size_t SendsOverThreeSeconds(bool ack) {
    RecordingMember owner(1);
    EXPECT_TRUE(host_->Join(owner, 0));
    const uint32_t box = Base(owner) + 1;
    Spawn(owner, LocalBox(box, 1));
    host_->ApplyStates(owner, StatePayload({{box, {0.25f, 1.5f, -2}, {0, 0, 0, 1}}}), 1.0);
    ClientReplicator replicator(config_.replication);
    Connection connection(7, ConnectionConfig{}, 0.0);
    Sends writer;
    std::vector<MemberLink*> receivers;
    for (double now = 1.0; now < 4.0; now += 1.0 / 60) {
      receivers.clear();
      host_->BeginTick(now, &receivers);
      const size_t before = writer.packets.size();
      replicator.Tick(host_->room().frame(), /*self=*/2, now, connection, writer, counters_);
      if (!ack) continue;
      for (size_t i = before; i < writer.packets.size(); ++i) {
        replicator.OnPacketAcked(LoadU16LE(writer.packets[i].data() + kPacketPrefixSize));
      }
    }
    return writer.packets.size();
  }
};

TEST_P(AckedStateTest, AnAcknowledgedStateIsSentOnceAndAnUnacknowledgedOneAgain) {
  const size_t acked = SendsOverThreeSeconds(true);
  EXPECT_EQ(acked, 1u);
  Rebuild();
  EXPECT_GE(SendsOverThreeSeconds(false), 3u);
}

INSTANTIATE_TEST_SUITE_P(Formats, AckedStateTest, ::testing::Bool(),
                         [](const auto& param_info) { return param_info.param ? "format9" : "format2"; });

}  // namespace
}  // namespace edgephys::room_host_testing
