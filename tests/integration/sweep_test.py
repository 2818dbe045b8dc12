"""X1: how `swarm sweep` turns its arguments into runs (scripts/mapmesh/sweep.py), without
running any: the grid, and every run option given to each run as `swarm run` takes it."""

import json
import random
import statistics
import sys
import tempfile
import unittest
from importlib.machinery import SourceFileLoader
from pathlib import Path

from swarm_test import REPO

sys.path.insert(0, str(REPO / "scripts"))
from mapmesh import columns, sweep, sweep_stats  # noqa: E402
from mapmesh.run import RunError  # noqa: E402

swarm = SourceFileLoader("swarm_cli", str(REPO / "scripts" / "swarm")).load_module()


class SweepPlanTest(unittest.TestCase):
    def test_every_run_option_reaches_each_run_as_swarm_run_takes_it(self):
        parser = swarm.build_parser()
        argv = ["sweep", "s.yaml", "--param", "radio.range_m=5,10", "--out", "/tmp/x", "--agents", "6",
                "--kill", "2@30", "--restart", "2@40", "--pause", "3@10:2", "--set", "duration_s=60",
                "--pace", "realtime", "--rate", "20", "--timeout", "99", "--inject", "all", "--inject-period", "0.5",
                "--inject-sim-period", "2",
                "--secure", "--inject-identity", "agent2", "--hosts", "netns", "--net-loss", "5", "--net-rate", "10",
                "--no-reference"]
        args = parser.parse_args(argv)
        flags = sweep.option_flags(args, args.run_defaults)
        # `swarm run` parses them back to the same options.
        run = args.run_parser.parse_args(["s.yaml", "--out", "/tmp/y"] + flags)
        for name in ("agents", "kill", "restart", "pause", "set", "pace", "rate", "timeout", "inject", "inject_period",
                     "inject_sim_period",
                     "secure", "inject_identity", "hosts", "net_loss", "net_rate", "no_reference"):
            self.assertEqual(getattr(run, name), getattr(args, name), name)
        # Defaults are not repeated.
        plain = parser.parse_args(["sweep", "s.yaml", "--param", "radio.range_m=5", "--out", "/tmp/x"])
        self.assertEqual(sweep.option_flags(plain, plain.run_defaults), [])

    def test_the_grid_is_every_combination_and_each_run_has_its_folder(self):
        grid = sweep.parse_params(["radio.range_m=5,10", "radio.loss_probability=0,0.5,0.9"], None)
        self.assertEqual(grid, [("radio.range_m", ["5", "10"]), ("radio.loss_probability", ["0", "0.5", "0.9"])])
        self.assertEqual(sweep.parse_params(["radio.range_m"], "1,2"), [("radio.range_m", ["1", "2"])])
        point = (("radio.range_m", "5"), ("fusion.method", "a b/c"))
        self.assertEqual(sweep.run_name(point, 3), "radio.range_m=5_fusion.method=a-b-c_seed3-14df9cc5")
        self.assertEqual(sweep.point_flags(point, 3), ["--set", "radio.range_m=5", "--set", "fusion.method=a b/c",
                                                       "--set", "seed=3"])
        for params, values, why in ((["x=1", "x=2"], None, "swept twice"), (["x="], None, "no values"),
                                    (["x=1,1"], None, "given twice"), (["x=1", "y=2"], "3", "--values goes with"),
                                    (["=1"], None, "expected KEY=V1")):
            with self.assertRaisesRegex(RunError, why):
                sweep.parse_params(params, values)


