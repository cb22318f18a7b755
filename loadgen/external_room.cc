#include "loadgen/external_room.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <thread>

#include "client/client_endpoint.h"
#include "edgephys/schema/control_generated.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/udp_socket.h"

namespace edgephys::loadgen {

void RefusalWatch::OnError(uint16_t reason, uint32_t entity_id, std::string_view detail) {
  if (refused_) return;
  refused_ = true;
  const bool named = reason <= static_cast<uint16_t>(schema::RejectReason::MAX);
  what_ = named ? schema::EnumNameRejectReason(static_cast<schema::RejectReason>(reason))
                : "reason " + std::to_string(reason);
  if (entity_id != 0) what_ += " (entity " + std::to_string(entity_id) + ")";
  if (!detail.empty()) what_ += ": " + std::string(detail);
}

struct ExternalRoom::Member {
  std::unique_ptr<UdpSocket> socket;
  std::unique_ptr<Client> client;
  bool join_requested = false;
};

ExternalRoom::ExternalRoom(RelayTarget* relay, const std::string& prefix, size_t members,
                           ClientConfig host_config, ClientConfig config,
                           const std::vector<ClientListener*>& listeners)
    : relay_(relay), t0_(std::chrono::steady_clock::now()) {
  const uint64_t salt = SecureRandom64();
  room_ = prefix + "-" + std::to_string(salt % 1000000);
  const uint32_t first_player = 1 + static_cast<uint32_t>((salt >> 20) % 1000000) * 64;
  host_config.require_packet_auth = config.require_packet_auth = false;
  members_.resize(members);
  for (size_t i = 0; i < members; ++i) {
    Member& m = members_[i];
    auto socket = UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0));
    if (!socket.ok()) {
      std::fprintf(stderr, "external room: cannot open a socket: %s\n",
                   std::string(socket.status().message()).c_str());
      std::abort();  // loopback sockets always open on a working machine
    }
    m.socket = std::move(*socket);
    m.client = std::make_unique<Client>(i == 0 ? host_config : config, m.socket.get(),
                                        i < listeners.size() ? listeners[i] : nullptr);
    (void)m.client->Connect(ToRelayAddress(relay_->endpoint()),
                            relay_->Token(room_, first_player + static_cast<uint32_t>(i)), Now());
  }
}

ExternalRoom::~ExternalRoom() { DisconnectAll(); }

size_t ExternalRoom::size() const { return members_.size(); }
Client& ExternalRoom::client(size_t i) { return *members_[i].client; }
const Client& ExternalRoom::client(size_t i) const { return *members_[i].client; }

double ExternalRoom::Now() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
}

void ExternalRoom::Update() {
  const double t = Now();
  for (Member& m : members_) {
    m.client->Update(t);
    if (m.client->state() == ClientState::kConnected && !m.join_requested) {
      (void)m.client->JoinRoom(room_);
      m.join_requested = true;
    }
  }
}

bool ExternalRoom::JoinAll(double timeout_s) {
  const double deadline = Now() + timeout_s;
  auto joined = [](const Member& m) { return m.client->joined(); };
  while (Now() < deadline && !std::all_of(members_.begin(), members_.end(), joined)) {
    Update();
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  for (size_t i = 0; i < members_.size(); ++i) {
    const Client& c = *members_[i].client;
    if (c.joined()) continue;
    std::fprintf(stderr, "external room: client %zu did not join %s on %s (state %d, reject %u)\n",
                 i, room_.c_str(), FormatEndpoint(relay_->endpoint()).c_str(),
                 static_cast<int>(c.state()), c.reject_reason());
    return false;
  }
  return true;
}

void ExternalRoom::DisconnectAll() {
  if (disconnected_) return;
  disconnected_ = true;
  for (Member& m : members_) m.client->Disconnect();
  for (int i = 0; i < 20; ++i) Update();
}

bool ExternalRoom::AllConnected() const {
  return std::all_of(members_.begin(), members_.end(), [](const Member& m) {
    return m.client->state() == ClientState::kConnected;
  });
}

uint64_t ExternalRoom::ReceivedBytes(size_t i) const {
  const ConnectionStats* stats = members_[i].client->stats();
  return stats != nullptr ? stats->bytes_received : 0;
}

double ExternalRoom::PhysicsSteps() {
  const double t = Now();
  if (steps_at_ < 0 || t - steps_at_ >= 0.2) {
    RelayFigures f = relay_->Read();
    if (f.ok) {
      if (steps_at_ >= 0 && t > steps_at_) {
        steps_rate_ = std::max(0.0, (f.physics_steps - steps_base_) / (t - steps_at_));
      }
      steps_base_ = f.physics_steps;
      steps_at_ = t;
    }
  }
  return steps_at_ < 0 ? 0 : steps_base_ + steps_rate_ * (t - steps_at_);
}

}  // namespace edgephys::loadgen
