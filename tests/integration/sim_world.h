// A relay and clients on an InMemoryNetwork, each socket behind a NetworkSimulator, pumped
// with a fake clock: deterministic, fast, and as lossy as a test wants.
#pragma once

#include <functional>
#include <memory>
#include <vector>

#include "client/client_endpoint.h"
#include "protocol/testing/in_memory_network.h"
#include "protocol/network_simulator.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {

// The hostile link the application-state tests run over: 20 % loss, 5 % duplication, 10 %
// reordering, 30 ms +- 20 ms one way.
inline NetworkConditions LossyLink() {
  NetworkConditions c;
  c.loss = 0.20;
  c.duplicate = 0.05;
  c.reorder = 0.10;
  c.latency_s = 0.030;
  c.jitter_s = 0.020;
  return c;
}

// RunUntil / RunFor (Pumped) advance the fake clock by Step()'s default 5 ms a step.
class SimWorld : public Pumped<SimWorld> {
 public:
  explicit SimWorld(const NetworkConditions& conditions = {},
                    RelayConfig config = LoopbackWorld::DefaultConfig())
      : conditions_(conditions) {
    relay_endpoint_ = Endpoint(asio::ip::make_address("10.0.0.1"), 7777);
    relay_raw_ = network_.CreateSocket(relay_endpoint_);
    relay_sim_ = std::make_unique<NetworkSimulator>(relay_raw_.get(), Seeded(1));
    relay_ = std::make_unique<Relay>(config, relay_sim_.get(), &counters_);
  }

  Client& AddClient(const std::vector<uint8_t>& token, ClientListener* listener = nullptr,
                    const ClientConfig& config = {}) {
    uint16_t port = static_cast<uint16_t>(20000 + raws_.size());
    raws_.push_back(network_.CreateSocket(Endpoint(asio::ip::make_address("10.0.0.2"), port)));
    sims_.push_back(std::make_unique<NetworkSimulator>(raws_.back().get(), Seeded(100 + port)));
    clients_.push_back(std::make_unique<Client>(config, sims_.back().get(), listener));
    (void)clients_.back()->Connect(ToRelayAddress(relay_endpoint_), token, now_);
    return *clients_.back();
  }

  // A client on a link of its own: both directions cross `link` (seeded per client), on top
  // of the world's conditions at the relay.
  Client& AddClientOnLink(const std::vector<uint8_t>& token, const NetworkConditions& link,
                          ClientListener* listener = nullptr, const ClientConfig& config = {}) {
    uint16_t port = static_cast<uint16_t>(20000 + raws_.size());
    raws_.push_back(network_.CreateSocket(Endpoint(asio::ip::make_address("10.0.0.2"), port)));
    NetworkConditions up = link, down = link;
    up.seed = 300 + 2 * port;
    down.seed = 301 + 2 * port;
    links_.push_back(std::make_unique<ImpairedSocket>(raws_.back().get(), up, down));
    clients_.push_back(std::make_unique<Client>(config, links_.back().get(), listener));
    (void)clients_.back()->Connect(ToRelayAddress(relay_endpoint_), token, now_);
    return *clients_.back();
  }
  const ImpairedSocket& link(size_t i) const { return *links_.at(i); }

  void Step(double dt = 0.005) {
    now_ += dt;
    relay_sim_->Update(now_);
    for (auto& s : sims_) s->Update(now_);
    for (auto& l : links_) l->Update(now_);
    relay_->Update(now_, UnixNow());
    for (auto& c : clients_) {
      if (c) c->Update(now_);
    }
  }

  // Stops pumping client `i` (it goes silent, as if the process died).
  void Freeze(size_t i) { frozen_.push_back(i); clients_[i].reset(); }

  double Now() const { return now_; }
  Relay& relay() { return *relay_; }
  RelayCounters& counters() { return counters_; }

 private:
  NetworkConditions Seeded(uint64_t seed) const {
    NetworkConditions c = conditions_;
    c.seed = seed;
    return c;
  }

  NetworkConditions conditions_;
  InMemoryNetwork network_;
  Endpoint relay_endpoint_;
  RelayCounters counters_;
  std::unique_ptr<DatagramSocket> relay_raw_;
  std::unique_ptr<NetworkSimulator> relay_sim_;
  std::unique_ptr<Relay> relay_;
  std::vector<std::unique_ptr<DatagramSocket>> raws_;
  std::vector<std::unique_ptr<NetworkSimulator>> sims_;
  std::vector<std::unique_ptr<ImpairedSocket>> links_;
  std::vector<std::unique_ptr<Client>> clients_;
  std::vector<size_t> frozen_;
  double now_ = 0;
};

}  // namespace edgephys::testing
