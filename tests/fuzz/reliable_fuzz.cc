// reliable_fuzz: Connection and its reliable channel (fragmentation, reassembly, window, acks).
//
// Input: u8 mode | records (u8 tag | u16 length | bytes), at most kMaxRecords.
// mode bit 0 clear, "raw": one Connection under attack. By tag % 4 a record is
//   0: a packet from the peer: a valid prefix (tag bit 2: kDisconnect, else kData) with the
//      connection id, then the bytes (header + chunks) -> ProcessPacket
//   1: SendReliable(bytes)  2: SendUnreliable(bytes)  3: Update() after bytes[0] ms
//   (the connection's own packets go nowhere; peer packets ack them by sequence)
// mode bit 0 set, "pair": two honest Connections A -> B over a link the input controls
// (drop / duplicate / reorder / delay). A sends the records as reliable messages (tag bit 0
// clear; sizes up to 8 KB, so several units each) or unreliable payloads. Checked: B delivers
// a prefix of A's reliable messages, in order, exactly once, and unreliable payloads only
// newer than those before; after the link heals, everything reliable arrives.
// Memory is bounded by small max_message_size / pending limits; in "raw" mode every step
// checks the receive side's bound (Connection::reliable_held_bytes(), connection.h).
#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>

#include "protocol/byte_io.h"
#include "protocol/sequence.h"
#include "tests/fuzz/fuzz_world.h"

namespace edgephys::fuzz {
namespace {

constexpr size_t kMaxRecords = 128;
constexpr uint32_t kId = 0x01020304;

ConnectionConfig FuzzConnectionConfig() {
  ConnectionConfig c;
  c.max_message_size = 64 << 10;
  c.max_pending_reliable_bytes = 256 << 10;
  c.max_held_reliable_bytes = 96 << 10;  // below max_message_size + window: refusals happen
  return c;
}

struct NullWriter final : PacketWriter {
  void WritePacket(std::span<const uint8_t> packet) override {
    EDGEPHYS_FUZZ_CHECK(packet.size() <= kMaxPacketSize);
    EDGEPHYS_FUZZ_CHECK(packet.size() >= kConnectionHeaderSize);
  }
};

struct CountingHandler final : ConnectionHandler {
  void OnReliableMessage(std::span<const uint8_t> message) override {
    EDGEPHYS_FUZZ_CHECK(!message.empty() && message.size() <= (64u << 10));
  }
  void OnUnreliablePayload(uint16_t, std::span<const uint8_t> payload) override {
    EDGEPHYS_FUZZ_CHECK(payload.size() <= kMaxUnreliablePayload);
  }
};

void RunRaw(Reader& in) {
  double now = 1.0;
  Connection c(kId, FuzzConnectionConfig(), now);
  NullWriter out;
  CountingHandler handler;
  for (size_t i = 0; i < kMaxRecords && !in.empty(); ++i) {
    const uint8_t tag = in.U8();
    auto bytes = in.Bytes(in.U16());
    switch (tag % 4) {
      case 0: {
        std::vector<uint8_t> packet(kPacketPrefixSize + bytes.size());
        WritePacketPrefix((tag & 4) ? PacketType::kDisconnect : PacketType::kData, kId, packet);
        std::copy(bytes.begin(), bytes.end(), packet.begin() + kPacketPrefixSize);
        (void)c.ProcessPacket(packet, now, handler);
        break;
      }
      case 1: (void)c.SendReliable(bytes); break;
      case 2: (void)c.SendUnreliable(bytes, now, out); break;
      case 3:
        now += (bytes.empty() ? 1 : bytes[0]) / 1000.0;
        c.Update(now, out);
        break;
    }
    EDGEPHYS_FUZZ_CHECK(c.stats().pending_reliable_bytes <= (256u << 10) + (64u << 10));
    EDGEPHYS_FUZZ_CHECK(c.reliable_held_bytes() <= (96u << 10) + kReliableHeldSlack);
  }
  c.Update(now + 0.5, out);
}

// A -> B: records what B delivers and checks it against what A sent.
class Receiver final : public ConnectionHandler {
 public:
  explicit Receiver(const std::vector<std::vector<uint8_t>>* sent_reliable,
                    const std::map<uint16_t, std::vector<uint8_t>>* sent_unreliable)
      : sent_reliable_(sent_reliable), sent_unreliable_(sent_unreliable) {}
  void OnReliableMessage(std::span<const uint8_t> message) override {
    EDGEPHYS_FUZZ_CHECK(delivered_ < sent_reliable_->size());
    const auto& expected = (*sent_reliable_)[delivered_++];
    EDGEPHYS_FUZZ_CHECK(std::equal(message.begin(), message.end(), expected.begin(), expected.end()));
  }
  void OnUnreliablePayload(uint16_t sequence, std::span<const uint8_t> payload) override {
    if (have_unreliable_) EDGEPHYS_FUZZ_CHECK(SequenceGreater(sequence, newest_unreliable_));
    have_unreliable_ = true;
    newest_unreliable_ = sequence;
    auto it = sent_unreliable_->find(sequence);
    EDGEPHYS_FUZZ_CHECK(it != sent_unreliable_->end());
    EDGEPHYS_FUZZ_CHECK(std::equal(payload.begin(), payload.end(), it->second.begin(), it->second.end()));
  }
  size_t delivered() const { return delivered_; }

