#include "relay/relay_shards.h"

#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/eventfd.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <ctime>
#include <mutex>

#include "protocol/packet_seal.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/packet.h"
#include "relay/spsc_ring.h"

namespace edgephys {
namespace {

uint64_t UnixNow() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

// FNV-1a, then a final mix so that the low bits (the modulo) depend on every byte.
uint64_t Mix(uint64_t h) {
  h ^= h >> 33;
  h *= 0xff51afd7ed558ccdull;
  h ^= h >> 33;
  h *= 0xc4ceb9fe1a85ec53ull;
  h ^= h >> 33;
  return h;
}

uint64_t HashBytes(const void* data, size_t size) {
  const auto* p = static_cast<const uint8_t*>(data);
  uint64_t h = 0xcbf29ce484222325ull;
  for (size_t i = 0; i < size; ++i) {
    h ^= p[i];
    h *= 0x100000001b3ull;
  }
  return Mix(h);
}

uint64_t HashAddress(const Endpoint& from) {
  if (from.address().is_v4()) {
    auto bytes = from.address().to_v4().to_bytes();
    return HashBytes(bytes.data(), bytes.size());
  }
  auto bytes = from.address().to_v6().to_bytes();
  return HashBytes(bytes.data(), bytes.size());
}

// One queued datagram. Bytes beyond kMaxDatagramSize (a sealed full packet) are not kept: the
// relay drops such a datagram by its reported size alone.
struct QueuedDatagram {
  Endpoint from;
  size_t size = 0;  // full size as received
  std::array<uint8_t, kMaxDatagramSize> data;
};

}  // namespace

// The DatagramSocket a shard's Relay sees: ReceiveFrom pops the shard's ring; SendTo queues
// into a batch that Flush() hands to sendmmsg.
class ShardSocket final : public DatagramSocket {
 public:
  ShardSocket(UdpSocket* socket, RelayCounters* counters, size_t queue_capacity)
      : socket_(socket), counters_(counters), ring_(queue_capacity) {
    pending_.reserve(UdpSocket::kMaxBatch);
    arena_.reserve(UdpSocket::kMaxBatch * kMaxDatagramSize);
  }

  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
    if (data.size() > 65507) return Status(StatusCode::kInvalidArgument, "datagram too large");
    pending_.push_back({to, arena_.size(), data.size()});
    arena_.insert(arena_.end(), data.begin(), data.end());
    if (pending_.size() >= UdpSocket::kMaxBatch) (void)Flush();
    return Status::Ok();
  }

  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    QueuedDatagram* d = ring_.Front();
    if (d == nullptr) return 0;
    const size_t size = d->size;
    std::memcpy(buffer.data(), d->data.data(), std::min({size, d->data.size(), buffer.size()}));
    *from = d->from;
    ring_.Pop();
    return size;
  }

  Endpoint LocalEndpoint() const override { return socket_->LocalEndpoint(); }

  // Sends everything queued since the last flush (one sendmmsg per 64 datagrams). Refused
  // datagrams are counted here (send_errors), so it returns 0 to the relay's FlushSends.
  size_t Flush() override {
    if (pending_.empty()) return 0;
    outgoing_.clear();
    for (const Pending& p : pending_) {
      outgoing_.push_back({p.to, std::span<const uint8_t>(arena_.data() + p.offset, p.size)});
    }
    UdpSocket::BatchSendResult r = socket_->SendBatch(outgoing_);
    if (r.refused > 0) {
      RelayCounters::Inc(counters_->send_errors, r.refused);
      send_refused.fetch_add(r.refused, std::memory_order_relaxed);
    }
    send_batches.fetch_add(1, std::memory_order_relaxed);
    pending_.clear();
    arena_.clear();
    return 0;
  }

  SpscRing<QueuedDatagram>& ring() { return ring_; }

  std::atomic<uint64_t> send_batches{0};
  std::atomic<uint64_t> send_refused{0};

 private:
  struct Pending {
    Endpoint to;
    size_t offset;
    size_t size;
  };
  UdpSocket* socket_;
  RelayCounters* counters_;
  SpscRing<QueuedDatagram> ring_;
  std::vector<Pending> pending_;
  std::vector<uint8_t> arena_;
  std::vector<UdpSocket::Outgoing> outgoing_;
};

