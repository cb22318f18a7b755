// Latency matching for the load generator's bots: which publish a received pose is, and whose.
//
// Two pieces, both about not timing a pose against the wrong publish:
//   * RoomEntityKey: entity ids are per room (slot s of a room owns s * kEntityIdBlock + n,
//     protocol/types.h), so bots in the same slot of different rooms spawn the same ids. Any
//     load-generator map from an entity to its publisher must be keyed by (room, entity); keyed
//     by the id alone it sends a receiver to another room's publisher, whose history matches
//     a pose only by coincidence and then with a time seconds off.
//   * PoseHistory: one publisher's recent positions of one entity, with the time of each
//     publish; Match() names the publish a received position came from.
//
// Single-threaded (the bot thread); no allocation after construction.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "protocol/types.h"

namespace edgephys::loadgen {

// (room, entity) as one 64-bit map key: the room index in the high half.
inline constexpr uint64_t RoomEntityKey(uint32_t room, uint32_t entity) {
  return (static_cast<uint64_t>(room) << 32) | entity;
}

class PoseHistory {
 public:
  struct Publish {
    double t = 0;       // the publisher's clock at the publish (seconds; the caller's choice)
    double unix_s = 0;  // CLOCK_REALTIME at the publish (seconds)
    Vec3f position;
  };

  // Holds the last kCapacity distinct publishes (~2 s at 30 Hz).
  static constexpr size_t kCapacity = 64;
  // A received position is a publish's if within this distance (m) of it: the relay's 1 mm
  // lattice rounds each axis by up to 0.5 mm (0.87 mm in 3-D); ~1.22 mm.
  static constexpr float kMatchDistanceSq = 1.5e-6f;

  // Records a publish. A position bit-identical to the last recorded one is not recorded: it is
  // the same pose published again (a hand resting over a box), which the relay does not send
  // again, so its latency counts from the first publish of the run.
  void Add(const Publish& p);

  // The publish `received` came from: the newest recorded publish within kMatchDistanceSq of
  // it, or nullptr if none (too old, or never published by this publisher). Newest first: a
  // pose still in the ring from an earlier pass of the same path must not win over the
  // current one. The pointer is valid until the next Add().
  const Publish* Match(const Vec3f& received) const;

  size_t size() const { return count_ < kCapacity ? count_ : kCapacity; }

 private:
  std::array<Publish, kCapacity> ring_{};
  size_t count_ = 0;  // publishes recorded in all (the next goes to count_ % kCapacity)
};

}  // namespace edgephys::loadgen
