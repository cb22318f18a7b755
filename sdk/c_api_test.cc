// Every function of the C API (include/edgephys/edgephys.h) called with bad arguments: NULL
// pointers, NaN and infinite floats, out-of-range sizes and enums, wrong struct sizes, a NULL,
// a closed and a destroyed handle. Each must return its error code (and set a message), never
// crash; scripts/fuzz.sh runs this binary again under ASan + UBSan (c_api_sanitized_test).
#include <gtest/gtest.h>

#include "protocol/join_token.h"

#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "edgephys/edgephys.h"

namespace {

// A client token's printable form (the relay at 127.0.0.1:9 never answers it).
std::string ClientTokenText() {
  edgephys::JoinToken t;
  t.room = "r";
  t.player_id = 1;
  t.expiry_unix_s = 4'000'000'000;
  return edgephys::Base64UrlEncode(*edgephys::SignJoinToken(t, "secret"));
}


constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr float kInf = std::numeric_limits<float>::infinity();

#define EXPECT_STATUS(expected, call)                                             \
  do {                                                                            \
    const edgephys_status got_ = (call);                                          \
    EXPECT_EQ(got_, expected) << #call << ": " << edgephys_last_error();          \
    if (got_ != EDGEPHYS_OK) {                                                    \
      EXPECT_STRNE(edgephys_last_error(), "") << #call;                           \
    }                                                                             \
  } while (0)

edgephys_client* NewClient() {
  edgephys_client_config cfg;
  EXPECT_EQ(edgephys_client_config_init(&cfg), EDGEPHYS_OK);
  cfg.bind_address = "127.0.0.1:0";
  edgephys_client* c = nullptr;
  EXPECT_EQ(edgephys_client_create(&cfg, &c), EDGEPHYS_OK) << edgephys_last_error();
  return c;
}

const edgephys_transform kIdentity{{0, 1, 0}, {0, 0, 0, 1}};

// Every function that takes a client, called with otherwise valid arguments.
std::vector<std::pair<std::string, std::function<edgephys_status(edgephys_client*)>>> ClientCalls() {
  static edgephys_spawn_desc desc;
  (void)edgephys_spawn_desc_init(&desc);
  return {
      {"close", [](edgephys_client* c) { return edgephys_client_close(c); }},
      {"connect", [](edgephys_client* c) { return edgephys_client_connect(c, "127.0.0.1:9", "AAAA", 1.0); }},
      {"update", [](edgephys_client* c) { return edgephys_client_update(c, 1.0); }},
      {"join", [](edgephys_client* c) { return edgephys_client_join(c, "lobby"); }},
      {"leave", [](edgephys_client* c) { return edgephys_client_leave(c); }},
      {"disconnect", [](edgephys_client* c) { return edgephys_client_disconnect(c); }},
      {"spawn", [](edgephys_client* c) { uint32_t id; return edgephys_client_spawn(c, &desc, &id); }},
      {"despawn", [](edgephys_client* c) { return edgephys_client_despawn(c, 65537); }},
      {"publish", [](edgephys_client* c) { return edgephys_client_publish_transform(c, 65537, &kIdentity); }},
      {"grab", [](edgephys_client* c) { return edgephys_client_grab(c, 65537, 65538); }},
      {"grab_at", [](edgephys_client* c) { return edgephys_client_grab_at(c, 65537, 65538, &kIdentity); }},
      {"release", [](edgephys_client* c) { return edgephys_client_release(c, 65537); }},
      {"poll_event", [](edgephys_client* c) { edgephys_event e; return edgephys_client_poll_event(c, &e); }},
      {"get_info", [](edgephys_client* c) {
         edgephys_client_info info{};
         info.struct_size = sizeof(info);
         return edgephys_client_get_info(c, &info);
       }},
      {"get_connection_status", [](edgephys_client* c) {
         edgephys_connection_status st{};
         st.struct_size = sizeof(st);
         return edgephys_client_get_connection_status(c, &st);
       }},
      {"get_entity", [](edgephys_client* c) { edgephys_entity e; return edgephys_client_get_entity(c, 1, &e); }},
      {"list_entities", [](edgephys_client* c) { size_t n; return edgephys_client_list_entities(c, nullptr, 0, &n); }},
      {"get_soft_body", [](edgephys_client* c) { size_t n; return edgephys_client_get_soft_body(c, 1, nullptr, 0, &n); }},
      {"sample_pose", [](edgephys_client* c) {
         edgephys_transform t;
         return edgephys_client_sample_pose(c, 1, 1.0, EDGEPHYS_INTERP_DQ_SCLERP, &t);
       }},
      {"get_state_format", [](edgephys_client* c) { uint32_t f; return edgephys_client_get_state_format(c, &f); }},
      {"set_max_playout_delay", [](edgephys_client* c) { return edgephys_client_set_max_playout_delay(c, 0.1); }},
      {"get_playout_delay", [](edgephys_client* c) { double d; return edgephys_client_get_playout_delay(c, 1, &d); }},
  };
}

TEST(CApi, VersionAndNames) {
  EXPECT_EQ(edgephys_abi_version(), EDGEPHYS_ABI_VERSION);
  EXPECT_STRNE(edgephys_version_string(), "");
  EXPECT_STREQ(edgephys_status_name(EDGEPHYS_OK), "ok");
  EXPECT_STREQ(edgephys_status_name(EDGEPHYS_E_INVALID_ARGUMENT), "invalid argument");
  EXPECT_STREQ(edgephys_status_name(EDGEPHYS_E_INVALID_HANDLE), "invalid handle");
  EXPECT_STREQ(edgephys_status_name(-1), "unknown");
  EXPECT_STREQ(edgephys_status_name(9999), "unknown");
  const double a = edgephys_now_s(), b = edgephys_now_s();
  EXPECT_TRUE(std::isfinite(a));
  EXPECT_LE(a, b);
}

TEST(CApi, ReasonNamesCoverTheTableAndSeparateTheFamilies) {
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_REJECTED, EDGEPHYS_REJECT_BAD_TOKEN), "BadToken");
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_ERROR, EDGEPHYS_REJECT_GRAB_REFUSED),
               "GrabRefused");
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_REJECTED, EDGEPHYS_REJECT_AUTH_REQUIRED),
               "AuthRequired");
  // Code 4 is RoomFull for a rejection and Kicked for a disconnect.
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_REJECTED, 4), "RoomFull");
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_DISCONNECTED, 4), "Kicked");
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_DISCONNECTED,
                                    EDGEPHYS_DISCONNECT_RELIABLE_OVERFLOW),
               "ReliableOverflow");
  // Every code of both families has a name; the first past each family's end has none.
  for (uint32_t code = 0; code <= EDGEPHYS_REJECT_BAD_PROOF; ++code) {
    EXPECT_STRNE(edgephys_reason_name(EDGEPHYS_EVENT_REJECTED, code), "unknown") << code;
  }
  for (uint32_t code = 0; code <= EDGEPHYS_DISCONNECT_RELIABLE_OVERFLOW; ++code) {
    EXPECT_STRNE(edgephys_reason_name(EDGEPHYS_EVENT_DISCONNECTED, code), "unknown") << code;
  }
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_REJECTED, EDGEPHYS_REJECT_BAD_PROOF + 1),
               "unknown");
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_DISCONNECTED,
                                    EDGEPHYS_DISCONNECT_RELIABLE_OVERFLOW + 1),
               "unknown");
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_JOINED, 1), "unknown");
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_REJECTED, 0xFFFFFFFFu), "unknown");
}

