// Room and entity properties through a real relay on a simulated network (fake clock): writes
// converge for every member and for late joiners, in order, also under 20 % loss, reordering
// and duplication; of two compare-and-set writers expecting the same version exactly one wins
// and the other gets the current value; an entity's properties go with it. Also the bytes a
// property update costs on the wire.
#include <gtest/gtest.h>

#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "protocol/packet_seal.h"
#include "protocol/property_codec.h"
#include "relay/room_host.h"
#include "tests/integration/property_inbox.h"
#include "tests/integration/sim_world.h"

namespace edgephys::testing {
namespace {

// Whether `c` holds exactly the properties of `want` (values, versions, writers).
::testing::AssertionResult SameProperties(const Client& c,
                                          const std::map<PropertyKey, PropertyRecord>& want) {
  if (c.properties().size() != want.size()) {
    return ::testing::AssertionFailure()
           << "player " << c.player_id() << " holds " << c.properties().size()
           << " properties, want " << want.size();
  }
  for (const auto& [k, p] : want) {
    const PropertyRecord* got = c.FindProperty(k.first, k.second);
    if (got == nullptr || !(got->value == p.value) || got->version != p.version ||
        got->writer != p.writer || got->authority != p.authority || got->owner != p.owner) {
      return ::testing::AssertionFailure() << "player " << c.player_id() << " differs on ("
                                           << k.first << ", " << k.second << ")";
    }
  }
  return ::testing::AssertionSuccess();
}

TEST(Properties, ConvergeInOrderUnderLossAndLateJoinersGetThemAll) {
  SimWorld world(LossyLink());
  PropertyInbox ia, ib, ic, id;
  auto [a, b, c] = AddJoined(world, "props", ia, ib, ic);
  Result<uint32_t> tool = a.Spawn({.position = {0, 1, 0}});
  ASSERT_TRUE(tool.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*tool) && c.FindEntity(*tool); }, 10.0));
  constexpr int kN = 30;
  uint32_t last_step_request = 0;
  for (int i = 0; i < kN; ++i) {
    Result<uint32_t> written = a.SetProperty(0, "step", PropertyValue::Int64(i));
    ASSERT_TRUE(written.ok());
    last_step_request = *written;
    ASSERT_TRUE(a.SetProperty(*tool, "tip", PropertyValue::Vec3({0.1f * i, 0, 1})).ok());
    ASSERT_TRUE(b.SetProperty(0, "title", PropertyValue::String("step " + std::to_string(i)),
                              PropertyAuthority::kAnyone).ok());
    if (i % 10 == 0) {
      ASSERT_TRUE(c.SetProperty(0, "gain", PropertyValue::Double(0.5 * i)).ok());
      ASSERT_TRUE(c.SetProperty(*tool, "note", PropertyValue::Bytes(std::string("\0\1", 2)),
                                PropertyAuthority::kAnyone).ok());
    }
    world.RunFor(0.02);
  }
  const auto done = [&](const Client& x) {
    const PropertyRecord* step = x.FindProperty(0, "step");
    const PropertyRecord* gain = x.FindProperty(0, "gain");
    return step && step->version == kN && gain && gain->version == 3 &&
           x.FindProperty(0, "title") && x.FindProperty(0, "title")->version == kN &&
           x.FindProperty(*tool, "tip") && x.FindProperty(*tool, "tip")->version == kN;
  };
  ASSERT_TRUE(world.RunUntil([&] { return done(a) && done(b) && done(c); }, 30.0));
  world.RunFor(1.0);  // nothing more (no duplicates) arrives
  // Every member was told of every write, once, in order.
  for (PropertyInbox* in : {&ia, &ib, &ic}) {
    EXPECT_EQ(in->Versions(0, "step"), OneTo(kN));
    EXPECT_EQ(in->Versions(0, "title"), OneTo(kN));
    EXPECT_EQ(in->Versions(*tool, "tip"), OneTo(kN));
    EXPECT_EQ(in->Versions(0, "gain"), OneTo(3));
    EXPECT_TRUE(in->errors.empty() && in->conflicts.empty());
  }
  const PropertyRecord& step = *b.FindProperty(0, "step");
  EXPECT_EQ(step.value, PropertyValue::Int64(kN - 1));
  EXPECT_EQ(step.writer, 1u);
  EXPECT_EQ(step.owner, 1u);  // the room property's creator
  EXPECT_EQ(c.FindProperty(*tool, "tip")->value, PropertyValue::Vec3({0.1f * (kN - 1), 0, 1}));
  EXPECT_EQ(a.FindProperty(*tool, "note")->value, PropertyValue::Bytes(std::string("\0\1", 2)));
  EXPECT_EQ(a.FindProperty(0, "title")->authority, PropertyAuthority::kAnyone);
  EXPECT_TRUE(SameProperties(b, a.properties()));
  EXPECT_TRUE(SameProperties(c, a.properties()));
  EXPECT_EQ(step.request_id, last_step_request);  // the writer's request id, to every member

  // A late joiner gets every property, after the spawn of the entity they belong to.
  Client& d = world.AddClient(MintToken("props", 4), &id);
  JoinAll(world, {&d}, "props");
  ASSERT_TRUE(world.RunUntil([&] { return d.properties().size() == a.properties().size(); }, 20.0));
  EXPECT_TRUE(SameProperties(d, a.properties()));
  ASSERT_FALSE(id.spawned.empty());
  EXPECT_EQ(id.changes.size(), a.properties().size());  // one announcement each

  // An entity's properties go with it, for everyone and for the relay.
  const RoomHost& room = *world.relay().rooms().at("props");
  EXPECT_EQ(room.properties().count(), 5u);  // step, title, gain; tip and note
  ASSERT_TRUE(a.Despawn(*tool).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return !b.FindEntity(*tool) && !c.FindEntity(*tool) && !d.FindEntity(*tool);
  }, 10.0));
  for (Client* x : {&a, &b, &c, &d}) {
    EXPECT_EQ(x->FindProperty(*tool, "tip"), nullptr);
    EXPECT_EQ(x->properties().size(), 3u);
  }
  EXPECT_EQ(room.properties().count(), 3u);
  EXPECT_EQ(room.property_stats().refused, 0u);
  EXPECT_EQ(room.property_stats().accepted, 3u * kN + 6);
}

