"""The thesis's remaining results (docs/THESIS.md): the simulated Victoria Park and its sweeps."""

import csv
import subprocess
import tempfile
import time
import unittest
from pathlib import Path

from swarm_test import BIN, DATASETS, REPO

LAB = str(BIN / "mapmesh-lab")


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


class VictoriaWorldTest(unittest.TestCase):
    def test_the_shipped_world_is_what_the_dataset_gives(self):
        if not (DATASETS / "victoria_park").is_dir():
            self.skipTest(f"datasets not found at {DATASETS} (set MAPMESH_DATASETS)")
        with tempfile.TemporaryDirectory(prefix="mapmesh_vpworld_") as tmp:
            r = subprocess.run([LAB, "victoria-world", "--out", tmp, "--datasets", str(DATASETS)],
                               capture_output=True, text=True, timeout=240)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("444 landmarks", r.stderr)
            for name in ["victoria_sim.yaml", "data/victoria_sim_landmarks.csv"]:
                self.assertEqual((Path(tmp) / name).read_text(), (REPO / "scenarios" / name).read_text(),
                                 f"scenarios/{name} is not what mapmesh-lab victoria-world makes: regenerate it")

    def test_bad_arguments_are_one_line(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_vpworld_") as tmp:
            for args in (["--robots", "9"], ["--segments", "1"], ["--bogus"]):
                r = subprocess.run([LAB, "victoria-world", "--out", tmp] + args, capture_output=True, text=True,
                                   timeout=120)
                self.assertNotEqual(r.returncode, 0, args)
                self.assertEqual(len(r.stderr.strip().splitlines()), 1, (args, r.stderr))
                self.assertEqual(list(Path(tmp).iterdir()), [], args)  # nothing written


class ThesisCountsTest(unittest.TestCase):
    """Slow (ctest label slow): the Victoria Park sweeps and Table 7 at the thesis's run counts."""

    COUNTS = {"fig75_76_vp_bearing.csv": (50, 9), "fig77_78_vp_velocity.csv": (250, 9),
              "fig80_81_vp_range.csv": (500, 9), "table7_vp_sim.csv": (50, 6)}

    def test_victoria_park_sweeps_and_table7_at_the_thesis_counts(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_thesis_") as tmp:
            start = time.monotonic()
            r = subprocess.run([LAB, "thesis-fusion", "--out", tmp, "--only",
                                "vp_bearing,vp_velocity,vp_range,vp_table7"],
                               capture_output=True, text=True, timeout=1800)
            elapsed = time.monotonic() - start
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertLess(elapsed, 1800)
            print(f"thesis counts: {elapsed:.0f} s")
            for name, (runs, points) in self.COUNTS.items():
                rows = read_csv(Path(tmp) / name)
                by = {(row["value"], row["robot_a"], row["robot_b"], row["method"]): row for row in rows}
                keys = {(v, a, b) for v, a, b, _ in by}
                self.assertEqual(len(keys), points, name)
                for v, a, b in keys:
                    ci, info = by[(v, a, b, "ci")], by[(v, a, b, "information")]
                    self.assertEqual(int(ci["runs"]), runs, name)
                    self.assertGreater(int(ci["fused_runs"]), 0.5 * runs, (name, v, a, b))
                    # The thesis's reading of Figs. 76, 78 and 81: CI's NEES stays below the
                    # M-estimator's (information fusion), and CI is consistent.
                    self.assertLess(float(ci["nees_merged"]), float(info["nees_merged"]), (name, v, a, b))
                    self.assertLess(float(ci["nees_merged"]), 3.0, (name, v, a, b))
                    if name == "table7_vp_sim.csv":
                        # Table 7's finding: the merged map's NEES is below both single maps'.
                        self.assertLess(float(ci["nees_merged"]), min(float(ci["nees_a"]), float(ci["nees_b"])),
                                        (a, b))


if __name__ == "__main__":
    unittest.main()