TEST(CApi, InitFunctionsRejectNull) {
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_config_init(nullptr));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_spawn_desc_init(nullptr));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_collider_init(nullptr));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_rigid_body_init(nullptr));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_joint_init(nullptr));
  edgephys_spawn_desc d;
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_spawn_desc_init(&d));
  EXPECT_STREQ(edgephys_last_error(), "");
  EXPECT_EQ(d.struct_size, sizeof(d));
  EXPECT_EQ(d.transform.rotation.w, 1.0f);
}

TEST(CApi, CreateRejectsBadConfigs) {
  edgephys_client* c = nullptr;
  edgephys_client_config cfg;
  ASSERT_EQ(edgephys_client_config_init(&cfg), EDGEPHYS_OK);
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_create(nullptr, &c));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_create(&cfg, nullptr));
  auto bad = [&](auto mutate, edgephys_status expected) {
    edgephys_client_config b = cfg;
    mutate(b);
    EXPECT_STATUS(expected, edgephys_client_create(&b, &c));
    EXPECT_EQ(c, nullptr);
  };
  bad([](auto& b) { b.struct_size = 3; }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.publish_rate_hz = std::nan(""); }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.publish_rate_hz = 0; }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.publish_rate_hz = 1e9; }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.handshake_timeout_s = INFINITY; }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.handshake_timeout_s = -1; }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.event_queue_capacity = 0; }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.event_queue_capacity = 0xFFFFFFFFu; }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.queue_state_events = 7; }, EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(cfg.require_packet_auth, 1u);  // sealing required unless turned off
  bad([](auto& b) { b.require_packet_auth = 2; }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.snapshot_capacity = 1; }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.snapshot_capacity = 1u << 30; }, EDGEPHYS_E_INVALID_ARGUMENT);
  bad([](auto& b) { b.bind_address = "not an address"; }, EDGEPHYS_E_MALFORMED);
  bad([](auto& b) { b.bind_address = "203.0.113.1:1"; }, EDGEPHYS_E_IO);  // not a local address
}

