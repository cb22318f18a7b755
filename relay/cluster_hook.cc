#include "relay/cluster_hook.h"

#include <spdlog/spdlog.h>

#include <tuple>

#include "protocol/redirect.h"
#include "relay/relay.h"

namespace edgephys {
namespace {

// A placement answer not received after this long is asked again.
constexpr double kPlacementRetryS = 1.0;

// The fields Entity and cluster::EntitySnapshot hold under one name and type, as references: all
// but the PhyS role (typed in Entity, a byte in the snapshot) and the two vectors (nodes, spawn),
// which ToSnapshot copies and FromSnapshot moves.
auto SharedFields(auto& x) {
  return std::tie(x.id, x.owner, x.creator, x.flags, x.held_by, x.spawn_seq, x.state,
                  x.linear_velocity, x.angular_velocity, x.authority_seq, x.former_owner,
                  x.takeover_allowed, x.on_owner_leave);
}

cluster::EntitySnapshot ToSnapshot(const Entity& e) {
  cluster::EntitySnapshot s;
  SharedFields(s) = SharedFields(e);
  s.physics_role = static_cast<uint8_t>(e.physics);
  s.nodes = e.nodes;
  s.spawn = e.spawn;
  return s;
}

Entity FromSnapshot(cluster::EntitySnapshot s) {
  Entity e;
  SharedFields(e) = SharedFields(s);
  e.physics = static_cast<PhysicsRole>(s.physics_role);
  e.state.entity_id = s.id;
  e.nodes = std::move(s.nodes);
  e.spawn = std::move(s.spawn);
  return e;
}

// Changes whenever anything a snapshot holds changes (entities' versions, members).
uint64_t Signature(const Room& room) {
  uint64_t sig = room.entities().size() * 1000003ull + room.size();
  for (const auto& [id, e] : room.entities()) {
    sig += (uint64_t{id} * 2654435761ull) ^ (uint64_t{e.version} << 20) ^ e.nodes_version ^
           (uint64_t{e.owner} << 40) ^ (uint64_t{e.authority_seq} << 8) ^
           (uint64_t{e.on_owner_leave} << 4) ^ (e.takeover_allowed ? 1ull << 36 : 0);
  }
  for (const auto& [pid, m] : room.members()) sig += uint64_t{pid} * 40503ull + m.slot;
  return sig;
}

}  // namespace

Result<std::unique_ptr<ClusterHook>> ClusterHook::Start(Relay* relay,
                                                        const ClusterOptions& options) {
  if (options.snapshot_interval_s <= 0) {
    return Status::InvalidArgument("snapshot interval must be > 0");
  }
  auto directory = cluster::Directory::Start(options.directory);
  if (!directory.ok()) return directory.status();
  return std::unique_ptr<ClusterHook>(new ClusterHook(relay, options, std::move(*directory)));
}

ClusterHook::ClusterHook(Relay* relay, const ClusterOptions& options,
                         std::unique_ptr<cluster::Directory> directory)
    : relay_(relay), options_(options), directory_(std::move(directory)) {}

ClusterHook::Route ClusterHook::RouteConnect(const JoinToken& token,
                                             std::span<const uint8_t> token_bytes,
                                             uint64_t unix_now_s, std::vector<uint8_t>* packet) {
  if ((token.permissions & kPermissionWorker) != 0) return Route::kLocal;  // PhyS workers
  auto view = directory_->view();
  // Asks for the room's placement (at most once per kPlacementRetryS) and defers the connect.
  const auto defer_for_placement = [&](bool prefer_self) {
    auto asked = asked_.find(token.room);
    if (asked == asked_.end() || relay_->now_ - asked->second > kPlacementRetryS) {
      asked_[token.room] = relay_->now_;
      directory_->RequestPlacement(token.room, prefer_self);
    }
    ++counters_.connects_deferred;
    return Route::kDeferred;
  };
  // Answers with a signed Redirect to `address`; `if_unsigned` when no ticket could be signed.
  const auto redirect_to = [&](const std::string& address, Route if_unsigned) {
    auto ticket = SignRedirect(token_bytes, token.session_secret, address,
                               unix_now_s + static_cast<uint64_t>(kRedirectLifetimeS));
    if (!ticket.ok()) return if_unsigned;
    *packet = BuildRedirectPacket(*ticket);
    ++counters_.redirects_sent;
    return Route::kRedirected;
  };
  if (relay_->rooms_.count(token.room) != 0 || local_fallback_.count(token.room) != 0) {
    // Held here: admitted only while no other live relay holds the room's lease (a copy that
    // lost it admits nobody; it is handed over in Update()).
    if (!view->healthy) return Route::kLocal;
    if (local_fallback_.count(token.room) != 0) return Route::kLocal;
    auto recorded = view->room_owner.find(token.room);
    if (recorded != view->room_owner.end() && recorded->second == directory_->relay_id()) {
      return Route::kLocal;  // ours
    }
    if (recorded == view->room_owner.end()) {
      // Held here but not (or no longer) recorded in Redis (a room created here, or its key
      // deleted or replaced by garbage): registered first (get-or-set, this relay preferred),
      // admitted once the view shows the lease.
      return defer_for_placement(/*prefer_self=*/true);
    }
    const cluster::RelayInfo* owner = view->OwnerOf(token.room);
    if (owner == nullptr) {  // the lease names another relay that is not live: wait
      ++counters_.connects_deferred;
      return Route::kDeferred;
    }
    return redirect_to(owner->address, Route::kDeferred);
  }
  if (!view->healthy) {
    ++counters_.local_fallbacks;
    return Route::kLocal;
  }
  auto owner = view->room_owner.find(token.room);
  if (owner != view->room_owner.end()) {
    if (owner->second == directory_->relay_id()) return Route::kLocal;
    auto relay = view->relays.find(owner->second);
    if (relay != view->relays.end()) return redirect_to(relay->second.address, Route::kLocal);
    // Owned by a relay that is gone (a live relay claims it on its next refresh), or alive
    // with an unusable entry: wait, never serve a second copy here.
    ++counters_.connects_deferred;
    return Route::kDeferred;
  }
  return defer_for_placement(/*prefer_self=*/false);
}

void ClusterHook::Update(double now, uint64_t unix_now_s) {
  for (cluster::DirectoryEvent& ev : directory_->TakeEvents()) {
    switch (ev.kind) {
      case cluster::DirectoryEvent::Kind::kPlaced:
        asked_.erase(ev.room);
        break;
      case cluster::DirectoryEvent::Kind::kPlacementFailed:
        asked_.erase(ev.room);
        // Redis unreachable: serve the room here. Garbage in its key with Redis up: keep
        // deferring (the next placement repairs the key), never a second copy.
        if (!directory_->view()->healthy) {
          local_fallback_.insert(ev.room);
          ++counters_.local_fallbacks;
        }
        break;
      case cluster::DirectoryEvent::Kind::kClaimed:
        Restore(ev, now);
        break;
    }
  }
  const cluster::DirectoryCounters& dc = directory_->counters();
  RelayCounters& rc = *relay_->counters_;
  rc.cluster_redis_errors.store(dc.redis_errors.load(std::memory_order_relaxed),
                                std::memory_order_relaxed);
  rc.cluster_bad_keys.store(dc.bad_keys.load(std::memory_order_relaxed) +
                                counters_.entities_skipped,
                            std::memory_order_relaxed);
  rc.cluster_redirects.store(counters_.redirects_sent, std::memory_order_relaxed);
  rc.cluster_rooms_restored.store(counters_.rooms_restored, std::memory_order_relaxed);
  HandOverLostRooms(now);
  // Rooms closed since the last update: no longer ours.
  std::set<std::string> rooms;
  for (const auto& [name, room] : relay_->rooms_) rooms.insert(name);
  for (const std::string& name : known_rooms_) {
    if (rooms.count(name) == 0) {
      directory_->Release(name);
      local_fallback_.erase(name);
      saved_sig_.erase(name);
    }
  }
  if (rooms != known_rooms_) directory_->SetLocalRooms(rooms);
  known_rooms_ = std::move(rooms);
  if (now >= next_snapshot_) {
    next_snapshot_ = now + options_.snapshot_interval_s;
    directory_->SetLoad(static_cast<uint32_t>(relay_->sessions_.size()),
                        static_cast<uint32_t>(relay_->rooms_.size()), false);
    SaveSnapshots(unix_now_s);
  }
}

void ClusterHook::HandOverLostRooms(double now) {
  auto view = directory_->view();
  if (!view->healthy) return;  // Redis unreachable: keep serving what we hold
  std::vector<std::pair<std::string, std::string>> lost;
  for (const auto& [name, host] : relay_->rooms_) {
    if (local_fallback_.count(name) != 0) continue;
    const cluster::RelayInfo* owner = view->OwnerOf(name);
    if (owner == nullptr || owner->id == directory_->relay_id()) {
      lost_since_.erase(name);
      continue;
    }
    // Another live relay holds the lease. Seen over two refreshes before acting, so one
    // stale read never drops a room.
    auto [it, fresh] = lost_since_.try_emplace(name, now);
    if (!fresh && now - it->second >= 2 * options_.directory.refresh_s) {
      lost.emplace_back(name, owner->id);
    }
  }
  for (const auto& [name, owner] : lost) {
    lost_since_.erase(name);
    ++counters_.rooms_handed_over;
    relay_->HandOverRoom(name, "the room moved to relay " + owner, now);
  }
}

void ClusterHook::SaveSnapshots(uint64_t unix_now_s) {
  auto view = directory_->view();
  for (const auto& [name, host] : relay_->rooms_) {
    const Room& room = host->room();
    auto owner = view->room_owner.find(name);
    if (view->healthy && owner == view->room_owner.end()) {
      // Created here (operator, fallback, or a join before the view knew it): register it.
      auto asked = asked_.find(name);
      if (asked == asked_.end() || relay_->now_ - asked->second > kPlacementRetryS) {
        asked_[name] = relay_->now_;
        directory_->RequestPlacement(name, /*prefer_self=*/true);
      }
    }
    // Only the lease holder writes (the write is also conditional in Redis).
    if (owner == view->room_owner.end() || owner->second != directory_->relay_id()) continue;
    uint64_t sig = Signature(room) + host->properties().changes() * 0x9E3779B97F4A7C15ull;
    auto saved = saved_sig_.find(name);
    if (saved != saved_sig_.end() && saved->second == sig) continue;
    saved_sig_[name] = sig;
    cluster::RoomSnapshot snap;
    snap.room = name;
    snap.written_unix_ms = unix_now_s * 1000;
    std::map<uint32_t, uint32_t> slots = room.reserved_slots();
    for (const auto& [pid, m] : room.members()) slots[pid] = m.slot;
    for (const auto& [pid, slot] : slots) snap.slots.push_back({pid, slot});
    snap.entities.reserve(room.entities().size());
    for (const auto& [id, e] : room.entities()) snap.entities.push_back(ToSnapshot(e));
    snap.properties.reserve(host->properties().count());
    for (const auto& [key, p] : host->properties().all()) {
      snap.properties.push_back(
          {key.first, key.second, p.value, p.authority, p.version, p.writer, p.owner, p.request_id});
    }
    directory_->SaveSnapshot(name, cluster::EncodeRoomSnapshot(snap));
    ++counters_.snapshots_saved;
  }
}

void ClusterHook::Restore(const cluster::DirectoryEvent& event, double now) {
  if (relay_->rooms_.count(event.room) != 0) {
    // The lease came back to the relay serving the room (its key was corrupted or named a
    // relay that is not live): the live copy is newer than any snapshot; keep it.
    lost_since_.erase(event.room);
    spdlog::warn("cluster: room '{}' lease taken back; the live copy is kept", event.room);
    return;
  }
  RoomHost& host = relay_->GetOrCreateRoom(event.room, now);
  std::vector<Entity> entities;
  std::map<uint32_t, uint32_t> slots;
  std::vector<std::pair<PropertyTable::Key, StoredProperty>> properties;
  if (event.has_snapshot) {
    cluster::RoomSnapshot snap = event.snapshot;
    for (const auto& s : snap.slots) slots[s.player_id] = s.slot;
    entities.reserve(snap.entities.size());
    for (auto& e : snap.entities) entities.push_back(FromSnapshot(std::move(e)));
    for (auto& p : snap.properties) {
      properties.emplace_back(PropertyTable::Key(p.entity_id, std::move(p.key)),
                              StoredProperty{std::move(p.value), p.version, p.writer, p.owner,
                                             p.authority, p.request_id});
    }
  }
  const size_t total = entities.size();
  const size_t skipped = host.Restore(std::move(entities), slots, now);
  const size_t properties_total = properties.size();
  const size_t properties_skipped = host.RestoreProperties(std::move(properties));
  ++counters_.rooms_restored;
  counters_.entities_restored += total - skipped;
  counters_.entities_skipped += skipped;
  spdlog::warn("cluster: room '{}' restored here ({} entities, {} skipped, {} properties, {} "
               "skipped, {} players expected)",
               event.room, total - skipped, skipped, properties_total - properties_skipped,
               properties_skipped, slots.size());
}

}  // namespace edgephys
