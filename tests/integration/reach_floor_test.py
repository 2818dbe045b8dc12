"""scripts/reach-floor: its help, and a one-line error for what it cannot read (its figures rest
on mapmesh/reached.py could_reach_until, tested in reached_test, and on the reference and
scoring tools that swarm run uses).

Run: cd tests/integration && /usr/bin/python3 -m unittest reach_floor_test
"""

import json
import subprocess
import tempfile
import unittest
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SCRIPT = REPO / "scripts" / "reach-floor"


class ReachFloorTest(unittest.TestCase):
    def test_help_and_bad_arguments_are_one_line(self):
        h = subprocess.run(["/usr/bin/python3", str(SCRIPT), "--help"], capture_output=True, text=True, timeout=60)
        self.assertEqual(h.returncode, 0)
        self.assertIn("Usage", h.stdout)
        self.assertIn("could_reach", h.stdout)
        with tempfile.TemporaryDirectory(prefix="mapmesh_reach_") as tmp:
            no_radio = Path(tmp) / "run"
            no_radio.mkdir()
            (no_radio / "summary.json").write_text(json.dumps({"agents": []}))
            (no_radio / "truth.json").write_text(json.dumps({"robots": [{"id": 1, "trajectory": [[0, 0, 0, 0]]}]}))
            (no_radio / "scenario.yaml").write_text("name: x\n")
            (no_radio / "run.json").write_text(json.dumps({"argv": []}))
            for args in ([], ["/nonexistent"], [tmp + "/empty_folder_that_is_not_there"], [str(no_radio)],
                         ["--bogus", str(no_radio)]):
                r = subprocess.run(["/usr/bin/python3", str(SCRIPT)] + args, capture_output=True, text=True, timeout=60)
                self.assertNotEqual(r.returncode, 0, args)
                self.assertEqual(len(r.stderr.strip().splitlines()), 1, (args, r.stderr))


if __name__ == "__main__":
    unittest.main()
