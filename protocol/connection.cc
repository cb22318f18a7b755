#include "protocol/connection.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "protocol/byte_io.h"
#include "protocol/packet_ledger.h"
#include "protocol/reliable_channel.h"
#include "protocol/sequence.h"

namespace edgephys {
namespace {

constexpr uint8_t kChunkReliable = 0x01;
constexpr uint8_t kChunkUnreliable = 0x02;
constexpr uint8_t kUnitFlagLast = 0x01;
constexpr size_t kReliableChunkHeader = 6;    // type, id, flags, len
constexpr size_t kUnreliableChunkHeader = 3;  // type, len

// A unit chunk holds at least one byte, so no packet can carry more units than this.
constexpr size_t kMaxUnitsPerPacket =
    (kMaxPacketSize - kConnectionHeaderSize) / (kReliableChunkHeader + 1);
constexpr int kDisconnectCopies = 3;
constexpr int kAckRange = 33;            // ack + 32 ack bits
constexpr double kLossSmoothing = 0.02;  // EWMA weight of one packet's fate (~50 packets)
constexpr double kMinLossTimeout = 1.0;
// Pacing: the peer acknowledges at most 33 of our packets per packet it sends (ack + 32 bits)
// and sends at least one per Update(), so larger bursts would go unacknowledged and be resent.
constexpr int kMaxDataPacketsPerUpdate = 16;

bool ValidDisconnectReason(uint8_t value) {
  return value >= static_cast<uint8_t>(DisconnectReason::kTimeout) &&
         value <= static_cast<uint8_t>(DisconnectReason::kReliableOverflow);
}

// A data packet, fully parsed and validated before any state changes.
struct ParsedData {
  uint16_t sequence = 0;
  uint16_t ack = 0;
  uint32_t ack_bits = 0;
  std::array<ReliableUnitView, kMaxUnitsPerPacket> units;
  size_t unit_count = 0;
  bool has_unreliable = false;
  std::span<const uint8_t> unreliable;
};

bool ParseChunks(ByteReader& reader, ParsedData* parsed) {
  while (reader.remaining() > 0) {
    uint8_t type = 0;
    reader.ReadU8(&type);
    if (type == kChunkReliable) {
      ReliableUnitView unit;
      uint8_t flags = 0;
      uint16_t size = 0;
      if (!reader.ReadU16(&unit.id) || !reader.ReadU8(&flags) || !reader.ReadU16(&size)) {
        return false;
      }
      if ((flags & ~kUnitFlagLast) != 0 || size == 0 || size > kMaxReliableUnitSize) return false;
      if (!reader.ReadBytes(size, &unit.data)) return false;
      if (parsed->unit_count == parsed->units.size()) return false;
      unit.last = (flags & kUnitFlagLast) != 0;
      parsed->units[parsed->unit_count++] = unit;
    } else if (type == kChunkUnreliable) {
      uint16_t size = 0;
      if (parsed->has_unreliable || !reader.ReadU16(&size)) return false;
      if (size == 0 || size > kMaxUnreliablePayload) return false;
      if (!reader.ReadBytes(size, &parsed->unreliable)) return false;
      parsed->has_unreliable = true;
    } else {
      return false;
    }
  }
  return true;
}

}  // namespace

struct Connection::Impl {
  Impl(Connection& owner_in, const ConnectionConfig& config_in, double now)
      : owner(owner_in),
        config(config_in),
        sender(config_in.max_message_size, config_in.max_pending_reliable_bytes),
        receiver(config_in.max_message_size, config_in.max_held_reliable_bytes),
        last_receive_time(now),
        last_send_time(now),
        last_now(now) {}

  // ---- packet building -------------------------------------------------------------------

  size_t BeginPacket(PacketType type) {
    unit_count = 0;
    WritePacketPrefix(type, owner.connection_id_, scratch);
    return kConnectionHeaderSize;
  }

  // Stamps sequence and acks into the scratch packet of `size` bytes and sends it.
  uint16_t FinishPacket(size_t size, bool ack_eliciting, double now, PacketWriter& out) {
    uint16_t sequence = next_sequence++;
    StoreU16LE(scratch.data() + kPacketPrefixSize, sequence);
    StoreU16LE(scratch.data() + kPacketPrefixSize + 2, received.ack());
    StoreU32LE(scratch.data() + kPacketPrefixSize + 4, received.AckBits());
    // The slot we are about to reuse must be resolved first (counted lost if still pending).
    while (static_cast<uint16_t>(sequence - oldest_unresolved) >= SentPacketLog::kCapacity) {
      ResolveOldest(/*lost=*/true);
    }
    sent.Add(sequence, now, ack_eliciting, std::span<const uint16_t>(units.data(), unit_count));
    unit_count = 0;
    out.WritePacket(std::span<const uint8_t>(scratch.data(), size));
    owner.stats_.packets_sent++;
    owner.stats_.bytes_sent += size + owner.datagram_overhead_;
    last_send_time = now;
    ack_pending = false;
    ack_urgent = false;
    return sequence;
  }

