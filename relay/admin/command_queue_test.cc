#include "relay/admin/command_queue.h"

#include <gtest/gtest.h>

#include <atomic>
#include <stdexcept>
#include <thread>

namespace edgephys::admin {
namespace {

using namespace std::chrono_literals;

TEST(CommandQueueTest, RunsCommandsOnTheLoopThreadAndReturnsTheirReplies) {
  CommandQueue q;
  std::atomic<bool> stop{false};
  std::thread::id loop_id;
  std::thread loop([&] {
    loop_id = std::this_thread::get_id();
    for (int i = 0; i < 5000 && !stop; ++i) {
      q.RunPending(42.0);
      std::this_thread::sleep_for(1ms);
    }
  });
  std::thread::id ran_on;
  auto reply = q.Call([&](double now) {
    ran_on = std::this_thread::get_id();
    AdminReply r;
    r.body = {{"now", now}};
    return r;
  }, 5s);
  stop = true;
  loop.join();
  ASSERT_TRUE(reply.has_value());
  EXPECT_EQ(reply->body["now"], 42.0);
  EXPECT_EQ(ran_on, loop_id);
}

TEST(CommandQueueTest, TimesOutWhenTheLoopDoesNotRun) {
  CommandQueue q;
  bool ran = false;
  auto reply = q.Call([&](double) { ran = true; return AdminReply{}; }, 20ms);
  EXPECT_FALSE(reply.has_value());
  q.RunPending(0);  // runs late; its reply is dropped, nothing dangles
  EXPECT_TRUE(ran);
}

TEST(CommandQueueTest, ACommandThatThrowsAnswers500AndTheLoopGoesOn) {
  CommandQueue q;
  std::thread loop([&] {
    for (int i = 0; i < 2000; ++i) {
      q.RunPending(0);
      std::this_thread::sleep_for(1ms);
    }
  });
  auto thrown = q.Call([](double) -> AdminReply { throw std::runtime_error("boom"); }, 5s);
  auto next = q.Call([](double) { return AdminReply{}; }, 5s);
  loop.join();
  ASSERT_TRUE(thrown.has_value());
  EXPECT_EQ(thrown->status, 500);
  EXPECT_EQ(thrown->body["error"]["code"], "internal");
  ASSERT_TRUE(next.has_value());
  EXPECT_EQ(next->status, 200);
}

TEST(CommandQueueTest, ClosedQueueFailsAtOnce) {
  CommandQueue q;
  q.Close();
  auto reply = q.Call([](double) { return AdminReply{}; }, 5s);
  EXPECT_FALSE(reply.has_value());
}

}  // namespace
}  // namespace edgephys::admin
