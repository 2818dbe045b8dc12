"""U1: `swarm sweep` run for real: stopped by a signal (the finished runs kept, nothing started
after it), completed by --resume, and its statistics (sweep_summary.csv) against a computation
of this test's own."""

import csv
import json
import signal
import statistics
import subprocess
import tempfile
import time
import unittest
from pathlib import Path

from swarm_test import SWARM, REPO, leftover_processes
from report_test import check_png

PARK4 = REPO / "scenarios" / "park4.yaml"


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def without_wall(rows):
    return [{k: v for k, v in r.items() if k != "wall_s"} for r in rows]


class SweepCase(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="mapmesh_sweep_")
        self.out = Path(self.tmp.name) / "sweep"

    def tearDown(self):
        self.tmp.cleanup()

    def sweep(self, *args, timeout=300):
        return subprocess.run(SWARM + ["sweep", str(PARK4)] + [str(a) for a in args] + ["--out", str(self.out)],
                              capture_output=True, text=True, timeout=timeout)


class SweepInterruptTest(SweepCase):
    def test_a_signal_during_the_second_run_stops_the_sweep_and_keeps_the_first(self):
        # U1: Ctrl-C stopped the two runs under way, then every queued run still started and
        # finished, and the sweep exited 130 with no line and no sweep.csv.
        names = [f"radio.range_m={r}_seed{s}" for r in (10, 25, 50) for s in (1, 2, 3, 4)]
        proc = subprocess.Popen(SWARM + ["sweep", str(PARK4), "--param", "radio.range_m=10,25,50", "--seeds",
                                         "1,2,3,4", "--jobs", "1", "--pace", "realtime", "--set", "duration_s=6",
                                         "--no-reference", "--out", str(self.out)],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            second = self.out / "runs" / names[1]
            deadline = time.monotonic() + 120
            while not (second / "run.json").exists():  # written once its run has started
                self.assertIsNone(proc.poll(), "the sweep ended before its second run")
                self.assertLess(time.monotonic(), deadline, "the second run never started")
                time.sleep(0.05)
            time.sleep(1.0)  # well inside it: the run takes 6 s
            sent = time.monotonic()
            proc.send_signal(signal.SIGINT)
            out, err = proc.communicate(timeout=30)
            took = time.monotonic() - sent
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
        self.assertEqual(proc.returncode, 130, out + err)
        self.assertLess(took, 10.0, out + err)
        started = sorted(p.name for p in (self.out / "runs").iterdir())
        self.assertEqual(started, sorted(names[:2]), "a run started after the signal")
        self.assertEqual(err.strip().splitlines()[-1],
                         "swarm: sweep interrupted (SIGINT): 1 of 12 runs finished and are in sweep.csv; the others "
                         "did not run to their end; --resume runs them")
        rows = read_csv(self.out / "sweep.csv")
        self.assertEqual({(r["radio.range_m"], r["seed"]) for r in rows}, {("10", "1")})
        self.assertEqual(len(rows), 4)
        self.assertTrue((self.out / "sweep.png").exists())
        self.assertIn(f"{self.out / 'sweep.csv'}  (1 of 12 runs)", out)
        # The second run was stopped as `swarm run` is stopped by Ctrl-C: its summary says so.
        self.assertTrue(json.loads((self.out / "runs" / names[1] / "summary.json").read_text())["interrupted"])
        self.assertEqual(leftover_processes(str(self.out)), [])


class SweepResumeTest(SweepCase):
    def test_resume_runs_only_what_did_not_finish(self):
        grid = ["--param", "radio.range_m=10,50", "--seeds", "1,2", "--set", "duration_s=20", "--no-reference"]
        r = self.sweep(*grid)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        first = read_csv(self.out / "sweep.csv")
        self.assertEqual(len(first), 4 * 4)
        runs = self.out / "runs"
        # One run lost its summary, one was stopped (as a signal leaves it).
        (runs / "radio.range_m=10_seed2" / "summary.json").unlink()
        stopped = runs / "radio.range_m=50_seed1" / "summary.json"
        stopped.write_text(json.dumps(dict(json.loads(stopped.read_text()), interrupted=True)))
        again = self.sweep(*grid)
        self.assertEqual(again.returncode, 2, again.stderr)
        self.assertIn("--resume to run only its missing runs", again.stderr)
        r = self.sweep(*grid, "--resume")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("4 runs, all checked, 2 finished before, 2 to run", r.stdout)
        progress = sorted(line.split(":")[0] for line in r.stdout.splitlines() if line.startswith("["))
        self.assertEqual(progress, ["[1/2] radio.range_m=10 seed 2", "[2/2] radio.range_m=50 seed 1"]
                         if progress[0].startswith("[1/2] radio.range_m=10") else
                         ["[1/2] radio.range_m=50 seed 1", "[2/2] radio.range_m=10 seed 2"])
        # Lockstep: the runs done again are the same runs (but for their wall time).
        self.assertEqual(without_wall(read_csv(self.out / "sweep.csv")), without_wall(first))
        self.assertIn("rmse_global_aligned_m", r.stdout)  # the figure without the reference
        r = self.sweep("--param", "radio.range_m=10,60", "--seeds", "1,2", "--set", "duration_s=20", "--no-reference",
                       "--resume")
        self.assertEqual(r.returncode, 2, r.stderr)
        self.assertIn("had another grid", r.stderr)


class SweepStatisticsTest(SweepCase):
    def test_three_ranges_three_seeds_with_a_kill(self):
        # U1: sweep.png averaged the killed agent's frozen figures into every band, drew a mean
        # that one outlier pulled up with a min-max band, no median and no per-seed points; the
        # progress lines gave coverage and RMSE but not the gap swept for.
        r = self.sweep("--param", "radio.range_m=10,25,50", "--seeds", "1,2,3", "--set", "duration_s=60",
                       "--kill", "3@30")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        progress = [line for line in r.stdout.splitlines() if line.startswith("[")]
        self.assertEqual(len(progress), 9)
        self.assertTrue(all("gap_to_central " in line and "(median over 3 agents alive at the end; 1 killed apart"
                            in line for line in progress), progress)
        rows = read_csv(self.out / "sweep.csv")
        summary = read_csv(self.out / "sweep_summary.csv")
        self.assertEqual(list(summary[0])[:2], ["radio.range_m", "metric"])
        # This test's own computation: per run the median over its agents of each group, then
        # over the three seeds the median and, with three seeds, the range (coverage 1 - 2^-2).
        metrics = ("gap_to_central", "coverage_global", "rmse_global_aligned_m", "nees_global")
        checked = 0
        for metric in metrics:
            for rng in ("10", "25", "50"):
                for group, alive in (("alive", "1"), ("killed", "0")):
                    per_seed = []
                    for seed in ("1", "2", "3"):
                        vals = [float(x[metric]) for x in rows if (x["radio.range_m"], x["seed"], x["alive"]) ==
                                (rng, seed, alive) and x[metric] not in ("", "None")]
                        if vals:
                            per_seed.append(statistics.median(vals))
                    line = [s for s in summary if (s["radio.range_m"], s["metric"], s["agents"]) ==
                            (rng, metric, group)]
                    self.assertEqual(len(line), 1, (metric, rng, group))
                    line = line[0]
                    self.assertEqual(int(line["seeds"]), len(per_seed))
                    self.assertAlmostEqual(float(line["median"]), statistics.median(per_seed), places=5)
                    self.assertAlmostEqual(float(line["lo"]), min(per_seed), places=5)
                    self.assertAlmostEqual(float(line["hi"]), max(per_seed), places=5)
                    self.assertAlmostEqual(float(line["interval_coverage"]), 0.75)
                    self.assertEqual([float(v.split(":")[1]) for v in line["per_seed"].split()],
                                     [float(f"{v:.6g}") for v in per_seed])
                    checked += 1
        self.assertEqual(checked, 4 * 3 * 2)
        # The killed agent (3) is apart: every run's agent 3 is dead at the end and in no alive figure.
        self.assertEqual({x["alive"] for x in rows if x["agent"] == "3"}, {"0"})
        check_png(self, self.out / "sweep.png", min_bytes=10_000)
        plot = subprocess.run(["/usr/bin/python3", str(REPO / "scripts" / "plots" / "sweep.py"), str(self.out)],
                              capture_output=True, text=True, timeout=120)
        self.assertEqual(plot.returncode, 0, plot.stderr)
        # A report of any run of the sweep: one for each.
        rep = subprocess.run(SWARM + ["report", str(self.out)], capture_output=True, text=True, timeout=300)
        self.assertEqual(rep.returncode, 0, rep.stdout + rep.stderr)
        self.assertIn("reports: 9 of 9 finished runs", rep.stdout)
        self.assertEqual(len(list(self.out.glob("runs/*/report.html"))), 9)


if __name__ == "__main__":
    unittest.main()
