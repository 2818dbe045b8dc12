"""The processes a run starts and the tools it runs: where the binaries are, how a child is set
up (its own process group, dying with the launcher, a host's network namespace), one started
process with what it cost (Proc), one robot's agent across its incarnations (AgentSlot), the
scenario check, and the plot scripts."""

import ctypes
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from . import netns
from .rundir import REPORT
from .run_error import RunError

REPO = Path(__file__).resolve().parents[2]
# Plots need matplotlib and numpy from Debian, which /usr/bin/python3 has (another python3 may
# come first on PATH).
PLOT_PYTHON = os.environ.get("MAPMESH_PLOT_PYTHON", "/usr/bin/python3")
PR_SET_PDEATHSIG = 1
EXIT_WRITE_FAILED = 3  # a process could not write a run file (common/app/process.h kExitWriteFailed)


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


def child_setup(netns_path=None):
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


def feeder_check(scenario, common):
    """The scenario as the run's processes will read it (mapmesh-feeder --check --events): its
    robots, duration, seed, faults and every key resolved. RunError (one line) when it is bad."""
    r = subprocess.run([binary("mapmesh-feeder"), "--scenario", str(scenario), "--check", "--events"] + common,
                       capture_output=True, text=True)
    if r.returncode != 0:
        raise RunError(last_line(r.stderr, "scenario check failed").removeprefix("mapmesh-feeder: "), 2)
    return json.loads(r.stdout.strip().splitlines()[-1])
