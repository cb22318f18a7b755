// The relay's log names causes: a disconnect by its reason's name (not a number), a spawn
// refused with OverBudget by the budget it used up. A live relay on loopback, its log captured.
#include <gtest/gtest.h>
#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <memory>
#include <sstream>

#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

// Routes the default logger into a string for the test's lifetime.
class CapturedLog {
 public:
  CapturedLog() : previous_(spdlog::default_logger()) {
    auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(out_);
    spdlog::set_default_logger(std::make_shared<spdlog::logger>("captured", sink));
    spdlog::set_level(spdlog::level::info);
  }
  ~CapturedLog() { spdlog::set_default_logger(previous_); }
  std::string text() const { return out_.str(); }

 private:
  std::ostringstream out_;
  std::shared_ptr<spdlog::logger> previous_;
};

TEST(RelayLog, NamesDisconnectReasonsAndTheBudgetAnOverBudgetSpawnUsedUp) {
  CapturedLog log;
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.room_defaults.budgets.max_entities = 1;
  LoopbackWorld world(config);
  Client& c = world.AddClient(MintToken("r", 1));
  ASSERT_TRUE(world.RunUntil([&] { return c.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(c.JoinRoom("r").ok());
  ASSERT_TRUE(world.RunUntil([&] { return c.joined(); }, 3.0));
  ASSERT_TRUE(c.Spawn({.position = {0, 1, 0}}).ok());
  ASSERT_TRUE(c.Spawn({.position = {1, 1, 0}}).ok());  // the room's second: over its budget
  ASSERT_TRUE(world.RunUntil([&] {
    return log.text().find("request rejected") != std::string::npos;
  }, 3.0)) << log.text();
  EXPECT_NE(log.text().find("OverBudget (over budget: room_entities)"), std::string::npos)
      << log.text();
  c.Disconnect();
  ASSERT_TRUE(world.RunUntil([&] {
    return log.text().find("player 1 disconnected") != std::string::npos;
  }, 3.0)) << log.text();
  EXPECT_NE(log.text().find("player 1 disconnected (ClientLeft)"), std::string::npos) << log.text();
  EXPECT_EQ(log.text().find("(reason "), std::string::npos) << log.text();
}

}  // namespace
}  // namespace edgephys::testing
