// udp_impair: a userspace UDP impairment proxy, the fallback of tests/netem/netem_test.sh on
// kernels without the netem qdisc (sch_netem). It listens on --listen, forwards every datagram
// to --upstream from a socket of its own per client source address (so the upstream sees one
// distinct peer per client), and relays the upstream's replies back to that client from the
// listen socket. Each direction is impaired independently, with the same model as tc netem
// (see impair_schedule.h): loss, delay with uniform jitter, duplication, reordering.
//
//   udp_impair --listen 0.0.0.0:7778 --upstream 127.0.0.1:7777 --loss 0.10 --delay-ms 30
//              --jitter-ms 10 --duplicate 0.02 --reorder 0.05 --seed 1 --max-seconds 200
//
// Flags:
//   --listen ip:port      where clients send (required)
//   --upstream ip:port    where their datagrams go (required); replies from any other address
//                         to a client's upstream socket are ignored
//   --loss P              probability [0,1] a datagram is dropped (per direction)
//   --delay-ms D          base one-way delay added per direction (ms)
//   --jitter-ms J         delay varies uniformly within D +- J (never below 0)
//   --duplicate P         probability [0,1] a surviving datagram is delivered twice (each copy
//                         gets its own delay)
//   --reorder P           probability [0,1] a copy skips the delay and so overtakes the ones
//                         waiting (netem's "reorder P" with gap 1); jitter reorders too
//   --impair both|up|down which directions are impaired (default both; up = client->upstream);
//                         an unimpaired direction is forwarded at once
//   --seed N              random seed (the two directions use N and N+1)
//   --max-seconds S       exit by itself after S seconds (required, > 0; default 300)
//   --max-clients N       distinct client sources tracked at once (default 64); a new source
//                         beyond that evicts the least recently active one (its upstream
//                         socket is closed and its queued datagrams dropped)
//   --idle-timeout S      forget a client silent for S seconds (default 60)
//   --max-queued N        datagrams waiting per direction (default 8192); beyond: dropped
//   --max-queued-bytes B  payload bytes waiting per direction (default 16 MiB); beyond: dropped
//
// Exits 0 after --max-seconds or on SIGTERM/SIGINT, printing one JSON line of counters to
// stdout ("up" and "down": received, dropped, duplicated, reordered, queue_full, forwarded,
// send_errors; "clients", "evicted", "expired", "seconds"); 1 when a socket cannot be opened;
// 2 on bad flags. Queued datagrams are discarded at exit. Single-threaded: poll(2) on the
// listen socket and the client sockets, timed by the next due datagram.
#include <CLI/CLI.hpp>

#include <poll.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

#include "protocol/endpoint.h"
#include "protocol/udp_socket.h"
#include "tests/netem/impair_schedule.h"

namespace {

using namespace edgephys;
using edgephys::netem::DelayQueue;
using edgephys::netem::Fate;
using edgephys::netem::ImpairParams;
using edgephys::netem::ImpairSchedule;

volatile std::sig_atomic_t g_stop = 0;
void OnSignal(int) { g_stop = 1; }

double MonoS() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

struct DirectionStats {
  uint64_t received = 0, dropped = 0, duplicated = 0, reordered = 0, queue_full = 0,
           forwarded = 0, send_errors = 0;
};

struct Direction {
  ImpairSchedule schedule;
  DelayQueue queue;
  DirectionStats stats;

