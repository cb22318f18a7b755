// Entity ownership through a real relay (docs/protocol.md "Ownership"): a hand over from A to B
// makes the relay accept B's states within one round trip of the change and drop (and count)
// A's later ones; a free entity is granted on request; a request is refused while the owner
// forbids takeover; a late joiner sees the current owner; the same under 20 % loss,
// duplication and reordering; hostile requests are refused and counted.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "client/client_testing.h"
#include "protocol/container_builder.h"
#include "relay/room_host.h"
#include "tests/integration/property_inbox.h"
#include "tests/integration/sim_world.h"

namespace edgephys::testing {
namespace {

using schema::RejectReason;

struct OwnershipInbox : PropertyInbox {
  struct Change {
    uint32_t entity, owner, seq;
    double at;
  };
  std::vector<Change> owner_changes;
  const double* clock = nullptr;
  std::function<void(uint32_t, uint32_t)> on_change;  // (entity, owner), inside the callback
  void OnOwnershipChanged(uint32_t entity, uint32_t owner, uint32_t seq) override {
    owner_changes.push_back({entity, owner, seq, clock != nullptr ? *clock : 0});
    if (on_change) on_change(entity, owner);
  }
};

// Received states are quantised (1 mm steps by default).
bool Near(float got, float want) { return std::fabs(got - want) < 0.002f; }

const Entity* RelayEntity(SimWorld& world, const char* room, uint32_t id) {
  const auto& entities = world.relay().rooms().at(room)->room().entities();
  const auto it = entities.find(id);
  return it == entities.end() ? nullptr : &it->second;
}

// Without loss, on a 30 ms (one way) link: B's first state after the change is accepted within
// one round trip (plus one publish interval and a step) of the change at the relay, A's later
// states are dropped and counted, and every member hears of the change once.
TEST(Ownership, HandOverAcceptsTheNewOwnerWithinOneRoundTripAndDropsTheOldOwnersStates) {
  NetworkConditions link;
  link.latency_s = 0.030;
  SimWorld world(link);
  double now = 0;
  OwnershipInbox ia, ib, ic;
  ia.clock = ib.clock = ic.clock = &now;
  auto [a, b, c] = AddJoined(world, "own", ia, ib, ic);
  Result<uint32_t> id = a.Spawn({.position = {0, 1, 0}});
  ASSERT_TRUE(id.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*id) && c.FindEntity(*id); }, 10.0));
  ASSERT_TRUE(a.PublishTransform(*id, {1, 1, 0}, {0, 0, 0, 1}).ok());
  ASSERT_TRUE(world.RunUntil([&] { return Near(c.FindEntity(*id)->state.position.x, 1.f); }, 5.0));

  // B moves it as soon as it hears it owns it (inside the callback, as a game would).
  ib.on_change = [&](uint32_t entity, uint32_t owner) {
    if (entity == *id && owner == 2) {
      EXPECT_TRUE(b.PublishTransform(*id, {-5, 1, 0}, {0, 0, 0, 1}).ok());
    }
  };
  ASSERT_TRUE(a.HandOver(*id, 2).ok());
  // A keeps moving it until it hears of the change.
  double changed_at = -1, accepted_at = -1;
  float a_x = 1;
  ASSERT_TRUE(world.RunUntil([&] {
    now = world.Now();
    if (a.Owns(*id)) {
      a_x += 0.001f;
      EXPECT_TRUE(a.PublishTransform(*id, {a_x, 1, 0}, {0, 0, 0, 1}).ok());
    }
    const Entity* e = RelayEntity(world, "own", *id);
    if (changed_at < 0 && e->authority_seq == 1) changed_at = world.Now();
    if (accepted_at < 0 && e->state.position.x == -5.f) accepted_at = world.Now();
    return accepted_at >= 0 && !a.Owns(*id);
  }, 5.0));
  const double rtt = 2 * link.latency_s;
  const double publish_interval = 1.0 / ClientConfig{}.publish_rate_hz;
  EXPECT_LE(accepted_at - changed_at, rtt + publish_interval + 3 * 0.005)
      << "B's first state was accepted " << accepted_at - changed_at << " s after the change";
  ASSERT_EQ(ib.owner_changes.size(), 1u);
  EXPECT_EQ(ib.owner_changes[0].owner, 2u);
  EXPECT_EQ(ib.owner_changes[0].seq, 1u);
  ASSERT_TRUE(world.RunUntil([&] { return ic.owner_changes.size() == 1; }, 2.0));
  EXPECT_EQ(c.FindEntity(*id)->owner, 2u);
  EXPECT_EQ(c.OwnerOf(*id), 2u);
  EXPECT_EQ(b.OwnerOf(*id), 2u);
  EXPECT_EQ(b.FindEntity(*id), nullptr);  // B's own now: no longer among the others' entities
  ASSERT_NE(a.FindEntity(*id), nullptr);  // A's view: another's entity
  EXPECT_EQ(a.FindEntity(*id)->owner, 2u);
  EXPECT_EQ(a.PublishTransform(*id, {9, 9, 9}, {0, 0, 0, 1}).code(), StatusCode::kNotFound);

  // A's states sent while the change was on its way arrived after it: dropped, counted. A late
  // state sent now (a stale sender) is too, and changes nothing.
  const uint64_t stale_before = world.counters().stale_owner_states.load();
  EXPECT_GE(stale_before, 1u);
  ASSERT_TRUE(ClientTesting::SendStateUnchecked(a, {*id, {42, 1, 0}, {0, 0, 0, 1}}, world.Now()).ok());
  world.RunFor(0.5);
  EXPECT_EQ(world.counters().stale_owner_states.load(), stale_before + 1);
  EXPECT_EQ(RelayEntity(world, "own", *id)->state.position.x, -5.f);
  EXPECT_EQ(world.relay().rooms().at("own")->ownership_stats().stale, stale_before + 1);
  // Everyone shows B's pose, A included.
  ASSERT_TRUE(world.RunUntil([&] {
    return Near(a.FindEntity(*id)->state.position.x, -5.f) && Near(c.FindEntity(*id)->state.position.x, -5.f);
  }, 2.0));
  EXPECT_TRUE(ia.errors.empty() && ib.errors.empty() && ic.errors.empty());
}

