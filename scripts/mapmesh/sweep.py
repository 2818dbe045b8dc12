"""`swarm sweep`: one scenario run over a grid of scenario values (every combination of the values
of each --param) and a list of seeds, with the run options given (faults, pace, injection,
security, hosts), several runs at a time, each in DIR/runs/. Every run is checked as `swarm run`
checks it before the first one starts. One CSV row per agent and run in DIR/sweep.csv (a column
per parameter, then the seed and the agent's figures), and DIR/sweep.png drawn by
scripts/plots/sweep.py."""

import csv
import hashlib
import itertools
import math
import os
import re
import shutil
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

from .columns import SWEEP_HEADER, sweep_row
from . import provenance
from .run import REPO, RunError, SwarmRun, last_line, plot
from .rundir import SUMMARY, read_json

SEED_KEY = "seed"
# A sweep runs at most this many runs (grid points times seeds); a larger grid is refused in one
# line before anything is checked: split it into several sweeps.
MAX_RUNS = 1000


def parse_params(params, values):
    """[(key, [values])] from the --param items (KEY=V1,V2 each, or one KEY with --values V1,V2).
    RunError (exit 2) names the item at fault."""
    if values is not None:
        if len(params) != 1 or "=" in params[0]:
            raise RunError("--values goes with a single --param KEY; or give each as --param KEY=V1,V2,...", 2)
        params = [f"{params[0]}={values}"]
    grid, seen = [], set()
    for item in params:
        key, sep, text = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise RunError(f"--param {item}: expected KEY=V1,V2,... (e.g. radio.range_m=8,20)", 2)
        if key == SEED_KEY:
            raise RunError(f"--param {item}: give seeds with --seeds", 2)
        if key in seen:
            raise RunError(f"--param {item}: {key} is swept twice; give its values once", 2)
        vals = [v.strip() for v in text.split(",") if v.strip()]
        if not vals:
            raise RunError(f"--param {item}: no values; give at least one, e.g. {key}=0,10,20", 2)
        if len(set(vals)) != len(vals):
            raise RunError(f"--param {item}: a value is given twice", 2)
        seen.add(key)
        grid.append((key, vals))
    return grid


def parse_seeds(text):
    if not text:
        return [None]
    try:
        seeds = [int(s) for s in text.split(",") if s.strip()]
    except ValueError:
        raise RunError(f"--seeds {text}: expected comma-separated integers", 2) from None
    if not seeds or len(set(seeds)) != len(seeds):
        raise RunError(f"--seeds {text}: expected distinct comma-separated integers", 2)
    return seeds


def run_name(point, seed):
    """The run's folder under runs/: KEY=VALUE_..._seedS, with anything but [A-Za-z0-9._=-] as '-'
    and then, so that values differing only there (`a b`, `a/b`, `a+b`) keep their own folders,
    the first 8 hex digits of the SHA-1 of the name as given."""
    name = "_".join(f"{k}={v}" for k, v in point) + (f"_seed{seed}" if seed is not None else "")
    safe = re.sub(r"[^A-Za-z0-9._=-]", "-", name)
    return safe if safe == name else f"{safe}-{hashlib.sha1(name.encode()).hexdigest()[:8]}"


def plan_size(grid, seeds):
    """The runs of a grid and seeds (a product of the counts: the plan is not built)."""
    return math.prod(len(v) for _, v in grid) * len(seeds)


def option_flags(args, defaults):
    """The `swarm run` flags that give a run the options the sweep was given (provenance.OPTIONS
    but the scenario; those left at their defaults are not repeated)."""
    return provenance.option_flags(args, defaults)


def point_flags(point, seed):
    seed_flags = ["--set", f"{SEED_KEY}={seed}"] if seed is not None else []
    return [f for k, v in point for f in ("--set", f"{k}={v}")] + seed_flags


def describe(point, seed):
    return " ".join(f"{k}={v}" for k, v in point) + (f" seed {seed}" if seed is not None else "")


def check_all(args, plan, out, progress=None, every_s=2.0):
    """Every point of the plan checked once as `swarm run` checks it (scenario and overrides, fault
    schedule, injector, hosts), with its first seed (any integer is a seed), before the first run
    starts. RunError names the run at fault. `progress(done, total)` is called every `every_s`
    seconds of checking and at the end."""
    points = list(dict.fromkeys(point for point, _ in plan))
    first_seed = {}
    for point, seed in plan:
        first_seed.setdefault(point, seed)
    last = time.monotonic()
    for done, point in enumerate(points, 1):
        seed = first_seed[point]
        argv = [args.scenario, "--out", str(out / "runs" / run_name(point, seed))] + option_flags(
            args, args.run_defaults) + point_flags(point, seed)
        run_args = args.run_parser.parse_args(argv)
        try:
            SwarmRun(run_args).check_plan()
        except RunError as e:
            raise RunError(f"{describe(point, seed)}: {e}", 2) from None
        if progress is not None and (done == len(points) or time.monotonic() - last >= every_s):
            last = time.monotonic()
            progress(done, len(points))


