"""The limit beside every run (docs/EXPERIMENTS.md "The limit"): `mapmesh-lab reference` on the
run's data after the run (the centralized optimum with no start known, with the true starts,
each robot's own, the known-pose map), on the data that reached each agent (reached.py), and on
every robot's data up to earlier times (the gap over time). Each function takes the SwarmRun."""

import concurrent.futures
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .procs import REPO, binary, last_line
from .reached import reached_until
from .rundir import (CHECKPOINT, HISTORY, REFERENCE, REFERENCE_OVER_TIME, REFERENCE_REACHED, STATS, RunDir,
                     agent_dir, read_history, read_json, write_json)
from .run_error import RunError


def compute_reference(run, interrupted):
    """DIR/reference.json by `mapmesh-lab reference` on the run's scenario (the same --agents and
    --set): the centralized batch optimum (with no robot's start known, the fair limit, and with
    every true start), each robot's own and the known-pose map, after the
    run so that it takes nothing from the agents. What summary.json's `reference` holds (the
    maps left out), with the wall time it took."""
    if getattr(run.args, "no_reference", False):
        return {"available": False, "why_none": "skipped (--no-reference)"}
    if interrupted:
        return {"available": False, "why_none": "the run was interrupted"}
    try:
        lab = binary("mapmesh-lab")
    except RunError as e:  # nothing else of the run is lost for want of it (the table's last line says why)
        return {"available": False, "why_none": str(e)}
    if not run.args.quiet:
        print("computing the reference (the centralized batch optimum; --no-reference skips it)", flush=True)
    start = time.monotonic()
    cmd = [lab, "reference", "--scenario", run.scenario, "--out", str(run.out / REFERENCE)] + run.common
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)
    wall = round(time.monotonic() - start, 3)
    if r.returncode != 0 or not (run.out / REFERENCE).exists():
        reason = last_line(r.stderr, f"exit code {r.returncode}").removeprefix("mapmesh-lab: ")
        return {"available": False, "why_none": f"mapmesh-lab reference failed: {reason}", "wall_s": wall}
    ref = RunDir(run.out).read(REFERENCE)
    return dict(strip_maps(ref), wall_s=wall)


def solve_until(run, lab, until, path):
    """`mapmesh-lab reference` of the fair optimum alone (no known-pose map, no known-starts
    optimum) on each robot's data up to until[robot] (the rest whole), into path."""
    cmd = [lab, "reference", "--scenario", run.scenario, "--no-known-pose", "--no-known-starts",
           "--out", str(path)] + run.common
    for robot, t in sorted(until.items()):
        cmd += ["--until", f"{robot}={t}"]
    return subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)


def compute_reached(run, reference):
    """agent_<id>/reference_reached.json for every agent that some robot's data reached only in
    part (reached.py): `mapmesh-lab reference` on the data that reached it, beside the
    central optimum of all of it. Returns {id: {robot: until_s}} (empty where all of it
    reached the agent), and the agents whose reference failed (their gap_to_reached: null)."""
    failed = set()  # agents whose reference of what reached them could not be computed
    if not reference.get("available"):
        return {}, failed
    agents = {}
    for rid in run.agents:
        d = run.out / agent_dir(rid)
        agents[rid] = tuple(read_json(d / name) if (d / name).exists() else None
                            for name in (STATS, CHECKPOINT))
    period = run.info.get("resolved", {}).get("agent.map_publish_period_s")
    period = float(period) if isinstance(period, (int, float)) else 1.0
    restarted = {rid for rid, slot in run.agents.items() if slot.restarted_at}
    # A joining agent's maps carry its own data only (its global map stays off the wire).
    joining = run.info.get("resolved", {}).get("agent.fusion") == "joining"
    until = reached_until(agents, float(run.info["duration"]), 2.0 * period, restarted, maps_relay=not joining)
    for rid, slot in run.agents.items():
        # A restarted agent holds what its earlier incarnations took (its checkpoint), which
        # its last process's stats do not count: its limit stays the whole run's.
        if slot.restarted_at:
            until[rid] = {}
    lab = binary("mapmesh-lab")
    for rid, robots in until.items():
        path = run.out / agent_dir(rid) / REFERENCE_REACHED
        path.unlink(missing_ok=True)
        if not robots:
            continue
        r = solve_until(run, lab, robots, path)
        if r.returncode != 0 or not path.exists():
            print(f"swarm: the reference of what reached agent {rid} failed: "
                  f"{last_line(r.stderr, f'exit code {r.returncode}')}", file=sys.stderr)
            failed.add(rid)
    return until, failed


