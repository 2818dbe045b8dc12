"""A run directory written by `scripts/swarm run` (README.md, "Outputs"): the names of its files
and how they are read, for the launcher (mapmesh/run.py, mapmesh/sweep.py), the report
(scripts/plots/report.py) and scripts/relay-error; and a robot's true pose at a time from its
truth.json trajectory. Standard library only."""

import errno
import json
import math
import os
import shutil
import stat
from pathlib import Path

from .run_error import RunError

# The run's files.
SUMMARY = "summary.json"
TRUTH = "truth.json"
TIMELINE = "timeline.json"
FEEDER = "feeder.json"
INJECT = "inject.json"
REFERENCE = "reference.json"  # the limit of the run's data (mapmesh-lab reference)
REFERENCE_OVER_TIME = "reference_over_time.json"  # the fair optimum of the data up to earlier times
REPORT = "report.html"
# Each agent's files, in its directory agent_dir(id).
STATS = "stats.json"
LOCAL_MAP = "local_map.json"
GLOBAL_MAP = "global_map.json"
TRAJECTORY = "trajectory.json"
HISTORY = "history.jsonl"
AGENT_LOG = "agent.log"
CHECKPOINT = "checkpoint.json"
# The limit of what reached the agent, where that was less than the whole run (reached.py).
REFERENCE_REACHED = "reference_reached.json"


# Everything else a run writes in DIR, besides agent_dir(id) for each agent: what an earlier run
# left there, for earlier_run() and clear_earlier_run().
RUN_FILES = (SUMMARY, TRUTH, TIMELINE, FEEDER, INJECT, REFERENCE, REFERENCE_OVER_TIME, REPORT, "feeder.log",
             "inject.log", "cyclonedds.xml", "cyclonedds-netns.xml", "run.json", "scenario.yaml")
RUN_DIRS = ("report", "security", "export")
# A run's own files: DIR holds an earlier run when one of them is there.
RUN_MARKS = (SUMMARY, FEEDER, TRUTH, "feeder.log", "run.json")


def earlier_run(out):
    """What of an earlier run DIR holds (names, sorted; empty when none): its files and agent
    directories."""
    out = Path(out)
    if not out.is_dir():
        return []
    agents = [p.name for p in out.glob("agent_*") if p.is_dir() and p.name[6:].isdigit()]
    marks = [n for n in RUN_MARKS if (out / n).exists()]
    if not agents and not marks:
        return []
    return sorted([n for n in RUN_FILES + RUN_DIRS if (out / n).exists()] + agents)


def clear_earlier_run(out):
    """Removes what an earlier run wrote in DIR (earlier_run), nothing else."""
    out = Path(out)
    for name in earlier_run(out):
        path = out / name
        if path.is_dir() and not path.is_symlink():
            shutil.rmtree(path)
        else:
            path.unlink(missing_ok=True)


def agent_dir(rid):
    """The name of agent RID's directory in a run directory."""
    return f"agent_{rid}"


# The largest run file a tool reads: an agent's checkpoint is at most its loader's 256 MB, and
# every other file of a 256-agent run is far smaller.
MAX_FILE_BYTES = 256 * 1024 * 1024


class RunFileError(ValueError):
    """A run file that is not what a run writes: str() is one line, the file then `reason`."""

    def __init__(self, path, reason):
        super().__init__(f"{path}: {reason}")
        self.path, self.reason = path, reason


def read_bytes(path, max_bytes=MAX_FILE_BYTES):
    """A run file's bytes; OSError when it cannot be opened, RunFileError when it is not a regular
    file (a FIFO or /dev/zero is never read) or holds more than max_bytes."""
    path = Path(path)
    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_CLOEXEC)
    with os.fdopen(fd, "rb") as f:
        st = os.fstat(f.fileno())
        if not stat.S_ISREG(st.st_mode):
            raise RunFileError(path, "not a regular file")
        data = f.read(max_bytes + 1)
    if len(data) > max_bytes:
        raise RunFileError(path, f"larger than the {max_bytes // (1024 * 1024)} MB a run file may be")
    return data


def read_json(path, max_bytes=MAX_FILE_BYTES):
    """A JSON file's value; OSError when it cannot be opened, RunFileError (a ValueError, one line
    naming the file) when it is not a regular file, too large, or not JSON."""
    data = read_bytes(path, max_bytes)
    try:
        return json.loads(data)
    except json.JSONDecodeError as e:
        raise RunFileError(path, f"not JSON ({e.msg}, line {e.lineno} column {e.colno})") from None
    except UnicodeDecodeError:
        raise RunFileError(path, "not JSON (not UTF-8 text)") from None


def why_unreadable(e):
    """The reason a run file could not be read, for a line that names it."""
    return e.reason if isinstance(e, RunFileError) else e.__class__.__name__


class RunDir:
    """The files of one run directory. `read` raises when a file is missing or unreadable,
    `read_if_present` only when it is unreadable, and `load` never for an optional file: it
    notes in `notes` what is missing (unless quiet) or unreadable."""

    def __init__(self, d):
        self.dir = Path(d)
        self.notes = []

    def path(self, name, rid=None):
        """The path of the run's file NAME, or of agent RID's file NAME."""
        return self.dir / name if rid is None else self.dir / agent_dir(rid) / name

    def read(self, name, rid=None):
        return read_json(self.path(name, rid))

    def read_if_present(self, name, rid=None):
        path = self.path(name, rid)
        return read_json(path) if path.exists() else None

    def load(self, name, rid=None, required=False, quiet=False):
        path = self.path(name, rid)
        if rid is not None:
            name = f"{agent_dir(rid)}/{name}"
        if not path.exists():
            if required:
                raise FileNotFoundError(path)
            if not quiet:
                self.notes.append(f"{name}: missing")
            return None
        try:
            return read_json(path)
        except (OSError, ValueError) as e:
            if required:
                raise
            self.notes.append(f"{name}: unreadable ({why_unreadable(e)})")
            return None

    def agent_ids(self):
        """The ids of the agents that have a directory here, in increasing order."""
        prefix = agent_dir("")
        return sorted(int(d.name[len(prefix):]) for d in self.dir.glob(prefix + "*")
                      if d.is_dir() and d.name[len(prefix):].isdigit())


