// Two things of one relay with a bulk room (more than Relay::kBulkRoomEntities entities) and a
// light room, on an in-memory network with a fake clock:
//  * The bulk room's members' datagrams (its receivers acknowledging thousand-entity packets)
//    are handled after the light room's tick in the same update (Relay::Update sets them aside,
//    Relay::TickDueRooms handles them between its passes): when the light room's first datagram
//    of an update leaves, the bulk receiver's connection has not yet seen any datagram of that
//    update; by the update's end it has seen them all. Serial and fork-join.
//  * A bulk room due just before a light room waits for it and ticks right after it in the
//    same update (relay/bulk_tick_scheduler.h), at an unchanged rate.
//  * Per-room work time (edgephys_room_update_seconds_total, RelayCounters::room_work): the
//    bulk room is charged more than the light one, and a closed room's series goes.
#include <gtest/gtest.h>

#include <algorithm>
#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "protocol/testing/in_memory_network.h"
#include "protocol/testing/tap_socket.h"
#include "tests/integration/bulk_rooms.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

double RoomSeconds(const RelayCounters& counters, const std::string& room) {
  for (const RoomWorkTimes::Series& s : counters.room_work.Snapshot()) {
    if (s.label == room) return s.seconds;
  }
  return -1;  // no series
}

class BulkRoomTest : public ::testing::TestWithParam<size_t> {
 protected:
  using Member = BulkRoomsMember;

  void SetUp() override {
    const RelayConfig config = BulkRoomsConfig(GetParam());
    const Endpoint relay_at(asio::ip::make_address("10.0.0.1"), 7777);
    relay_raw_ = network_.CreateSocket(relay_at);
    socket_ = std::make_unique<TapSocket>(relay_raw_.get());
    relay_ = std::make_unique<Relay>(config, socket_.get(), &counters_);
    if (light_room_phase_s_ > 0) {  // the light room ticks this long after the bulk room
      ASSERT_TRUE(relay_->CreateRoom("a-bulk", config.room_defaults, now_).ok());
      now_ += light_room_phase_s_;
      ASSERT_TRUE(relay_->CreateRoom("b-light", config.room_defaults, now_).ok());
    }
    ConnectBulkRoomsMembers(network_, relay_at, config, now_, &members_);
    ASSERT_FALSE(HasFatalFailure());
    for (int i = 0; i < 400 && !AllJoined(); ++i) Step(0.005);
    ASSERT_TRUE(AllJoined());
    SpawnBulkAndLight(members_, [this](double dt) { Step(dt); }, &bulk_, &light_);
    ASSERT_FALSE(HasFatalFailure());
  }

  bool AllJoined() const {
    for (const Member& m : members_) {
      if (!m.client->joined()) return false;
    }
    return true;
  }

  void Step(double dt) {
    now_ += dt;
    relay_->Update(now_, UnixNow());
    for (Member& m : members_) m.Update(now_);
  }

  // Everything moves, then one step of a whole tick interval (both rooms tick).
  void MoveAndStep(int t) {
    for (size_t i = 0; i < bulk_.size(); ++i) {
      (void)members_[0].client->PublishTransform(bulk_[i], {0.01f * i, 0.001f * t, 0}, {});
    }
    (void)members_[2].client->PublishTransform(light_[0], {0.01f * t, 1, 0}, {});
    Step(1.0 / 30);
  }

  double light_room_phase_s_ = 0;
  InMemoryNetwork network_;
  double now_ = 0;
  RelayCounters counters_;
  std::unique_ptr<DatagramSocket> relay_raw_;
  std::unique_ptr<TapSocket> socket_;
  int received_from_bulk_receiver_ = 0;  // datagrams, counted by a test's on_receive hook
  std::unique_ptr<Relay> relay_;
  std::vector<Member> members_;
  std::vector<uint32_t> bulk_, light_;
};

TEST_P(BulkRoomTest, ABulkRoomsDatagramsAreHandledAfterTheLightRoomsTick) {
  const uint32_t bulk_receiver_player = 2;  // members_[1]
  const Endpoint bulk_receiver = members_[1].socket->LocalEndpoint();
  socket_->on_receive = [this, bulk_receiver](const Endpoint& from, std::span<const uint8_t>) {
    if (from == bulk_receiver) ++received_from_bulk_receiver_;
  };
  const Endpoint light_receiver = members_[3].socket->LocalEndpoint();
  const ConnectionStats* bulk_stats = relay_->FindConnectionStats(bulk_receiver_player);
  ASSERT_NE(bulk_stats, nullptr);
  int checked = 0;
  for (int t = 1; t <= 30; ++t) {
    const uint64_t before = bulk_stats->packets_received;
    received_from_bulk_receiver_ = 0;
    int64_t seen_at_light_send = -1;
    socket_->on_send = [&](const Endpoint& to, std::span<const uint8_t>) {
      if (to == light_receiver && seen_at_light_send < 0) {
        seen_at_light_send = static_cast<int64_t>(bulk_stats->packets_received);
      }
    };
    MoveAndStep(t);
    socket_->on_send = nullptr;
    if (received_from_bulk_receiver_ == 0) continue;
    // Whatever came from the bulk receiver in this update was handled by its end.
    EXPECT_EQ(bulk_stats->packets_received, before + received_from_bulk_receiver_)
        << "update " << t;
    if (seen_at_light_send < 0) continue;
    ++checked;
    // ...but none of it before the light room's first datagram left.
    EXPECT_EQ(seen_at_light_send, static_cast<int64_t>(before)) << "update " << t;
  }
  EXPECT_GE(checked, 10);  // the bulk receiver sent, and the light room ticked, often enough
  EXPECT_GT(RelayCounters::Get(counters_.bulk_datagrams_deferred), 0u);
  // Still a working room: the bulk receiver has the latest positions.
  for (int i = 0; i < 10; ++i) Step(1.0 / 30);
  const auto& seen = members_[1].client->entities();
  ASSERT_EQ(seen.size(), bulk_.size());
  EXPECT_NEAR(seen.at(bulk_[7]).state.position.y, 0.030f, 0.002f);
}

