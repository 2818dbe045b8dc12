"""DIR/summary.json and DIR/timeline.json after a run (docs/OUTPUTS.md): each agent's figures from
its stats.json and mapmesh-eval's scores, the run's own, the reference beside them; and the lines
that tell a user what went wrong."""

import json
import signal
import subprocess
import sys
from pathlib import Path

from .procs import EXIT_WRITE_FAILED, binary
from .references import compute_reached, compute_reference, compute_reference_over_time
from .rundir import (AGENT_LOG, FEEDER, HISTORY, INJECT, STATS, SUMMARY, TIMELINE, TRUTH, RunDir, agent_dir,
                     read_history, write_json)

SHRINK_FRACTION = 0.9  # a final local map under this share of the most it held is flagged


def summarise(run, wall_s, interrupted):
    """DIR/summary.json and DIR/timeline.json of a finished run (run: the SwarmRun): the references
    first, then mapmesh-eval's scores, each agent's entry and the run's own. Returns the summary."""
    files = RunDir(run.out)
    reference = compute_reference(run, interrupted)
    reached, reached_failed = compute_reached(run, reference)
    over_time = compute_reference_over_time(run, reference)
    scores = {}
    if files.path(TRUTH).exists():
        r = subprocess.run([binary("mapmesh-eval"), "--run", str(run.out)], capture_output=True, text=True)
        if r.returncode == 0:
            scores = json.loads(r.stdout).get("agents", {})
        else:
            print(f"swarm: mapmesh-eval failed: {r.stderr.strip()}", file=sys.stderr)
    feeder_stats = {r["id"]: r for r in (files.read_if_present(FEEDER) or {}).get("robots", [])}
    agents = []
    for rid, slot in run.agents.items():
        # final, or the last checkpoint of a killed agent
        stats = files.read_if_present(STATS, rid) or {}
        held = most_landmarks(run.out / agent_dir(rid) / HISTORY)
        agents.append(agent_summary(slot, stats, scores.get(str(rid), {}), feeder_stats.get(rid, {}), held,
                                    None if rid in reached_failed else reached.get(rid, {})))
    # Scenario time played: the whole scenario, or where an interrupted run stopped.
    duration = run.info["duration"]
    played = (files.read_if_present(FEEDER) or {}).get("played_until_s")
    if interrupted and played is not None:
        duration = min(duration, played)
    summary = {
        "scenario": run.info["name"],
        "scenario_file": run.scenario,
        "scenario_duration_s": run.info["duration"],
        "sim_duration_s": duration,
        "wall_s": round(wall_s, 3),
        "real_time_factor": round(duration / wall_s, 3) if wall_s > 0 else None,
        "pace": run.args.pace or run.info["pace"],
        "interrupted": interrupted,
        "kills": [{"id": r, "t": t, "wall": run.kill_wall.get((t, r))} for t, r in run.kills],
        "restarts": [{"id": r, "t": t} for t, r in run.restarts],
        "pauses": run.pause_log,
        "feeder": {"exit_code": run.feeder.returncode if run.feeder else None,
                   "cpu_s": round(run.feeder.cpu_s, 3) if run.feeder else None,
                   "max_rss_mb": round(run.feeder.max_rss_mb, 1) if run.feeder else None},
        "agents": agents,
        "failed_agents": [a["id"] for a in agents if a["failed"]],
    }
    summary["reference"] = reference
    if over_time is not None:
        summary["reference"]["over_time"] = over_time
    summary["network"] = run.hosts.summary() if run.hosts else {"hosts": "loopback"}
    if run.args.inject:
        summary["injected"] = files.read_if_present(INJECT)
        summary["injector_exit_code"] = run.injector.returncode if run.injector else None
    write_json(files.path(SUMMARY), summary)
    # Each agent's counters and scored maps over time, for the report's time plots.
    timeline = {"kills": summary["kills"], "restarts": summary["restarts"], "pauses": summary["pauses"],
                "agents": {str(rid): scores.get(str(rid), {}).get("history", []) for rid in run.agents}}
    write_json(files.path(TIMELINE), timeline)
    return summary


