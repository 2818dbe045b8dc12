"""`swarm sweep`: one scenario run over a grid of scenario values (every combination of the values
of each --param) and a list of seeds, with the run options given (faults, pace, injection,
security, hosts), several runs at a time, each in DIR/runs/. Every run is checked as `swarm run`
checks it before the first one starts. One CSV row per agent and run in DIR/sweep.csv (a column
per parameter, then the seed and the agent's figures), and DIR/sweep.png drawn by
scripts/plots/sweep.py."""

import csv
import ctypes
import hashlib
import itertools
import json
import math
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from pathlib import Path

from .columns import SWEEP_COLUMNS, SWEEP_HEADER, sweep_row
from . import provenance, sweep_stats
from .procs import PR_SET_PDEATHSIG, REPO, detach_from_terminal, last_line, plot, write_report
from .run import SwarmRun
from .run_error import RunError
from .run import cmd_report as cmd_report_run
from .rundir import SUMMARY, read_json

try:
    _LIBC = ctypes.CDLL("libc.so.6", use_errno=True)
except OSError:
    _LIBC = None

SEED_KEY = "seed"
# A sweep runs at most this many runs (grid points times seeds); a larger grid is refused in one
# line before anything is checked: split it into several sweeps.
MAX_RUNS = 1000
# Wall seconds a run stopped by the sweep's stop has to write its outputs before it is killed
# (the acceptance bound of a stop is 10 s).
SWEEP_STOP_GRACE_S = 8.0
DEFINITION = "sweep.json"  # what the sweep is: scenario, grid, seeds, options (--resume compares it)
SUMMARY_CSV = "sweep_summary.csv"
OUTPUTS = ("sweep.csv", SUMMARY_CSV, "sweep.png", DEFINITION)
# sweep_summary.csv after the swept parameters: per metric and group of agents (alive at the end,
# killed), over the seeds: their count, the median, the interval and its coverage, the figures.
SUMMARY_HEADER = ["metric", "agents", "seeds", "median", "lo", "hi", "interval_coverage", "per_seed"]
# The figures summarised (sweep.csv's numeric agent columns) and the default of --metric.
METRICS = [c.name for c in SWEEP_COLUMNS if c.name not in ("agent", "alive")]
DEFAULT_METRIC = "gap_to_central"
NEEDS_REFERENCE = {"gap_to_central", "gap_to_central_known_starts", "gap_to_own_batch", "rmse_central_same_m",
                   "rmse_central_known_starts_same_m", "coverage_reached"}


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


