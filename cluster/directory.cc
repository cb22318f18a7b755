#include "cluster/directory.h"

#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

#include "cluster/redis_client.h"

namespace edgephys::cluster {
namespace {

using Clock = std::chrono::steady_clock;

double Seconds(Clock::time_point t) {
  return std::chrono::duration<double>(t.time_since_epoch()).count();
}

// get-or-set: KEYS[1] room key, KEYS[2] rooms set; ARGV[1] relay id, ARGV[2] room name.
constexpr const char* kPlaceScript =
    "local t = redis.call('TYPE', KEYS[1]).ok "
    "if t ~= 'none' and t ~= 'string' then redis.call('DEL', KEYS[1]) end "
    "local o = redis.call('GET', KEYS[1]) "
    "if o then return o end "
    "redis.call('SET', KEYS[1], ARGV[1]) "
    "redis.call('SADD', KEYS[2], ARGV[2]) "
    "return ARGV[1]";
// write-if-mine: KEYS[1] room key, KEYS[2] state key; ARGV[1] relay id, ARGV[2] snapshot. A
// relay that lost its room (another claimed it) never overwrites the new owner's state.
constexpr const char* kSaveScript =
    "if redis.call('GET', KEYS[1]) == ARGV[1] then "
    "redis.call('SET', KEYS[2], ARGV[2]) return 1 end "
    "return 0";
// compare-and-set: KEYS[1] room key; ARGV[1] expected owner, ARGV[2] new owner.
constexpr const char* kClaimScript =
    "if redis.call('GET', KEYS[1]) == ARGV[1] then "
    "redis.call('SET', KEYS[1], ARGV[2]) return 1 end "
    "return 0";
// delete-if-mine: KEYS[1] room key, KEYS[2] rooms set, KEYS[3] state key; ARGV[1] relay id,
// ARGV[2] room name.
constexpr const char* kReleaseScript =
    "if redis.call('GET', KEYS[1]) == ARGV[1] then "
    "redis.call('DEL', KEYS[1], KEYS[3]) redis.call('SREM', KEYS[2], ARGV[2]) return 1 end "
    "return 0";

uint64_t Fnv1a(const std::string& s) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : s) h = (h ^ c) * 1099511628211ull;
  return h;
}

bool ValidId(const std::string& id) {
  if (id.empty() || id.size() > 64) return false;
  return std::all_of(id.begin(), id.end(), [](char c) { return c > ' ' && c != ':' && c < 127; });
}

// host:port or [v6]:port with a port in 1..65535 and a host of printable characters.
bool ValidAddress(const std::string& address) {
  const size_t colon = address.rfind(':');
  if (colon == std::string::npos || colon == 0 || colon + 1 >= address.size() ||
      address.size() > 255) {
    return false;
  }
  const std::string port = address.substr(colon + 1);
  if (port.size() > 5 || !std::all_of(port.begin(), port.end(), [](char c) {
        return c >= '0' && c <= '9';
      })) {
    return false;
  }
  const int number = std::stoi(port);
  if (number < 1 || number > 65535) return false;
  return std::all_of(address.begin(), address.begin() + static_cast<long>(colon),
                     [](char c) { return c > ' ' && c < 127; });
}

}  // namespace

const RelayInfo* DirectoryView::OwnerOf(const std::string& room) const {
  auto it = room_owner.find(room);
  if (it == room_owner.end()) return nullptr;
  auto r = relays.find(it->second);
  return r == relays.end() ? nullptr : &r->second;
}

Result<std::unique_ptr<Directory>> Directory::Start(const DirectoryOptions& options) {
  if (!ValidId(options.relay_id)) return Status::InvalidArgument("bad relay id");
  if (options.public_address.empty()) return Status::InvalidArgument("no public address");
  if (options.heartbeat_s <= 0 || options.ttl_s <= options.heartbeat_s ||
      options.refresh_s <= 0 || options.redis_timeout_s <= 0) {
    return Status::InvalidArgument("heartbeat must be > 0 and < ttl; refresh, timeout > 0");
  }
  std::unique_ptr<Directory> d(new Directory(options));
  d->thread_ = std::thread([p = d.get()] { p->Run(); });
  return d;
}

