"""The fair limit through a real run (issue F1): the reference's centralized optimum knows no
robot's start but one gauge per group of robots whose data tie their frames; two groups of
robots far apart are two components, each solved and scored on its own, none merged into the
other, and every agent's gap is against the component its map holds.

Run: cd tests/integration && /usr/bin/python3 -m unittest fair_limit_test
"""

import json
import math
import unittest

from swarm_test import SwarmCase

# Two pairs of robots 80 m apart in one strip of trees: each pair's circles overlap, the pairs
# share no tree, never see each other and are out of radio range.
TWO_GROUPS = """version: 1
name: two_groups
seed: 4
duration_s: 60
world:
  landmarks:
    generator: {type: uniform, count: 220, area_m: [0, 0, 120, 20], min_spacing_m: 1.5}
robots:
  defaults:
    preset: thesis
    sensor: {signatures: true}
  list:
    - id: 1
      path: {type: circle, center_m: [10, 10], radius_m: 6, start_angle_deg: 0}
    - id: 2
      path: {type: circle, center_m: [20, 10], radius_m: 6, start_angle_deg: 180}
    - id: 3
      path: {type: circle, center_m: [100, 10], radius_m: 6, start_angle_deg: 0}
    - id: 4
      path: {type: circle, center_m: [110, 10], radius_m: 6, start_angle_deg: 180}
radio:
  range_m: 25
"""


def fitted_errors(points, truth):
    """The residuals of the least-squares rigid fit of points onto truth (2-D, closed form)."""
    n = len(points)
    pc = [sum(p[i] for p in points) / n for i in (0, 1)]
    tc = [sum(t[i] for t in truth) / n for i in (0, 1)]
    dot = sum((p[0] - pc[0]) * (t[0] - tc[0]) + (p[1] - pc[1]) * (t[1] - tc[1]) for p, t in zip(points, truth))
    cross = sum((p[0] - pc[0]) * (t[1] - tc[1]) - (p[1] - pc[1]) * (t[0] - tc[0]) for p, t in zip(points, truth))
    a = math.atan2(cross, dot)
    c, s = math.cos(a), math.sin(a)
    out = []
    for p, t in zip(points, truth):
        x, y = p[0] - pc[0], p[1] - pc[1]
        out.append((c * x - s * y + tc[0] - t[0], s * x + c * y + tc[1] - t[1]))
    return out


def rmse(errors):
    return math.sqrt(sum(e[0] ** 2 + e[1] ** 2 for e in errors) / len(errors))


class FairLimitTest(SwarmCase):
    def test_two_groups_far_apart_are_solved_and_scored_apart(self):
        scenario = self.out.parent / "two_groups.yaml"
        scenario.write_text(TWO_GROUPS)
        r = self.swarm(scenario, "--no-report")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("share too little with the rest: apart", r.stdout)
        s = self.summary()
        ref = s["reference"]
        central = ref["central"]
        self.assertEqual(sorted(sorted(c["robots"]) for c in central["components"]), [[1, 2], [3, 4]])
        self.assertTrue(all(c["in_world"] for c in central["components"]))  # each gauge at its true start
        self.assertEqual(sorted(central["unconnected"]), sorted(central["components"][1]["robots"]))
        self.assertEqual(central["observations_left_out"], 0)
        self.assertTrue(central["converged"])
        # Every landmark in the component of the robots that saw it (x < 60: the first pair's).
        full = json.loads((self.out / "reference.json").read_text())["central"]
        of = {int(k): v for k, v in full["landmark_component"].items()}
        first = next(k for k, c in enumerate(central["components"]) if 1 in c["robots"])
        truth = {lm["id"]: (lm["x"], lm["y"]) for lm in json.loads((self.out / "truth.json").read_text())["landmarks"]}
        landmarks = full["map"]["landmarks"]
        self.assertEqual(len(of), len(landmarks))
        for lm in landmarks:
            self.assertEqual(of[lm["signature"]] == first, truth[lm["signature"]][0] < 60, lm["signature"])
        # Scored on its own: each component fitted apart, the errors pooled.
        errors = []
        for k in range(len(central["components"])):
            part = [lm for lm in landmarks if of[lm["signature"]] == k]
            errors += fitted_errors([(lm["x"], lm["y"]) for lm in part], [truth[lm["signature"]] for lm in part])
        self.assertAlmostEqual(central["rmse_aligned_m"], rmse(errors), places=9)
        # The known-starts optimum ties the groups through the true starts: one component.
        self.assertEqual(len(ref["central_known_starts"]["components"]), 1)
        # Every agent merged only its own group, and is scored against it: a gap near 1, finite.
        for a in s["agents"]:
            self.assertIsNotNone(a["gap_to_central"], a["id"])
            self.assertLess(a["gap_to_central"], 3.0, a["id"])
            self.assertGreater(a["gap_to_central"], 0.5, a["id"])
            self.assertTrue(set(a["peers_aligned"]) <= ({1, 2} if a["id"] in (1, 2) else {3, 4}), a)


if __name__ == "__main__":
    unittest.main()