class SweepBoundsTest(unittest.TestCase):
    # R3: a 1000 x 1000 grid printed nothing for minutes (every point checked by its own
    # `mapmesh-feeder --check` first, no cap); values that differ only in characters a folder
    # name drops (`a b`, `a/b`, `a+b`) shared one folder and two of three runs failed.
    def test_values_a_folder_name_cannot_hold_keep_their_own_folders(self):
        names = {sweep.run_name((("fusion.method", v),), 1) for v in ("a b", "a/b", "a+b", "a-b")}
        self.assertEqual(len(names), 4, names)
        self.assertIn("fusion.method=a-b_seed1", names)  # a name that needs nothing keeps its form
        self.assertTrue(all(sweep.re.fullmatch(r"[A-Za-z0-9._=-]+", n) for n in names), names)
        self.assertEqual(sweep.run_name((("x", "a b"),), 1), sweep.run_name((("x", "a b"),), 1))

    def test_a_grid_beyond_the_bound_is_refused_in_one_line_before_any_check(self):
        parser = swarm.build_parser()
        values = ",".join(str(i) for i in range(1000))
        args = parser.parse_args(["sweep", "/nonexistent.yaml", "--param", f"a={values}", "--param", f"b={values}",
                                  "--out", "/tmp/never"])
        with self.assertRaises(RunError) as e:
            sweep.cmd_sweep(args)
        self.assertEqual(str(e.exception), f"--param: 1000 a x 1000 b is 1000000 runs; a sweep runs at most "
                                           f"{sweep.MAX_RUNS}: split the grid")
        self.assertEqual(e.exception.exit_code, 2)

    def test_each_point_is_checked_once_with_progress(self):
        parser = swarm.build_parser()
        args = parser.parse_args(["sweep", "s.yaml", "--param", "a=1,2", "--seeds", "1,2,3", "--out", "/tmp/x"])
        plan = [((("a", v),), s) for v in ("1", "2") for s in (1, 2, 3)]
        checked, shown = [], []
        real = sweep.SwarmRun.check_plan
        sweep.SwarmRun.check_plan = lambda run: checked.append(run.args.set)
        try:
            sweep.check_all(args, plan, sweep.Path("/tmp/x"), progress=lambda d, t: shown.append((d, t)), every_s=0)
        finally:
            sweep.SwarmRun.check_plan = real
        self.assertEqual(checked, [["a=1", "seed=1"], ["a=2", "seed=1"]])
        self.assertEqual(shown, [(1, 2), (2, 2)])

    def test_a_folder_holding_an_earlier_sweep_is_refused_and_kept(self):
        # U1: a sweep run again into the same --out replaced the earlier runs silently, where
        # `swarm run` refuses. Refused in one line before any check, nothing touched; with
        # --force the points are checked first, and a point that fails its check leaves the
        # earlier sweep as it was.
        parser = swarm.build_parser()
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp)
            (out / "sweep.csv").write_text("earlier\n")
            (out / "runs" / "radio.range_m=5_seed1").mkdir(parents=True)
            argv = ["sweep", "/nonexistent.yaml", "--param", "radio.range_m=5", "--out", str(out)]
            with self.assertRaises(RunError) as e:
                sweep.cmd_sweep(parser.parse_args(argv))
            self.assertEqual(str(e.exception), f"--out {out}: holds an earlier sweep (sweep.csv, runs/ with 1 run); "
                                               "choose another folder, add --resume to run only its "
                                               "missing runs, or --force to replace it")
            self.assertEqual(e.exception.exit_code, 2)
            with self.assertRaises(RunError) as e:
                sweep.cmd_sweep(parser.parse_args(argv + ["--force"]))
            self.assertIn("/nonexistent.yaml", str(e.exception))
            self.assertEqual((out / "sweep.csv").read_text(), "earlier\n")
            self.assertTrue((out / "runs" / "radio.range_m=5_seed1").is_dir())
            self.assertEqual(sweep.earlier_sweep(out / "runs" / "radio.range_m=5_seed1"), [])

    def test_resume_refuses_another_sweep_and_force_with_it(self):
        parser = swarm.build_parser()
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp)
            (out / "sweep.csv").write_text("earlier\n")
            argv = ["sweep", str(REPO / "scenarios" / "park4.yaml"), "--param", "radio.range_m=5,10", "--out", str(out)]
            with self.assertRaisesRegex(RunError, "holds no sweep.json"):
                sweep.cmd_sweep(parser.parse_args(argv + ["--resume"]))
            args = parser.parse_args(argv)
            definition = sweep.sweep_definition(args, sweep.parse_params(args.param, None), [None])
            (out / "sweep.json").write_text(json.dumps(definition))
            other = argv[:3] + ["radio.range_m=5,20"] + argv[4:] + ["--resume"]
            with self.assertRaises(RunError) as e:
                sweep.cmd_sweep(parser.parse_args(other))
            self.assertEqual(str(e.exception), f'--resume: the sweep in {out} had another grid ([["radio.range_m", '
                                               '["5", "10"]]], now [["radio.range_m", ["5", "20"]]]); give the same, '
                                               'or --force to replace it')
            with self.assertRaisesRegex(RunError, "had another run options"):
                sweep.cmd_sweep(parser.parse_args(argv + ["--resume", "--kill", "2@10"]))
            with self.assertRaisesRegex(RunError, "give one"):
                sweep.cmd_sweep(parser.parse_args(argv + ["--resume", "--force"]))
            for metric, why in (("nope", "not a figure of sweep.csv"), ("gap_to_central", "needs the reference")):
                with self.assertRaisesRegex(RunError, why):
                    sweep.cmd_sweep(parser.parse_args(argv + ["--resume", "--no-reference", "--metric", metric]))
            self.assertEqual((out / "sweep.csv").read_text(), "earlier\n")


