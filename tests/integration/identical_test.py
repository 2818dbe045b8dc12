"""Identical runs (D1), through real processes: two lockstep runs of one scenario, seed and fault
schedule are the same run (scripts/swarm compare finds no difference), and the in-process bus
(mapmesh-lab bus) gives the DDS swarm's maps, map for map."""

import json
import os
import subprocess
import unittest

from swarm_test import REPO, SWARM, SwarmCase

PARK4 = REPO / "scenarios" / "park4.yaml"
CIRCLE = REPO / "scenarios" / "thesis_circle_pair.yaml"
LINE3 = REPO / "scenarios" / "line3.yaml"
SUBMAPS = ["--set", "agent.slam=cekf_submaps"]
LAB = [os.path.join(os.environ.get("MAPMESH_BIN", str(REPO / "build" / "bin")), "mapmesh-lab")]
FAULTS = ["--kill", "2@60", "--kill", "5@90", "--restart", "2@100", "--pause", "3@120:2"]


def compare(a, b):
    return subprocess.run(SWARM + ["compare", str(a), str(b)], capture_output=True, text=True, timeout=60)


class IdenticalRunsTest(SwarmCase):
    def run_to(self, name, *args, reference=False):
        self.out = self.out.parent / name
        r = self.swarm(*args, "--no-report", *([] if reference else ["--no-reference"]), "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        return self.out

    def test_two_lockstep_runs_with_kills_a_restart_and_a_pause_are_the_same_run(self):
        first = self.run_to("first", PARK4, "--agents", "8", *FAULTS)
        second = self.run_to("second", PARK4, "--agents", "8", *FAULTS)
        r = compare(first, second)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertRegex(r.stdout, r"\d+ files compared, 0 differ")
        # What was compared holds the run: every agent's maps, the dead one's peers left behind.
        for rid in range(1, 9):
            self.assertTrue((first / f"agent_{rid}" / "global_map.json").is_file())
        self.assertTrue(any((first / "agent_5" / "snapshots").iterdir()))
        # ... and the comparison can fail: another seed is another run.
        other = self.run_to("other", PARK4, "--agents", "8", *FAULTS, "--set", "seed=2")
        r = compare(first, other)
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        self.assertIn("agent_1/local_map.json: differs", r.stdout)

    def assert_same_run(self, *args):
        """Two lockstep runs with these arguments are the same run."""
        first = self.run_to("first", *args)
        second = self.run_to("second", *args)
        r = compare(first, second)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertRegex(r.stdout, r"\d+ files compared, 0 differ")

    def test_two_lockstep_runs_relaying_submaps_are_the_same_run(self):
        # Submaps relayed by identity (cekf_submaps) keep runs identical: the same submaps go
        # out at the same ticks (stats.json's per-chain digests are compared too).
        self.assert_same_run(LINE3, *SUBMAPS)

    def test_two_lockstep_runs_joining_submap_chains_are_the_same_run(self):
        # The joining back-end (each solve started from the last) keeps runs identical too.
        self.assert_same_run(LINE3, *SUBMAPS, "--set", "agent.fusion=joining")

    def test_two_runs_with_the_reference_are_the_same_run(self):
        # The reference (on by default, as in the demo) is part of the run: reference.json and
        # summary.json's reference block are compared, its wall time (total_s) left out.
        first = self.run_to("first", CIRCLE, reference=True)
        second = self.run_to("second", CIRCLE, reference=True)
        reference = json.loads((first / "reference.json").read_text())
        self.assertIn("total_s", reference)
        self.assertIn("central", reference)
        r = compare(first, second)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertRegex(r.stdout, r"\d+ files compared, 0 differ")


class BusMatchesSwarmTest(SwarmCase):
    def check(self, scenario, *args):
        r = self.swarm(scenario, *args, "--no-report", "--no-reference", "--quiet")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        bus = self.out.parent / "bus"
        b = subprocess.run(LAB + ["bus", "--scenario", str(scenario), *args, "--out", str(bus)],
                           capture_output=True, text=True, timeout=120)
        self.assertEqual(b.returncode, 0, b.stdout + b.stderr)
        self.assertGreaterEqual(len(list(self.out.glob("agent_*"))), 2)
        self.assert_same_maps(bus, self.out)

    def test_park4_four_agents(self):
        self.check(PARK4)

    def test_park4_eight_agents(self):
        self.check(PARK4, "--agents", "8")

    def test_circle_pair(self):
        self.check(CIRCLE)

    def test_line3_relaying_submaps(self):
        self.check(LINE3, *SUBMAPS)


if __name__ == "__main__":
    unittest.main()