TEST(CApi, EveryClientFunctionRejectsANullHandle) {
  for (auto& [name, call] : ClientCalls()) {
    EXPECT_EQ(call(nullptr), EDGEPHYS_E_INVALID_HANDLE) << name;
    EXPECT_STRNE(edgephys_last_error(), "") << name;
  }
  EXPECT_STATUS(EDGEPHYS_E_INVALID_HANDLE, edgephys_client_destroy(nullptr));
}

TEST(CApi, EveryClientFunctionRejectsANeverCreatedHandle) {
  alignas(16) unsigned char garbage[256];
  std::memset(garbage, 0xAB, sizeof(garbage));
  auto* fake = reinterpret_cast<edgephys_client*>(garbage);
  for (auto& [name, call] : ClientCalls()) EXPECT_EQ(call(fake), EDGEPHYS_E_INVALID_HANDLE) << name;
  EXPECT_STATUS(EDGEPHYS_E_INVALID_HANDLE, edgephys_client_destroy(fake));
}

TEST(CApi, EveryClientFunctionRejectsAClosedHandle) {
  edgephys_client* c = NewClient();
  ASSERT_NE(c, nullptr);
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_close(c));
  for (auto& [name, call] : ClientCalls()) {
    EXPECT_EQ(call(c), EDGEPHYS_E_CLOSED) << name;
    EXPECT_STRNE(edgephys_last_error(), "") << name;
  }
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_destroy(c));
}

TEST(CApi, EveryClientFunctionRejectsADestroyedHandle) {
  edgephys_client* c = NewClient();
  ASSERT_NE(c, nullptr);
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_destroy(c));
  for (auto& [name, call] : ClientCalls()) EXPECT_EQ(call(c), EDGEPHYS_E_INVALID_HANDLE) << name;
  EXPECT_STATUS(EDGEPHYS_E_INVALID_HANDLE, edgephys_client_destroy(c));  // double destroy
}

class CApiClient : public ::testing::Test {
 protected:
  void SetUp() override {
    c_ = NewClient();
    ASSERT_NE(c_, nullptr);
  }
  void TearDown() override { EXPECT_EQ(edgephys_client_destroy(c_), EDGEPHYS_OK); }
  edgephys_client* c_ = nullptr;
};

