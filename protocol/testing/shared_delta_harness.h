// Test-only harness for format 9's relay side (protocol/shared_delta_codec.h): one room, one
// receiver's stream and its decoder, ticked and sent by hand with injected time (16 ms ticks),
// acknowledgements given by the test (stream.OnPacketAcked). Used by shared_delta_slots_test.cc
// and shared_delta_acks_test.cc.
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <utility>
#include <vector>

#include "protocol/shared_delta_codec.h"

namespace edgephys::testing_util {

struct SharedDeltaHarness {
  QuantizationParams params = *MakeQuantizationParams(QuantizationConfig{});
  SharedDeltaRoom room{params};
  SharedDeltaStream stream{params};
  SharedDeltaDecoder decoder{params};
  uint16_t seq = 0;
  uint32_t time_ms = 0;
  std::vector<uint8_t> buf = std::vector<uint8_t>(1179);

  // A room tick: prepares each (entity, state).
  void Tick(const std::vector<std::pair<SharedEntity*, EntityState>>& entities) {
    time_ms += 16;
    room.BeginTick(time_ms);
    for (const auto& [e, s] : entities) room.PrepareEntity(*e, PrepareState(params, s));
  }
  // Encodes `ids` (increasing) in one payload; returns its sequence and bytes. `sent`: handed to
  // the connection (OnSent, taking the next sequence); a payload not sent gets sequence 0.
  std::pair<uint16_t, std::vector<uint8_t>> Send(
      const std::vector<std::pair<uint32_t, SharedEntity*>>& ids, bool sent = true) {
    stream.Begin(buf, time_ms);
    for (const auto& [id, e] : ids) EXPECT_TRUE(stream.Add(id, *e)) << id;
    const size_t n = stream.Finish();
    EXPECT_GT(n, 0u);
    uint16_t s = 0;
    if (sent) {
      s = seq++;
      stream.OnSent(s, time_ms / 1000.0);
    }
    return {s, std::vector<uint8_t>(buf.begin(), buf.begin() + static_cast<std::ptrdiff_t>(n))};
  }
  // Decodes `payload`; entity `id`'s state (a test failure if it is not in the payload).
  EntityState Decode(const std::vector<uint8_t>& payload, uint32_t id) {
    EntityState state{};
    (void)Decode(payload, id, &state);
    return state;
  }
  // Decodes `payload`; returns the reference distance (ticks) of entity `id`'s record, -1 for a
  // keyframe (-2 and a test failure if it is not in the payload), its state in *state.
  int64_t Decode(const std::vector<uint8_t>& payload, uint32_t id, EntityState* state) {
    StateBatch batch;
    EXPECT_TRUE(decoder.Decode(payload, &batch).ok());
    for (const EntityState& s : batch.states) {
      if (s.entity_id == id) *state = s;
    }
    for (const auto& r : decoder.last_references()) {
      if (r.id == id) return r.reference < 0 ? -1 : r.version - r.reference;
    }
    ADD_FAILURE() << "entity " << id << " not decoded";
    return -2;
  }
};

}  // namespace edgephys::testing_util
