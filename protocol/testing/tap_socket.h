// TapSocket: a DatagramSocket that forwards to another and shows the traffic to hooks, so a
// test can watch or count what a relay (or a client) sends and receives without changing it.
#pragma once

#include <cstdint>
#include <functional>
#include <span>

#include "protocol/datagram_socket.h"

namespace edgephys::testing {

class TapSocket final : public DatagramSocket {
 public:
  using Hook = std::function<void(const Endpoint& peer, std::span<const uint8_t> datagram)>;

  // `inner` is not owned and must outlive this socket.
  explicit TapSocket(DatagramSocket* inner) : inner_(inner) {}

  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
    if (on_send) on_send(to, data);
    return inner_->SendTo(to, data);
  }
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    const size_t n = inner_->ReceiveFrom(from, buffer);
    if (n > 0 && on_receive) on_receive(*from, buffer.first(n));
    return n;
  }
  Endpoint LocalEndpoint() const override { return inner_->LocalEndpoint(); }

  Hook on_send;     // called before each datagram is handed to the inner socket; may be empty
  Hook on_receive;  // called for each datagram received; may be empty

 private:
  DatagramSocket* inner_;
};

}  // namespace edgephys::testing
