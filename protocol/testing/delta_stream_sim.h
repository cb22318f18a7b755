// Shared by the format-2 codec tests: a smooth test motion and a stream simulator
// (encoder -> loss, delay and reordering -> decoder, acknowledgements back with a delay) that
// measures bytes and the decoded error against the truth. Test-only; header-only.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cmath>
#include <deque>
#include <map>
#include <random>
#include <vector>

#include "protocol/byte_io.h"
#include "protocol/connection.h"
#include "protocol/delta_codec.h"
#include "protocol/testing/codec_test_util.h"

namespace edgephys::testing_util {

inline constexpr double kPi = 3.14159265358979323846;
inline constexpr size_t kPacketOverhead = 18 + 3;  // connection header + unreliable chunk header

// ---------------------------------------------------------------------------------------------
// Test motion: smooth paths at a given speed, spinning about a slowly varying axis. Two
// families (integrated wandering heading; Lissajous), parameters drawn from the seed.
class TestMotion {
 public:
  TestMotion(uint64_t seed, uint32_t index, double speed, double spin_dps, int family)
      : family_(family), speed_(speed) {
    std::mt19937_64 rng(seed * 7919 + index);
    std::uniform_real_distribution<double> u(0, 1);
    pos_[0] = (index % 16) * 4.0 - 30;
    pos_[1] = 1.0 + u(rng);
    pos_[2] = (index / 16) * 4.0 - 30;
    heading_ = 2 * kPi * u(rng);
    turn_amp_ = 0.3 + 0.9 * u(rng);  // rad/s: radius of curvature down to ~1.25 m at 1.5 m/s
    turn_freq_ = 0.2 + 0.6 * u(rng);
    turn_phase_ = 2 * kPi * u(rng);
    climb_phase_ = 2 * kPi * u(rng);
    for (int i = 0; i < 3; ++i) lis_w_[i] = 0.6 + 0.8 * u(rng), lis_p_[i] = 2 * kPi * u(rng);
    const double n = std::sqrt(
        (lis_w_[0] * lis_w_[0] + 0.25 * lis_w_[1] * lis_w_[1] + lis_w_[2] * lis_w_[2]) / 2.0);
    lis_a_ = speed / n;
    spin_ = spin_dps * kPi / 180.0;
    axis_tilt_ = 0.3 + 1.0 * u(rng);
    axis_rate_ = 0.1 + 0.4 * u(rng);
    axis_phase_ = 2 * kPi * u(rng);
    std::normal_distribution<double> nd;
    double q[4] = {nd(rng), nd(rng), nd(rng), nd(rng)};
    const double qn = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (int i = 0; i < 4; ++i) q_[i] = q[i] / qn;
    origin_[0] = pos_[0], origin_[1] = pos_[1], origin_[2] = pos_[2];
  }

  // Advances (1 ms integration steps) to `t` seconds and returns the truth.
  EntityState AdvanceTo(double t) {
    while (t_ + 1e-9 < t) {
      const double dt = std::min(0.001, t - t_);
      Step(dt);
    }
    EntityState s;
    if (family_ == 1) {
      s.position = {
          static_cast<float>(origin_[0] + lis_a_ * std::sin(lis_w_[0] * t + lis_p_[0])),
          static_cast<float>(origin_[1] + 0.5 * lis_a_ * std::sin(lis_w_[1] * t + lis_p_[1])),
          static_cast<float>(origin_[2] + lis_a_ * std::sin(lis_w_[2] * t + lis_p_[2]))};
    } else {
      s.position = {static_cast<float>(pos_[0]), static_cast<float>(pos_[1]),
                    static_cast<float>(pos_[2])};
    }
    s.rotation = {static_cast<float>(q_[0]), static_cast<float>(q_[1]), static_cast<float>(q_[2]),
                  static_cast<float>(q_[3])};
    return s;
  }

  void Teleport(double dx) { pos_[0] += dx, origin_[0] += dx; }

