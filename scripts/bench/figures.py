#!/usr/bin/env python3
"""The figures page's tables and charts, from scenario JSON.

  figures.py machine BUILD_DIR                 -> the machine block as JSON on stdout
  figures.py extract RAW_DIR MACHINE.json OUT  -> figures JSON (one table per scenario)
  figures.py render FIGURES.json DOC CHART_DIR [BASE.json [MERGED.json]]
                                               -> rewrites DOC's tables between
                                                  <!-- table:NAME --> and <!-- /table:NAME -->
                                                  and the machine block; .dat/.gp/.png charts;
                                                  tables not in FIGURES come from BASE; the
                                                  union is written to MERGED
  figures.py measured FIGURES.json NAME...     -> exit 1 unless each NAME has rows with numbers
  figures.py check DOC [NAME...]               -> exit 1 unless every table (or each NAME) has
                                                  at least one row and a number in every row

A table is {"title", "columns": [...], "rows": [[...]], "chart": {...} or absent}. A chart is
drawn from its table: x = column "x", one series per name in "y", gnuplot into CHART_DIR/NAME.png.
Raw inputs are edgephys-loadgen --json files named RAW_DIR/<table>.json (see scripts/bench.sh);
a table whose raw file is missing is left out of the figures JSON (the page keeps its rows).
"""
import glob
import json
import os
import platform
import re
import subprocess
import sys

# The anchors the ratios are taken against (docs/benchmarks.md "Anchors"; the paper's tables).
PAPER_RELAY_KBPS = {32: 12.56, 64: 24.86, 128: 49.50, 256: 96.80, 512: 193.60}
PAPER_PHOTON_KBPS = {32: 16.52, 64: 32.58, 128: 63.00, 256: 130.50, 512: 257.40}
PAPER_OBJ_MBPS = {500: 0.72, 1000: 1.32, 2000: 2.70, 5000: 5.45, 7500: 8.31, 10000: 10.95}
PAPER_BUNNY_MBPS = {1: 0.46, 3: 1.40}


def fmt(v, digits=3):
    if v is None:
        return "-"
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return f"{v:,}"
    if isinstance(v, float):
        if v != v:
            return "n/a"
        if abs(v) >= 1000:
            return f"{v:,.0f}"
        return f"{v:.{digits}f}"
    return str(v)


def machine(build_dir):
    cpu = platform.processor() or "unknown"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    compiler = "unknown"
    build_type = ""
    cache = os.path.join(build_dir, "CMakeCache.txt")
    if os.path.exists(cache):
        for line in open(cache):
            if line.startswith("CMAKE_CXX_COMPILER:"):
                cxx = line.split("=", 1)[1].strip()
                try:
                    compiler = subprocess.run([cxx, "--version"], capture_output=True,
                                              text=True).stdout.splitlines()[0]
                except (OSError, IndexError):
                    compiler = cxx
            if line.startswith("CMAKE_BUILD_TYPE:"):
                build_type = line.split("=", 1)[1].strip()
    def git(*args):
        r = subprocess.run(["git", *args], capture_output=True, text=True)
        return r.stdout.strip() if r.returncode == 0 else "unknown"
    commit = git("rev-parse", "--short=12", "HEAD")
    if git("status", "--porcelain", "--untracked-files=no"):
        commit += " (with local changes)"
    return {"cpu": cpu, "cores": os.cpu_count(), "kernel": platform.release(),
            "compiler": compiler, "build_type": build_type or "unknown", "commit": commit}


def load(raw_dir, name):
    """RAW_DIR/NAME.json and RAW_DIR/NAME.<n>.json (one scenario run in several commands)."""
    paths = sorted(glob.glob(os.path.join(raw_dir, name + ".json")) +
                   glob.glob(os.path.join(raw_dir, name + ".[0-9]*.json")))
    out = []
    for path in paths:
        with open(path) as f:
            out.append(json.load(f))
    return out


def t_relay_compare(j):
    rows = []
    for r in j["results"]:
        n = r["objects"]
        anchor = PAPER_PHOTON_KBPS if r["mode"] == "photon" else PAPER_RELAY_KBPS
        kbps = r["egress_bytes_per_s_per_receiver"] / 1000.0
        ip_udp = r.get("ip_udp_bytes_per_s_per_receiver")
        rows.append([r["mode"], n, kbps, ip_udp / 1000.0 if ip_udp is not None else None,
                     anchor.get(n),
                     kbps / anchor[n] if n in anchor else None,
                     r["bytes_per_update"], r["pos_err_max_m"] * 1000, r["rot_err_max_deg"]])
    return rows


