"""`swarm run`: one experiment. Starts N agents and the feeder on a private DDS domain, kills
and restarts agents at scenario times, ends the run, stops every process it started (also
when interrupted), scores the maps and writes DIR/summary.json."""

import fcntl
import json
import os
import selectors
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

from .columns import format_table
from . import ddsconfig, netns, secure
from .domain import DomainLease
from .procs import (EXIT_WRITE_FAILED, REPO, AgentSlot, Interrupted, Proc, bin_dir, binary, child_setup,
                    detach_from_terminal, feeder_check, last_line, write_report)
from .run_error import RunError  # noqa: F401  (re-exported: sweep and scale raise it)
from .progress import Progress
from . import provenance
from .rundir import AGENT_LOG, INJECT, SUMMARY, agent_dir, clear_earlier_run, earlier_run
from .schedule import add_scenario_faults, check_fault_schedule, fault_label, parse_pauses, parse_schedule
from .summary import describe_network, failure_message, summarise, warn_of_losses
from .references import describe_reference

STOP_GRACE_S = 15.0  # wall seconds the agents have to write their outputs once asked to stop ...
STOP_GRACE_S_PER_AGENT = 0.5  # ... or this much per agent, when that is longer
DISK_FULL_BYTES = 1 << 20  # less free space than this on --out's file system counts as full
LOCK = ".lock"  # in DIR while a run uses it (flock): a second run on the same DIR is refused


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
    def check_plan(self):
        """Everything about the run checked before anything starts or is written: the scenario with
        its overrides, the whole fault schedule (flags and the scenario's faults), the injector's
        cases and the hosts. RunError (one line) on the first fault."""
        self.info = feeder_check(self.scenario, self.common)
        add_scenario_faults(self, self.info.get("faults") or {})
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
                                 preexec_fn=lambda: child_setup(path), cwd=REPO, **kw)
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
            return summarise(self, wall_s, interrupted)
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


def common_args(args):
    """The arguments every process of a run gets: agents, overrides and the pace (in lockstep the
    agents exchange maps at the feeder's ticks, so every process learns it)."""
    common = ["--agents", str(args.agents)] if args.agents else []
    for s in args.set or []:
        common += ["--set", s]
    if getattr(args, "pace", None):
        common += ["--set", f"feeder.pace={args.pace}"]
    return common


def cmd_run(args):
    if args.from_run:
        provenance.apply_from(args)
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
    warn_of_losses(summary)
    if summary["interrupted"]:
        return 130
    if summary["failed_agents"]:
        print(failure_message(summary, args.out), file=sys.stderr)
        return 1
    return 0


def cmd_report(args):
    if not (Path(args.dir) / SUMMARY).exists():
        raise RunError(f"{args.dir}: no summary.json (run scripts/swarm run SCENARIO --out {args.dir})", 1)
    report = write_report(args.dir)
    if report is None:
        return 1
    print(f"report: {report}")
    return 0
