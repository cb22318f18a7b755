// The parts of the cluster tests' worlds (relays in a cluster over a real redis-server, in one
// process on real loopback UDP, pumped from the test thread): the relay nodes, with directory
// timings short enough for a failover well within a test, and the clients, which resume across
// every node and join their room once.
#pragma once

#include <gtest/gtest.h>

#include <functional>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "protocol/endpoint.h"
#include "protocol/udp_socket.h"
#include "relay/cluster_hook.h"
#include "relay/relay.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {

// Relay nodes: node i has its own loopback UDP socket from AddNode() on and, once started, its
// Relay.
class ClusterNodes {
 public:
  // Opens the socket of a new node; returns its index.
  int AddNode() {
    nodes_.push_back(std::make_unique<Node>());
    nodes_.back()->socket = std::move(*UdpSocket::Open(*ParseEndpoint("127.0.0.1:0")));
    return size() - 1;
  }

  // The relay configuration of the cluster tests: `secret`, 30 Hz rooms, a 1 s connection
  // timeout.
  static RelayConfig Config(const char* secret) {
    RelayConfig config;
    config.secret = secret;
    config.room_defaults.tick_rate_hz = 30;
    config.connection.timeout_s = 1.0;
    return config;
  }

  // Starts node `i`'s relay with `config`, in the cluster of the redis-server on `redis_port`
  // as `relay_id`, writing snapshots every `snapshot_s`.
  void StartRelay(int i, const RelayConfig& config, uint16_t redis_port,
                  const std::string& relay_id, double snapshot_s) {
    Node* node = nodes_[i].get();
    node->relay = std::make_unique<Relay>(config, node->socket.get(), &node->counters);
    ClusterOptions o;
    o.directory.redis_port = redis_port;
    o.directory.relay_id = relay_id;
    o.directory.public_address = FormatEndpoint(node->socket->LocalEndpoint());
    o.directory.heartbeat_s = 0.05;
    o.directory.ttl_s = 0.4;
    o.directory.refresh_s = 0.05;
    o.directory.redis_timeout_s = 0.3;
    o.snapshot_interval_s = snapshot_s;
    EXPECT_TRUE(node->relay->EnableCluster(o).ok());
  }

  // A client configuration that resumes (0.5 s an attempt) across every node.
  ClientConfig ResumingClientConfig() const {
    ClientConfig cc;
    cc.resume = true;
    cc.resume_attempt_s = 0.5;
    for (const auto& n : nodes_) cc.relays.push_back(ToRelayAddress(n->socket->LocalEndpoint()));
    return cc;
  }

  // Updates every live relay.
  void Update(double now) {
    for (auto& n : nodes_) {
      if (n->relay) n->relay->Update(now, UnixNow());
    }
  }

  // Destroys relay `i` at once: its UDP port goes silent, no last snapshot.
  void Kill(int i) { nodes_[i]->relay.reset(); }
  Relay* relay(int i) { return nodes_[i]->relay.get(); }
  const RelayCounters& counters(int i) const { return nodes_[i]->counters; }
  Endpoint endpoint(int i) const { return nodes_[i]->socket->LocalEndpoint(); }
  int size() const { return static_cast<int>(nodes_.size()); }

 private:
  struct Node {
    RelayCounters counters;
    std::unique_ptr<UdpSocket> socket;
    std::unique_ptr<Relay> relay;
  };
  std::vector<std::unique_ptr<Node>> nodes_;
};

// Clients on loopback sockets of their own. Each joins its room once, when first connected: the
// SDK rejoins by itself after a failover.
class AutoJoiningClients {
 public:
  // A client with `config` connecting to `relay` with `token`.
  Client& Add(const ClientConfig& config, ClientListener* listener, const RelayAddress& relay,
              const std::vector<uint8_t>& token, double now) {
    return clients_.Add(config, listener, asio::ip::make_address("127.0.0.1"), relay, token, now);
  }

  // Updates every client; one connected for the first time joins room_of(client).
  void Update(double now, const std::function<std::string(Client*)>& room_of) {
    for (const auto& c : clients_.all()) {
      c->Update(now);
      if (c->state() == ClientState::kConnected && !c->joined() && !c->resuming() &&
          joins_.insert(c.get()).second) {
        (void)c->JoinRoom(room_of(c.get()));
      }
    }
  }

 private:
  LoopbackClients clients_;
  std::set<Client*> joins_;
};

}  // namespace edgephys::testing
