// Connection (protocol/connection.h) against untrusted input: malformed, truncated, mutated and
// random packets are rejected as kMalformed and change no state (statistics included), and
// never crash. The end-to-end behaviour tests are in connection_test.cc.
#include <gtest/gtest.h>

#include <random>

#include "protocol/byte_io.h"
#include "protocol/connection.h"
#include "protocol/testing/connection_test_util.h"

namespace edgephys {
namespace {

using testing::Bytes;
using testing::CapturingWriter;
using testing::kTestConnectionId;
using testing::PacketBuilder;
using testing::RandomBytes;
using testing::RecordingHandler;

bool StatsEqual(const ConnectionStats& x, const ConnectionStats& y) {
  return x.rtt_s == y.rtt_s && x.rtt_var_s == y.rtt_var_s && x.loss == y.loss &&
         x.packets_sent == y.packets_sent && x.packets_received == y.packets_received &&
         x.bytes_sent == y.bytes_sent && x.bytes_received == y.bytes_received &&
         x.reliable_resends == y.reliable_resends && x.reliable_delivered == y.reliable_delivered &&
         x.stale_dropped == y.stale_dropped && x.duplicates_dropped == y.duplicates_dropped &&
         x.pending_reliable_bytes == y.pending_reliable_bytes;
}

// Offsets where each chunk of a well-formed data packet starts.
std::vector<size_t> ChunkStarts(const Bytes& packet) {
  std::vector<size_t> starts;
  size_t at = kConnectionHeaderSize;
  while (at < packet.size()) {
    starts.push_back(at);
    size_t header = packet[at] == 0x01 ? 6 : 3;
    at += header + LoadU16LE(packet.data() + at + header - 2);
  }
  return starts;
}

// Broken variants of a well-formed data packet; each must be rejected as kMalformed.
std::vector<Bytes> MalformedVariants(const Bytes& packet, std::mt19937& rng) {
  std::vector<Bytes> out;
  std::vector<size_t> starts = ChunkStarts(packet);
  size_t last = starts.empty() ? kConnectionHeaderSize : starts.back();
  // Truncated inside the prefix, the header or the last chunk.
  out.push_back(Bytes(packet.begin(), packet.begin() + rng() % kConnectionHeaderSize));
  if (!starts.empty()) {
    size_t cut = last + 1 + rng() % (packet.size() - last - 1);
    out.push_back(Bytes(packet.begin(), packet.begin() + static_cast<std::ptrdiff_t>(cut)));
  }
  Bytes b = packet;
  b.push_back(0x7F);  // unknown chunk type
  out.push_back(b);
  b = packet;
  b.push_back(0x02);  // chunk header cut short
  out.push_back(b);
  if (!starts.empty()) {
    b = packet;  // length beyond the packet
    size_t header = b[last] == 0x01 ? 6 : 3;
    StoreU16LE(b.data() + last + header - 2,
               static_cast<uint16_t>(packet.size() - last - header + 1));
    out.push_back(b);
    b = packet;  // zero length
    StoreU16LE(b.data() + last + header - 2, 0);
    out.push_back(b);
    if (b[last] == 0x01) {
      b = packet;  // unknown unit flag
      b[last + 3] |= 0x80;
      out.push_back(b);
    }
  }
  b = packet;  // a second unreliable chunk
  PacketBuilder extra(PacketType::kData, 0);
  Bytes tail = extra.Unreliable({1}).Unreliable({2}).Build();
  b.insert(b.end(), tail.begin() + kConnectionHeaderSize, tail.end());
  out.push_back(b);
  b = packet;  // someone else's connection
  StoreU32LE(b.data() + 6, kTestConnectionId + 1);
  out.push_back(b);
  b = packet;  // not a data packet
  b[5] = static_cast<uint8_t>(PacketType::kAccept);
  out.push_back(b);
  b = Bytes(packet.begin(), packet.begin() + kConnectionHeaderSize);  // disconnect, bad reason
  b[5] = static_cast<uint8_t>(PacketType::kDisconnect);
  b.push_back(0);
  out.push_back(b);
  b.back() = 200;
  out.push_back(b);
  b.back() = static_cast<uint8_t>(DisconnectReason::kKicked);
  b.push_back(0);  // trailing byte
  out.push_back(b);
  b = packet;  // oversized unit
  if (!starts.empty() && b[last] == 0x01) {
    Bytes unit(kMaxReliableUnitSize + 1, 9);
    Bytes t = PacketBuilder(PacketType::kData, 0).Unit(1, true, unit).Build();
    b = Bytes(packet.begin(), packet.begin() + kConnectionHeaderSize);
    b.insert(b.end(), t.begin() + kConnectionHeaderSize, t.end());
    out.push_back(b);
  }
  return out;
}

TEST(ConnectionTest, MalformedPacketsChangeNoState) {
  // `sender` produces real traffic; `twin` sees exactly that, `victim` also the broken variants.
  ConnectionConfig config;
  Connection sender(kTestConnectionId, config, 0), victim(kTestConnectionId, config, 0),
      twin(kTestConnectionId, config, 0);
  RecordingHandler hs, hv, ht;
  std::mt19937 rng(21);
  int malformed = 0;
  for (int step = 1; step <= 300; ++step) {
    double now = step * 0.01;
    CapturingWriter from_sender(&hs);
    if (step % 3 == 0) {
      ASSERT_TRUE(sender.SendReliable(RandomBytes(1 + rng() % 3000, step)).ok());
    }
    Bytes payload = RandomBytes(1 + rng() % 100, step + 1000);
    ASSERT_TRUE(sender.SendUnreliable(payload, now, from_sender).ok());
    sender.Update(now, from_sender);
    for (const Bytes& packet : from_sender.packets) {
      for (const Bytes& bad : MalformedVariants(packet, rng)) {
        Status status = victim.ProcessPacket(bad, now, hv);
        ASSERT_EQ(status.code(), StatusCode::kMalformed) << "variant of size " << bad.size();
        ++malformed;
        ASSERT_TRUE(StatsEqual(victim.stats(), twin.stats()));
      }
      if (rng() % 4 == 0) continue;  // some loss, so acks and resends get exercised
      EXPECT_EQ(victim.ProcessPacket(packet, now, hv).code(),
                twin.ProcessPacket(packet, now, ht).code());
    }
    CapturingWriter from_victim(&hv), from_twin(&ht);
    victim.Update(now, from_victim);
    twin.Update(now, from_twin);
    ASSERT_EQ(from_victim.packets, from_twin.packets) << "step " << step;
    // Only feeds the sender its acks; what it makes of them is not under test here.
    for (const Bytes& packet : from_twin.packets) (void)sender.ProcessPacket(packet, now, hs);
    ASSERT_TRUE(StatsEqual(victim.stats(), twin.stats()));
    ASSERT_EQ(hv.reliable, ht.reliable);
    ASSERT_EQ(hv.unreliable, ht.unreliable);
  }
  EXPECT_GT(malformed, 3000);
  EXPECT_GT(ht.reliable.size(), 50u);
  EXPECT_TRUE(victim.connected());
}

TEST(ConnectionTest, RandomAndMutatedPacketsNeverCrash) {
  // A corpus of real packets, then thousands of seeded mutations of them and pure garbage.
  ConnectionConfig config;
  Connection sender(kTestConnectionId, config, 0);
  CapturingWriter corpus;
  std::mt19937 rng(99);
  for (int step = 1; step <= 100; ++step) {
    if (step % 2 == 0) {
      ASSERT_TRUE(sender.SendReliable(RandomBytes(1 + rng() % 4000, step)).ok());
    }
    ASSERT_TRUE(
        sender.SendUnreliable(RandomBytes(1 + rng() % 500, step), step * 0.01, corpus).ok());
    sender.Update(step * 0.01, corpus);
  }
  auto victim = std::make_unique<Connection>(kTestConnectionId, config, 0);
  RecordingHandler h;
  std::map<StatusCode, int> codes;
  int replaced = 0;
  for (int i = 0; i < 20000; ++i) {
    const Bytes& original = corpus.packets[rng() % corpus.packets.size()];
    Bytes packet = original;
    switch (rng() % 5) {
      case 0:  // flip a few bytes
        for (uint32_t n = 1 + rng() % 4; n > 0; --n)
          packet[rng() % packet.size()] ^= 1 + rng() % 255;
        break;
      case 1:  // truncate
        packet.resize(rng() % packet.size());
        break;
      case 2:  // extend with garbage
        for (uint32_t n = 1 + rng() % 64; n > 0; --n) packet.push_back(static_cast<uint8_t>(rng()));
        break;
      case 3:  // overwrite a 16-bit field after the prefix (lengths, ids, sequences)
        if (packet.size() > kPacketPrefixSize + 2) {
          StoreU16LE(
              packet.data() + kPacketPrefixSize + rng() % (packet.size() - kPacketPrefixSize - 1),
              static_cast<uint16_t>(rng()));
        }
        break;
      default:  // garbage
        packet = RandomBytes(rng() % 1300, static_cast<uint32_t>(i));
        break;
    }
    Status status = victim->ProcessPacket(packet, 1.0 + i * 1e-4, h);
    codes[status.code()]++;
    EXPECT_TRUE(status.code() == StatusCode::kOk || status.code() == StatusCode::kMalformed ||
                status.code() == StatusCode::kAlreadyExists ||
                status.code() == StatusCode::kTooLarge ||
                status.code() == StatusCode::kResourceExhausted)
        << static_cast<int>(status.code());
    if (packet.size() < kConnectionHeaderSize) {
      EXPECT_EQ(status.code(), StatusCode::kMalformed);
    }
    if (!victim->connected()) {
      victim = std::make_unique<Connection>(kTestConnectionId, config, 0);
      ++replaced;
    }
  }
  EXPECT_GT(codes[StatusCode::kMalformed], 10000);
  EXPECT_GT(codes[StatusCode::kOk], 100);
  (void)replaced;
}

}  // namespace
}  // namespace edgephys
