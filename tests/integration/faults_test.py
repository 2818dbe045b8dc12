"""Faults a fault-injection tool must survive itself (R1), through real processes: a paused
agent (lockstep waits for it and loses nothing; realtime counts exactly what it lost), and
hostile input published over DDS during a run (each refusal counted, the maps unaffected)."""

import json
import unittest

from swarm_test import REPO, SwarmCase

PARK4 = REPO / "scenarios" / "park4.yaml"


class FaultRunCase(SwarmCase):
    def run_ok(self, *args, out=None):
        if out is not None:
            self.out = out
        r = self.swarm(*args, "--no-report")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        return {a["id"]: a for a in self.summary()["agents"]}


class PauseTest(FaultRunCase):
    def test_lockstep_waits_for_a_paused_agent_and_loses_nothing(self):
        base = self.out
        clean = self.run_ok(PARK4, out=base.parent / "clean")
        paused = self.run_ok(PARK4, "--pause", "2@30:3", out=base.parent / "paused")
        pauses = self.summary()["pauses"]
        self.assertEqual(len(pauses), 1)
        self.assertGreaterEqual(pauses[0]["wall_end"] - pauses[0]["wall_start"], 3.0)
        self.assertEqual(paused[2]["paused_at"], [30.0])
        for rid, a in paused.items():
            # Every sensor message the feeder sent was processed, none lost.
            self.assertEqual(a["odom_processed"], a["odom_sent"], a)
            self.assertEqual(a["scans_processed"], a["scans_sent"], a)
            self.assertEqual(a["odometry_lost"], 0)
            self.assertEqual(a["scans_lost"], 0)
            # ... and received once: what was sent again is counted apart (R2).
            self.assertEqual(a["odom_received"], a["odom_sent"], a)
            self.assertEqual(a["scans_received"], a["scans_sent"], a)
        # The same stream, the same local map.
        self.assertAlmostEqual(paused[2]["local"]["rmse_m"], clean[2]["local"]["rmse_m"],
                               delta=0.1 * clean[2]["local"]["rmse_m"])
        self.assertEqual(paused[2]["local"]["landmarks"], clean[2]["local"]["landmarks"])
        # The feeder waited for it rather than declaring it dead.
        log = (self.out / "feeder.log").read_text()
        self.assertIn("agent 2 lost (DDS liveliness); its process exists", log)
        self.assertNotIn("no longer waiting for it", log)

    def test_realtime_counts_exactly_what_a_paused_agent_lost(self):
        agents = self.run_ok(PARK4, "--pace", "realtime", "--rate", "20", "--pause", "2@30:3")
        for rid, a in agents.items():
            with self.subTest(agent=rid):
                # Sent = received + lost, for both streams (nothing is lost after the last message).
                self.assertEqual(a["odom_sent"], a["odom_received"] + a["odometry_lost"], a)
                self.assertEqual(a["scans_sent"], a["scans_received"] + a["scans_lost"], a)
                if rid != 2:
                    self.assertEqual(a["odometry_lost"], 0)
        self.assertGreater(agents[2]["odometry_lost"], 0)  # the pause did lose data, and it shows
        self.assertGreater(agents[2]["scans_lost"], 0)


