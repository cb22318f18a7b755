// Properties through the C API against a real relay on loopback UDP: set, compare-and-set
// (of two writers expecting the same version one wins; the other gets
// EDGEPHYS_EVENT_PROPERTY_CONFLICT with the current value), PROPERTY_CHANGED events carrying the
// writer, the version and the request id, a late joiner's properties, refusals as ERROR events
// naming the property, and bad arguments refused before anything is sent.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include "edgephys/edgephys.h"
#include "edgephys/edgephys.hpp"
#include "protocol/join_token.h"
#include "tests/integration/c_client_connect.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

struct Seen {
  edgephys_event event;
  edgephys_property property;
  std::string bytes;  // a string/bytes value
};

// A C API client that keeps the spawns, errors and property events it got.
class CClient : public CClientBase {
 public:
  using CClientBase::CClientBase;

  std::vector<Seen> Changes(uint32_t entity, const char* key) const {
    std::vector<Seen> out;
    for (const Seen& s : changed) {
      if (s.event.entity_id == entity && std::strcmp(s.event.detail, key) == 0) out.push_back(s);
    }
    return out;
  }

  std::vector<uint32_t> spawned;
  std::vector<Seen> changed, conflicts;
  std::vector<edgephys_event> errors;

 private:
  void OnEvent(const edgephys_event& ev) override {
    if (ev.type == EDGEPHYS_EVENT_SPAWNED) spawned.push_back(ev.entity_id);
    if (ev.type == EDGEPHYS_EVENT_ERROR) errors.push_back(ev);
    if (ev.type == EDGEPHYS_EVENT_PROPERTY_CHANGED || ev.type == EDGEPHYS_EVENT_PROPERTY_CONFLICT) {
      Seen s{ev, {}, {}};
      s.property.struct_size = sizeof(s.property);
      char buffer[256];
      EXPECT_EQ(edgephys_client_get_event_property(c, &s.property, buffer, sizeof(buffer)),
                EDGEPHYS_OK)
          << edgephys_last_error();
      if (s.property.value.data != nullptr) {
        s.bytes.assign(static_cast<const char*>(s.property.value.data), s.property.value.size);
      }
      s.property.value.data = nullptr;
      (ev.type == EDGEPHYS_EVENT_PROPERTY_CHANGED ? changed : conflicts).push_back(s);
    }
  }
};

edgephys_property_value Int(int64_t v) {
  edgephys_property_value p{};
  p.type = EDGEPHYS_PROPERTY_INT64;
  p.int_value = v;
  return p;
}

