// The public surface of client/client.h that does not need a relay: RelayAddress parsing and
// printing, the conversions of client_endpoint.h, and Connect()'s checks of the addresses and
// the token it is given (a bad one is refused before anything is sent, and the client stays
// usable).
#include <gtest/gtest.h>

#include <utility>
#include <vector>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "protocol/datagram_socket.h"
#include "protocol/join_token.h"

namespace edgephys {
namespace {

// Records where each datagram goes; never receives anything.
class SendLog final : public DatagramSocket {
 public:
  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
    sent.emplace_back(to, data.size());
    return Status::Ok();
  }
  size_t ReceiveFrom(Endpoint*, std::span<uint8_t>) override { return 0; }
  Endpoint LocalEndpoint() const override { return Endpoint(); }
  std::vector<std::pair<Endpoint, size_t>> sent;
};

// A client token (relay part | session secret), as a backend hands it out.
const std::vector<uint8_t> kToken = [] {
  JoinToken t;
  t.room = "r";
  t.player_id = 1;
  t.expiry_unix_s = 4'000'000'000;
  return *SignJoinToken(t, "secret");
}();

TEST(RelayAddressTest, ParsesNumericAddressesCanonically) {
  Result<RelayAddress> v4 = ParseRelayAddress("127.0.0.1:7777");
  ASSERT_TRUE(v4.ok()) << v4.status().ToString();
  EXPECT_EQ(*v4, (RelayAddress{"127.0.0.1", 7777}));
  Result<RelayAddress> v6 = ParseRelayAddress("[0:0::1]:9");
  ASSERT_TRUE(v6.ok()) << v6.status().ToString();
  EXPECT_EQ(*v6, (RelayAddress{"::1", 9}));
  EXPECT_EQ(FormatRelayAddress(*v4), "127.0.0.1:7777");
  EXPECT_EQ(FormatRelayAddress(*v6), "[::1]:9");
  EXPECT_EQ(*ParseRelayAddress(FormatRelayAddress(*v6)), *v6);
}

TEST(RelayAddressTest, RefusesNamesAndMalformedText) {
  for (const char* bad : {"", "garbage", "127.0.0.1", "127.0.0.1:", "127.0.0.1:65536",
                          "127.0.0.1:-1", "127.0.0.1:80x", "relay.no-such-host.invalid:7777",
                          "[::1:7777", "1.2.3.4.5:1", "\xff\xfe:1"}) {
    Result<RelayAddress> r = ParseRelayAddress(bad);
    EXPECT_FALSE(r.ok()) << bad;
    if (!r.ok()) {
      EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument) << bad;
    }
  }
}

TEST(RelayAddressTest, ConvertsToAndFromEndpoints) {
  const Endpoint e(asio::ip::make_address("10.1.2.3"), 4000);
  EXPECT_EQ(ToRelayAddress(e), (RelayAddress{"10.1.2.3", 4000}));
  Result<Endpoint> back = ToEndpoint(ToRelayAddress(e));
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(*back, e);
  EXPECT_FALSE(ToEndpoint({"localhost", 1}).ok());
  EXPECT_FALSE(ToEndpoint({"", 1}).ok());
}

TEST(ClientAddressTest, ConnectRefusesABadAddressAndSendsNothing) {
  SendLog socket;
  Client client(ClientConfig{}, &socket);
  Status st = client.Connect({"not-an-ip", 7777}, kToken, 0);
  EXPECT_EQ(st.code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(client.state(), ClientState::kIdle);
  EXPECT_TRUE(socket.sent.empty());

  // Still usable: a good address starts the handshake there.
  ASSERT_TRUE(client.Connect({"127.0.0.1", 7777}, kToken, 0).ok());
  EXPECT_EQ(client.state(), ClientState::kHandshaking);
  EXPECT_EQ(client.server(), (RelayAddress{"127.0.0.1", 7777}));
  ASSERT_EQ(socket.sent.size(), 1u);  // the Hello
  EXPECT_EQ(socket.sent[0].first, Endpoint(asio::ip::make_address("127.0.0.1"), 7777));
  EXPECT_EQ(client.Connect({"127.0.0.1", 7777}, kToken, 0).code(), StatusCode::kInvalidArgument);
}

// The SDK needs the whole client token: its relay part alone (no session secret to prove), an
// old-format token or bytes that are no token are refused before anything is sent.
TEST(ClientAddressTest, ConnectRefusesAnythingButAClientToken) {
  SendLog socket;
  Client client(ClientConfig{}, &socket);
  const std::vector<uint8_t> relay_part(kToken.begin(), kToken.end() - kSessionSecretSize);
  std::vector<uint8_t> old_format = kToken;
  old_format[0] = 1;
  for (const std::vector<uint8_t>& bad :
       {relay_part, old_format, std::vector<uint8_t>(64, 1), std::vector<uint8_t>()}) {
    Status st = client.Connect({"127.0.0.1", 7777}, bad, 0);
    EXPECT_EQ(st.code(), StatusCode::kMalformed) << st.ToString();
    EXPECT_EQ(client.state(), ClientState::kIdle);
  }
  EXPECT_NE(client.Connect({"127.0.0.1", 7777}, relay_part, 0).detail().find("session secret"),
            std::string_view::npos);
  EXPECT_TRUE(socket.sent.empty());
  ASSERT_TRUE(client.Connect({"127.0.0.1", 7777}, kToken, 0).ok());
  EXPECT_EQ(socket.sent.size(), 1u);
}

TEST(ClientAddressTest, ConnectRefusesABadRelayInTheConfig) {
  SendLog socket;
  ClientConfig config;
  config.resume = true;
  config.relays = {{"127.0.0.2", 1}, {"::1", 2}, {"relay-3", 3}};
  Client client(config, &socket);
  EXPECT_EQ(client.Connect({"127.0.0.1", 7777}, kToken, 0).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(client.state(), ClientState::kIdle);
  EXPECT_TRUE(socket.sent.empty());
}

TEST(ClientAddressTest, AccessorsBeforeConnectAreEmpty) {
  SendLog socket;
  Client client(ClientConfig{}, &socket);  // no listener
  EXPECT_EQ(client.stats(), nullptr);
  EXPECT_TRUE(client.entities().empty());
  EXPECT_EQ(client.FindEntity(1), nullptr);
  EXPECT_FALSE(client.joined());
  EXPECT_EQ(client.Spawn({.position = {0, 1, 0}}).status().code(), StatusCode::kNotConnected);
  EXPECT_EQ(client.PublishTransform(1, {}, {}).code(), StatusCode::kNotFound);
  client.Update(1.0);  // nothing to do, nothing sent
  client.Disconnect();
  EXPECT_TRUE(socket.sent.empty());
}

}  // namespace
}  // namespace edgephys
