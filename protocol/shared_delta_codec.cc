#include "protocol/shared_delta_codec.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "protocol/byte_io.h"
#include "protocol/delta_prediction.h"

namespace edgephys {
namespace {

using namespace delta_internal;  // NOLINT

constexpr int kMaxK = 7;
constexpr uint64_t kStatsSampleEvery = 4;
constexpr uint8_t kEmpty = 0, kBuilding = 1, kReady = 2;

bool TickAtOrBefore(uint32_t a, uint32_t b) { return static_cast<int32_t>(a - b) <= 0; }

}  // namespace

// ================================ Room ================================

const SharedEntity::Version* SharedEntity::At(uint32_t tick) const {
  const size_t size = versions_.size();
  const uint32_t held = static_cast<uint32_t>(std::min<size_t>(next_, size));
  // Ticks increase from the oldest held (logical 0) to the newest: binary search for the last
  // version prepared at or before `tick`.
  const uint64_t mask = size - 1;  // a power of two (SharedDeltaRoom's constructor)
  auto at = [&](uint32_t j) -> const Version& {
    return versions_[static_cast<size_t>((next_ - held + j) & mask)];
  };
  if (held == 0 || !TickAtOrBefore(at(0).tick, tick)) return nullptr;
  // Common cases in O(1): the newest version, or an entity that changed every tick since.
  const Version& newest = at(held - 1);
  if (TickAtOrBefore(newest.tick, tick)) return &newest;
  // At most one version per tick: the version `back` places before the newest is at or before
  // `tick`, so the answer lies from there on (few versions when the entity changed in most
  // ticks since).
  const uint32_t back = newest.tick - tick;  // > 0
  uint32_t lo = 0, hi = held - 1;  // at(lo) <= tick; at(hi) > tick
  if (back < held) {
    lo = held - 1 - back;
    if (at(lo).tick == tick) return &at(lo);
  }
  while (hi - lo > 1) {
    const uint32_t mid = lo + (hi - lo) / 2;
    if (TickAtOrBefore(at(mid).tick, tick)) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return &at(lo);
}

SharedDeltaRoom::SharedDeltaRoom(const QuantizationParams& params, size_t versions_per_entity)
    : q_(params),
      versions_per_entity_(std::bit_ceil(std::max<size_t>(versions_per_entity, 4))),
      tick_times_(kSharedTickWindow, 0) {}

bool SharedDeltaRoom::TickTime(uint32_t t, uint32_t* time_ms) const {
  const uint32_t age = tick_ - t;
  if (t == 0 || age >= kSharedTickWindow || age >= tick_) return false;
  *time_ms = tick_times_[t % kSharedTickWindow];
  return true;
}

void SharedDeltaRoom::ChooseParams() {
  for (int f = 0; f < 2; ++f) {
    double best = std::numeric_limits<double>::infinity();
    for (int o = 0; o < 3; ++o) {
      for (int k = 0; k <= kMaxK; ++k) {
        const double full = full_[f][o][k];
        const double masked = masked_[f][o][k];
        if (full <= 0 && masked <= 0) continue;  // no statistics yet
        if (full < best) {
          best = full;
          params_.order[f] = o;
          params_.k[f] = k;
          params_.mask[f] = false;
        }
        if (masked < best) {
          best = masked;
          params_.order[f] = o;
          params_.k[f] = k;
          params_.mask[f] = true;
        }
      }
    }
  }
}

void SharedDeltaRoom::BeginTick(uint32_t time_ms) {
  for (int f = 0; f < 2; ++f) {
    for (int o = 0; o < 3; ++o) {
      for (int k = 0; k <= kMaxK; ++k) {
        full_[f][o][k] = 0.5 * full_[f][o][k] + tick_full_[f][o][k];
        masked_[f][o][k] = 0.5 * masked_[f][o][k] + tick_masked_[f][o][k];
        tick_full_[f][o][k] = tick_masked_[f][o][k] = 0;
      }
    }
  }
  ChooseParams();
  ++tick_;
  if (tick_ == 0) ++tick_;  // 0 means "none" (wraps after ~2 years at 60 Hz)
  time_ms_ = time_ms;
  tick_times_[tick_ % kSharedTickWindow] = time_ms;
}

void SharedDeltaRoom::PrepareEntity(SharedEntity& e, const PreparedState& state) {
  e.room_ = this;
  if (e.serial_ == 0) e.BindSlot(auto_slots_++, ++auto_serials_);
  // Fold last tick's bodies into the statistics (weighted by their users) and empty the cache.
  for (SharedEntity::Slot& s : e.slots_) {
    if (s.state.load(std::memory_order_relaxed) == kReady && s.sampled) {
      const double w = s.uses.load(std::memory_order_relaxed);
      for (int o = 0; o < 3; ++o) {
        bool pos_zero = true, rot_zero = s.rot_same[o];
        for (int a = 0; a < 3; ++a) {
          pos_zero = pos_zero && s.pos_res[o][a] == 0;
          rot_zero = rot_zero && s.rot_res[o][a] == 0;
        }
        for (int k = 0; k <= kMaxK; ++k) {
          double pos_bits = 0, rot_bits = s.rot_same[o] ? 1 : 3;
          for (int a = 0; a < 3; ++a) {
            pos_bits += ExpGolombBits(ZigZag(s.pos_res[o][a]), k);
            rot_bits += ExpGolombBits(ZigZag(s.rot_res[o][a]), k);
          }
          tick_full_[0][o][k] += w * pos_bits;
          tick_full_[1][o][k] += w * rot_bits;
          tick_masked_[0][o][k] += w * (1 + (pos_zero ? 0 : pos_bits));
          tick_masked_[1][o][k] += w * (1 + (rot_zero ? 0 : rot_bits));
        }
      }
    }
    s.state.store(kEmpty, std::memory_order_relaxed);
    s.uses.store(0, std::memory_order_relaxed);
    s.sampled = false;
  }
  e.cache_tick_ = tick_;
  if (e.versions_.empty()) e.versions_.resize(versions_per_entity_);
  if (e.next_ == 0 || !(e.Newest().q == state.q)) {
    SharedEntity::Version& v = e.versions_[static_cast<size_t>(e.next_ % e.versions_.size())];
    v.tick = tick_;
    v.q = state.q;
    v.rot4 = state.rot4;
    if (state.has_float) {
      v.position = state.position;
      v.rotation = state.rotation;
    } else {
      v.position = DequantizePosition(q_, state.q.position);
      v.rotation = DequantizeRotation(q_, state.q.rotation);
    }
    ++e.next_;
  }
}

bool SharedDeltaRoom::Encode(const SharedEntity& e, const SharedBaselineKey& key,
                             SharedEntity::Slot* slot, uint8_t* out, size_t* nbits) const {
  if (e.next_ == 0) return false;
  BitWriter w({out, kSharedBodyMaxBytes});
  const QuantizedState& q = e.Newest().q;
  bool ok = true;
  if (key.depth == 0) {
    ok = WriteKeyframeState(w, q_, q);
    *nbits = w.bit_position();
    return ok;
  }
  History h;
  const uint32_t ticks[3] = {key.ref, key.s1, key.s2};
  for (int i = 0; i < 3; ++i) {
    const SharedEntity::Version* v = e.At(ticks[i]);
    uint32_t t_ms = 0;
    if (v == nullptr || !TickTime(ticks[i], &t_ms)) {
      stats_.missing_versions.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    h.s[i] = MakeSample(v->q, v->rot4, t_ms);
  }
  h.depth = std::min<uint8_t>(key.depth, 3);
  const bool sample =
      slot != nullptr &&
      stats_.encodes.load(std::memory_order_relaxed) % kStatsSampleEvery == 0;
  Residuals res;
  ComputeResiduals(q_, h, q, time_ms_, params_.order, sample, &res);
  if (sample) {
    slot->sampled = true;
    for (int o = 0; o < 3; ++o) {
      slot->rot_same[o] = res.rot_same[o];
      for (int a = 0; a < 3; ++a) {
        slot->pos_res[o][a] = res.pos[o][a];
        slot->rot_res[o][a] = res.rot[o][a];
      }
    }
  }
  DeltaBodyMarks marks;
  ok = ok && WriteDeltaBody(w, res, q, params_.k, params_.mask, params_.order, &marks);
  *nbits = w.bit_position();
  return ok;
}

bool SharedDeltaRoom::Body(SharedEntity& e, const SharedBaselineKey& key,
                           std::array<uint8_t, kSharedBodyMaxBytes>& scratch,
                           const uint8_t** bits, size_t* nbits, bool* hit) const {
  *hit = false;
  if (e.room_ != this || e.cache_tick_ != tick_) return false;
  for (SharedEntity::Slot& s : e.slots_) {
    uint8_t st = s.state.load(std::memory_order_acquire);
    if (st == kEmpty) {
      if (!s.state.compare_exchange_strong(st, kBuilding, std::memory_order_acq_rel)) {
        if (st != kReady) continue;  // another thread builds it (maybe our key): go on
      } else {
        size_t n = 0;
        s.sampled = false;
        if (!Encode(e, key, &s, s.body.data(), &n)) {
          s.state.store(kEmpty, std::memory_order_release);
          return false;
        }
        s.key = key;
        s.bits = static_cast<uint16_t>(n);
        s.uses.store(1, std::memory_order_relaxed);
        stats_.encodes.fetch_add(1, std::memory_order_relaxed);
        s.state.store(kReady, std::memory_order_release);
        *bits = s.body.data();
        *nbits = n;
        return true;
      }
    }
    if (st == kReady && s.key == key) {
      // Not a read-modify-write: concurrent users may lose a count (it only weights the
      // statistics), but the hot path takes no locked instruction.
      s.uses.store(s.uses.load(std::memory_order_relaxed) + 1, std::memory_order_relaxed);
      *hit = true;
      *bits = s.body.data();
      *nbits = s.bits;
      return true;
    }
  }
  size_t n = 0;
  if (!Encode(e, key, nullptr, scratch.data(), &n)) return false;
  stats_.uncached.fetch_add(1, std::memory_order_relaxed);
  *bits = scratch.data();
  *nbits = n;
  return true;
}

bool SharedDeltaRoom::HeldWithin(const SharedEntity& e, uint32_t ref_tick,
                                 const EntityState& truth, double pos2, double min_dot,
                                 double reach2, double lattice_min_dot) const {
  if (e.room_ != this) return false;
  const uint32_t age = tick_ - ref_tick;
  std::atomic<uint32_t>* memo =
      age < SharedEntity::kWithinAges ? &e.within_memo_[age] : nullptr;
  const uint32_t tag = tick_ << 2;
  if (memo != nullptr) {
    const uint32_t word = memo->load(std::memory_order_relaxed);
    if ((word & ~3u) == tag && (word & 3u) != 0) return (word & 3u) == 2;
  }
  const SharedEntity::Version* v = e.At(ref_tick);
  if (v == nullptr) return false;
  delta_internal::WithinThresholds within(q_, truth, pos2, min_dot, reach2, lattice_min_dot);
  const bool ok = within(*v);
  if (memo != nullptr) memo->store(tag | (ok ? 2u : 1u), std::memory_order_relaxed);
  return ok;
}

SharedDeltaDecoder::SharedDeltaDecoder(const QuantizationParams& params, size_t max_entities)
    : DeltaStreamDecoder({kSharedDeltaStateFormat, kSharedDeltaHeaderSize, 5, 4, 9,
                          "malformed format-9 state payload"},
                         params, max_entities) {}

}  // namespace edgephys