TEST(CApiProperties, SetCompareAndSetConflictAndLateJoiner) {
  LoopbackWorld world;
  CClient a(world, MintToken("step", 1)), b(world, MintToken("step", 2));
  ASSERT_TRUE(Pump(world, {&a, &b}, "step", [&] { return a.joined && b.joined; }));
  // The shared "current step": created by A, anyone may advance it with compare-and-set.
  edgephys_property_value v0 = Int(0);
  uint32_t made = 0;
  ASSERT_EQ(edgephys_client_compare_and_set_property(a.c, 0, "current step", &v0, 0,
                                                     EDGEPHYS_AUTHORITY_ANYONE, &made),
            EDGEPHYS_OK);
  ASSERT_TRUE(Pump(world, {&a, &b}, nullptr, [&] { return !b.Changes(0, "current step").empty(); }));
  const Seen first = b.Changes(0, "current step")[0];
  EXPECT_EQ(first.event.player_id, 1u);  // the writer
  EXPECT_EQ(first.event.code, 1u);       // the version
  EXPECT_EQ(first.event.other_id, made);  // the request id
  EXPECT_EQ(first.event.flags, static_cast<uint32_t>(EDGEPHYS_PROPERTY_INT64));
  EXPECT_EQ(first.property.authority, static_cast<uint32_t>(EDGEPHYS_AUTHORITY_ANYONE));
  EXPECT_EQ(first.property.owner, 1u);
  // Both try to move from version 1 to their own next step: one wins.
  edgephys_property_value va = Int(10), vb = Int(20);
  uint32_t ra = 0, rb = 0;
  ASSERT_EQ(edgephys_client_compare_and_set_property(a.c, 0, "current step", &va, 1, 0, &ra), EDGEPHYS_OK);
  ASSERT_EQ(edgephys_client_compare_and_set_property(b.c, 0, "current step", &vb, 1, 0, &rb), EDGEPHYS_OK);
  ASSERT_TRUE(Pump(world, {&a, &b}, nullptr, [&] {
    return a.conflicts.size() + b.conflicts.size() == 1 && a.Changes(0, "current step").size() == 2 &&
           b.Changes(0, "current step").size() == 2;
  }));
  world.RunFor(0.2);
  for (CClient* c : {&a, &b}) c->Update(nullptr);
  ASSERT_EQ(a.conflicts.size() + b.conflicts.size(), 1u);
  const bool a_lost = a.conflicts.size() == 1;
  const Seen& lost = a_lost ? a.conflicts[0] : b.conflicts[0];
  EXPECT_EQ(lost.event.other_id, a_lost ? ra : rb);
  EXPECT_STREQ(lost.event.detail, "current step");
  EXPECT_EQ(lost.event.code, 2u);
  EXPECT_EQ(lost.property.version, 2u);
  EXPECT_EQ(lost.property.value.int_value, a_lost ? 20 : 10);  // the winner's value
  EXPECT_EQ(lost.event.player_id, a_lost ? 2u : 1u);
  edgephys_property now{};
  now.struct_size = sizeof(now);
  ASSERT_EQ(edgephys_client_get_property(a.c, 0, "current step", &now, nullptr, 0), EDGEPHYS_OK);
  EXPECT_EQ(now.version, 2u);
  EXPECT_EQ(now.value.int_value, lost.property.value.int_value);

  // A string and an entity property; a late joiner gets all of them, after the entity.
  edgephys_property_value title{};
  title.type = EDGEPHYS_PROPERTY_STRING;
  title.data = "suture, step 2";
  title.size = std::strlen("suture, step 2");
  ASSERT_EQ(edgephys_client_set_property(a.c, 0, "title", &title, 0, nullptr), EDGEPHYS_OK);
  edgephys_spawn_desc desc;
  ASSERT_EQ(edgephys_spawn_desc_init(&desc), EDGEPHYS_OK);
  uint32_t tool = 0;
  ASSERT_EQ(edgephys_client_spawn(a.c, &desc, &tool), EDGEPHYS_OK) << edgephys_last_error();
  edgephys_property_value tip{};
  tip.type = EDGEPHYS_PROPERTY_VEC3;
  tip.vec3 = {0.1f, 0.2f, 0.3f};
  ASSERT_EQ(edgephys_client_set_property(a.c, tool, "tip", &tip, 0, nullptr), EDGEPHYS_OK);
  ASSERT_TRUE(Pump(world, {&a, &b}, nullptr, [&] { return !b.Changes(tool, "tip").empty(); }));
  CClient c(world, MintToken("step", 3));
  ASSERT_TRUE(Pump(world, {&a, &b, &c}, "step", [&] { return c.changed.size() == 3; }));
  ASSERT_FALSE(c.spawned.empty());
  EXPECT_EQ(c.Changes(0, "current step").at(0).property.version, 2u);
  EXPECT_EQ(c.Changes(0, "title").at(0).bytes, "suture, step 2");
  const Seen& t = c.Changes(tool, "tip").at(0);
  EXPECT_FLOAT_EQ(t.property.value.vec3.z, 0.3f);
  EXPECT_EQ(t.property.writer, 1u);
  char small[4];
  edgephys_property p{};
  p.struct_size = sizeof(p);
  EXPECT_EQ(edgephys_client_get_property(c.c, 0, "title", &p, small, sizeof(small)),
            EDGEPHYS_E_BUFFER_TOO_SMALL);
  EXPECT_EQ(p.value.size, std::strlen("suture, step 2"));
}