  void SendAckOnly(double now, PacketWriter& out) {
    FinishPacket(BeginPacket(PacketType::kData), /*ack_eliciting=*/false, now, out);
  }

  void SendDisconnects(PacketWriter& out) {
    for (; pending_disconnect_sends > 0; --pending_disconnect_sends) {
      size_t size = BeginPacket(PacketType::kDisconnect);
      StoreU16LE(scratch.data() + kPacketPrefixSize, next_sequence++);
      StoreU16LE(scratch.data() + kPacketPrefixSize + 2, received.ack());
      StoreU32LE(scratch.data() + kPacketPrefixSize + 4, received.AckBits());
      scratch[size++] = static_cast<uint8_t>(owner.disconnect_reason_);
      out.WritePacket(std::span<const uint8_t>(scratch.data(), size));
      owner.stats_.packets_sent++;
      owner.stats_.bytes_sent += size + owner.datagram_overhead_;
    }
  }

  // New units first, then those whose resend timeout expired, packed greedily in unit order,
  // at most kMaxDataPacketsPerUpdate packets (the rest waits for the next Update()).
  void SendDueUnits(double now, PacketWriter& out) {
    double timeout = ResendTimeout();
    size_t size = 0;
    int packets = 0;
    for (bool resends : {false, true}) {
      for (size_t i = 0; i < sender.sendable_count(); ++i) {
        if (sender.IsSent(i) != resends || !sender.IsDue(i, now, timeout)) continue;
        ReliableUnitView unit = sender.View(i);
        size_t need = kReliableChunkHeader + unit.data.size();
        if (size != 0 && (size + need > kMaxPacketSize || unit_count == units.size())) {
          FinishPacket(size, /*ack_eliciting=*/true, now, out);
          size = 0;
        }
        if (size == 0) {
          if (packets == kMaxDataPacketsPerUpdate) return;
          size = BeginPacket(PacketType::kData);
          ++packets;
        }
        WriteUnit(i, unit, now, &size);
      }
    }
    if (size != 0) FinishPacket(size, /*ack_eliciting=*/true, now, out);
  }

  // Writes sendable unit `i` (its `unit` view) at scratch[*size] and marks it sent.
  void WriteUnit(size_t i, const ReliableUnitView& unit, double now, size_t* size) {
    uint8_t* p = scratch.data() + *size;
    p[0] = kChunkReliable;
    StoreU16LE(p + 1, unit.id);
    p[3] = unit.last ? kUnitFlagLast : 0;
    StoreU16LE(p + 4, static_cast<uint16_t>(unit.data.size()));
    std::copy(unit.data.begin(), unit.data.end(), p + kReliableChunkHeader);
    *size += kReliableChunkHeader + unit.data.size();
    units[unit_count++] = unit.id;
    if (sender.MarkSent(i, now)) owner.stats_.reliable_resends++;
  }

  // Fills the rest of the packet being built (`*size` bytes so far) with due reliable units
  // that fit, new ones first, then expired ones: reliable messages ride on an unreliable
  // payload's packet instead of a datagram of their own. Looks at most kPiggybackScan units
  // per pass, so a long queue (a join stream) costs a bounded scan per packet.
  void AppendDueUnits(size_t* size, double now) {
    if (sender.sendable_count() == 0) return;
    const double timeout = ResendTimeout();
    for (bool resends : {false, true}) {
      const size_t n = std::min(sender.sendable_count(), kPiggybackScan);
      for (size_t i = 0; i < n; ++i) {
        if (unit_count == units.size() || *size + kReliableChunkHeader >= kMaxPacketSize) return;
        if (sender.IsSent(i) != resends || !sender.IsDue(i, now, timeout)) continue;
        ReliableUnitView unit = sender.View(i);
        if (*size + kReliableChunkHeader + unit.data.size() > kMaxPacketSize) continue;
        WriteUnit(i, unit, now, size);
      }
    }
  }
  static constexpr size_t kPiggybackScan = 64;

  // Never-sent units inside the send window (those beyond it wait for acks, not for time).
  size_t SendableUnsent() const {
    const size_t beyond =
        sender.queued_units() > kReliableWindow ? sender.queued_units() - kReliableWindow : 0;
    return sender.unsent_units() > beyond ? sender.unsent_units() - beyond : 0;
  }

