// Helpers shared by the application-message integration tests: tagged, sequenced payloads, a
// ClientListener base that records them and the errors a client is told of, and JoinAll.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <span>
#include <string_view>
#include <vector>

#include "client/client.h"
#include "edgephys/schema/control_generated.h"

namespace edgephys::testing {

// Payload: u8 tag (which stream), u32 sequence, then filler up to the wanted size (at least 5
// bytes): byte i is i * filler_step + seq, so a payload mixed with another one is caught.
inline std::vector<uint8_t> TaggedPayload(uint8_t tag, uint32_t seq, size_t size,
                                          uint8_t filler_step) {
  std::vector<uint8_t> p(std::max<size_t>(size, 5));
  p[0] = tag;
  std::memcpy(&p[1], &seq, 4);
  for (size_t i = 5; i < p.size(); ++i) p[i] = static_cast<uint8_t>(i * filler_step + seq);
  return p;
}

// Records the messages a subclass hands to Record (from OnMessage or OnUnreliableMessage) and
// every error reason; Stream checks payloads made by TaggedPayload with `filler_step`.
// Single-threaded: the simulated world calls it from its own loop.
struct MessageInbox : ClientListener {
  explicit MessageInbox(uint8_t step) : filler_step(step) {}
  uint8_t filler_step;
  struct Got {
    uint32_t sender;
    std::vector<uint8_t> payload;
  };
  std::vector<Got> got;
  std::vector<uint16_t> errors;
  void Record(uint32_t sender, std::span<const uint8_t> payload) {
    got.push_back({sender, {payload.begin(), payload.end()}});
  }
  void OnError(uint16_t reason, uint32_t, std::string_view) override { errors.push_back(reason); }
  // The sequences received from `sender` with `tag`, in arrival order; checks each payload's
  // filler.
  std::vector<uint32_t> Stream(uint32_t sender, uint8_t tag) const {
    std::vector<uint32_t> seqs;
    for (const Got& g : got) {
      if (g.sender != sender || g.payload.empty() || g.payload[0] != tag) continue;
      uint32_t seq = 0;
      std::memcpy(&seq, &g.payload[1], 4);
      EXPECT_EQ(g.payload, TaggedPayload(tag, seq, g.payload.size(), filler_step));
      seqs.push_back(seq);
    }
    return seqs;
  }
  size_t Count(schema::RejectReason reason) const {
    return std::count(errors.begin(), errors.end(), static_cast<uint16_t>(reason));
  }
};

}  // namespace edgephys::testing