def agent_summary(slot, stats, score, sent, held, reached):
    """One agent's entry of summary.json: how its processes ended, its stats.json's counters,
    mapmesh-eval's scores, what the feeder sent it, the most its maps held, and the robots' data
    that reached it only in part (reached: {robot: until_s}; None when its reference failed)."""
    return {
        "id": slot.id,
        "alive_at_end": slot.alive_at_end,
        "exit_code": slot.current.returncode if slot.current else None,
        "restarts": len(slot.restarted_at),
        "killed_at": slot.killed_at,
        "restarted_at": slot.restarted_at,
        "paused_at": slot.paused_at,
        "final_state": bool(stats.get("final", False)),
        "local": score.get("local"),
        "global": score.get("global"),
        # The map against the limit on the same landmarks (RMSE after a rigid fit over the
        # optimum's): the global map over the centralized batch optimum with no start
        # known (the agents' knowledge), and over the one that knows every true start; the
        # local map over the robot's own batch optimum (docs/EXPERIMENTS.md "The limit").
        "gap_to_central": score.get("gap_to_central"),
        "gap_to_central_known_starts": score.get("gap_to_central_known_starts"),
        "gap_to_own_batch": score.get("gap_to_own_batch"),
        # The global map over the optimum of the data that reached the agent by the end
        # (each other robot's up to reached_until[robot] s, the rest whole; reached.py).
        "gap_to_reached": None if reached is None else score.get("gap_to_reached"),
        "reached_until": {str(r): t for r, t in sorted((reached or {}).items())},
        "peers_aligned": stats.get("peers_aligned", []),
        "peers_stale": stats.get("peers_stale", []),
        "alignment_errors": score.get("alignment_errors", {}),
        # Per peer that can no longer speak: the last map received of it, whether it overlaps
        # this agent's final local map, and how many of its landmarks the global map holds.
        "dead_peers": score.get("dead_peers", []),
        "maps_received": stats.get("maps_received"),
        "maps_dropped": stats.get("maps_dropped"),
        "maps_rejected": stats.get("maps_rejected", {}),
        "bytes_sent": stats.get("bytes_sent"),
        "bytes_received": stats.get("bytes_received"),
        "bytes_per_landmark": stats.get("bytes_per_landmark"),
        "odom_processed": stats.get("odom_processed"),
        "scans_processed": stats.get("scans_processed"),
        "odom_sent": sent.get("odom_sent"),
        "scans_sent": sent.get("scans_sent"),
        # Sensor messages the (last) agent process received in sequence, those it never got
        # (gaps in their sequence numbers), and those sent before it joined the stream
        # (sent = received + lost + before_join, but for a tail lost after the last);
        # messages it got again, and numbers out of sequence, apart (docs/OUTPUTS.md).
        "odom_received": stats.get("odom_received"),
        "odometry_lost": stats.get("odometry_lost"),
        "odom_before_join": stats.get("odom_before_join"),
        "odom_duplicate": stats.get("odom_duplicate"),
        "odom_out_of_sequence": stats.get("odom_out_of_sequence"),
        "scans_received": stats.get("scans_received"),
        "scans_lost": stats.get("scans_lost"),
        "scans_before_join": stats.get("scans_before_join"),
        "scans_duplicate": stats.get("scans_duplicate"),
        "scans_out_of_sequence": stats.get("scans_out_of_sequence"),
        "odom_implausible": stats.get("odom_implausible"),
        "scans_implausible": stats.get("scans_implausible"),
        "links_refused": stats.get("links_refused"),
        "not_from_feeder": stats.get("not_from_feeder"),
        # Samples its transport dropped unread for their size, and own maps not sent for it.
        "transport_oversize": stats.get("transport_oversize"),
        "maps_beyond_sample_size": stats.get("maps_beyond_sample_size"),
        "maps_refused": stats.get("maps_refused", {}),
        # Lockstep: peers' messages the inbox refused on arrival, by reason (docs/OUTPUTS.md).
        "inbox_refused": stats.get("inbox_refused", {}),
        # Writes that failed (a full disk): from the first, no snapshots or checkpoints.
        "outputs": stats.get("outputs"),
        # The most landmarks its local and global maps held at any checkpoint of any
        # incarnation, and whether a final map has fewer than 90 % of them (a restart that
        # lost what the agent held).
        "held": held,
        "map_shrank": shrank(held, stats),
        "frame_in_world": score.get("frame_in_world"),
        "cpu_s": round(sum(p.cpu_s for p in slot.procs), 3),
        "max_rss_mb": round(max((p.max_rss_mb for p in slot.procs), default=0.0), 1),
        "incarnations": [{"incarnation": i, "exit_code": p.returncode, "killed": p.killed, "failed": p.failed}
                         for i, p in enumerate(slot.procs, start=1)],
        "failed": any(p.failed for p in slot.procs),
    }


