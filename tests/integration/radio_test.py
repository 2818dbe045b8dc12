"""U1: a radio beyond the disc (radio.model: log_distance, shadowing, walls) through the real
processes: a sweep over the shadowing sigma runs, a lockstep run with it is the same run again,
and what the feeder published (feeder.json "links") is what the report and the export draw.
Each link's latency (radio.latency_s, latency_jitter_s): what the agents took from each peer is
as old as its link's latency, which the test draws itself, and such a run is the same run again."""

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


MASK = (1 << 64) - 1


def mix64(x):
    """splitmix64's output function (common/types/keyed_draw.h), written again from its definition."""
    x = (x + 0x9E3779B97F4A7C15) & MASK
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & MASK
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & MASK
    return x ^ (x >> 31)


def link_latency(seed, a, b, latency_s, jitter_s):
    """A link's latency: latency_s plus the pair's uniform draw (stream 3) in [0, jitter_s)."""
    k = mix64(seed)
    for part in (3, min(a, b), max(a, b)):
        k = mix64(k ^ part)
    return latency_s + jitter_s * (mix64(k) >> 11) * 2.0 ** -53


class RadioModelTest(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="mapmesh_radio_")
        self.dir = Path(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def swarm_run(self, name, *args):
        out = self.dir / name
        r = subprocess.run(SWARM + ["run", str(PARK4), "--agents", "8", "--no-reference", "--no-report", "--out",
                                    str(out)] + list(args), capture_output=True, text=True, timeout=300)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        return out

    def data_until(self, run):
        """{(agent, robot): how old the newest data the agent took of the robot was at the end}."""
        summary = json.loads((run / "summary.json").read_text())
        end = summary["sim_duration_s"]
        out = {}
        for a in summary["agents"]:
            stats = json.loads((run / f"agent_{a['id']}" / "stats.json").read_text())
            for robot, t in stats["data_until"].items():
                out[(a["id"], int(robot))] = end - t
        return out

    def test_each_link_has_its_latency_and_a_run_with_it_is_the_same_run_again(self):
        latency, jitter = 4.0, 6.0
        flags = ["--set", f"radio.latency_s={latency}", "--set", f"radio.latency_jitter_s={jitter}"]
        plain = self.data_until(self.swarm_run("plain"))
        delayed_run = self.swarm_run("delayed", *flags)
        delayed = self.data_until(delayed_run)
        made = json.loads((delayed_run / "run.json").read_text())
        seed = made["seed"]
        period = made["resolved"]["agent.map_publish_period_s"]  # the exchange ticks' period
        fresh = [pair for pair, lag in plain.items() if lag <= period]  # linked to the end, without latency
        self.assertGreater(len(fresh), 4)
        for pair, lag in delayed.items():
            with self.subTest(pair=pair):
                self.assertGreaterEqual(lag, latency - 1e-9)  # nothing came faster than any link
                if pair in fresh:  # the direct link delivered up to its own latency, and a tick
                    self.assertLessEqual(lag, link_latency(seed, *pair, latency, jitter) + period + 1e-9)
        lags = [link_latency(seed, *pair, latency, jitter) for pair in fresh]
        self.assertGreater(max(lags) - min(lags), 1.0)  # links of their own latency
        stats = [json.loads(p.read_text()) for p in sorted(delayed_run.glob("agent_*/stats.json"))]
        self.assertEqual(sum(s["maps_delay_overflow"] for s in stats), 0)
        for s in stats:  # a latency above the ticks' period: every map taken was held first
            self.assertGreater(s["maps_received"], 0)
            self.assertLessEqual(s["maps_received"], s["maps_delayed"])
        # At the end, what was sent in the last latency of each linked pair is still in flight.
        self.assertGreater(sum(s["in_flight"] for s in stats), 2 * len(fresh))
        again = self.swarm_run("again", *flags)
        r = subprocess.run(SWARM + ["compare", str(delayed_run), str(again)], capture_output=True, text=True,
                           timeout=120)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)

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