TEST(Ownership, RequestsTakeoverReleaseAndLateJoinersUnderLoss) {
  SimWorld world(LossyLink());
  OwnershipInbox ia, ib, ic, id_in;
  auto [a, b, c] = AddJoined(world, "own2", ia, ib, ic);
  Result<uint32_t> tool = a.Spawn({.position = {0, 1, 0}});
  Result<uint32_t> free_box = a.Spawn({.position = {2, 1, 0}});
  ASSERT_TRUE(tool.ok() && free_box.ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return b.FindEntity(*tool) && c.FindEntity(*tool) && b.FindEntity(*free_box) &&
           c.FindEntity(*free_box);
  }, 10.0));

  // Forbidden (the default): B's request is refused with its reason; nothing changes.
  ASSERT_TRUE(b.RequestOwnership(*tool).ok());
  ASSERT_TRUE(world.RunUntil([&] { return !ib.errors.empty(); }, 10.0));
  EXPECT_EQ(ib.Count(RejectReason::TakeoverRefused), 1u);
  EXPECT_TRUE(a.Owns(*tool));
  EXPECT_EQ(RequestsRejected(world.counters(), RejectReason::TakeoverRefused), 1u);

  // Released to the room: C's request is granted.
  ASSERT_TRUE(a.ReleaseOwnership(*free_box).ok());
  ASSERT_TRUE(world.RunUntil([&] { return c.OwnerOf(*free_box) == 0 && !a.Owns(*free_box); }, 10.0));
  ASSERT_TRUE(c.RequestOwnership(*free_box).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return c.Owns(*free_box) && a.OwnerOf(*free_box) == 3 && b.OwnerOf(*free_box) == 3;
  }, 10.0));

  // Takeover allowed: B's request is granted at once; C moves the box; B moves the tool.
  ASSERT_TRUE(a.SetTakeoverAllowed(*tool, true).ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*tool)->takeover_allowed; }, 10.0));
  ASSERT_TRUE(b.RequestOwnership(*tool).ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.Owns(*tool) && c.OwnerOf(*tool) == 2; }, 10.0));
  ASSERT_TRUE(b.PublishTransform(*tool, {0.5f, 1, 0}, {0, 0, 0, 1}).ok());
  ASSERT_TRUE(c.PublishTransform(*free_box, {3, 1, 0}, {0, 0, 0, 1}).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return Near(a.FindEntity(*tool)->state.position.x, 0.5f) &&
           Near(a.FindEntity(*free_box)->state.position.x, 3.f) &&
           Near(b.FindEntity(*free_box)->state.position.x, 3.f) &&
           Near(c.FindEntity(*tool)->state.position.x, 0.5f);
  }, 10.0));
  // A stale state of A's for the tool (it owned it before): dropped and counted.
  const uint64_t stale = world.counters().stale_owner_states.load();
  for (int i = 0; i < 20; ++i) {  // 20 % loss: several, so that some arrive
    ASSERT_TRUE(ClientTesting::SendStateUnchecked(a, {*tool, {7, 7, 7}, {0, 0, 0, 1}}, world.Now()).ok());
    world.RunFor(0.01);
  }
  world.RunFor(1.0);
  EXPECT_GT(world.counters().stale_owner_states.load(), stale);
  EXPECT_EQ(RelayEntity(world, "own2", *tool)->state.position.x, 0.5f);
  for (OwnershipInbox* in : {&ia, &ib, &ic}) {  // each change once, in order
    std::vector<uint32_t> tool_seqs;
    for (const auto& ch : in->owner_changes) {
      if (ch.entity == *tool) tool_seqs.push_back(ch.seq);
    }
    EXPECT_EQ(tool_seqs, std::vector<uint32_t>{1});
  }

  // A late joiner sees the current owners and sequences.
  Client& d = world.AddClient(MintToken("own2", 4), &id_in);
  JoinAll(world, {&d}, "own2");
  ASSERT_TRUE(world.RunUntil([&] {
    return d.FindEntity(*tool) && d.FindEntity(*free_box) && id_in.owner_changes.size() == 2;
  }, 20.0));
  EXPECT_EQ(d.OwnerOf(*tool), 2u);
  EXPECT_EQ(d.FindEntity(*tool)->authority_seq, 1u);
  EXPECT_TRUE(d.FindEntity(*tool)->takeover_allowed);  // the setting stays with the entity
  EXPECT_EQ(d.OwnerOf(*free_box), 3u);
  EXPECT_EQ(d.FindEntity(*free_box)->authority_seq, 2u);
  ASSERT_TRUE(world.RunUntil([&] { return Near(d.FindEntity(*tool)->state.position.x, 0.5f); }, 10.0));

  // Hand back to its creator under loss: converges.
  ASSERT_TRUE(b.HandOver(*tool, 1).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return a.Owns(*tool) && c.OwnerOf(*tool) == 1 && d.OwnerOf(*tool) == 1 && !b.Owns(*tool);
  }, 10.0));
  ASSERT_TRUE(a.PublishTransform(*tool, {0.25f, 1, 0}, {0, 0, 0, 1}).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return Near(b.FindEntity(*tool)->state.position.x, 0.25f) &&
           Near(d.FindEntity(*tool)->state.position.x, 0.25f);
  }, 10.0));
  EXPECT_EQ(world.relay().rooms().at("own2")->ownership_stats().changes, 4u);
}

