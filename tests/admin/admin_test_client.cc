// A small SDK client for the admin API's end-to-end tests (tests/admin/admin_api_test.sh and
// tests/browser/monitor_test.mjs): it connects to a relay with a token it mints from the
// secret, joins the room, spawns one entity and moves it, and prints what happens, one line
// each, flushed:
//   joined <room> <player_id>
//   disconnected <DisconnectReason number> <detail, may be empty>
//   rejected <RejectReason number> | failed
// It exits when disconnected or after --run-for seconds (exit 0), or on a refused connection
// (exit 3). Bounded: it never runs longer than --run-for.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"

int main(int argc, char** argv) {
  using namespace edgephys;
  CLI::App app{"edgephys admin test client"};
  std::string relay = "127.0.0.1:7777", secret = "edgephys-dev-secret", room = "lobby";
  uint32_t player = 1;
  double run_for = 30;
  app.add_option("--relay", relay);
  app.add_option("--secret", secret);
  app.add_option("--room", room);
  app.add_option("--player", player)->required();
  app.add_option("--run-for", run_for);
  CLI11_PARSE(app, argc, argv);

  auto server = ParseEndpoint(relay);
  auto socket = UdpSocket::Open(*ParseEndpoint("127.0.0.1:0"));
  if (!server.ok() || !socket.ok()) {
    std::printf("failed bad address\n");
    return 2;
  }
  JoinToken token;
  token.room = room;
  token.player_id = player;
  token.expiry_unix_s = static_cast<uint64_t>(std::time(nullptr)) + 3600;
  token.nonce = SecureRandom64();
  auto bytes = SignJoinToken(token, secret);
  if (!bytes.ok()) return 2;

  Client client(ClientConfig{}, socket->get());
  const auto start = std::chrono::steady_clock::now();
  auto now = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  (void)client.Connect(ToRelayAddress(*server), *bytes, now());
  bool join_sent = false, announced = false;
  std::optional<uint32_t> entity;
  while (now() < run_for) {
    client.Update(now());
    switch (client.state()) {
      case ClientState::kRejected:
        std::printf("rejected %u\n", client.reject_reason());
        return 3;
      case ClientState::kFailed:
        std::printf("failed\n");
        return 3;
      case ClientState::kDisconnected:
        std::printf("disconnected %d %s\n", static_cast<int>(client.disconnect_reason()),
                    client.disconnect_detail().c_str());
        std::fflush(stdout);
        return 0;
      default: break;
    }
    if (client.state() == ClientState::kConnected && !join_sent) {
      join_sent = client.JoinRoom(room).ok();
    }
    if (client.joined() && !announced) {
      announced = true;
      std::printf("joined %s %u\n", room.c_str(), client.player_id());
      std::fflush(stdout);
      auto id = client.Spawn({});
      if (id.ok()) entity = *id;
    }
    if (entity) {
      // Round a unit circle at 1 m height; each player at its own phase, so players apart.
      float t = static_cast<float>(now()) + 0.9f * static_cast<float>(player % 7);
      (void)client.PublishTransform(*entity, {std::sin(t), 1.0f, std::cos(t)}, {0, 0, 0, 1});
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  client.Disconnect();
  client.Update(now());
  return 0;
}
