"""scripts/limit-table: runs each configuration once per seed with the --set overrides given, and
tabulates them (docs/EXPERIMENTS.md "The limit", "Maps at the limit"); kept runs are reused.

Run: cd tests/integration && /usr/bin/python3 -m unittest limit_table_test
"""

import json
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCRIPT = [sys.executable, str(REPO / "scripts" / "limit-table")]


class LimitTableTest(unittest.TestCase):
    def test_one_seed_with_an_override_then_the_table_alone(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "lt"
            args = ["--out", str(out), "--only", "circle", "--seeds", "3", "--set", "agent.slam=cekf_submaps"]
            r = subprocess.run(SCRIPT + args, capture_output=True, text=True, timeout=300)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            rows = [line for line in r.stdout.splitlines() if line.startswith("| circle |")]
            self.assertEqual(len(rows), 1, r.stdout)
            cells = [c.strip() for c in rows[0].strip("|").split("|")]
            self.assertEqual(len(cells), 14, rows[0])
            self.assertEqual(cells[1], "1")  # one run
            # The fair optimum, the known-starts one, their ratio, known poses, global, and the gaps to
            # both optima and to what reached each agent: all measured.
            for cell in cells[2:10]:
                self.assertNotIn("–", cell, rows[0])
            # The ratio (of unrounded figures) within what the printed ones' rounding allows.
            fair, starts = float(cells[2].split()[0]), float(cells[3].split()[0])
            ratio = float(cells[4].split()[0])
            self.assertGreaterEqual(ratio, (fair - 0.0005) / (starts + 0.0005) - 0.005, rows[0])
            self.assertLessEqual(ratio, (fair + 0.0005) / (starts - 0.0005) + 0.005, rows[0])
            run = json.loads((out / "circle" / "seed_3" / "run.json").read_text())
            self.assertIn("agent.slam=cekf_submaps", json.dumps(run))
            self.assertIn("seed=3", json.dumps(run))
            # Kept runs are tabulated again without running.
            again = subprocess.run(SCRIPT + args + ["--table-only"], capture_output=True, text=True, timeout=60)
            self.assertEqual(again.returncode, 0, again.stderr)
            self.assertIn(rows[0], again.stdout)

    def test_bad_arguments_are_one_line(self):
        r = subprocess.run(SCRIPT + ["--out", "/tmp/x", "--only", "nowhere"], capture_output=True, text=True,
                           timeout=60)
        self.assertNotEqual(r.returncode, 0)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("nowhere", r.stderr)


if __name__ == "__main__":
    unittest.main()
