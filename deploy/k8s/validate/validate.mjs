// Offline validation of deploy/k8s (ctest `k8s_manifests`):
//  1. every document is checked against its kind's Kubernetes OpenAPI schema (kubernetes-models)
//     or the Prometheus Operator CRD schema (@kubernetes-models/prometheus-operator): unknown
//     fields, wrong types and missing required fields fail;
//  2. the properties that make a room stay on one relay are present: numeric non-root UID/GID
//     matching the Dockerfile's USER, relays on Redis, one public address per relay pod,
//     a preStop drain, liveness on /healthz, a worker that takes the relay's DNS name (the
//     worker resolves it again before every attach), a PodDisruptionBudget, images by version
//     tag, the PodMonitor label kube-prometheus-stack selects on.
// Usage: node validate.mjs <repository root>. Exit 0 when valid; 1 with every failure named.
import fs from "node:fs";
import path from "node:path";
import { parseAllDocuments } from "yaml";

const root = path.resolve(process.argv[2] ?? "../../..");
const dir = path.join(root, "deploy/k8s");
const failures = [];
const fail = (m) => failures.push(m);

const kinds = {
  "v1/Service": "kubernetes-models/v1/Service",
  "v1/ConfigMap": "kubernetes-models/v1/ConfigMap",
  "apps/v1/StatefulSet": "kubernetes-models/apps/v1/StatefulSet",
  "apps/v1/Deployment": "kubernetes-models/apps/v1/Deployment",
  "policy/v1/PodDisruptionBudget": "kubernetes-models/policy/v1/PodDisruptionBudget",
  "monitoring.coreos.com/v1/PodMonitor":
    "@kubernetes-models/prometheus-operator/monitoring.coreos.com/v1/PodMonitor",
};

const docs = [];
for (const f of fs.readdirSync(dir).filter((f) => f.endsWith(".yaml")).sort()) {
  for (const d of parseAllDocuments(fs.readFileSync(path.join(dir, f), "utf8"))) {
    if (d.errors.length) { fail(`${f}: YAML: ${d.errors[0].message}`); continue; }
    const obj = d.toJS();
    if (obj == null) continue;
    const key = `${obj.apiVersion}/${obj.kind}`;
    const mod = kinds[key];
    if (!mod) { fail(`${f}: ${key} has no schema here (add it to validate.mjs)`); continue; }
    const cls = Object.values(await import(mod)).find((v) => typeof v === "function" && v.name === obj.kind);
    try {
      new cls(obj).validate();
    } catch (e) {
      fail(`${f}: ${key} ${obj.metadata?.name}: ${e.message.split("\n").slice(0, 6).join(" | ")}`);
    }
    docs.push({ file: f, obj });
  }
}
console.log(`schema-checked ${docs.length} documents: ${docs.map((d) => `${d.obj.kind}/${d.obj.metadata.name}`).join(", ")}`);

const find = (kind, name) => docs.find((d) => d.obj.kind === kind && d.obj.metadata.name === name)?.obj;
const dockerfile = fs.readFileSync(path.join(root, "Dockerfile"), "utf8");
const user = /^USER\s+(\d+):(\d+)\s*$/m.exec(dockerfile);
if (!user) fail("Dockerfile: USER is not numeric uid:gid (runAsNonRoot cannot verify a name)");

