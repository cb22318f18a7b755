// A hand-driven client for hostile tests: it completes the real handshake (Hello, Challenge,
// Connect with its own X25519 key and proof, Accept) on its own loopback socket, then sends data packets
// the test composes unit by unit, sealed with the session's keys as the relay expects. What
// the relay sends it is read and dropped (never acknowledged), as an attacker would.
//
// Thread-safety: none; the test thread drives it. Failure: Poll() leaves state() at
// kHandshaking until an Accept arrives; SendUnit() returns false before that.
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include "protocol/byte_io.h"
#include "protocol/connection.h"
#include "protocol/handshake.h"
#include "protocol/packet_seal.h"
#include "protocol/udp_socket.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {

class RawPeer {
 public:
  enum class State { kHandshaking, kConnected, kRejected };

  // `token`: a client token (SignJoinToken's output).
  RawPeer(const asio::ip::address& local, const Endpoint& relay, std::vector<uint8_t> token)
      : socket_(std::move(*UdpSocket::Open(Endpoint(local, 0)))),
        relay_(relay),
        token_(RelayPart(token)),
        secret_(SecretOf(token)),
        nonce_(SecureRandom64()),
        kx_(std::move(*KeyExchange::Generate())) {}

  State state() const { return state_; }
  uint32_t connection_id() const { return connection_id_; }

  // Sends a Hello (again) while no Challenge came: the relay may drop it (handshake limits).
  void SendHello() {
    if (!cookie_.empty() || state_ != State::kHandshaking) return;
    flatbuffers::FlatBufferBuilder fbb(64);
    FinishControl(fbb, schema::CreateHello(fbb, nonce_));
    (void)socket_->SendTo(relay_, BuildHandshakePacket(PacketType::kHello, fbb, kMinHelloPacketSize));
  }

  // Reads everything pending; advances the handshake.
  void Poll() {
    Endpoint from;
    while (size_t n = socket_->ReceiveFrom(&from, buffer_)) {
      if (state_ != State::kHandshaking || n <= kPacketPrefixSize) continue;
      std::span<const uint8_t> packet(buffer_.data(), n);
      const auto* msg = VerifyControlMessage(packet.subspan(kPacketPrefixSize));
      if (msg == nullptr) continue;
      if (msg->body_type() == schema::Body::Challenge && cookie_.empty()) {
        const auto* cookie = msg->body_as_Challenge()->cookie();
        if (cookie == nullptr) continue;
        cookie_.assign(cookie->begin(), cookie->end());
        SendConnect();
      } else if (msg->body_type() == schema::Body::Accept) {
        const auto* accept = msg->body_as_Accept();
        if (accept->relay_key() == nullptr) continue;
        auto keys = kx_.Derive(std::span(accept->relay_key()->data(), accept->relay_key()->size()),
                               /*own_is_client=*/true, token_, secret_, nonce_,
                               accept->connection_id());
        if (!keys.ok()) continue;
        seal_ = std::make_unique<PacketSeal>(*keys, PacketSeal::Side::kClient);
        connection_id_ = accept->connection_id();
        state_ = State::kConnected;
      } else if (msg->body_type() == schema::Body::Reject) {
        state_ = State::kRejected;
      }
    }
  }

  // Resends the Connect (the first, or its answer, may be lost).
  void SendConnect() {
    if (cookie_.empty() || state_ != State::kHandshaking) return;
    (void)socket_->SendTo(relay_, BuildConnectPacket({nonce_, cookie_, token_, kx_.public_key()},
                                                     secret_));
  }

  // One sealed data packet carrying reliable unit `id` of `size` bytes (`last`: the last unit
  // of its message). False before the handshake completed or if the socket refused it.
  bool SendUnit(uint16_t id, bool last, size_t size = kMaxReliableUnitSize) {
    if (state_ != State::kConnected) return false;
    std::vector<uint8_t> packet(kConnectionHeaderSize);
    WritePacketPrefix(PacketType::kData, connection_id_, packet);
    StoreU16LE(packet.data() + kPacketPrefixSize, sequence_++);
    StoreU16LE(packet.data() + kPacketPrefixSize + 2, 0xFFFF);  // acknowledges nothing
    StoreU32LE(packet.data() + kPacketPrefixSize + 4, 0);
    packet.push_back(0x01);
    packet.push_back(static_cast<uint8_t>(id));
    packet.push_back(static_cast<uint8_t>(id >> 8));
    packet.push_back(last ? 1 : 0);
    packet.push_back(static_cast<uint8_t>(size));
    packet.push_back(static_cast<uint8_t>(size >> 8));
    packet.resize(packet.size() + size, static_cast<uint8_t>(id));
    std::array<uint8_t, kMaxDatagramSize> sealed{};
    const size_t n = seal_->Seal(packet, sealed);
    return n > 0 && socket_->SendTo(relay_, std::span(sealed.data(), n)).ok();
  }

 private:
  std::unique_ptr<UdpSocket> socket_;
  Endpoint relay_;
  std::vector<uint8_t> token_;  // the relay part
  SessionSecret secret_;
  uint64_t nonce_;
  KeyExchange kx_;
  std::vector<uint8_t> cookie_;
  std::unique_ptr<PacketSeal> seal_;
  uint32_t connection_id_ = 0;
  uint16_t sequence_ = 0;
  State state_ = State::kHandshaking;
  std::array<uint8_t, 2048> buffer_{};
};

}  // namespace edgephys::testing
