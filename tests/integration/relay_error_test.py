"""scripts/relay-error on a synthetic line of three whose errors are planted: robot 1's map frame
is turned by 0.5 degrees (a frame error), and the relay chain put robot 3's landmarks 5 cm off
in robot 1's map. The figures must separate the two: the chain's error alone, the frame error
alone, and both; and the primary one, after a rigid fit of the whole global map to the truth,
must leave the frame error out and share the chain's error between the relayed landmarks and
the holder's own.

Run: cd tests/integration && /usr/bin/python3 -m unittest relay_error_test
"""

import json
import math
import subprocess
import tempfile
import unittest
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "scripts" / "relay-error"
TURN = math.radians(0.5)
SHIFT = (0.05, 0.0)


def turn(p, a=TURN):
    c, s = math.cos(a), math.sin(a)
    return (c * p[0] - s * p[1], s * p[0] + c * p[1])


def lm(i, p, signature=None):
    return {"id": i, "signature": i if signature is None else signature, "x": p[0], "y": p[1],
            "cov": [0.01, 0.0, 0.01]}


def fit_rmse(pairs, scored):
    """RMSE over the pairs with index in scored after the least-squares rigid fit of all
    (estimate, truth) pairs: the closed form in 2-D (rotation from the summed cross and dot
    products of the centred points)."""
    n = len(pairs)
    ce = [sum(e[i] for e, _ in pairs) / n for i in (0, 1)]
    ct = [sum(t[i] for _, t in pairs) / n for i in (0, 1)]
    cross = dot = 0.0
    for e, t in pairs:
        ex, ey, tx, ty = e[0] - ce[0], e[1] - ce[1], t[0] - ct[0], t[1] - ct[1]
        dot += ex * tx + ey * ty
        cross += ex * ty - ey * tx
    a = math.atan2(cross, dot)
    sq = []
    for k in scored:
        e, t = pairs[k]
        p = turn((e[0] - ce[0], e[1] - ce[1]), a)
        sq.append((p[0] + ct[0] - t[0]) ** 2 + (p[1] + ct[1] - t[1]) ** 2)
    return math.sqrt(sum(sq) / len(sq))


def make_run(d):
    # Robots' true frames: robot 1 at the origin, robot 2 at (20, 0), robot 3 at (40, 0), all
    # heading along x. Landmarks: 0-9 robot 1's, 10-19 robot 2's, 20-29 robot 3's only.
    starts = {1: 0.0, 2: 20.0, 3: 40.0}
    world = {i: (starts[1 + i // 10] + (i % 5) * 2.0 - 4.0, 3.0 * (i % 10 // 5) - 1.5 + 0.1 * i) for i in range(30)}
    truth = {"landmarks": [{"id": i, "x": p[0], "y": p[1]} for i, p in world.items()],
             "robots": [{"id": r, "trajectory": [[0.0, x, 0.0, 0.0], [100.0, x, 0.0, 0.0]]} for r, x in starts.items()]}
    (d / "truth.json").write_text(json.dumps(truth))

    def in_frame(i, r):
        return (world[i][0] - starts[r], world[i][1])

    for r in starts:
        a = d / f"agent_{r}"
        a.mkdir()
        (a / "stats.json").write_text(json.dumps({"frame_origin_stamp": 0.0}))
        mine = range(10 * (r - 1), 10 * r)
        # Robot 1's map is turned by its frame error; the others are exact.
        est = (lambda p: turn(p)) if r == 1 else (lambda p: p)
        (a / "local_map.json").write_text(json.dumps({"landmarks": [lm(i, est(in_frame(i, r))) for i in mine]}))
    # Robot 1's global map: its own landmarks and robot 3's, carried into its (turned) frame
    # with the chain's error SHIFT; robot 2's are left out (not needed). As in an agent's
    # global map, only its own landmarks keep their signatures; one more landmark is nowhere
    # near a true one.
    glob = [lm(i, turn(in_frame(i, 1))) for i in range(10)]
    for i in range(20, 30):
        p = turn(in_frame(i, 1))
        glob.append(lm(i, (p[0] + SHIFT[0], p[1] + SHIFT[1]), signature=-1))
    glob.append(lm(99, (70.0, 30.0), signature=-1))
    (d / "agent_1" / "global_map.json").write_text(json.dumps({"landmarks": glob}))

    def rms(v):
        return math.sqrt(sum(x * x + y * y for x, y in v) / len(v))

    frame_only = [(turn(in_frame(i, 1))[0] - in_frame(i, 1)[0], turn(in_frame(i, 1))[1] - in_frame(i, 1)[1])
                  for i in range(20, 30)]
    both = [(x + SHIFT[0], y + SHIFT[1]) for x, y in frame_only]
    # The whole-map fit: robot 1's 20 matched global landmarks against their truth in its frame;
    # the relayed ones (the last 10) scored.
    pairs = [((g["x"], g["y"]), in_frame(g["id"], 1)) for g in glob[:20]]
    return rms(frame_only), rms(both), fit_rmse(pairs, range(10, 20))


class RelayErrorTest(unittest.TestCase):
    def test_separates_the_chains_error_from_the_holders_frame_error(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_relay_") as tmp:
            d = Path(tmp)
            frame_only, both, whole = make_run(d)
            r = subprocess.run(["/usr/bin/python3", str(SCRIPT), str(d), "1", "3"], capture_output=True, text=True,
                               timeout=60)
            self.assertEqual(r.returncode, 0, r.stderr)
            out = json.loads(r.stdout)
            self.assertEqual(out["source_only_landmarks"], 10)
            self.assertEqual(out["held"], 10)
            # The primary figure comes first, after the ids and counts.
            self.assertEqual(list(out)[:6], ["holder", "source", "source_only_landmarks", "whole_map_fit_m",
                                             "whole_map_fit_held", "whole_map_fit_matched"])
            self.assertEqual(out["whole_map_fit_held"], 10)
            self.assertEqual(out["whole_map_fit_matched"], 20)  # not the landmark far from any true one
            self.assertAlmostEqual(out["whole_map_fit_m"], whole, places=6)
            # The frame's turn is fitted away, and the chain's 5 cm is shared with the holder's own
            # landmarks: about half of it is left on the relayed ones.
            self.assertAlmostEqual(whole, math.hypot(*SHIFT) / 2, delta=0.002)
            self.assertAlmostEqual(out["own_placed_m"], math.hypot(*SHIFT), places=6)
            self.assertAlmostEqual(out["oracle_m"], frame_only, places=6)
            self.assertAlmostEqual(out["true_frame_m"], both, places=6)
            self.assertAlmostEqual(out["holder_frame_rotation_deg"], -0.5, places=6)
            self.assertAlmostEqual(out["source_local_rmse_m"], 0.0, places=9)
            self.assertGreater(frame_only, 0.3)  # 0.5 degrees at about 40 m: the frame error dominates

    def test_help_and_bad_arguments_are_one_line(self):
        h = subprocess.run(["/usr/bin/python3", str(SCRIPT), "--help"], capture_output=True, text=True, timeout=60)
        self.assertEqual(h.returncode, 0)
        self.assertIn("Usage", h.stdout)
        with tempfile.TemporaryDirectory(prefix="mapmesh_relay_") as tmp:
            make_run(Path(tmp))
            for args in ([], ["/nonexistent", "1", "3"], [tmp, "1", "x"], [tmp, "1", "9"]):
                r = subprocess.run(["/usr/bin/python3", str(SCRIPT)] + args, capture_output=True, text=True, timeout=60)
                self.assertNotEqual(r.returncode, 0, args)
                self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)


if __name__ == "__main__":
    unittest.main()
