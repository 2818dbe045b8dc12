"""Checkpoints end to end: mapmesh-agent --resume refuses every bad checkpoint file with one
line and exit code 2, fast and small, before it touches DDS; a valid one is resumed; and the
launcher fails a run whose restarted agent fails. Every subprocess has a hard timeout."""

import json
import os
import signal
import subprocess
import sys
import tempfile
import time
import unittest
from pathlib import Path

from swarm_test import BIN, DATA, REPO, SWARM, SwarmCase

sys.path.insert(0, str(REPO / "scripts"))
from mapmesh.domain import DomainLease  # noqa: E402

SCENARIO = DATA / "three.yaml"
INCARNATION = 3  # the resuming process's; the checkpoints below hold incarnations 1 and 2


def landmark(i, x=None):
    return {"id": 10 + i, "signature": i, "x": 1.5 * i if x is None else x, "y": -0.5 * i, "cov": [0.1, 0.01, 0.2]}


def snapshot(robot, incarnation, n):
    return {"robot": robot, "incarnation": incarnation, "origin_stamp": 0.5, "processed_until": 9.5,
            "local": {"shape_sigma_m": 0.05, "landmarks": [landmark(i) for i in range(n)]},
            "global": {"shape_sigma_m": 0.05, "landmarks": [landmark(i) for i in range(n + 2)]}}


def good_checkpoint(robot=1):
    """What agent `robot`'s incarnation 2 writes, with incarnation 1 not yet re-merged."""
    c = snapshot(robot, 2, 6)
    c["earlier"] = [snapshot(robot, 1, 4)]
    return c


def deep_checkpoint(levels):
    """Incarnation entries nested `levels` deep in earlier[] (text, never built as a dict)."""
    entry = ('{"robot":1,"incarnation":1,"origin_stamp":0,"processed_until":0,'
             '"local":{"landmarks":[]},"global":{"landmarks":[]},"earlier":[')
    return entry * levels + "]}" * levels


def run_agent(out, *extra, timeout=5.0):
    """Runs mapmesh-agent --resume for robot 1 with its files in `out`; returns (exit code,
    stderr, wall seconds, max RSS in MB). Kills it and fails if it outlives `timeout`."""
    lease = DomainLease()
    try:
        cmd = [str(BIN / "mapmesh-agent"), "--scenario", str(SCENARIO), "--id", "1", "--domain", str(lease.id),
               "--out", str(out), "--incarnation", str(INCARNATION), "--resume"] + list(extra)
        with tempfile.TemporaryFile() as err:
            start = time.monotonic()
            p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
            while True:
                pid, status, usage = os.wait4(p.pid, os.WNOHANG)
                if pid == p.pid:
                    break
                if time.monotonic() - start > timeout:
                    p.kill()
                    os.wait4(p.pid, 0)
                    raise AssertionError(f"mapmesh-agent still running after {timeout} s: {cmd}")
                time.sleep(0.01)
            wall = time.monotonic() - start
            p.returncode = os.waitstatus_to_exitcode(status)
            err.seek(0)
            return p.returncode, err.read().decode(errors="replace"), wall, usage.ru_maxrss / 1024.0
    finally:
        lease.close()