struct RelayShards::Shard {
  Shard(UdpSocket* udp, RelayCounters* counters, size_t queue_capacity)
      : socket(udp, counters, queue_capacity) {}
  ~Shard() {
    if (event_fd >= 0) ::close(event_fd);
  }

  // Wakes the shard thread (from any thread).
  void Wake() {
    uint64_t one = 1;
    ssize_t ignored = ::write(event_fd, &one, sizeof(one));
    (void)ignored;
  }

  ShardSocket socket;
  std::unique_ptr<Relay> relay;
  std::thread thread;
  int event_fd = -1;
  std::atomic<bool> sleeping{false};  // the shard is (about to be) blocked in ppoll
  std::atomic<bool> stop{false};

  // Tasks from RunOnShard (mutex only off the hot path; the shard checks `has_tasks` first).
  std::mutex task_mutex;
  std::vector<std::function<void(Relay&, double)>> tasks;
  bool accepting_tasks = true;
  std::atomic<bool> has_tasks{false};

  // Written by the receive thread.
  std::atomic<uint64_t> datagrams_queued{0};
  std::atomic<uint64_t> queue_drops{0};
  // Written by the shard thread.
  std::atomic<uint64_t> updates{0};
  std::atomic<size_t> rooms{0};
  std::atomic<size_t> sessions{0};
};

RelayShards::RelayShards(UdpSocket* socket, RelayCounters* counters,
                         const RelayShardsOptions& options)
    : socket_(socket),
      counters_(counters),
      options_(options),
      start_(std::chrono::steady_clock::now()) {}

Result<std::unique_ptr<RelayShards>> RelayShards::Start(const RelayConfig& config,
                                                        UdpSocket* socket, RelayCounters* counters,
                                                        const RelayShardsOptions& options) {
  if (socket == nullptr || counters == nullptr) {
    return Status(StatusCode::kInvalidArgument, "null socket or counters");
  }
  if (options.shards == 0 || options.shards > kMaxShards || options.queue_capacity == 0) {
    return Status(StatusCode::kInvalidArgument, "shards must be 1..64, queue capacity > 0");
  }
  // The shards log through spdlog's default logger, which libspdlog creates lazily (a function
  // static) on first use. Create it here, before any shard thread exists, so that the threads
  // only ever read a finished logger: the lazy initialisation happens inside the (possibly
  // uninstrumented) library, where ThreadSanitizer cannot see the guard that orders it and
  // reports the shards' first log lines as racing with it.
  (void)spdlog::default_logger_raw();
  std::unique_ptr<RelayShards> self(new RelayShards(socket, counters, options));
  const size_t n = options.shards;
  RelayConfig shard_config = config;
  shard_config.max_clients = static_cast<uint32_t>((config.max_clients + n - 1) / n);
  shard_config.physics_threads = std::max<size_t>(1, config.physics_threads / n);
  RelayShardOptions shard_options;
  shard_options.count = static_cast<uint32_t>(n);
  shard_options.cookie_key = CookieJar::RandomKey();
  shard_options.shared_counters = true;
  for (size_t i = 0; i < n; ++i) {
    auto shard = std::make_unique<Shard>(socket, counters, options.queue_capacity);
    shard->event_fd = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
    if (shard->event_fd < 0) return Status(StatusCode::kIoError, "cannot create eventfd");
    shard_options.index = static_cast<uint32_t>(i);
    shard->relay = std::make_unique<Relay>(shard_config, &shard->socket, counters, shard_options);
    self->shards_.push_back(std::move(shard));
  }
  for (auto& shard : self->shards_) {
    Shard* s = shard.get();
    RelayShards* owner = self.get();
    s->thread = std::thread([owner, s] { owner->ShardLoop(*s); });
  }
  self->receiver_ = std::thread([owner = self.get()] { owner->ReceiveLoop(); });
  return self;
}

RelayShards::~RelayShards() { Stop(); }

double RelayShards::Now() const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
}

void RelayShards::Stop() {
  if (stopped_) return;
  stopped_ = true;
  stop_receiving_.store(true);
  if (receiver_.joinable()) receiver_.join();
  for (auto& s : shards_) {
    s->stop.store(true);
    s->Wake();
  }
  for (auto& s : shards_) {
    if (s->thread.joinable()) s->thread.join();
  }
}

