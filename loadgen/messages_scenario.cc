// messages as a Scenario: options, validation and the report (JSON, table; no charts).
#include <CLI/CLI.hpp>

#include <cmath>

#include "client/client.h"
#include "loadgen/messages.h"
#include "loadgen/scenario.h"

namespace edgephys::loadgen {

NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(MessagesResult, joined, window_s, sent, send_refused, received,
                                   relay_refusals, sent_per_s, delivered_per_s,
                                   relay_egress_bytes_per_s, expected_total, received_total,
                                   duplicates, property_writes, property_message_bytes,
                                   property_sent_bytes, property_received_bytes,
                                   property_sent_net_bytes, property_received_net_bytes)
// The options a report echoes, named as the members.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(MessagesOptions, users, rate_hz, payload_bytes, unreliable,
                                   warmup_s, duration_s, tick_rate_hz, property_hz,
                                   property_seconds, packet_auth)

namespace {

// NaN (unknown) as JSON null.
nlohmann::json OrNull(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

nlohmann::json Json(const MessagesOptions& o, const MessagesResult& r) {
  nlohmann::json j = {{"options", o}};
  j["summary"] = r;
  j["summary"]["relay_cpu"] = OrNull(r.relay_cpu);
  j["summary"]["delivered_per_core_s"] = OrNull(r.delivered_per_core_s);
  j["summary"]["accepted_per_core_s"] = OrNull(r.accepted_per_core_s);
  j["notes"] = {
      {"delivered_per_core_s",
       "message copies delivered to the room's members per second, divided by the relay's CPU "
       "seconds per second (in-process: its thread's CPU clock)"},
      {"property_*_bytes",
       "UDP payload bytes (sealed datagrams, IP/UDP headers excluded) per property write: the "
       "writer's sent, one listener's received; _net_ subtracts the same connection's idle "
       "traffic over an equal window"}};
  if (o.external.enabled()) {
    j["relay"] = ExternalRelayJson(o.external);
    j["notes"]["relay_cpu"] = ExternalRelayCpuNote(o.external);
    j["notes"]["budgets"] = "an external relay applies its own message budgets";
  }
  return j;
}

void FillTable(const MessagesOptions& o, const MessagesResult& r, Table* t) {
  t->Line("%-28s %u bots, %s, %.0f msg/s each, %u B payload, %.1f s measured\n", "room",
          r.joined, o.unreliable ? "unreliable" : "reliable", o.rate_hz, o.payload_bytes,
          r.window_s);
  t->Line("%-28s %12.0f\n", "messages sent /s", r.sent_per_s);
  t->Line("%-28s %12.0f\n", "copies delivered /s", r.delivered_per_s);
  t->Line("%-28s %12.3f\n", "relay CPU (cores)", r.relay_cpu);
  t->Line("%-28s %12.0f\n", "delivered per relay core /s", r.delivered_per_core_s);
  t->Line("%-28s %12.0f\n", "accepted per relay core /s", r.accepted_per_core_s);
  t->Line("%-28s %12.0f\n", "relay egress B/s", r.relay_egress_bytes_per_s);
  t->Line("%-28s %12llu / %llu (duplicates %llu, refused %llu + %llu)\n", "received / expected",
          static_cast<unsigned long long>(r.received_total),
          static_cast<unsigned long long>(r.expected_total),
          static_cast<unsigned long long>(r.duplicates),
          static_cast<unsigned long long>(r.relay_refusals),
          static_cast<unsigned long long>(r.send_refused));
  t->Line("%-28s %12llu writes at %.0f Hz; message %u B\n", "property updates",
          static_cast<unsigned long long>(r.property_writes), o.property_hz,
          r.property_message_bytes);
  t->Line("%-28s %12.1f (net %.1f)\n", "  B/update writer -> relay", r.property_sent_bytes,
          r.property_sent_net_bytes);
  t->Line("%-28s %12.1f (net %.1f)\n", "  B/update relay -> member", r.property_received_bytes,
          r.property_received_net_bytes);
}

class MessagesScenario final : public MeasuringScenario<MessagesOptions, MessagesResult> {
 public:
  MessagesScenario()
      : MeasuringScenario(
            "messages",
            "Application messages one relay core forwards in a room; bytes per property update",
            {Json, FillTable}) {}

  void AddOptions(CLI::App& cmd) override {
    cmd.add_option("--users", o_.users, "Bots in the room");
    cmd.add_option("--rate", o_.rate_hz, "Messages per second each bot sends to the room");
    cmd.add_option("--payload", o_.payload_bytes, "Message payload bytes (>= 8)");
    cmd.add_flag("--unreliable", o_.unreliable, "Send unreliable messages (one datagram each)");
    cmd.add_option("--warmup", o_.warmup_s, "Seconds of messages before measuring");
    cmd.add_option("--seconds,--duration", o_.duration_s, "Measured seconds");
    AddRelayRoomOptions(cmd, &o_.tick_rate_hz, &o_.packet_auth);
    cmd.add_option("--property-hz", o_.property_hz, "Property writes per second (phase 2)");
    cmd.add_option("--property-seconds", o_.property_seconds, "Seconds of property writes");
    AddExternalRelayOptions(cmd, &o_.external);
  }

  std::string Validate() override {
    if (o_.users == 0 || o_.users > 4096 || o_.rate_hz <= 0 || o_.rate_hz > 100000 ||
        o_.payload_bytes > kMaxUnreliableMessageBytes || o_.warmup_s < 0 || o_.duration_s <= 0 ||
        o_.duration_s > 600 || o_.tick_rate_hz <= 0 || o_.tick_rate_hz > 1000 ||
        o_.property_hz <= 0 || o_.property_hz > 1000 || o_.property_seconds <= 0 ||
        o_.property_seconds > 60) {
      return "invalid messages options (users 1..4096, payload <= 1165, durations > 0, rates > 0)";
    }
    return ValidateExternalRelay(o_.external);
  }

  std::optional<MessagesResult> Measure() override { return RunMessages(o_); }

  bool Succeeded(const MessagesResult& r) const override {
    return r.joined == o_.users && r.received > 0;
  }
};

}  // namespace

std::unique_ptr<Scenario> MakeMessagesScenario() { return std::make_unique<MessagesScenario>(); }

}  // namespace edgephys::loadgen
