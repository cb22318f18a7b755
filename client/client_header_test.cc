// What a game sees when it includes client/client.h alone: it can describe a dissected entity
// (plain structs, shape/joint/flag constants) and drive a Client without Asio, FlatBuffers or a
// generated schema header (tests/public_header_test.sh checks the include list; this TU checks
// that the header is self-sufficient for that and that those headers really stayed out).
#include "client/client.h"

#include <gtest/gtest.h>

#if defined(ASIO_DETAIL_CONFIG_HPP) || defined(FLATBUFFERS_VERSION_MAJOR) || \
    defined(FLATBUFFERS_GENERATED_CONTAINER_EDGEPHYS_SCHEMA_H_) ||  \
    defined(FLATBUFFERS_GENERATED_CONTROL_EDGEPHYS_SCHEMA_H_)
#error "client/client.h pulled in Asio, FlatBuffers or a generated schema header"
#endif

namespace edgephys {
namespace {

class CountingListener final : public ClientListener {
 public:
  void OnEntityUpdated(const RemoteEntity&) override { ++updates; }
  int updates = 0;
};

TEST(ClientHeaderTest, AGameDescribesADissectedEntityWithThePublicHeaderAlone) {
  SpawnDesc desc{.position = {0, 1, 0},
                 .flags = entity_flags::kOffloaded | entity_flags::kInteractable};
  desc.rigid_body = RigidBodySpec{.mass = 2.0f};
  desc.colliders.push_back(ColliderSpec{.shape = collider_shape::kSphere, .radius = 0.25f});
  desc.joints.push_back(JointSpec{.kind = joint_kind::kHinge, .connected_entity = 7});
  EXPECT_EQ(static_cast<int>(desc.colliders[0].shape), 1);  // schema/container.fbs: Sphere
  EXPECT_EQ(static_cast<int>(desc.joints[0].kind), 1);      // Hinge
  EXPECT_EQ(desc.flags, 0x24u);                              // Interactable | Offloaded

  CountingListener listener;
  Client client(ClientConfig{}, /*socket=*/nullptr, &listener);  // never touched unconnected
  EXPECT_EQ(client.Spawn(desc).status().code(), StatusCode::kNotConnected);
  EXPECT_EQ(client.state(), ClientState::kIdle);
  EXPECT_EQ(listener.updates, 0);
}

}  // namespace
}  // namespace edgephys
