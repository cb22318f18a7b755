// RoomWorkTimes: how long the relay worked for each room, exported as
// edgephys_room_update_seconds_total{room="..."} (metrics/metrics_exporter.cc;
// docs/operations.md, "Metrics").
//
// What counts as a room's work (Relay, relay/relay.cc): handling its members' datagrams
// (opening, acks, messages), applying its PhyS results, its tick (frame, picks, encoding and
// sends of every receiver) and servicing its members' connections (resends, keep-alives).
// Steady-clock seconds, summed over the relay's threads (receivers of one tick may run in
// parallel on the fork-join pool, so a room can be charged more than one second per second).
// Work for sessions in no room (handshakes, joins that fail) and PhyS steps on the physics
// threads are not charged to any room (edgephys_physics_step_seconds has those).
//
// Bounded label cardinality: at most max_rooms() rooms have series of their own; the work of
// further rooms is summed in one series labelled kOtherLabel ("~other"), which only grows. A
// room that closes is Remove()d, and its series disappears (its seconds are forgotten, not
// moved to "~other"; a room of the same name opened later starts again at 0, which Prometheus
// reads as a counter reset). Labels are room names with every byte outside printable ASCII,
// and '~', written as '?', so the exposition stays valid UTF-8 and "~other" names no room;
// rooms whose names map to the same label share one series.
//
// Thread-safety: every method may be called from any thread (one mutex). The relay calls Add
// for each room it worked for at most every kPublishIntervalS (RoomWorkLedger below batches
// per update), so the lock is taken a few times per room per second, not per datagram.
#pragma once

#include <chrono>
#include <cmath>
#include <cstddef>
#include <map>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>
#include <utility>
#include <vector>

namespace edgephys {

class RoomWorkTimes {
 public:
  static constexpr size_t kDefaultMaxRooms = 128;
  static constexpr std::string_view kOtherLabel = "~other";

  explicit RoomWorkTimes(size_t max_rooms = kDefaultMaxRooms) : max_rooms_(max_rooms) {}
  RoomWorkTimes(const RoomWorkTimes&) = delete;
  RoomWorkTimes& operator=(const RoomWorkTimes&) = delete;

  size_t max_rooms() const { return max_rooms_; }

  // Adds `seconds` of work for `room`. Negative, NaN or infinite amounts are ignored. A room
  // not yet tracked gets a series of its own while fewer than max_rooms() are tracked;
  // otherwise its seconds go to "~other".
  void Add(std::string_view room, double seconds) {
    if (!std::isfinite(seconds) || seconds < 0) return;
    std::lock_guard lock(mu_);
    auto it = rooms_.find(room);
    if (it != rooms_.end()) {
      it->second += seconds;
    } else if (rooms_.size() < max_rooms_) {
      rooms_.emplace(std::string(room), seconds);
    } else {
      other_ += seconds;
      other_used_ = true;
    }
  }

  // The room closed: its series goes. Rooms in "~other" are not tracked one by one; removing
  // one of them changes nothing. A no-op for unknown rooms.
  void Remove(std::string_view room) {
    std::lock_guard lock(mu_);
    auto it = rooms_.find(room);
    if (it != rooms_.end()) rooms_.erase(it);
  }

  struct Series {
    std::string label;
    double seconds = 0;
  };
  // The series to export, one per distinct label, ordered by label; "~other" last, and only
  // once a room has overflowed the cap.
  std::vector<Series> Snapshot() const {
    std::map<std::string, double> by_label;
    double other = 0;
    bool other_used = false;
    {
      std::lock_guard lock(mu_);
      for (const auto& [room, seconds] : rooms_) by_label[Label(room)] += seconds;
      other = other_;
      other_used = other_used_;
    }
    std::vector<Series> out;
    out.reserve(by_label.size() + 1);
    for (auto& [label, seconds] : by_label) out.push_back({label, seconds});
    if (other_used) out.push_back({std::string(kOtherLabel), other});
    return out;
  }

  // The label of a room name (see above).
  static std::string Label(std::string_view room) {
    std::string label(room);
    for (char& c : label) {
      const auto u = static_cast<unsigned char>(c);
      if (u < 0x20 || u > 0x7e || c == '~') c = '?';
    }
    return label;
  }

 private:
  const size_t max_rooms_;
  mutable std::mutex mu_;
  std::map<std::string, double, std::less<>> rooms_;
  double other_ = 0;
  bool other_used_ = false;
};

// The relay thread's side: charges work to rooms without locking and hands the sums to a
// RoomWorkTimes at most every kPublishIntervalS. Keys are the rooms' addresses (a RoomHost);
// Forget() before a room is destroyed. Not thread-safe: one thread (the relay's loop).
class RoomWorkLedger {
 public:
  static constexpr double kPublishIntervalS = 0.1;
  using Clock = std::chrono::steady_clock;

  static double SecondsSince(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
  }

  // `room` is the key, `name` the room's name (read only by Publish).
  void Charge(const void* room, const std::string* name, double seconds) {
    if (room == nullptr) return;
    Pending& p = pending_[room];
    p.name = name;
    p.seconds += seconds;
  }

  // Adds what was charged to `times` if kPublishIntervalS passed since the last publication
  // (or `force`), and clears it. `now` in seconds on any monotonic clock.
  void Publish(RoomWorkTimes* times, double now, bool force = false) {
    if (!force && now - published_at_ < kPublishIntervalS) return;
    published_at_ = now;
    for (auto& [room, p] : pending_) {
      if (p.seconds > 0) times->Add(*p.name, p.seconds);
      p.seconds = 0;
    }
  }

  // `room` (named `name`) closes: what it was charged and not yet published is dropped, and
  // its series removed from `times`.
  void Forget(const void* room, std::string_view name, RoomWorkTimes* times) {
    pending_.erase(room);
    times->Remove(name);
  }

 private:
  struct Pending {
    const std::string* name = nullptr;
    double seconds = 0;
  };
  std::unordered_map<const void*, Pending> pending_;
  double published_at_ = -1e300;
};

}  // namespace edgephys