 private:
  void Step(double dt) {
    const double tm = t_ + dt / 2;
    // Wandering heading at constant speed, gentle climb.
    const double turn = turn_amp_ * std::sin(turn_freq_ * tm + turn_phase_);
    const double climb = 0.15 * std::sin(0.5 * tm + climb_phase_);
    const double dir[3] = {std::cos(heading_ + turn * dt / 2) * std::cos(climb), std::sin(climb),
                           std::sin(heading_ + turn * dt / 2) * std::cos(climb)};
    for (int i = 0; i < 3; ++i) pos_[i] += speed_ * dt * dir[i];
    heading_ += turn * dt;
    // Spin about an axis precessing slowly around +y.
    const double th = axis_phase_ + axis_rate_ * tm;
    const double ax[3] = {std::sin(axis_tilt_) * std::cos(th), std::cos(axis_tilt_),
                          std::sin(axis_tilt_) * std::sin(th)};
    const double half = spin_ * dt / 2, s = std::sin(half), c = std::cos(half);
    const double d[4] = {ax[0] * s, ax[1] * s, ax[2] * s, c};
    // q = d * q (world-frame angular velocity)
    const double x = d[3] * q_[0] + d[0] * q_[3] + d[1] * q_[2] - d[2] * q_[1];
    const double y = d[3] * q_[1] - d[0] * q_[2] + d[1] * q_[3] + d[2] * q_[0];
    const double z = d[3] * q_[2] + d[0] * q_[1] - d[1] * q_[0] + d[2] * q_[3];
    const double w = d[3] * q_[3] - d[0] * q_[0] - d[1] * q_[1] - d[2] * q_[2];
    const double n = std::sqrt(x * x + y * y + z * z + w * w);
    q_[0] = x / n, q_[1] = y / n, q_[2] = z / n, q_[3] = w / n;
    t_ += dt;
  }