for (const d of docs.filter((d) => d.obj.spec?.template?.spec)) {
  const name = `${d.obj.kind}/${d.obj.metadata.name}`;
  const pod = d.obj.spec.template.spec;
  const sc = pod.securityContext ?? {};
  if (sc.runAsNonRoot !== true) fail(`${name}: runAsNonRoot is not true`);
  if (!Number.isInteger(sc.runAsUser) || sc.runAsUser === 0) fail(`${name}: runAsUser is not a numeric non-root UID`);
  if (!Number.isInteger(sc.runAsGroup) || sc.runAsGroup === 0) fail(`${name}: runAsGroup is not a numeric non-root GID`);
  for (const c of pod.containers) {
    if (/^localhost\//.test(c.image) || !/:[0-9]+\.[0-9]+\.[0-9]+$/.test(c.image))
      fail(`${name}: image ${c.image} is not pullable by version tag`);
    if (c.image.includes("edgephys-relay") && user && (sc.runAsUser !== +user[1] || sc.runAsGroup !== +user[2]))
      fail(`${name}: runAsUser/runAsGroup ${sc.runAsUser}:${sc.runAsGroup} differ from the Dockerfile's USER ${user[1]}:${user[2]}`);
  }
}

const sts = find("StatefulSet", "edgephys-relay");
if (!sts) fail("no StatefulSet edgephys-relay");
else {
  const c = sts.spec.template.spec.containers.find((c) => c.name === "relay");
  const cmd = [...(c.command ?? []), ...(c.args ?? [])].join(" ");
  if (!/--redis\s+"?\$redis:6379/.test(cmd) || !cmd.includes("getent hosts edgephys-redis"))
    fail("relay: not started with --redis on the edgephys-redis Service");
  if (!find("Service", "edgephys-redis") || !find("Deployment", "edgephys-redis"))
    fail("no Redis Service and Deployment");
  if (!/--public-address\s+"\$\{EDGEPHYS_PUBLIC_HOST:-\$NODE_IP\}:7777"/.test(cmd))
    fail("relay: no per-pod --public-address");
  const game = c.ports.find((p) => p.name === "game");
  if (game?.hostPort !== 7777 || game.protocol !== "UDP") fail("relay: the game port has no hostPort 7777/UDP (the per-pod address)");
  const nodeIp = c.env.find((e) => e.name === "NODE_IP");
  if (nodeIp?.valueFrom?.fieldRef?.fieldPath !== "status.hostIP") fail("relay: NODE_IP is not the node's address");
  const anti = sts.spec.template.spec.affinity?.podAntiAffinity?.requiredDuringSchedulingIgnoredDuringExecution ?? [];
  if (!anti.some((t) => t.topologyKey === "kubernetes.io/hostname")) fail("relay: two relays could share a node's hostPort");
  if (!cmd.includes("--relay-id \"$POD_NAME\"")) fail("relay: --relay-id is not the pod name");
  const pre = (c.lifecycle?.preStop?.exec?.command ?? []).join(" ");
  if (!/-X POST/.test(pre) || !pre.includes("/v1/drain") || !pre.includes("Authorization: Bearer $EDGEPHYS_ADMIN_KEY"))
    fail("relay: no preStop POST /v1/drain with the admin key");
  const deadline = +(/"deadline_s":\s*(\d+)/.exec(pre)?.[1] ?? NaN);
  if (!(deadline < sts.spec.template.spec.terminationGracePeriodSeconds))
    fail("relay: the drain deadline does not fit in terminationGracePeriodSeconds");
  if (!dockerfile.match(/^\s+curl \\$/m)) fail("Dockerfile: the runtime image lacks curl, which preStop runs");
  if (c.livenessProbe?.httpGet?.path !== "/healthz") fail("relay: liveness is not /healthz");
  if (c.readinessProbe?.httpGet?.path !== "/readyz") fail("relay: readiness is not /readyz");
  // Memory: the limit covers docs/operations.md "Memory" at the flags it runs with (idle
  // process + clients x per-connection idle + partial-message cap), with 256 MiB for rooms.
  const flag = (name, dflt) => +(new RegExp(`--${name}\\s+(\\d+)`).exec(cmd)?.[1] ?? dflt);
  const mib = 1024 * 1024;
  const worst = 40 * mib + flag("max-clients", 4096) * 210 * 1024 +
                flag("max-reassembly-bytes", 128 * mib) + 256 * mib;
  const units = { Ki: 1024, Mi: mib, Gi: 1024 * mib };
  const lim = /^(\d+)(Ki|Mi|Gi)$/.exec(c.resources?.limits?.memory ?? "");
  if (!lim || +lim[1] * units[lim[2]] < worst)
    fail(`relay: memory limit ${c.resources?.limits?.memory} under the documented worst case ${Math.ceil(worst / mib)}Mi (docs/operations.md "Memory")`);
}

const pdb = docs.find((d) => d.obj.kind === "PodDisruptionBudget")?.obj;
if (!pdb || pdb.spec.selector?.matchLabels?.["app.kubernetes.io/name"] !== "edgephys-relay")
  fail("no PodDisruptionBudget over the relays");

const phys = find("Deployment", "edgephys-phys");
if (!phys) fail("no Deployment edgephys-phys");
else {
  const c = phys.spec.template.spec.containers[0];
  const argv = [...(c.command ?? []), ...(c.args ?? [])];
  const relay = argv[argv.indexOf("--relay") + 1];
  if (argv[0] !== "/usr/local/bin/edgephys-phys" || relay !== "edgephys-relay-0.edgephys-relay:7777")
    fail("phys: not edgephys-phys --relay <relay pod DNS name> (resolved again before every attach)");
  const src = fs.readFileSync(path.join(root, "physics_backend/worker_main.cc"), "utf8");
  const loop = src.slice(src.indexOf("while (!g_stop.load())"));
  if (!/ResolveRelay\(/.test(loop)) fail("physics_backend/worker_main.cc: the relay is not resolved inside the reconnect loop");
}

const pm = docs.find((d) => d.obj.kind === "PodMonitor")?.obj;
if (pm?.metadata?.labels?.release !== "kube-prometheus-stack") fail("PodMonitor: no label release: kube-prometheus-stack");

if (failures.length) {
  for (const f of failures) console.log("FAIL:", f);
  process.exit(1);
}
console.log("deploy/k8s: schemas valid; UID, Redis, per-pod address, preStop drain, PDB, worker re-resolve, image tags, PodMonitor label present");
