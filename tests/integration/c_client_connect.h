// ConnectCClient: the set-up the C API integration tests share. Creates a C API client bound to
// 127.0.0.1:0 and starts its connection to `world`'s relay with `token` (base64url-encoded for
// the C API). Returns the client, owned by the caller (edgephys_client_destroy), or nullptr
// when creation failed; every failure is a failed expectation naming edgephys_last_error().
// CClientBase: such a client pumped with the world (Pump), its events kept by a test's
// subclass.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "edgephys/edgephys.h"
#include "protocol/join_token.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {

inline edgephys_client* ConnectCClient(LoopbackWorld& world, const std::vector<uint8_t>& token) {
  edgephys_client_config cfg;
  EXPECT_EQ(edgephys_client_config_init(&cfg), EDGEPHYS_OK);
  cfg.bind_address = "127.0.0.1:0";
  edgephys_client* c = nullptr;
  EXPECT_EQ(edgephys_client_create(&cfg, &c), EDGEPHYS_OK) << edgephys_last_error();
  if (c == nullptr) return nullptr;
  const std::string address = "127.0.0.1:" + std::to_string(world.relay_endpoint().port());
  EXPECT_EQ(edgephys_client_connect(c, address.c_str(), Base64UrlEncode(token).c_str(),
                                    world.Now()),
            EDGEPHYS_OK)
      << edgephys_last_error();
  return c;
}

// One C API client of a LoopbackWorld's relay (ConnectCClient), destroyed with this object.
// Update polls every event: it joins `room` on CONNECTED when given one, notes the player id
// and the join, and hands each event to OnEvent (a subclass's own records). Test thread only.
class CClientBase {
 public:
  CClientBase(LoopbackWorld& world, const std::vector<uint8_t>& token)
      : c(ConnectCClient(world, token)), world_(world) {}
  CClientBase(const CClientBase&) = delete;
  CClientBase& operator=(const CClientBase&) = delete;
  virtual ~CClientBase() { edgephys_client_destroy(c); }

  void Update(const char* room) {
    ASSERT_EQ(edgephys_client_update(c, world_.Now()), EDGEPHYS_OK);
    edgephys_event ev;
    while (edgephys_client_poll_event(c, &ev) == EDGEPHYS_OK && ev.type != EDGEPHYS_EVENT_NONE) {
      if (ev.type == EDGEPHYS_EVENT_CONNECTED && room != nullptr) {
        EXPECT_EQ(edgephys_client_join(c, room), EDGEPHYS_OK);
      }
      if (ev.type == EDGEPHYS_EVENT_CONNECTED) player_id = ev.player_id;
      if (ev.type == EDGEPHYS_EVENT_JOINED) joined = true;
      OnEvent(ev);
    }
  }

  edgephys_client* c = nullptr;
  uint32_t player_id = 0;
  bool joined = false;

 protected:
  virtual void OnEvent(const edgephys_event& ev) = 0;

 private:
  LoopbackWorld& world_;
};

// Pumps `world`, updating every client (joining `room` on CONNECTED when given one), until
// `done` returns true or `timeout_s` passes; returns done().
inline bool Pump(LoopbackWorld& world, std::vector<CClientBase*> clients, const char* room,
                         const std::function<bool()>& done, double timeout_s = 5.0) {
  return world.RunUntil([&] {
    for (CClientBase* c : clients) c->Update(room);
    return done();
  }, timeout_s);
}

}  // namespace edgephys::testing
