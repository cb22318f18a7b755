// Wrap-around-safe arithmetic on 16-bit sequence numbers (packet sequences, reliable unit ids).
// `a` is newer than `b` when it is ahead by less than half the sequence space (RFC 1982 style).
// Thread-safety: pure functions. Cost: O(1).
#pragma once

#include <cstdint>

namespace edgephys {

// Signed distance a - b in [-32768, 32767], correct across the wrap at 65535 -> 0.
constexpr int SequenceDiff(uint16_t a, uint16_t b) {
  return static_cast<int16_t>(static_cast<uint16_t>(a - b));
}

// True when `a` is newer than `b`.
constexpr bool SequenceGreater(uint16_t a, uint16_t b) { return SequenceDiff(a, b) > 0; }

static_assert(SequenceGreater(0, 65535));
static_assert(!SequenceGreater(65535, 0));
static_assert(SequenceGreater(100, 99));
static_assert(SequenceDiff(2, 65534) == 4);

}  // namespace edgephys