 private:
  const std::vector<std::vector<uint8_t>>* sent_reliable_;
  const std::map<uint16_t, std::vector<uint8_t>>* sent_unreliable_;
  size_t delivered_ = 0;
  bool have_unreliable_ = false;
  uint16_t newest_unreliable_ = 0;
};

struct QueueWriter final : PacketWriter {
  std::deque<std::vector<uint8_t>> packets;
  void WritePacket(std::span<const uint8_t> packet) override {
    EDGEPHYS_FUZZ_CHECK(packet.size() <= kMaxPacketSize);
    if (packets.size() < 4096) packets.emplace_back(packet.begin(), packet.end());
  }
};

// Delivers queued packets; `control` (if any) decides per packet: drop, duplicate, swap with
// the next one, or deliver.
void Deliver(QueueWriter& queue, Connection& to, ConnectionHandler& handler, double now,
             Reader* control) {
  while (!queue.packets.empty()) {
    std::vector<uint8_t> p = std::move(queue.packets.front());
    queue.packets.pop_front();
    uint8_t action = control ? control->U8() % 8 : 0;
    if (action == 1) continue;  // drop
    if (action == 2 && !queue.packets.empty()) {
      std::swap(p, queue.packets.front());  // reorder
    }
    (void)to.ProcessPacket(p, now, handler);
    if (action == 3) (void)to.ProcessPacket(p, now, handler);  // duplicate
  }
}

void RunPair(Reader& in) {
  double now = 1.0;
  Connection a(kId, FuzzConnectionConfig(), now);
  Connection b(kId, FuzzConnectionConfig(), now);
  std::vector<std::vector<uint8_t>> sent_reliable;
  std::map<uint16_t, std::vector<uint8_t>> sent_unreliable;
  Receiver b_handler(&sent_reliable, &sent_unreliable);
  CountingHandler a_handler;
  QueueWriter a_out, b_out;
  size_t total_bytes = 0;
  for (size_t i = 0; i < kMaxRecords && !in.empty(); ++i) {
    const uint8_t tag = in.U8();
    const size_t len = in.U16() % 8192;
    auto bytes = in.Bytes(len);
    // Expand short inputs so messages span several units: repeat the bytes up to `len`.
    std::vector<uint8_t> message;
    if (!bytes.empty()) {
      size_t want = (tag & 2) ? len : bytes.size();
      while (message.size() < want) {
        message.insert(message.end(), bytes.begin(),
                       bytes.begin() + std::min(bytes.size(), want - message.size()));
      }
    }
    if (!message.empty()) {
      if ((tag & 1) == 0) {
        if (total_bytes + message.size() <= (200u << 10) && a.SendReliable(message).ok()) {
          total_bytes += message.size();
          sent_reliable.push_back(std::move(message));
        }
      } else if (message.size() <= kMaxUnreliablePayload) {
        Result<uint16_t> seq = a.SendUnreliable(message, now, a_out);
        if (seq.ok()) sent_unreliable[*seq] = std::move(message);
      }
    }
    now += (tag >> 4) / 1000.0;  // 0..15 ms
    a.Update(now, a_out);
    Deliver(a_out, b, b_handler, now, &in);
    b.Update(now, b_out);
    Deliver(b_out, a, a_handler, now, &in);
    EDGEPHYS_FUZZ_CHECK(a.connected() && b.connected());
  }
  // Heal the link: everything reliable must arrive.
  for (int step = 0; step < 400 && b_handler.delivered() < sent_reliable.size(); ++step) {
    now += 0.02;
    a.Update(now, a_out);
    Deliver(a_out, b, b_handler, now, nullptr);
    b.Update(now, b_out);
    Deliver(b_out, a, a_handler, now, nullptr);
  }
  EDGEPHYS_FUZZ_CHECK(a.connected() && b.connected());
  EDGEPHYS_FUZZ_CHECK(b_handler.delivered() == sent_reliable.size());
}

}  // namespace
}  // namespace edgephys::fuzz

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  edgephys::fuzz::Reader in(data, size);
  if (in.U8() & 1) {
    edgephys::fuzz::RunPair(in);
  } else {
    edgephys::fuzz::RunRaw(in);
  }
  return 0;
}
