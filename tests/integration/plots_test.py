"""The lab's experiment CSVs through their plot scripts: every figure is written and is a PNG
of non-trivial size. Plots run with Debian's /usr/bin/python3 (matplotlib, numpy)."""

import json
import math
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
            self.assertEqual([p.name for p in pngs], ["fig45_overlap.png", "fig46_similarity.png", "fig48_50_noise.png",
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
            only = [] if have_vp else ["--only", "bearing", "velocity", "range", "fig58"]
            subprocess.run([str(BIN / "mapmesh-lab"), "thesis-fusion", "--out", str(out), "--seeds", "1",
                            "--threads", "1"] + only, check=True, capture_output=True, timeout=240)
            csvs = sorted(p.name for p in out.glob("*.csv"))
            expected = ["fig58_ellipses.csv", "fig61_62_bearing.csv", "fig64_65_velocity.csv", "fig72_73_range.csv"]
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


class SearchPlotsTest(unittest.TestCase):
    def test_ransac_arw_and_its_figure(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_plots_") as tmp:
            csv_path = Path(tmp) / "search.csv"
            subprocess.run([str(BIN / "mapmesh-lab"), "search", "--trials", "2", "--landmarks", "60",
                            "--overlaps", "0,0.5", "--csv", str(csv_path)], check=True, capture_output=True,
                           timeout=240)
            lines = csv_path.read_text().splitlines()
            self.assertEqual(len(lines), 1 + 2 * 2 * 3)  # header, then 2 overlaps x 2 pairs x 3 searches
            script = str(REPO / "scripts" / "plots" / "search.py")
            r = subprocess.run(["/usr/bin/python3", script, tmp], capture_output=True, text=True, timeout=120)
            self.assertEqual(r.returncode, 0, r.stderr)
            data = (Path(tmp) / "search.png").read_bytes()
            self.assertTrue(data.startswith(PNG_SIGNATURE))
            self.assertGreater(len(data), 10_000)
            bad = subprocess.run(["/usr/bin/python3", script, "/nonexistent/dir"], capture_output=True, text=True,
                                 timeout=60)
            self.assertNotEqual(bad.returncode, 0)
            self.assertEqual(len(bad.stderr.strip().splitlines()), 1, bad.stderr)


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


class CostPlotsTest(unittest.TestCase):
    """scripts/plots/cost.py on a planted mapmesh-bench report (no benchmark is run): the medians,
    the ratios and the figures follow from the planted times."""

    SCRIPT = str(REPO / "scripts" / "plots" / "cost.py")

    @staticmethod
    def planted_report():
        runs = []

        def add(name, t, unit="us", aggregate=None):
            runs.append({"name": name + (f"_{aggregate}" if aggregate else ""), "run_name": name,
                         "run_type": "aggregate" if aggregate else "iteration", "aggregate_name": aggregate or "",
                         "cpu_time": t, "real_time": 1e9, "time_unit": unit})

        for n in (50, 100, 200, 400, 500, 1000):  # c n log n: the growth exponent of n log n
            add(f"BM_ThesisDelaunay/{n}", 0.01 * n * math.log(n), aggregate="median")
            add(f"BM_ThesisDelaunay/{n}", 1e6, aggregate="mean")  # not the median: ignored
        for m in (10, 20, 50, 100, 200, 500, 1000):
            add(f"BM_ThesisRansacHypothesis/{m}", 40, "ns")
            add(f"BM_ThesisRansacConsensus/mahalanobis/{m}", m, "ns")  # 1 ns a candidate: 40 ns at 40
            add(f"BM_ThesisRansacConsensus/euclidean/{m}", 0.5 * m, "ns")  # ... at 80
        for method, k in (("ml", 1), ("information", 3), ("ci", 4), ("ci_det", 6), ("ci_det_search", 20)):
            for n in (2, 10, 100, 1000):
                for spread in (1.0, 50.0, 0.5):  # three repetitions without aggregates: the median is k n
                    add(f"BM_ThesisFuse/{method}/{n}", spread * k * n / 1000.0, "ms")
        add("BM_AlignMaps/1000/10", 5.0, "ms")  # not one of the thesis's: ignored
        return {"context": {}, "benchmarks": runs}

    def test_planted_report_gives_its_ratios_and_figures(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_cost_") as tmp:
            report = Path(tmp) / "report.json"
            report.write_text(json.dumps(self.planted_report()))
            out = Path(tmp) / "out"
            r = subprocess.run(["/usr/bin/python3", self.SCRIPT, "--json", str(report), str(out)],
                               capture_output=True, text=True, timeout=120)
            self.assertEqual(r.returncode, 0, r.stderr)
            self.assertIn("growth exponent of our time over n: 1.19 (n log n over the same range: 1.19", r.stdout)
            # 0.01 n ln n us, and per n log2 n in ns; at 400 the thesis's one value (40 us) beside ours
            self.assertIn("| 1000 | 69.1 µs | 6.93 |", r.stdout)
            self.assertIn("| 400 | 24 µs | 6.93 | 40 µs |", r.stdout)
            self.assertIn("ours / thesis at 400 landmarks: 0.599", r.stdout)
            self.assertIn("hypothesis max/min over the counts: 1.00", r.stdout)
            self.assertIn("consensus (mahalanobis): 1 ns per candidate, growth exponent 1.00; as dear as a hypothesis "
                          "at 40 candidates", r.stdout)
            self.assertIn("consensus (euclidean): 0.5 ns per candidate, growth exponent 1.00; as dear as a hypothesis "
                          "at 80 candidates", r.stdout)
            self.assertIn("| 100 | 100 µs | 300 µs | 400 µs | 600 µs | 2 ms | 1 ms | 21.5 ms |", r.stdout)
            self.assertIn("| ml/ci | 0.25 | 0.25 | 0.25 | 0.25 | about 0.5 |", r.stdout)
            self.assertIn("| ci_det/ci | 1.5 | 1.5 | 1.5 | 1.5 | 239 / 239 / 21.5 (2/10/100) |", r.stdout)
            self.assertIn("| ci_det_search/ci_det | 3.33 |", r.stdout)
            self.assertNotIn("AlignMaps", r.stdout)
            pngs = sorted(p.name for p in out.glob("*.png"))
            self.assertEqual(pngs, ["fig43_delaunay.png", "fig47_ransac_steps.png", "fig54_fusion.png",
                                    "table6_ci.png"])
            for name in pngs:
                data = (out / name).read_bytes()
                self.assertTrue(data.startswith(PNG_SIGNATURE), name)
                self.assertGreater(len(data), 10_000, name)

    def test_bad_inputs_are_one_line(self):
        h = subprocess.run(["/usr/bin/python3", self.SCRIPT, "--help"], capture_output=True, text=True, timeout=60)
        self.assertEqual(h.returncode, 0)
        self.assertIn("Usage", h.stdout)
        with tempfile.TemporaryDirectory(prefix="mapmesh_cost_") as tmp:
            garbled = Path(tmp) / "garbled.json"
            garbled.write_text("{not json")
            other = Path(tmp) / "other.json"
            foreign = {"name": "BM_AlignMaps/60/50", "run_name": "BM_AlignMaps/60/50", "cpu_time": 1.0,
                       "time_unit": "ms"}
            other.write_text(json.dumps({"benchmarks": [foreign]}))
            for args, says in ((["--json", str(garbled)], "not a readable JSON report"),
                               (["--json", str(Path(tmp) / "missing.json")], "not a readable JSON report"),
                               (["--json", str(other)], "no BM_Thesis benchmark"),
                               (["--bench", str(Path(tmp) / "no-bench")], "no such benchmark executable")):
                r = subprocess.run(["/usr/bin/python3", self.SCRIPT] + args + [str(Path(tmp) / "out")],
                                   capture_output=True, text=True, timeout=60)
                self.assertEqual(r.returncode, 1, args)
                self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
                self.assertIn(says, r.stderr)


if __name__ == "__main__":
    unittest.main()