size_t RelayShards::ShardOfRoom(std::string_view room) const {
  return HashBytes(room.data(), room.size()) % shards_.size();
}

size_t RelayShards::Route(const Endpoint& from, std::span<const uint8_t> datagram) const {
  const size_t n = shards_.size();
  if (n == 1) return 0;
  const size_t by_address = HashAddress(from) % n;
  PacketPrefix prefix{};
  DropReason reason{};
  if (!ParsePacketPrefix(datagram, &prefix, &reason)) return by_address;
  switch (prefix.type) {
    case PacketType::kData:
    case PacketType::kDisconnect:
      return prefix.connection_id % n;
    case PacketType::kConnect: {
      // Parsed as the relay will parse it; any failure there is a drop on whichever shard.
      const schema::ControlMessage* msg =
          VerifyControlMessage(datagram.subspan(kPacketPrefixSize), schema::Body::Connect);
      if (msg == nullptr) return by_address;
      const auto* token = msg->body_as_Connect()->token();
      if (token == nullptr) return by_address;
      JoinTokenRoute route;
      if (!PeekJoinToken(std::span<const uint8_t>(token->data(), token->size()), &route)) {
        return by_address;
      }
      if ((route.permissions & kPermissionWorker) != 0) return Mix(route.nonce) % n;
      return ShardOfRoom(route.room);
    }
    default:
      return by_address;  // Hello, and types a client never sends (the shard counts them)
  }
}

void RelayShards::ReceiveLoop() {
  constexpr size_t kBatch = UdpSocket::kMaxBatch;
  std::vector<std::array<uint8_t, kMaxDatagramSize>> buffers(kBatch);
  std::array<UdpSocket::ReceiveSlot, kBatch> slots{};
  for (size_t i = 0; i < kBatch; ++i) slots[i].buffer = buffers[i];
  while (!stop_receiving_.load(std::memory_order_relaxed)) {
    const size_t n = socket_->ReceiveBatch(slots);
    if (n == 0) {
      socket_->WaitReadable(0.01);  // bounded, so Stop() is noticed
      continue;
    }
    uint64_t touched = 0;  // bit i: shard i got a datagram in this batch
    for (size_t i = 0; i < n; ++i) {
      const UdpSocket::ReceiveSlot& slot = slots[i];
      if (slot.size == 0) continue;
      const size_t kept = std::min(slot.size, slot.buffer.size());
      std::span<const uint8_t> bytes(slot.buffer.data(), kept);
      const size_t target = Route(slot.from, bytes);
      Shard& shard = *shards_[target];
      QueuedDatagram* d = shard.socket.ring().Claim();
      if (d == nullptr) {
        shard.queue_drops.fetch_add(1, std::memory_order_relaxed);
        RelayCounters::Inc(counters_->io_queue_drops);
        continue;
      }
      d->from = slot.from;
      d->size = slot.size;
      std::memcpy(d->data.data(), bytes.data(), kept);
      shard.socket.ring().Publish();
      shard.datagrams_queued.fetch_add(1, std::memory_order_relaxed);
      touched |= uint64_t{1} << target;
    }
    // Wake the shards that sleep. Both sides flip `sleeping` with read-modify-writes, so they
    // are ordered against each other on that one variable: either this exchange comes after
    // the shard's exchange(true) and reads `true` (wake it), or the shard's exchange reads
    // this one's write, which (acq_rel) makes the datagrams published above visible to the
    // shard's Empty() check, and it does not sleep. (Stand-alone fences would do the same, but
    // ThreadSanitizer does not model them.) Clearing the flag also spares the next batches a
    // redundant eventfd write while the shard is still waking.
    for (size_t i = 0; i < shards_.size(); ++i) {
      if ((touched >> i & 1) == 0) continue;
      if (shards_[i]->sleeping.exchange(false, std::memory_order_acq_rel)) shards_[i]->Wake();
    }
  }
}

