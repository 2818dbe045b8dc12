"""scripts/lint-layers: the repository's own layers point down (the ctest cxx_layers runs it on
the tree), and the lint refuses each kind of include that points the wrong way, on a small tree
written here: a process's header, a higher layer, a layer it does not know, DDS or a clock in
the pure core; what transport/ may include it lets through."""

import subprocess
import tempfile
import unittest
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
LINT = REPO / "scripts" / "lint-layers"


def lint(root):
    return subprocess.run(["/usr/bin/python3", str(LINT), "--root", str(root)], capture_output=True, text=True,
                          timeout=60)


class LintLayersTest(unittest.TestCase):
    def tree(self, files):
        root = Path(self.enterContext(tempfile.TemporaryDirectory()))
        for name, text in files.items():
            path = root / "common" / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text)
        return root

    def test_each_include_that_points_the_wrong_way_is_refused_and_the_rest_pass(self):
        clean = {
            "check.h": "#pragma once\n",
            "types/a.h": '#include "common/check.h"\n#include <vector>\n',
            "slam/s.cc": '#include "common/slam/s.h"\n#include "common/map/m.h"\n#include <random>\n'
                         "std::mt19937_64 rng(1);  // seeded: allowed\n// std::random_device in a comment\n",
            "config/c.cc": '#include "common/options/o.h"\n',
            "transport/t.cc": '#include <dds/dds.h>\n#include "mapmesh.h"\n#include "common/map/m.h"\n'
                              "auto t = std::chrono::steady_clock::now();\n",
        }
        result = lint(self.tree(clean))
        self.assertEqual(result.returncode, 0, result.stdout + result.stderr)
        self.assertIn("5 files", result.stdout)

        wrong = {
            "config/scenario.h": '#include "agent/agent_options.h"\n',
            "map/limits.h": '#include "common/config/scenario_limits.h"\n',
            "slam/local.cc": '\n#include "common/merge/spatial.h"\n',
            "merge/fit.cc": '#  include "common/metrics/chi2.h"\n',
            "geometry/g.cc": '#include "common/newlayer/x.h"\n',
            "newlayer/x.h": "#pragma once\n",
            "metrics/clock.cc": "#include <chrono>\n",
            "merge/dds.cc": "#include <dds/dds.h>\n",
            "map/idl.cc": '#include "mapmesh.h"\n',
            "io/seed.cc": "std::random_device device;\n",
            "transport/up.cc": '#include "common/config/scenario.h"\n',
        }
        result = lint(self.tree({**clean, **wrong}))
        self.assertEqual(result.returncode, 1, result.stdout)
        lines = result.stdout.splitlines()
        expected = [
            "common/config/scenario.h:1: includes agent/agent_options.h",
            "common/geometry/g.cc:1: includes common/newlayer/x.h",
            "common/io/seed.cc:1: std::random_device",
            "common/map/idl.cc:1: includes mapmesh.h",
            "common/map/limits.h:1: includes common/config/scenario_limits.h: common/map/ may include only",
            "common/merge/dds.cc:1: includes dds/dds.h",
            "common/merge/fit.cc:1: includes common/metrics/chi2.h",
            "common/metrics/clock.cc:1: includes chrono",
            "common/newlayer/x.h:1: layer common/newlayer/ is not placed",
            "common/slam/local.cc:2: includes common/merge/spatial.h",
            "common/transport/up.cc:1: includes common/config/scenario.h",
        ]
        self.assertEqual(len(lines), len(expected), result.stdout)
        for line, start in zip(lines, expected):
            self.assertTrue(line.startswith(start), f"{line!r} does not start with {start!r}")
        self.assertIn("11 includes point the wrong way", result.stderr)

    def test_the_repository_passes_and_a_missing_root_is_one_line(self):
        result = lint(REPO)
        self.assertEqual(result.returncode, 0, result.stdout + result.stderr)
        self.assertEqual(subprocess.run(["grep", "-rn", '#include "agent', str(REPO / "common")],
                                        capture_output=True).returncode, 1, "common/ includes agent/")
        missing = lint(REPO / "no-such-dir")
        self.assertEqual(missing.returncode, 2)
        self.assertEqual(len(missing.stderr.strip().splitlines()), 1, missing.stderr)


if __name__ == "__main__":
    unittest.main()
