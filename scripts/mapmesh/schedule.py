"""A run's fault schedule: kills, restarts and pauses from the flags (ID@T, ID@T:SECONDS) and the
scenario's `faults:`, checked as a whole before anything starts."""

from .run_error import RunError


def parse_schedule(items, what):
    """['2@10', '3@12.5'] -> [(10.0, 2), (12.5, 3)]"""
    out = []
    for item in items or []:
        try:
            rid, t = item.split("@")
            rid, t = int(rid), float(t)
            if rid <= 0 or t < 0:
                raise ValueError
        except ValueError:
            raise RunError(f"--{what} {item}: expected ID@T with a robot id and a time in scenario seconds", 2)
        out.append((t, rid))
    return out


FAULT_KINDS = ("kill", "restart", "pause")


def fault_label(kind, rid, t, origins=None):
    """How an error names a fault: the flag as given, or the scenario's faults entry."""
    where = (origins or {}).get((kind, rid, t))
    return f"{where} ({kind} {rid}@{t:g})" if where else f"--{kind} {rid}@{t:g}"


def check_fault_schedule(kills, restarts, pauses, origins=None):
    """The whole fault schedule, in scenario time, before anything starts: every restart follows a
    kill of its agent (at the same time, the kill goes first), no agent is killed twice without a
    restart between, and no agent is paused while killed. RunError (one line) on the first that
    does not hold. kills and restarts as from parse_schedule, pauses as from parse_pauses;
    origins names the faults that came from the scenario ({(kind, id, t): "faults.kill[0]"})."""
    events = sorted([(t, 0, rid) for t, rid in kills] + [(t, 1, rid) for t, rid in restarts] +
                    [(t, 2, rid) for t, rid, _ in pauses])
    dead = {}  # robot -> when the kill in force was
    for t, kind, rid in events:
        name = fault_label(FAULT_KINDS[kind], rid, t, origins)
        if kind == 0:
            if rid in dead:
                raise RunError(f"{name}: agent {rid} is already killed at {dead[rid]:g} s, with no "
                               f"restart of it between", 2)
            dead[rid] = t
        elif kind == 1:
            if rid not in dead:
                raise RunError(f"{name}: agent {rid} is running then (restart only follows a "
                               f"kill of it at or before {t:g} s)", 2)
            del dead[rid]
        elif rid in dead:
            raise RunError(f"{name}: agent {rid} is killed then (at {dead[rid]:g} s)", 2)


def parse_pauses(items):
    """['2@30:10'] -> [(30.0, 2, 10.0)]: agent ID stopped (SIGSTOP) at scenario time T for SECONDS of wall time."""
    out = []
    for item in items or []:
        try:
            rid, rest = item.split("@")
            t, seconds = rest.split(":")
            rid, t, seconds = int(rid), float(t), float(seconds)
            if rid <= 0 or t < 0 or not seconds > 0 or seconds > 86400:
                raise ValueError
        except ValueError:
            raise RunError(f"--pause {item}: expected ID@T:SECONDS with a robot id, a time in scenario seconds "
                           "and a pause in wall seconds (0 < SECONDS <= 86400)", 2)
        out.append((t, rid, seconds))
    return out


def add_scenario_faults(run, faults):
    """The scenario's `faults:` join the flags' of run (a SwarmRun; mapmesh-feeder checked each
    entry)."""
    for kind, into in (("kill", run.kills), ("restart", run.restarts)):
        for i, e in enumerate(faults.get(kind, [])):
            into.append((float(e["t"]), int(e["id"])))
            run.fault_origins[(kind, int(e["id"]), float(e["t"]))] = f"faults.{kind}[{i}]"
    for i, e in enumerate(faults.get("pause", [])):
        run.pauses.append((float(e["t"]), int(e["id"]), float(e["seconds"])))
        run.fault_origins[("pause", int(e["id"]), float(e["t"]))] = f"faults.pause[{i}]"
    if faults.get("inject"):
        if run.args.inject:
            raise RunError(f"--inject {run.args.inject}: the scenario injects too (faults.inject.cases: "
                           f"{faults['inject']}); give one of them", 2)
        run.args.inject = faults["inject"]
        run.args.inject_period = float(faults.get("inject_period_s", run.args.inject_period))
