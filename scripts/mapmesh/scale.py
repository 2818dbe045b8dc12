"""`swarm bench-scale`: one scenario run with more and more agents, one run at a time (the
host is what is measured), each in DIR/runs/N; one CSV row per size in DIR/scale.csv, and
DIR/scale.png drawn by scripts/plots/scale.py. docs/BENCHMARKS.md ("Swarm scale") has the
figures and the command."""

import csv
import math
import subprocess
import sys
import time
from pathlib import Path

from .procs import REPO, last_line, plot
from .run_error import RunError
from .rundir import SUMMARY, read_json

# An aligned peer whose placement is this far from the truth (the transform between the two
# maps' own fits to the landmark truth) is a false alignment: true ones are off by centimetres
# to a few decimetres in the park, false ones lie along a row of trees, metres away.
FALSE_ALIGNMENT_M = 2.0
FALSE_ALIGNMENT_DEG = 5.0
STARTUP_S_PER_AGENT = 2.0  # wall seconds the feeder waits for the agents to come up, per agent

HEADER = ["agents", "exit_0", "wall_s", "rtf", "cpu_per_agent_mean_s", "cpu_per_agent_max_s", "rss_per_agent_mean_mb",
          "rss_per_agent_max_mb", "bytes_per_landmark", "peers_aligned_mean", "cpu_per_agent_per_peer_s",
          "coverage_global_mean", "rmse_global_aligned_mean_m", "rmse_global_mean_m", "false_alignments",
          "alignments_scored"]


def _mean(values):
    values = [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    return sum(values) / len(values) if values else float("nan")


def scale_row(n, summary):
    """The CSV row of one run of n agents from its summary.json."""
    agents = summary["agents"]
    cpu = [a.get("cpu_s") for a in agents if a.get("cpu_s") is not None]
    rss = [a.get("max_rss_mb") for a in agents if a.get("max_rss_mb") is not None]
    peers = [len(a.get("peers_aligned") or []) for a in agents]
    false = scored = 0
    for a in agents:
        for e in (a.get("alignment_errors") or {}).values():
            if e.get("trans_fit_m") is None:
                continue
            scored += 1
            if e["trans_fit_m"] > FALSE_ALIGNMENT_M or math.degrees(abs(e["rot_fit_rad"])) > FALSE_ALIGNMENT_DEG:
                false += 1
    cpu_mean, peers_mean = _mean(cpu), _mean(peers)

    def metric(kind, key):
        return _mean([(a.get(kind) or {}).get(key) for a in agents])

    return {
        "agents": n,
        "exit_0": sum(1 for a in agents if a.get("exit_code") == 0),
        "wall_s": round(summary["wall_s"], 1),
        "rtf": round(summary["real_time_factor"], 2),
        "cpu_per_agent_mean_s": round(cpu_mean, 2),
        "cpu_per_agent_max_s": round(max(cpu), 2) if cpu else "",
        "rss_per_agent_mean_mb": round(_mean(rss), 1),
        "rss_per_agent_max_mb": round(max(rss), 1) if rss else "",
        "bytes_per_landmark": round(_mean([a.get("bytes_per_landmark") for a in agents]), 2),
        "peers_aligned_mean": round(peers_mean, 1),
        "cpu_per_agent_per_peer_s": round(cpu_mean / peers_mean, 4) if peers_mean > 0 else "",
        "coverage_global_mean": round(metric("global", "coverage"), 3),
        # Map accuracy (issue 19): after a rigid fit of each map to the truth, then in the robots'
        # true frames (heading drift included).
        "rmse_global_aligned_mean_m": round(metric("global", "rmse_aligned_m"), 3),
        "rmse_global_mean_m": round(metric("global", "rmse_m"), 3),
        "false_alignments": false,
        "alignments_scored": scored,
    }


def cmd_bench_scale(args):
    try:
        sizes = [int(s) for s in args.sizes.split(",") if s.strip()]
    except ValueError:
        raise RunError(f"--sizes {args.sizes}: expected comma-separated agent counts, e.g. 8,16,32", 2)
    if not sizes or min(sizes) <= 0:
        raise RunError(f"--sizes {args.sizes}: expected positive agent counts, e.g. 8,16,32", 2)
    out = Path(args.out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    path = out / "scale.csv"
    rows, failed = [], 0
    start = time.monotonic()
    print(f"bench-scale: {args.scenario} with {sizes} agents, one run at a time", flush=True)
    for n in sizes:
        run_dir = out / "runs" / str(n)
        cmd = [sys.executable, str(REPO / "scripts" / "swarm"), "run", args.scenario, "--out", str(run_dir),
               "--agents", str(n), "--quiet", "--no-report", "--timeout", str(args.timeout),
               # The host is what is measured: the reference (park4 x 64: 7 s after the run) is left out.
               "--no-reference",
               "--force",  # its own runs/N folder: a benchmark run again replaces its runs
               # N processes discovering each other on two cores take longer than the scenario's
               # 30 s to come up (128 agents: about a minute); a --set of the same key wins.
               "--set", f"feeder.startup_timeout_s={max(30.0, STARTUP_S_PER_AGENT * n):g}"]
        for s in args.set or []:
            cmd += ["--set", s]
        r = subprocess.run(cmd, capture_output=True, text=True)
        if not (run_dir / SUMMARY).exists():
            raise RunError(f"{n} agents: {last_line(r.stderr, f'exit code {r.returncode}')}", 1)
        summary = read_json(run_dir / SUMMARY)
        failed += r.returncode != 0
        row = scale_row(n, summary)
        rows.append(row)
        print(f"[{n} agents] wall {row['wall_s']} s, RTF {row['rtf']}, CPU/agent {row['cpu_per_agent_mean_s']} s "
              f"(max {row['cpu_per_agent_max_s']}), peers aligned {row['peers_aligned_mean']}, coverage "
              f"{row['coverage_global_mean']}, false alignments {row['false_alignments']}, exit 0: "
              f"{row['exit_0']}/{n}  ({time.monotonic() - start:.0f} s)", flush=True)
        # Written after every size: a long sweep stopped half way keeps what it measured.
        with open(path, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=HEADER)
            w.writeheader()
            w.writerows(rows)
    print(f"csv:  {path}")
    if not plot("scale.py", out, "scale plot"):
        return 1
    print(f"plot: {out / 'scale.png'}")
    return 1 if failed else 0
