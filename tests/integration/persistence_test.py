"""Where a run keeps its files (R2): a disk that fills up during a run, one that stays full, and
two runs started on one folder. Real processes through scripts/swarm; the full disk is a small
tmpfs (these tests skip, saying why, where one cannot be mounted)."""

import json
import subprocess
import tempfile
import time
import unittest
from pathlib import Path

from swarm_test import REPO, SWARM, SwarmCase, leftover_processes

PARK4 = REPO / "scenarios" / "park4.yaml"


def why_no_tmpfs():
    d = tempfile.mkdtemp(prefix="mapmesh_tmpfs_probe_")
    try:
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", d], capture_output=True, text=True)
        if r.returncode != 0:
            return "cannot mount a tmpfs: " + (r.stderr.strip() or f"mount exit code {r.returncode}")
        subprocess.run(["umount", d], check=True)
        return None
    except OSError as e:
        return f"cannot mount a tmpfs: {e}"
    finally:
        Path(d).rmdir()


WHY_NOT = why_no_tmpfs()


def tmp_files(root):
    return [str(p) for p in Path(root).rglob("*.tmp")]


@unittest.skipIf(WHY_NOT, WHY_NOT or "")
class DiskFullTest(SwarmCase):
    def small_disk(self, size):
        """A tmpfs of `size` (mount's syntax), unmounted at the end; self.out goes in it."""
        mnt = Path(tempfile.mkdtemp(prefix="mapmesh_full_"))
        subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)], check=True)
        self.addCleanup(lambda: (subprocess.run(["umount", "-l", str(mnt)]), mnt.rmdir()))
        self.out = mnt / "run"
        return mnt

    def test_a_disk_full_for_a_while_stops_snapshots_not_mapping(self):
        # Real time (10 s of wall time), so that the disk can fill up while the agents map.
        realtime = ["--no-report", "--no-reference", "--pace", "realtime", "--rate", "20", "--timeout", "200"]
        clean = self.out.parent / "clean"
        r = subprocess.run(SWARM + ["run", str(PARK4), "--out", str(clean)] + realtime, capture_output=True,
                           text=True, timeout=240)
        self.assertEqual(r.returncode, 0, r.stderr)
        ref = {a["id"]: a for a in json.loads((clean / "summary.json").read_text())["agents"]}
        mnt = self.small_disk("64m")
        p = subprocess.Popen(SWARM + ["run", str(PARK4), "--out", str(self.out)] + realtime,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            # Once every agent has written a checkpoint, the disk is full for 3 s.
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and not all(
                    (self.out / f"agent_{i}" / "checkpoint.json").exists() for i in range(1, 5)):
                time.sleep(0.05)
            filler = mnt / "filler"
            with open(filler, "wb") as f:
                try:
                    while True:
                        f.write(b"\0" * (1 << 16))
                        f.flush()
                except OSError:
                    pass
            full_at = time.monotonic()
            time.sleep(3.0)
            filler.unlink()
            out, err = p.communicate(timeout=200)
        finally:
            if p.poll() is None:
                p.kill()
        self.assertLess(full_at - deadline + 60, 9.0, "the run was nearly over before the disk filled up")
        self.assertEqual(p.returncode, 0, out + err)
        self.assertEqual(tmp_files(self.out), [])
        for a in self.summary()["agents"]:
            with self.subTest(agent=a["id"]):
                stats = json.loads((self.out / f"agent_{a['id']}" / "stats.json").read_text())
                outputs = stats["outputs"]
                # Each agent wrote at least once a second: each met the full disk, once.
                self.assertGreater(outputs["write_failures"], 0)
                self.assertIsNotNone(outputs["stopped_at"])
                self.assertIn("No space left on device", outputs["reason"])
                self.assertEqual(a["outputs"], outputs)
                # It kept mapping to the end, and its final outputs were written once there was room.
                self.assertEqual(a["exit_code"], 0)
                self.assertTrue(stats["final"])
                self.assertEqual(a["odom_processed"], a["odom_sent"], a)
                self.assertGreaterEqual(a["local"]["landmarks"], 0.9 * ref[a["id"]]["local"]["landmarks"])
                self.assertGreaterEqual(a["global"]["coverage"], 0.9 * ref[a["id"]]["global"]["coverage"])
        self.assertIn("snapshots and checkpoints stopped at a failed write (", err)

    def test_a_disk_that_stays_full_is_named_as_the_cause(self):
        self.small_disk("1m")
        r = self.swarm(PARK4, "--no-report", "--no-reference")
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        last = r.stderr.strip().splitlines()[-1]
        self.assertTrue(last.startswith("swarm: disk full: "), last)
        self.assertIn("agents 1, 2, 3, 4 could not write their outputs", last)
        self.assertNotIn("Traceback", r.stderr)
        self.assertEqual(tmp_files(self.out), [])
        self.assertEqual(leftover_processes(str(self.out)), [])


class RunFolderTest(SwarmCase):
    def test_a_second_run_on_a_folder_in_use_is_refused_in_one_line(self):
        first = subprocess.Popen(SWARM + ["run", str(PARK4), "--out", str(self.out), "--no-report", "--no-reference",
                                          "--pace", "realtime", "--rate", "10", "--timeout", "200"],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and len(leftover_processes(str(self.out))) < 5:
                time.sleep(0.1)
            second = self.swarm(PARK4, "--no-report", "--no-reference")
            out, err = first.communicate(timeout=200)
        finally:
            if first.poll() is None:
                first.kill()
        self.assertEqual(second.returncode, 2, second.stdout + second.stderr)
        self.assertEqual(second.stdout, "")
        lines = second.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, second.stderr)
        self.assertIn(f"another run (pid {first.pid}) is using this folder", lines[0])
        # The first run went on undisturbed, and the folder holds it alone.
        self.assertEqual(first.returncode, 0, out + err)
        summary = self.summary()
        self.assertEqual(sorted(a["id"] for a in summary["agents"]), [1, 2, 3, 4])
        self.assertTrue(all(a["exit_code"] == 0 for a in summary["agents"]))


if __name__ == "__main__":
    unittest.main()