TEST_P(BulkRoomTest, RoomWorkTimeGrowsWithTheRoomsWorkAndGoesWhenTheRoomCloses) {
  for (int t = 1; t <= 30; ++t) MoveAndStep(t);
  Step(2 * RoomWorkLedger::kPublishIntervalS);  // publish what the last updates charged
  const double bulk = RoomSeconds(counters_, "a-bulk");
  const double light = RoomSeconds(counters_, "b-light");
  ASSERT_GT(light, 0);
  // 1,100 moving entities to one receiver against one hand to one receiver.
  EXPECT_GT(bulk, 3 * light) << "bulk " << bulk << " s, light " << light << " s";
  // The light room goes on alone; the bulk room keeps its members but nothing moves there.
  for (int t = 31; t <= 60; ++t) {
    (void)members_[2].client->PublishTransform(light_[0], {0.01f * t, 1, 0}, {});
    Step(1.0 / 30);
  }
  EXPECT_GT(RoomSeconds(counters_, "b-light"), light);
  ASSERT_TRUE(relay_->CloseRoom("b-light", "test", now_).ok());
  EXPECT_EQ(RoomSeconds(counters_, "b-light"), -1);  // series gone at once
  for (int i = 0; i < 10; ++i) Step(2 * RoomWorkLedger::kPublishIntervalS);
  EXPECT_EQ(RoomSeconds(counters_, "b-light"), -1);  // and does not come back
  EXPECT_GT(RoomSeconds(counters_, "a-bulk"), bulk);
  relay_.reset();  // a relay that goes takes its rooms' series with it
  EXPECT_TRUE(counters_.room_work.Snapshot().empty());
}

class BulkRoomPhaseTest : public BulkRoomTest {
 protected:
  void SetUp() override {
    light_room_phase_s_ = 0.001;
    BulkRoomTest::SetUp();
  }
};

TEST_P(BulkRoomPhaseTest, ABulkRoomDueJustBeforeALightRoomTicksInItsUpdate) {
  const Room* bulk_room = relay_->FindRoom("a-bulk");
  const Room* light_room = relay_->FindRoom("b-light");
  ASSERT_NE(bulk_room, nullptr);
  ASSERT_NE(light_room, nullptr);
  const Endpoint bulk_receiver = members_[1].socket->LocalEndpoint();
  const Endpoint light_receiver = members_[3].socket->LocalEndpoint();
  int first_bulk = -1, first_light = -1, sends = 0;
  socket_->on_send = [&](const Endpoint& to, std::span<const uint8_t>) {
    if (to == bulk_receiver && first_bulk < 0) first_bulk = sends;
    if (to == light_receiver && first_light < 0) first_light = sends;
    ++sends;
  };
  int bulk_ticks = 0, bulk_alone = 0, bulk_sent_first = 0;
  double max_late = 0;
  // One second in 1 ms updates; everything moves at the rooms' 30 Hz.
  for (int ms = 1; ms <= 1000; ++ms) {
    if (ms % 33 == 0) {
      for (size_t i = 0; i < bulk_.size(); ++i) {
        (void)members_[0].client->PublishTransform(bulk_[i], {0.01f * i, 0.0001f * ms, 0}, {});
      }
      (void)members_[2].client->PublishTransform(light_[0], {0.001f * ms, 1, 0}, {});
    }
    const double bulk_due = bulk_room->next_tick(), light_due = light_room->next_tick();
    first_bulk = first_light = -1;
    sends = 0;
    Step(0.001);
    if (bulk_room->next_tick() == bulk_due) continue;  // the bulk room did not tick
    ++bulk_ticks;
    max_late = std::max(max_late, now_ - bulk_due);
    if (light_room->next_tick() == light_due) ++bulk_alone;  // ...without the light room
    if (first_bulk >= 0 && first_light >= 0 && first_bulk < first_light) ++bulk_sent_first;
  }
  socket_->on_send = nullptr;
  // The bulk room ticked at its rate, on its schedule (30 Hz)...
  EXPECT_GE(bulk_ticks, 29);
  EXPECT_LE(bulk_ticks, 31);
  // ...and always in the light room's update, after it: without the wait, 1 ms before it,
  // alone; late by the light room's 1 ms, never by half its interval.
  EXPECT_LE(bulk_alone, 1) << "of " << bulk_ticks << " ticks";  // the first may precede the alignment
  EXPECT_EQ(bulk_sent_first, 0);
  EXPECT_LT(max_late, 0.5 / 30);
}

INSTANTIATE_TEST_SUITE_P(Threads, BulkRoomPhaseTest, ::testing::Values(size_t{1}, size_t{2}));

INSTANTIATE_TEST_SUITE_P(Threads, BulkRoomTest, ::testing::Values(size_t{1}, size_t{2}));

}  // namespace
}  // namespace edgephys::testing