Directory::Directory(const DirectoryOptions& options)
    : options_(options),
      redis_(std::make_unique<RedisClient>(options.redis_host, options.redis_port,
                                           options.redis_timeout_s)),
      view_(std::make_shared<DirectoryView>()) {}

Directory::~Directory() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    stop_ = true;
  }
  wake_.notify_all();
  if (thread_.joinable()) thread_.join();
}

std::string Directory::Key(const char* kind, const std::string& name) const {
  return options_.key_prefix + kind + name;
}

void Directory::SetLoad(uint32_t users, uint32_t rooms, bool draining) {
  std::lock_guard<std::mutex> lock(mu_);
  users_ = users, rooms_ = rooms, draining_ = draining;
}

void Directory::RequestPlacement(const std::string& room, bool prefer_self) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (!placement_pending_.insert(room).second) return;
    placement_requests_[room] = prefer_self;
  }
  wake_.notify_all();
}

void Directory::SaveSnapshot(const std::string& room, std::vector<uint8_t> bytes) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    snapshots_[room] = std::move(bytes);
  }
  wake_.notify_all();
}

void Directory::Release(const std::string& room) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    snapshots_.erase(room);
    releases_.push_back(room);
  }
  wake_.notify_all();
}

std::vector<DirectoryEvent> Directory::TakeEvents() {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<DirectoryEvent> out;
  out.swap(events_);
  return out;
}

std::shared_ptr<const DirectoryView> Directory::view() const {
  std::lock_guard<std::mutex> lock(mu_);
  return view_;
}

void Directory::Post(DirectoryEvent event) {
  std::lock_guard<std::mutex> lock(mu_);
  if (event.kind != DirectoryEvent::Kind::kClaimed) placement_pending_.erase(event.room);
  events_.push_back(std::move(event));
}

void Directory::Run() {
  Clock::time_point next_heartbeat = Clock::now();
  Clock::time_point next_refresh = Clock::now();
  const auto heartbeat = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(options_.heartbeat_s));
  const auto refresh = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(options_.refresh_s));
  for (;;) {
    {
      std::unique_lock<std::mutex> lock(mu_);
      wake_.wait_until(lock, std::min(next_heartbeat, next_refresh), [&] {
        return stop_ || !placement_requests_.empty() || !snapshots_.empty() ||
               !releases_.empty();
      });
      if (stop_) break;
    }
    Clock::time_point now = Clock::now();
    if (now >= next_heartbeat) {
      Heartbeat();
      next_heartbeat = now + heartbeat;
    }
    if (now >= next_refresh) {
      Refresh();
      next_refresh = Clock::now() + refresh;
    }
    std::map<std::string, bool> placements;
    std::vector<std::string> releases;
    {
      std::lock_guard<std::mutex> lock(mu_);
      placements.swap(placement_requests_);
      releases.swap(releases_);
    }
    for (const auto& [room, prefer_self] : placements) DoPlacement(room, prefer_self);
    for (const std::string& room : releases) DoRelease(room);
    FlushSnapshots();
  }
  // A clean stop: leave the cluster at once rather than at the TTL. Rooms stay owned by this
  // id, so another relay claims them (and their snapshots) on its next refresh.
  (void)redis_->Pipeline({{"DEL", Key("relay:", options_.relay_id)},
                          {"SREM", options_.key_prefix + "relays", options_.relay_id}});
}