Quatf AboutY(float angle) { return {0, std::sin(angle / 2), 0, std::cos(angle / 2)}; }
Quatf Mul(const Quatf& a, const Quatf& b) {
  return {a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y, a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
          a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w, a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z};
}
double AngleDeg(const Quatf& a, const Quatf& b) {
  const double dot = std::fabs(double(a.x) * b.x + double(a.y) * b.y + double(a.z) * b.z +
                               double(a.w) * b.w);
  return 2 * std::acos(std::min(1.0, dot)) * 180 / 3.14159265358979;
}
// Whether `s` lies on the uniform motion from `from` at `v` (m/s) turning at `w_y` (rad/s about
// y): within 1 mm of the line and 0.1 degree of the rotation, at some time 0 < t < 2 s.
::testing::AssertionResult OnMotion(const EntityState& from, const Vec3f& v, float w_y,
                                    const EntityState& s) {
  const Vec3f d{s.position.x - from.position.x, s.position.y - from.position.y,
                s.position.z - from.position.z};
  const double vv = double(v.x) * v.x + double(v.y) * v.y + double(v.z) * v.z;
  const double t = (d.x * v.x + d.y * v.y + d.z * v.z) / vv;
  const double rx = d.x - v.x * t, ry = d.y - v.y * t, rz = d.z - v.z * t;
  const double off = std::sqrt(rx * rx + ry * ry + rz * rz);
  const double angle = AngleDeg(Mul(AboutY(static_cast<float>(w_y * t)), from.rotation), s.rotation);
  if (t <= 0 || t > 2 || off > 0.001 || angle > 0.1) {
    return ::testing::AssertionFailure() << "t " << t << " s, " << off * 1000
                                         << " mm off the line, " << angle << " deg off the turn";
  }
  return ::testing::AssertionSuccess();
}

