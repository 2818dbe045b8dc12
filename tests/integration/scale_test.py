"""Swarm scale (issue S1): the DDS configuration a run uses and its limit, nothing leaving the
machine, and `swarm bench-scale` writing its CSV and plot.

Run: cd tests/integration && /usr/bin/python3 -m unittest scale_test
"""

import csv
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
import unittest
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SWARM = [sys.executable, str(REPO / "scripts" / "swarm")]
PARK4 = REPO / "scenarios" / "park4.yaml"
UNICAST = REPO / "config" / "cyclonedds-loopback-unicast.xml"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
sys.path.insert(0, str(REPO / "scripts"))
from mapmesh import ddsconfig  # noqa: E402
from mapmesh.run_error import RunError  # noqa: E402
from mapmesh.scale import HEADER, scale_row  # noqa: E402


def env_without_dds_uri():
    env = dict(os.environ)
    env.pop("CYCLONEDDS_URI", None)
    return env


class DdsConfigTest(unittest.TestCase):
    def test_the_shipped_configs_limits(self):
        self.assertEqual(ddsconfig.participant_limit(f"file://{REPO / 'config' / 'cyclonedds-loopback.xml'}"),
                         (None, None))
        self.assertEqual(ddsconfig.participant_limit(f"file://{UNICAST}"), (61, "Discovery/MaxAutoParticipantIndex 60"))
        inline = "<CycloneDDS><Domain><Discovery><ParticipantIndex>auto</ParticipantIndex></Discovery></Domain>" \
                 "</CycloneDDS>"
        self.assertEqual(ddsconfig.participant_limit(inline)[0], 10)  # Cyclone's default MaxAutoParticipantIndex 9

    def test_fallback_to_unicast_where_multicast_on_lo_fails(self):
        changes, note = ddsconfig.choose(40, env={}, probe=lambda: False)
        self.assertEqual(changes, {"CYCLONEDDS_URI": f"file://{UNICAST}"})
        self.assertIn("unicast", note)
        self.assertEqual(ddsconfig.choose(200, env={}, probe=lambda: True), ({}, None))
        with self.assertRaises(RunError) as e:
            ddsconfig.choose(65, env={}, probe=lambda: False)
        self.assertIn("MaxAutoParticipantIndex 60", str(e.exception))

    def test_a_large_run_on_the_default_config_gets_longer_participant_leases(self):
        with tempfile.TemporaryDirectory() as d:
            self.assertEqual(ddsconfig.choose(ddsconfig.LARGE_SWARM, env={}, probe=lambda: True, run_dir=d),
                             ({}, None))
            changes, note = ddsconfig.choose(ddsconfig.LARGE_SWARM + 1, env={}, probe=lambda: True, run_dir=d)
            path = Path(d) / "cyclonedds.xml"
            self.assertEqual(changes, {"CYCLONEDDS_URI": f"file://{path}"})
            self.assertIn(ddsconfig.LARGE_SWARM_LEASE, note)
            text = path.read_text()
            self.assertIn(f"<LeaseDuration>{ddsconfig.LARGE_SWARM_LEASE}</LeaseDuration>", text)
            self.assertEqual(text.replace(f"<LeaseDuration>{ddsconfig.LARGE_SWARM_LEASE}</LeaseDuration>",
                                          "<LeaseDuration>1s</LeaseDuration>"), ddsconfig.DEFAULT.read_text())
            self.assertEqual(ddsconfig.participant_limit(changes["CYCLONEDDS_URI"]), (None, None))
            # A configuration the user chose is left alone.
            self.assertEqual(ddsconfig.choose(200, env={"CYCLONEDDS_URI": changes["CYCLONEDDS_URI"]}, run_dir=d),
                             ({}, None))

    def test_a_run_larger_than_the_configs_limit_is_one_line_naming_it(self):
        env = env_without_dds_uri()
        env["CYCLONEDDS_URI"] = f"file://{UNICAST}"
        with tempfile.TemporaryDirectory() as d:
            t0 = time.monotonic()
            r = subprocess.run(SWARM + ["run", str(PARK4), "--agents", "64", "--out", d, "--quiet"], env=env,
                               capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 2, r.stderr)
            lines = r.stderr.strip().splitlines()
            self.assertEqual(len(lines), 1, r.stderr)
            self.assertIn("65 DDS processes", lines[0])
            self.assertIn("MaxAutoParticipantIndex 60", lines[0])
            self.assertLess(time.monotonic() - t0, 30)
            self.assertFalse(list(Path(d).glob("agent_*")), "no agent was started")

    def test_multicast_on_loopback_works_here(self):
        # The default config relies on it; where it fails, runs fall back (tested above).
        if not ddsconfig.loopback_multicast_works():
            self.skipTest("multicast on lo does not work on this host: runs use the unicast fallback")


