#include "protocol/network_simulator.h"

#include <algorithm>

namespace edgephys {

NetworkSimulator::NetworkSimulator(DatagramSocket* inner, const NetworkConditions& conditions,
                                   size_t max_queued)
    : inner_(inner), conditions_(conditions), max_queued_(max_queued), rng_(conditions.seed) {}

void NetworkSimulator::SetConditions(const NetworkConditions& conditions) {
  conditions_ = conditions;
  rng_.seed(conditions.seed);
}

double NetworkSimulator::Uniform() {
  // 53 random bits: the same sequence on every platform (unlike std::uniform_real_distribution).
  return static_cast<double>(rng_() >> 11) * 0x1.0p-53;
}

bool NetworkSimulator::Later(size_t a, size_t b) const {
  const Entry& x = entries_[a];
  const Entry& y = entries_[b];
  return x.due > y.due || (x.due == y.due && x.order > y.order);
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
  if (heap_.size() >= max_queued_) {
    stats_.queue_full++;
    return;
  }
  double delay = std::max(0.0, conditions_.latency_s + jitter);
  if (reordered) {
    stats_.delayed++;
    delay += extra;
  }
  size_t index;
  if (!free_.empty()) {
    index = free_.back();
    free_.pop_back();
  } else {
    index = entries_.size();
    entries_.emplace_back();
  }
  Entry& entry = entries_[index];
  entry.due = now_ + delay;
  entry.order = next_order_++;
  entry.to = to;
  entry.data.assign(data.begin(), data.end());
  heap_.push_back(index);
  std::push_heap(heap_.begin(), heap_.end(), [this](size_t a, size_t b) { return Later(a, b); });
}

void NetworkSimulator::Update(double now) {
  now_ = now;
  auto later = [this](size_t a, size_t b) { return Later(a, b); };
  while (!heap_.empty() && entries_[heap_.front()].due <= now) {
    std::pop_heap(heap_.begin(), heap_.end(), later);
    size_t index = heap_.back();
    heap_.pop_back();
    Entry& entry = entries_[index];
    stats_.forwarded++;
    if (!inner_->SendTo(entry.to, entry.data).ok()) stats_.inner_errors++;
    free_.push_back(index);
  }
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
