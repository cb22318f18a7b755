#include "client/connection_rates.h"

#include <cmath>

#include "protocol/connection_types.h"

namespace edgephys {

ConnectionRates::Totals ConnectionRates::From(const ConnectionStats& stats) {
  return {stats.bytes_sent, stats.bytes_received, stats.packets_sent, stats.packets_received};
}

ConnectionRates::ConnectionRates(double window_s)
    : window_s_(window_s > 0 && std::isfinite(window_s) ? window_s : 1.0),
      spacing_s_(window_s_ / static_cast<double>(kSlots - 1)) {}

void ConnectionRates::Reset() {
  head_ = 0;
  count_ = 0;
  have_newest_ = false;
}

void ConnectionRates::Sample(double now_s, const Totals& totals) {
  if (!std::isfinite(now_s)) return;
  if (have_newest_) {
    const Totals& last = newest_.totals;
    if (now_s < newest_.t || totals.bytes_sent < last.bytes_sent ||
        totals.bytes_received < last.bytes_received || totals.packets_sent < last.packets_sent ||
        totals.packets_received < last.packets_received) {
      Reset();
    }
  }
  newest_ = {now_s, totals};
  have_newest_ = true;
  if (count_ > 0 && now_s - At(count_ - 1).t < spacing_s_) return;
  if (count_ == kSlots) {  // drop the oldest
    head_ = (head_ + 1) % kSlots;
    --count_;
  }
  ring_[(head_ + count_) % kSlots] = newest_;
  ++count_;
}

ConnectionRates::Rates ConnectionRates::Get() const {
  if (!have_newest_ || count_ == 0) return {};
  size_t base = 0;
  while (base + 1 < count_ && newest_.t - At(base).t > window_s_) ++base;
  if (newest_.t - At(base).t < window_s_ / 2 && base > 0) --base;
  const Point& from = At(base);
  const double span = newest_.t - from.t;
  if (span < 1e-3) return {};
  auto per_s = [span](uint64_t a, uint64_t b) { return static_cast<double>(b - a) / span; };
  return {per_s(from.totals.bytes_sent, newest_.totals.bytes_sent),
          per_s(from.totals.bytes_received, newest_.totals.bytes_received),
          per_s(from.totals.packets_sent, newest_.totals.packets_sent),
          per_s(from.totals.packets_received, newest_.totals.packets_received)};
}

}  // namespace edgephys
