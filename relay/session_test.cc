// Session's due bookkeeping across a parallel room tick: a session made due while a pool thread
// replicates it (buffered) tells its host at the flush, on the flushing (relay) thread; the
// host's due list is never touched from a pool thread.
#include "relay/session.h"

#include <gtest/gtest.h>

#include <limits>
#include <thread>
#include <vector>

#include "protocol/endpoint.h"
#include "relay/entity.h"
#include "relay/relay_counters.h"

namespace edgephys {
namespace {

constexpr double kDue = -std::numeric_limits<double>::infinity();

class RecordingHost final : public SessionHost {
 public:
  void OnJoinRoom(Session&, std::string_view, double) override {}
  void OnLeaveRoom(Session&, double) override {}
  void OnWorkerHello(Session&) override {}
  void OnWorkerResult(Session&, const schema::WorkerResult&) override {}
  void OnWorkerStates(Session&, std::span<const uint8_t>) override {}
  void Transmit(const Endpoint&, std::span<const uint8_t>) override {}
  void OnServiceSoon(Session&) override { due_reports.push_back(std::this_thread::get_id()); }
  std::vector<std::thread::id> due_reports;
};

struct SessionFixture : ::testing::Test {
  RecordingHost host;
  RelayCounters counters;
  Session session{&host, &counters, *ParseEndpoint("127.0.0.1:4000"), 0x1234, 7, 0, "room", 1,
                  ConnectionConfig{}, AbuseLimits{}, 0.0};
  ReplicationFrame frame;
  SessionFixture() { session.StartReplication(ReplicationConfig{}); }
};

TEST_F(SessionFixture, DueInAParallelTickIsReportedAtTheFlushOnTheRelayThread) {
  session.set_service_at(5.0);  // waiting on a timer
  std::thread pool([&] { session.Replicate(frame, 1.0, counters, /*buffered=*/true); });
  pool.join();
  EXPECT_EQ(session.service_at(), kDue);
  EXPECT_TRUE(host.due_reports.empty()) << "the host heard it from the pool thread";
  session.FlushReplication();
  ASSERT_EQ(host.due_reports.size(), 1u);
  EXPECT_EQ(host.due_reports[0], std::this_thread::get_id());
  session.FlushReplication();  // told once
  EXPECT_EQ(host.due_reports.size(), 1u);
}

TEST_F(SessionFixture, DueInASerialTickIsReportedAtOnceAndOnlyOnce) {
  session.set_service_at(5.0);
  session.Replicate(frame, 1.0, counters, /*buffered=*/false);
  EXPECT_EQ(host.due_reports.size(), 1u);
  session.Replicate(frame, 1.1, counters, /*buffered=*/false);  // already due
  session.FlushReplication();
  EXPECT_EQ(host.due_reports.size(), 1u);
}

}  // namespace
}  // namespace edgephys
