#include "relay/join_stream.h"

#include <algorithm>

namespace edgephys {

JoinStream::JoinStream(const EntityTable& entities) {
  std::vector<std::pair<uint64_t, uint32_t>> order;
  order.reserve(entities.size());
  for (const auto& [id, e] : entities) order.emplace_back(e.spawn_seq, id);
  std::sort(order.begin(), order.end());
  ids_.reserve(order.size());
  for (const auto& [seq, id] : order) ids_.push_back(id);
}

bool JoinStream::Fits(const MemberLink& link, size_t bytes) const {
  const size_t capacity = link.ReliableCapacity();
  const size_t pending = link.ReliablePending();
  return pending == 0 || pending + bytes <= capacity / 2;
}

bool JoinStream::Pump(MemberLink& link, const EntityTable& entities) {
  while (next_ < ids_.size()) {
    auto it = entities.find(ids_[next_]);
    if (it == entities.end()) {  // despawned before its turn
      ++next_;
      continue;
    }
    if (!Fits(link, it->second.spawn.size())) return true;
    if (!link.SendReliable(it->second.spawn)) return false;
    ++next_;
    ++sent_;
  }
  while (!held_.empty()) {
    if (!Fits(link, held_.front().size())) return true;
    if (!link.SendReliable(held_.front())) return false;
    held_bytes_ -= held_.front().size();
    held_.pop_front();
  }
  return true;
}

}  // namespace edgephys