  // Applies the impairment to one datagram arriving at `now` for `tag`.
  void Arrive(double now, uint64_t tag, std::span<const uint8_t> data) {
    stats.received++;
    const Fate fate = schedule.Decide();
    if (fate.copies == 0) {
      stats.dropped++;
      return;
    }
    if (fate.copies == 2) stats.duplicated++;
    for (int i = 0; i < fate.copies; ++i) {
      if (fate.reordered[i]) stats.reordered++;
      if (!queue.Push(now + fate.delay_s[i], tag, data)) stats.queue_full++;
    }
  }
};

struct Client {
  bool used = false;
  uint32_t generation = 0;
  Endpoint from;
  std::unique_ptr<UdpSocket> up;
  double last_active = 0;
};

uint64_t Tag(size_t slot, uint32_t generation) { return (uint64_t{generation} << 32) | slot; }

void PrintStats(const char* name, const DirectionStats& s, const char* sep) {
  std::printf("\"%s\":{\"received\":%llu,\"dropped\":%llu,\"duplicated\":%llu,\"reordered\":%llu,"
              "\"queue_full\":%llu,\"forwarded\":%llu,\"send_errors\":%llu}%s",
              name, static_cast<unsigned long long>(s.received),
              static_cast<unsigned long long>(s.dropped),
              static_cast<unsigned long long>(s.duplicated),
              static_cast<unsigned long long>(s.reordered),
              static_cast<unsigned long long>(s.queue_full),
              static_cast<unsigned long long>(s.forwarded),
              static_cast<unsigned long long>(s.send_errors), sep);
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"udp_impair: UDP forwarder with netem-like loss, delay, jitter, duplication, reordering"};
  std::string listen_text, upstream_text, impair = "both";
  double loss = 0, delay_ms = 0, jitter_ms = 0, duplicate = 0, reorder = 0;
  double max_seconds = 300, idle_timeout = 60;
  uint64_t seed = 1;
  size_t max_clients = 64, max_queued = 8192, max_queued_bytes = 16u << 20;
  app.add_option("--listen", listen_text, "Listen ip:port")->required();
  app.add_option("--upstream", upstream_text, "Upstream ip:port")->required();
  app.add_option("--loss", loss, "Drop probability per direction")->check(CLI::Range(0.0, 1.0));
  app.add_option("--delay-ms", delay_ms, "Base delay per direction (ms)")->check(CLI::Range(0.0, 60000.0));
  app.add_option("--jitter-ms", jitter_ms, "Uniform jitter +- (ms)")->check(CLI::Range(0.0, 60000.0));
  app.add_option("--duplicate", duplicate, "Duplicate probability")->check(CLI::Range(0.0, 1.0));
  app.add_option("--reorder", reorder, "Probability a copy skips the delay")->check(CLI::Range(0.0, 1.0));
  app.add_option("--impair", impair, "both | up | down")->check(CLI::IsMember({"both", "up", "down"}))
      ->capture_default_str();
  app.add_option("--seed", seed, "Random seed")->capture_default_str();
  app.add_option("--max-seconds", max_seconds, "Exit after this long (s)")
      ->check(CLI::Range(0.001, 86400.0))->capture_default_str();
  app.add_option("--max-clients", max_clients, "Client sources tracked at once")
      ->check(CLI::Range(1, 4096))->capture_default_str();
  app.add_option("--idle-timeout", idle_timeout, "Forget a silent client after (s)")
      ->check(CLI::Range(0.001, 86400.0))->capture_default_str();
  app.add_option("--max-queued", max_queued, "Datagrams queued per direction")
      ->check(CLI::Range(1, 1 << 20))->capture_default_str();
  app.add_option("--max-queued-bytes", max_queued_bytes, "Payload bytes queued per direction")
      ->check(CLI::Range(65536, 1 << 30))->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  Result<Endpoint> listen_ep = ParseEndpoint(listen_text);
  Result<Endpoint> upstream = ParseEndpoint(upstream_text);
  if (!listen_ep.ok() || !upstream.ok()) {
    std::fprintf(stderr, "udp_impair: bad --listen or --upstream (want ip:port)\n");
    return 2;
  }
  auto listen_socket = UdpSocket::Open(*listen_ep);
  if (!listen_socket.ok()) {
    std::fprintf(stderr, "udp_impair: cannot bind %s\n", listen_text.c_str());
    return 1;
  }
  UdpSocket& down_socket = **listen_socket;
  const Endpoint up_bind(upstream->address().is_v4() ? asio::ip::address(asio::ip::address_v4::any())
                                                     : asio::ip::address(asio::ip::address_v6::any()),
                         0);

  ImpairParams params{loss, duplicate, reorder, delay_ms / 1000, jitter_ms / 1000};
  const ImpairParams none{};
  Direction up{ImpairSchedule(impair != "down" ? params : none, seed),
               DelayQueue(max_queued, max_queued_bytes), {}};
  Direction down{ImpairSchedule(impair != "up" ? params : none, seed + 1),
                 DelayQueue(max_queued, max_queued_bytes), {}};

