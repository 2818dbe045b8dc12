"""`swarm run`: one experiment. Starts N agents and the feeder on a private DDS domain, kills
and restarts agents at scenario times, ends the run, stops every process it started (also
when interrupted), scores the maps and writes DIR/summary.json."""

import concurrent.futures
import ctypes
import errno
import fcntl
import json
import os
import selectors
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from .columns import format_table
from . import ddsconfig, netns, secure
from .domain import DomainLease
from .run_error import RunError  # noqa: F401  (re-exported: sweep and scale raise it)
from .progress import Progress
from . import provenance
from .reached import reached_until
from .rundir import (AGENT_LOG, CHECKPOINT, FEEDER, INJECT, REFERENCE, REFERENCE_OVER_TIME, REFERENCE_REACHED, REPORT,
                     STATS, SUMMARY, TIMELINE, TRUTH, RunDir, agent_dir, clear_earlier_run, earlier_run, read_json)

REPO = Path(__file__).resolve().parents[2]
# Plots need matplotlib and numpy from Debian, which /usr/bin/python3 has (another python3 may
# come first on PATH).
PLOT_PYTHON = os.environ.get("MAPMESH_PLOT_PYTHON", "/usr/bin/python3")
PR_SET_PDEATHSIG = 1


EXIT_WRITE_FAILED = 3  # a process could not write a run file (common/app/process.h kExitWriteFailed)
DISK_FULL_BYTES = 1 << 20  # less free space than this on --out's file system counts as full
LOCK = ".lock"  # in DIR while a run uses it (flock): a second run on the same DIR is refused
HISTORY = "history.jsonl"  # an agent's line of counters at every checkpoint, all incarnations
SHRINK_FRACTION = 0.9  # a final local map under this share of the most it held is flagged

STOP_GRACE_S = 15.0  # wall seconds the agents have to write their outputs once asked to stop ...
STOP_GRACE_S_PER_AGENT = 0.5  # ... or this much per agent, when that is longer


class Interrupted(Exception):
    pass


def detach_from_terminal():
    """After a hangup, whatever is printed goes nowhere rather than failing on the closed
    terminal (EIO)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    for fd in (1, 2):
        os.dup2(devnull, fd)
    os.close(devnull)


def bin_dir():
    return Path(os.environ.get("MAPMESH_BIN", REPO / "build" / "bin"))


def binary(name):
    path = bin_dir() / name
    if not path.exists():
        raise RunError(f"{path} not found: build first (cmake -S . -B build && cmake --build build -j2)")
    return str(path)


def _child_setup(netns_path=None):
    # Own process group (a terminal's Ctrl-C reaches only the launcher, which stops the
    # children in order), and die with the launcher even if it is SIGKILLed. With --hosts
    # netns, also move into the host's network namespace.
    os.setpgrp()
    try:
        ctypes.CDLL("libc.so.6", use_errno=True).prctl(PR_SET_PDEATHSIG, signal.SIGKILL)
    except OSError:
        pass
    if netns_path:
        netns.enter(netns_path)


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


class Proc:
    """One started process, what it cost, and how the launcher ended it (if it did)."""

    def __init__(self, popen):
        self.popen = popen
        self.pid = popen.pid
        self.returncode = None
        self.cpu_s = 0.0
        self.max_rss_mb = 0.0
        self.killed = False   # SIGKILLed by the --kill schedule: a fault we caused, not a failure
        self.stopped = False  # still running when the run ended, and asked to stop

    @property
    def failed(self):
        """True unless the process was killed by the schedule or, stopped at the end, exited 0:
        a non-zero exit, a signal we did not send, or an end on its own while the run went on."""
        if self.killed:
            return False
        return not self.stopped or self.returncode != 0

    def _reaped(self, status, usage):
        self.returncode = os.waitstatus_to_exitcode(status)
        self.popen.returncode = self.returncode  # so Popen never waits for it again
        self.cpu_s = usage.ru_utime + usage.ru_stime
        self.max_rss_mb = usage.ru_maxrss / 1024.0

    def poll(self):
        if self.returncode is None:
            try:
                pid, status, usage = os.wait4(self.pid, os.WNOHANG)
            except ChildProcessError:
                return self.returncode
            if pid == self.pid:
                self._reaped(status, usage)
        return self.returncode

    def wait(self, timeout):
        end = time.monotonic() + timeout
        while self.poll() is None and time.monotonic() < end:
            time.sleep(0.02)
        return self.returncode

    def signal(self, sig):
        if self.poll() is None:
            try:
                os.kill(self.pid, sig)
            except ProcessLookupError:
                pass

    def stop(self, grace_s):
        """SIGTERM, then SIGKILL after grace_s."""
        if self.poll() is not None:
            return self.returncode
        self.signal(signal.SIGTERM)
        if self.wait(grace_s) is None:
            self.signal(signal.SIGKILL)
            self.wait(5.0)
        return self.returncode


class AgentSlot:
    """Everything about one robot's agent across its incarnations."""

    def __init__(self, rid):
        self.id = rid
        self.procs = []
        self.killed_at = []
        self.restarted_at = []
        self.paused_at = []
        self.alive_at_end = False

    @property
    def current(self):
        return self.procs[-1] if self.procs else None


