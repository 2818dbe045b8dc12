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
from .run import RunError
from .rundir import SUMMARY, TRAJECTORY, TRUTH, RunDir, truth_robots

EXPORT = "export"


def agent_frame(agent):
    """The pose [x, y, theta] of the agent's map frame in the world when the run knows it (its true
    pose at the frame's origin: trajectory_frame true_origin), else None."""
    frame = agent.get("frame_in_world")
    known = (agent.get("local") or {}).get("trajectory_frame") == "true_origin"
    return [float(v) for v in frame] if known and isinstance(frame, list) and len(frame) == 3 else None


def export_tum(run, summary, out):
    """Writes out/agent_N.tum and out/agent_N_truth.tum; returns [(path, poses written)]."""
    out.mkdir(parents=True, exist_ok=True)
    truth = run.read_if_present(TRUTH) or {}
    robots = truth_robots(truth)
    headings = truth.get("headings_known", True)
    written = []
    for agent in summary["agents"]:
        rid = agent["id"]
        traj = run.read_if_present(TRAJECTORY, rid)
        if traj is None:
            print(f"swarm export: agent {rid}: no {TRAJECTORY}, no trajectory written", file=sys.stderr)
            continue
        est = out / f"agent_{rid}.tum"
        n = tum.write(est, traj.get("poses", []), [
            f"mapmesh run {run.dir.resolve()}: agent {rid}'s estimated trajectory in its map frame "
            f"(the robot's pose at t = {traj.get('frame_origin_stamp')} s is the origin)"])
        written.append((est, n))
        robot = robots.get(rid)
        if robot is None or not robot.get("trajectory"):
            continue
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
        written.append((path, tum.write(path, poses, comments)))
    return written


def cmd_export(args):
    run = RunDir(args.dir)
    if not (run.dir / SUMMARY).exists():
        raise RunError(f"{args.dir}: no summary.json (a folder written by scripts/swarm run)", 2)
    try:
        summary = run.read(SUMMARY)
    except (OSError, ValueError) as e:
        raise RunError(f"{run.dir / SUMMARY}: unreadable ({e.__class__.__name__})", 1) from None
    out = Path(args.out) if args.out else run.dir / EXPORT
    both = not args.tum and not args.mcap
    if args.tum or both:
        files = export_tum(run, summary, out / "tum")
        print(f"tum:  {out / 'tum'}  ({len(files)} files, {sum(n for _, n in files)} poses)")
    if args.mcap or both:
        from .mcap_export import export_mcap
        path, counts = export_mcap(run, summary, out / "run.mcap")
        print(f"mcap: {path}  ({sum(counts.values())} messages on {len(counts)} topics)")
        if args.counts:
            print(json.dumps(counts, sort_keys=True))
    return 0
