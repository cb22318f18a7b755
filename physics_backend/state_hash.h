// Determinism check: a 64-bit FNV-1a hash over the bit patterns of every entity's transform,
// velocities and soft-body nodes, visited in ascending entity id. Two worlds fed the same
// containers and commands in the same order must hash equal after the same number of steps.
//
// Thread-safety: reads the world; call from the world's thread. Cost: O(n log n) in entities
// plus O(soft nodes); allocates scratch vectors. A diagnostic, not for the hot path.
#pragma once

#include <cstddef>
#include <cstdint>

namespace edgephys::physics {

class PhysicsWorld;

inline constexpr uint64_t kFnv1aOffset = 14695981039346656037ull;
inline constexpr uint64_t kFnv1aPrime = 1099511628211ull;

// FNV-1a over `size` bytes, continuing from `hash`.
uint64_t Fnv1a(const void* data, size_t size, uint64_t hash = kFnv1aOffset);

// Hash of all bodies' state: id, position, rotation (x, y, z, w), linear and angular velocity
// as float32 bit patterns (so -0.0 != 0.0 and any last-bit difference changes the hash).
uint64_t HashWorldState(const PhysicsWorld& world);

}  // namespace edgephys::physics