TEST_F(CApiClient, ConnectRejectsBadArguments) {
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_connect(c_, nullptr, "AAAA", 1));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_connect(c_, "127.0.0.1:9", nullptr, 1));
  EXPECT_STATUS(EDGEPHYS_E_MALFORMED, edgephys_client_connect(c_, "nowhere", "AAAA", 1));
  EXPECT_STATUS(EDGEPHYS_E_MALFORMED, edgephys_client_connect(c_, "127.0.0.1:9", "not base64!", 1));
  EXPECT_STATUS(EDGEPHYS_E_MALFORMED, edgephys_client_connect(c_, "127.0.0.1:9", "", 1));
  std::string huge(10000, 'A');
  EXPECT_STATUS(EDGEPHYS_E_TOO_LARGE, edgephys_client_connect(c_, "127.0.0.1:9", huge.c_str(), 1));
  std::string long_token(400, 'A');  // decodes, but longer than any join token
  EXPECT_STATUS(EDGEPHYS_E_MALFORMED, edgephys_client_connect(c_, "127.0.0.1:9", long_token.c_str(), 1));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_connect(c_, "127.0.0.1:9", "AAAA", std::nan("")));
  // Not a client token (no session secret): refused before anything is sent.
  EXPECT_STATUS(EDGEPHYS_E_MALFORMED, edgephys_client_connect(c_, "127.0.0.1:9", "AAAA", 1));
  const std::string token = ClientTokenText();
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_connect(c_, "127.0.0.1:9", token.c_str(), 1));
  EXPECT_STATUS(EDGEPHYS_E_ALREADY_EXISTS, edgephys_client_connect(c_, "127.0.0.1:9", token.c_str(), 1));
}

TEST_F(CApiClient, UpdateRejectsNonFiniteAndBackwardsTime) {
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_update(c_, 5.0));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_update(c_, std::nan("")));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_update(c_, INFINITY));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_update(c_, 4.0));
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_update(c_, 5.0));
}

TEST_F(CApiClient, RoomCallsNeedAConnectionAndAValidName) {
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_join(c_, nullptr));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_join(c_, ""));
  std::string long_room(65, 'r');
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_join(c_, long_room.c_str()));
  EXPECT_STATUS(EDGEPHYS_E_NOT_CONNECTED, edgephys_client_join(c_, "lobby"));
  EXPECT_STATUS(EDGEPHYS_E_NOT_CONNECTED, edgephys_client_leave(c_));
  EXPECT_STATUS(EDGEPHYS_E_NOT_CONNECTED, edgephys_client_disconnect(c_));
  EXPECT_STATUS(EDGEPHYS_E_NOT_CONNECTED, edgephys_client_despawn(c_, 65537));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_grab(c_, 0, 65537));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_grab(c_, 65537, 0));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_grab_at(c_, 65537, 65538, nullptr));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_grab_at(c_, 0, 65538, &kIdentity));
  EXPECT_STATUS(EDGEPHYS_E_NOT_CONNECTED, edgephys_client_grab(c_, 65537, 65538));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_release(c_, 0));
  EXPECT_STATUS(EDGEPHYS_E_NOT_CONNECTED, edgephys_client_release(c_, 65537));
}

TEST_F(CApiClient, PublishRejectsNullNaNAndNonUnitRotations) {
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_publish_transform(c_, 65537, nullptr));
  for (edgephys_transform t : {edgephys_transform{{kNaN, 0, 0}, {0, 0, 0, 1}},
                               edgephys_transform{{0, kInf, 0}, {0, 0, 0, 1}},
                               edgephys_transform{{0, 0, 2e6f}, {0, 0, 0, 1}},
                               edgephys_transform{{0, 0, 0}, {0, 0, 0, kNaN}},
                               edgephys_transform{{0, 0, 0}, {0, 0, 0, 2}},
                               edgephys_transform{{0, 0, 0}, {0, 0, 0, 0}}}) {
    EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_publish_transform(c_, 65537, &t));
  }
  EXPECT_STATUS(EDGEPHYS_E_NOT_CONNECTED, edgephys_client_publish_transform(c_, 65537, &kIdentity));
}

