"""A2: the scripts' one submap decoder (scripts/mapmesh/submap_codec.py) against the layout
common/map/submap_codec.h documents, packed here on its own, and against the submaps a real run's
agents wrote to their checkpoints; and what is not a submap refused in one line."""

import json
import struct
import subprocess
import sys
import tempfile
import unittest
from pathlib import Path

from swarm_test import SWARM, REPO

sys.path.insert(0, str(REPO / "scripts"))
from mapmesh import reached, submap_codec  # noqa: E402


def pack(robot, incarnation, index, opened, closed, keys, x, lower, magic=b"MS", version=1):
    """A submap laid out as submap_codec.h says, by this test's own code."""
    out = struct.pack("<2sBBIIIddI", magic, version, 0, robot, incarnation, index, opened, closed, len(keys))
    out += struct.pack(f"<{len(keys)}I", *keys) + struct.pack(f"<{len(x)}d", *x)
    for r, row in enumerate(lower):
        out += struct.pack(f"<{r + 1}f", *row[: r + 1])
    return out


class SubmapCodecTest(unittest.TestCase):
    def test_a_packed_submap_reads_back_field_by_field(self):
        keys = [7, 3]
        x = [1.0, -2.0, 0.5, 3.0, 4.0, -5.0, 6.0]
        lower = [[0.25 * (c + 1) for c in range(r)] + [0.5 + r] for r in range(7)]  # diagonal last in each row
        raw = pack(4, 2, 9, 10.5, 20.25, keys, x, lower)
        self.assertEqual(len(raw), submap_codec.size(2))
        s = submap_codec.decode(raw)
        self.assertEqual((s.robot, s.incarnation, s.index, s.opened_s, s.closed_s), (4, 2, 9, 10.5, 20.25))
        self.assertEqual(s.keys, (7, 3))
        self.assertEqual(s.x, tuple(x))
        self.assertEqual([list(row) for row in s.lower], lower)  # f32 values exact at these
        cov = s.covariance()
        for r in range(7):
            for c in range(7):
                self.assertAlmostEqual(cov[r][c], sum(lower[r][k] * lower[c][k] for k in range(min(r, c) + 1)))
        self.assertEqual(submap_codec.header(raw), (4, 2, 9, 10.5, 20.25, 2))

    def test_what_is_not_a_submap_is_refused_in_one_line(self):
        good = pack(1, 1, 0, 0.0, 1.0, [5], [0.0] * 5, [[1.0] * (r + 1) for r in range(5)])
        for raw, why in ((good[:20], "at least 36 bytes"), (b"XX" + good[2:], "not a submap"),
                         (good[:2] + b"\x02" + good[3:], "version 2"), (good + b"\x00", "is 140 bytes, got 141"),
                         (good[:-1], "got 139"),
                         (pack(1, 1, 0, 0.0, 1.0, list(range(501)), [], []), "501 landmarks")):
            with self.assertRaisesRegex(ValueError, why):
                submap_codec.decode(raw)
        with self.assertRaisesRegex(ValueError, "not base64"):
            submap_codec.decode_base64("@@@")

    def test_the_submaps_of_a_real_run_read_back(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_submaps_") as tmp:
            out = Path(tmp) / "run"
            r = subprocess.run(SWARM + ["run", str(REPO / "scenarios" / "thesis_circle_pair.yaml"), "--set",
                                        "agent.slam=cekf_submaps", "--set", "duration_s=80", "--no-reference",
                                        "--no-report", "--quiet", "--out", str(out)],
                               capture_output=True, text=True, timeout=300)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            decoded = 0
            for agent in sorted(out.glob("agent_*")):
                checkpoint = json.loads((agent / "checkpoint.json").read_text())
                stats = json.loads((agent / "stats.json").read_text())
                latest = {}
                for text in checkpoint["submaps"]:
                    s = submap_codec.decode_base64(text)
                    decoded += 1
                    self.assertEqual(len(s.x), 3 + 2 * len(s.keys))
                    self.assertEqual(len(set(s.keys)), len(s.keys))
                    self.assertLessEqual(s.opened_s, s.closed_s)
                    self.assertTrue(all(row[-1] > 0 for row in s.lower))  # L's diagonal: p positive definite
                    self.assertEqual(reached.submap_closed(text), (s.robot, s.closed_s))
                    latest[s.robot] = max(latest.get(s.robot, 0.0), s.closed_s)
                # The agent's own account of each chain it holds: the latest closing time.
                self.assertEqual(latest, {c["robot"]: c["closed_until"] for c in stats["submaps"]["chains"]})
            self.assertGreater(decoded, 4)


if __name__ == "__main__":
    unittest.main()