class HostileInputTest(FaultRunCase):
    CASES = "odometry_stamp,far_reading,links_stamp,version_jump,huge_map,out_of_bounds"

    def test_each_hostile_message_is_refused_counted_and_changes_nothing(self):
        base = self.out
        clean = self.run_ok(PARK4, out=base.parent / "clean")
        hostile = self.run_ok(PARK4, "--inject", self.CASES, "--inject-period", "0.05", out=base.parent / "hostile")
        summary = self.summary()
        self.assertEqual(summary["injector_exit_code"], 0)
        cases = summary["injected"]["cases"]
        for case in self.CASES.split(","):
            self.assertGreater(cases[case]["sent"], 0, case)
        huge_receivers = 0
        for rid, a in hostile.items():
            with self.subTest(agent=rid):
                c = clean[rid]
                self.assertEqual(a["exit_code"], 0)
                stats = json.loads((self.out / f"agent_{rid}" / "stats.json").read_text())
                # Each kind refused and counted.
                self.assertGreater(stats["odom_implausible"], 0)
                self.assertGreater(stats["observations"]["out_of_range"], 0)
                # (links_stamp's table comes from the injector, not the feeder: refused unread)
                self.assertGreater(stats["not_from_feeder"]["links"], 0)
                # version_jump's maps claim the robots' own incarnations from another writer than
                # theirs: refused before they are read (issue R3, agent/robot_writers.h; the gate
                # behind, for a writer that is the robot's own, is AgentNodeLimits'). out_of_bounds
                # claims an incarnation of its own, which no tick lists: dropped by the inbox (in
                # real time, decoded and rejected: exchange_test).
                self.assertGreater(stats["maps_refused"]["other_writer"], 0)
                self.assertEqual(stats["maps_refused"]["version_jump"], 0)
                self.assertEqual(stats["maps_encode_failed"], 0)
                # The far reading's scan is numbered 999999: the loss count stays exact (R2).
                self.assertGreater(stats["scans_out_of_sequence"], 0)
                self.assertEqual(a["scans_lost"], 0, a)
                self.assertEqual(a["scans_received"], a["scans_sent"], a)
                # It kept mapping and publishing: its maps are as good as in the clean run.
                self.assertEqual(a["odom_processed"], c["odom_processed"])
                self.assertGreater(stats["maps_sent"], 0.9 * json.loads(
                    (base.parent / "clean" / f"agent_{rid}" / "stats.json").read_text())["maps_sent"])
                self.assertLessEqual(a["local"]["rmse_m"], 1.1 * c["local"]["rmse_m"])
                self.assertLessEqual(a["global"]["rmse_m"], 1.1 * c["global"]["rmse_m"])
                self.assertGreaterEqual(a["global"]["coverage"], 0.9 * c["global"]["coverage"])
                # 1.6 MB maps refused unread (their cost is a benchmark: BM_AgentReceivesPeerMap):
                # in lockstep by the inbox, since no tick listed their incarnation.
                huge_receivers += stats["inbox_refused"]["incarnation"] > 0
                self.assertEqual(stats["maps_refused"]["too_many_landmarks"], 0)
        self.assertGreater(huge_receivers, 0)


class TickFloodTest(FaultRunCase):
    # R3: one participant stalled a lockstep run for good. Maps claiming a robot not in the run
    # at tick 0xFFFFFFFF, the run's own robots at ticks far ahead, or at the next tick with 1000
    # sightings each, one every 1.6 s of scenario time: the agents kept every one of a tick not
    # yet applied, their inbox filled (65 536 entries), every genuine map was dropped, and no
    # deliver phase could complete (268adcd's agents with this injector: this run stopped at
    # t = 314 of 400 when the launcher's timeout ended it, no summary.json). Now the inbox
    # (agent/lockstep_inbox.h) refuses each on arrival, counted, and the run is the clean run.
    def test_a_flood_of_far_ticks_and_sightings_stalls_nothing_and_changes_nothing(self):
        base = self.out
        longer = ["--set", "duration_s=400"]
        clean = self.run_ok(PARK4, *longer, out=base.parent / "clean")
        # One map every 1.6 s of scenario time: about what one every 0.02 s of wall time gives on an
        # idle host (250), whatever the host's load (by wall time a loaded host's slower run got
        # more, and its CPU grew with them: 1.54 x once beside a full ctest -j2).
        flooded = self.run_ok(PARK4, *longer, "--inject", "tick_flood", "--inject-sim-period", "1.6",
                              out=base.parent / "flooded")
        summary = self.summary()
        self.assertEqual(summary["injector_exit_code"], 0)
        self.assertGreater(summary["injected"]["cases"]["tick_flood"]["sent"], 100)
        self.assertEqual(summary["sim_duration_s"], 400.0)
        for rid, a in flooded.items():
            with self.subTest(agent=rid):
                refused = a["inbox_refused"]
                self.assertGreater(refused["unknown_robot"], 0, refused)
                self.assertEqual(refused["incarnation"], 0, refused)
                # The far ticks and the flooded sightings under the run's robots' names come from
                # another writer than each robot's: refused before the inbox looks at them (the
                # inbox's own gates, far_tick and too_many_sightings, for a forger that spoke before
                # the robot did: lockstep_inbox_test).
                self.assertGreater(a["maps_refused"]["other_writer"], 0, a["maps_refused"])
                self.assertLessEqual(a["max_rss_mb"], 1.2 * clean[rid]["max_rss_mb"], (a, clean[rid]))
        # The same run, byte for byte (lockstep).
        self.assert_same_maps(self.out, base.parent / "clean")
        # CPU is a benchmark, not asserted here: the flood costs 1.08-1.16 x the clean run's,
        # summed over the agents (five interleaved pairs of 1000 s runs on an idle host,
        # docs/BENCHMARKS.md "A flood of far ticks"), but one pair of runs beside other tests
        # cannot show it: two identical clean runs differed by 1.20 x, and beside a ctest -j2 a
        # flooded run measured 1.52 x one clean run before it (the host's load changed between
        # the two).