  struct sigaction sa {};
  sa.sa_handler = OnSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGTERM, &sa, nullptr);
  sigaction(SIGINT, &sa, nullptr);

  std::vector<Client> clients(max_clients);
  uint64_t evicted = 0, expired = 0, distinct = 0, unknown_replies = 0;
  std::vector<uint8_t> buffer(65536);
  std::vector<pollfd> fds;
  std::vector<size_t> fd_slot;  // fds[i] (i >= 1) belongs to clients[fd_slot[i]]
  const double t0 = MonoS();
  const double end = t0 + max_seconds;
  double next_expiry_check = t0 + 1;
  std::fprintf(stderr, "udp_impair: %s -> %s, loss %.3f delay %.1f ms jitter %.1f ms duplicate %.3f "
               "reorder %.3f (%s), for at most %.0f s\n",
               FormatEndpoint(down_socket.LocalEndpoint()).c_str(), FormatEndpoint(*upstream).c_str(),
               loss, delay_ms, jitter_ms, duplicate, reorder, impair.c_str(), max_seconds);

  auto find_or_add = [&](const Endpoint& from, double now) -> Client* {
    Client* lru = nullptr;
    Client* unused = nullptr;
    for (Client& c : clients) {
      if (c.used && c.from == from) return &c;
      if (!c.used) {
        if (unused == nullptr) unused = &c;
      } else if (lru == nullptr || c.last_active < lru->last_active) {
        lru = &c;
      }
    }
    Client* slot = unused;
    if (slot == nullptr) {  // all in use: evict the least recently active
      slot = lru;
      slot->up.reset();
      slot->used = false;
      evicted++;
    }
    auto socket = UdpSocket::Open(up_bind);
    if (!socket.ok()) return nullptr;
    slot->used = true;
    slot->generation++;  // datagrams queued for the previous occupant are dropped
    slot->from = from;
    slot->up = std::move(*socket);
    slot->last_active = now;
    distinct++;
    return slot;
  };

  while (!g_stop) {
    double now = MonoS();
    if (now >= end) break;

    // Release what is due.
    up.stats.forwarded += up.queue.PopDue(now, [&](uint64_t tag, std::span<const uint8_t> data, double) {
      Client& c = clients[tag & 0xffffffffu];
      if (!c.used || c.generation != (tag >> 32)) return;
      if (!c.up->SendTo(*upstream, data).ok()) up.stats.send_errors++;
    });
    down.stats.forwarded += down.queue.PopDue(now, [&](uint64_t tag, std::span<const uint8_t> data, double) {
      Client& c = clients[tag & 0xffffffffu];
      if (!c.used || c.generation != (tag >> 32)) return;
      if (!down_socket.SendTo(c.from, data).ok()) down.stats.send_errors++;
    });

    if (now >= next_expiry_check) {
      next_expiry_check = now + 1;
      for (Client& c : clients) {
        if (c.used && now - c.last_active > idle_timeout) {
          c.up.reset();
          c.used = false;
          expired++;
        }
      }
    }

    // Wait for input or the next due datagram (poll's millisecond resolution, rounded up).
    double wake = std::min(end, next_expiry_check);
    if (!up.queue.empty()) wake = std::min(wake, up.queue.next_due());
    if (!down.queue.empty()) wake = std::min(wake, down.queue.next_due());
    int timeout_ms = static_cast<int>(std::ceil(std::max(0.0, wake - now) * 1000));
    fds.clear();
    fd_slot.clear();
    fds.push_back({down_socket.native_handle(), POLLIN, 0});
    fd_slot.push_back(0);
    for (size_t i = 0; i < clients.size(); ++i) {
      if (!clients[i].used) continue;
      fds.push_back({clients[i].up->native_handle(), POLLIN, 0});
      fd_slot.push_back(i);
    }
    int ready = poll(fds.data(), fds.size(), timeout_ms);
    if (ready < 0) {
      if (errno == EINTR) continue;
      std::fprintf(stderr, "udp_impair: poll: %s\n", std::strerror(errno));
      break;
    }
    if (ready == 0) continue;
    now = MonoS();

    // Client -> upstream. At most 1024 datagrams per socket per round, to stay fair.
    if (fds[0].revents != 0) {
      for (int k = 0; k < 1024; ++k) {
        Endpoint from;
        size_t n = down_socket.ReceiveFrom(&from, buffer);
        if (n == 0) break;
        if (n > buffer.size()) continue;  // truncated; cannot happen for UDP over IPv4/6
        Client* c = find_or_add(from, now);
        if (c == nullptr) {
          up.stats.received++;
          up.stats.send_errors++;
          continue;
        }
        c->last_active = now;
        up.Arrive(now, Tag(static_cast<size_t>(c - clients.data()), c->generation),
                  std::span<const uint8_t>(buffer.data(), n));
      }
    }
    // Upstream -> clients.
    for (size_t i = 1; i < fds.size(); ++i) {
      if (fds[i].revents == 0) continue;
      Client& c = clients[fd_slot[i]];
      if (!c.used) continue;  // evicted above in this round
      for (int k = 0; k < 1024; ++k) {
        Endpoint from;
        size_t n = c.up->ReceiveFrom(&from, buffer);
        if (n == 0) break;
        if (n > buffer.size()) continue;
        if (from != *upstream) {
          unknown_replies++;
          continue;
        }
        down.Arrive(now, Tag(fd_slot[i], c.generation), std::span<const uint8_t>(buffer.data(), n));
      }
    }
  }

  size_t active = 0;
  for (const Client& c : clients) active += c.used;
  std::printf("{\"tool\":\"udp_impair\",");
  PrintStats("up", up.stats, ",");
  PrintStats("down", down.stats, ",");
  std::printf("\"clients\":%llu,\"active\":%zu,\"evicted\":%llu,\"expired\":%llu,"
              "\"unknown_replies\":%llu,\"queued_at_exit\":%zu,\"seconds\":%.1f}\n",
              static_cast<unsigned long long>(distinct), active,
              static_cast<unsigned long long>(evicted), static_cast<unsigned long long>(expired),
              static_cast<unsigned long long>(unknown_replies), up.queue.size() + down.queue.size(),
              MonoS() - t0);
  std::fflush(stdout);
  return 0;
}