TEST(Properties, OfTwoCompareAndSetWritersExactlyOneWinsAndTheOtherSeesTheCurrentValue) {
  SimWorld world(LossyLink());
  PropertyInbox ia, ib, ic;
  auto [a, b, c] = AddJoined(world, "cas", ia, ib, ic);
  // Created once: the second create (expected version 0) loses.
  Result<uint32_t> made = a.CompareAndSetProperty(0, "turn", PropertyValue::Int64(0), 0,
                                                  PropertyAuthority::kAnyone);
  ASSERT_TRUE(made.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindProperty(0, "turn") != nullptr; }, 10.0));
  Result<uint32_t> late = b.CompareAndSetProperty(0, "turn", PropertyValue::Int64(99), 0);
  ASSERT_TRUE(late.ok());
  ASSERT_TRUE(world.RunUntil([&] { return !ib.conflicts.empty(); }, 10.0));
  EXPECT_EQ(ib.conflicts[0].request_id, *late);
  EXPECT_EQ(ib.conflicts[0].version, 1u);
  EXPECT_EQ(ib.conflicts[0].value, PropertyValue::Int64(0));
  EXPECT_EQ(ib.conflicts[0].writer, 1u);

  constexpr uint32_t kRounds = 20;
  for (uint32_t round = 1; round <= kRounds; ++round) {
    const size_t conflicts_before = ia.conflicts.size() + ib.conflicts.size();
    // Both expect the version they see now; both writes leave in the same step.
    Result<uint32_t> ra = a.CompareAndSetProperty(0, "turn", PropertyValue::Int64(1000 + round), round);
    Result<uint32_t> rb = b.CompareAndSetProperty(0, "turn", PropertyValue::Int64(2000 + round), round);
    ASSERT_TRUE(ra.ok() && rb.ok());
    ASSERT_TRUE(world.RunUntil([&] {
      for (const Client* x : {&a, &b, &c}) {
        const PropertyRecord* p = x->FindProperty(0, "turn");
        if (p == nullptr || p->version != round + 1) return false;
      }
      return ia.conflicts.size() + ib.conflicts.size() > conflicts_before;
    }, 20.0)) << "round " << round;
    ASSERT_EQ(ia.conflicts.size() + ib.conflicts.size(), conflicts_before + 1) << round;
    const PropertyRecord& now = *c.FindProperty(0, "turn");
    const bool a_won = now.writer == 1;
    const PropertyRecord& lost = a_won ? ib.conflicts.back() : ia.conflicts.back();
    EXPECT_EQ(lost.request_id, a_won ? *rb : *ra);
    EXPECT_EQ(lost.version, round + 1);
    EXPECT_EQ(lost.value, PropertyValue::Int64((a_won ? 1000 : 2000) + round));
    EXPECT_EQ(lost.writer, a_won ? 1u : 2u);
    EXPECT_EQ(now.value, lost.value);
    EXPECT_EQ(a.FindProperty(0, "turn")->value, now.value);
    EXPECT_EQ(b.FindProperty(0, "turn")->value, now.value);
  }
  const RoomHost::PropertyStats& stats = world.relay().rooms().at("cas")->property_stats();
  EXPECT_EQ(stats.conflicts, kRounds + 1);
  EXPECT_EQ(stats.accepted, kRounds + 1);
  EXPECT_EQ(stats.refused, 0u);
  EXPECT_EQ(world.counters().property_conflicts.load(), kRounds + 1);  // /metrics
  EXPECT_EQ(world.counters().property_writes.load(), kRounds + 1);
  EXPECT_TRUE(ic.conflicts.empty());  // a conflict goes to the losing writer only
}

