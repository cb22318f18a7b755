#include "protocol/flat_id_map.h"

#include <gtest/gtest.h>

#include <random>
#include <unordered_map>

#include "protocol/types.h"

namespace edgephys {
namespace {

struct Value {
  uint32_t id = 0;
  uint64_t payload = 0;
};

// Random inserts, lookups and erases against std::unordered_map, with ids drawn from dense
// blocks (as entity ids are) and from the whole 32-bit range, including 0 and UINT32_MAX.
TEST(FlatIdMap, MatchesUnorderedMapUnderRandomOperations) {
  for (uint32_t seed = 1; seed <= 5; ++seed) {
    std::mt19937 rng(seed);
    FlatIdMap<Value> map;
    std::unordered_map<uint32_t, uint64_t> ref;
    auto draw = [&]() -> uint32_t {
      switch (rng() % 4) {
        case 0: return rng() % 64;                      // a dense block from 0
        case 1: return kEntityIdBlock + rng() % 512;    // another block (slot 1)
        case 2: return rng() % 2 ? 0u : 0xFFFFFFFFu;    // the extremes
        default: return static_cast<uint32_t>(rng());   // anywhere
      }
    };
    for (int op = 0; op < 50000; ++op) {
      const uint32_t id = draw();
      switch (rng() % 3) {
        case 0: {
          auto [v, inserted] = map.TryEmplace(id);
          const bool ref_inserted = ref.emplace(id, 0).second;
          ASSERT_EQ(inserted, ref_inserted);
          if (inserted) {
            EXPECT_EQ(v->payload, 0u);  // value-initialised, even in a reused slot
            v->id = id;
          }
          v->payload = rng();
          ref[id] = v->payload;
          break;
        }
        case 1: {
          const Value* v = map.Find(id);
          auto it = ref.find(id);
          ASSERT_EQ(v != nullptr, it != ref.end());
          if (v != nullptr) {
            EXPECT_EQ(v->id, id);
            EXPECT_EQ(v->payload, it->second);
          }
          break;
        }
        default:
          ASSERT_EQ(map.Erase(id), ref.erase(id) == 1);
          break;
      }
      ASSERT_EQ(map.size(), ref.size());
    }
    size_t visited = 0;
    map.ForEach([&](uint32_t id, Value& v) {
      ++visited;
      ASSERT_EQ(ref.count(id), 1u);
      EXPECT_EQ(v.payload, ref[id]);
    });
    EXPECT_EQ(visited, ref.size());
    map.Clear();
    EXPECT_TRUE(map.empty());
    EXPECT_EQ(map.Find(0), nullptr);
  }
}

}  // namespace
}  // namespace edgephys
