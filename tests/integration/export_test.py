"""X1: `swarm export` (scripts/mapmesh/export.py): a run's trajectories as TUM files for evo,
checked against the run's own figures, and the run as an MCAP file, read back with the MCAP
project's own reader (npm @mcap/core, tests/js/mcap_read.mjs) and every message checked against
Foxglove's own JSON schemas; never with the project's writer alone."""

import json
import math
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

import numpy as np

from swarm_test import REPO, SWARM

sys.path.insert(0, str(REPO / "scripts"))
from mapmesh import mcap, mcap_export, tum  # noqa: E402

SCENARIOS = REPO / "scenarios"
MCAP_READ = REPO / "tests" / "js" / "mcap_read.mjs"


def rigid_fit_rmse(est, ref):
    """RMSE of est (N x 2) after the least-squares rigid fit onto ref (Umeyama, no scale)."""
    est, ref = np.asarray(est), np.asarray(ref)
    me, mr = est.mean(axis=0), ref.mean(axis=0)
    u, _, vt = np.linalg.svd((est - me).T @ (ref - mr))
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, d]) @ u.T
    moved = (rot @ (est - me).T).T + mr
    return float(np.sqrt(np.mean(np.sum((moved - ref) ** 2, axis=1))))


def read_mcap(testcase, path):
    r = subprocess.run(["node", str(MCAP_READ), str(path)], capture_output=True, text=True, timeout=120)
    return r, (json.loads(r.stdout) if r.returncode == 0 else None)


class ExportTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory(prefix="mapmesh_export_")
        cls.rundir = Path(cls.tmp.name) / "run"
        r = subprocess.run(SWARM + ["run", str(SCENARIOS / "park4.yaml"), "--out", str(cls.rundir), "--set",
                                    "duration_s=60", "--kill", "2@20", "--restart", "2@35", "--quiet", "--no-report"],
                           capture_output=True, text=True, timeout=240)
        assert r.returncode == 0, r.stdout + r.stderr
        cls.summary = json.loads((cls.rundir / "summary.json").read_text())
        cls.truth = json.loads((cls.rundir / "truth.json").read_text())

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_tum_files_pass_the_format_check_and_give_the_runs_own_trajectory_errors(self):
        r = subprocess.run(SWARM + ["export", str(self.rundir), "--tum"], capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        d = self.rundir / "export" / "tum"
        self.assertIn(f"tum:  {d}  (8 files", r.stdout)
        self.assertFalse((self.rundir / "export" / "run.mcap").exists())
        truth = {rb["id"]: rb for rb in self.truth["robots"]}
        for a in self.summary["agents"]:
            rid = a["id"]
            with self.subTest(agent=rid):
                est = tum.read(d / f"agent_{rid}.tum")  # 8 numbers a line, stamps increasing, unit quaternions
                ref = tum.read(d / f"agent_{rid}_truth.tum")
                self.assertEqual(len(ref), len(truth[rid]["trajectory"]))
                traj = json.loads((self.rundir / f"agent_{rid}" / "trajectory.json").read_text())["poses"]
                self.assertEqual(len(est), len(traj))
                for row, pose in zip(est, traj):
                    self.assertAlmostEqual(row[0], pose[0], places=6)
                    self.assertAlmostEqual(math.atan2(row[6], row[7]) * 2 % (2 * math.pi),
                                           pose[3] % (2 * math.pi), places=6)
                # Both in the agent's map frame (a simulated world): at the stamps both have, the
                # error without a fit is the run's true-frame figure, after a rigid fit its ATE.
                self.assertEqual(a["local"]["trajectory_frame"], "true_origin")
                at = {round(row[0], 6): row for row in ref}
                pairs = [(row, at[round(row[0], 6)]) for row in est if round(row[0], 6) in at]
                self.assertGreater(len(pairs), 0.9 * len(est))
                e = np.array([[p[1], p[2]] for p, _ in pairs])
                t = np.array([[q[1], q[2]] for _, q in pairs])
                self.assertAlmostEqual(float(np.sqrt(np.mean(np.sum((e - t) ** 2, axis=1)))),
                                       a["local"]["trajectory_rmse_m"], delta=1e-6)
                self.assertAlmostEqual(rigid_fit_rmse(e, t), a["local"]["trajectory_ate_aligned_m"], delta=1e-6)
                self.assertLess(a["local"]["trajectory_ate_aligned_m"], a["local"]["trajectory_rmse_m"] + 1e-9)
                rpe = a["local"]["trajectory_rpe"]
                self.assertEqual(rpe["delta_s"], 1.0)
                self.assertGreater(rpe["pairs"], 50)
                self.assertGreater(rpe["translation_rmse_m"], 0.0)
                self.assertLess(rpe["translation_rmse_m"], 0.1)

    def test_a_bad_tum_line_is_named(self):
        with tempfile.TemporaryDirectory() as tmp:
            for text, why in (("1 2 3 4 5 6 7\n", "7 fields"), ("1 0 0 0 0 0 0 1\n1 0 0 0 0 0 0 1\n", "not after"),
                              ("1 0 0 0 0 0 0.5 0.5\n", "unit length")):
                path = Path(tmp) / "x.tum"
                path.write_text("# c\n" + text)
                with self.assertRaisesRegex(ValueError, why):
                    tum.read(path)

    def test_mcap_is_read_back_by_the_mcap_reader_with_the_expected_messages(self):
        out = Path(self.tmp.name) / "exported"
        r = subprocess.run(SWARM + ["export", str(self.rundir), "--mcap", "--out", str(out)], capture_output=True,
                           text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        path = out / "run.mcap"
        r, got = read_mcap(self, path)
        self.assertEqual(r.returncode, 0, r.stderr)
        # What the run's files say there must be, counted here from them.
        expected = {"/tf": 1, "/truth/landmarks": 1}
        for rb in self.truth["robots"]:
            expected[f"/truth/agent_{rb['id']}/pose"] = len(rb["trajectory"])
        for a in self.summary["agents"]:
            rid = a["id"]
            traj = json.loads((self.rundir / f"agent_{rid}" / "trajectory.json").read_text())["poses"]
            expected[f"/agent_{rid}/pose"] = len(traj)
            snaps = {json.loads(line).get("snapshot") for line in
                     (self.rundir / f"agent_{rid}" / "history.jsonl").read_text().splitlines()}
            for kind in ("local", "global"):
                n = sum(1 for s in snaps if s and (self.rundir / f"agent_{rid}" / f"{s}_{kind}.json").exists())
                self.assertGreater(n, 3)
                expected[f"/agent_{rid}/{kind}_map"] = n
        expected["/radio/links"] = int(60 / 0.5) + 1
        expected["/events"] = 2  # the kill and the restart
        aligned = {p for a in self.summary["agents"] for p in a["peers_aligned"]}
        self.assertTrue(aligned)  # the agents did align
        self.assertGreaterEqual(got["topics"].pop("/alignments"), len(aligned))
        self.assertEqual(got["topics"], expected)
        self.assertEqual({k: v for k, v in got["stream_topics"].items() if k != "/alignments"}, expected)
        counts = dict(got["statistics"]["channel_message_counts"])
        counts.pop("/alignments")
        self.assertEqual(counts, expected)
        self.assertEqual((got["not_json"], got["out_of_order"], got["invalid"]), (0, 0, {}), got["errors"])
        schemas = got["schemas"]
        self.assertEqual(schemas["/agent_1/local_map"], "foxglove.SceneUpdate")
        self.assertEqual(schemas["/agent_1/pose"], "foxglove.PoseInFrame")
        self.assertEqual(schemas["/tf"], "foxglove.FrameTransforms")
        self.assertEqual(schemas["/events"], "foxglove.Log")
        self.assertTrue(all(e == "json" for e in got["encodings"].values()))
        self.assertEqual(got["samples"]["/events"]["message"], "agent 2 killed")
        # Agent 1's first local map: an ellipse per landmark, as many as it says it holds.
        ent = got["samples"]["/agent_1/local_map"]["entities"][0]
        self.assertEqual(ent["frame_id"], "agent_1")
        self.assertEqual(int(ent["metadata"][0]["value"]), len(ent["cylinders"]))

    def test_the_reader_refuses_a_damaged_file_and_flags_a_message_foxglove_would_not_read(self):
        with tempfile.TemporaryDirectory() as tmp:
            w = mcap.Writer()
            good = w.channel("/good", "foxglove.PoseInFrame", mcap_export.POSE_IN_FRAME)
            bad = w.channel("/bad", "foxglove.PoseInFrame", mcap_export.POSE_IN_FRAME)
            for i in range(5):
                w.message(good, i * 10**9, {"timestamp": mcap_export.stamp(i), "frame_id": "world",
                                            "pose": mcap_export.pose(i, 0.0, 0.1)})
            w.message(bad, 2 * 10**9, {"timestamp": mcap_export.stamp(2), "frame_id": "world",
                                       "pose": {"position": {"x": "one", "y": 0, "z": 0},
                                                "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}})
            path = Path(tmp) / "x.mcap"
            self.assertEqual(w.finish(path), {"/good": 5, "/bad": 1})
            r, got = read_mcap(self, path)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertEqual(got["topics"], {"/good": 5, "/bad": 1})
            self.assertEqual(got["invalid"], {"/bad": 1})
            self.assertIn("/bad: data/pose/position/x must be number", got["errors"][0])
            # One byte of a message changed: its chunk's CRC no longer holds.
            data = bytearray(path.read_bytes())
            at = data.index(b'"frame_id":"world"')
            data[at + 13] ^= 0x01
            path.write_bytes(bytes(data))
            r, _ = read_mcap(self, path)
            self.assertEqual(r.returncode, 1)
            self.assertIn("crc", r.stderr.lower())


if __name__ == "__main__":
    unittest.main()
