"""`swarm sweep`: one scenario run over a list of values of one scenario key and a list of
seeds, several runs at a time, each in DIR/runs/; one CSV row per agent and run in
DIR/sweep.csv, and DIR/sweep.png drawn by scripts/plots/sweep.py."""

import csv
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from .columns import SWEEP_HEADER, sweep_row
from .run import REPO, RunError, last_line, plot
from .rundir import SUMMARY, read_json


def _run_one(args, value, seed, run_dir):
    """One `swarm run` with KEY=value (and seed=seed unless None); its summary and exit code."""
    cmd = [sys.executable, str(REPO / "scripts" / "swarm"), "run", args.scenario, "--out", str(run_dir),
           "--set", f"{args.param}={value}", "--quiet", "--no-report", "--timeout", str(args.timeout),
           "--force"]  # the sweep's own runs/ folder: a sweep run again replaces its runs, as before
    if seed is not None:
        cmd += ["--set", f"seed={seed}"]
    if args.agents:
        cmd += ["--agents", str(args.agents)]
    for s in args.set or []:
        cmd += ["--set", s]
    if getattr(args, "no_reference", False):
        cmd += ["--no-reference"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if not (run_dir / SUMMARY).exists():
        reason = last_line(r.stderr, f"exit code {r.returncode}")
        raise RunError(f"{args.param}={value}" + (f" seed {seed}" if seed is not None else "") + f": {reason}", 1)
    return read_json(run_dir / SUMMARY), r.returncode


def cmd_sweep(args):
    values = [v for v in args.values.split(",") if v.strip()]
    try:
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()] if args.seeds else [None]
    except ValueError:
        raise RunError(f"--seeds {args.seeds}: expected comma-separated integers", 2)
    if not values:
        raise RunError("--values: give at least one value, e.g. --values 0,10,20", 2)
    out = Path(args.out)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    jobs = args.jobs or max(1, min(2, os.cpu_count() or 1))
    plan = [(v, s) for v in values for s in seeds]
    start = time.monotonic()
    print(f"sweep: {args.param} over {values}, seeds {seeds if seeds != [None] else 'of the scenario'}: "
          f"{len(plan)} runs, {jobs} at a time", flush=True)

    def one(item):
        v, seed = item
        name = f"{args.param}={v}" + (f"_seed{seed}" if seed is not None else "")
        return _run_one(args, v, seed, out / "runs" / name)

    results = {}
    failed = 0
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        for done, ((v, s), (summary, code)) in enumerate(zip(plan, pool.map(one, plan)), 1):
            results[(v, s)] = summary
            failed += code != 0
            cov = [a["global"]["coverage"] for a in summary["agents"] if a.get("global") and
                   a["global"].get("coverage") is not None]
            mean_cov = sum(cov) / len(cov) if cov else float("nan")
            print(f"[{done}/{len(plan)}] {args.param}={v}" + (f" seed {s}" if s is not None else "") + ": "
                  f"mean global coverage {mean_cov:.2f}  ({time.monotonic() - start:.0f} s)", flush=True)
    path = out / "sweep.csv"
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow([args.param] + SWEEP_HEADER)
        for (v, s) in plan:
            summary = results[(v, s)]
            w.writerows(sweep_row(v, s if s is not None else "", summary, a) for a in summary["agents"])
    print(f"csv:  {path}")
    if not plot("sweep.py", out, "sweep plot"):
        return 1
    print(f"plot: {out / 'sweep.png'}")
    return 1 if failed else 0
