"""`swarm export DIR`: a finished run in standard formats, in DIR/export/ (docs/EXPORTS.md):
  --tum   tum/agent_N.tum, each agent's estimated trajectory in its map frame, and
          tum/agent_N_truth.tum, its true one: in the same frame where the run knows where that
          frame lies (simulated worlds), else in the world frame (align it, e.g. evo_ape --align);
  --mcap  run.mcap, the run over time for Foxglove and other MCAP readers (mapmesh/mcap_export.py).
Standard library only."""

import json
import sys
from pathlib import Path

from . import tum
from .run_error import RunError
from .rundir import SUMMARY, TRAJECTORY, TRUTH, RunDir, truth_robots, why_unreadable

EXPORT = "export"


def agent_frame(agent):
    """The pose [x, y, theta] of the agent's map frame in the world when the run knows it (its true
    pose at the frame's origin: trajectory_frame true_origin), else None."""
    frame = agent.get("frame_in_world")
    known = (agent.get("local") or {}).get("trajectory_frame") == "true_origin"
    return [float(v) for v in frame] if known and isinstance(frame, list) and len(frame) == 3 else None


def checked_agents(run, summary):
    """summary.json's agents, each an object with an integer id; RunError naming the field."""
    agents = summary.get("agents") if isinstance(summary, dict) else None
    if not isinstance(agents, list):
        raise RunError(f"{run.dir / SUMMARY}: field agents: expected a list of agents", 1)
    for i, a in enumerate(agents):
        if not isinstance(a, dict) or not isinstance(a.get("id"), int) or isinstance(a.get("id"), bool):
            raise RunError(f"{run.dir / SUMMARY}: field agents[{i}]: expected an object with an integer id", 1)
    return agents


def read_or_say(run, name, rid=None):
    """run.read_if_present, with a file that cannot be read as one RunError line naming it."""
    try:
        return run.read_if_present(name, rid)
    except (OSError, ValueError) as e:
        raise RunError(f"{run.path(name, rid)}: unreadable ({why_unreadable(e)})", 1) from None


def write_tum(path, poses, comments, source, field):
    try:
        return tum.write(path, poses, comments)
    except ValueError as e:
        raise RunError(f"{source}: field {field}: {e}", 1) from None


def export_tum(run, summary, out):
    """Writes out/agent_N.tum and out/agent_N_truth.tum; returns [(path, poses written)]. RunError
    (one line naming the file and field) on content no run writes; no partial file is left."""
    agents = checked_agents(run, summary)
    out.mkdir(parents=True, exist_ok=True)
    truth = read_or_say(run, TRUTH) or {}
    if not isinstance(truth, dict):
        raise RunError(f"{run.path(TRUTH)}: expected an object", 1)
    robots = truth_robots(truth)
    headings = truth.get("headings_known", True)
    written = []
    for agent in agents:
        rid = agent["id"]
        traj = read_or_say(run, TRAJECTORY, rid)
        if traj is None:
            print(f"swarm export: agent {rid}: no {TRAJECTORY}, no trajectory written", file=sys.stderr)
            continue
        if not isinstance(traj, dict) or not isinstance(traj.get("poses", []), list):
            raise RunError(f"{run.path(TRAJECTORY, rid)}: field poses: expected a list of poses", 1)
        est = out / f"agent_{rid}.tum"
        n = write_tum(est, traj.get("poses", []), [
            f"mapmesh run {run.dir.resolve()}: agent {rid}'s estimated trajectory in its map frame "
            f"(the robot's pose at t = {traj.get('frame_origin_stamp')} s is the origin)"],
            run.path(TRAJECTORY, rid), "poses")
        written.append((est, n))
        robot = robots.get(rid)
        if robot is None or not robot.get("trajectory"):
            continue
        if not all(tum.finite_pose(p) for p in robot["trajectory"]):
            raise RunError(f"{run.path(TRUTH)}: field robots[id {rid}].trajectory: a pose is not 4 finite numbers", 1)
        frame = agent_frame(agent)
        if frame is not None:
            to_map = tum.inverse(frame)
            poses = [[p[0]] + tum.compose(to_map, p[1:4]) for p in robot["trajectory"]]
            where = "in the agent's map frame (the same as agent_%d.tum: compare without alignment)" % rid
        else:
            poses = [list(p[:4]) for p in robot["trajectory"]]
            where = "in the world frame (the agent's frame is not known here: align, e.g. evo_ape --align)"
        comments = [f"mapmesh run {run.dir.resolve()}: robot {rid}'s true trajectory {where}"]
        if not headings:
            comments.append("the truth has no headings (GPS): orientations are not measured; use positions only")
        path = out / f"agent_{rid}_truth.tum"
        written.append((path, write_tum(path, poses, comments, run.path(TRUTH), f"robots[id {rid}].trajectory")))
    return written


def cmd_export(args):
    run = RunDir(args.dir)
    if not (run.dir / SUMMARY).exists():
        raise RunError(f"{args.dir}: no summary.json (a folder written by scripts/swarm run)", 2)
    try:
        summary = run.read(SUMMARY)
    except (OSError, ValueError) as e:
        raise RunError(f"{run.dir / SUMMARY}: unreadable ({why_unreadable(e)})", 1) from None
    out = Path(args.out) if args.out else run.dir / EXPORT
    if out.exists() and not out.is_dir():
        raise RunError(f"--out {out}: is a file, not a folder; choose a folder", 2)
    for sub_path in (out / "tum", out / "run.mcap"):
        if sub_path.exists() and sub_path.is_dir() == (sub_path.name == "run.mcap"):
            raise RunError(f"--out {out}: {sub_path} is in the way (a {'folder' if sub_path.is_dir() else 'file'})", 2)
    both = not args.tum and not args.mcap
    if args.tum or both:
        files = export_tum(run, summary, out / "tum")
        print(f"tum:  {out / 'tum'}  ({len(files)} files, {sum(n for _, n in files)} poses)")
    if args.mcap or both:
        from .mcap_export import export_mcap
        checked_agents(run, summary)
        try:
            path, counts = export_mcap(run, summary, out / "run.mcap")
        except (ValueError, TypeError, KeyError, AttributeError, IndexError) as e:
            raise RunError(f"{run.dir}: a file holds what no run writes ({e.__class__.__name__}: {e}); "
                           f"run.mcap not written", 1) from None
        print(f"mcap: {path}  ({sum(counts.values())} messages on {len(counts)} topics)")
        if args.counts:
            print(json.dumps(counts, sort_keys=True))
    return 0
