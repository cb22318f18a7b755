// The attacks of edgephys-loadgen hostile (loadgen/hostile.h), one per finding of issue 14:
//
//   physics  --soft-bodies offloaded soft bodies of ~--particles particles each (finding 1)
//   names    --huge-names persistent entities with --name-bytes names, then persistent
//            entities with 1000-byte names until refused: a room a late joiner cannot join
//            (finding 2)
//   churn    connect, join, spawn 128 persistent entities, leave; again (finding 3)
//   flood    Hello and Connect datagrams at --flood-rate from another loopback address
//            (finding 4)
//   forged   an unsealed Disconnect and a tampered Data packet with an honest member's exact
//            address and connection id, and replays of its real packets (finding 5)
//   invalid  NaN / Inf / zero / negative / 1e38 scales, an unknown and a self parent,
//            JoinRoom(""), NaN states (finding 6)
//
// An attack runs on one thread (the caller's): Prepare() before the baseline, Step() throughout
// the attack phase, Finish() after. None of them blocks for longer than a few seconds.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "loadgen/hostile.h"
#include "protocol/datagram_socket.h"
#include "protocol/udp_socket.h"

namespace edgephys::loadgen {

// A client's socket that keeps its last Data datagrams (as sent: sealed) and lets another
// thread send from the very same address, as an on-path attacker spoofing it would.
// Thread-safety: SendTo/ReceiveFrom on the owner's thread; Recorded() and Forge() from any.
class RecordingSocket final : public DatagramSocket {
 public:
  static constexpr size_t kKept = 32;
  explicit RecordingSocket(std::unique_ptr<UdpSocket> inner) : inner_(std::move(inner)) {}
  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override;
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    return inner_->ReceiveFrom(from, buffer);
  }
  Endpoint LocalEndpoint() const override { return inner_->LocalEndpoint(); }
  // The last kKept Data datagrams sent, oldest first.
  std::vector<std::vector<uint8_t>> Recorded() const;
  Status Forge(const Endpoint& to, std::span<const uint8_t> data) { return inner_->SendTo(to, data); }

 private:
  std::unique_ptr<UdpSocket> inner_;
  mutable std::mutex mu_;
  std::vector<std::vector<uint8_t>> ring_;
  size_t next_ = 0;
};

struct AttackContext {
  const HostileOptions* options = nullptr;
  RelayTarget* relay = nullptr;
  std::string room;                  // the attacker's room (A)
  asio::ip::address attacker_address;
  asio::ip::address flood_address;
  bool flood_possible = false;       // the relay is on IPv4 loopback
  uint32_t first_player = 0;         // the attacker's player ids start here
  RecordingSocket* victim = nullptr; // an honest member of A (for forged)
  std::function<double()> now;       // steady seconds of the run
};

class HostileAttack {
 public:
  virtual ~HostileAttack() = default;
  // Connects and readies what the attack needs; "" or why it cannot run.
  virtual std::string Prepare(const AttackContext& ctx) = 0;
  // Between Prepare() and the attack phase (the baseline): keeps a connection alive.
  virtual void Idle(double now) { (void)now; }
  virtual void Step(double now) = 0;
  // True once the attack has run its course (everything sent and answered); continuous
  // attacks are always done (their phase lasts --phase).
  virtual bool Done(double now) const = 0;
  virtual void Finish() = 0;  // disconnects
  virtual nlohmann::json Notes() const = 0;
};

struct HostileAttackInfo {
  const char* name;
  const char* description;
  std::unique_ptr<HostileAttack> (*make)();
};

// Every attack, in the order.
const std::vector<HostileAttackInfo>& HostileAttacks();
const HostileAttackInfo* FindHostileAttack(const std::string& name);

}  // namespace edgephys::loadgen
