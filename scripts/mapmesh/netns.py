"""Hosts in network namespaces for a run (`swarm run --hosts netns`).

Each agent, the feeder and the injector get a network namespace of their own, `<tag>-<host>`,
with one interface, eth0, a veth whose other end is a port of a bridge. The bridge lives in a
namespace of its own too (`<tag>-hub`), so the run touches nothing of the host's network:
nothing leaves the machine, and deleting the run's namespaces removes every link it made.

In each host's namespace, optionally:
- `tc` token bucket (tbf) on eth0: the host sends at most RATE Mbit/s;
- an nftables rule: the host drops LOSS % of the UDP datagrams it receives, chosen by the
  kernel's random number generator (numgen), and counts what it received and dropped.

The namespaces are removed at the end (close()), also when the launcher is interrupted. If the
launcher itself dies (SIGKILL, a crash), a reaper process it started first, in a session of its
own, sees its pipe close and removes them; a later run also removes any namespaces left by a
launcher that no longer exists. The run's processes die with the launcher (PR_SET_PDEATHSIG).

Needs root (CAP_NET_ADMIN and CAP_SYS_ADMIN), iproute2, and nftables when LOSS > 0."""

import ctypes
import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

from . import ddsconfig
from .run_error import RunError

CLONE_NEWNET = 0x40000000
NETNS_DIR = Path("/run/netns")
HUB = "hub"
IFACE = "eth0"
SUBNET = "10.77"  # hosts are 10.77.0.1, 10.77.0.2, ... /16 on the bridge
TAG_RE = re.compile(r"^mm(\d+)r(\d+)-")
_runs_in_this_process = 0


def _tool(name):
    """The path of tool NAME: on PATH, or in the sbin directories a non-root PATH may lack."""
    return shutil.which(name) or next((p for p in (f"/usr/sbin/{name}", f"/sbin/{name}") if os.access(p, os.X_OK)),
                                      None)


def require(loss_percent, rate_mbit, euid=None, tool=_tool):
    """Raises RunError (one line) unless this process can make the namespaces: root, ip, and
    tc and nft when a rate or a loss is asked for."""
    euid = os.geteuid() if euid is None else euid
    if euid != 0:
        raise RunError("--hosts netns: needs root (it creates network namespaces, veth links and nftables rules); "
                       "run as root, or use --hosts loopback", 2)
    needed = [("ip", "iproute2")]
    if rate_mbit:
        needed.append(("tc", "iproute2"))
    if loss_percent:
        needed.append(("nft", "nftables"))
    missing = [f"{name} (Debian package {pkg})" for name, pkg in needed if tool(name) is None]
    if missing:
        raise RunError(f"--hosts netns: {', '.join(missing)} not found; scripts/install-deps installs it", 2)


def _run(args, what, stdin=None):
    r = subprocess.run(args, input=stdin, capture_output=True, text=True)
    if r.returncode != 0:
        tail = (r.stderr.strip().splitlines() or [f"exit code {r.returncode}"])[-1]
        raise RunError(f"--hosts netns: {what} failed: {tail}", 1)
    return r.stdout


def list_namespaces():
    """The names of the host's named network namespaces."""
    try:
        return sorted(p.name for p in NETNS_DIR.iterdir())
    except OSError:
        return []


def delete_namespaces(names):
    """Deletes the named namespaces that exist (no error for those that do not)."""
    present = set(list_namespaces())
    batch = "".join(f"netns del {n}\n" for n in names if n in present)
    if batch:
        subprocess.run([_tool("ip") or "ip", "-force", "-batch", "-"], input=batch, capture_output=True, text=True)


def _alive(pid):
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale():
    """Removes namespaces left by launchers that no longer run; returns their names."""
    stale = [n for n in list_namespaces() if (m := TAG_RE.match(n)) and not _alive(int(m.group(1)))]
    delete_namespaces(stale)
    return stale