TEST_F(CApiClient, SpawnRejectsEveryBadField) {
  uint32_t id = 0;
  edgephys_spawn_desc ok;
  ASSERT_EQ(edgephys_spawn_desc_init(&ok), EDGEPHYS_OK);
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_spawn(c_, nullptr, &id));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_spawn(c_, &ok, nullptr));
  EXPECT_STATUS(EDGEPHYS_E_NOT_CONNECTED, edgephys_client_spawn(c_, &ok, &id));  // valid, not joined

  edgephys_collider box;
  ASSERT_EQ(edgephys_collider_init(&box), EDGEPHYS_OK);
  edgephys_rigid_body body;
  ASSERT_EQ(edgephys_rigid_body_init(&body), EDGEPHYS_OK);
  edgephys_joint joint;
  ASSERT_EQ(edgephys_joint_init(&joint), EDGEPHYS_OK);
  const float particles[6] = {0, 0, 0, 1, 0, 0};
  const float masses[2] = {1, 1};
  const uint32_t springs[2] = {0, 1};
  edgephys_soft_body soft{particles, masses, 2, springs, 1, 10, 0.1f};
  const float tri[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const uint32_t tri_idx[3] = {0, 1, 2};

  // Makes `c` a collider of `shape` over `floats` vertex floats and, when given, `count`
  // triangle corners (otherwise c's indices stay as they are).
  auto mesh = [](edgephys_collider& c, uint32_t shape, const float* vertices, uint32_t floats,
                 const uint32_t* indices = nullptr, uint32_t count = 0) {
    c.shape = shape;
    c.vertices = vertices;
    c.vertex_float_count = floats;
    if (indices != nullptr) {
      c.indices = indices;
      c.index_count = count;
    }
  };
  // `ok` with one collider `c`, the body `b`, one joint `j` and the soft body `s`.
  auto full = [&ok](const edgephys_collider& c, const edgephys_rigid_body& b,
                    const edgephys_joint& j, const edgephys_soft_body& s) {
    edgephys_spawn_desc d = ok;
    d.colliders = &c;
    d.collider_count = 1;
    d.rigid_body = &b;
    d.joints = &j;
    d.joint_count = 1;
    d.soft_body = &s;
    return d;
  };
  struct Case {
    const char* what;
    std::function<void(edgephys_spawn_desc&, edgephys_collider&, edgephys_rigid_body&,
                       edgephys_joint&, edgephys_soft_body&)> mutate;
  };
  const std::vector<Case> cases = {
      {"struct_size", [](auto& d, auto&, auto&, auto&, auto&) { d.struct_size = 1; }},
      {"NaN position", [](auto& d, auto&, auto&, auto&, auto&) { d.transform.position.x = kNaN; }},
      {"far position", [](auto& d, auto&, auto&, auto&, auto&) { d.transform.position.y = 1e7f; }},
      {"zero rotation", [](auto& d, auto&, auto&, auto&, auto&) { d.transform.rotation.w = 0; }},
      {"NaN scale", [](auto& d, auto&, auto&, auto&, auto&) { d.scale.z = kNaN; }},
      {"zero scale", [](auto& d, auto&, auto&, auto&, auto&) { d.scale.x = 0; }},
      {"unknown flags", [](auto& d, auto&, auto&, auto&, auto&) { d.flags = 1u << 20; }},
      {"long name", [](auto& d, auto&, auto&, auto&, auto&) {
         static const std::string name(200, 'n');
         d.name = name.c_str();
       }},
      {"too many colliders", [](auto& d, auto&, auto&, auto&, auto&) { d.collider_count = EDGEPHYS_MAX_COLLIDERS + 1; }},
      {"NULL colliders", [](auto& d, auto&, auto&, auto&, auto&) { d.colliders = nullptr; }},
      {"too many joints", [](auto& d, auto&, auto&, auto&, auto&) { d.joint_count = EDGEPHYS_MAX_JOINTS + 1; }},
      {"NULL joints", [](auto& d, auto&, auto&, auto&, auto&) { d.joints = nullptr; }},
      {"collider shape", [](auto&, auto& c, auto&, auto&, auto&) { c.shape = 99; }},
      {"collider NaN extents", [](auto&, auto& c, auto&, auto&, auto&) { c.half_extents.y = kNaN; }},
      {"collider negative extents", [](auto&, auto& c, auto&, auto&, auto&) { c.half_extents.y = -1; }},
      {"collider inf radius", [](auto&, auto& c, auto&, auto&, auto&) { c.radius = kInf; }},
      {"collider NaN local position", [](auto&, auto& c, auto&, auto&, auto&) { c.local_position.x = kNaN; }},
      {"collider bad local rotation", [](auto&, auto& c, auto&, auto&, auto&) { c.local_rotation.w = 3; }},
      {"collider trigger flag", [](auto&, auto& c, auto&, auto&, auto&) { c.is_trigger = 2; }},
      {"collider NULL vertices", [](auto&, auto& c, auto&, auto&, auto&) { c.vertex_float_count = 9; }},
      {"collider huge mesh", [&](auto&, auto& c, auto&, auto&, auto&) {
         c.vertices = tri;
         c.vertex_float_count = EDGEPHYS_MAX_MESH_FLOATS + 3;
       }},
      {"collider vertex count not x3", [&](auto&, auto& c, auto&, auto&, auto&) {
         c.vertices = tri;
         c.vertex_float_count = 4;
       }},
      {"collider mesh index out of range", [&](auto&, auto& c, auto&, auto&, auto&) {
         static const uint32_t bad_idx[3] = {0, 1, 7};
         mesh(c, EDGEPHYS_SHAPE_TRIANGLE_MESH, tri, 9, bad_idx, 3);
       }},
      {"collider mesh without triangles", [&](auto&, auto& c, auto&, auto&, auto&) {
         mesh(c, EDGEPHYS_SHAPE_TRIANGLE_MESH, tri, 9);
       }},
      {"collider mesh NaN vertex", [&](auto&, auto& c, auto&, auto&, auto&) {
         static const float nan_tri[9] = {0, 0, 0, kNaN, 0, 0, 0, 1, 0};
         mesh(c, EDGEPHYS_SHAPE_TRIANGLE_MESH, nan_tri, 9, tri_idx, 3);
       }},
      {"hull with too few points", [&](auto&, auto& c, auto&, auto&, auto&) {
         mesh(c, EDGEPHYS_SHAPE_CONVEX_HULL, tri, 6);
       }},
      {"body NaN mass", [](auto&, auto&, auto& b, auto&, auto&) { b.mass = kNaN; }},
      {"body negative mass", [](auto&, auto&, auto& b, auto&, auto&) { b.mass = -1; }},
      {"body inf friction", [](auto&, auto&, auto& b, auto&, auto&) { b.friction = kInf; }},
      {"body kinematic flag", [](auto&, auto&, auto& b, auto&, auto&) { b.kinematic = 5; }},
      {"body NaN velocity", [](auto&, auto&, auto& b, auto&, auto&) { b.angular_velocity.z = kNaN; }},
      {"joint kind", [](auto&, auto&, auto&, auto& j, auto&) { j.kind = 42; }},
      {"joint NaN anchor", [](auto&, auto&, auto&, auto& j, auto&) { j.anchor.x = kNaN; }},
      {"joint negative stiffness", [](auto&, auto&, auto&, auto& j, auto&) { j.stiffness = -2; }},
      {"soft zero particles", [](auto&, auto&, auto&, auto&, auto& s) { s.particle_count = 0; }},
      {"soft too many particles", [](auto&, auto&, auto&, auto&, auto& s) { s.particle_count = EDGEPHYS_MAX_SOFT_BODY_PARTICLES + 1; }},
      {"soft too many springs", [](auto&, auto&, auto&, auto&, auto& s) { s.spring_count = EDGEPHYS_MAX_SOFT_BODY_SPRINGS + 1; }},
      {"soft NULL particles", [](auto&, auto&, auto&, auto&, auto& s) { s.particles = nullptr; }},
      {"soft NULL masses", [](auto&, auto&, auto&, auto&, auto& s) { s.masses = nullptr; }},
      {"soft NULL springs", [](auto&, auto&, auto&, auto&, auto& s) { s.springs = nullptr; }},
      {"soft NaN particle", [](auto&, auto&, auto&, auto&, auto& s) {
         static const float p[6] = {0, kNaN, 0, 1, 0, 0};
         s.particles = p;
       }},
      {"soft zero mass", [](auto&, auto&, auto&, auto&, auto& s) {
         static const float m[2] = {1, 0};
         s.masses = m;
       }},
      {"soft spring out of range", [](auto&, auto&, auto&, auto&, auto& s) {
         static const uint32_t sp[2] = {0, 2};
         s.springs = sp;
       }},
      {"soft damping above 1", [](auto&, auto&, auto&, auto&, auto& s) { s.damping = 1.5f; }},
      {"soft NaN stiffness", [](auto&, auto&, auto&, auto&, auto& s) { s.stiffness = kNaN; }},
  };
  for (const Case& k : cases) {
    edgephys_collider c = box;
    edgephys_rigid_body b = body;
    edgephys_joint j = joint;
    edgephys_soft_body s = soft;
    edgephys_spawn_desc d = full(c, b, j, s);
    k.mutate(d, c, b, j, s);
    id = 12345;
    EXPECT_EQ(edgephys_client_spawn(c_, &d, &id), EDGEPHYS_E_INVALID_ARGUMENT) << k.what;
    EXPECT_STRNE(edgephys_last_error(), "") << k.what;
    EXPECT_EQ(id, 12345u) << k.what << ": out-param written on failure";
  }
  // The unmutated full description passes validation (and stops at "not joined").
  edgephys_spawn_desc d = full(box, body, joint, soft);
  EXPECT_STATUS(EDGEPHYS_E_NOT_CONNECTED, edgephys_client_spawn(c_, &d, &id));
}