class ForgedSubmapsTest(FaultRunCase):
    # R3: forged submaps won everywhere. Copies of a robot's latest closed submap under its next
    # five indices (landmarks moved 3-15 m), or under an incarnation that never ran (77, and 78
    # opened at -1e9 s), riding on a copy of the next robot's latest local map a tick later.
    # Measured with the build before (R3's inbox, 268adcd's submap gates): the riders were taken
    # before the map's version was looked at, every agent held 262-279 submaps against 20 and
    # counted 193-271 conflicts, joined 1 or 2 of 4 chains (the ghost's time overlapping the
    # real chain's superseded it), and its global map was 2.7-9.0 m off after a rigid fit
    # against 0.05 m; CPU 3.2 x. Now the inbox refuses a copy of an earlier tick's map
    # (`inbox_refused.replayed`), what rides on a map is taken only with the map, a submap
    # of the agent's own robot only from itself, one opened before the run never, and only an
    # incarnation heard supersedes (agent_node_test, submap_book_test, lockstep_inbox_test):
    # the run is the clean run.
    # forged_relay: the same forgeries on the next robot's next map key, written before the
    # robot's own (first arrival won the key). With the build before (094009b) every agent kept
    # the forger's, refused the robot's own (`key_taken` 81-90) and held the forgeries
    # (`conflicts` 152-215): 71 of 200 files differed from the clean run. Now a map claiming a
    # robot incarnation from another DDS writer than its maps came from is refused on arrival
    # (`maps_refused.other_writer`, agent/robot_writers.h), the copies above with it.
    JOINING = ["--set", "agent.slam=cekf_submaps", "--set", "agent.fusion=joining"]
    CASES = "forged_submaps,ghost_incarnation,forged_relay"

    def test_forged_and_ghost_submaps_are_refused_counted_and_change_nothing(self):
        base = self.out
        clean = self.run_ok(PARK4, *self.JOINING, out=base.parent / "clean")
        forged = self.run_ok(PARK4, *self.JOINING, "--inject", self.CASES, "--inject-sim-period", "1.5",
                             out=base.parent / "forged")
        summary = self.summary()
        self.assertEqual(summary["injector_exit_code"], 0)
        for case in self.CASES.split(","):
            self.assertGreater(summary["injected"]["cases"][case]["sent"], 10, case)
        for rid, a in forged.items():
            with self.subTest(agent=rid):
                st = json.loads((self.out / f"agent_{rid}" / "stats.json").read_text())
                held = json.loads((base.parent / "clean" / f"agent_{rid}" / "stats.json").read_text())
                self.assertGreater(st["maps_refused"]["other_writer"], 0, st["maps_refused"])
                self.assertEqual(st["inbox_refused"]["key_taken"], 0, st["inbox_refused"])
                self.assertEqual(st["submaps"]["conflicts"], 0, st["submaps"])
                self.assertEqual(st["submaps"]["chains"], held["submaps"]["chains"])  # every digest the clean run's
                # Owners' digests (every local map carries its own chain's): no genuine copy disowned.
                for run in (st, held):
                    self.assertEqual(run["submaps"]["owner_conflicts"], 0, run["submaps"])
                    self.assertEqual(run["submaps"]["ahead_of_owner"], 0, run["submaps"])
                self.assertEqual(a["exit_code"], 0)
                self.assertLessEqual(a["max_rss_mb"], 1.2 * clean[rid]["max_rss_mb"], (a, clean[rid]))
        self.assert_same_maps(self.out, base.parent / "clean")
        # CPU: measured, not asserted (TickFloodTest says why): docs/EXPERIMENTS.md "Forged and
        # ghost submaps" (4.15-4.43 s summed against 4.22 s).