def leftovers(tag, marker=None):
    """What of run TAG is still on this host: its named namespaces, its links (every veth end
    carries the alias TAG-HOST; looked for in every network namespace a process or a name
    holds), and the processes whose command line holds MARKER (say, the run directory).
    Empty lists when the run cleaned up."""
    names = [n for n in list_namespaces() if n.startswith(tag + "-")]
    holders = {}  # an open descriptor of each live network namespace (it keeps it while we look)
    try:
        for p in [Path("/proc/1/ns/net")] + [NETNS_DIR / n for n in list_namespaces()] + \
                [d / "ns" / "net" for d in Path("/proc").iterdir() if d.name.isdigit()]:
            try:
                fd = os.open(p, os.O_RDONLY | os.O_CLOEXEC)
            except OSError:
                continue  # its process ended meanwhile
            inode = os.fstat(fd).st_ino
            if inode in holders:
                os.close(fd)
            else:
                holders[inode] = fd
        links = []
        for fd in holders.values():
            try:
                r = subprocess.run([_tool("ip") or "ip", "-o", "link", "show"], capture_output=True, text=True,
                                   preexec_fn=lambda fd=fd: enter(fd))
            except subprocess.SubprocessError:
                # setns refuses a namespace that is being destroyed (its last process just
                # exited); its links go with it. (The run's own links are made by root in this
                # user namespace, so a namespace of another one cannot hold them.)
                continue
            links += [line.split(":")[1].strip() for line in r.stdout.splitlines() if f" alias {tag}-" in line]
    finally:
        for fd in holders.values():
            os.close(fd)
    processes = []
    if marker:
        for d in Path("/proc").iterdir():
            try:
                if d.name.isdigit() and int(d.name) != os.getpid() and \
                        marker.encode() in (d / "cmdline").read_bytes():
                    processes.append(int(d.name))
            except OSError:
                pass
    return {"namespaces": names, "links": links, "processes": processes}


def enter(where):
    """Moves the calling process into the network namespace at path `where`, or of the open
    descriptor `where` (for a child before exec)."""
    libc = ctypes.CDLL("libc.so.6", use_errno=True)
    fd = where if isinstance(where, int) else os.open(where, os.O_RDONLY | os.O_CLOEXEC)
    try:
        if libc.setns(fd, CLONE_NEWNET) != 0:
            err = ctypes.get_errno()
            raise OSError(err, f"setns {where}: {os.strerror(err)}")
    finally:
        if not isinstance(where, int):
            os.close(fd)


def address(index):
    """The address of host number `index` (1, 2, ...) on the bridge."""
    return f"{SUBNET}.{index // 256}.{index % 256}"


def nft_rules(loss_percent):
    """The nftables table of a host: count the UDP it receives, and drop LOSS % of it."""
    per_10k = int(round(loss_percent * 100))
    return f"""table inet mapmesh {{
  chain input {{
    type filter hook input priority filter; policy accept;
    meta l4proto udp counter comment "received"
    meta l4proto udp numgen random mod 10000 < {per_10k} counter drop comment "dropped"
  }}
}}
"""


def nft_counts(listing):
    """{'received': packets, 'dropped': packets} from `nft -j list table inet mapmesh`."""
    out = {}
    for item in json.loads(listing).get("nftables", []):
        rule = item.get("rule")
        if not rule:
            continue
        name = rule.get("comment")
        for e in rule.get("expr", []):
            if "counter" in e and name:
                out[name] = e["counter"]["packets"]
    return out


# The reaper: waits until the launcher's end closes its stdin, then deletes the namespaces.
REAPER = ("import sys; sys.path.insert(0, sys.argv[1]); from mapmesh import netns; sys.stdin.buffer.read(); "
          "netns.delete_namespaces(sys.argv[2:])")