// The figure for docs/benchmarks.md: bytes of one sealed UDP datagram carrying a property
// update, writer -> relay (PropertySet) and relay -> member (PropertyChanged), no loss, with
// no entity states in flight. Checked only to be a single datagram of plausible size.
TEST(Properties, BytesOnTheWirePerUpdate) {
  SimWorld world;
  PropertyInbox ia, ib;
  auto [a, b] = AddJoined(world, "wire", ia, ib);
  world.RunFor(1.0);
  struct Case {
    const char* name;
    const char* key;
    PropertyValue value;
  };
  const std::vector<Case> cases = {
      {"int64", "step", PropertyValue::Int64(42)},
      {"vec3", "marker", PropertyValue::Vec3({1.5f, 0.25f, -3})},
      {"bool", "lit", PropertyValue::Bool(true)},
      {"string(16)", "title", PropertyValue::String("0123456789abcdef")},
  };
  for (const Case& k : cases) {
    for (int repeat = 0; repeat < 2; ++repeat) {  // the second write: the steady figure
      world.RunFor(0.3);
      const ConnectionStats sa = *a.stats();
      const size_t changes = ib.changes.size();
      ASSERT_TRUE(a.SetProperty(0, k.key, k.value).ok());
      world.Step();  // A sends
      const uint64_t up_packets = a.stats()->packets_sent - sa.packets_sent;
      const uint64_t up_bytes = a.stats()->bytes_sent - sa.bytes_sent;
      // The step in which B is told: what arrived at B in it.
      uint64_t down_packets = 0, down_bytes = 0;
      for (int i = 0; i < 400 && ib.changes.size() == changes; ++i) {
        const ConnectionStats sb = *b.stats();
        world.Step();
        down_packets = b.stats()->packets_received - sb.packets_received;
        down_bytes = b.stats()->bytes_received - sb.bytes_received;
      }
      ASSERT_GT(ib.changes.size(), changes);
      ASSERT_EQ(up_packets, 1u) << k.name;
      ASSERT_EQ(down_packets, 1u) << k.name;
      EXPECT_GT(up_bytes, 20u);
      EXPECT_LT(up_bytes, 200u);
      EXPECT_GT(down_bytes, up_bytes);  // the change names its writer and version
      if (repeat == 1) {
        std::printf("property update %-10s key '%s': writer->relay %llu B, relay->member %llu B "
                    "(sealed UDP payload)\n",
                    k.name, k.key, static_cast<unsigned long long>(up_bytes),
                    static_cast<unsigned long long>(down_bytes));  // stats count the seal
        // Of which the ControlMessage{PropertyChanged} itself:
        PropertyRecord r{0, k.key, k.value, 2, 1, 1, PropertyAuthority::kOwner, 1};
        flatbuffers::FlatBufferBuilder fbb(128);
        BuildPropertyChanged(fbb, r);
        std::printf("  PropertyChanged message %u B; seal %zu B\n", fbb.GetSize(), kSealOverhead);
      }
    }
  }
}

}  // namespace
}  // namespace edgephys::testing
