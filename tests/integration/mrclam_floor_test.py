"""scripts/mrclam-floor on synthetic MRCLAM-format datasets whose noise is planted: a robot
drives a circle among eight landmarks with ground truth, sightings and commanded odometry
written in MRCLAM's files. The script must recover the planted range and bearing noise and
bias, find the known-pose map exact when the sightings are exact, and its own-frame bound must
scale with the noise as a Cramer-Rao bound does (all sigmas x4: the bound x4).

Run: cd tests/integration && /usr/bin/python3 -m unittest mrclam_floor_test
"""

import json
import math
import os
import random
import subprocess
import tempfile
import unittest
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "scripts" / "mrclam-floor"
BIN = Path(os.environ.get("MAPMESH_BIN", REPO / "build" / "bin"))
DATASETS = Path(os.environ.get("MAPMESH_DATASETS", REPO.parent / "shared" / "datasets"))
LANDMARKS = {6 + i: (4.0 * math.cos(i * math.pi / 4) + 0.3 * i, 3.0 * math.sin(i * math.pi / 4)) for i in range(8)}


def write_dataset(folder, seed, range_sigma, bearing_sigma, range_bias=0.0, bearing_bias=0.0, odo_sigma=0.0):
    """Robot 1 drives a circle of radius 1.5 m at 0.3 m/s for 120 s; every 0.2 s it sees each
    landmark within 6 m and 60 degrees either side, with the planted noise."""
    rng = random.Random(seed)
    folder.mkdir(parents=True)
    header = "# synthetic\n# for mrclam_floor_test\n# fields\n# fields\n"
    (folder / "Barcodes.dat").write_text(header + "".join(f"{s}\t{s + 10}\n" for s in LANDMARKS))
    (folder / "Landmark_Groundtruth.dat").write_text(
        header + "".join(f"{s}\t{x:.6f}\t{y:.6f}\t0\t0\n" for s, (x, y) in LANDMARKS.items()))
    v, radius, t0 = 0.3, 1.5, 1000.0
    w = v / radius
    gt, odo, meas = [], [], []
    for k in range(0, 1201):
        t = t0 + 0.1 * k
        a = w * (t - t0)
        x, y, h = radius * math.sin(a), radius * (1 - math.cos(a)), a
        gt.append(f"{t:.3f}\t{x:.8f}\t{y:.8f}\t{math.atan2(math.sin(h), math.cos(h)):.8f}\n")
        odo.append(f"{t:.3f}\t{v + rng.gauss(0, odo_sigma):.5f}\t{w + rng.gauss(0, odo_sigma):.5f}\n")
        if k % 2:
            continue
        for s, (lx, ly) in LANDMARKS.items():
            r = math.hypot(lx - x, ly - y)
            b = math.atan2(ly - y, lx - x) - h
            b = math.atan2(math.sin(b), math.cos(b))
            if r < 6 and abs(b) < math.radians(60):
                meas.append(f"{t:.3f}\t{s + 10}\t{r + range_bias + rng.gauss(0, range_sigma):.6f}\t"
                            f"{b + bearing_bias + rng.gauss(0, bearing_sigma):.7f}\n")
    (folder / "Robot1_Groundtruth.dat").write_text(header + "".join(gt))
    (folder / "Robot1_Odometry.dat").write_text(header + "".join(odo))
    (folder / "Robot1_Measurement.dat").write_text(header + "".join(meas))


def floor(folder):
    out = subprocess.run(["/usr/bin/python3", str(SCRIPT), "--dataset", str(folder), "--odometry-delay-s", "0"],
                         capture_output=True, text=True, timeout=120)
    if out.returncode != 0:
        raise AssertionError(out.stderr)
    return json.loads(out.stdout)["robots"]["1"]