class Hosts:
    """The run's namespaces: create() makes them, spawn_setup(host) is a child's preexec step
    into one, close() reads the kernel's counters and removes them all."""

    def __init__(self, hosts, loss_percent=0.0, rate_mbit=None):
        global _runs_in_this_process
        _runs_in_this_process += 1
        self.tag = f"mm{os.getpid()}r{_runs_in_this_process}"
        self.hosts = list(hosts)
        self.loss = float(loss_percent or 0.0)
        self.rate = rate_mbit
        self.ip = _tool("ip")
        self.names = {h: f"{self.tag}-{h}" for h in self.hosts}
        self.hub = f"{self.tag}-{HUB}"
        self.addresses = {h: address(i) for i, h in enumerate(self.hosts, start=1)}
        self.created = False
        self.counts = {}
        self.reaper = None
        self.closed = False

    def all_names(self):
        return [self.names[h] for h in self.hosts] + [self.hub]

    def _start_reaper(self):
        self.reaper = subprocess.Popen([sys.executable, "-c", REAPER, str(Path(__file__).resolve().parents[1])] +
                                       self.all_names(),
                                       stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                       start_new_session=True, close_fds=True)

    def create(self):
        remove_stale()
        self._start_reaper()  # first: from here on the namespaces go when this process does
        _run([self.ip, "-batch", "-"], "ip netns add", "".join(f"netns add {n}\n" for n in self.all_names()))
        hub = ["link set lo up", "link add br0 type bridge mcast_snooping 0", "link set br0 up"]
        for k, h in enumerate(self.hosts, start=1):
            hub += [f"link add h{k} type veth peer name {IFACE} netns {self.names[h]}", f"link set h{k} master br0",
                    f"link set h{k} alias {self.names[h]}", f"link set h{k} up"]
        _run([self.ip, "-n", self.hub, "-batch", "-"], "setting up the bridge", "\n".join(hub) + "\n")
        for h in self.hosts:
            ns = self.names[h]
            cmds = ["link set lo up", f"link set {IFACE} alias {ns}", f"addr add {self.addresses[h]}/16 dev {IFACE}",
                    f"link set {IFACE} up", f"route add 224.0.0.0/4 dev {IFACE}"]
            _run([self.ip, "-n", ns, "-batch", "-"], f"setting up {ns}", "\n".join(cmds) + "\n")
            if self.rate:
                burst_bytes = max(16000, int(self.rate * 1e6 / 8 * 0.02))  # 20 ms at the rate
                _run([_tool("tc"), "-n", ns, "qdisc", "add", "dev", IFACE, "root", "tbf", "rate", f"{self.rate}mbit",
                      "burst", str(burst_bytes), "latency", "100ms"], f"tc tbf in {ns}")
            if self.loss:
                _run([self.ip, "netns", "exec", ns, _tool("nft"), "-f", "-"], f"nftables in {ns}",
                     nft_rules(self.loss))
        self.created = True

    def path(self, host):
        return str(NETNS_DIR / self.names[host])

    def cyclone_config(self, directory, participants):
        """The Cyclone config every host uses (it names eth0, no loopback), written to DIRECTORY."""
        return ddsconfig.for_interface(IFACE, participants, Path(directory) / "cyclonedds-netns.xml")

    def _read_counts(self):
        for h in self.hosts:
            ns = self.names[h]
            entry = {"namespace": ns, "address": self.addresses[h]}
            if self.loss:
                r = subprocess.run([self.ip, "netns", "exec", ns, _tool("nft"), "-j", "list", "table", "inet",
                                    "mapmesh"], capture_output=True, text=True)
                if r.returncode == 0:
                    c = nft_counts(r.stdout)
                    entry["udp_received"], entry["udp_dropped"] = c.get("received"), c.get("dropped")
            if self.rate:
                r = subprocess.run([_tool("tc"), "-n", ns, "-s", "-j", "qdisc", "show", "dev", IFACE],
                                   capture_output=True, text=True)
                if r.returncode == 0:
                    q = next((q for q in json.loads(r.stdout or "[]") if q.get("kind") == "tbf"), {})
                    entry["tbf"] = {k: q.get(k) for k in ("bytes", "packets", "drops", "overlimits")}
            self.counts[h] = entry

    def close(self):
        """Reads the counters, deletes every namespace of the run (and so its links), and ends
        the reaper. Safe to call more than once."""
        if self.closed:
            return
        self.closed = True
        try:
            if self.created:
                self._read_counts()
        finally:
            delete_namespaces(self.all_names())
            if self.reaper is not None:
                try:
                    self.reaper.stdin.close()
                    self.reaper.wait(10.0)
                except (OSError, subprocess.TimeoutExpired):
                    self.reaper.kill()

    def summary(self):
        """What summary.json's `network` records of these hosts."""
        received = sum(c.get("udp_received") or 0 for c in self.counts.values())
        dropped = sum(c.get("udp_dropped") or 0 for c in self.counts.values())
        out = {"hosts": "netns", "tag": self.tag, "bridge_namespace": self.hub, "loss_percent": self.loss,
               "rate_mbit": self.rate, "per_host": self.counts}
        if self.loss:
            out.update(udp_received=received, udp_dropped=dropped,
                       udp_dropped_percent=round(100.0 * dropped / received, 2) if received else None)
        return out


def probe():
    """None when this host can run --hosts netns with loss and a rate (root, the tools, and a
    kernel that gives namespaces, veth, tbf and nftables), else why not, in one line (for
    tests that skip)."""
    try:
        require(5, 1)
    except RunError as e:
        return str(e)
    name = f"mm{os.getpid()}r0-probe"
    try:
        _run([_tool("ip"), "netns", "add", name], "ip netns add")
        _run([_tool("ip"), "-n", name, "link", "add", "name", "p0", "type", "veth", "peer", "name", "p1"], "veth")
        _run([_tool("tc"), "-n", name, "qdisc", "add", "dev", "p0", "root", "tbf", "rate", "1mbit", "burst", "16000",
              "latency", "100ms"], "tc tbf")
        _run([_tool("ip"), "netns", "exec", name, _tool("nft"), "-f", "-"], "nftables", nft_rules(5))
    except RunError as e:
        return str(e)
    finally:
        delete_namespaces([name])
    return None
