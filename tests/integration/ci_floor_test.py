"""scripts/ci-floor on a real run of the circle pair (cekf_submaps) and on a copy of it whose
maps and submaps are planted exact: exact estimates at their true placements must score 0, the
real ones a finite gap; bad input is one line.

Run: cd tests/integration && /usr/bin/python3 -m unittest ci_floor_test
"""

import base64
import json
import math
import re
import shutil
import struct
import subprocess
import sys
import unittest
from pathlib import Path

from swarm_test import SwarmCase

REPO = Path(__file__).resolve().parents[2]
SCRIPT = [sys.executable, str(REPO / "scripts" / "ci-floor")]
SCENARIOS = REPO / "scenarios"
LINE = re.compile(r"submaps at their true frames ([0-9.]+) \((\d+) landmarks\), "
                  r"maps at their own fits ([0-9.]+) \((\d+)\)")


def plant_exact(run):
    """Every local map's landmarks at their true positions, every own submap's at their true
    positions in the robot's true frame when it opened (the trajectory is sampled on the
    submaps' 0.5 s grid)."""
    truth_json = json.loads((run / "truth.json").read_text())
    truth = {lm["id"]: (lm["x"], lm["y"]) for lm in truth_json["landmarks"]}
    for agent in sorted(run.glob("agent_*")):
        robot = int(agent.name.split("_")[1])
        trajectory = {round(p[0], 6): p[1:] for r in truth_json["robots"] if r["id"] == robot for p in r["trajectory"]}
        local = json.loads((agent / "local_map.json").read_text())
        signature = {lm["id"]: lm["signature"] for lm in local["landmarks"]}
        for lm in local["landmarks"]:
            lm["x"], lm["y"] = truth[lm["signature"]]
        (agent / "local_map.json").write_text(json.dumps(local))
        checkpoint = json.loads((agent / "checkpoint.json").read_text())
        planted = []
        for payload in checkpoint["submaps"]:
            b = bytearray(base64.b64decode(payload))
            owner, = struct.unpack_from("<I", b, 4)
            opened, = struct.unpack_from("<d", b, 16)
            n, = struct.unpack_from("<I", b, 32)
            if owner == robot:
                x, y, theta = trajectory[round(opened, 6)]
                c, s = math.cos(theta), math.sin(theta)
                keys = struct.unpack_from(f"<{n}I", b, 36)
                for i, key in enumerate(keys):
                    tx, ty = truth[signature[key]]
                    dx, dy = tx - x, ty - y
                    struct.pack_into("<dd", b, 36 + 4 * n + 8 * (3 + 2 * i), c * dx + s * dy, -s * dx + c * dy)
            planted.append(base64.b64encode(bytes(b)).decode())
        checkpoint["submaps"] = planted
        (agent / "checkpoint.json").write_text(json.dumps(checkpoint))


class CiFloorTest(SwarmCase):
    def floor(self, *args):
        return subprocess.run(SCRIPT + [str(a) for a in args], capture_output=True, text=True, timeout=120)

    def test_exact_estimates_score_zero_and_real_ones_a_gap(self):
        r = self.swarm(SCENARIOS / "thesis_circle_pair.yaml", "--set", "agent.slam=cekf_submaps", "--no-report")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        real = self.floor(self.out)
        self.assertEqual(real.returncode, 0, real.stderr)
        m = LINE.search(real.stdout)
        self.assertIsNotNone(m, real.stdout)
        self.assertGreater(float(m.group(1)), 0.0)
        self.assertGreater(float(m.group(3)), 0.0)
        self.assertGreaterEqual(int(m.group(2)), 50)  # the pair's closed submaps hold most of the circle
        self.assertGreaterEqual(int(m.group(4)), int(m.group(2)))
        exact = self.out.parent / "exact"
        shutil.copytree(self.out, exact)
        plant_exact(exact)
        planted = self.floor(exact)
        self.assertEqual(planted.returncode, 0, planted.stderr)
        m = LINE.search(planted.stdout)
        self.assertIsNotNone(m, planted.stdout)
        self.assertEqual(m.group(1), "0.00", planted.stdout)
        self.assertEqual(m.group(3), "0.00", planted.stdout)
        # A folder of runs: one line each, then the median, 90th percentile and worst.
        both = self.floor(self.out.parent)
        self.assertEqual(both.returncode, 0, both.stderr)
        self.assertEqual(len(LINE.findall(both.stdout)), 2, both.stdout)
        self.assertRegex(both.stdout, r"submaps median [0-9.]+ / p90 [0-9.]+ / worst [0-9.]+")
        self.assertRegex(both.stdout, r"maps median [0-9.]+ / p90 [0-9.]+ / worst [0-9.]+")

    def test_help_and_bad_input_are_one_line(self):
        h = self.floor("--help")
        self.assertEqual(h.returncode, 0)
        self.assertIn("at its true frame", h.stdout)
        for bad in (self.out.parent / "none", REPO / "scenarios"):
            r = self.floor(bad)
            self.assertEqual(r.returncode, 1, r.stdout)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertTrue(r.stderr.startswith("ci-floor: "), r.stderr)


if __name__ == "__main__":
    unittest.main()