// Real Bullet (embedded PhyS): a body A simulates locally (mirrored in PhyS) is released to the
// room and PhyS carries on with it from A's last pose at A's velocities; B then requests it
// and gets PhyS's pose and velocities to carry on locally. No despawn; within 1 mm and
// 0.1 degree of the motion at both switches.
TEST(Ownership, ReleaseOffloadsToPhySAndARequestReclaimsKeepingPoseAndVelocity) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.physics_threads = 1;  // PhyS steps on the relay's thread: in step with the fake clock
  SimWorld world({}, config);
  OwnershipInbox ia, ib;
  auto [a, b] = AddJoined(world, "switch", ia, ib);
  EntitySpec box = DynamicBox(0, {0, 5, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  box.rigid_body->use_gravity = false;
  Result<uint32_t> id = a.Spawn(box);
  ASSERT_TRUE(id.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*id) != nullptr; }, 5.0));
  ASSERT_EQ(RelayEntity(world, "switch", *id)->physics, PhysicsRole::kMirrored);
  const Vec3f v{1, 0, 0.5f};
  const float w_y = 1.0f;
  // A's local physics: uniform motion, published every step.
  Vec3f p{0, 5, 0};
  Quatf q = AboutY(0);
  for (int i = 1; i <= 60; ++i) {
    p = {p.x + v.x * 0.005f, p.y, p.z + v.z * 0.005f};
    q = AboutY(w_y * 0.005f * i);
    ASSERT_TRUE(a.PublishTransform(*id, p, q).ok());
    world.Step();
  }
  ASSERT_TRUE(world.RunUntil([&] { return RelayEntity(world, "switch", *id)->state.position.x == p.x; }, 2.0));
  const EntityState released = RelayEntity(world, "switch", *id)->state;
  ASSERT_TRUE(a.ReleaseOwnership(*id, v, {0, w_y, 0}).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    const Entity* e = RelayEntity(world, "switch", *id);
    return e->physics == PhysicsRole::kSimulated && e->state.position.x != released.position.x;
  }, 5.0));
  const Entity* e = RelayEntity(world, "switch", *id);
  EXPECT_EQ(e->owner, 0u);
  EXPECT_TRUE(OnMotion(released, v, w_y, e->state));
  EXPECT_NEAR(e->linear_velocity.x, v.x, 0.001);
  EXPECT_NEAR(e->linear_velocity.y, 0, 0.001);
  EXPECT_NEAR(e->linear_velocity.z, v.z, 0.001);
  EXPECT_NEAR(e->angular_velocity.y, w_y, 0.1 * 3.14159265 / 180);
  ASSERT_TRUE(world.RunUntil([&] { return ia.owner_changes.size() == 1 && ib.owner_changes.size() == 1; }, 2.0));
  EXPECT_FALSE(a.Owns(*id));
  EXPECT_EQ(ib.owner_changes[0].owner, 0u);
  // Let PhyS carry it a while; then B takes it back.
  world.RunFor(0.3);
  ASSERT_TRUE(b.RequestOwnership(*id).ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.Owns(*id); }, 5.0));
  EntityState gained;
  Vec3f linear, angular;
  ASSERT_TRUE(b.OwnedMotion(*id, &gained, &linear, &angular).ok());
  e = RelayEntity(world, "switch", *id);
  EXPECT_EQ(e->physics, PhysicsRole::kMirrored);
  EXPECT_EQ(e->owner, 2u);
  EXPECT_TRUE(OnMotion(released, v, w_y, gained));  // where PhyS had carried it
  EXPECT_EQ(gained.position.x, e->state.position.x);  // exactly the relay's pose at the change
  EXPECT_NEAR(linear.x, v.x, 0.001);
  EXPECT_NEAR(linear.z, v.z, 0.001);
  EXPECT_NEAR(angular.y, w_y, 0.1 * 3.14159265 / 180);
  EXPECT_TRUE(ia.errors.empty() && ib.errors.empty());
  EXPECT_TRUE(ib.spawned.size() == 1);  // never despawned and spawned again
  // B's local physics moves it on; the relay takes B's states.
  ASSERT_TRUE(b.PublishTransform(*id, {gained.position.x + 0.01f, gained.position.y, gained.position.z},
                                 gained.rotation).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return RelayEntity(world, "switch", *id)->state.position.x == gained.position.x + 0.01f;
  }, 2.0));
}