class HugeSubmapsTest(FaultRunCase):
    # R3: large valid submaps took an agent out of the run, bounded by count, not bytes (100 of
    # 500 landmarks, 2 MB each: 881 MB RSS at the agent in range, 360-403 MB relayed by each of
    # the others). mapmesh-inject huge_submaps sends two such submaps under a robot's identity at
    # new indices on a map key agents take (forged_relay's carrier), one every 1.5 s of scenario
    # time. With the build before (1470085) the lockstep inbox refused each carrier (it came after
    # the robot's own map of that key: `past_tick`, `key_taken`), but only once the transport had
    # taken and decoded it: every agent's RSS 38-45 MB against 16 MB in the clean run (2.4 x).
    # Now an agent's transport drops any sample beyond what the run's agents can send
    # (AgentNode::MaxSampleBytes, 2.9 MB with these settings; Cyclone's MaxSampleSize) before it
    # is reassembled, counted in stats.json `transport_oversize`. Huge submaps that fit in a
    # sample are refused unread by agent.max_submap_bytes (AgentNodeLimits).
    JOINING = ["--set", "agent.slam=cekf_submaps", "--set", "agent.fusion=joining"]

    def test_huge_valid_submaps_are_dropped_unread_and_change_nothing(self):
        base = self.out
        clean = self.run_ok(PARK4, *self.JOINING, out=base.parent / "clean")
        huge = self.run_ok(PARK4, *self.JOINING, "--inject", "huge_submaps", "--inject-sim-period", "1.5",
                           out=base.parent / "huge")
        summary = self.summary()
        self.assertEqual(summary["injector_exit_code"], 0)
        sent = summary["injected"]["cases"]["huge_submaps"]["sent"]
        self.assertGreater(sent, 5)
        for rid, a in huge.items():
            with self.subTest(agent=rid):
                c = clean[rid]
                self.assertEqual(a["exit_code"], 0)
                st = json.loads((self.out / f"agent_{rid}" / "stats.json").read_text())
                was = json.loads((base.parent / "clean" / f"agent_{rid}" / "stats.json").read_text())
                self.assertGreater(st["transport_oversize"]["dropped"], 0, st["transport_oversize"])
                self.assertEqual(was["transport_oversize"]["dropped"], 0)
                self.assertEqual(st["maps_beyond_sample_size"], 0)
                self.assertEqual(st["submaps"]["held"], was["submaps"]["held"])
                self.assertLessEqual(a["max_rss_mb"], 1.2 * c["max_rss_mb"], (a, c))
        self.assert_same_maps(self.out, base.parent / "clean")
        # CPU: measured, not asserted (TickFloodTest says why): 1.05-1.08 x the clean run's per
        # agent on an idle host (docs/EXPERIMENTS.md "Huge submaps").


def storm(robot, kills=12, first=10, every=15, back_after=3):
    """--kill/--restart arguments: `robot` killed `kills` times, every `every` s from `first`,
    each time restarted `back_after` s later."""
    args = []
    for k in range(kills):
        t = first + every * k
        args += ["--kill", f"{robot}@{t}", "--restart", f"{robot}@{t + back_after}"]
    return args


