#pragma once
// Filling a loopback benchmark's result from a measured relay window (loadgen/loopback_room.h).

#include <cstddef>

#include "loadgen/loopback_room.h"

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

}  // namespace edgephys::loadgen