def _run_one(args, point, seed, run_dir):
    """One `swarm run` at a point of the grid; (its summary or None, its exit code, why it failed)."""
    cmd = [sys.executable, str(REPO / "scripts" / "swarm"), "run", args.scenario, "--out", str(run_dir),
           "--quiet", "--no-report",
           "--force"]  # the sweep's own runs/ folder, new or cleared by the sweep's --force
    cmd += option_flags(args, args.run_defaults) + point_flags(point, seed)
    r = subprocess.run(cmd, capture_output=True, text=True)
    if not (run_dir / SUMMARY).exists():
        return None, r.returncode, last_line(r.stderr, f"exit code {r.returncode}").removeprefix("swarm: ")
    return read_json(run_dir / SUMMARY), r.returncode, None


def mean_of(summary, *path):
    vals = []
    for a in summary["agents"]:
        v = a
        for p in path:
            v = v.get(p) if isinstance(v, dict) else None
        if isinstance(v, (int, float)) and math.isfinite(v):
            vals.append(v)
    return sum(vals) / len(vals) if vals else float("nan")


def duration(seconds):
    seconds = max(0, int(round(seconds)))
    return f"{seconds // 60} min {seconds % 60:02d} s" if seconds >= 60 else f"{seconds} s"


def earlier_sweep(out):
    """What an earlier sweep left in `out`: its sweep.csv and sweep.png, and its runs/ when it
    holds any (empty when there is none)."""
    found = [name for name in ("sweep.csv", "sweep.png") if (out / name).exists()]
    runs = out / "runs"
    if runs.is_dir():
        n = sum(1 for p in runs.iterdir() if p.is_dir())
        if n:
            found.append(f"runs/ with {n} run{'s' if n != 1 else ''}")
    return found


def cmd_sweep(args):
    grid = parse_params(args.param, args.values)
    seeds = parse_seeds(args.seeds)
    if args.jobs is not None and args.jobs <= 0:
        raise RunError("--jobs must be positive", 2)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise RunError(f"--out {out}: is a file, not a folder; choose a folder", 2)
    keys = [k for k, _ in grid]
    runs = plan_size(grid, seeds)
    if runs > MAX_RUNS:
        counts = " x ".join(f"{len(v)} {k}" for k, v in grid) + (f" x {len(seeds)} seeds" if seeds != [None] else "")
        raise RunError(f"--param: {counts} is {runs} runs; a sweep runs at most {MAX_RUNS}: split the grid", 2)
    plan = [(tuple(zip(keys, combo)), s) for combo in itertools.product(*[v for _, v in grid]) for s in seeds]

    def checking(done, total):
        print(f"sweep: checked {done} of {total} points", flush=True)

    earlier = earlier_sweep(out)
    if earlier and not getattr(args, "force", False):
        raise RunError(f"--out {out}: holds an earlier sweep ({', '.join(earlier)}); choose another folder, or add "
                       "--force to replace it", 2)
    check_all(args, plan, out, progress=None if getattr(args, "quiet", False) else checking)
    if earlier:  # --force: nothing of the earlier sweep is left to be taken for this one's
        shutil.rmtree(out / "runs", ignore_errors=True)
        for name in ("sweep.csv", "sweep.png"):
            (out / name).unlink(missing_ok=True)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    jobs = args.jobs or max(1, min(2, os.cpu_count() or 1))
    start = time.monotonic()
    print(f"sweep: {' x '.join(f'{k} {v}' for k, v in grid)}, seeds "
          f"{seeds if seeds != [None] else 'of the scenario'}: {len(plan)} runs, all checked, {jobs} at a time",
          flush=True)

    results, failures = {}, []
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(_run_one, args, point, seed, out / "runs" / run_name(point, seed)): (point, seed)
                   for point, seed in plan}
        for done, future in enumerate(as_completed(futures), 1):
            point, seed = futures[future]
            summary, code, why = future.result()
            elapsed = time.monotonic() - start
            eta = elapsed / done * (len(plan) - done)
            head = f"[{done}/{len(plan)}] {describe(point, seed)}: "
            tail = f"  ({duration(elapsed)}; about {duration(eta)} to go)" if done < len(plan) else \
                f"  ({duration(elapsed)})"
            if summary is None:
                failures.append(f"{describe(point, seed)} ({why})")
                print(head + f"failed: {why}" + tail, flush=True)
                continue
            results[(point, seed)] = summary
            if code != 0:
                failures.append(f"{describe(point, seed)} (exit code {code}; {out / 'runs' / run_name(point, seed)})")
            print(head + f"mean global coverage {mean_of(summary, 'global', 'coverage'):.2f}, RMSE after rigid fit "
                  f"{mean_of(summary, 'global', 'rmse_aligned_m'):.3f} m" + (f", exit code {code}" if code else "")
                  + tail, flush=True)
    path = out / "sweep.csv"
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(keys + SWEEP_HEADER)
        for point, s in plan:
            summary = results.get((point, s))
            if summary is None:
                continue
            values = [v for _, v in point]
            w.writerows(values + sweep_row(s if s is not None else "", summary, a) for a in summary["agents"])
    print(f"csv:  {path}  ({len(results)} of {len(plan)} runs)")
    plotted = bool(results) and plot("sweep.py", out, "sweep plot")
    if plotted:
        print(f"plot: {out / 'sweep.png'}")
    if failures:
        print(f"swarm: {len(failures)} of {len(plan)} runs failed: " + "; ".join(failures), file=sys.stderr)
        return 1
    return 0 if plotted else 1
