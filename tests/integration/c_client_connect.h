// ConnectCClient: the set-up the C API integration tests share. Creates a C API client bound to
// 127.0.0.1:0 and starts its connection to `world`'s relay with `token` (base64url-encoded for
// the C API). Returns the client, owned by the caller (edgephys_client_destroy), or nullptr
// when creation failed; every failure is a failed expectation naming edgephys_last_error().
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
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

}  // namespace edgephys::testing
