"""X1: how `swarm sweep` turns its arguments into runs (scripts/mapmesh/sweep.py), without
running any: the grid, and every run option given to each run as `swarm run` takes it."""

import sys
import unittest
from importlib.machinery import SourceFileLoader

from swarm_test import REPO

sys.path.insert(0, str(REPO / "scripts"))
from mapmesh import sweep  # noqa: E402
from mapmesh.run import RunError  # noqa: E402

swarm = SourceFileLoader("swarm_cli", str(REPO / "scripts" / "swarm")).load_module()


class SweepPlanTest(unittest.TestCase):
    def test_every_run_option_reaches_each_run_as_swarm_run_takes_it(self):
        parser = swarm.build_parser()
        argv = ["sweep", "s.yaml", "--param", "radio.range_m=5,10", "--out", "/tmp/x", "--agents", "6",
                "--kill", "2@30", "--restart", "2@40", "--pause", "3@10:2", "--set", "duration_s=60",
                "--pace", "realtime", "--rate", "20", "--timeout", "99", "--inject", "all", "--inject-period", "0.5",
                "--secure", "--inject-identity", "agent2", "--hosts", "netns", "--net-loss", "5", "--net-rate", "10",
                "--no-reference"]
        args = parser.parse_args(argv)
        flags = sweep.option_flags(args, args.run_defaults)
        # `swarm run` parses them back to the same options.
        run = args.run_parser.parse_args(["s.yaml", "--out", "/tmp/y"] + flags)
        for name in ("agents", "kill", "restart", "pause", "set", "pace", "rate", "timeout", "inject", "inject_period",
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
        self.assertEqual(sweep.run_name(point, 3), "radio.range_m=5_fusion.method=a-b-c_seed3")
        self.assertEqual(sweep.point_flags(point, 3), ["--set", "radio.range_m=5", "--set", "fusion.method=a b/c",
                                                       "--set", "seed=3"])
        for params, values, why in ((["x=1", "x=2"], None, "swept twice"), (["x="], None, "no values"),
                                    (["x=1,1"], None, "given twice"), (["x=1", "y=2"], "3", "--values goes with"),
                                    (["=1"], None, "expected KEY=V1")):
            with self.assertRaisesRegex(RunError, why):
                sweep.parse_params(params, values)


if __name__ == "__main__":
    unittest.main()