def compute_reference_over_time(run, reference):
    """DIR/reference_over_time.json, for the gap over time: the centralized optimum with no start
    known (reference.json's `central`) of every robot's data up to each of several times, by
    `mapmesh-lab reference --until ROBOT=T` for every robot (two at a time). The times: for k
    in 1 .. --gap-samples - 1, the latest snapshot time of any agent (history.jsonl) no later
    than k / --gap-samples of the scenario (the end is reference.json's). mapmesh-eval scores
    each agent's snapshot at those times against them (timeline.json). Returns what
    summary.json's reference holds of it (the times and the wall time), or None."""
    samples = getattr(run.args, "gap_samples", 0) or 0
    (run.out / REFERENCE_OVER_TIME).unlink(missing_ok=True)
    if samples < 2 or not reference.get("available"):
        return None
    duration = float(run.info["duration"])
    shots = sorted(snapshot_times(run.out / agent_dir(rid) / HISTORY for rid in run.agents))
    times = []
    for k in range(1, samples):
        before = [t for t in shots if t <= duration * k / samples + 1e-9]
        if before and before[-1] > 0 and before[-1] not in times:
            times.append(before[-1])
    if not times:
        return None
    if not run.args.quiet:
        print(f"computing the optimum at {len(times)} earlier times, for the gap over time "
              "(--gap-samples 0 skips it)", flush=True)
    lab = binary("mapmesh-lab")
    start = time.monotonic()

    def solve(t):
        with tempfile.TemporaryDirectory() as tmp:
            path = Path(tmp) / REFERENCE
            r = solve_until(run, lab, {rid: t for rid in run.agents}, path)
            if r.returncode != 0 or not path.exists():
                print(f"swarm: the optimum at t={t:g} s failed: {last_line(r.stderr, f'exit code {r.returncode}')}",
                      file=sys.stderr)
                return None
            ref = read_json(path)
            return {"t": t, "central": ref.get("central"), "total_s": ref.get("total_s")}

    with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
        solved = [s for s in pool.map(solve, times) if s is not None and s.get("central")]
    wall = round(time.monotonic() - start, 3)
    write_json(run.out / REFERENCE_OVER_TIME, {"available": bool(solved), "samples": solved})
    return {"samples_t": [s["t"] for s in solved], "wall_s": wall}


def strip_maps(value):
    """A reference.json without its maps (every "map" and "landmark_component" key, at any depth)."""
    if isinstance(value, dict):
        return {k: strip_maps(v) for k, v in value.items() if k not in ("map", "landmark_component")}
    return value


def describe_reference(ref):
    """One line on the run's reference: the centralized optimum with no start known (the fair
    limit), with the true starts, and the known-pose map; or why there is none."""
    if not ref or not ref.get("available"):
        return f"reference: none ({(ref or {}).get('why_none', 'not computed')})"
    c = ref["central"]
    line = f"reference: centralized batch optimum {c['rmse_aligned_m']:.3f} m after a rigid fit"
    if c.get("nees_mean") is not None:
        line += f" (NEES {c['nees_mean']:.2f})"
    if not c.get("converged"):
        line += " NOT CONVERGED"
    if c.get("unconnected"):
        line += f" (robots {', '.join(str(r) for r in c['unconnected'])} share too little with the rest: apart)"
    s = ref.get("central_known_starts")
    if s:
        line += f", with the true starts {s['rmse_aligned_m']:.3f} m"
    k = ref.get("known_pose")
    if k:
        line += f", known poses {k['rmse_aligned_m']:.3f} m"
    return line + f"; solved in {ref.get('wall_s', ref.get('total_s', 0.0)):.1f} s"


def snapshot_times(paths):
    """The scenario times of the snapshots in these history.jsonl files but the final ones."""
    return {e["t"] for p in paths for e in read_history(p)
            if isinstance(e.get("t"), (int, float)) and not e.get("final")}
