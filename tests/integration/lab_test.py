"""mapmesh-lab bus: a scenario's agents in one process over an in-memory bus, and its table."""

import re
import subprocess
import tempfile
import unittest
from pathlib import Path

from swarm_test import BIN, DATASETS, REPO


def bus(scenario):
    r = subprocess.run([str(BIN / "mapmesh-lab"), "bus", "--scenario", str(REPO / "scenarios" / scenario)],
                       capture_output=True, text=True, timeout=240)
    if r.returncode != 0:
        raise AssertionError(r.stdout + r.stderr)
    lines = r.stdout.splitlines()
    header = next(i for i, line in enumerate(lines) if line.split()[:2] == ["id", "alive"])
    rows = {}
    for line in lines[header + 1:]:
        if not line.strip():
            break  # the table ends; first alignments and worst transforms follow
        f = line.split()
        rows[int(f[0])] = {"alive": f[1], "lm_loc": int(f[3]), "rmse_loc": f[4], "lm_glob": int(f[5]),
                           "rmse_glb": f[6], "cov_glb": f[9], "peers": " ".join(f[10:])}
    return lines[header], rows


class LabBusTest(unittest.TestCase):
    def test_circle_pair_aligns_and_is_scored_against_the_truth(self):
        header, rows = bus("thesis_circle_pair.yaml")
        self.assertIn("error m/deg", header)
        self.assertEqual(sorted(rows), [1, 2])
        for rid, r in rows.items():
            self.assertEqual(r["alive"], "yes")
            self.assertGreater(r["lm_loc"], 50)
            self.assertGreaterEqual(r["lm_glob"], r["lm_loc"])
            self.assertEqual(float(r["cov_glb"]), 1.0)
            self.assertLess(float(r["rmse_glb"]), 1.0)
            # "2.1(0.21/1.29 fit 0.00/0.01)": robot 2's first incarnation, its alignment's error
            # against the true start poses, then against the frames the two maps are in.
            peers = re.findall(r"(\d+)\.(\d+)\(([\d.]+)/([\d.]+) fit ([\d.]+)/([\d.]+)\)", r["peers"])
            self.assertEqual(len(peers), 1, r["peers"])
            robot, incarnation, _, _, fit_m, fit_deg = peers[0]
            self.assertEqual((int(robot), int(incarnation)), (3 - rid, 1))
            self.assertLess(float(fit_m), 0.05)
            self.assertLess(float(fit_deg), 0.5)

    def test_victoria_park_without_landmark_truth_prints_map_sizes(self):
        if not DATASETS.is_dir():
            self.skipTest(f"datasets not found at {DATASETS} (set MAPMESH_DATASETS)")
        header, rows = bus("victoria_4.yaml")
        self.assertNotIn("error", header)
        self.assertEqual(sorted(rows), [1, 2, 3, 4])
        for r in rows.values():
            self.assertGreater(r["lm_loc"], 100)  # the map's size, not a count of matched landmarks
            self.assertGreater(r["lm_glob"], r["lm_loc"])
            self.assertEqual((r["rmse_loc"], r["rmse_glb"], r["cov_glb"]), ("-", "-", "-"))
            self.assertGreaterEqual(len(r["peers"].split()), 1)
            for p in r["peers"].split():
                robot, incarnation = p.split(".")
                self.assertIn(int(robot), [1, 2, 3, 4])
                self.assertEqual(incarnation, "1")


if __name__ == "__main__":
    unittest.main()


class LabReferenceUntilTest(unittest.TestCase):
    def test_bad_until_is_one_line_and_writes_nothing(self):
        # --until ROBOT=T (the reference of what reached one agent): a robot not in the scenario,
        # a robot given twice, or a malformed pair is one line, exit 2, and no file.
        out = Path(tempfile.mkdtemp(prefix="lab_until_")) / "reference.json"
        for until in (["9=5"], ["2=5", "2=6"], ["x=5"], ["-1=5"], ["2=-1"], ["2=5s"], ["=5"]):
            out.unlink(missing_ok=True)
            args = [str(BIN / "mapmesh-lab"), "reference", "--scenario", str(REPO / "scenarios" / "line3.yaml"),
                    "--no-known-pose", "--out", str(out)]
            for u in until:
                args += ["--until", u]
            r = subprocess.run(args, capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 2, (until, r.stderr))
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, (until, r.stderr))
            self.assertIn("--until", r.stderr)
            self.assertFalse(out.exists(), until)
