"""R3: the tools read run files within bounds. A run folder is only files anyone can edit:
`swarm export` on a run whose summary.json was /dev/zero read 3.8 GB and died with MemoryError;
an `agents` string, a NaN pose or an --out naming a file gave tracebacks and left a partial TUM
file; `--from` took `timeout: -5` and followed a scenario_copy outside the run's folder. Each
is one line naming the file and field now, with nothing partial left. No DDS, no run: the
folders are written here."""

import json
import os
import shutil
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

from swarm_test import REPO, SWARM

sys.path.insert(0, str(REPO / "scripts"))
from mapmesh import rundir  # noqa: E402


def swarm(*args):
    return subprocess.run(SWARM + [str(a) for a in args], capture_output=True, text=True, timeout=60)


class ToolBoundsCase(unittest.TestCase):
    def setUp(self):
        self.dir = Path(tempfile.mkdtemp(prefix="mapmesh_bounds_"))
        self.addCleanup(shutil.rmtree, self.dir, True)

    def one_line(self, r, code, *needles):
        self.assertEqual(r.returncode, code, r.stdout + r.stderr)
        lines = r.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, r.stderr)
        self.assertNotIn("Traceback", r.stderr)
        for n in needles:
            self.assertIn(n, lines[0])
        return lines[0]

    def a_run(self, summary, trajectory=None):
        run = self.dir / "run"
        (run / "agent_1").mkdir(parents=True)
        (run / "summary.json").write_text(summary if isinstance(summary, str) else json.dumps(summary))
        if trajectory is not None:
            (run / "agent_1" / "trajectory.json").write_text(trajectory)
        return run


class ReadJsonTest(ToolBoundsCase):
    def test_what_is_not_a_small_regular_json_file_is_refused_in_one_line(self):
        fifo = self.dir / "fifo.json"
        os.mkfifo(fifo)
        big = self.dir / "big.json"
        big.write_text("[" + "0," * 600 + "0]")
        bad = self.dir / "bad.json"
        bad.write_bytes(b'{"a": \xff}')
        broken = self.dir / "broken.json"
        broken.write_text('{"a": 1,\n "b": }')
        for path, why, limit in ((fifo, "not a regular file", None), (Path("/dev/zero"), "not a regular file", None),
                                 (big, "larger than the 0 MB", 1000), (bad, "not UTF-8", None),
                                 (broken, "line 2 column", None)):
            with self.subTest(path=path.name):
                with self.assertRaises(rundir.RunFileError) as e:
                    rundir.read_json(path, **({"max_bytes": limit} if limit else {}))
                self.assertIn(why, str(e.exception))
                self.assertTrue(str(e.exception).startswith(str(path)), str(e.exception))
                self.assertNotIn("\n", str(e.exception))
        self.assertEqual(rundir.read_json(big), [0] * 601)
        with self.assertRaises(FileNotFoundError):
            rundir.read_json(self.dir / "missing.json")


class ExportBoundsTest(ToolBoundsCase):
    def test_a_summary_that_is_dev_zero_is_refused_unread(self):
        run = self.dir / "run"
        run.mkdir()
        (run / "summary.json").symlink_to("/dev/zero")
        self.one_line(swarm("export", run), 1, "summary.json: unreadable (not a regular file)")

    def test_bad_content_is_one_line_naming_the_field_and_leaves_no_file(self):
        for summary, trajectory, field in (
                ({"agents": "1,2"}, None, "field agents: expected a list"),
                ({"agents": [{"id": "1"}]}, None, "field agents[0]: expected an object with an integer id"),
                ({"agents": [{"id": 1}]}, '{"poses": [[0, 0, 0, 0], [1, NaN, 0, 0]]}',
                 "trajectory.json: field poses: pose 1: not 4 finite numbers"),
                ({"agents": [{"id": 1}]}, '{"poses": [[0, 0, 0, 0], ["1", 0, 0, 0]]}',
                 "field poses: pose 1"),
                ({"agents": [{"id": 1}]}, '{"poses": 3}', "field poses: expected a list")):
            with self.subTest(field=field):
                shutil.rmtree(self.dir / "run", ignore_errors=True)
                run = self.a_run(summary, trajectory)
                self.one_line(swarm("export", run, "--tum"), 1, field)
                tum = run / "export" / "tum"
                self.assertEqual(sorted(p.name for p in tum.iterdir()) if tum.exists() else [], [])

    def test_an_out_that_is_a_file_is_refused_before_anything_is_written(self):
        run = self.a_run({"agents": [{"id": 1}]}, '{"poses": [[0, 0, 0, 0]]}')
        target = self.dir / "a_file"
        target.write_text("mine")
        self.one_line(swarm("export", run, "--out", target), 2, f"--out {target}: is a file, not a folder")
        self.assertEqual(target.read_text(), "mine")
        # And a good run exports.
        r = swarm("export", run, "--tum", "--out", self.dir / "ok")
        self.assertEqual(r.returncode, 0, r.stderr)
        self.assertTrue((self.dir / "ok" / "tum" / "agent_1.tum").is_file())


class FromBoundsTest(ToolBoundsCase):
    def run_json(self, **changes):
        scenario = REPO / "scenarios" / "park4.yaml"
        record = {"version": 1, "scenario_file": str(scenario), "scenario_copy": "scenario.yaml",
                  "scenario_sha256": "0" * 64, "options": {"timeout": 3600.0, "inject_period": 0.2}}
        for k, v in changes.items():
            if k == "options":
                record["options"].update(v)
            else:
                record[k] = v
        d = self.dir / "earlier"
        d.mkdir(exist_ok=True)
        shutil.copy(scenario, d / "scenario.yaml")
        (d / "run.json").write_text(json.dumps(record))
        return d / "run.json"

    def test_options_from_a_run_json_pass_the_command_lines_checks(self):
        for changes, why in (({"options": {"timeout": -5}}, "--timeout must be positive"),
                             ({"options": {"agents": 0}}, "--agents must be positive"),
                             ({"options": {"agents": "six"}}, "invalid int value: 'six'"),
                             ({"options": {"pace": "fast"}}, "invalid choice: 'fast'"),
                             ({"options": {"secure": "yes"}}, "secure: 'yes', expected true or false"),
                             ({"options": {"kill": [2]}}, "kill: [2], expected a list of strings"),
                             ({"scenario_copy": "../../etc/passwd"}, "is not a file name in the run's folder"),
                             ({"scenario_copy": "/tmp/x.yaml"}, "is not a file name in the run's folder")):
            with self.subTest(changes=changes):
                path = self.run_json(**changes)
                self.one_line(swarm("run", "--from", path, "--out", self.dir / "again"), 2, f"--from {path}", why)
                self.assertFalse((self.dir / "again").exists())

    def test_the_command_line_refuses_a_timeout_that_is_not_positive(self):
        r = swarm("run", REPO / "scenarios" / "park4.yaml", "--timeout", "-5", "--out", self.dir / "x")
        self.assertEqual(r.returncode, 2)
        self.assertIn("--timeout must be positive", r.stderr)
        self.assertFalse((self.dir / "x").exists())


if __name__ == "__main__":
    unittest.main()
