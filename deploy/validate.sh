#!/usr/bin/env bash
# Checks the deployment files without running them (ctest `deploy_files`):
#  * every YAML and JSON file parses (python3 + PyYAML when present, else JSON only);
#  * the compose file has Redis, two relays, a PhyS worker and Prometheus; the relays' admin
#    API listens off-loopback only with a key in the environment;
#  * the k8s StatefulSet probes /healthz (liveness) and /readyz (readiness) on the admin port;
#  * every edgephys_ metric the Grafana dashboard queries is one the relay exports
#    (relay/relay_metrics.cc, metrics/), and promtool parses every query (as recording rules) and
#    the Prometheus config;
#  * podman-compose (Debian 12's 1.0.3 has no `config`): `--dry-run up` with podman replaced by
#    `true`, so nothing is built, created or started; the podman commands it would run must
#    carry --redis, the ulimits and the locally built images;
#  * `kubectl apply --dry-run=client` when kubectl exists. The Kubernetes schema check is
#    ctest `k8s_manifests` (deploy/k8s/validate).
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
    if "node_modules" in p.parts or p.name == "package-lock.json":
        continue
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
        cmd, env = " ".join(services[s]["command"]).split(), services[s]["environment"]
        addr = cmd[cmd.index("--admin-addr") + 1]
        if not addr.startswith("127.") and "EDGEPHYS_ADMIN_KEY" not in env:
            fail(f"compose: {s} serves the admin API on {addr} without a key")
        if "--physics-idle" not in cmd: fail(f"compose: {s} runs PhyS threads at normal priority")
        if '"$$r:6379"' not in cmd: fail(f"compose: {s} is not on Redis (--redis)")
        if "--public-address" not in cmd: fail(f"compose: {s} has no --public-address for redirects")
    for name, svc in services.items():
        if "ipv4_address" in json.dumps(svc.get("networks", {})):
            fail(f"compose: {name} has a static ipv4_address (podman-compose 1.0.3 fails on it)")
        if not svc["image"].startswith("localhost/"):
            fail(f"compose: {name} uses {svc['image']} from a registry, not an image built here")
    if "edgephys-phys" not in " ".join(services["phys"]["entrypoint"]): fail("compose: phys is not edgephys-phys")
    kinds = {}
    for d in docs["deploy/k8s/relay.yaml"]: kinds.setdefault(d["kind"], []).append(d)
    sts = kinds["StatefulSet"][0]
    c = sts["spec"]["template"]["spec"]["containers"][0]
    if c["livenessProbe"]["httpGet"]["path"] != "/healthz": fail("k8s: liveness is not /healthz")
    if "--physics-idle" not in " ".join(c["args"]): fail("k8s: the relay runs PhyS threads at normal priority")
    if c["readinessProbe"]["httpGet"]["path"] != "/readyz": fail("k8s: readiness is not /readyz")
    if sts["spec"]["template"]["metadata"]["annotations"].get("prometheus.io/scrape") != "true":
        fail("k8s: no scrape annotation")
    if not kinds.get("Service"): fail("k8s: no Service")
    pm = docs["deploy/k8s/podmonitor.yaml"][0]
    if pm["kind"] != "PodMonitor": fail("k8s: podmonitor.yaml is not a PodMonitor")

exported = set(re.findall(r'"(edgephys_[a-z_]+)"', pathlib.Path("relay/relay_metrics.cc").read_text()))
exported |= set(re.findall(r'"(edgephys_[a-z_]+)"', pathlib.Path("metrics/metrics_exporter.cc").read_text()))
exported_process = set(re.findall(r'"(process_[a-z_]+)"', pathlib.Path("metrics/process_metrics.cc").read_text()))
dash = docs["deploy/grafana/edgephys.json"][0]
exprs = [t["expr"] for p in dash["panels"] for t in p.get("targets", [])]
used = set()
for e in exprs:
    for m in re.findall(r"edgephys_[a-z_]+", e):
        base = re.sub(r"_(bucket|sum|count)$", "", m)
        if base not in exported: fail(f"dashboard queries {m}, which the relay does not export")
        used.add(base)
    for m in re.findall(r"\bprocess_[a-z_]+", e):
        if m not in exported_process: fail(f"dashboard queries {m}, which the exporter does not export")
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
  if ! EDGEPHYS_SECRET=x EDGEPHYS_ADMIN_KEY=y podman-compose --podman-path "$(command -v true)" --dry-run \
       -p edgephys-validate -f deploy/compose.yaml up -d >"$work/compose.out" 2>&1; then
    echo "FAIL: podman-compose rejects deploy/compose.yaml:"; cat "$work/compose.out"; exit 1
  fi
  for want in "edgephys-validate_relay-a_1" "edgephys-validate_relay-b_1" "edgephys-validate_phys_1" \
              "edgephys-validate_prometheus_1" "edgephys-validate_redis_1" '--redis "$r:6379"' \
              "--ulimit nproc=4096:4096" "--relay relay-a:7777"; do
    grep -qF -- "$want" "$work/compose.out" || { echo "FAIL: podman-compose would not run: $want"; cat "$work/compose.out"; exit 1; }
  done
  echo "podman-compose $(dpkg-query -W -f '${Version}' podman-compose 2>/dev/null || echo '(version unknown)') --dry-run up: accepted"
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