def t_multiobject(j):
    rows = []
    for r in j["results"]:
        n = r["objects"]
        mbps = r.get("egress_mbit_per_s_per_client", 0.0)
        rows.append([n, r.get("step_ms_median", 0.0), r.get("raw_bullet_step_ms_median", 0.0),
                     r.get("step_ratio_phys_to_raw", 0.0), mbps,
                     r.get("ip_udp_mbit_per_s_per_client"), PAPER_OBJ_MBPS.get(n),
                     mbps / PAPER_OBJ_MBPS[n] if n in PAPER_OBJ_MBPS else None,
                     r.get("display_err_p99_m", 0.0) * 1000, r.get("pos_err_sent_max_m", 0.0) * 1000])
    return rows


def t_softbody(j):
    rows = []
    for r in j["results"]:
        b = r["bunnies"]
        mbps = r["egress_mbit_per_s_per_client"]
        rows.append([b, r["particles"], r["step_ms_median"], mbps,
                     r.get("ip_udp_mbit_per_s_per_client"), PAPER_BUNNY_MBPS.get(b),
                     mbps / PAPER_BUNNY_MBPS[b] if b in PAPER_BUNNY_MBPS else None,
                     r["node_err_p99_m"] * 1000, r["node_err_sent_max_m"] * 1000])
    return rows


def t_ccu(j):
    runs = j.get("runs") or [{"summary": j["summary"]}]
    impaired = j["options"].get("impaired", {}).get("fraction", 0.0) * 100
    rows = []
    for run in runs:
        s = run.get("summary", run)
        rows.append([s["users"], s["rooms"], impaired, s["reliable_lost"], s["hand_update_ratio"],
                     s["latency_arrival_ms_p50"], s["latency_arrival_ms_p99"],
                     s["latency_user_to_user_ms_p99"], s["relay_cpu_mean"] or 0.0,
                     s.get("relay_us_per_update"), s.get("bytes_per_update"),
                     s["egress_bytes_per_s_per_user"]])
    return rows


def t_ceiling(j):
    rows = []
    for s in j["summary"]:
        rows.append([s["io_threads"], s["clients_joined"], s["relay_packets_per_s"],
                     s["mean_datagram_bytes"], s["iperf3_packets_per_s"], s["ratio_packets"],
                     s["relay_cpu_cores"]])
    return rows


def t_interp(j):
    by = {}
    for r in j["results"]:
        if r["network"] != "clean":
            continue
        by.setdefault(r["rate_hz"], {})[r["interpolator"]] = r
    rows = []
    for rate in sorted(by):
        d = by[rate]
        def p99(name):
            return d[name]["pos_err_p99_m"] * 1000 if name in d else None
        any_r = next(iter(d.values()))
        rows.append([rate, p99("lerp_slerp"), p99("hermite"), p99("none"), any_r["display_delay_ms"]])
    return rows


def t_codec(j):
    labels = {"step": ("step, mm", 1000.0), "rotation_bound": ("rotation bound, deg", 1.0),
              "threshold": ("threshold, mm", 1000.0)}
    rows = []
    for r in j["results"]:
        label, scale = labels.get(r["dimension"], (r["dimension"], 1.0))
        rows.append([label, r["value"] * scale, r["bytes_per_s_per_receiver"] / 1000.0,
                     r["bytes_per_update"], r["pos_err_max_m"] * 1000, r["rot_err_max_deg"]])
    return rows


def t_codec_bench(j):
    rows = []
    for b in j.get("benchmarks", []):
        if b.get("aggregate_name", "median") != "median" or "items_per_second" not in b:
            continue
        rows.append([b.get("run_name", b["name"]), b["items_per_second"] / 1e6,
                     b.get("payload_bytes_per_entity")])
    return rows


def t_messages(j):
    o, s = j["options"], j["summary"]
    return [["unreliable" if o["unreliable"] else "reliable", o["users"], o["rate_hz"],
             o["payload_bytes"], s["sent_per_s"], s["delivered_per_s"], s["relay_cpu"],
             s["delivered_per_core_s"], s["accepted_per_core_s"],
             s["relay_egress_bytes_per_s"] / 1e6, s["received_total"] / max(s["expected_total"], 1),
             s["property_sent_bytes"], s["property_received_bytes"]]]