void Directory::Heartbeat() {
  nlohmann::json info;
  {
    std::lock_guard<std::mutex> lock(mu_);
    info = {{"address", options_.public_address},
            {"users", users_},
            {"rooms", rooms_},
            {"draining", draining_}};
  }
  auto ttl_ms = std::to_string(static_cast<int64_t>(options_.ttl_s * 1000));
  auto replies = redis_->Pipeline({{"SET", Key("relay:", options_.relay_id), info.dump(), "PX",
                                    ttl_ms},
                                   {"SADD", options_.key_prefix + "relays", options_.relay_id}});
  if (!replies.ok()) {
    counters_.redis_errors.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  for (const RedisReply& r : *replies) {
    if (r.is_error()) counters_.bad_keys.fetch_add(1, std::memory_order_relaxed);
  }
  counters_.heartbeats.fetch_add(1, std::memory_order_relaxed);
}

void Directory::Refresh() {
  const double now = Seconds(Clock::now());
  auto view = std::make_shared<DirectoryView>();
  auto bad_key = [this] { counters_.bad_keys.fetch_add(1, std::memory_order_relaxed); };
  auto publish_unhealthy = [&] {
    std::lock_guard<std::mutex> lock(mu_);
    if (view_->healthy && now - last_ok_refresh_ > std::max(1.0, 3 * options_.refresh_s)) {
      auto stale = std::make_shared<DirectoryView>(*view_);
      stale->healthy = false;
      view_ = stale;
    }
  };
  auto lists = redis_->Pipeline({{"SMEMBERS", options_.key_prefix + "relays"},
                                 {"SMEMBERS", options_.key_prefix + "rooms"}});
  if (!lists.ok()) {
    counters_.redis_errors.fetch_add(1, std::memory_order_relaxed);
    return publish_unhealthy();
  }
  std::vector<std::string> listed, rooms;
  for (int i = 0; i < 2; ++i) {
    const RedisReply& r = (*lists)[i];
    if (r.kind != RedisReply::Kind::kArray) {  // e.g. the set overwritten with another type
      bad_key();
      continue;
    }
    for (const RedisReply& e : r.elements) {
      if (e.is_string()) (i == 0 ? listed : rooms).push_back(e.str);
    }
  }
  // Room owners first (so that every owner's own heartbeat key is read).
  std::vector<std::vector<std::string>> cmds, stale_rooms;
  if (!rooms.empty()) {
    std::vector<std::string> mget_rooms{"MGET"};
    for (const auto& room : rooms) mget_rooms.push_back(Key("room:", room));
    cmds.push_back(std::move(mget_rooms));
    auto got = redis_->Pipeline(cmds);
    if (!got.ok()) {
      counters_.redis_errors.fetch_add(1, std::memory_order_relaxed);
      return publish_unhealthy();
    }
    const RedisReply& arr = (*got)[0];
    for (size_t i = 0; i < rooms.size(); ++i) {
      if (arr.kind != RedisReply::Kind::kArray || i >= arr.elements.size()) break;
      const RedisReply& v = arr.elements[i];
      if (v.is_string()) {
        view->room_owner[rooms[i]] = v.str;
      } else {  // deleted or not a string: forget it (a placement re-creates it)
        stale_rooms.push_back({"SREM", options_.key_prefix + "rooms", rooms[i]});
      }
    }
    cmds.clear();
  }
  // A relay is alive while its own heartbeat key exists: the ids listed in the relay set,
  // every room owner and this relay are read by key, so a relay missing from the set or an
  // entry overwritten once does not make a live relay dead (and its rooms claimable).
  std::set<std::string> ids(listed.begin(), listed.end());
  for (const auto& [room, owner] : view->room_owner) {
    if (ValidId(owner)) ids.insert(owner);
  }
  ids.insert(options_.relay_id);
  std::vector<std::string> relay_ids(ids.begin(), ids.end());
  std::vector<std::string> mget_relays{"MGET"};
  for (const auto& id : relay_ids) mget_relays.push_back(Key("relay:", id));
  auto got = redis_->Pipeline({mget_relays});
  if (!got.ok()) {
    counters_.redis_errors.fetch_add(1, std::memory_order_relaxed);
    return publish_unhealthy();
  }
  std::vector<std::vector<std::string>> cleanup = std::move(stale_rooms);
  std::set<std::string> listed_set(listed.begin(), listed.end());
  const RedisReply& arr = (*got)[0];
  for (size_t i = 0; i < relay_ids.size(); ++i) {
    if (arr.kind != RedisReply::Kind::kArray || i >= arr.elements.size()) break;
    const RedisReply& v = arr.elements[i];
    if (v.kind == RedisReply::Kind::kNil) {  // expired (or not a string): out of the cluster
      if (listed_set.count(relay_ids[i]) != 0) {
        cleanup.push_back({"SREM", options_.key_prefix + "relays", relay_ids[i]});
      }
      continue;
    }
    auto j = nlohmann::json::parse(v.str, nullptr, /*allow_exceptions=*/false);
    if (!j.is_object() || !j.contains("address") || !j["address"].is_string() ||
        !ValidAddress(j["address"].get<std::string>()) ||
        !j.value("users", nlohmann::json()).is_number_unsigned() ||
        !j.value("rooms", nlohmann::json()).is_number_unsigned()) {
      // Alive (its key exists) but unusable: never placed on or redirected to, never claimed
      // from while its key lives.
      bad_key();
      view->unroutable.insert(relay_ids[i]);
      continue;
    }
    RelayInfo info;
    info.id = relay_ids[i];
    info.address = j["address"].get<std::string>();
    info.users = j["users"].get<uint32_t>();
    info.rooms = j["rooms"].get<uint32_t>();
    info.draining = j.value("draining", nlohmann::json(false)).is_boolean() &&
                    j.value("draining", false);
    view->relays[info.id] = info;
  }
  if (!cleanup.empty()) {
    auto done = redis_->Pipeline(cleanup);
    if (!done.ok()) counters_.redis_errors.fetch_add(1, std::memory_order_relaxed);
  }
  view->healthy = true;
  last_ok_refresh_ = now;
  ClaimOrphans(view.get());
  std::lock_guard<std::mutex> lock(mu_);
  view_ = std::move(view);
}

void Directory::ClaimOrphans(DirectoryView* view) {
  // This relay must itself be live in the view to claim (a relay that lost its own
  // registration, e.g. Redis restarted, claims nothing until its next heartbeat).
  if (view->relays.count(options_.relay_id) == 0) return;
  std::vector<std::string> candidates;
  for (const auto& [id, info] : view->relays) {
    if (!info.draining) candidates.push_back(id);
  }
  if (candidates.empty()) return;  // std::map: already sorted
  std::set<std::string> local;
  {
    std::lock_guard<std::mutex> lock(mu_);
    local = local_rooms_;
  }
  std::map<std::string, int> orphans;
  for (auto& [room, owner] : view->room_owner) {
    if (view->relays.count(owner) != 0 || view->unroutable.count(owner) != 0) continue;
    // Ownerless: the holder (a live copy here) takes it back at once; the relay the room
    // hashes to waits one more refresh, so a live holder keeps its room.
    const int seen = orphans[room] = orphan_refreshes_[room] + 1;
    const bool held_here = local.count(room) != 0;
    if (!held_here && (seen < 2 || candidates[Fnv1a(room) % candidates.size()] != options_.relay_id)) {
      continue;
    }
    auto claimed = redis_->Command({"EVAL", kClaimScript, "1", Key("room:", room), owner,
                                    options_.relay_id});
    if (!claimed.ok()) {
      counters_.redis_errors.fetch_add(1, std::memory_order_relaxed);
      return;
    }
    if (claimed->kind != RedisReply::Kind::kInteger) {
      counters_.bad_keys.fetch_add(1, std::memory_order_relaxed);
      continue;
    }
    if (claimed->integer != 1) continue;  // someone else changed it first
    DirectoryEvent ev;
    ev.kind = DirectoryEvent::Kind::kClaimed;
    ev.room = room;
    ev.owner = options_.relay_id;
    auto state = redis_->Command({"GET", Key("state:", room)});
    if (!state.ok()) {
      counters_.redis_errors.fetch_add(1, std::memory_order_relaxed);
    } else if (state->is_string()) {
      auto snap = DecodeRoomSnapshot(std::span<const uint8_t>(
          reinterpret_cast<const uint8_t*>(state->str.data()), state->str.size()));
      if (snap.ok() && snap->room == room) {
        ev.has_snapshot = true;
        ev.snapshot = std::move(*snap);
      } else {
        counters_.bad_keys.fetch_add(1, std::memory_order_relaxed);
      }
    } else if (state->kind != RedisReply::Kind::kNil) {
      counters_.bad_keys.fetch_add(1, std::memory_order_relaxed);
    }
    spdlog::warn("cluster: claimed room '{}' from dead relay '{}' ({} entities)", room, owner,
                 ev.snapshot.entities.size());
    counters_.claims.fetch_add(1, std::memory_order_relaxed);
    owner = options_.relay_id;
    orphans.erase(room);
    Post(std::move(ev));
  }
  orphan_refreshes_ = std::move(orphans);
}

void Directory::SetLocalRooms(std::set<std::string> rooms) {
  std::lock_guard<std::mutex> lock(mu_);
  local_rooms_ = std::move(rooms);
}

void Directory::DoPlacement(const std::string& room, bool prefer_self) {
  std::shared_ptr<const DirectoryView> v = view();
  std::string target = options_.relay_id;
  if (!prefer_self) {
    // Least loaded: fewest rooms, then fewest users; this relay's own load is current.
    const RelayInfo* best = nullptr;
    for (const auto& [id, info] : v->relays) {
      if (info.draining) continue;
      if (best == nullptr || std::tie(info.rooms, info.users, info.id) <
                                 std::tie(best->rooms, best->users, best->id)) {
        best = &info;
      }
    }
    if (best != nullptr) target = best->id;
  }
  auto placed = redis_->Command({"EVAL", kPlaceScript, "2", Key("room:", room),
                                 options_.key_prefix + "rooms", target, room});
  DirectoryEvent ev;
  ev.room = room;
  if (!placed.ok()) {
    counters_.redis_errors.fetch_add(1, std::memory_order_relaxed);
    ev.kind = DirectoryEvent::Kind::kPlacementFailed;
    return Post(std::move(ev));
  }
  if (!placed->is_string()) {  // e.g. WRONGTYPE: the room key holds garbage
    counters_.bad_keys.fetch_add(1, std::memory_order_relaxed);
    ev.kind = DirectoryEvent::Kind::kPlacementFailed;
    return Post(std::move(ev));
  }
  counters_.placements.fetch_add(1, std::memory_order_relaxed);
  ev.kind = DirectoryEvent::Kind::kPlaced;
  ev.owner = placed->str;
  {
    // Count the room against its relay at once, so a burst of placements before the next
    // heartbeat spreads instead of all going to the same least-loaded relay.
    std::lock_guard<std::mutex> lock(mu_);
    auto updated = std::make_shared<DirectoryView>(*view_);
    updated->room_owner[room] = ev.owner;
    if (placed->str == target) {
      auto r = updated->relays.find(target);
      if (r != updated->relays.end()) ++r->second.rooms;
    }
    view_ = std::move(updated);
  }
  Post(std::move(ev));
}

void Directory::FlushSnapshots() {
  std::map<std::string, std::vector<uint8_t>> pending;
  {
    std::lock_guard<std::mutex> lock(mu_);
    pending.swap(snapshots_);
  }
  if (pending.empty()) return;
  std::vector<std::vector<std::string>> cmds;
  uint64_t bytes = 0;
  for (auto& [room, data] : pending) {
    bytes += data.size();
    cmds.push_back({"EVAL", kSaveScript, "2", Key("room:", room), Key("state:", room),
                    options_.relay_id, std::string(data.begin(), data.end())});
  }
  auto done = redis_->Pipeline(cmds);
  if (!done.ok()) {
    counters_.redis_errors.fetch_add(1, std::memory_order_relaxed);
    return;
  }
  for (const RedisReply& r : *done) {
    if (r.is_error()) counters_.bad_keys.fetch_add(1, std::memory_order_relaxed);
  }
  counters_.snapshots_written.fetch_add(pending.size(), std::memory_order_relaxed);
  counters_.snapshot_bytes_written.fetch_add(bytes, std::memory_order_relaxed);
}

void Directory::DoRelease(const std::string& room) {
  auto done = redis_->Command({"EVAL", kReleaseScript, "3", Key("room:", room),
                               options_.key_prefix + "rooms", Key("state:", room),
                               options_.relay_id, room});
  if (!done.ok()) {
    counters_.redis_errors.fetch_add(1, std::memory_order_relaxed);
  } else if (done->is_error()) {
    counters_.bad_keys.fetch_add(1, std::memory_order_relaxed);
  }
}

}  // namespace edgephys::cluster
