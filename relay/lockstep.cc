#include "relay/lockstep.h"

#include <algorithm>
#include <mutex>

#include "relay/entity.h"

namespace edgephys {
namespace {

// The canonical replicator's player id: owns nothing (its walk skips no entity anyway).
constexpr uint32_t kNobody = 0xFFFFFFFFu;

std::mutex& RegistryMutex() {  // Register runs in receivers' ticks, which may be parallel
  static std::mutex m;
  return m;
}

}  // namespace

// ---------------------------------- LockstepMember ----------------------------------

void LockstepMember::Expect(uint32_t tick, uint16_t sequence, uint32_t payload, bool acked,
                            bool has_sequence) {
  TickAcks& t = ticks[tick % ticks.size()];
  if (t.tick != tick) t = TickAcks{tick, 0, 0};
  ++t.need;
  if (acked) {
    ++t.got;
    return;
  }
  if (!has_sequence) return;
  sent[sequence % sent.size()] = Sent{true, false, sequence, tick, payload};
}

bool LockstepMember::OnAcked(uint16_t sequence) {
  Sent& s = sent[sequence % sent.size()];
  if (!s.valid || s.acked || s.sequence != sequence) return false;
  s.acked = true;
  if (TickAcks* t = At(s.tick); t != nullptr && t->got < t->need) ++t->got;
  return true;
}

uint32_t LockstepGroup::Payload::OwnedBy(uint32_t player) const {
  auto it = std::lower_bound(owners.begin(), owners.end(), std::make_pair(player, 0u));
  return it != owners.end() && it->first == player ? it->second : 0;
}

// ---------------------------------- LockstepGroup ----------------------------------

LockstepGroup::LockstepGroup(const ReplicationConfig& config, double tick_rate_hz)
    : ack_ticks_(std::max<uint32_t>(1, std::min<uint32_t>(config.lockstep_ack_ticks, 32))),
      canonical_(std::make_unique<ClientReplicator>(config)) {
  // The canonical stream counts a payload acknowledged ack_ticks_ ticks after sending it:
  // until then its sends are in flight, and never resent for want of an acknowledgement.
  resend_after_s_ = ack_ticks_ / std::max(1.0, tick_rate_hz) + 0.05;
  canonical_->lockstep_capture_ = this;
}

LockstepGroup::~LockstepGroup() = default;

void LockstepGroup::Register(ClientReplicator* r) {
  std::lock_guard<std::mutex> lock(RegistryMutex());
  members_.push_back(r);
}

void LockstepGroup::Unregister(ClientReplicator* r) {
  std::lock_guard<std::mutex> lock(RegistryMutex());
  members_.erase(std::remove(members_.begin(), members_.end(), r), members_.end());
}

size_t LockstepGroup::in_lockstep() const {
  size_t n = 0;
  for (const ClientReplicator* r : members_) n += r->in_lockstep() ? 1 : 0;
  return n;
}

uint16_t LockstepGroup::Capture(std::span<const uint8_t> payload, size_t entities,
                                uint32_t number, std::span<const uint32_t> owners) {
  if (payload_count_ == payloads_.size()) payloads_.emplace_back();
  Payload& p = payloads_[payload_count_++];
  p.number = number;
  p.entities = entities;
  p.bytes.assign(payload.begin(), payload.end());
  p.owners.clear();
  owner_scratch_.assign(owners.begin(), owners.end());
  std::sort(owner_scratch_.begin(), owner_scratch_.end());
  for (uint32_t o : owner_scratch_) {
    if (p.owners.empty() || p.owners.back().first != o) p.owners.emplace_back(o, 0);
    ++p.owners.back().second;
  }
  TickPayloads& t = tick_payloads_[tick_ % tick_payloads_.size()];
  if (t.tick != tick_) {
    t.tick = tick_;
    t.numbers.clear();
  }
  t.numbers.push_back(number);
  return next_sequence_++;
}

bool LockstepGroup::DueAcked(ClientReplicator& r, uint32_t due) {
  LockstepMember& m = *r.member_;
  LockstepMember::TickAcks* a = m.At(due);
  if (static_cast<int32_t>(due - m.since) < 0) {  // its own packets stood for the tick's
    return a == nullptr || a->got == a->need;
  }
  const TickPayloads* c = PayloadsOf(due);
  if (c == nullptr) return true;
  return a != nullptr && a->need == c->numbers.size() && a->got == a->need;
}

void LockstepGroup::Leave(ClientReplicator& r, uint32_t due, RelayCounters& counters) {
  LockstepMember& m = *r.member_;
  // The canonical payloads not yet due (ticks due .. tick_-1), as this receiver got them.
  fixes_.clear();
  for (uint32_t t = due; t != tick_; ++t) {
    const TickPayloads* c = PayloadsOf(t);
    if (c == nullptr) continue;
    const LockstepMember::TickAcks* a = m.At(t);
    const bool own = static_cast<int32_t>(t - m.since) < 0;
    for (uint32_t number : c->numbers) {
      SharedDeltaStream::PayloadFix fix;
      fix.payload = number;
      if (own) {  // all of its own packets of the tick, or none counts
        fix.acked = a != nullptr && a->got == a->need;
      } else {
        for (const LockstepMember::Sent& s : m.sent) {
          if (!s.valid || s.tick != t || s.payload != number) continue;
          fix.acked = s.acked;
          fix.has_sequence = !s.acked;
          fix.sequence = s.sequence;
          break;
        }
      }
      fixes_.push_back(fix);
    }
  }
  r.AdoptCanonical(*canonical_, fixes_);
  m.in = false;
  m.next_check = tick_ + kRejoinEvery;
  RelayCounters::Inc(counters.lockstep_leaves);
}

bool LockstepGroup::TryRejoin(ClientReplicator& r, const ReplicationFrame& frame,
                              RelayCounters& counters) {
  SharedDeltaStream& mine = r.shared_->codec();
  SharedDeltaStream& canonical = canonical_->shared_->codec();
  // Entities whose records differ (typically ones at rest: each stream acknowledged its own
  // send of the same version, in different ticks) are allowed up to a budget: the canonical
  // stream forgets them, so its next send of each is a keyframe, to every lockstep receiver.
  const size_t budget = std::max<size_t>(kMinForcedKeyframes, frame.by_id.size() / 8);
  forced_.clear();
  for (const Entity* e : frame.by_id) {
    if (e->shared == nullptr || mine.SameBaselines(canonical, *e->shared, tick_)) continue;
    if (forced_.size() == budget) return false;
    forced_.push_back(e);
  }
  for (const Entity* e : forced_) {
    canonical.Forget(e->id);
    // Re-decided at its next due time: no record, so a keyframe (not "settled").
    if (e->slot < canonical_->views_.size()) canonical_->views_[e->slot].settled_version = 0;
  }
  RelayCounters::Inc(counters.lockstep_forced_keyframes, forced_.size());
  LockstepMember& m = *r.member_;
  m.sent.fill({});
  m.ticks.fill({});
  // Its own packets of the last ack_ticks_ - 1 ticks stand for the canonical payloads of their
  // ticks (same sends, by SameBaselines): each tick's must all be acknowledged when it is due.
  in_flight_.clear();
  mine.PayloadsAfter(tick_ - ack_ticks_, &in_flight_);
  for (const SharedDeltaStream::SentPayloadInfo& p : in_flight_) {
    // Without a known sequence its acknowledgement cannot be learnt: the tick stays incomplete.
    m.Expect(p.tick, p.sequence, 0, p.acked, p.has_sequence);
  }
  m.in = true;
  m.since = tick_;
  return true;
}

void LockstepGroup::BeginTick(const ReplicationFrame& frame, const SharedDeltaRoom& room,
                              double now, RelayCounters& counters) {
  tick_ = room.tick();
  payload_count_ = 0;
  // 1. Leaves, before anything of this tick: the canonical payloads of tick (now - L) become
  //    baselines in this tick's canonical payloads.
  const uint32_t due = tick_ - ack_ticks_;
  for (ClientReplicator* r : members_) {
    if (r->member_->in && !DueAcked(*r, due)) Leave(*r, due, counters);
  }
  // 2. A few rejoin checks (members that ticked last tick, round robin).
  size_t checks = 0;
  for (size_t k = 0; k < members_.size() && checks < kRejoinChecksPerTick; ++k) {
    ClientReplicator* r = members_[rejoin_cursor_++ % members_.size()];
    LockstepMember& m = *r->member_;
    if (m.in || !m.ticked || m.last_tick != tick_ - 1) continue;
    if (static_cast<int32_t>(tick_ - m.next_check) < 0) continue;
    ++checks;
    m.next_check = tick_ + kRejoinEvery;
    if (TryRejoin(*r, frame, counters)) RelayCounters::Inc(counters.lockstep_rejoins);
  }
  // 3. The canonical replicator's tick: this tick's payloads (Capture).
  ClientReplicator& c = *canonical_;
  c.last_tick_ = now;
  c.time_ms_ = static_cast<uint32_t>(static_cast<uint64_t>(now * 1000.0));
  c.TickEntities(frame, kNobody, now, resend_after_s_, nullptr, nullptr, counters);
}

// ------------------------- ClientReplicator's lockstep side -------------------------

void ClientReplicator::CopyCanonical(const LockstepGroup& group, uint32_t self, double now,
                                     Connection& connection, PacketWriter& out,
                                     RelayCounters& counters) {
  uint64_t updates = 0, sends = 0;
  for (const LockstepGroup::Payload& p : group.payloads()) {
    Result<uint16_t> seq = connection.SendUnreliable(p.bytes, now, out);
    if (!seq.ok()) continue;  // never counted acknowledged: leaves lockstep when due
    member_->Expect(group.tick(), *seq, p.number, false);
    updates += p.entities - p.OwnedBy(self);
    ++sends;
  }
  if (sends == 0) return;
  RelayCounters::Inc(counters.entity_updates_sent, updates);
  RelayCounters::Inc(counters.lockstep_sends, sends);
}

void ClientReplicator::AdoptCanonical(const ClientReplicator& canonical,
                                      std::span<const SharedDeltaStream::PayloadFix> fixes) {
  views_ = canonical.views_;
  view_slot_of_ = canonical.view_slot_of_;
  live_views_ = canonical.live_views_;
  bytes_per_entity_ = canonical.bytes_per_entity_;
  shared_->AdoptFrom(*canonical.shared_, fixes);
}

}  // namespace edgephys
