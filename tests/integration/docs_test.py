"""docs/OUTPUTS.md against a real run: every field of summary.json's objects (and run.json's) is listed there, and
every field listed there is in the run's summary (but those marked *with ...*, which only some
options write).

Run: cd tests/integration && /usr/bin/python3 -m unittest docs_test
"""

import json
import re
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SWARM = [sys.executable, str(REPO / "scripts" / "swarm")]
OUTPUTS = REPO / "docs" / "OUTPUTS.md"


def documented():
    """{section title: (fields, conditional fields)} from the tables of docs/OUTPUTS.md: the
    backticked names of each row's first cell; a row whose description starts with *with is
    conditional."""
    out, title = {}, None
    for line in OUTPUTS.read_text().splitlines():
        if line.startswith("## "):
            title = line[3:].strip()
            out[title] = (set(), set())
        elif title and line.startswith("| `"):
            cells = line.split("|")
            names = set(re.findall(r"`([^`]+)`", cells[1]))
            out[title][1 if cells[2].strip().startswith("*with") else 0].update(names)
    return out


class OutputsDocTest(unittest.TestCase):
    def test_every_summary_field_is_documented_and_every_documented_field_is_written(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_docs_") as tmp:
            out = Path(tmp) / "run"
            r = subprocess.run(SWARM + ["run", str(REPO / "scenarios" / "line3.yaml"), "--out", str(out),
                                        "--set", "duration_s=30", "--kill", "2@10", "--restart", "2@20",
                                        "--no-report", "--quiet", "--timeout", "200"],
                               capture_output=True, text=True, timeout=240)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            s = json.loads((out / "summary.json").read_text())
            made = json.loads((out / "run.json").read_text())
        docs = documented()
        ref = s["reference"]
        self.assertTrue(ref["available"], ref)
        objects = {
            "The run": [s],
            "An agent (`agents[]`)": s["agents"],
            "A map against the truth (`agents[].local`, `agents[].global`)":
                [a[k] for a in s["agents"] for k in ("local", "global")],
            "The limit (`reference`)": [ref],
            "A reference map (`reference.central`, `.central_known_starts`, `.known_pose`, `.own_batch[]`, "
            "`.own_known_pose[]`)":
                [ref["central"], ref["central_known_starts"], ref["known_pose"]] + list(ref["own_batch"].values())
                + list(ref["own_known_pose"].values()),
            "How the run was made (`run.json`)": [made],
        }
        self.assertEqual(sorted(docs), sorted(objects))
        for title, records in objects.items():
            fields, conditional = docs[title]
            written = set().union(*(set(r) for r in records))
            self.assertEqual(sorted(written - fields - conditional), [], f"{title}: not in docs/OUTPUTS.md")
            self.assertEqual(sorted(fields - written), [], f"{title}: documented but not written")


if __name__ == "__main__":
    unittest.main()