  int family_;
  double speed_;
  double t_ = 0;
  double pos_[3], origin_[3];
  double heading_, turn_amp_, turn_freq_, turn_phase_, climb_phase_;
  double lis_w_[3], lis_p_[3], lis_a_;
  double spin_, axis_tilt_, axis_rate_, axis_phase_;
  double q_[4];
};

// ---------------------------------------------------------------------------------------------
// Stream simulator: encoder -> (loss, delay/reordering) -> decoder, acks back with delay.
struct SimConfig {
  int entities = 64;
  int ticks = 240;
  double tick_hz = 12;
  double loss = 0;
  int max_extra_delay_ticks = 0;  // each packet arrives 0..this many ticks late (reordering)
  int ack_delay_ticks = 1;        // acks reach the encoder this many ticks after arrival
  double ack_loss = 0;            // an arrived packet's ack is never reported
  bool drop_stale = false;        // emulate Connection's sequenced channel (drops old payloads)
  uint64_t seed = 1;
  int family = 0;  // motion family; -1 alternates per entity
  double speed = 1.5, spin_dps = 90;
  QuantizationConfig quant;
  DeltaEncoderOptions options;
  int freeze_after_tick = -1;         // truth stops changing from this tick on
  int lossless_after_tick = 1 << 30;  // network becomes perfect and in order from this tick on
  bool check_references = true;
  // < 1: each entity goes in a tick with this probability (irregular gaps between an entity's
  // versions, as a bandwidth budget or selective sync makes them); the lossless ticks still send
  // every entity.
  double send_probability = 1;
};

// The network the convergence tests share: 150 entities over 400 ticks at 48 Hz, 20 % loss,
// up to 3 ticks of reordering, acks 2 ticks late and 10 % of them lost, alternating motions;
// the truth freezes at tick 300 and the network is perfect from 340 (so a converged stream can
// be checked).
inline SimConfig LossyReorderedSim(uint64_t seed) {
  SimConfig c;
  c.seed = seed;
  c.entities = 150;
  c.ticks = 400;
  c.tick_hz = 48;
  c.loss = 0.2;
  c.max_extra_delay_ticks = 3;
  c.ack_delay_ticks = 2;
  c.ack_loss = 0.1;
  c.family = -1;
  c.freeze_after_tick = 300;
  c.lossless_after_tick = 340;
  return c;
}

// Irregular sends (each entity in a tick with probability `send_probability`): 120 entities over 300 ticks at 60 Hz, lossless, alternating motions, a 0.5 mm lattice
// for even seeds and 1 mm for odd ones; the truth freezes at tick 250, every entity is sent
// from 260.
inline SimConfig IrregularSendsSim(uint64_t seed, double send_probability) {
  SimConfig c;
  c.seed = seed;
  c.entities = 120;
  c.ticks = 300;
  c.tick_hz = 60;
  c.send_probability = send_probability;
  c.family = -1;
  c.freeze_after_tick = 250;
  c.lossless_after_tick = 260;
  c.quant.position_step_m = seed % 2 == 0 ? 0.0005f : 0.001f;
  return c;
}

struct SimResult {
  uint64_t bytes = 0, updates = 0, packets = 0, outputs = 0;
  double max_pos_err = 0, max_rot_err = 0;
  uint64_t bad_references = 0;
  DeltaEncoderStats enc;
  DeltaDecoderStats dec;
  bool converged = false;
  double BytesPerUpdate() const { return static_cast<double>(bytes) / updates; }
};

inline SimResult RunStream(const SimConfig& c) {
  SimResult res;
  auto params = MakeQuantizationParams(c.quant);
  EXPECT_TRUE(params.ok());
  DeltaEncoder enc(*params, c.options);
  DeltaDecoder dec(*params);
  std::mt19937_64 rng(c.seed * 31 + 5);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<TestMotion> motions;
  for (int i = 0; i < c.entities; ++i) {
    motions.emplace_back(c.seed, i, c.speed, c.spin_dps, c.family < 0 ? i % 2 : c.family);
  }
  struct Sent {
    std::vector<uint8_t> payload;
    std::vector<EntityState> truth;  // sorted by id
    uint16_t seq;
    int64_t encode_event;
    int64_t ack_event = -1;
  };
  std::map<int64_t, Sent> sent;  // by encoder counter (= payload index)
  struct InFlight {
    int arrive_tick;
    double order;
    int64_t counter;
  };
  std::vector<InFlight> network;
  struct PendingAck {
    int tick;
    uint16_t seq;
    int64_t counter;
  };
  std::deque<PendingAck> acks;
  int64_t event = 0;
  int64_t next_counter = 0;
  uint16_t next_seq = 100;
  int64_t highest_delivered = -1;
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  std::vector<EntityState> truth(c.entities);
  std::vector<EntityState> last_output(c.entities);
  std::vector<bool> have_output(c.entities, false);
  StateBatch batch;
  int64_t counter_base = -1;

  for (int tick = 0; tick < c.ticks; ++tick) {
    const uint32_t time_ms = static_cast<uint32_t>(std::lround(tick * 1000.0 / c.tick_hz));
    const double now = time_ms / 1000.0;
    const bool lossless = tick >= c.lossless_after_tick;
    // Acks due now.
    while (!acks.empty() && acks.front().tick <= tick) {
      enc.OnPacketAcked(acks.front().seq);
      sent[acks.front().counter].ack_event = event++;
      acks.pop_front();
    }
    if (c.freeze_after_tick < 0 || tick < c.freeze_after_tick) {
      for (int i = 0; i < c.entities; ++i) {
        truth[i] = motions[i].AdvanceTo(now);
        truth[i].entity_id = static_cast<uint32_t>(i * 3 + 1);  // sparse ids
      }
    }
    // Encode all entities, as many payloads as needed.
    auto send = [&](size_t size) {
      if (size == 0) return;
      const int64_t counter = next_counter++;
      Sent& s = sent[counter];
      s.payload.assign(buf.begin(), buf.begin() + static_cast<long>(size));
      s.seq = next_seq++;
      s.encode_event = event++;
      enc.OnSent(s.seq, now);
      res.bytes += size + kPacketOverhead;
      ++res.packets;
      if (!lossless && u(rng) < c.loss) return;
      const int delay = lossless ? 0 : static_cast<int>(rng() % (c.max_extra_delay_ticks + 1));
      network.push_back({tick + delay, u(rng), counter});
    };
    std::vector<EntityState> in_payload;
    enc.Begin(buf, time_ms);
    for (int i = 0; i < c.entities; ++i) {
      if (c.send_probability < 1 && !lossless && u(rng) >= c.send_probability) continue;
      const EntityState& state = truth[i];
      auto add = [&] { return enc.Add(state); };
      if (!add()) {
        EXPECT_GT(enc.count(), 0u);
        const size_t size = enc.Finish();
        EXPECT_LE(size, kMaxUnreliablePayload);
        send(size);
        sent[next_counter - 1].truth = in_payload;
        in_payload.clear();
        enc.Begin(buf, time_ms);
        EXPECT_TRUE(add());
      }
      in_payload.push_back(state);
      ++res.updates;
    }
    const size_t last = enc.Finish();
    send(last);
    if (last > 0) {
      sent[next_counter - 1].truth = in_payload;
    }

    // Deliver what arrives this tick, in a random order among them (reordering).
    std::vector<InFlight> arriving;
    for (auto it = network.begin(); it != network.end();) {
      if (it->arrive_tick <= tick) {
        arriving.push_back(*it);
        it = network.erase(it);
      } else {
        ++it;
      }
    }
    std::sort(arriving.begin(), arriving.end(), [&](const InFlight& a, const InFlight& b) {
      return lossless ? a.counter < b.counter : a.order < b.order;
    });
    for (const InFlight& a : arriving) {
      Sent& s = sent[a.counter];
      if (lossless || u(rng) >= c.ack_loss) {
        acks.push_back({tick + c.ack_delay_ticks, s.seq, a.counter});
      }
      if (c.drop_stale && a.counter <= highest_delivered) continue;  // acked but dropped
      highest_delivered = std::max(highest_delivered, a.counter);
      batch.states.clear();
      Status st = dec.Decode(s.payload, &batch);
      EXPECT_TRUE(st.ok());
      if (counter_base < 0) counter_base = (int64_t{1} << 20) + (a.counter & 0xffff) - a.counter;
      for (const auto& ref : dec.last_references()) {
        if (ref.reference < 0 || !c.check_references) continue;
        const Sent& base = sent[ref.reference - counter_base];
        const Sent& cur = sent[ref.version - counter_base];
        if (base.ack_event < 0 || base.ack_event > cur.encode_event) ++res.bad_references;
      }
      for (size_t j = 0; j < batch.states.size(); ++j) {
        const EntityState& out = batch.states[j];
        auto t =
            std::lower_bound(s.truth.begin(), s.truth.end(), out.entity_id,
                             [](const EntityState& e, uint32_t id) { return e.entity_id < id; });
        EXPECT_TRUE(t != s.truth.end() && t->entity_id == out.entity_id);
        if (t == s.truth.end()) continue;
        res.max_pos_err = std::max(res.max_pos_err, PositionError(out.position, t->position));
        res.max_rot_err = std::max(res.max_rot_err, RotationErrorDeg(out.rotation, t->rotation));
        const size_t idx = (out.entity_id - 1) / 3;
        last_output[idx] = out;
        have_output[idx] = true;
        ++res.outputs;
      }
    }
    // Keep memory bounded: forget payloads far in the past.
    while (!sent.empty() && sent.begin()->first + 20000 < next_counter) sent.erase(sent.begin());
  }
  // Converged: the last output of every entity equals the quantised final truth.
  res.converged = true;
  for (int i = 0; i < c.entities; ++i) {
    QuantizedState q;
    QuantizeState(*params, truth[i], &q);
    const Vec3f p = DequantizePosition(*params, q.position);
    const Quatf r = DequantizeRotation(*params, q.rotation);
    if (!have_output[i] || last_output[i].position.x != p.x || last_output[i].position.y != p.y ||
        last_output[i].position.z != p.z || last_output[i].rotation.x != r.x ||
        last_output[i].rotation.w != r.w) {
      res.converged = false;
    }
  }
  res.enc = enc.stats();
  res.dec = dec.stats();
  return res;
}

inline void ExpectWithinBounds(const SimResult& r, const QuantizationConfig& q) {
  EXPECT_LE(r.max_pos_err, q.position_step_m * std::sqrt(3.0) / 2 + FloatSlack(100));
  EXPECT_LE(r.max_rot_err, q.rotation_error_deg);
}

// A lossy, reordering run (SimConfig with loss and reordering, then lossless): prints its
// figures, and expects the bounds held, no reference went wrong or unresolved, nothing was
// malformed, reordering did make payloads stale, and the receiver converged at the end.
inline void ExpectConvergedUnderLoss(const SimResult& r, const QuantizationConfig& q,
                                     uint64_t seed) {
  std::printf("seed %llu: %.2f bytes/update, max err %.3f mm %.4f deg, keyframes %llu\n",
              static_cast<unsigned long long>(seed), r.BytesPerUpdate(), r.max_pos_err * 1e3,
              r.max_rot_err, static_cast<unsigned long long>(r.enc.keyframes));
  ExpectWithinBounds(r, q);
  EXPECT_EQ(r.bad_references, 0u);
  EXPECT_EQ(r.dec.unresolved_references, 0u);
  EXPECT_EQ(r.dec.malformed, 0u);
  EXPECT_GT(r.dec.stale_skipped, 0u);  // reordering did happen
  EXPECT_TRUE(r.converged);
}

// ---------------------------------------------------------------------------------------------


}  // namespace edgephys::testing_util
