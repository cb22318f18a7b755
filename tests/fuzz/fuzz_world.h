// Shared pieces of the edgephys fuzz targets: an input reader, and a relay plus real clients
// over an InMemoryNetwork pumped with a fake clock (no sleeps, no OS sockets, no threads).
//
// Every target builds its world afresh for each input, so a finding reproduces from the one
// input libFuzzer saves (only SecureRandom64 nonces / connection ids differ between runs, and
// the targets never let the fuzzer depend on their values).
#pragma once


#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "protocol/container_builder.h"
#include "protocol/handshake.h"
#include "protocol/packet_seal.h"
#include "protocol/testing/in_memory_network.h"
#include "protocol/join_token.h"
#include "relay/relay.h"

namespace edgephys::fuzz {

// Aborts (a finding) when an invariant the fuzzer checks does not hold.
#define EDGEPHYS_FUZZ_CHECK(cond)                                                   \
  do {                                                                              \
    if (!(cond)) {                                                                  \
      std::fprintf(stderr, "%s:%d: fuzz invariant failed: %s\n", __FILE__, __LINE__, \
                   #cond);                                                          \
      std::abort();                                                                 \
    }                                                                               \
  } while (0)

// Reads an input front to back; running out yields zeros / empty spans.
class Reader {
 public:
  Reader(const uint8_t* data, size_t size) : data_(data), size_(size) {}
  bool empty() const { return pos_ >= size_; }
  size_t remaining() const { return size_ - pos_; }
  uint8_t U8() { return pos_ < size_ ? data_[pos_++] : 0; }
  uint16_t U16() {
    uint16_t lo = U8();
    return static_cast<uint16_t>(lo | (U8() << 8));
  }
  // Up to `n` bytes (fewer at the end of the input).
  std::span<const uint8_t> Bytes(size_t n) {
    n = std::min(n, remaining());
    std::span<const uint8_t> out(data_ + pos_, n);
    pos_ += n;
    return out;
  }
  std::span<const uint8_t> Rest() { return Bytes(remaining()); }

 private:
  const uint8_t* data_;
  size_t size_;
  size_t pos_ = 0;
};

// Records are `u8 tag | u16 length | length bytes`; the corpus generator writes them with this.
inline void PutRecord(std::vector<uint8_t>* out, uint8_t tag, std::span<const uint8_t> bytes) {
  out->push_back(tag);
  out->push_back(static_cast<uint8_t>(bytes.size() & 0xff));
  out->push_back(static_cast<uint8_t>(bytes.size() >> 8));
  out->insert(out->end(), bytes.begin(), bytes.end());
}

inline constexpr char kFuzzSecret[] = "fuzz-secret";
inline constexpr char kFuzzRoom[] = "fuzz";
inline constexpr uint64_t kUnixNow = 1'700'000'000;  // fake wall clock (token expiry)

inline std::vector<uint8_t> MintToken(uint32_t player, uint32_t permissions,
                                      const std::string& room = kFuzzRoom) {
  JoinToken t;
  t.room = room;
  t.player_id = player;
  t.permissions = permissions;
  t.expiry_unix_s = kUnixNow + 3600;
  t.nonce = SecureRandom64();
  return *SignJoinToken(t, kFuzzSecret);
}

inline Endpoint Ep(const char* address, uint16_t port) {
  return Endpoint(asio::ip::make_address(address), port);
}

inline RelayConfig FuzzRelayConfig() {
  RelayConfig c;
  c.secret = kFuzzSecret;
  c.physics_threads = 1;  // no pool threads: everything on the fuzzing thread
  c.room_defaults.tick_rate_hz = 30;
  return c;
}

// Wraps a socket and remembers the connection id of the data packets sent through it (the
// client SDK does not expose its connection id; the fuzzers need it to address the session).
class TapSocket final : public DatagramSocket {
 public:
  explicit TapSocket(std::unique_ptr<DatagramSocket> inner) : inner_(std::move(inner)) {}
  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
    PacketPrefix prefix{};
    DropReason reason{};
    if (ParsePacketPrefix(data.first(std::min(data.size(), kMaxPacketSize)), &prefix, &reason) &&
        prefix.type == PacketType::kData) {
      connection_id_ = prefix.connection_id;
      last_data_.assign(data.begin(), data.end());  // sealed (the relay seals by default)
    }
    return inner_->SendTo(to, data);
  }
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    return inner_->ReceiveFrom(from, buffer);
  }
  Endpoint LocalEndpoint() const override { return inner_->LocalEndpoint(); }
  // Sends from this socket's address without recording anything (fuzz bytes).
  Status SendUntapped(const Endpoint& to, std::span<const uint8_t> data) {
    return inner_->SendTo(to, data);
  }
  uint32_t connection_id() const { return connection_id_; }
  // The last data packet the client sent, as on the wire (for replays and forgeries).
  const std::vector<uint8_t>& last_data() const { return last_data_; }