def most_landmarks(path):
    """The most landmarks of each map in an agent's history.jsonl (any incarnation):
    {"local": n, "global": n}, or None without a history."""
    most = {}
    for entry in read_history(path):
        for kind in ("local", "global"):
            n = entry.get(f"{kind}_landmarks")
            if isinstance(n, int):
                most[kind] = max(most.get(kind, 0), n)
    return most or None


def shrank(held, stats):
    """Whether a final map (stats.json) has fewer than SHRINK_FRACTION of the most it held."""
    if not held:
        return False
    return any(isinstance(stats.get(f"{kind}_landmarks"), int) and kind in held
               and stats[f"{kind}_landmarks"] < SHRINK_FRACTION * held[kind] for kind in ("local", "global"))


def describe_network(net):
    """One line on the hosts of a --hosts netns run and what their kernels dropped."""
    line = f"network: {len(net['per_host'])} hosts in namespaces {net['tag']}-* on one bridge"
    if net.get("rate_mbit"):
        line += f", {net['rate_mbit']:g} Mbit/s each"
    if net.get("loss_percent"):
        line += (f"; their kernels dropped {net['udp_dropped']} of {net['udp_received']} UDP datagrams received "
                 f"({net['udp_dropped_percent']} %, asked {net['loss_percent']:g} %)")
    return line


def failure_message(summary, out):
    """One line naming each failed agent, how each failed incarnation ended, and its log."""
    parts = []
    for a in summary["agents"]:
        if not a["failed"]:
            continue
        how = ", ".join(f"incarnation {i['incarnation']} {describe_end(i['exit_code'])}"
                        for i in a["incarnations"] if i["failed"])
        log = Path(out) / agent_dir(a["id"]) / AGENT_LOG
        parts.append(f"agent {a['id']} ({how}; see {log})")
    return f"swarm: agents {summary['failed_agents']} failed: " + "; ".join(parts)


def describe_end(code):
    if code is None:
        return "did not end"
    if code < 0:
        try:
            return f"died of {signal.Signals(-code).name}"
        except ValueError:
            return f"died of signal {-code}"
    if code == 0:
        return "exited 0 before the end of the run"
    if code == EXIT_WRITE_FAILED:
        return f"could not write its outputs (exit code {code})"
    return f"exited with code {code}"


def warn_of_losses(summary):
    """A line on stderr for each agent whose final map ended smaller than it was (map_shrank), and
    one for the agents whose snapshots and checkpoints stopped at a failed write."""
    for a in summary["agents"]:
        if a.get("map_shrank"):
            held = a["held"]
            ends = {kind: (a.get(kind) or {}).get("landmarks") for kind in ("local", "global")}
            which = [f"its {kind} map ended with {ends[kind]} landmarks where it held {held[kind]}"
                     for kind in ("local", "global") if isinstance(ends[kind], int) and held.get(kind)
                     and ends[kind] < SHRINK_FRACTION * held[kind]] or ["a final map ended smaller than it was"]
            print(f"swarm: agent {a['id']}: " + "; ".join(which) + f" (fewer than {SHRINK_FRACTION:.0%}; the most at "
                  "any checkpoint: map_shrank and held in summary.json)", file=sys.stderr)
    stopped = [a for a in summary["agents"] if (a.get("outputs") or {}).get("stopped_at") is not None]
    if stopped:
        print(f"swarm: agents {', '.join(str(a['id']) for a in stopped)}: snapshots and checkpoints stopped at a "
              f"failed write ({stopped[0]['outputs']['reason']}); mapping went on and the final outputs were "
              "written (stats.json outputs)", file=sys.stderr)
