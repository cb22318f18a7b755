// FlatIdMap<T>: a map from 32-bit ids (entity ids) to T, for the per-receiver hot paths of the
// relay (the delta encoder's per-entity tracks, the replicator's per-entity views).
//
// Why not std::unordered_map: a lookup there walks bucket -> node -> value, two or three
// dependent cache misses, and the relay does several lookups per entity per receiver per tick.
// Here the ids sit in a small open-addressing table of (id, slot) pairs (linear probing,
// power-of-two capacity, at most half full), and the values in a vector indexed by slot: one
// miss for the probe (the table is compact) and one for the value.
//
// Contract:
//  * Find / TryEmplace / Erase are O(1) on average. TryEmplace value-initialises a new T.
//  * Pointers and references to values stay valid until the next TryEmplace that inserts (the
//    value vector may grow) or Clear; Erase invalidates only the erased value's.
//  * Erased slots are reused; erased table entries become tombstones, and the table is rebuilt
//    (allocating) once tombstones and live ids together pass half its capacity. Inserting and
//    erasing the same ids over and over therefore allocates only now and then, and a map whose
//    set of ids does not change never allocates.
//  * Iteration: ForEach(f) calls f(id, value) for every live entry, in no particular order.
// Thread-safety: none (one owner thread).
#pragma once

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace edgephys {

template <typename T>
class FlatIdMap {
 public:
  FlatIdMap() = default;

  // The value for `id`, or nullptr.
  T* Find(uint32_t id) {
    const int32_t s = SlotOf(id);
    return s < 0 ? nullptr : &values_[static_cast<size_t>(s)];
  }
  const T* Find(uint32_t id) const {
    const int32_t s = SlotOf(id);
    return s < 0 ? nullptr : &values_[static_cast<size_t>(s)];
  }

  // The value for `id` (inserted, value-initialised, if absent) and whether it was inserted.
  std::pair<T*, bool> TryEmplace(uint32_t id) {
    if (const int32_t s = SlotOf(id); s >= 0) return {&values_[static_cast<size_t>(s)], false};
    if ((size_ + tombstones_ + 1) * 2 > table_.size()) Rehash();
    int32_t slot;
    if (!free_.empty()) {
      slot = free_.back();
      free_.pop_back();
      values_[static_cast<size_t>(slot)] = T{};
    } else {
      slot = static_cast<int32_t>(values_.size());
      values_.emplace_back();
    }
    size_t i = Hash(id) & mask_;
    while (table_[i].slot >= 0) i = (i + 1) & mask_;  // empty or tombstone
    if (table_[i].slot == kTombstone) --tombstones_;
    table_[i] = {id, slot};
    ++size_;
    return {&values_[static_cast<size_t>(slot)], true};
  }

  T& operator[](uint32_t id) { return *TryEmplace(id).first; }

  // Removes `id`; false if absent.
  bool Erase(uint32_t id) {
    if (table_.empty()) return false;
    for (size_t i = Hash(id) & mask_;; i = (i + 1) & mask_) {
      Cell& c = table_[i];
      if (c.slot == kEmpty) return false;
      if (c.slot >= 0 && c.id == id) {
        values_[static_cast<size_t>(c.slot)] = T{};  // release what the value holds
        free_.push_back(c.slot);
        c.slot = kTombstone;
        --size_;
        ++tombstones_;
        return true;
      }
    }
  }

  void Clear() {
    table_.clear();
    values_.clear();
    free_.clear();
    size_ = tombstones_ = 0;
    mask_ = 0;
  }

  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }

  template <typename F>
  void ForEach(F&& f) {
    for (const Cell& c : table_) {
      if (c.slot >= 0) f(c.id, values_[static_cast<size_t>(c.slot)]);
    }
  }

 private:
  static constexpr int32_t kEmpty = -1;
  static constexpr int32_t kTombstone = -2;
  struct Cell {
    uint32_t id = 0;
    int32_t slot = kEmpty;
  };

  static size_t Hash(uint32_t id) {
    // Entity ids come in dense blocks; a multiplicative hash spreads them over the table.
    return static_cast<size_t>((static_cast<uint64_t>(id) * 0x9E3779B97F4A7C15ull) >> 32);
  }

  int32_t SlotOf(uint32_t id) const {
    if (size_ == 0) return -1;
    for (size_t i = Hash(id) & mask_;; i = (i + 1) & mask_) {
      const Cell& c = table_[i];
      if (c.slot == kEmpty) return -1;
      if (c.slot >= 0 && c.id == id) return c.slot;
    }
  }

  void Rehash() {
    size_t capacity = 16;
    while (capacity < (size_ + 1) * 4) capacity *= 2;  // at most a quarter full after
    std::vector<Cell> old = std::move(table_);
    table_.assign(capacity, Cell{});
    mask_ = capacity - 1;
    tombstones_ = 0;
    for (const Cell& c : old) {
      if (c.slot < 0) continue;
      size_t i = Hash(c.id) & mask_;
      while (table_[i].slot != kEmpty) i = (i + 1) & mask_;
      table_[i] = c;
    }
  }

  std::vector<Cell> table_;
  std::vector<T> values_;
  std::vector<int32_t> free_;
  size_t size_ = 0;
  size_t tombstones_ = 0;
  size_t mask_ = 0;
};

}  // namespace edgephys