class SwarmRun:
    def __init__(self, args):
        self.args = args
        self.scenario = str(Path(args.scenario))
        self.out = Path(os.path.abspath(args.out))  # the processes run in the repository
        self.kills = parse_schedule(args.kill, "kill")
        self.restarts = parse_schedule(args.restart, "restart")
        self.pauses = parse_pauses(getattr(args, "pause", None))
        self.fault_origins = {}  # (kind, id, t) -> the scenario's faults entry it came from
        self.paused = []  # pauses under way: [resume at (monotonic), record]
        self.pause_log = []  # what happened: {"id", "t", "seconds", "wall_start", "wall_end"}
        self.common = common_args(args)  # arguments every process gets
        self.feeder = None
        self.injector = None
        self.kill_wall = {}  # (t, id) -> wall time of the kill
        self.agents = {}
        self.lease = None
        self.info = None
        self.security = None  # secure.RunSecurity with --secure
        self.hosts = None  # netns.Hosts with --hosts netns
        self.dds_config = None  # the Cyclone config every process is given (--hosts netns)
        self.lock = None  # DIR/.lock's descriptor while this run holds it

    # ----- set-up -------------------------------------------------------------------------
    def add_scenario_faults(self, faults):
        """The scenario's `faults:` join the flags' (mapmesh-feeder checked each entry)."""
        for kind, into in (("kill", self.kills), ("restart", self.restarts)):
            for i, e in enumerate(faults.get(kind, [])):
                into.append((float(e["t"]), int(e["id"])))
                self.fault_origins[(kind, int(e["id"]), float(e["t"]))] = f"faults.{kind}[{i}]"
        for i, e in enumerate(faults.get("pause", [])):
            self.pauses.append((float(e["t"]), int(e["id"]), float(e["seconds"])))
            self.fault_origins[("pause", int(e["id"]), float(e["t"]))] = f"faults.pause[{i}]"
        if faults.get("inject"):
            if self.args.inject:
                raise RunError(f"--inject {self.args.inject}: the scenario injects too (faults.inject.cases: "
                               f"{faults['inject']}); give one of them", 2)
            self.args.inject = faults["inject"]
            self.args.inject_period = float(faults.get("inject_period_s", self.args.inject_period))

    def check_plan(self):
        """Everything about the run checked before anything starts or is written: the scenario with
        its overrides, the whole fault schedule (flags and the scenario's faults), the injector's
        cases and the hosts. RunError (one line) on the first fault."""
        self.info = feeder_check(self.scenario, self.common)
        self.add_scenario_faults(self.info.get("faults") or {})
        ids = set(self.info["robots"])
        schedule = ([("kill", t, rid) for t, rid in self.kills] + [("restart", t, rid) for t, rid in self.restarts]
                    + [("pause", t, rid) for t, rid, _ in self.pauses])
        for kind, t, rid in schedule:
            if rid not in ids:
                raise RunError(f"{fault_label(kind, rid, t, self.fault_origins)}: no robot {rid} in this run "
                               f"(robots {sorted(ids)})", 2)
            if t > self.info["duration"]:
                raise RunError(f"{fault_label(kind, rid, t, self.fault_origins)}: after the end of the run "
                               f"({self.info['duration']} s)", 2)
        check_fault_schedule(self.kills, self.restarts, self.pauses, self.fault_origins)

        who = self.args.inject_identity
        if who != "none" and not (self.args.inject and self.args.secure):
            raise RunError(f"--inject-identity {who}: needs --inject and --secure", 2)
        if who.startswith("agent") and int(who[5:]) not in ids:
            raise RunError(f"--inject-identity {who}: no robot {who[5:]} in this run (robots {sorted(ids)})", 2)
        if self.args.inject:
            cmd = [binary("mapmesh-inject"), "--scenario", self.scenario, "--cases", self.args.inject,
                   "--check"] + self.common
            r = subprocess.run(cmd, capture_output=True, text=True)
            if r.returncode != 0:
                raise RunError("--inject: " + last_line(r.stderr, "check failed").removeprefix("mapmesh-inject: "), 2)
        net = getattr(self.args, "hosts", "loopback")
        if net == "netns":
            netns.require(self.args.net_loss, self.args.net_rate)
        elif self.args.net_loss or self.args.net_rate:
            raise RunError("--net-loss and --net-rate act on the hosts' links: they need --hosts netns", 2)

    def check_scenario(self):
        """The run's plan checked (check_plan), then its folder made ready: created, locked, an
        earlier run refused or (--force) cleared; the DDS config chosen."""
        self.check_plan()
        net = getattr(self.args, "hosts", "loopback")
        # Every agent, the feeder and the injector join the run's domain.
        if self.out.exists() and not self.out.is_dir():
            raise RunError(f"--out {self.out}: is a file, not a folder; choose a folder", 2)
        try:
            self.out.mkdir(parents=True, exist_ok=True)
        except OSError as e:
            raise RunError(f"--out {self.out}: cannot create the folder ({e.strerror})", 2) from None
        if self.lock is None:  # before anything in DIR changes
            self.lock = lock_run_dir(self.out)
            earlier = earlier_run(self.out)
            if earlier and not getattr(self.args, "force", False):
                shown = ", ".join(earlier[:4]) + (f" and {len(earlier) - 4} more" if len(earlier) > 4 else "")
                raise RunError(f"--out {self.out}: holds an earlier run ({shown}); choose another folder, or add "
                               "--force to replace it", 2)
            clear_earlier_run(self.out)
        if net == "netns":
            return  # the hosts' own config (execute) holds any number of processes
        processes = len(self.info["robots"]) + 1 + (1 if self.args.inject else 0)
        changes, note = ddsconfig.choose(processes, run_dir=self.out)
        os.environ.update(changes)
        if note and not self.args.quiet:
            print(f"swarm: {note}", file=sys.stderr)

    def agent_cmd(self, rid, incarnation):
        resume = ["--resume"] if incarnation > 1 else []
        cmd = [binary("mapmesh-agent"), "--scenario", self.scenario, "--id", str(rid),
               "--domain", str(self.lease.id), "--out", str(self.out / agent_dir(rid)),
               "--incarnation", str(incarnation)] + resume + self.common
        return cmd + self.dds_flags(lambda: self.security.agent_config(rid))

    def dds_flags(self, secure_config=None):
        """The --dds-config a process gets: under --secure the config of its identity
        (secure_config(); a process with none gets the run's), else the run's (--hosts netns),
        else none (the default loopback config)."""
        if self.security and secure_config is not None:
            return ["--dds-config", str(secure_config())]
        return ["--dds-config", str(self.dds_config)] if self.dds_config else []

    def spawn(self, cmd, log_path, append=False, host=None, **kw):
        """Starts cmd with its output in log_path; with --hosts netns, in namespace `host`."""
        path = self.hosts.path(host) if self.hosts else None
        log = open(log_path, "ab" if append else "wb")
        try:
            p = subprocess.Popen(cmd, stdout=kw.pop("stdout", log), stderr=log,
                                 preexec_fn=lambda: _child_setup(path), cwd=REPO, **kw)
        finally:
            log.close()
        return Proc(p)

    def start_agent(self, rid):
        slot = self.agents[rid]
        incarnation = len(slot.procs) + 1
        if incarnation == 1:  # an earlier run's files in DIR must not leak into this one
            shutil.rmtree(self.out / agent_dir(rid), ignore_errors=True)
        (self.out / agent_dir(rid)).mkdir(parents=True, exist_ok=True)
        slot.procs.append(self.spawn(self.agent_cmd(rid, incarnation), self.out / agent_dir(rid) / AGENT_LOG,
                                     append=incarnation > 1, host=f"agent{rid}"))

    def start_injector(self):
        cmd = [binary("mapmesh-inject"), "--scenario", self.scenario, "--domain", str(self.lease.id),
               "--cases", self.args.inject, "--period-s", str(self.args.inject_period),
               "--report", str(self.out / INJECT)] + self.common
        if getattr(self.args, "inject_sim_period", None):
            cmd += ["--sim-period-s", str(self.args.inject_sim_period)]
        who = self.args.inject_identity
        if who == "forged":
            cmd += self.dds_flags(lambda: self.security.forged_config())
        elif who.startswith("agent"):
            cmd += self.dds_flags(lambda: self.security.agent_config(int(who[5:])))
            cmd += ["--as-robot", who[5:]] if self.security else []
        else:
            cmd += self.dds_flags()
        self.injector = self.spawn(cmd, self.out / "inject.log", host="inject")

    # ----- the run ------------------------------------------------------------------------
    def execute(self):
        self.check_scenario()  # DIR created, locked, and what an earlier run left there removed (--force)
        provenance.write_run_json(self.out, self.args, self.info, self.kills, self.restarts, self.pauses, bin_dir())
        self.lease = DomainLease()
        wall_start = time.monotonic()
        interrupted = False
        # A closed terminal (SIGHUP) stops a run as SIGTERM does, outputs written; before and
        # after the run's loop it only takes the terminal away.
        old_hup = signal.signal(signal.SIGHUP, self._on_hangup_outside_loop)
        try:
            if getattr(self.args, "hosts", "loopback") == "netns":
                self.start_hosts()
            if self.args.secure:
                base = self.dds_config or os.environ.get("CYCLONEDDS_URI", f"file://{ddsconfig.DEFAULT}")
                self.security = secure.RunSecurity(self.out, self.lease.id, str(base).removeprefix("file://"))
                # Every identity made and checked before anything starts (a restarted agent checks
                # its own again: mapmesh-agent refuses a key that does not match its certificate).
                self.security.feeder_config()
                for rid in self.info["robots"]:
                    self.security.agent_config(rid)
                self.security.check()
            for rid in self.info["robots"]:
                self.agents[rid] = AgentSlot(rid)
                self.start_agent(rid)
            if self.args.inject:
                self.start_injector()
            holds = sorted({t for t, _ in self.kills + self.restarts} | {t for t, _, _ in self.pauses})
            cmd = [binary("mapmesh-feeder"), "--scenario", self.scenario, "--domain", str(self.lease.id),
                   "--out", str(self.out), "--events", "--control"] + self.common
            cmd += self.dds_flags(lambda: self.security.feeder_config())
            if self.args.rate:
                cmd += ["--rate", str(self.args.rate)]
            for t in holds:
                cmd += ["--hold-at", str(t)]
            self.feeder = self.spawn(cmd, self.out / "feeder.log", stdout=subprocess.PIPE, stdin=subprocess.PIPE,
                                     host="feeder")
            # The feeder tells a paused agent (its process exists) from a dead one by its process.
            for rid, slot in self.agents.items():
                self.send(f"pid {rid} {slot.current.pid}")
            self.loop(wall_start)
        except Interrupted:
            interrupted = True
        finally:
            try:
                self.stop_all()
            finally:
                if self.hosts:
                    self.hosts.close()
                self.lease.close()
        wall_s = time.monotonic() - wall_start
        try:
            return self.summarise(wall_s, interrupted)
        finally:
            signal.signal(signal.SIGHUP, old_hup)

    def start_hosts(self):
        """--hosts netns: a namespace per agent, for the feeder and for the injector, on one
        bridge, and the Cyclone config that names their interface."""
        names = [f"agent{rid}" for rid in self.info["robots"]] + ["feeder"] + (["inject"] if self.args.inject else [])
        self.hosts = netns.Hosts(names, loss_percent=self.args.net_loss, rate_mbit=self.args.net_rate)
        self.hosts.create()
        self.dds_config = self.hosts.cyclone_config(self.out, len(names))
        if not self.args.quiet:
            extra = "".join([f", {self.args.net_loss:g} % UDP loss on receipt" if self.args.net_loss else "",
                             f", {self.args.net_rate:g} Mbit/s per host" if self.args.net_rate else ""])
            print(f"swarm: {len(names)} hosts in network namespaces {self.hosts.tag}-* on one bridge{extra}",
                  file=sys.stderr)

    def send(self, line):
        try:
            self.feeder.popen.stdin.write((line + "\n").encode())
            self.feeder.popen.stdin.flush()
        except (BrokenPipeError, OSError):
            pass

    def on_hold(self, t):
        for when, rid in sorted(self.kills):
            if when <= t + 1e-9 and rid not in self.done_kills.get(when, set()):
                self.done_kills.setdefault(when, set()).add(rid)
                slot = self.agents[rid]
                if slot.current and slot.current.poll() is None:
                    self.kill_wall[(when, rid)] = time.time()  # for liveliness timing
                    slot.current.killed = True
                    slot.current.signal(signal.SIGKILL)
                    slot.current.wait(5.0)
                    slot.killed_at.append(t)
                    self.reported_dead.add(slot.current.pid)
                    self.send(f"dead {rid}")
                    self.progress.note(f"t={t:.1f}s killed agent {rid}")
        for when, rid in sorted(self.restarts):
            if when <= t + 1e-9 and rid not in self.done_restarts.get(when, set()):
                self.done_restarts.setdefault(when, set()).add(rid)
                slot = self.agents[rid]
                if slot.current and slot.current.poll() is None:
                    self.progress.note(f"t={t:.1f}s --restart {rid}: agent {rid} is still running; not restarted")
                    continue
                self.send(f"expect {rid}")
                self.start_agent(rid)
                self.send(f"pid {rid} {slot.current.pid}")
                slot.restarted_at.append(t)
                self.progress.note(f"t={t:.1f}s restarted agent {rid}")
        for when, rid, seconds in sorted(self.pauses):
            if when <= t + 1e-9 and (when, rid) not in self.done_pauses:
                self.done_pauses.add((when, rid))
                slot = self.agents[rid]
                if not (slot.current and slot.current.poll() is None):
                    self.progress.note(f"t={t:.1f}s --pause {rid}: agent {rid} is not running; not paused")
                    continue
                slot.current.signal(signal.SIGSTOP)
                record = {"id": rid, "t": when, "seconds": seconds, "wall_start": time.time(), "wall_end": None}
                self.pause_log.append(record)
                slot.paused_at.append(t)
                self.paused.append([time.monotonic() + seconds, record, slot.current])
                self.progress.note(f"t={t:.1f}s paused agent {rid} for {seconds:g} s")
        self.send("continue")

    def resume_paused(self, everyone=False):
        """SIGCONT to the paused agents whose pause is over (or to all of them)."""
        now = time.monotonic()
        for entry in list(self.paused):
            resume_at, record, proc = entry
            if everyone or now >= resume_at:
                proc.signal(signal.SIGCONT)
                record["wall_end"] = time.time()
                self.paused.remove(entry)
                if not everyone:
                    self.progress.note(f"agent {record['id']} resumed after {record['seconds']:g} s")

    def loop(self, wall_start):
        self.done_kills, self.done_restarts, self.done_pauses = {}, {}, set()
        self.reported_dead = set()  # pids whose end the feeder has been told about
        self.progress = Progress(self.info["duration"], quiet=self.args.quiet)
        deadline = wall_start + self.args.timeout
        sel = selectors.DefaultSelector()
        out = self.feeder.popen.stdout
        os.set_blocking(out.fileno(), False)
        sel.register(out, selectors.EVENT_READ)
        buf = b""
        old_handlers = {s: signal.signal(s, self._on_signal) for s in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)}
        try:
            while True:
                if time.monotonic() > deadline:
                    raise RunError(f"run exceeded --timeout {self.args.timeout:.0f} s; stopped", 1)
                eof = False
                self.resume_paused()
                wait = min([0.25] + [max(0.0, at - time.monotonic()) for at, _, _ in self.paused])
                for _key, _ in sel.select(timeout=wait):
                    chunk = out.read()
                    if chunk == b"":
                        eof = True
                    elif chunk:
                        buf += chunk
                while b"\n" in buf:
                    line, buf = buf.split(b"\n", 1)
                    self.on_event(line)
                # An agent that died on its own must not hold up lockstep.
                for rid, slot in self.agents.items():
                    p = slot.current
                    if p and p.poll() is not None and p.pid not in self.reported_dead:
                        self.reported_dead.add(p.pid)
                        self.progress.note(f"agent {rid} exited unexpectedly (code {p.returncode})")
                        self.send(f"dead {rid}")
                if eof or self.feeder.poll() is not None:
                    break
            code = self.feeder.wait(30.0)
            if code != 0:
                raise RunError(self.why_the_feeder_failed(code), 1)
        finally:
            for s, h in old_handlers.items():
                signal.signal(s, h)
            self.progress.finish()

    def why_the_feeder_failed(self, code):
        """One line: a full disk when that is the cause, else the feeder's exit code and log."""
        free = disk_full(self.out)
        if code == EXIT_WRITE_FAILED or free is not None:
            self.stop_all()  # the agents' exit codes say which could not write either
            cannot = [rid for rid, slot in self.agents.items()
                      if slot.current is not None and slot.current.returncode == EXIT_WRITE_FAILED]
            who = "the feeder" + (f" and agents {', '.join(map(str, cannot))}" if cannot else "")
            if free is not None:
                return (f"disk full: {self.out} has {free // 1024} KiB free; {who} could not write their outputs "
                        f"(summary.json not written); make room and run again")
            return f"{who} could not write their outputs in {self.out}: see {self.out / 'feeder.log'}"
        return f"mapmesh-feeder exited with code {code}: see {self.out / 'feeder.log'}"

    def _on_signal(self, signum, _frame):
        if signum == signal.SIGHUP:
            detach_from_terminal()
        raise Interrupted()

    def _on_hangup_outside_loop(self, _signum, _frame):
        detach_from_terminal()  # the run goes on to its summary

    def on_event(self, line):
        try:
            ev = json.loads(line)
        except ValueError:
            return
        kind = ev.get("event")
        if kind == "hold":
            self.on_hold(ev["t"])
        elif kind == "progress":
            self.progress.update(ev)
        elif kind == "done":
            for slot in self.agents.values():
                slot.alive_at_end = slot.current is not None and slot.current.poll() is None

    def stop_all(self):
        """Stops every process this run started: agents politely (they write their maps),
        then the feeder; anything that does not stop in time is killed. A fault injector stops
        first, so that the agents' final maps are written with no injection under way."""
        self.resume_paused(everyone=True)  # a stopped process would not hear SIGTERM
        if self.injector is not None:
            self.injector.stop(10.0)
        for slot in self.agents.values():
            if slot.current is not None and slot.current.poll() is None:
                slot.current.stopped = True
                slot.current.signal(signal.SIGTERM)
        # All write their outputs at once: on a few cores a large swarm needs longer than one
        # agent alone (128 agents: more than 15 s), so the wait is for all of them together.
        deadline = time.monotonic() + max(STOP_GRACE_S, STOP_GRACE_S_PER_AGENT * len(self.agents))
        for slot in self.agents.values():
            if slot.current is not None:
                slot.current.stop(max(1.0, deadline - time.monotonic()))
        if self.feeder is not None:
            if self.feeder.poll() is None:
                self.send("stop")
            self.feeder.stop(10.0)
            if self.feeder.popen.stdout:
                self.feeder.popen.stdout.close()
            if self.feeder.popen.stdin:
                try:
                    self.feeder.popen.stdin.close()
                except OSError:
                    pass

    # ----- results ------------------------------------------------------------------------
    def compute_reference(self, interrupted):
        """DIR/reference.json by `mapmesh-lab reference` on the run's scenario (the same --agents and
        --set): the centralized batch optimum (with no robot's start known, the fair limit, and with
        every true start), each robot's own and the known-pose map, after the
        run so that it takes nothing from the agents. What summary.json's `reference` holds (the
        maps left out), with the wall time it took."""
        if getattr(self.args, "no_reference", False):
            return {"available": False, "why_none": "skipped (--no-reference)"}
        if interrupted:
            return {"available": False, "why_none": "the run was interrupted"}
        try:
            lab = binary("mapmesh-lab")
        except RunError as e:  # nothing else of the run is lost for want of it (the table's last line says why)
            return {"available": False, "why_none": str(e)}
        if not self.args.quiet:
            print("computing the reference (the centralized batch optimum; --no-reference skips it)", flush=True)
        start = time.monotonic()
        cmd = [lab, "reference", "--scenario", self.scenario, "--out", str(self.out / REFERENCE)] + self.common
        r = subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)
        wall = round(time.monotonic() - start, 3)
        if r.returncode != 0 or not (self.out / REFERENCE).exists():
            reason = last_line(r.stderr, f"exit code {r.returncode}").removeprefix("mapmesh-lab: ")
            return {"available": False, "why_none": f"mapmesh-lab reference failed: {reason}", "wall_s": wall}
        ref = RunDir(self.out).read(REFERENCE)
        return dict(strip_maps(ref), wall_s=wall)

    def solve_until(self, lab, until, path):
        """`mapmesh-lab reference` of the fair optimum alone (no known-pose map, no known-starts
        optimum) on each robot's data up to until[robot] (the rest whole), into path."""
        cmd = [lab, "reference", "--scenario", self.scenario, "--no-known-pose", "--no-known-starts",
               "--out", str(path)] + self.common
        for robot, t in sorted(until.items()):
            cmd += ["--until", f"{robot}={t}"]
        return subprocess.run(cmd, capture_output=True, text=True, cwd=REPO)

    def compute_reached(self, reference):
        """agent_<id>/reference_reached.json for every agent that some robot's data reached only in
        part (reached.py): `mapmesh-lab reference` on the data that reached it, beside the
        central optimum of all of it. Returns {id: {robot: until_s}} (empty where all of it
        reached the agent), and the agents whose reference failed (their gap_to_reached: null)."""
        failed = set()  # agents whose reference of what reached them could not be computed
        if not reference.get("available"):
            return {}, failed
        agents = {}
        for rid in self.agents:
            d = self.out / agent_dir(rid)
            agents[rid] = tuple(read_json(d / name) if (d / name).exists() else None
                                for name in (STATS, CHECKPOINT))
        period = self.info.get("resolved", {}).get("agent.map_publish_period_s")
        period = float(period) if isinstance(period, (int, float)) else 1.0
        restarted = {rid for rid, slot in self.agents.items() if slot.restarted_at}
        # A joining agent's maps carry its own data only (its global map stays off the wire).
        joining = self.info.get("resolved", {}).get("agent.fusion") == "joining"
        until = reached_until(agents, float(self.info["duration"]), 2.0 * period, restarted, maps_relay=not joining)
        for rid, slot in self.agents.items():
            # A restarted agent holds what its earlier incarnations took (its checkpoint), which
            # its last process's stats do not count: its limit stays the whole run's.
            if slot.restarted_at:
                until[rid] = {}
        lab = binary("mapmesh-lab")
        for rid, robots in until.items():
            path = self.out / agent_dir(rid) / REFERENCE_REACHED
            path.unlink(missing_ok=True)
            if not robots:
                continue
            r = self.solve_until(lab, robots, path)
            if r.returncode != 0 or not path.exists():
                print(f"swarm: the reference of what reached agent {rid} failed: "
                      f"{last_line(r.stderr, f'exit code {r.returncode}')}", file=sys.stderr)
                failed.add(rid)
        return until, failed

    def compute_reference_over_time(self, reference):
        """DIR/reference_over_time.json, for the gap over time: the centralized optimum with no start
        known (reference.json's `central`) of every robot's data up to each of several times, by
        `mapmesh-lab reference --until ROBOT=T` for every robot (two at a time). The times: for k
        in 1 .. --gap-samples - 1, the latest snapshot time of any agent (history.jsonl) no later
        than k / --gap-samples of the scenario (the end is reference.json's). mapmesh-eval scores
        each agent's snapshot at those times against them (timeline.json). Returns what
        summary.json's reference holds of it (the times and the wall time), or None."""
        samples = getattr(self.args, "gap_samples", 0) or 0
        (self.out / REFERENCE_OVER_TIME).unlink(missing_ok=True)
        if samples < 2 or not reference.get("available"):
            return None
        duration = float(self.info["duration"])
        shots = sorted(snapshot_times(self.out / agent_dir(rid) / HISTORY for rid in self.agents))
        times = []
        for k in range(1, samples):
            before = [t for t in shots if t <= duration * k / samples + 1e-9]
            if before and before[-1] > 0 and before[-1] not in times:
                times.append(before[-1])
        if not times:
            return None
        if not self.args.quiet:
            print(f"computing the optimum at {len(times)} earlier times, for the gap over time "
                  "(--gap-samples 0 skips it)", flush=True)
        lab = binary("mapmesh-lab")
        start = time.monotonic()

        def solve(t):
            with tempfile.TemporaryDirectory() as tmp:
                path = Path(tmp) / REFERENCE
                r = self.solve_until(lab, {rid: t for rid in self.agents}, path)
                if r.returncode != 0 or not path.exists():
                    print(f"swarm: the optimum at t={t:g} s failed: {last_line(r.stderr, f'exit code {r.returncode}')}",
                          file=sys.stderr)
                    return None
                ref = read_json(path)
                return {"t": t, "central": ref.get("central"), "total_s": ref.get("total_s")}

        with concurrent.futures.ThreadPoolExecutor(max_workers=2) as pool:
            solved = [s for s in pool.map(solve, times) if s is not None and s.get("central")]
        wall = round(time.monotonic() - start, 3)
        write_json(self.out / REFERENCE_OVER_TIME, {"available": bool(solved), "samples": solved})
        return {"samples_t": [s["t"] for s in solved], "wall_s": wall}

    def summarise(self, wall_s, interrupted):
        run = RunDir(self.out)
        reference = self.compute_reference(interrupted)
        reached, reached_failed = self.compute_reached(reference)
        over_time = self.compute_reference_over_time(reference)
        scores = {}
        if run.path(TRUTH).exists():
            r = subprocess.run([binary("mapmesh-eval"), "--run", str(self.out)], capture_output=True, text=True)
            if r.returncode == 0:
                scores = json.loads(r.stdout).get("agents", {})
            else:
                print(f"swarm: mapmesh-eval failed: {r.stderr.strip()}", file=sys.stderr)
        feeder_stats = {r["id"]: r for r in (run.read_if_present(FEEDER) or {}).get("robots", [])}
        agents = []
        for rid, slot in self.agents.items():
            # final, or the last checkpoint of a killed agent
            stats = run.read_if_present(STATS, rid) or {}
            held = most_landmarks(self.out / agent_dir(rid) / HISTORY)
            score = scores.get(str(rid), {})
            sent = feeder_stats.get(rid, {})
            agents.append({
                "id": rid,
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
                "gap_to_reached": None if rid in reached_failed else score.get("gap_to_reached"),
                "reached_until": {str(r): t for r, t in sorted(reached.get(rid, {}).items())},
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
            })
        # Scenario time played: the whole scenario, or where an interrupted run stopped.
        duration = self.info["duration"]
        played = (run.read_if_present(FEEDER) or {}).get("played_until_s")
        if interrupted and played is not None:
            duration = min(duration, played)
        summary = {
            "scenario": self.info["name"],
            "scenario_file": self.scenario,
            "scenario_duration_s": self.info["duration"],
            "sim_duration_s": duration,
            "wall_s": round(wall_s, 3),
            "real_time_factor": round(duration / wall_s, 3) if wall_s > 0 else None,
            "pace": self.args.pace or self.info["pace"],
            "interrupted": interrupted,
            "kills": [{"id": r, "t": t, "wall": self.kill_wall.get((t, r))} for t, r in self.kills],
            "restarts": [{"id": r, "t": t} for t, r in self.restarts],
            "pauses": self.pause_log,
            "feeder": {"exit_code": self.feeder.returncode if self.feeder else None,
                       "cpu_s": round(self.feeder.cpu_s, 3) if self.feeder else None,
                       "max_rss_mb": round(self.feeder.max_rss_mb, 1) if self.feeder else None},
            "agents": agents,
            "failed_agents": [a["id"] for a in agents if a["failed"]],
        }
        summary["reference"] = reference
        if over_time is not None:
            summary["reference"]["over_time"] = over_time
        summary["network"] = self.hosts.summary() if self.hosts else {"hosts": "loopback"}
        if self.args.inject:
            summary["injected"] = run.read_if_present(INJECT)
            summary["injector_exit_code"] = self.injector.returncode if self.injector else None
        write_json(run.path(SUMMARY), summary)
        # Each agent's counters and scored maps over time, for the report's time plots.
        timeline = {"kills": summary["kills"], "restarts": summary["restarts"], "pauses": summary["pauses"],
                    "agents": {str(rid): scores.get(str(rid), {}).get("history", []) for rid in self.agents}}
        write_json(run.path(TIMELINE), timeline)
        return summary


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