class SweepStatsTest(unittest.TestCase):
    # U1: the sweep plot drew a mean that one outlier (22x) pulled up, with a min-max band.
    def test_the_interval_holds_the_median_as_often_as_it_says(self):
        for n in range(1, 40):
            med, lo, hi, cover = sweep_stats.median_interval(list(range(n, 0, -1)))
            self.assertEqual(med, statistics.median(range(1, n + 1)))
            k = lo  # the values are 1..n: the k-th order statistic is k
            self.assertEqual(hi, n + 1 - k)
            # The coverage by its own sum: P(k <= B <= n - k), B ~ Binomial(n, 1/2).
            own = sum(sweep_stats.math.comb(n, i) for i in range(k, n - k + 1)) / 2 ** n
            self.assertAlmostEqual(cover, own, places=12)
            if n >= 6:
                self.assertGreaterEqual(cover, 0.95)
                wider = sum(sweep_stats.math.comb(n, i) for i in range(k + 1, n - k)) / 2 ** n
                self.assertLess(wider, 0.95, n)  # the narrowest interval with 95 %
            else:
                self.assertEqual((lo, hi), (1, n))  # too few: the whole range, its coverage said
                self.assertAlmostEqual(cover, 1 - 2 ** (1 - n))
        # Seeded draws of a skewed law whose median is known (exponential: ln 2): the interval
        # holds it as often as its coverage says (within four standard errors).
        rng = random.Random(20261204)
        for n in (3, 7, 12, 25):
            trials, hits, cover = 3000, 0, None
            for _ in range(trials):
                _, lo, hi, cover = sweep_stats.median_interval([rng.expovariate(1.0) for _ in range(n)])
                hits += lo <= sweep_stats.math.log(2) <= hi
            se = (cover * (1 - cover) / trials) ** 0.5
            self.assertLess(abs(hits / trials - cover), 4 * se + 1e-9, (n, hits / trials, cover))

    def test_each_run_is_one_figure_per_group_and_killed_agents_are_apart(self):
        rows = [{"alive": "1", "g": "1.0"}, {"alive": "1", "g": "22"}, {"alive": "1", "g": "1.2"},
                {"alive": "0", "g": "5"}, {"alive": "1", "g": ""}]
        self.assertEqual(sweep_stats.run_figures(rows, "g"), {"alive": (1.2, 3), "killed": (5.0, 1)})
        runs = [("p", 1, rows), ("p", 2, [{"alive": "1", "g": "2"}]), ("q", 1, [{"alive": "0", "g": "nan"}])]
        out = sweep_stats.summarise(runs, "g")
        self.assertEqual([(p, g, s) for p, g, s, _ in out], [("p", "alive", [(1, 1.2), (2, 2.0)]),
                                                             ("p", "killed", [(1, 5.0)])])
        self.assertEqual(out[0][3][:3], (1.6, 1.2, 2.0))


class RunTableTest(unittest.TestCase):
    # U1: the printed table said gap_central / cov_global where sweep.csv and summary.json say
    # gap_to_central / coverage_global.
    def test_the_table_names_are_the_csv_names_and_fit_a_terminal_at_any_swarm(self):
        rng = random.Random(7)
        for n in (1, 4, 64, 256):
            agents = [{"id": i, "alive_at_end": i % 5 != 0, "exit_code": 0 if i % 5 else None, "restarts": i % 3,
                       "local": {"landmarks": rng.randrange(500), "rmse_aligned_m": rng.random(),
                                 "rmse_m": 10 * rng.random()},
                       "global": {"landmarks": rng.randrange(1000), "rmse_aligned_m": rng.random(), "rmse_m": None,
                                  "coverage": rng.random()},
                       "gap_to_central": 50 * rng.random(), "gap_to_own_batch": None,
                       "peers_aligned": list(range(rng.randrange(n))), "maps_received": rng.randrange(10 ** 6),
                       "bytes_sent": rng.randrange(10 ** 9), "bytes_received": rng.randrange(10 ** 9),
                       "cpu_s": 100 * rng.random(), "max_rss_mb": 300 * rng.random()} for i in range(1, n + 1)]
            summary = {"scenario": "s", "sim_duration_s": 1.0, "wall_s": 1.0, "real_time_factor": 1.0, "agents": agents}
            lines = columns.format_table(summary).splitlines()[1:]
            self.assertLessEqual(max(map(len, lines)), columns.TABLE_WIDTH)
            blocks = "\n".join(lines).split("\n\n")
            headers = [b.splitlines()[0].split() for b in blocks]
            self.assertTrue(all(h[0] == "agent" for h in headers))
            names = [name for h in headers for name in h[1:]]
            self.assertEqual(["agent"] + names, [c.name for c in columns.TABLE_COLUMNS])
            csv_names = set(columns.SWEEP_HEADER)
            for c in columns.TABLE_COLUMNS:  # sweep.csv's name, else summary.json's key
                self.assertTrue(c.name in csv_names or c.name == c.key, c.key)
            for b in blocks:
                rows = [r.split() for r in b.splitlines()[1:]]
                self.assertEqual([int(r[0]) for r in rows], [a["id"] for a in agents])
            cells = {name: [r.split()[i] for r in b.splitlines()[1:]]
                     for b in blocks for i, name in enumerate(b.splitlines()[0].split())}
            self.assertEqual(cells["gap_to_central"], [f"{a['gap_to_central']:.2f}" for a in agents])
            self.assertEqual(cells["rmse_global_m"], ["-"] * n)
            self.assertEqual(cells["peers_aligned"], [str(len(a["peers_aligned"])) for a in agents])
            self.assertEqual(cells["exit_code"], ["0" if a["exit_code"] == 0 else "-" for a in agents])


if __name__ == "__main__":
    unittest.main()
