"""Which Cyclone DDS configuration a run's processes use, and whether it can hold them all.

The default (config/cyclonedds-loopback.xml, what the binaries read when CYCLONEDDS_URI is
unset) discovers by multicast on the loopback interface, with no cap on processes. Where
multicast on lo does not work, runs fall back to config/cyclonedds-loopback-unicast.xml, whose
unicast discovery numbers the processes of a domain (ParticipantIndex auto) up to
MaxAutoParticipantIndex: a run needing more is refused with a one-line error naming that limit,
instead of agents failing to start one by one."""

import os
import socket
import struct
import xml.etree.ElementTree as ET
from pathlib import Path

from .run_error import RunError

REPO = Path(__file__).resolve().parents[2]
DEFAULT = REPO / "config" / "cyclonedds-loopback.xml"
UNICAST = REPO / "config" / "cyclonedds-loopback-unicast.xml"
# Beyond this many processes on one host, start-up (every process discovering every other on
# a few cores) starves Cyclone's threads for longer than the default 1 s participant lease:
# leases lapse and are renewed over and over, and Cyclone 0.10.2 crashed in its lease-expiry
# path (SIGSEGV in 10 of 128 agents). Such runs get a participant lease of LARGE_SWARM_LEASE.
LARGE_SWARM = 64
LARGE_SWARM_LEASE = "10s"
CYCLONE_DEFAULT_MAX_AUTO_INDEX = 9  # Cyclone's own default of Discovery/MaxAutoParticipantIndex


def loopback_multicast_works(group="239.255.0.1", timeout_s=0.5):
    """Whether a multicast datagram sent on lo (TTL 0) comes back to a socket joined on lo."""
    try:
        rx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
        tx = socket.socket(socket.AF_INET, socket.SOCK_DGRAM, socket.IPPROTO_UDP)
    except OSError:
        return False
    with rx, tx:
        try:
            rx.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            rx.bind((group, 0))
            port = rx.getsockname()[1]
            mreq = struct.pack("4s4s", socket.inet_aton(group), socket.inet_aton("127.0.0.1"))
            rx.setsockopt(socket.IPPROTO_IP, socket.IP_ADD_MEMBERSHIP, mreq)
            rx.settimeout(timeout_s)
            tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton("127.0.0.1"))
            tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_TTL, 0)
            tx.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
            token = os.urandom(8)
            tx.sendto(token, (group, port))
            while True:
                data, _ = rx.recvfrom(64)
                if data == token:
                    return True
        except OSError:
            return False


def participant_limit(uri):
    """How many processes one domain of the Cyclone config at `uri` (file://, a path or inline
    XML) can hold, as (limit, why), or (None, None) when it numbers none (multicast discovery,
    ParticipantIndex none) or cannot be read."""
    try:
        text = uri.strip()
        if not text.startswith("<"):
            path = text[len("file://"):] if text.startswith("file://") else text
            text = Path(path).read_text()
        root = ET.fromstring(text)
    except (OSError, ET.ParseError, ValueError):
        return None, None

    def find(name):
        for e in root.iter():
            if e.tag.rsplit("}", 1)[-1] == name and e.text and e.text.strip():
                return e.text.strip()
        return None

    index = (find("ParticipantIndex") or "default").lower()
    if index not in ("auto", "default"):
        return None, None
    allow = (find("AllowMulticast") or "default").lower()
    if index == "default" and allow not in ("false",):
        return None, None  # Cyclone uses none with multicast discovery
    max_auto = find("MaxAutoParticipantIndex")
    limit = int(max_auto) + 1 if max_auto and max_auto.isdigit() else CYCLONE_DEFAULT_MAX_AUTO_INDEX + 1
    return limit, f"Discovery/MaxAutoParticipantIndex {limit - 1}"


def choose(participants, env=None, probe=loopback_multicast_works, run_dir=None):
    """The environment changes a run of `participants` DDS processes needs, and a note for the
    user (or None). A large run on the default config gets its own copy of it in run_dir with a
    longer participant lease. Raises RunError when the configuration cannot hold them."""
    env = os.environ if env is None else env
    uri = env.get("CYCLONEDDS_URI")
    changes, note = {}, None
    if not uri:
        if probe():
            if participants <= LARGE_SWARM or run_dir is None:
                return changes, None
            text = DEFAULT.read_text()
            longer = text.replace("<LeaseDuration>1s</LeaseDuration>", f"<LeaseDuration>{LARGE_SWARM_LEASE}"
                                                                       "</LeaseDuration>")
            if longer == text:
                raise RunError(f"{DEFAULT}: no <LeaseDuration>1s</LeaseDuration> to lengthen for a large run", 2)
            path = Path(run_dir) / "cyclonedds.xml"
            path.write_text(longer)
            changes["CYCLONEDDS_URI"] = f"file://{path}"
            return changes, (f"{participants} DDS processes: participant leases of {LARGE_SWARM_LEASE} "
                             f"({path.name} in the run directory)")
        uri = f"file://{UNICAST}"
        changes["CYCLONEDDS_URI"] = uri
        note = f"multicast on lo does not work here: unicast discovery ({UNICAST.name})"
    limit, why = participant_limit(uri)
    if limit is not None and participants > limit:
        raise RunError(f"{participants} DDS processes (agents, feeder, injector) cannot share one domain: the Cyclone "
                       f"config {uri} holds at most {limit} ({why}); raise it, or use multicast discovery "
                       f"(config/cyclonedds-loopback.xml)", 2)
    return changes, note


LOSSY_LINK_INTERNAL = '<HeartbeatInterval min="2ms">5ms</HeartbeatInterval><NackDelay>0ms</NackDelay>'


def for_interface(interface, participants, path):
    """The default config with INTERFACE (a real network interface) in place of lo, multicast that
    crosses one link (time-to-live 1), quick repair of lost samples, and, for a large run, the
    longer participant leases; written to PATH, whose path it returns."""
    text = DEFAULT.read_text()
    changed = text.replace('<NetworkInterface name="lo" multicast="true"/>',
                           f'<NetworkInterface name="{interface}" multicast="true"/>')
    changed = changed.replace("<MulticastTimeToLive>0</MulticastTimeToLive>",
                              "<MulticastTimeToLive>1</MulticastTimeToLive>")
    # A real link loses datagrams: a reader asks for a lost sample again at once, and a writer
    # with unacknowledged data sends heartbeats every 5 ms (Cyclone: 100 ms), so that a loss
    # costs lockstep a few milliseconds instead of a tenth of a second.
    changed = changed.replace("<Internal>", "<Internal>\n      " + LOSSY_LINK_INTERNAL)
    if participants > LARGE_SWARM:
        changed = changed.replace("<LeaseDuration>1s</LeaseDuration>",
                                  f"<LeaseDuration>{LARGE_SWARM_LEASE}</LeaseDuration>")
    if changed.count(interface) != 1 or "<MulticastTimeToLive>1<" not in changed:
        raise RunError(f"{DEFAULT}: no loopback interface or time-to-live to replace for {interface}", 2)
    Path(path).write_text(changed)
    return Path(path)