TEST(Ownership, HostileRequestsAreRefusedAndCounted) {
  SimWorld world;
  OwnershipInbox ia, ib, is;
  auto [a, b, spectator] = AddJoined(world, "own3", ia, ib, Joiner{&is, kPermissionMessage});
  Result<uint32_t> id = a.Spawn({.position = {0, 1, 0}});
  ASSERT_TRUE(id.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*id) && spectator.FindEntity(*id); }, 10.0));
  // Raw requests: the client SDK refuses these before sending.
  const auto raw = [&](Client& from, uint32_t entity, schema::OwnershipAction action, uint32_t to) {
    flatbuffers::FlatBufferBuilder fbb(64);
    FinishControl(fbb, schema::CreateOwnershipRequest(fbb, entity, action, to, true));
    ASSERT_TRUE(ClientTesting::SendReliableUnchecked(from, {fbb.GetBufferPointer(), fbb.GetSize()}).ok());
  };
  using A = schema::OwnershipAction;
  raw(b, 0xdeadbeef, A::Request, 0);
  raw(b, *id, A::HandOver, 2);
  raw(b, *id, A::Release, 0);
  raw(b, *id, A::SetTakeover, 0);
  raw(a, *id, A::HandOver, 99);
  raw(a, *id, A::HandOver, 3);  // the spectator may not own
  raw(spectator, *id, A::Request, 0);
  raw(a, *id, static_cast<A>(9), 0);
  ASSERT_TRUE(world.RunUntil([&] {
    return ib.errors.size() == 4 && ia.errors.size() == 3 && is.errors.size() == 1;
  }, 10.0));
  EXPECT_EQ(ib.Count(RejectReason::UnknownEntity), 1u);
  EXPECT_EQ(ib.Count(RejectReason::NotOwner), 3u);
  EXPECT_EQ(ia.Count(RejectReason::UnknownPlayer), 1u);
  EXPECT_EQ(ia.Count(RejectReason::NotPermitted), 1u);
  EXPECT_EQ(ia.Count(RejectReason::InvalidMessage), 1u);
  EXPECT_EQ(is.Count(RejectReason::NotPermitted), 1u);
  EXPECT_EQ(RequestsRejected(world.counters(), RejectReason::NotOwner), 3u);
  EXPECT_EQ(world.relay().rooms().at("own3")->ownership_stats().refused, 8u);
  EXPECT_TRUE(a.Owns(*id));
  EXPECT_EQ(world.counters().ownership_changes.load(), 0u);
  // The client refuses what it can tell is wrong without sending.
  EXPECT_EQ(b.HandOver(*id, 1).code(), StatusCode::kNotFound);
  EXPECT_EQ(a.HandOver(*id, 0).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(a.HandOver(*id, 1).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(b.RequestOwnership(0xdeadbeef).code(), StatusCode::kNotFound);
  EXPECT_EQ(b.ReleaseOwnership(*id).code(), StatusCode::kNotFound);
  // A flood of requests: the rate budget refuses the excess, counted; the room goes on.
  ASSERT_TRUE(a.SetTakeoverAllowed(*id, true).ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*id)->takeover_allowed; }, 10.0));
  for (int i = 0; i < 400; ++i) (void)b.RequestOwnership(*id);
  ASSERT_TRUE(world.RunUntil([&] { return ib.Count(RejectReason::RateLimited) > 0 && b.Owns(*id); }, 10.0));
  EXPECT_GT(RequestsRejected(world.counters(), RejectReason::RateLimited), 0u);
}

}  // namespace
}  // namespace edgephys::testing
