#!/usr/bin/env bash
# Checks the deployment files without running them (ctest `deploy_files`):
#  * every YAML and JSON file parses (python3 + PyYAML when present, else JSON only);
#  * the compose file has Redis, two relays, a PhyS worker and Prometheus; the relays' admin
#    API listens off-loopback only with a key in the environment;
#  * the k8s StatefulSet probes /healthz (liveness) and /readyz (readiness) on the admin port;
#  * every edgephys_ metric the Grafana dashboard queries is one the relay exports
#    (metrics/metrics_exporter.cc), and promtool parses every query (as recording rules) and
#    the Prometheus config;
#  * `podman-compose config` and `kubectl apply --dry-run=client` when those tools exist.
# Prints what it could not run.
set -euo pipefail
cd "$(dirname "$0")/.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

python3 - "$work" <<'PY'
import json, pathlib, re, sys
work = pathlib.Path(sys.argv[1])
try:
    import yaml
except ImportError:
    yaml = None
    print("note: PyYAML missing; YAML files not parsed")
docs = {}
for p in sorted(pathlib.Path("deploy").rglob("*")):
    if p.suffix in (".yaml", ".yml") and yaml:
        docs[str(p)] = [d for d in yaml.safe_load_all(p.read_text()) if d is not None]
    elif p.suffix == ".json":
        docs[str(p)] = [json.loads(p.read_text())]
print("parsed:", ", ".join(f"{k} ({len(v)})" for k, v in docs.items()))

def fail(msg):
    print("FAIL:", msg); sys.exit(1)

if yaml:
    compose = docs["deploy/compose.yaml"][0]
    services = compose["services"]
    for s in ("redis", "relay-a", "relay-b", "phys", "prometheus"):
        if s not in services: fail(f"compose: no service {s}")
    for s in ("relay-a", "relay-b"):
        cmd, env = services[s]["command"], services[s]["environment"]
        addr = cmd[cmd.index("--admin-addr") + 1]
        if not addr.startswith("127.") and "EDGEPHYS_ADMIN_KEY" not in env:
            fail(f"compose: {s} serves the admin API on {addr} without a key")
        if "--physics-idle" not in cmd: fail(f"compose: {s} runs PhyS threads at normal priority")
    if "edgephys-phys" not in " ".join(services["phys"]["entrypoint"]): fail("compose: phys is not edgephys-phys")
    kinds = {}
    for d in docs["deploy/k8s/relay.yaml"]: kinds.setdefault(d["kind"], []).append(d)
    sts = kinds["StatefulSet"][0]
    c = sts["spec"]["template"]["spec"]["containers"][0]
    if c["livenessProbe"]["httpGet"]["path"] != "/healthz": fail("k8s: liveness is not /healthz")
    if "--physics-idle" not in c["args"]: fail("k8s: the relay runs PhyS threads at normal priority")
    if c["readinessProbe"]["httpGet"]["path"] != "/readyz": fail("k8s: readiness is not /readyz")
    if sts["spec"]["template"]["metadata"]["annotations"].get("prometheus.io/scrape") != "true":
        fail("k8s: no scrape annotation")
    if not kinds.get("Service"): fail("k8s: no Service")
    pm = docs["deploy/k8s/podmonitor.yaml"][0]
    if pm["kind"] != "PodMonitor": fail("k8s: podmonitor.yaml is not a PodMonitor")

exported = set(re.findall(r'"(edgephys_[a-z_]+)"', pathlib.Path("metrics/metrics_exporter.cc").read_text()))
dash = docs["deploy/grafana/edgephys.json"][0]
exprs = [t["expr"] for p in dash["panels"] for t in p.get("targets", [])]
used = set()
for e in exprs:
    for m in re.findall(r"edgephys_[a-z_]+", e):
        base = re.sub(r"_(bucket|sum|count)$", "", m)
        if base not in exported: fail(f"dashboard queries {m}, which the relay does not export")
        used.add(base)
print(f"dashboard: {len(exprs)} queries over {len(used)} of the relay's {len(exported)} metrics")
rules = ["groups:", "  - name: dashboard", "    rules:"]
for i, e in enumerate(exprs):
    e = e.replace("$instance", ".*")
    rules += [f"      - record: dashboard_query_{i}", f"        expr: {json.dumps(e)}"]
(work / "rules.yml").write_text("\n".join(rules) + "\n")
PY

if command -v promtool >/dev/null; then
  promtool check rules "$work/rules.yml" >/dev/null || { echo "FAIL: promtool rejects a dashboard query"; promtool check rules "$work/rules.yml"; exit 1; }
  promtool check config deploy/prometheus.yml >/dev/null || { echo "FAIL: promtool rejects deploy/prometheus.yml"; exit 1; }
  echo "promtool: dashboard queries and deploy/prometheus.yml accepted"
else
  echo "not run: promtool (not installed)"
fi
if command -v podman-compose >/dev/null; then
  EDGEPHYS_SECRET=x EDGEPHYS_ADMIN_KEY=y podman-compose -f deploy/compose.yaml config >/dev/null
  echo "podman-compose config: accepted"
else
  echo "not run: podman-compose config (podman-compose not installed)"
fi
if command -v kubectl >/dev/null; then
  # An empty kubeconfig: never talk to a real cluster from a test.
  if KUBECONFIG="$work/none" kubectl apply --dry-run=client --validate=false -f deploy/k8s/relay.yaml -f deploy/k8s/phys.yaml \
       -f deploy/k8s/redis.yaml >"$work/kubectl.out" 2>&1; then
    echo "kubectl apply --dry-run=client: $(tr '\n' ';' <"$work/kubectl.out")"
  else
    echo "not run: kubectl dry run needs a cluster here: $(head -n1 "$work/kubectl.out")"
  fi
else
  echo "not run: kubectl (not installed)"
fi
echo "deployment files valid"