 private:
  std::vector<uint8_t> last_data_;
  std::unique_ptr<DatagramSocket> inner_;
  uint32_t connection_id_ = 0;
};

// A relay and real clients on one InMemoryNetwork, with a fake clock.
class World {
 public:
  static constexpr double kDt = 1.0 / 60.0;

  explicit World(const RelayConfig& config = FuzzRelayConfig())
      : relay_endpoint_(Ep("10.0.0.1", 7777)) {
    relay_socket_ = net_.CreateSocket(relay_endpoint_);
    relay_ = std::make_unique<Relay>(config, relay_socket_.get(), &counters_);
  }
  ~World() {
    clients_.clear();  // clients before their sockets
    relay_.reset();
  }

  // A client at 10.0.1.<2 + index>:40000 (one address each, so per-address limits of the
  // relay never get in the way) connecting with a fresh token. Not pumped yet.
  Client& AddClient(uint32_t player, uint32_t permissions, ClientListener* listener = nullptr) {
    std::string address = "10.0.1." + std::to_string(2 + sockets_.size());
    sockets_.push_back(
        std::make_unique<TapSocket>(net_.CreateSocket(Ep(address.c_str(), 40000))));
    clients_.push_back(std::make_unique<Client>(ClientConfig{}, sockets_.back().get(), listener));
    Client& c = *clients_.back();
    auto token = MintToken(player, permissions);
    (void)c.Connect(ToRelayAddress(relay_endpoint_), token, now_);
    return c;
  }

  void Step() {
    now_ += kDt;
    relay_->Update(now_, kUnixNow);
    for (auto& c : clients_) c->Update(now_);
  }

  // Pumps until `done()` or `max_steps` steps; returns done().
  template <typename F>
  bool StepUntil(F&& done, int max_steps) {
    for (int i = 0; i < max_steps && !done(); ++i) Step();
    return done();
  }

  // Connects `c` and joins it to the fuzz room. Returns false if that did not happen.
  bool ConnectAndJoin(Client& c) {
    if (!StepUntil([&] { return c.state() == ClientState::kConnected; }, 20)) return false;
    if (!c.JoinRoom(kFuzzRoom).ok()) return false;
    return StepUntil([&] { return c.joined(); }, 20);
  }

  Relay& relay() { return *relay_; }
  RelayCounters& counters() { return counters_; }
  DatagramSocket& relay_socket() { return *relay_socket_; }
  TapSocket& client_socket(size_t i) { return *sockets_[i]; }
  const Endpoint& relay_endpoint() const { return relay_endpoint_; }
  InMemoryNetwork& network() { return net_; }
  double now() const { return now_; }
  void Advance(double dt) { now_ += dt; }

 private:
  InMemoryNetwork net_{1024};
  RelayCounters counters_;
  Endpoint relay_endpoint_;
  std::unique_ptr<DatagramSocket> relay_socket_;
  std::unique_ptr<Relay> relay_;
  std::vector<std::unique_ptr<TapSocket>> sockets_;
  std::vector<std::unique_ptr<Client>> clients_;
  double now_ = 1.0;
};

}  // namespace edgephys::fuzz