class Runner:
    """The sweep's `swarm run`s, each in a process group of its own (a terminal's Ctrl-C reaches the
    sweep alone, which stops them in order) that dies with the sweep even if it is SIGKILLed.
    After stop() no run starts, and the running ones are stopped as `swarm run` is stopped by
    Ctrl-C (SIGINT: the agents write their maps); one still there after `grace_s` is killed."""

    def __init__(self):
        self.lock = threading.RLock()  # re-entered by a signal handler in the thread that holds it
        self.running = set()
        self.stopped = False

    def run(self, cmd):
        """(exit code, stderr) of the command, or None when the sweep was stopped before it started."""
        with self.lock:
            if self.stopped:
                return None
            proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                    process_group=0, preexec_fn=_die_with_the_sweep)
            self.running.add(proc)
        try:
            _, err = proc.communicate()
        finally:
            with self.lock:
                self.running.discard(proc)
        return proc.returncode, err

    def refuse_new(self):
        """No run starts after this (a signal handler calls it: a run is started or refused whole)."""
        with self.lock:
            self.stopped = True

    def stop(self, grace_s=SWEEP_STOP_GRACE_S):
        with self.lock:
            self.stopped = True
            procs = list(self.running)
        for proc in procs:
            proc.send_signal(signal.SIGINT)
        deadline = time.monotonic() + grace_s
        for proc in procs:
            try:
                proc.wait(max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                proc.kill()
        return len(procs)


def _die_with_the_sweep():
    # In the child between fork and exec: one call into the libc loaded before any thread started.
    if _LIBC is not None:
        _LIBC.prctl(PR_SET_PDEATHSIG, signal.SIGKILL)


def _run_one(args, runner, point, seed, run_dir):
    """One `swarm run` at a point of the grid: (its summary or None, its exit code, why it failed),
    or None when the sweep was stopped before it started."""
    cmd = [sys.executable, str(REPO / "scripts" / "swarm"), "run", args.scenario, "--out", str(run_dir),
           "--quiet", "--no-report",
           "--force"]  # the sweep's own runs/ folder, new or cleared by the sweep's --force
    cmd += option_flags(args, args.run_defaults) + point_flags(point, seed)
    ran = runner.run(cmd)
    if ran is None:
        return None
    code, err = ran
    if not (run_dir / SUMMARY).exists():
        return None, code, last_line(err, f"exit code {code}").removeprefix("swarm: ")
    return read_json(run_dir / SUMMARY), code, None


def finished_summary(run_dir):
    """The summary of a run that went to its end (one that was interrupted did not), or None."""
    try:
        summary = read_json(run_dir / SUMMARY)
    except (OSError, ValueError, RunError):
        return None
    return None if not isinstance(summary, dict) or summary.get("interrupted", True) else summary


def duration(seconds):
    seconds = max(0, int(round(seconds)))
    return f"{seconds // 60} min {seconds % 60:02d} s" if seconds >= 60 else f"{seconds} s"


def earlier_sweep(out):
    """What an earlier sweep left in `out`: its files and its runs/ when it holds any (empty when
    there is none)."""
    found = [name for name in OUTPUTS if (out / name).exists()]
    runs = out / "runs"
    if runs.is_dir():
        n = sum(1 for p in runs.iterdir() if p.is_dir())
        if n:
            found.append(f"runs/ with {n} run{'s' if n != 1 else ''}")
    return found


def sweep_definition(args, grid, seeds):
    """What makes two sweeps the same sweep (sweep.json): the scenario file, the grid, the seeds
    and the run options, as `--resume` compares them."""
    return {"scenario": str(Path(args.scenario).resolve()), "grid": [[k, list(v)] for k, v in grid],
            "seeds": seeds, "options": option_flags(args, args.run_defaults)}


def resumable(out, definition):
    """RunError unless `out` holds a sweep.json with this definition."""
    try:
        earlier = read_json(out / DEFINITION)
    except FileNotFoundError:
        raise RunError(f"--resume: {out} holds no {DEFINITION} (no sweep, or one written before --resume); "
                       "run it again with --force", 2) from None
    except (OSError, ValueError) as e:
        raise RunError(f"--resume: {out / DEFINITION}: {e}", 2) from None
    for key, what in (("scenario", "scenario"), ("grid", "grid"), ("seeds", "seeds"), ("options", "run options")):
        if not isinstance(earlier, dict) or earlier.get(key) != definition[key]:
            was = earlier.get(key) if isinstance(earlier, dict) else None
            raise RunError(f"--resume: the sweep in {out} had another {what} ({json.dumps(was)}, now "
                           f"{json.dumps(definition[key])}); give the same, or --force to replace it", 2)


def pick_metric(args):
    """The figure the progress lines give (--metric, a sweep.csv column): the gap by default, the
    RMSE after a rigid fit without the reference."""
    if args.metric is None:
        return "rmse_global_aligned_m" if args.no_reference else DEFAULT_METRIC
    if args.metric not in METRICS:
        raise RunError(f"--metric {args.metric}: not a figure of sweep.csv; one of {', '.join(METRICS)}", 2)
    if args.no_reference and args.metric in NEEDS_REFERENCE:
        raise RunError(f"--metric {args.metric}: needs the reference, which --no-reference leaves out", 2)
    return args.metric


def progress_figures(summary, metric):
    """`gap_to_central 2.54 (median over 3 agents alive at the end; 1 killed apart: 0.91), coverage_global 0.69`."""
    rows = [{c.name: c.csv_cell(a) for c in SWEEP_COLUMNS} for a in summary["agents"]]
    parts = []
    for m in dict.fromkeys([metric, "coverage_global"]):
        figs = sweep_stats.run_figures(rows, m)
        alive, killed = figs.get("alive"), figs.get("killed")
        text = f"{m} {alive[0]:.3g}" if alive else f"{m} -"
        if m == metric:
            text += f" (median over {alive[1] if alive else 0} agents alive at the end"
            text += f"; {killed[1]} killed apart: {killed[0]:.3g})" if killed else ")"
        parts.append(text)
    return ", ".join(parts)


def on_signals(handler):
    """Installs handler for SIGINT, SIGTERM and SIGHUP; the earlier handlers."""
    return {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}


def cmd_sweep(args):
    grid = parse_params(args.param, args.values)
    seeds = parse_seeds(args.seeds)
    if args.jobs is not None and args.jobs <= 0:
        raise RunError("--jobs must be positive", 2)
    if args.force and args.resume:
        raise RunError("--force replaces an earlier sweep, --resume completes it: give one", 2)
    metric = pick_metric(args)
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise RunError(f"--out {out}: is a file, not a folder; choose a folder", 2)
    keys = [k for k, _ in grid]
    runs = plan_size(grid, seeds)
    if runs > MAX_RUNS:
        counts = " x ".join(f"{len(v)} {k}" for k, v in grid) + (f" x {len(seeds)} seeds" if seeds != [None] else "")
        raise RunError(f"--param: {counts} is {runs} runs; a sweep runs at most {MAX_RUNS}: split the grid", 2)
    plan = [(tuple(zip(keys, combo)), s) for combo in itertools.product(*[v for _, v in grid]) for s in seeds]
    definition = sweep_definition(args, grid, seeds)

    def checking(done, total):
        print(f"sweep: checked {done} of {total} points", flush=True)

    earlier = earlier_sweep(out)
    if earlier and not (args.force or args.resume):
        raise RunError(f"--out {out}: holds an earlier sweep ({', '.join(earlier)}); choose another folder, add "
                       "--resume to run only its missing runs, or --force to replace it", 2)
    if args.resume and earlier:
        resumable(out, definition)
    check_all(args, plan, out, progress=None if getattr(args, "quiet", False) else checking)
    if earlier and args.force:  # nothing of the earlier sweep is left to be taken for this one's
        shutil.rmtree(out / "runs", ignore_errors=True)
        for name in OUTPUTS:
            (out / name).unlink(missing_ok=True)
    (out / "runs").mkdir(parents=True, exist_ok=True)
    (out / DEFINITION).write_text(json.dumps(definition, indent=2) + "\n")
    results = {}
    if args.resume:
        for point, seed in plan:
            summary = finished_summary(out / "runs" / run_name(point, seed))
            if summary is not None:
                results[(point, seed)] = summary
    todo = [(point, seed) for point, seed in plan if (point, seed) not in results]
    jobs = args.jobs or max(1, min(2, os.cpu_count() or 1))
    print(f"sweep: {' x '.join(f'{k} {v}' for k, v in grid)}, seeds "
          f"{seeds if seeds != [None] else 'of the scenario'}: {len(plan)} runs, all checked, "
          + (f"{len(results)} finished before, {len(todo)} to run, " if args.resume else "")
          + f"{jobs} at a time", flush=True)

    runner, caught = Runner(), []

    def interrupted(signum, _frame):
        if signum == signal.SIGHUP:
            detach_from_terminal()
        runner.refuse_new()
        caught.append(signal.Signals(signum).name)

    failures = []
    old_handlers = on_signals(interrupted)
    try:
        failures = execute(args, runner, out, todo, results, metric, caught)
    finally:
        for s, h in old_handlers.items():
            signal.signal(s, h)
    return finish(out, keys, plan, results, failures, caught)


def execute(args, runner, out, todo, results, metric, caught):
    """Runs `todo` with the runner, `--jobs` at a time, into results {(point, seed): summary} (the
    runs that went to their end), with a progress line each, until all are done or a signal is
    caught (then no run starts and the running ones are stopped); the failures, one line each."""
    start = time.monotonic()
    failures = []
    jobs = args.jobs or max(1, min(2, os.cpu_count() or 1))
    with ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = {pool.submit(_run_one, args, runner, point, seed, out / "runs" / run_name(point, seed)):
                   (point, seed) for point, seed in todo}
        pending, done = set(futures), 0
        while pending:
            if caught:
                runner.stop(SWEEP_STOP_GRACE_S)
                for f in pending:
                    f.cancel()
                wait(pending)
                break
            finished, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            for future in finished:
                point, seed = futures[future]
                ran = future.result()
                if ran is None:  # stopped before it started
                    continue
                summary, code, why = ran
                if summary is not None and summary.get("interrupted") and caught:
                    continue  # stopped by the sweep's stop: not a finished run
                done += 1
                elapsed = time.monotonic() - start
                eta = elapsed / done * (len(todo) - done)
                head = f"[{done}/{len(todo)}] {describe(point, seed)}: "
                tail = f"  ({duration(elapsed)}; about {duration(eta)} to go)" if done < len(todo) else \
                    f"  ({duration(elapsed)})"
                if summary is None:
                    failures.append(f"{describe(point, seed)} ({why})")
                    print(head + f"failed: {why}" + tail, flush=True)
                    continue
                results[(point, seed)] = summary
                if code != 0:
                    failures.append(f"{describe(point, seed)} (exit code {code}; "
                                    f"{out / 'runs' / run_name(point, seed)})")
                print(head + progress_figures(summary, metric) + (f", exit code {code}" if code else "") + tail,
                      flush=True)
    return failures


def write_csvs(out, keys, plan, results):
    """DIR/sweep.csv (a row per run and agent) and DIR/sweep_summary.csv (per grid point, metric and
    group of agents: the median over the seeds of each run's median, its interval and the
    per-seed figures; scripts/mapmesh/sweep_stats.py) of the finished runs, in the plan's order."""
    rows = []  # (point, seed, [{column: cell}]) per finished run
    with open(out / "sweep.csv", "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(keys + SWEEP_HEADER)
        for point, s in plan:
            summary = results.get((point, s))
            if summary is None:
                continue
            values = [v for _, v in point]
            lines = [sweep_row(s if s is not None else "", summary, a) for a in summary["agents"]]
            w.writerows(values + line for line in lines)
            rows.append((point, s, [dict(zip(SWEEP_HEADER, line)) for line in lines]))
    with open(out / SUMMARY_CSV, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(keys + SUMMARY_HEADER)
        for metric in METRICS:
            for point, group, per_seed, (med, lo, hi, cover) in sweep_stats.summarise(rows, metric):
                w.writerow([v for _, v in point] + [metric, group, len(per_seed), f"{med:.6g}", f"{lo:.6g}",
                                                    f"{hi:.6g}", f"{cover:.4f}",
                                                    " ".join(f"{'' if s is None else s}:{v:.6g}"
                                                             for s, v in per_seed)])


def finish(out, keys, plan, results, failures, caught):
    """Writes the CSVs and the plot of the finished runs and says what happened; the exit code
    (130 after a signal)."""
    write_csvs(out, keys, plan, results)
    print(f"csv:  {out / 'sweep.csv'}  ({len(results)} of {len(plan)} runs)")
    print(f"      {out / SUMMARY_CSV}  (median and interval over the seeds per grid point)")
    plotted = bool(results) and plot("sweep.py", out, "sweep plot")
    if plotted:
        print(f"plot: {out / 'sweep.png'}")
    if results:
        print(f"reports: scripts/swarm report {out}  (or {out / 'runs' / 'RUN'} for one run)")
    if caught:
        print(f"swarm: sweep interrupted ({caught[0]}): {len(results)} of {len(plan)} runs finished and are in "
              f"sweep.csv; the others did not run to their end; --resume runs them", file=sys.stderr)
        return 130
    if failures:
        print(f"swarm: {len(failures)} of {len(plan)} runs failed: " + "; ".join(failures), file=sys.stderr)
        return 1
    return 0 if plotted else 1


def cmd_report(args):
    """`swarm report DIR`: the report of a run, or of each finished run of a sweep in DIR."""
    out = Path(args.dir)
    if (out / SUMMARY).exists() or not ((out / DEFINITION).exists() or (out / "sweep.csv").exists()):
        return cmd_report_run(args)
    runs = sorted(p for p in (out / "runs").glob("*") if p.is_dir() and finished_summary(p) is not None) \
        if (out / "runs").is_dir() else []
    if not runs:
        raise RunError(f"{out}: a sweep with no finished run (scripts/swarm sweep ... --resume --out {out})", 1)
    written = 0
    for i, run_dir in enumerate(runs, 1):
        report = write_report(run_dir)
        written += report is not None
        print(f"[{i}/{len(runs)}] report: {report if report else 'not written (above)'}", flush=True)
    print(f"reports: {written} of {len(runs)} finished runs of {out}")
    return 0 if written == len(runs) else 1