class RestartStormTest(FaultRunCase):
    # R2: agent 3 of park4 killed and restarted 12 times ended with 25 landmarks and coverage
    # 0.12 (185 and 0.93 after one kill), and agent 4, which relayed through it, fell from 0.94
    # to 0.71. Now the feeder replays its robot's stream to each new incarnation, which rebuilds
    # its map in its own frame and places the earlier ones there (docs/EXPERIMENTS.md "Faults").
    def storm_costs_nothing(self, *pace):
        base = self.out
        one = self.run_ok(PARK4, *pace, "--kill", "3@90", "--restart", "3@93", out=base.parent / "one")
        stormy = self.run_ok(PARK4, *pace, *storm(3), out=base.parent / "storm")
        a, b = stormy[3], one[3]
        self.assertEqual(a["restarts"], 12)
        self.assertGreaterEqual(a["local"]["landmarks"], 0.9 * b["local"]["landmarks"])
        self.assertFalse(a["map_shrank"], a["held"])
        # It was sent its whole stream each time, and took it all.
        self.assertEqual(a["odom_received"], a["odom_sent"], a)
        self.assertEqual(a["scans_received"], a["scans_sent"], a)
        self.assertEqual(a["odom_before_join"], 0)
        feeder = json.loads((self.out / "feeder.json").read_text())
        self.assertGreater(feeder["sensor_messages_replayed"], 12 * 100)
        for rid in (1, 2, 4):
            with self.subTest(survivor=rid):
                self.assertGreaterEqual(stormy[rid]["global"]["coverage"], 0.95 * one[rid]["global"]["coverage"])
        # Each earlier incarnation was placed in the last one's frame, exactly.
        stats = json.loads((self.out / "agent_3" / "stats.json").read_text())
        own = [p for p in stats["peers"] if p["own_checkpoint"]]
        self.assertTrue(own)
        for p in own:
            self.assertEqual(p["first_aligned_by"], "continuity", p)
        return one, stormy

    def test_a_restart_storm_costs_nothing_in_lockstep(self):
        one, stormy = self.storm_costs_nothing()
        # In lockstep the stream and the filter are the run's: the very map of the one-kill run.
        for name in ("local_map.json", "trajectory.json"):
            self.assertEqual((self.out / "agent_3" / name).read_text(),
                             (self.out.parent / "one" / "agent_3" / name).read_text(), name)
        # R3: its global map too. Each incarnation carries the peers' frames it had placed in its
        # checkpoint, and the next weighs them on the maps instead of searching afresh: coverage
        # 0.96 against 0.965 after one kill (the build before: 0.825, its last incarnation
        # aligned none of its peers again; docs/EXPERIMENTS.md "A restart storm").
        self.assertGreaterEqual(stormy[3]["global"]["coverage"], one[3]["global"]["coverage"] - 0.02,
                                (stormy[3]["global"], one[3]["global"]))
        cp = json.loads((self.out / "agent_3" / "checkpoint.json").read_text())
        self.assertEqual(sorted(p["robot"] for p in cp["peers"]), [1, 2, 4])

    def test_a_restart_storm_costs_nothing_in_realtime(self):
        self.storm_costs_nothing("--pace", "realtime", "--rate", "20")

    def test_without_kept_streams_a_storm_empties_the_agent_and_says_so(self):
        # What every restart storm did before: each incarnation joins the stream where it is.
        agents = self.run_ok(PARK4, "--set", "feeder.keep_streams=false", *storm(3))
        a = agents[3]
        self.assertTrue(a["map_shrank"], a["held"])
        self.assertLess(a["local"]["landmarks"], 0.5 * a["held"]["global"])
        self.assertGreater(a["odom_before_join"], 0)


class ForgedLinksTest(FaultRunCase):
    # R2: link tables linking everyone, stamped 15 s ahead (plausible), every 0.1 s, from a writer
    # that is not the feeder's, once let every agent hear every other at radio.range_m=0.
    def test_link_tables_not_from_the_feeder_are_refused_and_counted(self):
        agents = self.run_ok(PARK4, "--pace", "realtime", "--rate", "20", "--set", "radio.range_m=0",
                             "--inject", "links_ahead", "--inject-period", "0.1")
        self.assertGreater(self.summary()["injected"]["cases"]["links_ahead"]["sent"], 0)
        for rid, a in agents.items():
            with self.subTest(agent=rid):
                stats = json.loads((self.out / f"agent_{rid}" / "stats.json").read_text())
                self.assertGreater(stats["not_from_feeder"]["links"], 0)
                self.assertEqual(stats["not_from_feeder"]["ticks"], 0)
                # Nobody is in range: no peer's map passed the radio, no peer is aligned.
                self.assertEqual(stats["maps_received"], 0, stats["maps_received_from"])
                self.assertGreater(stats["maps_out_of_range"], 0)
                self.assertEqual(stats["peers_aligned"], [])


if __name__ == "__main__":
    unittest.main()
