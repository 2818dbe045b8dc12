"""Real hosts (E1), through real processes: `swarm run --hosts netns` puts each agent and the
feeder in a network namespace of its own on one bridge, loses datagrams in the kernel
(nftables), matches the loopback run, and leaves no namespace, link or process behind, also
when the launcher itself is killed."""

import os
import shutil
import signal
import subprocess
import sys
import time
import unittest

from swarm_test import REPO, SWARM, SwarmCase

sys.path.insert(0, str(REPO / "scripts"))
from mapmesh import netns  # noqa: E402
from mapmesh.run_error import RunError  # noqa: E402

PARK4 = REPO / "scenarios" / "park4.yaml"
WHY_NOT = netns.probe()


class NetnsArgumentsTest(SwarmCase):
    """What needs no root: the refusals and the pure parts."""

    def test_without_root_or_tools_it_is_one_line(self):
        with self.assertRaisesRegex(RunError, r"^--hosts netns: needs root .*use --hosts loopback$"):
            netns.require(5, None, euid=1000)
        with self.assertRaisesRegex(RunError, r"^--hosts netns: nft \(Debian package nftables\) not found"):
            netns.require(5, None, euid=0, tool=lambda name: None if name == "nft" else "/usr/sbin/" + name)
        netns.require(0, None, euid=0, tool=lambda name: None if name == "nft" else "/usr/sbin/" + name)
        r = self.swarm(PARK4, "--net-loss", "5")
        self.assertEqual(r.returncode, 2)
        self.assertEqual(r.stderr.strip(), "swarm: --net-loss and --net-rate act on the hosts' links: they need "
                                           "--hosts netns")
        for bad in [["--net-loss", "100"], ["--net-loss", "x"], ["--net-rate", "0"]]:
            r = self.swarm(PARK4, "--hosts", "netns", *bad)
            self.assertEqual(r.returncode, 2, bad)
            self.assertIn(f"argument {bad[0]}: '{bad[1]}': expected", r.stderr)
        setpriv = shutil.which("setpriv")
        if os.geteuid() == 0 and setpriv:  # the launcher itself, as an unprivileged user
            r = subprocess.run([setpriv, "--reuid=65534", "--regid=65534", "--clear-groups"] + SWARM +
                               ["run", str(PARK4), "--hosts", "netns", "--out", "/nonexistent/run"],
                               capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 2, r.stderr)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn("--hosts netns: needs root", r.stderr)

    def test_addresses_and_loss_rules(self):
        self.assertEqual([netns.address(k) for k in (1, 2, 255, 256, 300)],
                         ["10.77.0.1", "10.77.0.2", "10.77.0.255", "10.77.1.0", "10.77.1.44"])
        self.assertIn("numgen random mod 10000 < 500 counter drop", netns.nft_rules(5))
        self.assertIn("numgen random mod 10000 < 25 counter drop", netns.nft_rules(0.25))
        listing = ('{"nftables": [{"metainfo": {}}, {"rule": {"comment": "received", "expr": [{"match": {}}, '
                   '{"counter": {"packets": 200, "bytes": 1}}]}}, {"rule": {"comment": "dropped", "expr": '
                   '[{"counter": {"packets": 9, "bytes": 1}}, {"drop": null}]}}]}')
        self.assertEqual(netns.nft_counts(listing), {"received": 200, "dropped": 9})


@unittest.skipIf(WHY_NOT, f"--hosts netns cannot run here: {WHY_NOT}")
class NetnsTest(SwarmCase):
    def run_ok(self, name, *args):
        self.out = self.out.parent / name
        r = self.swarm(PARK4, "--agents", "8", *args, "--no-report", timeout=280)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        return r, self.summary()

    def assert_nothing_left(self, tag, marker):
        left = netns.leftovers(tag, marker)
        self.assertEqual(left, {"namespaces": [], "links": [], "processes": []})

    def test_eight_agents_with_five_percent_kernel_loss_match_loopback_and_leave_nothing(self):
        _, loop = self.run_ok("loopback")
        r, ns = self.run_ok("netns", "--hosts", "netns", "--net-loss", "5")
        net = ns["network"]
        self.assertEqual(net["hosts"], "netns")
        self.assertEqual(sorted(net["per_host"]), sorted([f"agent{k}" for k in range(1, 9)] + ["feeder"]))
        # The loss happened in the kernels: each host dropped about 5 % of what it received
        # (tens of thousands of datagrams: the binomial spread is under 0.2 points).
        self.assertGreater(net["udp_received"], 10000)
        self.assertTrue(3.5 <= net["udp_dropped_percent"] <= 6.5, net)
        for host, c in net["per_host"].items():
            self.assertGreater(c["udp_dropped"], 0, host)
        self.assertIn(f"their kernels dropped {net['udp_dropped']} of {net['udp_received']}", r.stdout)
        config = (self.out / "cyclonedds-netns.xml").read_text()
        self.assertIn('<NetworkInterface name="eth0"', config)
        self.assertNotIn('name="lo"', config)
        before = {a["id"]: a for a in loop["agents"]}
        for a in ns["agents"]:
            with self.subTest(agent=a["id"]):
                self.assertEqual(a["exit_code"], 0)
                self.assertFalse(a["failed"])
                log = (self.out / f"agent_{a['id']}" / "agent.log").read_text()
                self.assertIn(f"config {self.out / 'cyclonedds-netns.xml'}", log)
                # Reliable sensor streams were repaired: every message sent was processed.
                self.assertEqual(a["odom_processed"], a["odom_sent"])
                self.assertEqual(a["scans_processed"], a["scans_sent"])
                # Maps crossed the bridge (no loopback between namespaces).
                self.assertGreater(a["maps_received"], 0)
                self.assertEqual(a["global"]["landmarks"], before[a["id"]]["global"]["landmarks"])
        # Kernel loss changes nothing: every map is the loopback run's, byte for byte.
        self.assert_same_maps(self.out, self.out.parent / "loopback")
        self.assert_nothing_left(net["tag"], str(self.out))

    def test_a_killed_launcher_leaves_no_namespace_link_or_process(self):
        self.out = self.out.parent / "killed"
        launcher = subprocess.Popen(SWARM + ["run", str(PARK4), "--out", str(self.out), "--hosts", "netns",
                                             "--net-loss", "5", "--quiet", "--no-report"],
                                    stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        tag = f"mm{launcher.pid}r1"
        try:
            deadline = time.monotonic() + 60
            while True:  # until the agents run in their namespaces (4 agents, the feeder, the hub)
                up = [p for p in self.out.glob("agent_*/agent.log") if " up: " in p.read_text()]
                if len(up) == 4 and len(netns.leftovers(tag)["namespaces"]) == 6:
                    break
                self.assertIsNone(launcher.poll(), launcher.stderr.read() if launcher.poll() is not None else "")
                self.assertLess(time.monotonic(), deadline, "the run did not come up within 60 s")
                time.sleep(0.1)
            self.assertEqual(len(netns.leftovers(tag)["links"]), 10)  # both ends of 5 veth pairs
            self.assertGreaterEqual(len(netns.leftovers(tag, str(self.out))["processes"]), 5)
        finally:
            launcher.send_signal(signal.SIGKILL)
            launcher.wait(10)
            launcher.stderr.close()
        deadline = time.monotonic() + 15
        while (left := netns.leftovers(tag, str(self.out))) != {"namespaces": [], "links": [], "processes": []} \
                and time.monotonic() < deadline:
            time.sleep(0.2)
        self.assertEqual(left, {"namespaces": [], "links": [], "processes": []})


if __name__ == "__main__":
    unittest.main()