def median_rows(rows, key_cols):
    """One row per key (the first KEY_COLS cells): the median of each other cell over runs."""
    groups = {}
    for row in rows:
        groups.setdefault(tuple(row[:key_cols]), []).append(row)
    out = []
    for key, rs in groups.items():
        med = list(key)
        for i in range(key_cols, len(rs[0])):
            vals = sorted(r[i] for r in rs if r[i] is not None)
            med.append(vals[len(vals) // 2] if vals else None)
        out.append(med)
    return out


EXTRACTORS = {
    "messages": t_messages,
    "relay_compare": t_relay_compare,
    "multiobject_quarter": t_multiobject,
    "multiobject_full": t_multiobject,
    "softbody": t_softbody,
    "ccu": t_ccu,
    "ceiling": t_ceiling,
    "interp_sweep": t_interp,
    "codec_sweep": t_codec,
    "codec_bench": t_codec_bench,
}


def extract(raw_dir, machine_path, out_path, template_path):
    with open(template_path) as f:
        template = json.load(f)
    with open(machine_path) as f:
        figures = {"machine": json.load(f), "tables": {}}
    for name, fn in EXTRACTORS.items():
        runs = load(raw_dir, name)
        if not runs:
            continue
        table = dict(template["tables"][name])
        table["commit"] = figures["machine"]["commit"]
        table["rows"] = [row for j in runs for row in fn(j)]
        if table.get("median_key_columns"):  # several runs of one configuration: medians
            table["rows"] = median_rows(table["rows"], table["median_key_columns"])
        figures["tables"][name] = table
    with open(out_path, "w") as f:
        json.dump(figures, f, indent=1)
        f.write("\n")


def markdown(table):
    cols = table["columns"]
    digits = table.get("digits", [3] * len(cols))
    out = ["| " + " | ".join(cols) + " |", "|" + "|".join("---" for _ in cols) + "|"]
    for row in table["rows"]:
        out.append("| " + " | ".join(fmt(v, d) for v, d in zip(row, digits)) + " |")
    return "\n".join(out)


def machine_md(m, tables=None):
    lines = [
        "| CPU | cores | kernel | compiler | build | commit |",
        "|---|---|---|---|---|---|",
        f"| {m['cpu']} | {m['cores']} | {m['kernel']} | {m['compiler']} | {m['build_type']} | {m['commit']} |",
    ]
    older = {}  # tables a partial run (--only) kept from an earlier run: commit -> names
    for name, table in (tables or {}).items():
        if table.get("commit", m["commit"]) != m["commit"]:
            older.setdefault(table["commit"], []).append(name)
    if older:
        lines.append("")
        lines.append("Measured at " + m["commit"] + ": " +
                     ", ".join(n for n, t in tables.items() if t.get("commit", m["commit"]) == m["commit"]) +
                     ". Kept from earlier runs: " +
                     "; ".join(f"{', '.join(names)} at {c}" for c, names in older.items()) + ".")
    return "\n".join(lines)


def replace_block(text, name, body):
    pat = re.compile(r"(<!-- %s -->\n)(?:.*?\n)?(<!-- /%s -->)" % (re.escape(name), re.escape(name)),
                     re.S)
    if not pat.search(text):
        sys.exit(f"figures.py: the page has no <!-- {name} --> block")
    return pat.sub(lambda m: m.group(1) + body + "\n" + m.group(2), text)


def q(text):
    """A gnuplot double-quoted string."""
    return '"' + str(text).replace("\\", "\\\\").replace('"', '\\"') + '"'


def chart(name, table, chart_dir):
    c = table.get("chart")
    if not c:
        return
    cols = table["columns"]
    x = cols.index(c["x"])
    ys = [cols.index(y) for y in c["y"]]
    group = cols.index(c["group"]) if "group" in c else None
    groups = {}
    for row in table["rows"]:
        key = str(row[group]) if group is not None else ""
        groups.setdefault(key, []).append(row)
    dat = os.path.join(chart_dir, name + ".dat")
    with open(dat, "w") as f:
        f.write(f"# {table['title']}: {cols[x]} then " + ", ".join(cols[i] for i in ys) + "\n")
        for key, rows in groups.items():
            f.write(f"# {key}\n" if key else "")
            for row in rows:
                f.write(" ".join("?" if row[i] is None else str(row[i]).replace(" ", "_")
                                 for i in [x] + ys) + "\n")
            f.write("\n\n")
    plots = []
    for gi, key in enumerate(groups):
        for yi, col in enumerate(ys):
            label = key if key and len(ys) == 1 else (key + " " if key else "") + cols[col]
            using = f"{2 + yi}:xtic(1)" if c.get("categorical") else f"1:{2 + yi}"
            plots.append(f"'{name}.dat' index {gi} using {using} with linespoints lw 2 title {q(label)}")
    gp = os.path.join(chart_dir, name + ".gp")
    with open(gp, "w") as f:
        f.write("# Written by scripts/bench/figures.py from docs/charts/figures.json; do not edit.\n")
        f.write("set terminal pngcairo size 800,450 noenhanced font 'sans,10'\n")
        f.write(f"set output '{name}.png'\n")
        f.write(f"set title {q(c.get('title', table['title']))}\n")
        f.write(f"set xlabel {q(cols[x])}\nset ylabel {q(c.get('ylabel', cols[ys[0]]))}\n")
        f.write("set grid\nset key top left\nset datafile missing '?'\n")
        if c.get("logx"):
            f.write("set logscale x 2\n")
        if c.get("logy"):
            f.write("set logscale y\n")
        f.write("plot " + ", \\\n     ".join(plots) + "\n")
    r = subprocess.run(["gnuplot", name + ".gp"], cwd=chart_dir, capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write(f"figures.py: gnuplot failed on {gp}:\n{r.stderr}")
        sys.exit(1)


def render(figures_path, doc_path, chart_dir, base_path=None, merged_path=None):
    with open(figures_path) as f:
        figures = json.load(f)
    if base_path:  # tables measured in this run override the committed ones
        with open(base_path) as f:
            base = json.load(f)
        for table in base["tables"].values():  # tables kept from the run that measured them
            table.setdefault("commit", base["machine"]["commit"])
        base["tables"].update(figures["tables"])
        base["machine"] = figures["machine"]
        figures = base
    with open(doc_path) as f:
        text = f.read()
    text = replace_block(text, "machine", machine_md(figures["machine"], figures["tables"]))
    for name, table in figures["tables"].items():
        text = replace_block(text, "table:" + name, markdown(table))
        chart(name, table, chart_dir)
    with open(doc_path, "w") as f:
        f.write(text)
    if merged_path:
        with open(merged_path, "w") as f:
            json.dump(figures, f, indent=1)
            f.write("\n")


def measured(figures_path, names):
    """Exit 1 unless each NAME was measured: a table with rows, and a number in every row."""
    with open(figures_path) as f:
        tables = json.load(f)["tables"]
    bad = []
    for name in names:
        rows = tables.get(name, {}).get("rows", [])
        if not rows:
            bad.append(f"{name}: not measured")
        for row in rows:
            if not any(isinstance(v, (int, float)) and not isinstance(v, bool) and v == v
                       for v in row[1:]):
                bad.append(f"{name}: a row without a number: {row}")
    for b in bad:
        print("figures measured:", b)
    print(f"figures measured: {len(names)} tables, {len(bad)} problems")
    return 1 if bad else 0


def check(doc_path, names):
    with open(doc_path) as f:
        text = f.read()
    blocks = dict(re.findall(r"<!-- table:(\w+) -->\n(.*?)\n<!-- /table:\1 -->", text, re.S))
    bad = []
    for name in names or blocks:
        body = blocks.get(name)
        if body is None:
            bad.append(f"{name}: no table")
            continue
        rows = [l for l in body.splitlines()[2:] if l.startswith("|")]
        if not rows:
            bad.append(f"{name}: no rows")
        for row in rows:
            if not re.search(r"\|\s*-?[0-9][0-9,]*(\.[0-9]+)?\s*(\||$)", row):
                bad.append(f"{name}: a row without a number: {row}")
    for b in bad:
        print("figures check:", b)
    print(f"figures check: {len(blocks)} tables, {len(bad)} problems")
    return 1 if bad else 0


def main(argv):
    if len(argv) >= 3 and argv[1] == "machine":
        json.dump(machine(argv[2]), sys.stdout, indent=1)
        print()
        return 0
    if len(argv) == 6 and argv[1] == "extract":
        extract(argv[2], argv[3], argv[4], argv[5])
        return 0
    if len(argv) in (5, 6, 7) and argv[1] == "render":
        render(*argv[2:])
        return 0
    if len(argv) >= 3 and argv[1] == "measured":
        return measured(argv[2], argv[3:])
    if len(argv) >= 3 and argv[1] == "check":
        return check(argv[2], argv[3:])
    sys.stderr.write(__doc__)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv))