TEST_F(CApiClient, QueriesRejectNullsWrongSizesAndUnknownIds) {
  edgephys_event ev;
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_poll_event(c_, nullptr));
  std::memset(&ev, 0xFF, sizeof(ev));
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_poll_event(c_, &ev));
  EXPECT_EQ(ev.type, static_cast<uint32_t>(EDGEPHYS_EVENT_NONE));

  edgephys_client_info info{};
  static_assert(sizeof(info) == 64, "the C# and Python bindings declare 64 bytes");
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_get_info(c_, nullptr));
  info.struct_size = 4;
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_get_info(c_, &info));
  info.struct_size = sizeof(info);
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_get_info(c_, &info));
  EXPECT_EQ(info.state, static_cast<uint32_t>(EDGEPHYS_STATE_IDLE));
  EXPECT_EQ(info.joined, 0u);
  EXPECT_EQ(info.state_payloads_refused, 0u);

  edgephys_connection_status st;
  static_assert(sizeof(st) == 144, "the C# and Python bindings declare 144 bytes");
  std::memset(&st, 0xAB, sizeof(st));
  st.struct_size = sizeof(st);
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_get_connection_status(c_, nullptr));
  st.struct_size = sizeof(st) - 8;  // an older, shorter struct
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_get_connection_status(c_, &st));
  st.struct_size = sizeof(st);
  EXPECT_STATUS(EDGEPHYS_E_NOT_CONNECTED, edgephys_client_get_connection_status(c_, &st));
  EXPECT_EQ(st.pending_reliable_bytes, 0xABABABABABABABABull);  // a failing call writes nothing

  edgephys_entity e;
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_get_entity(c_, 1, nullptr));
  EXPECT_STATUS(EDGEPHYS_E_NOT_FOUND, edgephys_client_get_entity(c_, 1, &e));

  size_t n = 99;
  uint32_t ids[4];
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_list_entities(c_, ids, 4, nullptr));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_list_entities(c_, nullptr, 4, &n));
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_list_entities(c_, nullptr, 0, &n));
  EXPECT_EQ(n, 0u);

  edgephys_vec3 nodes[4];
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_get_soft_body(c_, 1, nodes, 4, nullptr));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_get_soft_body(c_, 1, nullptr, 4, &n));
  EXPECT_STATUS(EDGEPHYS_E_NOT_FOUND, edgephys_client_get_soft_body(c_, 1, nodes, 4, &n));

  edgephys_transform t;
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_sample_pose(c_, 1, 1.0, 0, nullptr));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_sample_pose(c_, 1, 1.0, 77, &t));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT,
                edgephys_client_sample_pose(c_, 1, 1.0, EDGEPHYS_INTERP_AUTO + 1, &t));
  EXPECT_STATUS(EDGEPHYS_E_NOT_FOUND, edgephys_client_sample_pose(c_, 1, 1.0, EDGEPHYS_INTERP_AUTO, &t));
  uint32_t format = 5;
  EXPECT_STATUS(EDGEPHYS_E_NOT_FOUND, edgephys_client_get_state_format(c_, &format));  // not joined
  EXPECT_EQ(format, 0u);
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_get_state_format(c_, nullptr));
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_sample_pose(c_, 1, std::nan(""), 0, &t));
  EXPECT_STATUS(EDGEPHYS_E_NOT_FOUND, edgephys_client_sample_pose(c_, 1, 1.0, 0, &t));

  const double inf = std::numeric_limits<double>::infinity();
  for (double bad : {-0.001, 4.001, 1e300, std::nan(""), inf, -inf}) {
    EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_set_max_playout_delay(c_, bad));
  }
  for (double good : {0.0, 0.001, 0.1, 4.0, 0.0}) {
    EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_set_max_playout_delay(c_, good));
  }
  double delay = 7;
  EXPECT_STATUS(EDGEPHYS_E_INVALID_ARGUMENT, edgephys_client_get_playout_delay(c_, 1, nullptr));
  EXPECT_STATUS(EDGEPHYS_E_NOT_FOUND, edgephys_client_get_playout_delay(c_, 1, &delay));
  EXPECT_EQ(delay, 0.0);
}