def history_lines(path):
    """The entries of an agent's history.jsonl (a line cut by a kill left out); none without one."""
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


def snapshot_times(paths):
    """The scenario times of the snapshots in these history.jsonl files but the final ones."""
    return {e["t"] for p in paths for e in history_lines(p)
            if isinstance(e.get("t"), (int, float)) and not e.get("final")}


def most_landmarks(path):
    """The most landmarks of each map in an agent's history.jsonl (any incarnation):
    {"local": n, "global": n}, or None without a history."""
    most = {}
    for entry in history_lines(path):
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


def disk_full(path):
    """The free bytes on path's file system when it is full (under DISK_FULL_BYTES), else None."""
    try:
        free = shutil.disk_usage(path).free
    except OSError:
        return None
    return free if free < DISK_FULL_BYTES else None


def lock_run_dir(out):
    """Takes DIR/.lock for this run (held until the process ends); RunError when another run
    holds it."""
    fd = os.open(out / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        holder = os.read(fd, 32).decode(errors="replace").strip() or "?"
        os.close(fd)
        raise RunError(f"{out}: another run (pid {holder}) is using this folder; wait for it or choose another --out",
                       2) from None
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
    except OSError:
        pass  # (a full disk) the lock holds without the pid
    return fd


def last_line(text, default):
    """The last line of a process's stderr (its one-line reason), or default."""
    return (text.strip().splitlines() or [default])[-1]


def plot(script, run_dir, what):
    """Runs scripts/plots/SCRIPT on RUN_DIR with Debian's python3 (matplotlib). True when it
    worked; otherwise prints why WHAT was not written and returns False."""
    r = subprocess.run([PLOT_PYTHON, str(REPO / "scripts" / "plots" / script), str(run_dir)],
                       capture_output=True, text=True)
    if r.returncode != 0:
        print(f"swarm: {what} not written: {last_line(r.stderr, f'exit code {r.returncode}')}", file=sys.stderr)
    return r.returncode == 0


def write_report(run_dir):
    """RUN_DIR/report.html by scripts/plots/report.py. Returns its path, or None with the
    reason on stderr."""
    return Path(run_dir) / REPORT if plot("report.py", run_dir, "report") else None


def common_args(args):
    """The arguments every process of a run gets: agents, overrides and the pace (in lockstep the
    agents exchange maps at the feeder's ticks, so every process learns it)."""
    common = ["--agents", str(args.agents)] if args.agents else []
    for s in args.set or []:
        common += ["--set", s]
    if getattr(args, "pace", None):
        common += ["--set", f"feeder.pace={args.pace}"]
    return common


def feeder_check(scenario, common):
    """The scenario as the run's processes will read it (mapmesh-feeder --check --events): its
    robots, duration, seed, faults and every key resolved. RunError (one line) when it is bad."""
    r = subprocess.run([binary("mapmesh-feeder"), "--scenario", str(scenario), "--check", "--events"] + common,
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise RunError(last_line(r.stderr, "scenario check failed").removeprefix("mapmesh-feeder: "), 2)
    return json.loads(r.stdout.strip().splitlines()[-1])


def cmd_run(args):
    if args.from_run:
        if args.scenario:
            raise RunError(f"--from {args.from_run}: the scenario comes from the run.json; give no SCENARIO", 2)
        defaults = getattr(args, "option_defaults", {})
        given = [n for n in provenance.OPTIONS if n != "scenario" and n in defaults and getattr(args, n) != defaults[n]]
        if given:
            raise RunError(f"--from {args.from_run}: every run option comes from the run.json; give none beside it "
                           f"(got --{given[0].replace('_', '-')})", 2)
        try:
            options, _ = provenance.options_from(args.from_run)
            # Every option as the command line takes it: the same parser, the same ranges.
            if hasattr(args, "options_parser"):
                parsed = args.options_parser().parse_args(provenance.option_flags(options, defaults))
                why = args.option_values_error(parsed)
                if why:
                    raise ValueError(why)
                options = {name: getattr(parsed, name) if name != "scenario" else value
                           for name, value in options.items()}
        except ValueError as e:
            message = str(e)
            where = "" if message.startswith("--from") else f"--from {args.from_run}: "
            raise RunError(where + message, 2) from None
        for name, value in options.items():
            setattr(args, name, value)
    if not args.scenario:
        raise RunError("give a SCENARIO.yaml (or --from DIR/run.json)", 2)
    if args.print_config:
        provenance.print_config(feeder_check(args.scenario, common_args(args))["resolved"])
        return 0
    if not args.out:
        raise RunError("--out DIR: where the run goes (required)", 2)
    run = SwarmRun(args)
    summary = run.execute()
    print(format_table(summary))
    print(describe_reference(summary.get("reference")))
    if summary["network"]["hosts"] == "netns":
        print(describe_network(summary["network"]))
    print(f"summary: {Path(args.out) / SUMMARY}")
    if not args.no_report and not summary["interrupted"]:
        report = write_report(args.out)
        if report:
            print(f"report:  {report}")
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
    if summary["interrupted"]:
        return 130
    if summary["failed_agents"]:
        print(failure_message(summary, args.out), file=sys.stderr)
        return 1
    return 0


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


def cmd_report(args):
    if not (Path(args.dir) / SUMMARY).exists():
        raise RunError(f"{args.dir}: no summary.json (run scripts/swarm run SCENARIO --out {args.dir})", 1)
    report = write_report(args.dir)
    if report is None:
        return 1
    print(f"report: {report}")
    return 0