TEST(CApiProperties, RefusalsAreErrorEventsNamingThePropertyAndBadArgumentsNeverLeave) {
  LoopbackWorld world;
  CClient a(world, MintToken("rules", 1)), b(world, MintToken("rules", 2));
  ASSERT_TRUE(Pump(world, {&a, &b}, "rules", [&] { return a.joined && b.joined; }));
  edgephys_property_value lit{};
  lit.type = EDGEPHYS_PROPERTY_BOOL;
  lit.int_value = 1;
  ASSERT_EQ(edgephys_client_set_property(a.c, 0, "lights", &lit, EDGEPHYS_AUTHORITY_OWNER, nullptr), EDGEPHYS_OK);
  ASSERT_TRUE(Pump(world, {&a, &b}, nullptr, [&] { return !b.changed.empty(); }));
  lit.int_value = 0;
  ASSERT_EQ(edgephys_client_set_property(b.c, 0, "lights", &lit, 0, nullptr), EDGEPHYS_OK);
  ASSERT_TRUE(Pump(world, {&a, &b}, nullptr, [&] { return !b.errors.empty(); }));
  EXPECT_EQ(b.errors[0].code, static_cast<uint32_t>(EDGEPHYS_REJECT_NOT_OWNER));
  EXPECT_STREQ(edgephys_reason_name(b.errors[0].type, b.errors[0].code), "NotOwner");
  EXPECT_NE(std::strstr(b.errors[0].detail, "'lights'"), nullptr) << b.errors[0].detail;

  // Bad arguments: refused here, nothing sent.
  edgephys_property_value bad{};
  bad.type = EDGEPHYS_PROPERTY_DOUBLE;
  bad.double_value = NAN;
  EXPECT_EQ(edgephys_client_set_property(a.c, 0, "x", &bad, 0, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_NE(std::strstr(edgephys_last_error(), "NaN"), nullptr) << edgephys_last_error();
  bad.type = EDGEPHYS_PROPERTY_QUAT;
  bad.quat = {0, 0, INFINITY, 1};
  EXPECT_EQ(edgephys_client_set_property(a.c, 0, "x", &bad, 0, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  bad.type = 9;
  EXPECT_EQ(edgephys_client_set_property(a.c, 0, "x", &bad, 0, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  edgephys_property_value ok = Int(1);
  const std::string long_key(65, 'k');
  EXPECT_EQ(edgephys_client_set_property(a.c, 0, long_key.c_str(), &ok, 0, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_set_property(a.c, 0, "", &ok, 0, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_set_property(a.c, 0, nullptr, &ok, 0, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_set_property(a.c, 0, "x", nullptr, 0, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_set_property(a.c, 0, "x", &ok, 2, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_set_property(a.c, 424242, "x", &ok, 0, nullptr), EDGEPHYS_E_NOT_FOUND);
  EXPECT_EQ(edgephys_client_set_property(nullptr, 0, "x", &ok, 0, nullptr), EDGEPHYS_E_INVALID_HANDLE);
  std::vector<char> huge(EDGEPHYS_MAX_PROPERTY_VALUE_BYTES + 1, 'h');
  edgephys_property_value big{};
  big.type = EDGEPHYS_PROPERTY_BYTES;
  big.data = huge.data();
  big.size = huge.size();
  EXPECT_EQ(edgephys_client_set_property(a.c, 0, "x", &big, 0, nullptr), EDGEPHYS_E_TOO_LARGE);
  big.data = nullptr;
  big.size = 3;
  EXPECT_EQ(edgephys_client_set_property(a.c, 0, "x", &big, 0, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  edgephys_property out{};
  out.struct_size = sizeof(out);
  EXPECT_EQ(edgephys_client_get_property(a.c, 0, "nope", &out, nullptr, 0), EDGEPHYS_E_NOT_FOUND);
  out.struct_size = 3;
  EXPECT_EQ(edgephys_client_get_property(a.c, 0, "lights", &out, nullptr, 0), EDGEPHYS_E_INVALID_ARGUMENT);
  out.struct_size = sizeof(out);
  edgephys_event ev;
  ASSERT_EQ(edgephys_client_poll_event(a.c, &ev), EDGEPHYS_OK);  // empty or not a property event
  EXPECT_EQ(edgephys_client_get_event_property(a.c, &out, nullptr, 0), EDGEPHYS_E_NOT_FOUND);
  world.RunFor(0.3);
  for (CClient* c : {&a, &b}) c->Update(nullptr);
  EXPECT_EQ(a.changed.size(), 1u);  // only "lights" ever existed
  EXPECT_TRUE(a.errors.empty());
}

TEST(CApiProperties, TheCppWrapperWritesAndReadsEveryType) {
  LoopbackWorld world;
  edgephys_client_config cfg;
  ASSERT_EQ(edgephys_client_config_init(&cfg), EDGEPHYS_OK);
  cfg.bind_address = "127.0.0.1:0";
  sdk::Client a(&cfg), b(&cfg);
  ASSERT_TRUE(a.ok() && b.ok());
  const std::string relay = "127.0.0.1:" + std::to_string(world.relay_endpoint().port());
  ASSERT_EQ(a.Connect(relay, Base64UrlEncode(MintToken("cpp", 1)), world.Now()), EDGEPHYS_OK);
  ASSERT_EQ(b.Connect(relay, Base64UrlEncode(MintToken("cpp", 2)), world.Now()), EDGEPHYS_OK);
  int joined = 0;
  std::vector<sdk::Property> seen;
  const auto pump = [&](const std::function<bool()>& done) {
    return world.RunUntil([&] {
      for (sdk::Client* c : {&a, &b}) {
        EXPECT_EQ(c->Update(world.Now()), EDGEPHYS_OK);
        edgephys_event ev;
        while (c->Poll(&ev)) {
          if (ev.type == EDGEPHYS_EVENT_CONNECTED) {
            EXPECT_EQ(c->Join("cpp"), EDGEPHYS_OK);
          }
          if (ev.type == EDGEPHYS_EVENT_JOINED) ++joined;
          if (ev.type == EDGEPHYS_EVENT_PROPERTY_CHANGED && c == &b) {
            sdk::Property p;
            EXPECT_TRUE(c->EventProperty(&p));
            seen.push_back(p);
          }
        }
      }
      return done();
    }, 5.0);
  };
  ASSERT_TRUE(pump([&] { return joined == 2; }));
  const std::string text = "hello", blob("\0\xff\x01", 3);
  EXPECT_NE(a.SetProperty(0, "b", sdk::BoolValue(true)), 0u);
  EXPECT_NE(a.SetProperty(0, "i", sdk::Int64Value(-7)), 0u);
  EXPECT_NE(a.SetProperty(0, "d", sdk::DoubleValue(2.5)), 0u);
  EXPECT_NE(a.SetProperty(0, "s", sdk::StringValue(text)), 0u);
  EXPECT_NE(a.SetProperty(0, "y", sdk::StringValue(blob, true)), 0u);
  EXPECT_NE(a.SetProperty(0, "v", sdk::Vec3Value({1, 2, 3})), 0u);
  EXPECT_NE(a.SetProperty(0, "q", sdk::QuatValue({0, 0, 0, 1})), 0u);
  EXPECT_EQ(a.SetProperty(0, "n", sdk::DoubleValue(NAN)), 0u);
  ASSERT_TRUE(pump([&] { return seen.size() == 7; }));
  sdk::Property p;
  ASSERT_TRUE(b.GetProperty(0, "s", &p));
  EXPECT_EQ(std::string(static_cast<const char*>(p.info.value.data), p.info.value.size), text);
  ASSERT_TRUE(b.GetProperty(0, "y", &p));
  EXPECT_EQ(p.bytes, blob);
  ASSERT_TRUE(b.GetProperty(0, "v", &p));
  EXPECT_FLOAT_EQ(p.info.value.vec3.y, 2);
  ASSERT_TRUE(b.GetProperty(0, "d", &p));
  EXPECT_DOUBLE_EQ(p.info.value.double_value, 2.5);
  ASSERT_TRUE(b.GetProperty(0, "i", &p));
  EXPECT_EQ(p.info.value.int_value, -7);
  EXPECT_EQ(p.info.writer, 1u);
  EXPECT_FALSE(b.GetProperty(0, "n", &p));
  EXPECT_EQ(seen[3].bytes, text);  // the event's own copy
}

}  // namespace
}  // namespace edgephys::testing