TEST_F(CApiClient, CloseTwiceIsAnErrorAndDestroyStillFrees) {
  EXPECT_STATUS(EDGEPHYS_OK, edgephys_client_close(c_));
  EXPECT_STATUS(EDGEPHYS_E_CLOSED, edgephys_client_close(c_));
}

TEST(CApi, HandshakeTimeoutEndsInAnEventNotAHang) {
  edgephys_client_config cfg;
  ASSERT_EQ(edgephys_client_config_init(&cfg), EDGEPHYS_OK);
  cfg.bind_address = "127.0.0.1:0";
  cfg.handshake_timeout_s = 0.5;
  edgephys_client* c = nullptr;
  ASSERT_EQ(edgephys_client_create(&cfg, &c), EDGEPHYS_OK);
  // A token-shaped string for a port nobody serves: the handshake times out.
  std::string token = ClientTokenText();
  ASSERT_EQ(edgephys_client_connect(c, "127.0.0.1:9", token.c_str(), 0.0), EDGEPHYS_OK) << edgephys_last_error();
  edgephys_client_info info{};
  info.struct_size = sizeof(info);
  for (int i = 1; i <= 20; ++i) {  // simulated time: 2 s in 0.1 s steps
    ASSERT_EQ(edgephys_client_update(c, 0.1 * i), EDGEPHYS_OK);
  }
  ASSERT_EQ(edgephys_client_get_info(c, &info), EDGEPHYS_OK);
  EXPECT_EQ(info.state, static_cast<uint32_t>(EDGEPHYS_STATE_FAILED));
  edgephys_event ev;
  ASSERT_EQ(edgephys_client_poll_event(c, &ev), EDGEPHYS_OK);
  EXPECT_EQ(ev.type, static_cast<uint32_t>(EDGEPHYS_EVENT_DISCONNECTED));
  EXPECT_EQ(ev.code, 0u);
  EXPECT_NE(std::string(ev.detail).find("handshake timeout"), std::string::npos) << ev.detail;
  EXPECT_EQ(edgephys_client_join(c, "lobby"), EDGEPHYS_E_NOT_CONNECTED);
  EXPECT_EQ(edgephys_client_destroy(c), EDGEPHYS_OK);
}

}  // namespace