class MrclamFloorTest(unittest.TestCase):
    def test_recovers_planted_noise_and_bound_scales_with_it(self):
        with tempfile.TemporaryDirectory() as d:
            exact = Path(d) / "exact"
            write_dataset(exact, 1, 0.0, 0.0)
            r = floor(exact)
            self.assertGreater(r["sightings"], 1000)
            self.assertLess(r["known_pose_rmse_m"], 1e-3)
            self.assertLess(r["known_pose_aligned_m"], 1e-3)
            self.assertLess(r["known_pose_ml_rmse_m"], 1e-3)
            self.assertLess(r["known_pose_ml_aligned_m"], 1e-3)

            noisy = Path(d) / "noisy"
            write_dataset(noisy, 2, 0.08, math.radians(1.0), range_bias=0.05, bearing_bias=math.radians(0.5),
                          odo_sigma=0.04)
            r = floor(noisy)
            self.assertAlmostEqual(r["range_sigma_m"], 0.08, delta=0.08 * 0.1)
            self.assertAlmostEqual(r["bearing_sigma_deg"], 1.0, delta=0.1)
            self.assertAlmostEqual(r["range_bias_m"], 0.05, delta=0.01)
            self.assertAlmostEqual(r["bearing_bias_deg"], 0.5, delta=0.1)
            # The biases stay in the known-pose map: each landmark is 5 cm farther out along the
            # sight line and turned by 0.5 deg, which no averaging removes.
            self.assertGreater(r["known_pose_rmse_m"], 0.03)

            quiet = Path(d) / "quiet"
            write_dataset(quiet, 2, 0.02, math.radians(0.25), odo_sigma=0.01)
            q = floor(quiet)
            self.assertGreater(r["own_frame_bound_m"], 0.0)
            ratio = r["own_frame_bound_m"] / q["own_frame_bound_m"]
            self.assertAlmostEqual(ratio, 4.0, delta=0.4)

    def test_its_known_pose_map_agrees_with_the_reference_on_dataset_7(self):
        """Two implementations of the maximum-likelihood known-pose map on MRCLAM 7, this script's
        (numpy, 100 Hz Vicon) and `mapmesh-lab reference`'s (C++, the feeder's 10 Hz truth), agree
        robot by robot."""
        if not (DATASETS / "mrclam" / "MRCLAM_Dataset7").is_dir():
            self.skipTest(f"MRCLAM 7 not found under {DATASETS} (set MAPMESH_DATASETS)")
        out = subprocess.run(["/usr/bin/python3", str(SCRIPT), "--dataset", "7", "--datasets", str(DATASETS)],
                             capture_output=True, text=True, timeout=120)
        self.assertEqual(out.returncode, 0, out.stderr)
        script = json.loads(out.stdout)["robots"]
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "reference.json"
            r = subprocess.run([str(BIN / "mapmesh-lab"), "reference", "--scenario",
                                str(REPO / "scenarios" / "mrclam_7.yaml"), "--datasets", str(DATASETS), "--out",
                                str(path)], capture_output=True, text=True, timeout=240)
            self.assertEqual(r.returncode, 0, r.stderr)
            ref = json.loads(path.read_text())
        self.assertTrue(ref["available"])
        self.assertEqual(sorted(ref["own_known_pose"]), sorted(script))
        for robot, s in script.items():
            c = ref["own_known_pose"][robot]
            for mine, theirs in ((s["known_pose_ml_aligned_m"], c["rmse_aligned_m"]),
                                 (s["known_pose_ml_rmse_m"], c["rmse_m"])):
                self.assertAlmostEqual(mine, theirs, delta=max(0.002, 0.05 * mine), msg=f"robot {robot}")

    def test_help_and_bad_arguments_are_one_line(self):
        out = subprocess.run(["/usr/bin/python3", str(SCRIPT), "--help"], capture_output=True, text=True, timeout=60)
        self.assertEqual(out.returncode, 0)
        self.assertIn("--window-s", out.stdout)
        with tempfile.TemporaryDirectory() as d:
            out = subprocess.run(["/usr/bin/python3", str(SCRIPT), "--dataset", d], capture_output=True, text=True,
                                 timeout=60)
            self.assertEqual(out.returncode, 1)
            self.assertEqual(len(out.stderr.strip().splitlines()), 1, out.stderr)
            self.assertIn("no MRCLAM dataset there", out.stderr)
            folder = Path(d) / "no_truth"
            write_dataset(folder, 3, 0.0, 0.0)
            (folder / "Robot1_Groundtruth.dat").unlink()
            out = subprocess.run(["/usr/bin/python3", str(SCRIPT), "--dataset", str(folder)], capture_output=True,
                                 text=True, timeout=60)
            self.assertEqual(out.returncode, 1)
            self.assertEqual(len(out.stderr.strip().splitlines()), 1, out.stderr)
            self.assertIn("no robot has Vicon ground truth", out.stderr)


if __name__ == "__main__":
    unittest.main()
