#!/usr/bin/env python3
"""Writes deploy/grafana/edgephys.json, the Grafana dashboard over the relay's edgephys_
metrics (metrics/metrics_exporter.cc). Edit the panels here and re-run; the JSON is committed.
    python3 deploy/grafana/make_dashboard.py
"""
import json
import os

DS = {"type": "prometheus", "uid": "${DS_PROMETHEUS}"}
SEL = 'instance=~"$instance"'
panels = []
_y = 0


def row(title):
    global _y
    panels.append({"type": "row", "title": title, "collapsed": False,
                   "gridPos": {"h": 1, "w": 24, "x": 0, "y": _y}, "id": len(panels) + 1,
                   "panels": []})
    _y += 1


def panel(title, exprs, unit="short", kind="timeseries", w=8, h=7, x=0, desc=""):
    targets = [{"datasource": DS, "expr": e, "legendFormat": l, "refId": chr(65 + i)}
               for i, (e, l) in enumerate(exprs)]
    p = {"type": kind, "title": title, "datasource": DS, "targets": targets,
         "description": desc, "id": len(panels) + 1,
         "gridPos": {"h": h, "w": w, "x": x, "y": _y},
         "fieldConfig": {"defaults": {"unit": unit}, "overrides": []},
         "options": {"legend": {"displayMode": "list", "placement": "bottom"}}
         if kind == "timeseries" else {"reduceOptions": {"calcs": ["lastNotNull"]}}}
    panels.append(p)


def line(*specs):
    """Panels side by side, widths summing to 24."""
    global _y
    x = 0
    for title, exprs, unit, w, desc in specs:
        panel(title, exprs, unit, w=w, x=x, desc=desc,
              kind="stat" if title.startswith("Now:") else "timeseries")
        x += w
    _y += 4 if all(s[0].startswith("Now:") for s in specs) else 7


row("Load")
line(("Now: rooms", [(f"sum(edgephys_rooms{{{SEL}}})", "rooms")], "short", 6, "Rooms open"),
     ("Now: clients", [(f"sum(edgephys_clients{{{SEL}}})", "clients")], "short", 6, "Connections"),
     ("Now: entities", [(f"sum(edgephys_entities{{{SEL}}})", "entities")], "short", 6, ""),
     ("Now: PhyS workers", [(f"sum(edgephys_physics_workers{{{SEL}}})", "workers")], "short", 6,
      "Remote edgephys-phys workers attached"))
line(("Rooms and clients", [(f"edgephys_rooms{{{SEL}}}", "rooms {{instance}}"),
                            (f"edgephys_clients{{{SEL}}}", "clients {{instance}}")], "short", 12, ""),
     ("Entities", [(f"edgephys_entities{{{SEL}}}", "{{instance}}")], "short", 12, ""))
row("Process")
line(("Relay CPU (cores)", [(f"rate(process_cpu_seconds_total{{{SEL}}}[1m])", "{{instance}}")], "short", 8,
      "User + system CPU seconds per second of the relay process (all its threads)"),
     ("Resident memory", [(f"process_resident_memory_bytes{{{SEL}}}", "{{instance}}")], "bytes", 8, ""),
     ("Open descriptors", [(f"process_open_fds{{{SEL}}}", "open {{instance}}"),
                           (f"process_max_fds{{{SEL}}}", "limit {{instance}}")], "short", 8,
      "Sockets and files; the limit is the nofile soft limit"))
line(("Relay loop time per room (top 10)", [(f"topk(10, rate(edgephys_room_update_seconds_total{{{SEL}}}[1m]))", "{{room}} {{instance}}")], "short", 24,
      "Seconds per second the relay worked for each room (its datagrams, PhyS results, ticks): which room takes the loop"))
row("Traffic")
line(("Bytes/s", [(f"rate(edgephys_bytes_received_total{{{SEL}}}[1m])", "in {{instance}}"),
                  (f"rate(edgephys_bytes_sent_total{{{SEL}}}[1m])", "out {{instance}}")], "Bps", 8, "UDP payload"),
     ("Packets/s", [(f"rate(edgephys_packets_received_total{{{SEL}}}[1m])", "in {{instance}}"),
                    (f"rate(edgephys_packets_sent_total{{{SEL}}}[1m])", "out {{instance}}")], "pps", 8, ""),
     ("Entity updates/s", [(f"rate(edgephys_entity_updates_received_total{{{SEL}}}[1m])", "received {{instance}}"),
                           (f"rate(edgephys_entity_updates_sent_total{{{SEL}}}[1m])", "sent {{instance}}")], "short", 8, ""))
