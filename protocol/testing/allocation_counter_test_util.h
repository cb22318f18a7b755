// Test-only: counts every operator new while `g_counting` is set, so steady-state "allocates
// nothing" promises can be asserted. Replaces the global operator new/delete (malloc/free
// based): include it in exactly ONE translation unit of a test binary.
#pragma once

#include <atomic>
#include <cstdlib>
#include <new>

// The replacement pair below is malloc/free based on purpose; GCC cannot see that they match.
#pragma GCC diagnostic ignored "-Wmismatched-new-delete"

namespace edgephys::testing_util {
inline std::atomic<bool> g_counting{false};
inline std::atomic<long> g_allocations{0};
}  // namespace edgephys::testing_util

void* operator new(std::size_t size) {
  if (edgephys::testing_util::g_counting.load(std::memory_order_relaxed)) {
    edgephys::testing_util::g_allocations.fetch_add(1);
  }
  if (void* p = std::malloc(size == 0 ? 1 : size)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
