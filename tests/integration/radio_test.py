"""U1: a radio beyond the disc (radio.model: log_distance, shadowing, walls) through the real
processes: a sweep over the shadowing sigma runs, a lockstep run with it is the same run again,
and what the feeder published (feeder.json "links") is what the report and the export draw."""

import json
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

from swarm_test import BIN, SWARM, REPO

sys.path.insert(0, str(REPO / "scripts"))
from mapmesh.rundir import published_spans  # noqa: E402

PARK4 = REPO / "scenarios" / "park4.yaml"
# park4's 60 m square cut by a wall from (30, 10) to (30, 50).
LOG_DISTANCE = ["--set", "radio.model=log_distance", "--set", "radio.walls=[[30, 10, 30, 50]]",
                "--set", "duration_s=60", "--no-reference"]


class RadioModelTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="mapmesh_radio_")
        self.dir = Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def test_a_sweep_over_the_shadowing_runs_and_each_run_is_the_same_run_again(self):
        sweep = self.dir / "sweep"
        r = subprocess.run(SWARM + ["sweep", str(PARK4), "--param", "radio.shadowing_sigma_db=0,8"] + LOG_DISTANCE
                           + ["--out", str(sweep)], capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        spans = {}
        for sigma in ("0", "8"):
            run = sweep / "runs" / f"radio.shadowing_sigma_db={sigma}"
            links = json.loads((run / "feeder.json").read_text())["links"]
            self.assertEqual(links["model"], "log_distance")
            self.assertEqual(links["tables"], 121)  # 0 to 60 s every 0.5 s
            spans[sigma] = links["spans"]
            self.assertTrue(spans[sigma], sigma)
            resolved = json.loads((run / "run.json").read_text())["resolved"]
            self.assertEqual(resolved["radio.shadowing_sigma_db"], float(sigma))
        # The shadowing decided other links than the path loss alone.
        self.assertNotEqual(spans["8"], spans["0"])
        # The same point run again on its own: the same run, byte for byte (swarm compare).
        again = self.dir / "again"
        r = subprocess.run(SWARM + ["run", str(PARK4), "--set", "radio.shadowing_sigma_db=8"] + LOG_DISTANCE
                           + ["--quiet", "--no-report", "--out", str(again)], capture_output=True, text=True,
                           timeout=300)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        c = subprocess.run(SWARM + ["compare", str(sweep / "runs" / "radio.shadowing_sigma_db=8"), str(again)],
                           capture_output=True, text=True, timeout=120)
        self.assertEqual(c.returncode, 0, c.stdout + c.stderr)
        # The report's "who hears whom" is what the feeder published.
        r = subprocess.run(SWARM + ["report", str(again)], capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        feeder = json.loads((again / "feeder.json").read_text())
        pairs = published_spans(feeder)
        self.assertEqual(sum(len(v) for v in pairs.values()), len(feeder["links"]["spans"]))

    def test_bad_radio_keys_are_refused_in_one_line(self):
        feeder = BIN / "mapmesh-feeder"
        for sets, why in ((["radio.shadowing_sigma_db=3"], "only with radio.model: log_distance"),
                          (["radio.model=log_distance", "radio.walls=[[1, 2, 3]]"], "expected a wall"),
                          (["radio.model=log_distance", "radio.walls=[[1, 2, 1, 2]]"], "two ends must differ"),
                          (["radio.model=ns3"], "disc, log_distance"),
                          (["radio.model=log_distance", "radio.path_loss_exponent=0"], "path_loss_exponent")):
            cmd = [str(feeder), "--scenario", str(PARK4), "--check"] + [x for s in sets for x in ("--set", s)]
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=60)
            self.assertNotEqual(r.returncode, 0, sets)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn(why, r.stderr)


if __name__ == "__main__":
    unittest.main()
