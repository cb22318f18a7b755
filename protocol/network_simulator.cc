#include "protocol/network_simulator.h"

#include <algorithm>
#include <limits>

namespace edgephys {

NetworkSimulator::NetworkSimulator(DatagramSocket* inner, const NetworkConditions& conditions,
                                   size_t max_queued)
    : inner_(inner),
      conditions_(conditions),
      max_queued_(max_queued),
      rng_(conditions.seed),
      queue_(max_queued, std::numeric_limits<size_t>::max()) {}

void NetworkSimulator::SetConditions(const NetworkConditions& conditions) {
  conditions_ = conditions;
  rng_.seed(conditions.seed);
}

double NetworkSimulator::Uniform() {
  // 53 random bits: the same sequence on every platform (unlike std::uniform_real_distribution).
  return static_cast<double>(rng_() >> 11) * 0x1.0p-53;
}

Status NetworkSimulator::SendTo(const Endpoint& to, std::span<const uint8_t> data) {
  stats_.sent++;
  // Always draw the same number of values per datagram, so one decision does not shift the
  // random stream of the others when conditions change.
  bool lost = Uniform() < conditions_.loss;
  bool duplicated = Uniform() < conditions_.duplicate;
  if (lost) {
    stats_.dropped++;
    return Status::Ok();
  }
  Enqueue(to, data);
  if (duplicated) {
    stats_.duplicated++;
    Enqueue(to, data);
  }
  return Status::Ok();
}

void NetworkSimulator::Enqueue(const Endpoint& to, std::span<const uint8_t> data) {
  double jitter = (2 * Uniform() - 1) * conditions_.jitter_s;
  bool reordered = Uniform() < conditions_.reorder;
  double extra = Uniform() * conditions_.reorder_delay_s;
  if (queue_.size() >= max_queued_) {
    stats_.queue_full++;
    return;
  }
  double delay = std::max(0.0, conditions_.latency_s + jitter);
  if (reordered) {
    stats_.delayed++;
    delay += extra;
  }
  (void)queue_.Push(now_ + delay, to, data);  // room checked above; no byte cap
}

void NetworkSimulator::Update(double now) {
  now_ = now;
  queue_.PopDue(now, [this](const Endpoint& to, std::span<const uint8_t> data, double) {
    stats_.forwarded++;
    if (!inner_->SendTo(to, data).ok()) stats_.inner_errors++;
  });
}

size_t NetworkSimulator::ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) {
  return inner_->ReceiveFrom(from, buffer);
}

Endpoint NetworkSimulator::LocalEndpoint() const { return inner_->LocalEndpoint(); }

ImpairedSocket::ImpairedSocket(DatagramSocket* inner, const NetworkConditions& up,
                               const NetworkConditions& down)
    : inner_(inner), up_(inner, up), down_(&inbox_, down), scratch_(65536) {}

void ImpairedSocket::Update(double now) {
  now_ = now;
  up_.Update(now);
  down_.Update(now);
}

Status ImpairedSocket::SendTo(const Endpoint& to, std::span<const uint8_t> data) {
  return up_.SendTo(to, data);
}

size_t ImpairedSocket::ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) {
  for (;;) {
    Endpoint source;
    const size_t n = inner_->ReceiveFrom(&source, scratch_);
    if (n == 0) break;
    // Oversized datagrams keep their true size only as far as the scratch buffer (64 KiB, the
    // UDP maximum) holds them.
    (void)down_.SendTo(source, std::span<const uint8_t>(scratch_.data(), std::min(n, scratch_.size())));
  }
  down_.Update(now_);  // those the conditions give no delay
  return inbox_.ReceiveFrom(from, buffer);
}

Endpoint ImpairedSocket::LocalEndpoint() const { return inner_->LocalEndpoint(); }

Status ImpairedSocket::Inbox::SendTo(const Endpoint& from, std::span<const uint8_t> data) {
  due_.push_back({from, std::vector<uint8_t>(data.begin(), data.end())});
  return Status::Ok();
}

size_t ImpairedSocket::Inbox::ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) {
  if (due_.empty()) return 0;
  Datagram& d = due_.front();
  *from = d.from;
  const size_t n = d.data.size();
  std::copy_n(d.data.begin(), std::min(n, buffer.size()), buffer.begin());
  due_.pop_front();
  return n;
}

}  // namespace edgephys