row("Latency and quality")
line(("RTT (clients)", [(f"histogram_quantile(0.5, sum by (le) (rate(edgephys_rtt_seconds_bucket{{{SEL}}}[5m])))", "p50"),
                        (f"histogram_quantile(0.99, sum by (le) (rate(edgephys_rtt_seconds_bucket{{{SEL}}}[5m])))", "p99")], "s", 8,
      "One sample per client per second"),
     ("Room tick duration", [(f"histogram_quantile(0.99, sum by (le) (rate(edgephys_tick_duration_seconds_bucket{{{SEL}}}[5m])))", "p99"),
                             (f"histogram_quantile(0.5, sum by (le) (rate(edgephys_tick_duration_seconds_bucket{{{SEL}}}[5m])))", "p50")], "s", 8,
      "Alert when p99 approaches 1/tick-rate"),
     ("Reliable resends/s", [(f"rate(edgephys_reliable_resends_total{{{SEL}}}[1m])", "{{instance}}"),
                             (f"rate(edgephys_send_errors_total{{{SEL}}}[1m])", "send errors {{instance}}"),
                             (f"rate(edgephys_io_queue_drops_total{{{SEL}}}[1m])", "io queue drops {{instance}}")], "short", 8, ""))
row("Refusals and disconnects")
line(("Packets rejected/s by reason", [(f"sum by (reason) (rate(edgephys_packets_rejected_total{{{SEL}}}[1m]))", "{{reason}}")], "pps", 8,
      "A rising rate: abuse or a broken client build"),
     ("Requests rejected/s by reason", [(f"sum by (reason) (rate(edgephys_requests_rejected_total{{{SEL}}}[1m]))", "{{reason}}")], "short", 8,
      "expired_token: clock skew between backend and relay"),
     ("Disconnects/s by reason", [(f"sum by (reason) (rate(edgephys_disconnects_total{{{SEL}}}[1m]))", "{{reason}}")], "short", 8, ""))
line(("Entity updates rejected/s by reason", [(f"sum by (reason) (rate(edgephys_entity_updates_rejected_total{{{SEL}}}[1m]))", "{{reason}}")], "short", 12, ""),
     ("Handshakes completed/s", [(f"rate(edgephys_connections_accepted_total{{{SEL}}}[1m])", "{{instance}}")], "short", 12, ""))
line(("Spawns refused/s by budget", [(f"sum by (reason) (rate(edgephys_budget_refusals_total{{{SEL}}}[1m]))", "{{reason}}")], "short", 24,
      "Error{OverBudget}: the room or player budget used up (docs/operations.md, Room budgets)"),)
row("Cluster (--redis)")
line(("Redirects/s", [(f"rate(edgephys_cluster_redirects_total{{{SEL}}}[1m])", "{{instance}}")], "short", 6,
      "Connects sent to the relay holding the room"),
     ("Rooms restored (5 min)", [(f"increase(edgephys_cluster_rooms_restored_total{{{SEL}}}[5m])", "{{instance}}")], "short", 6,
      "Rooms of dead relays claimed here"),
     ("Redis errors/s", [(f"rate(edgephys_cluster_redis_errors_total{{{SEL}}}[1m])", "{{instance}}")], "short", 6,
      "Failed Redis round trips: down, timeout, protocol"),
     ("Bad keys/s", [(f"rate(edgephys_cluster_bad_keys_total{{{SEL}}}[1m])", "{{instance}}")], "short", 6,
      "Garbage met in the cluster's Redis keys"))
row("PhyS")
line(("Real-time factor (slowest room)", [(f"edgephys_physics_realtime_factor{{{SEL}}}", "{{instance}}")], "short", 8,
      "Below 1: that room simulates slower than real time"),
     ("Bodies", [(f"edgephys_physics_bodies{{{SEL}}}", "bodies {{instance}}"),
                 (f"edgephys_physics_sleeping_bodies{{{SEL}}}", "sleeping {{instance}}")], "short", 8, ""),
     ("Step time p99, failovers", [(f"histogram_quantile(0.99, sum by (le) (rate(edgephys_physics_step_seconds_bucket{{{SEL}}}[5m])))", "step p99"),
                                   (f"increase(edgephys_physics_failovers_total{{{SEL}}}[5m])", "failovers / 5 min {{instance}}")], "s", 8, ""))

dashboard = {
    "__inputs": [{"name": "DS_PROMETHEUS", "label": "Prometheus", "type": "datasource",
                  "pluginId": "prometheus", "pluginName": "Prometheus"}],
    "__requires": [{"type": "grafana", "id": "grafana", "name": "Grafana", "version": "9.0.0"},
                   {"type": "datasource", "id": "prometheus", "name": "Prometheus", "version": "1.0.0"}],
    "title": "edgephys relays",
    "uid": "edgephys-relays",
    "description": "edgephys relay metrics (docs/operations.md, Metrics)",
    "tags": ["edgephys"],
    "timezone": "browser",
    "schemaVersion": 38,
    "version": 1,
    "refresh": "10s",
    "time": {"from": "now-1h", "to": "now"},
    "templating": {"list": [{
        "name": "instance", "label": "relay", "type": "query", "datasource": DS,
        "query": {"query": "label_values(edgephys_build_info, instance)", "refId": "instance"},
        "definition": "label_values(edgephys_build_info, instance)",
        "includeAll": True, "multi": True, "allValue": ".*", "refresh": 2,
        "current": {"selected": True, "text": ["All"], "value": ["$__all"]}}]},
    "panels": panels,
}
out = os.path.join(os.path.dirname(os.path.abspath(__file__)), "edgephys.json")
with open(out, "w") as f:
    json.dump(dashboard, f, indent=2)
    f.write("\n")
print(out, len(panels), "panels")
