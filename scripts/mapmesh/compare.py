"""swarm compare: whether two run directories hold the same run (docs/EXCHANGE.md "Identical runs").

Compared byte for byte: every agent's local_map.json, global_map.json, trajectory.json,
checkpoint.json, history.jsonl, peers/ and snapshots/, and truth.json. Compared as JSON with the
host's measurements left out: summary.json, timeline.json, feeder.json, reference.json,
reference_over_time.json and each
agent's stats.json. What is left out, and why, is VOLATILE; logs and the report are not compared.
A secure run's checkpoint holds its submaps' signatures, which ECDSA draws afresh each time
(the submaps are compared, their signatures are not): checkpoints that differ in bytes are
compared again without them.
"""

from pathlib import Path

from .run_error import RunError
from .rundir import read_json

# Keys whose values measure the host or the transport, not the run: wall-clock times and
# timestamps (the reference's total_s among them), CPU time, memory, the sensor messages a
# lockstep feeder sent again (to a participant back from a pause, when its lease lapsed during
# it, which depends on the host's load: the feeder's sensor_messages_resent, and *_duplicate at
# the agent; what the agent received in sequence and processed is compared), the lockstep
# inbox's maps of past ticks (how much of the writers' history a restarted agent gets before its
# first tick depends on the host: past_tick in inbox_refused), and with --hosts netns the
# namespaces' names and the datagrams their kernels received and dropped.
VOLATILE = frozenset({
    "wall_s", "real_time_factor", "cpu_s", "max_rss_mb", "wall", "wall_start", "wall_end", "peers_lost_wall",
    "solve_s", "total_s", "odom_duplicate", "scans_duplicate", "sensor_messages_resent", "past_tick",
    "tag", "bridge_namespace", "namespace", "udp_received", "udp_dropped", "udp_dropped_percent",
})
BYTES = ["local_map.json", "global_map.json", "trajectory.json", "checkpoint.json", "history.jsonl"]
BYTE_DIRS = ["peers", "snapshots"]
JSON_TOP = ["summary.json", "timeline.json", "feeder.json", "reference.json", "reference_over_time.json"]


def strip(value):
    """The document without VOLATILE keys, at any depth."""
    if isinstance(value, dict):
        return {k: strip(v) for k, v in value.items() if k not in VOLATILE}
    if isinstance(value, list):
        return [strip(v) for v in value]
    return value


def first_difference(a, b, path=""):
    """The path of the first place where two JSON values differ (None when equal)."""
    if type(a) is not type(b):
        return path or "/"
    if isinstance(a, dict):
        for k in sorted(set(a) | set(b)):
            if k not in a or k not in b:
                return f"{path}/{k}"
            d = first_difference(a[k], b[k], f"{path}/{k}")
            if d is not None:
                return d
        return None
    if isinstance(a, list):
        if len(a) != len(b):
            return f"{path} (length {len(a)} vs {len(b)})"
        for i, (u, v) in enumerate(zip(a, b)):
            d = first_difference(u, v, f"{path}[{i}]")
            if d is not None:
                return d
        return None
    return None if a == b else (path or "/")


def without_signatures(checkpoint):
    """A checkpoint's document with each signed submap ({"submap", "signature"}) as its submap."""
    if isinstance(checkpoint, dict) and isinstance(checkpoint.get("submaps"), list):
        checkpoint = dict(checkpoint)
        checkpoint["submaps"] = [e.get("submap") if isinstance(e, dict) else e for e in checkpoint["submaps"]]
    return checkpoint


def load(path):
    try:
        return read_json(path)
    except (OSError, ValueError) as e:
        raise RunError(f"{path}: not a readable JSON file ({e})", 2)


def files_to_compare(a, b):
    """(relative path, how) for every file either run holds that is compared."""
    names = set()
    for run in (a, b):
        for name in JSON_TOP + ["truth.json"]:
            if (run / name).is_file():
                names.add(name)
        for agent in run.glob("agent_*"):
            for name in BYTES + ["stats.json"]:
                if (agent / name).is_file():
                    names.add(f"{agent.name}/{name}")
            for d in BYTE_DIRS:
                for f in (agent / d).glob("*"):
                    names.add(f"{agent.name}/{d}/{f.name}")
    return sorted(names)


def compare(a, b):
    """The differences between runs a and b, one line each, and the number of files compared."""
    diffs = []
    names = files_to_compare(a, b)
    for name in names:
        fa, fb = a / name, b / name
        if not fa.is_file() or not fb.is_file():
            diffs.append(f"{name}: only in {a if fa.is_file() else b}")
            continue
        if Path(name).name in JSON_TOP or Path(name).name == "stats.json":
            d = first_difference(strip(load(fa)), strip(load(fb)))
            if d is not None:
                diffs.append(f"{name}: differs at {d}")
        elif fa.read_bytes() != fb.read_bytes():
            if Path(name).name == "checkpoint.json":
                d = first_difference(without_signatures(load(fa)), without_signatures(load(fb)))
                if d is not None:
                    diffs.append(f"{name}: differs at {d}")
            else:
                diffs.append(f"{name}: differs")
    return diffs, len(names)


def cmd_compare(args):
    a, b = Path(args.a), Path(args.b)
    for run in (a, b):
        if not (run / "summary.json").is_file():
            raise RunError(f"{run}: not a run directory (no summary.json)", 2)
    diffs, n = compare(a, b)
    for line in diffs[:args.max_lines]:
        print(line)
    if len(diffs) > args.max_lines:
        print(f"... and {len(diffs) - args.max_lines} more")
    print(f"{n} files compared, {len(diffs)} differ" + ("" if diffs else ": the same run"))
    return 1 if diffs else 0