  // ---- acknowledgements, RTT and loss ----------------------------------------------------

  double ResendTimeout() const {
    if (!have_rtt) return config.max_resend_s;
    double rto = owner.stats_.rtt_s + 4 * owner.stats_.rtt_var_s;
    return std::clamp(rto, config.min_resend_s, config.max_resend_s);
  }

  double LossTimeout() const { return std::max(kMinLossTimeout, 4 * owner.stats_.rtt_s); }

  void LossSample(double lost) { owner.stats_.loss += kLossSmoothing * (lost - owner.stats_.loss); }

  void RttSample(double rtt) {
    ConnectionStats& s = owner.stats_;
    if (!have_rtt) {
      have_rtt = true;
      s.rtt_s = rtt;
      s.rtt_var_s = rtt / 2;
    } else {
      s.rtt_var_s = 0.75 * s.rtt_var_s + 0.25 * std::fabs(s.rtt_s - rtt);
      s.rtt_s = 0.875 * s.rtt_s + 0.125 * rtt;
    }
  }

  void ResolveOldest(bool lost) {
    if (SentPacketLog::Record* r = sent.Find(oldest_unresolved); r != nullptr && !r->resolved) {
      r->resolved = true;
      if (r->ack_eliciting) LossSample(lost ? 1.0 : 0.0);
    }
    ++oldest_unresolved;
  }

  // Deems lost the oldest pending packets that fell out of the ack range or waited too long.
  void DetectLoss(double now) {
    double loss_timeout = LossTimeout();
    while (oldest_unresolved != next_sequence) {
      SentPacketLog::Record* r = sent.Find(oldest_unresolved);
      if (r != nullptr && !r->resolved) {
        bool out_of_range = have_peer_ack && SequenceDiff(peer_ack, r->sequence) >= kAckRange;
        if (!out_of_range && now - r->send_time < loss_timeout) break;
      }
      ResolveOldest(/*lost=*/true);
    }
  }

  void AckPacket(uint16_t sequence, bool newest, double now, ConnectionHandler& handler) {
    SentPacketLog::Record* r = sent.Find(sequence);
    if (r == nullptr || r->acked) return;
    r->acked = true;
    if (!r->resolved) {
      r->resolved = true;
      if (r->ack_eliciting) LossSample(0.0);
    }
    if (newest && r->ack_eliciting) RttSample(std::max(0.0, now - r->send_time));
    for (uint16_t unit_id : sent.Units(*r)) sender.Ack(unit_id);
    handler.OnPacketAcked(sequence);
  }

  void ProcessAcks(uint16_t ack, uint32_t ack_bits, double now, ConnectionHandler& handler) {
    // An ack for a sequence we have not sent yet is bogus (or the "nothing received" marker).
    if (SequenceDiff(ack, next_sequence) >= 0) return;
    if (!have_peer_ack || SequenceGreater(ack, peer_ack)) {
      have_peer_ack = true;
      peer_ack = ack;
    }
    AckPacket(ack, /*newest=*/true, now, handler);
    for (uint32_t i = 0; i < 32; ++i) {
      if (ack_bits & (1u << i)) {
        AckPacket(static_cast<uint16_t>(ack - 1 - i), /*newest=*/false, now, handler);
      }
    }
    owner.stats_.pending_reliable_bytes = sender.pending_bytes();
    DetectLoss(now);
  }

  void ProtocolError() {
    owner.disconnect_reason_ = DisconnectReason::kProtocolError;
    pending_disconnect_sends = kDisconnectCopies;
  }