void RelayShards::ShardLoop(Shard& shard) {
  Relay& relay = *shard.relay;
  auto run_tasks = [&](bool final) {
    std::vector<std::function<void(Relay&, double)>> tasks;
    {
      std::lock_guard<std::mutex> lock(shard.task_mutex);
      tasks.swap(shard.tasks);
      shard.has_tasks.store(false, std::memory_order_relaxed);
      if (final) shard.accepting_tasks = false;
    }
    for (auto& task : tasks) task(relay, Now());
    (void)shard.socket.Flush();
  };
  const double wait_s = std::clamp(options_.idle_wait_s, 0.0001, 0.1);
  timespec timeout{};
  timeout.tv_sec = static_cast<time_t>(std::floor(wait_s));
  timeout.tv_nsec = static_cast<long>((wait_s - std::floor(wait_s)) * 1e9);
  while (!shard.stop.load(std::memory_order_acquire)) {
    if (shard.has_tasks.load(std::memory_order_acquire)) run_tasks(false);
    relay.Update(Now(), UnixNow());
    (void)shard.socket.Flush();
    shard.updates.fetch_add(1, std::memory_order_relaxed);
    shard.rooms.store(relay.room_count(), std::memory_order_relaxed);
    shard.sessions.store(relay.session_count(), std::memory_order_relaxed);

    // Pairs with the exchange in ReceiveLoop (see there).
    shard.sleeping.exchange(true, std::memory_order_acq_rel);
    if (shard.socket.ring().Empty() && !shard.has_tasks.load(std::memory_order_relaxed) &&
        !shard.stop.load(std::memory_order_relaxed)) {
      pollfd fd{};
      fd.fd = shard.event_fd;
      fd.events = POLLIN;
      if (::ppoll(&fd, 1, &timeout, nullptr) > 0 && (fd.revents & POLLIN) != 0) {
        uint64_t drained = 0;
        ssize_t ignored = ::read(shard.event_fd, &drained, sizeof(drained));  // non-blocking
        (void)ignored;
      }
    }
    shard.sleeping.store(false, std::memory_order_relaxed);
  }
  // Stopping: the receive thread has stopped (joined before `stop` was set), so the ring only
  // shrinks now. Handle everything queued - one Update takes at most
  // config.max_datagrams_per_update of it (bounded by the ring's capacity in case that is 0)
  // - then say goodbye.
  run_tasks(true);
  for (size_t i = 0; i <= shard.socket.ring().capacity(); ++i) {
    relay.Update(Now(), UnixNow());
    if (shard.socket.ring().Empty()) break;
  }
  relay.Shutdown();
  (void)shard.socket.Flush();
  shard.rooms.store(relay.room_count(), std::memory_order_relaxed);
  shard.sessions.store(relay.session_count(), std::memory_order_relaxed);
}

bool RelayShards::RunOnShard(size_t index, const std::function<void(Relay&, double)>& fn) {
  if (index >= shards_.size()) return false;
  Shard& shard = *shards_[index];
  std::mutex done_mutex;
  std::condition_variable done_cv;
  bool done = false;
  {
    std::lock_guard<std::mutex> lock(shard.task_mutex);
    if (!shard.accepting_tasks) return false;
    shard.tasks.push_back([&](Relay& relay, double now) {
      fn(relay, now);
      std::lock_guard<std::mutex> done_lock(done_mutex);
      done = true;
      done_cv.notify_one();
    });
    shard.has_tasks.store(true, std::memory_order_release);
  }
  shard.Wake();
  std::unique_lock<std::mutex> lock(done_mutex);
  done_cv.wait(lock, [&] { return done; });
  return true;
}

Status RelayShards::CreateRoom(const std::string& name, const RoomConfig& config) {
  Status result(StatusCode::kNotConnected, "relay shards stopped");
  RunOnShard(ShardOfRoom(name),
             [&](Relay& relay, double now) { result = relay.CreateRoom(name, config, now); });
  return result;
}

RelayShards::ShardStats RelayShards::stats(size_t index) const {
  ShardStats out;
  if (index >= shards_.size()) return out;
  const Shard& s = *shards_[index];
  out.datagrams_queued = s.datagrams_queued.load(std::memory_order_relaxed);
  out.queue_drops = s.queue_drops.load(std::memory_order_relaxed);
  out.updates = s.updates.load(std::memory_order_relaxed);
  out.send_batches = s.socket.send_batches.load(std::memory_order_relaxed);
  out.send_refused = s.socket.send_refused.load(std::memory_order_relaxed);
  out.rooms = s.rooms.load(std::memory_order_relaxed);
  out.sessions = s.sessions.load(std::memory_order_relaxed);
  return out;
}

}  // namespace edgephys
