"""The lab's experiment CSVs through their plot scripts: every figure is written and is a PNG
of non-trivial size. Plots run with Debian's /usr/bin/python3 (matplotlib, numpy)."""

import subprocess
import tempfile
import unittest
from pathlib import Path

from swarm_test import BIN, DATASETS, REPO

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


class AlignmentPlotsTest(unittest.TestCase):
    def test_thesis_alignment_figures(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_plots_") as tmp:
            out = Path(tmp) / "alignment"
            subprocess.run([str(BIN / "mapmesh-lab"), "thesis-align", "--out", str(out), "--trials", "1"],
                           check=True, capture_output=True, timeout=120)
            r = subprocess.run(["/usr/bin/python3", str(REPO / "scripts" / "plots" / "alignment.py"), str(out)],
                               capture_output=True, text=True, timeout=120)
            self.assertEqual(r.returncode, 0, r.stderr)
            pngs = sorted(out.glob("*.png"))
            self.assertEqual([p.name for p in pngs], ["fig46_similarity.png", "fig48_50_noise.png",
                                                      "fig49_51_match_ratio.png", "fig52_53_distance.png"])
            for p in pngs:
                data = p.read_bytes()
                self.assertTrue(data.startswith(PNG_SIGNATURE), p.name)
                self.assertGreater(len(data), 10_000, p.name)

    def test_help_and_missing_directory(self):
        script = str(REPO / "scripts" / "plots" / "alignment.py")
        h = subprocess.run(["/usr/bin/python3", script, "--help"], capture_output=True, text=True, timeout=60)
        self.assertEqual(h.returncode, 0)
        self.assertIn("Usage", h.stdout)
        r = subprocess.run(["/usr/bin/python3", script, "/nonexistent/dir"],
                           capture_output=True, text=True, timeout=60)
        self.assertNotEqual(r.returncode, 0)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)


class FusionPlotsTest(unittest.TestCase):
    def test_thesis_fusion_figures(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_plots_") as tmp:
            out = Path(tmp) / "fusion"
            # Table 7 replays Victoria Park: without the datasets only the simulated figures are drawn.
            have_vp = (DATASETS / "victoria_park").is_dir()
            only = [] if have_vp else ["--only", "bearing", "velocity", "range"]
            subprocess.run([str(BIN / "mapmesh-lab"), "thesis-fusion", "--out", str(out), "--seeds", "1",
                            "--threads", "1"] + only, check=True, capture_output=True, timeout=240)
            csvs = sorted(p.name for p in out.glob("*.csv"))
            expected = ["fig61_62_bearing.csv", "fig64_65_velocity.csv", "fig72_73_range.csv"]
            if have_vp:  # every experiment: the simulated Victoria Park, low overlap and the real replay
                expected += ["fig66_69_low_overlap.csv", "fig75_76_vp_bearing.csv", "fig77_78_vp_velocity.csv",
                             "fig80_81_vp_range.csv", "table7_victoria.csv", "table7_vp_sim.csv"]
            self.assertEqual(csvs, sorted(expected))
            r = subprocess.run(["/usr/bin/python3", str(REPO / "scripts" / "plots" / "fusion.py"), str(out)],
                               capture_output=True, text=True, timeout=120)
            self.assertEqual(r.returncode, 0, r.stderr)
            pngs = sorted(p.name for p in out.glob("*.png"))
            self.assertEqual(pngs, [c.replace(".csv", ".png") for c in csvs])
            for name in pngs:
                data = (out / name).read_bytes()
                self.assertTrue(data.startswith(PNG_SIGNATURE), name)
                self.assertGreater(len(data), 10_000, name)

    def test_help_and_missing_directory(self):
        script = str(REPO / "scripts" / "plots" / "fusion.py")
        h = subprocess.run(["/usr/bin/python3", script, "--help"], capture_output=True, text=True, timeout=60)
        self.assertEqual(h.returncode, 0)
        self.assertIn("Usage", h.stdout)
        r = subprocess.run(["/usr/bin/python3", script, "/nonexistent/dir"], capture_output=True, text=True, timeout=60)
        self.assertNotEqual(r.returncode, 0)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)


class WorldPlotTest(unittest.TestCase):
    SCRIPT = str(REPO / "scripts" / "plots" / "world.py")
    ENV = {"MAPMESH_BIN": str(BIN), "PATH": "/usr/bin:/bin"}

    def test_the_simulated_victoria_park_and_a_generated_world(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_plots_") as tmp:
            for scenario in ["victoria_sim.yaml", "thesis_low_overlap.yaml"]:
                out = Path(tmp) / scenario.replace(".yaml", ".png")
                r = subprocess.run(["/usr/bin/python3", self.SCRIPT, str(REPO / "scenarios" / scenario), str(out)],
                                   capture_output=True, text=True, timeout=120, env=self.ENV)
                self.assertEqual(r.returncode, 0, r.stderr)
                data = out.read_bytes()
                self.assertTrue(data.startswith(PNG_SIGNATURE), scenario)
                self.assertGreater(len(data), 20_000, scenario)

    def test_help_and_bad_input_are_one_line(self):
        h = subprocess.run(["/usr/bin/python3", self.SCRIPT, "--help"], capture_output=True, text=True, timeout=60)
        self.assertEqual(h.returncode, 0)
        self.assertIn("scenario", h.stdout)
        with tempfile.TemporaryDirectory(prefix="mapmesh_plots_") as tmp:
            for args in (["/nonexistent.yaml", f"{tmp}/x.png"],
                         [str(REPO / "scenarios" / "park4.yaml"), f"{tmp}/x.png", "--set", "bogus=1"]):
                r = subprocess.run(["/usr/bin/python3", self.SCRIPT] + args, capture_output=True, text=True,
                                   timeout=60, env=self.ENV)
                self.assertNotEqual(r.returncode, 0, args)
                self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
                self.assertFalse(Path(f"{tmp}/x.png").exists())


if __name__ == "__main__":
    unittest.main()