  Connection& owner;
  ConnectionConfig config;
  ReliableSender sender;
  ReliableReceiver receiver;
  SentPacketLog sent;
  ReceivedPacketLog received;
  uint16_t next_sequence = 0;
  uint16_t oldest_unresolved = 0;  // oldest of our packets not yet acked or deemed lost
  bool have_peer_ack = false;
  uint16_t peer_ack = 0;  // newest of our sequences the peer reported
  bool have_rtt = false;
  double last_receive_time;
  double last_send_time;
  bool ack_pending = false;  // the peer sent chunks we have not acknowledged yet
  bool ack_urgent = false;   // ... among them reliable units (acknowledged without delay)
  double ack_pending_since = 0;  // when ack_pending became true
  bool have_unreliable = false;
  uint16_t newest_unreliable = 0;  // sequence of the newest unreliable payload delivered
  int pending_disconnect_sends = 0;
  double last_now = 0;       // the latest `now` given to this connection
  std::array<uint8_t, kMaxPacketSize> scratch{};
  std::array<uint16_t, kMaxUnitsPerPacket> units{};  // unit ids of the packet being built
  size_t unit_count = 0;
  ParsedData parsed;  // reused by ProcessPacket
};

Connection::Connection(uint32_t connection_id, const ConnectionConfig& config, double now)
    : connection_id_(connection_id), impl_(new Impl(*this, config, now)) {}

Connection::~Connection() { delete impl_; }

Status Connection::SendReliable(std::span<const uint8_t> message) {
  if (!connected()) return Status::NotConnected("connection closed");
  Status status = impl_->sender.Queue(message);
  stats_.pending_reliable_bytes = impl_->sender.pending_bytes();
  return status;
}

uint64_t Connection::reliable_queued_end() const { return impl_->sender.queued_end(); }
uint64_t Connection::reliable_acked_end() const { return impl_->sender.acked_end(); }

Result<uint16_t> Connection::SendUnreliable(std::span<const uint8_t> payload, double now,
                                            PacketWriter& out) {
  if (!connected()) return Status::NotConnected("connection closed");
  if (payload.empty()) return Status::InvalidArgument("empty unreliable payload");
  if (payload.size() > kMaxUnreliablePayload) {
    return Status::TooLarge("unreliable payload exceeds kMaxUnreliablePayload");
  }
  size_t size = impl_->BeginPacket(PacketType::kData);
  uint8_t* p = impl_->scratch.data() + size;
  p[0] = kChunkUnreliable;
  StoreU16LE(p + 1, static_cast<uint16_t>(payload.size()));
  std::copy(payload.begin(), payload.end(), p + kUnreliableChunkHeader);
  size += kUnreliableChunkHeader + payload.size();
  impl_->last_now = now;
  impl_->AppendDueUnits(&size, now);
  return impl_->FinishPacket(size, /*ack_eliciting=*/true, now, out);
}

Status Connection::ProcessPacket(std::span<const uint8_t> packet, double now,
                                 ConnectionHandler& handler) {
  if (!connected()) return Status::NotConnected("connection closed");
  impl_->last_now = now;
  static const Status kMalformed = Status::Malformed("malformed data packet");
  PacketPrefix prefix{};
  DropReason reason{};
  if (!ParsePacketPrefix(packet, &prefix, &reason)) return kMalformed;
  if (prefix.connection_id != connection_id_) return kMalformed;
  ByteReader reader(packet.subspan(kPacketPrefixSize));
  ParsedData& parsed = impl_->parsed;
  parsed.unit_count = 0;
  parsed.has_unreliable = false;
  if (!reader.ReadU16(&parsed.sequence) || !reader.ReadU16(&parsed.ack) ||
      !reader.ReadU32(&parsed.ack_bits)) {
    return kMalformed;
  }

  if (prefix.type == PacketType::kDisconnect) {
    uint8_t value = 0;
    if (!reader.ReadU8(&value) || reader.remaining() != 0 || !ValidDisconnectReason(value)) {
      return kMalformed;
    }
    disconnect_reason_ = static_cast<DisconnectReason>(value);
    stats_.packets_received++;
    stats_.bytes_received += packet.size() + datagram_overhead_;
    return Status::Ok();
  }
  if (prefix.type != PacketType::kData) return kMalformed;
  if (!ParseChunks(reader, &parsed)) return kMalformed;

  // Parsed and valid. Checks against our state, still without changing it.
  if (impl_->received.IsDuplicate(parsed.sequence)) {
    stats_.duplicates_dropped++;
    return Status::AlreadyExists("duplicate packet");
  }
  for (size_t i = 0; i < parsed.unit_count; ++i) {
    if (impl_->receiver.Classify(parsed.units[i].id) ==
        ReliableReceiver::Placement::kOutsideWindow) {
      impl_->ProtocolError();
      return Status::ResourceExhausted("reliable unit outside the window");
    }
  }

  // Reliable units that would need reassembly memory past the bound, and do not continue the
  // stream: refused whole and unacknowledged (the peer resends them); its acks still apply.
  if (!impl_->receiver.Admits(std::span<const ReliableUnitView>(parsed.units.data(),
                                                                  parsed.unit_count))) {
    impl_->last_receive_time = now;
    stats_.packets_received++;
    stats_.bytes_received += packet.size();
    stats_.reassembly_refused++;
    impl_->ProcessAcks(parsed.ack, parsed.ack_bits, now, handler);
    return Status::QueueFull("reliable reassembly memory full");
  }

  // A packet whose unreliable payload is stale is dropped whole, reliable units included (the
  // peer resends them), and not acknowledged, so the sender never counts a dropped payload
  // as delivered (the delta codecs reference only acknowledged states). Its acks still apply.
  const bool unordered = parsed.has_unreliable && !parsed.unreliable.empty() &&
                         parsed.unreliable[0] == kUnorderedPayloadFormat;
  const bool stale = parsed.has_unreliable && !unordered && impl_->have_unreliable &&
                     !SequenceGreater(parsed.sequence, impl_->newest_unreliable);
  if (stale) {
    impl_->last_receive_time = now;
    stats_.packets_received++;
    stats_.bytes_received += packet.size() + datagram_overhead_;
    stats_.stale_dropped++;
    impl_->ProcessAcks(parsed.ack, parsed.ack_bits, now, handler);
    return Status::Ok();
  }

  // Apply.
  impl_->received.Record(parsed.sequence);
  impl_->last_receive_time = now;
  stats_.packets_received++;
  stats_.bytes_received += packet.size() + datagram_overhead_;
  if (parsed.unit_count > 0 || parsed.has_unreliable) {
    if (!impl_->ack_pending) impl_->ack_pending_since = now;
    impl_->ack_pending = true;
    if (parsed.unit_count > 0) impl_->ack_urgent = true;
  }
  impl_->ProcessAcks(parsed.ack, parsed.ack_bits, now, handler);

  for (size_t i = 0; i < parsed.unit_count && connected(); ++i) {
    Status status = impl_->receiver.Receive(parsed.units[i], handler, &stats_.reliable_delivered,
                                            &stats_.duplicates_dropped);
    if (!status.ok()) {
      impl_->ProtocolError();
      return status;
    }
  }
  if (parsed.has_unreliable && unordered && connected()) {
    handler.OnUnreliablePayload(parsed.sequence, parsed.unreliable);
  } else if (parsed.has_unreliable && connected()) {
    if (!impl_->have_unreliable || SequenceGreater(parsed.sequence, impl_->newest_unreliable)) {
      impl_->have_unreliable = true;
      impl_->newest_unreliable = parsed.sequence;
      handler.OnUnreliablePayload(parsed.sequence, parsed.unreliable);
    } else {
      stats_.stale_dropped++;
    }
  }
  return Status::Ok();
}

size_t Connection::reliable_held_bytes() const { return impl_->receiver.held_bytes(); }
size_t Connection::reliable_partial_bytes() const { return impl_->receiver.partial_bytes(); }

void Connection::SetTimeout(double timeout_s) {
  if (timeout_s > 0) impl_->config.timeout_s = timeout_s;
}

double Connection::NextTimer() const {
  const Impl& m = *impl_;
  if (m.pending_disconnect_sends > 0) return m.last_now;
  if (!connected()) return std::numeric_limits<double>::infinity();
  double t = std::min(m.last_receive_time + m.config.timeout_s,
                      m.last_send_time + m.config.keepalive_interval_s);
  if (m.ack_pending) {
    t = std::min(t, m.ack_urgent ? m.last_now : m.ack_pending_since + m.config.max_ack_delay_s);
  }
  // Unsent units left (Update() stopped at its packet cap): at once.
  if (m.SendableUnsent() > 0) t = std::min(t, m.last_now);
  return std::min(t, m.sender.OldestInFlight(Impl::kPiggybackScan) + m.ResendTimeout());
}

void Connection::Update(double now, PacketWriter& out) {
  if (impl_->pending_disconnect_sends > 0) {
    impl_->SendDisconnects(out);
    return;
  }
  if (!connected()) return;
  if (now - impl_->last_receive_time >= impl_->config.timeout_s) {
    disconnect_reason_ = DisconnectReason::kTimeout;
    return;
  }
  impl_->last_now = now;
  impl_->DetectLoss(now);
  auto ack_due = [&] {
    return impl_->ack_pending &&
           (impl_->ack_urgent || now - impl_->ack_pending_since >= impl_->config.max_ack_delay_s);
  };
  auto keepalive_due = [&] {
    return now - impl_->last_send_time >= impl_->config.keepalive_interval_s;
  };
  impl_->SendDueUnits(now, out);
  if (ack_due() || keepalive_due()) impl_->SendAckOnly(now, out);
  stats_.pending_reliable_bytes = impl_->sender.pending_bytes();
}

void Connection::Disconnect(DisconnectReason reason, PacketWriter& out) {
  if (connected()) {
    if (reason == DisconnectReason::kNone) return;
    disconnect_reason_ = reason;
    impl_->pending_disconnect_sends = kDisconnectCopies;
  }
  impl_->SendDisconnects(out);
}

}  // namespace edgephys
