// The admin HTTP server of the tests, on an ephemeral loopback port.
#pragma once

#include <gtest/gtest.h>

#include <memory>
#include <string>

#include "relay/admin/admin_http.h"

namespace edgephys::testing {

// The port of a server started on "<host>:0" (from the address it bound).
inline int AdminPort(const admin::AdminHttpServer& server) {
  const std::string& address = server.address();
  return std::stoi(address.substr(address.rfind(':') + 1));
}

// Starts an admin server for `backend` with `options` on an ephemeral 127.0.0.1 port
// (options.address is set here). Null, after a test failure naming the cause, if it did not
// start.
inline std::unique_ptr<admin::AdminHttpServer> StartLoopbackAdmin(admin::AdminHttpOptions options,
                                                                  admin::AdminBackend* backend) {
  options.address = "127.0.0.1:0";
  auto started = admin::AdminHttpServer::Start(options, backend);
  EXPECT_TRUE(started.ok()) << started.status().ToString();
  if (!started.ok()) return nullptr;
  return std::move(*started);
}

}  // namespace edgephys::testing