class ResumeBadCheckpointTest(unittest.TestCase):
    """Each bad checkpoint: exit code 2, one stderr line "mapmesh-agent: PATH: reason", within
    5 s and 200 MB."""

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory(prefix="mapmesh_ckpt_")
        self.out = Path(self.tmp.name) / "agent_1"
        self.out.mkdir()
        self.path = self.out / "checkpoint.json"

    def tearDown(self):
        self.tmp.cleanup()

    def refused(self, reason):
        code, err, wall, rss = run_agent(self.out)
        print(f"\n{self.id()}: exit {code}, {wall:.2f} s, {rss:.1f} MB: {err.strip()}")
        self.assertEqual(code, 2, err)
        lines = err.strip().splitlines()
        self.assertEqual(len(lines), 1, err)
        self.assertEqual(lines[0], f"mapmesh-agent: {self.path}: {reason}")
        self.assertLess(wall, 5.0)
        self.assertLess(rss, 200.0)

    def write(self, value):
        self.path.write_text(value if isinstance(value, str) else json.dumps(value))

    def test_wrong_robot(self):
        self.write(good_checkpoint(robot=2))
        self.refused("robot is 2, expected 1")

    def test_wrong_robot_in_an_earlier_incarnation(self):
        c = good_checkpoint()
        c["earlier"].append(snapshot(1, 7, 1))
        c["earlier"][1]["robot"] = 5
        self.write(c)
        self.refused("earlier[1].robot is 5, expected 1")

    def test_own_incarnation(self):
        c = good_checkpoint()
        c["earlier"][0]["incarnation"] = INCARNATION
        self.write(c)
        self.refused(f"earlier[0].incarnation {INCARNATION} is the resuming process's own incarnation")

    def test_earlier_nested_100000_deep(self):
        self.write(deep_checkpoint(100000))
        self.refused("nested deeper than 136 levels (at most 64 earlier incarnations, nested or not)")

    def test_nan_mean(self):
        c = good_checkpoint()
        c["local"]["landmarks"][2]["x"] = None  # how nlohmann writes NaN
        self.write(c)
        self.refused("local.landmarks[2].x is null, expected a finite number (NaN and inf are written as null)")

    def test_nan_literal(self):
        c = good_checkpoint()
        c["local"]["landmarks"][2]["x"] = float("nan")
        self.write(json.dumps(c))  # Python writes NaN, which is not JSON
        code, err, _, _ = run_agent(self.out)
        self.assertEqual(code, 2, err)
        self.assertIn(f"mapmesh-agent: {self.path}: not valid JSON: parse error", err)
        self.assertEqual(len(err.strip().splitlines()), 1, err)

    def test_infinite_covariance(self):
        c = good_checkpoint()
        c["global"]["landmarks"][1]["cov"][2] = 123456789.0
        self.write(json.dumps(c).replace("123456789.0", "1e999"))
        self.refused("not valid JSON: number overflow parsing '1e999'")

    def test_non_psd_covariance(self):
        c = good_checkpoint()
        c["earlier"][0]["global"]["landmarks"][3]["cov"] = [1.0, 2.0, 1.0]
        self.write(c)
        self.refused("earlier[0].global.landmarks[3].cov [1, 2, 1] is not positive semi-definite")

    def test_duplicate_landmark_id(self):
        c = good_checkpoint()
        c["local"]["landmarks"][4]["id"] = c["local"]["landmarks"][0]["id"]
        self.write(c)
        self.refused("local.landmarks[4].id 10 is a duplicate in local")

    def test_absurd_coordinate(self):
        c = good_checkpoint()
        c["local"]["landmarks"][1]["y"] = 3e8
        self.write(c)
        self.refused("local.landmarks[1].y is 300000000 m, beyond the world bound of 5000 m")

    def test_a_landmark_beyond_the_world(self):
        # R2: 50 km away, inside the file format's bound but not the scenario's world
        # (agent.world_radius_m, which bounds a peer's map too).
        c = good_checkpoint()
        c["earlier"][0]["global"]["landmarks"][2]["x"] = 5e4
        self.write(c)
        self.refused("earlier[0].global.landmarks[2].x is 50000 m, beyond the world bound of 5000 m")

    def test_stamps_after_the_end_of_the_run(self):
        # R2: stamps of 1e300 were accepted; the run (three.yaml) ends at 30 s, and stamps up to
        # agent.max_stamp_jump_s (20 s) beyond are taken, as sensor stamps are.
        c = good_checkpoint()
        c["processed_until"] = 1e300
        self.write(c)
        self.refused("processed_until is 1e+300 s, after the end of the run (50 s)")

    def test_oversize_file(self):
        with open(self.path, "wb") as f:  # sparse: nothing of it may be read
            f.truncate((256 << 20) + 1)
        self.refused("is 268435457 bytes, more than the limit of 268435456")

    def test_malformed_json(self):
        text = json.dumps(good_checkpoint())
        self.write(text[: len(text) // 2])  # a write cut short
        code, err, _, _ = run_agent(self.out)
        self.assertEqual(code, 2, err)
        self.assertIn(f"mapmesh-agent: {self.path}: not valid JSON: parse error", err)
        self.assertEqual(len(err.strip().splitlines()), 1, err)

    def test_missing_key(self):
        c = good_checkpoint()
        del c["earlier"][0]["processed_until"]
        self.write(c)
        self.refused("earlier[0].processed_until is missing")

    def test_wrong_type(self):
        c = good_checkpoint()
        c["incarnation"] = "2"
        self.write(c)
        self.refused("incarnation is a string, expected an integer >= 0")

    def test_checkpoint_is_a_directory(self):
        self.path.mkdir()
        self.refused("is a directory, not a checkpoint file")


class ResumeGoodCheckpointTest(unittest.TestCase):
    """The controls: a valid checkpoint is resumed and a missing one is a fresh start; the agent
    comes up on DDS and ends with 0 on SIGTERM."""

    def start_and_stop(self, out):
        lease = DomainLease()
        log = out.parent / "agent.log"
        try:
            with open(log, "wb") as f:
                p = subprocess.Popen([str(BIN / "mapmesh-agent"), "--scenario", str(SCENARIO), "--id", "1",
                                      "--domain", str(lease.id), "--out", str(out), "--incarnation", str(INCARNATION),
                                      "--resume"], stdout=subprocess.DEVNULL, stderr=f)
            try:
                deadline = time.monotonic() + 20
                while time.monotonic() < deadline and p.poll() is None and "] up: " not in log.read_text():
                    time.sleep(0.05)
                self.assertIsNone(p.poll(), log.read_text())
                self.assertIn("] up: ", log.read_text())
                p.send_signal(signal.SIGTERM)
                self.assertEqual(p.wait(timeout=20), 0, log.read_text())
            finally:
                if p.poll() is None:
                    p.kill()
                    p.wait(timeout=10)
        finally:
            lease.close()
        return log.read_text()

    def test_a_valid_checkpoint_is_resumed_and_carried_on(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_ckpt_") as tmp:
            out = Path(tmp) / "agent_1"
            out.mkdir()
            (out / "checkpoint.json").write_text(json.dumps(good_checkpoint()))
            log = self.start_and_stop(out)
            self.assertIn("resumed incarnation 2 (t=9.5s, 6 local and 8 global landmarks, 1 earlier incarnations, "
                          "0 submaps)", log)
            # The new checkpoint carries both earlier incarnations on (nothing was re-merged).
            written = json.loads((out / "checkpoint.json").read_text())
            self.assertEqual(written["incarnation"], INCARNATION)
            earlier = {e["incarnation"]: len(e["local"]["landmarks"]) for e in written["earlier"]}
            self.assertEqual(earlier, {1: 4, 2: 6})

    def test_a_missing_checkpoint_starts_afresh(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_ckpt_") as tmp:
            out = Path(tmp) / "agent_1"
            out.mkdir()
            log = self.start_and_stop(out)
            self.assertIn(f"--resume: no checkpoint at {out}/checkpoint.json; starting afresh", log)


# The restarted incarnation of an agent fails in a chosen way, decided before it starts, so
# nothing races the launcher: the launcher runs this wrapper as mapmesh-agent (MAPMESH_BIN
# points at a directory holding it and links to the real executables). For --resume it
# spoils the checkpoint (robot 3's, so the real agent refuses it and exits 2), or dies of
# SIGUSR1 (a signal nobody sent it, without a core file); then it execs the real agent in the
# same process, which the launcher tracks.
WRAPPER = """#!/usr/bin/python3
import json, os, signal, sys
argv = sys.argv[1:]
if "--resume" in argv:
    out = argv[argv.index("--out") + 1]
    if os.environ["MAPMESH_TEST_RESTART"] == "bad-checkpoint":
        with open(os.path.join(out, "checkpoint.json"), "w") as f:
            json.dump({CHECKPOINT}, f)
    else:
        os.kill(os.getpid(), signal.SIGUSR1)
os.execv({REAL!r}, [{REAL!r}] + argv)
"""


class RestartFailureTest(SwarmCase):
    def swarm_with_failing_restart(self, how):
        bindir = Path(self.tmp.name) / "bin"
        bindir.mkdir()
        for name in ("mapmesh-feeder", "mapmesh-eval", "mapmesh-inject"):
            (bindir / name).symlink_to(BIN / name)
        wrapper = bindir / "mapmesh-agent"
        wrapper.write_text(WRAPPER.replace("{CHECKPOINT}", repr(good_checkpoint(robot=3)))
                           .replace("{REAL!r}", repr(str(BIN / "mapmesh-agent"))))
        wrapper.chmod(0o755)
        env = dict(os.environ, MAPMESH_BIN=str(bindir), MAPMESH_TEST_RESTART=how)
        r = subprocess.run(SWARM + ["run", str(SCENARIO), "--kill", "2@5", "--restart", "2@8", "--no-report",
                                    "--out", str(self.out), "--timeout", "200"],
                           capture_output=True, text=True, timeout=240, env=env)
        self.assertEqual(r.returncode, 1, r.stdout + r.stderr)
        s = self.summary()
        self.assertEqual(s["failed_agents"], [2])
        agents = {a["id"]: a for a in s["agents"]}
        for rid in (1, 3):
            self.assertFalse(agents[rid]["failed"])
            self.assertEqual(agents[rid]["incarnations"],
                             [{"incarnation": 1, "exit_code": 0, "killed": False, "failed": False}])
        a = agents[2]
        self.assertTrue(a["failed"])
        self.assertEqual(a["restarts"], 1)
        self.assertFalse(a["alive_at_end"])
        self.assertEqual(a["incarnations"][0], {"incarnation": 1, "exit_code": -9, "killed": True, "failed": False})
        log = self.out / "agent_2" / "agent.log"
        lines = r.stderr.strip().splitlines()
        self.assertEqual(len(lines), 1, r.stderr)
        return a["incarnations"][1], lines[0], log.read_text()

    def test_a_restarted_agent_refusing_its_checkpoint_fails_the_run(self):
        second, message, log = self.swarm_with_failing_restart("bad-checkpoint")
        self.assertEqual(second, {"incarnation": 2, "exit_code": 2, "killed": False, "failed": True})
        self.assertEqual(message, f"swarm: agents [2] failed: agent 2 (incarnation 2 exited with code 2; see "
                                  f"{self.out / 'agent_2' / 'agent.log'})")
        self.assertIn(f"mapmesh-agent: {self.out / 'agent_2' / 'checkpoint.json'}: robot is 3, expected 2\n", log)

    def test_a_restarted_agent_dying_of_a_signal_fails_the_run(self):
        second, message, _ = self.swarm_with_failing_restart("signal")
        self.assertEqual(second, {"incarnation": 2, "exit_code": -signal.SIGUSR1, "killed": False, "failed": True})
        self.assertIn("agent 2 (incarnation 2 died of SIGUSR1; see ", message)


if __name__ == "__main__":
    unittest.main()
