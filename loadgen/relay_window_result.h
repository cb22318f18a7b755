#pragma once
// Filling a PhyS scene run's result (multiobject, softbody) from a measured relay window: an
// in-process relay's (loadgen/loopback_room.h) or an external relay's /metrics
// (loadgen/relay_target.h).

#include <cstddef>

#include "loadgen/loopback_room.h"
#include "loadgen/relay_target.h"

namespace edgephys::loadgen {

// Sets relay_ok, the per-receiver egress/socket/IP-UDP Mb/s, the mean PhyS step (ms) and the
// simulated-seconds-per-wall-second of `r` from `window` over `receivers` clients at step `dt_s`.
// Result is any struct with those fields; window.elapsed_s must be > 0.
template <class Result>
void SetRelayWindowRates(Result* r, const WindowMeter::Totals& window, size_t receivers, double dt_s) {
  r->relay_ok = true;
  r->egress_mbit_per_s_per_client = window.RelayMbitPerReceiver(receivers);
  r->socket_mbit_per_s_per_client = window.SocketMbitPerReceiver(receivers);
  r->ip_udp_mbit_per_s_per_client = window.IpUdpMbitPerReceiver(receivers);
  r->relay_step_ms_mean = window.step_ms_mean;
  r->sim_speed = static_cast<double>(window.physics_steps) * dt_s / window.elapsed_s;
}

// The same fields from an external relay's /metrics at the window's start (`a`) and end (`b`),
// `elapsed_s` apart, and the bytes the `receivers` clients' sockets received in it. Egress is
// the relay's bytes sent per member, the host counted: PhyS drives the scene, so the host is
// sent it as the receivers are (any other traffic on that relay counts too). IP-UDP is unknown,
// and so is every /metrics figure if a scrape failed.
template <class Result>
void SetExternalWindowRates(Result* r, const RelayFigures& a, const RelayFigures& b,
                            size_t receivers, double elapsed_s, double socket_bytes, double dt_s) {
  const bool metrics = a.ok && b.ok;
  const double step_count = metrics ? b.physics_step_count - a.physics_step_count : 0;
  r->relay_ok = true;
  r->egress_mbit_per_s_per_client = metrics ? (b.bytes_sent - a.bytes_sent) * 8 / 1e6 /
                                                  (static_cast<double>(receivers + 1) * elapsed_s)
                                            : kUnknown;
  r->socket_mbit_per_s_per_client =
      socket_bytes * 8 / 1e6 / (static_cast<double>(receivers) * elapsed_s);
  r->ip_udp_mbit_per_s_per_client = kUnknown;
  r->relay_step_ms_mean =
      step_count > 0 ? (b.physics_step_seconds_sum - a.physics_step_seconds_sum) / step_count * 1e3
                     : kUnknown;
  r->sim_speed = metrics ? (b.physics_steps - a.physics_steps) * dt_s / elapsed_s : kUnknown;
}

}  // namespace edgephys::loadgen