def truth_robots(truth):
    """{robot id: its truth.json record (start, trajectory)} of a truth.json value (or None)."""
    return {r.get("id"): r for r in (truth or {}).get("robots", [])}


def wrap_angle(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def pose_at(trajectory, t):
    """The pose [x, y, theta] of a [[t, x, y, theta], ...] trajectory at time t, or None for an
    empty trajectory. Clamped to its ends; between two samples the position is interpolated
    linearly and the heading along the shorter arc, as mapmesh-eval does (Pose2 Interpolate)."""
    if not trajectory:
        return None
    if t <= trajectory[0][0]:
        return list(trajectory[0][1:4])
    if t >= trajectory[-1][0]:
        return list(trajectory[-1][1:4])
    lo, hi = 0, len(trajectory) - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if trajectory[mid][0] <= t:
            lo = mid
        else:
            hi = mid
    a, b = trajectory[lo], trajectory[hi]
    s = (t - a[0]) / (b[0] - a[0]) if b[0] > a[0] else 0.0
    return [a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2]), wrap_angle(a[3] + s * wrap_angle(b[3] - a[3]))]


def radio_links(robots, range_m, period_s, duration_s):
    """[(t, [(a, b), ...])] every period_s from 0 to duration_s: the pairs of robots (a < b) within
    range_m of each other at t, from their truth.json trajectories, as the feeder decides
    (sim_feeder/radio_model.h). robots: {id: truth.json record}."""
    ids = sorted(rid for rid, r in robots.items() if r.get("trajectory"))
    out = []
    for k in range(int(math.floor(duration_s / period_s + 1e-9)) + 1):
        t = k * period_s
        at = {rid: pose_at(robots[rid]["trajectory"], t) for rid in ids}
        pairs = [(a, b) for i, a in enumerate(ids) for b in ids[i + 1:]
                 if math.hypot(at[a][0] - at[b][0], at[a][1] - at[b][1]) <= range_m]
        out.append((t, pairs))
    return out


def radio_spans(links, period_s):
    """{(a, b): [(start, end)]}: the spans in which each pair was in range, from radio_links."""
    spans = {}
    for t, pairs in links:
        for pair in pairs:
            runs = spans.setdefault(pair, [])
            if runs and abs(runs[-1][1] - t) < 1e-9:
                runs[-1] = (runs[-1][0], t + period_s)
            else:
                runs.append((t, t + period_s))
    return spans


def published_spans(feeder):
    """{(a, b): [(start, end)]} of feeder.json's "links" (the tables the feeder published, whatever
    radio.model decided), or None for a feeder.json written before it recorded them."""
    links = (feeder or {}).get("links") if isinstance(feeder, dict) else None
    if not isinstance(links, dict) or not isinstance(links.get("spans"), list):
        return None
    spans = {}
    for a, b, start, end in links["spans"]:
        spans.setdefault((min(a, b), max(a, b)), []).append((start, end))
    return spans


def links_from_spans(spans, period_s, duration_s):
    """[(t, [(a, b), ...])] every period_s from 0 to duration_s, as radio_links gives them, from
    the spans of published_spans: the pairs whose span holds t."""
    out = []
    for k in range(int(math.floor(duration_s / period_s + 1e-9)) + 1):
        t = k * period_s
        out.append((t, sorted(pair for pair, runs in spans.items()
                              if any(start - 1e-9 <= t < end - 1e-9 for start, end in runs))))
    return out


def history_lines(path):
    """The entries of an agent's history.jsonl, one at a time (a line cut short by a kill is
    skipped); none when the file is missing or unreadable."""
    try:
        with open(path) as f:
            for line in f:
                try:
                    entry = json.loads(line)
                except ValueError:
                    continue  # a line cut by a kill
                if isinstance(entry, dict):
                    yield entry
    except OSError:
        return


def read_history(path):
    """The entries of an agent's history.jsonl as a list (history_lines)."""
    return list(history_lines(path))


def alignment_changes(entries):
    """[(t, peer, aligned?)] from an agent's history entries: a peer that appears among
    peers_aligned, or leaves it, within one incarnation (a new incarnation starts with none)."""
    out, held, inc = [], set(), None
    for e in entries:
        if not isinstance(e.get("t"), (int, float)):
            continue
        if e.get("incarnation") != inc:
            held, inc = set(), e.get("incarnation")
        now = {p for p in (e.get("peers_aligned") or []) if isinstance(p, int)}
        out += [(float(e["t"]), p, True) for p in sorted(now - held)]
        out += [(float(e["t"]), p, False) for p in sorted(held - now)]
        held = now
    return out


def write_json(path, value):
    """Writes path atomically; on failure nothing is left behind (RunError "disk full" when the
    file system has no room)."""
    tmp = path.with_name(path.name + ".tmp")
    try:
        tmp.write_text(json.dumps(value, indent=1) + "\n")
        tmp.replace(path)
    except OSError as e:
        tmp.unlink(missing_ok=True)
        if e.errno in (errno.ENOSPC, errno.EDQUOT):
            raise RunError(f"disk full: {path} not written ({e.strerror}); make room and run again", 1) from e
        raise RunError(f"{path} not written: {e.strerror}", 1) from e