class LoopbackOnlyTest(unittest.TestCase):
    """Captures every frame on every interface during a run: RTPS (DDS) packets appear on lo and
    nowhere else."""

    def test_nothing_leaves_the_machine(self):
        if os.geteuid() != 0:
            self.skipTest("capturing packets needs root")
        sockets = []
        for _, name in socket.if_nameindex():
            s = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.ntohs(0x0003))
            try:
                s.bind((name, 0))
            except OSError:
                s.close()
                continue
            s.settimeout(0.05)
            sockets.append((name, s))
        counts = {name: 0 for name, _ in sockets}
        stop = threading.Event()

        def capture(name, s):
            while not stop.is_set():
                try:
                    frame = s.recv(65535)
                except socket.timeout:
                    continue
                except OSError:
                    return  # the interface went down
                if b"RTPS" in frame:
                    counts[name] += 1

        threads = [threading.Thread(target=capture, args=item, daemon=True) for item in sockets]
        for t in threads:
            t.start()
        try:
            with tempfile.TemporaryDirectory() as d:
                r = subprocess.run(SWARM + ["run", str(PARK4), "--agents", "4", "--out", d, "--quiet", "--no-report"],
                                   env=env_without_dds_uri(), capture_output=True, text=True, timeout=120)
                self.assertEqual(r.returncode, 0, r.stderr)
        finally:
            stop.set()
            for t in threads:
                t.join()
            for _, s in sockets:
                s.close()
        self.assertGreater(counts.get("lo", 0), 100, counts)  # the capture sees the run's traffic ...
        self.assertEqual({k: v for k, v in counts.items() if k != "lo" and v}, {}, counts)  # ... only on lo


class BenchScaleTest(unittest.TestCase):
    def test_two_sizes_give_a_row_each_and_a_plot(self):
        with tempfile.TemporaryDirectory() as d:
            r = subprocess.run(SWARM + ["bench-scale", str(PARK4), "--sizes", "2,4", "--out", d,
                                        "--set", "duration_s=40"],
                               env=env_without_dds_uri(), capture_output=True, text=True, timeout=240)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            with open(Path(d) / "scale.csv", newline="") as f:
                rows = list(csv.DictReader(f))
            self.assertEqual([int(x["agents"]) for x in rows], [2, 4])
            self.assertEqual(list(rows[0].keys()), HEADER)
            for row in rows:
                self.assertEqual(int(row["exit_0"]), int(row["agents"]))
                self.assertGreater(float(row["rtf"]), 0)
                self.assertGreater(float(row["cpu_per_agent_mean_s"]), 0)
                self.assertGreater(float(row["rss_per_agent_mean_mb"]), 1)
                self.assertGreater(float(row["bytes_per_landmark"]), 10)
            png = (Path(d) / "scale.png").read_bytes()
            self.assertEqual(png[:8], PNG_SIGNATURE)
            self.assertGreater(len(png), 20000)

    def test_bad_sizes_are_one_line(self):
        for sizes in ["8,x", "0", ""]:
            r = subprocess.run(SWARM + ["bench-scale", str(PARK4), "--sizes", sizes, "--out", "/nonexistent/x"],
                               capture_output=True, text=True, timeout=30)
            self.assertEqual(r.returncode, 2, sizes)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
            self.assertIn("--sizes", r.stderr)

    def test_false_alignments_are_counted_from_the_fit_errors(self):
        def agent(errors, exit_code=0, rmse_aligned=0.1, rmse=0.4):
            return {"exit_code": exit_code, "cpu_s": 2.0, "max_rss_mb": 10.0, "bytes_per_landmark": 16.0,
                    "peers_aligned": list(range(len(errors))),
                    "global": {"coverage": 0.5, "rmse_aligned_m": rmse_aligned, "rmse_m": rmse},
                    "alignment_errors": {str(i): e for i, e in enumerate(errors)}}
        good = {"trans_fit_m": 0.2, "rot_fit_rad": 0.01}
        far = {"trans_fit_m": 35.0, "rot_fit_rad": 0.01}
        turned = {"trans_fit_m": 0.3, "rot_fit_rad": 0.2}  # 11 degrees
        row = scale_row(2, {"wall_s": 10.0, "real_time_factor": 20.0,
                            "agents": [agent([good, far]),
                                       agent([turned, good, good, good], exit_code=1, rmse_aligned=0.2, rmse=None)]})
        self.assertEqual(row["false_alignments"], 2)
        self.assertEqual(row["alignments_scored"], 6)
        self.assertEqual(row["exit_0"], 1)
        self.assertEqual(row["peers_aligned_mean"], 3.0)
        self.assertAlmostEqual(row["cpu_per_agent_per_peer_s"], 2.0 / 3.0, places=3)
        # Map accuracy: the mean RMSE after a rigid fit first, the true-frame one beside it (nulls skipped).
        self.assertEqual(row["rmse_global_aligned_mean_m"], 0.15)
        self.assertEqual(row["rmse_global_mean_m"], 0.4)
        self.assertEqual(HEADER[HEADER.index("rmse_global_aligned_mean_m") + 1], "rmse_global_mean_m")


if __name__ == "__main__":
    unittest.main()
