"""End-to-end map exchange (M6) through real agent processes over DDS, driven by scripts/swarm
on private domains: alignment and union, multi-hop relay, kills, restarts and liveliness.
Every run has a hard timeout."""

import base64
import csv
import json
import math
import struct
import subprocess
import unittest

from report_test import SWEEP_HEADER, check_in_browser, check_png, check_report, check_sweep
from swarm_test import REPO, SWARM, SwarmCase

SCENARIOS = REPO / "scenarios"


def history(run, rid):
    """Agent rid's history.jsonl lines (one per checkpoint and at the end)."""
    path = run / f"agent_{rid}" / "history.jsonl"
    return [json.loads(line) for line in path.read_text().splitlines() if line.strip()]


def origins(map_json, robot):
    """(incarnation, id) of every landmark input from `robot` in a global map JSON."""
    return {(o[1], o[2]) for lm in map_json["landmarks"] for o in lm.get("origins", []) if o[0] == robot}


class ExchangeTest(SwarmCase):
    def run_ok(self, *args, timeout=240):
        r = self.swarm(*args, "--no-report", timeout=timeout)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        return {a["id"]: a for a in self.summary()["agents"]}

    def run_eight_killing(self, kills):
        """park4 with 8 agents, killing {robot: scenario time}; the agents by id."""
        args = [SCENARIOS / "park4.yaml", "--agents", "8"]
        for rid, t in kills.items():
            args += ["--kill", f"{rid}@{t}"]
        return self.run_ok(*args)

    def test_circle_pair_align_and_both_hold_the_union(self):
        agents = self.run_ok(SCENARIOS / "thesis_circle_pair.yaml")
        for rid, other in ((1, 2), (2, 1)):
            a = agents[rid]
            self.assertEqual(a["peers_aligned"], [other])
            e = a["alignment_errors"][str(other)]
            # The alignment against the frames the two maps are really in (their fits to the
            # truth); the error against the true start poses adds both maps' own frame errors.
            self.assertLessEqual(e["trans_fit_m"], 0.2, e)
            self.assertLessEqual(math.degrees(e["rot_fit_rad"]), 1.0, e)
            self.assertLess(e["trans_m"], 0.5, e)
            g = a["global"]
            self.assertEqual(g["coverage"], 1.0)  # every landmark either robot saw
            self.assertEqual(g["matched"], g["landmarks"])  # and no duplicates nor strays
            self.assertLessEqual(g["nees_mean"], a["local"]["nees_mean"] + 1e-6)
            self.assertEqual(g["identities_mixed"], 0, g)  # no landmark fuses two trees

    def test_multi_hop_line_of_three(self):
        agents = self.run_ok(SCENARIOS / "line3.yaml")
        one, three = agents[1], agents[3]
        self.assertEqual(one["peers_aligned"], [2])  # 1 never hears 3
        stats = json.loads((self.out / "agent_1" / "stats.json").read_text())
        self.assertNotIn("3", stats["maps_received_from"])
        # Yet its global map covers what 3 saw, every landmark on a true one.
        self.assertLess(one["local"]["coverage"], 0.6)
        self.assertGreaterEqual(one["global"]["coverage"], 0.9)
        self.assertEqual(one["global"]["matched"], one["global"]["landmarks"])
        self.assertLess(one["global"]["rmse_m"], 0.5)
        self.assertGreater(three["local"]["landmarks"], 0)

    def test_submaps_reach_two_hops_byte_for_byte(self):
        # cekf_submaps: closed submaps ride on the local maps and are relayed by identity
        # (agent/submap_relay.h). Robot 1 never hears robot 3, yet holds robot 3's chain, each
        # submap the very bytes robot 3 made; nothing is refused, nothing twice in a book.
        self.run_ok(SCENARIOS / "line3.yaml", "--set", "agent.slam=cekf_submaps")
        stats = {rid: json.loads((self.out / f"agent_{rid}" / "stats.json").read_text()) for rid in (1, 2, 3)}
        self.assertNotIn("3", stats[1]["maps_received_from"])
        chains = {rid: {(c["robot"], c["incarnation"]): c for c in s["submaps"]["chains"]} for rid, s in stats.items()}
        for rid, s in stats.items():
            sm = s["submaps"]
            self.assertGreaterEqual(sm["own"], 2, sm)
            self.assertEqual(chains[rid][(rid, 1)]["count"], sm["own"])
            self.assertEqual(sm["held"], sum(c["held"] for c in chains[rid].values()))
            self.assertEqual(sm["conflicts"] + sm["full"] + sm["unsendable"], 0, sm)
            self.assertEqual(sum(sm["rejected"].values()) + sum(sm["refused"].values()), 0, sm)
        own3 = chains[3][(3, 1)]
        held3 = chains[1][(3, 1)]
        self.assertGreaterEqual(held3["count"], own3["count"] - 1)  # the last may close too late to travel
        self.assertGreaterEqual(held3["count"], 1)
        self.assertEqual(held3["digests"], own3["digests"][:held3["count"]])
        # Robot 2, between them, holds both ends' chains, and sent each submap about once (a
        # resend only for one its peers had not shown yet): not every period.
        self.assertGreaterEqual(chains[2][(1, 1)]["count"], 1)
        self.assertGreaterEqual(chains[2][(3, 1)]["count"], 1)
        self.assertLessEqual(stats[2]["submaps"]["sent"], 2 * stats[2]["submaps"]["held"])

    def test_ci_places_a_peers_submaps_on_their_own(self):
        # agent.ci_placement piecewise: each agent places the other's closed submaps one by one
        # against its own map and fuses each by CI (common/merge/submap_placement.h). On the
        # circle pair every submap fits; the maps hold the union without duplicates, within
        # twice the central optimum (over 10 seeds at worst 1.89; this seed 1.22 and 1.08) and
        # consistent (NEES at worst 2.67 over 10 seeds: the placements' covariance allows for
        # the own map's shared errors).
        agents = self.run_ok(SCENARIOS / "thesis_circle_pair.yaml", "--set", "agent.slam=cekf_submaps",
                             "--set", "agent.ci_placement=piecewise")
        for rid, a in agents.items():
            pw = json.loads((self.out / f"agent_{rid}" / "stats.json").read_text())["ci_piecewise"]
            self.assertGreaterEqual(pw["submaps"], 3, pw)
            self.assertEqual(pw["fitted"] + pw["chained"], pw["submaps"], pw)
            self.assertGreaterEqual(pw["fitted"], pw["submaps"] - 1, pw)
            self.assertGreaterEqual(pw["pairs"], 3 * pw["fitted"], pw)
            g = a["global"]
            self.assertEqual(g["coverage"], 1.0, g)
            self.assertEqual(g["matched"], g["landmarks"], g)
            self.assertLessEqual(a["gap_to_central"], 2.0, rid)
            self.assertLessEqual(g["nees_mean"], 3.0, g)

    def test_joining_submap_chains_beats_ci_on_every_global_map(self):
        # park4 (default seed) with the submap SLAM: CI fuses the peers' bent maps, joining
        # joins their submap chains (open submaps on the local maps). Every agent's global map
        # after a rigid fit is better joined (measured 0.041-0.055 m against CI's 0.072-0.145 m)
        # and within twice the central optimum (1.08-1.61); each agent joined every chain it was
        # offered, and the solve converged.
        submaps = ["--set", "agent.slam=cekf_submaps"]
        base = self.out
        self.out = base.parent / "ci"
        ci = self.run_ok(SCENARIOS / "park4.yaml", *submaps)
        self.out = base.parent / "joining"
        joined = self.run_ok(SCENARIOS / "park4.yaml", *submaps, "--set", "agent.fusion=joining")
        # The snapshots over time are scored as the final maps are (peers' landmarks by the
        # identities their origins name): the last, at the end of the run, gives the final
        # figures (by distance, agent 2's last snapshot scored NEES 14.4 against the final 2.58).
        timeline = json.loads((self.out / "timeline.json").read_text())
        for rid, a in joined.items():
            last = [s for s in timeline["agents"][str(rid)] if "global" in s][-1]
            self.assertEqual(last["global"]["matched"], a["global"]["matched"], rid)
            self.assertAlmostEqual(last["global"]["nees_mean"], a["global"]["nees_mean"], places=9, msg=rid)
        for rid, a in joined.items():
            self.assertLess(a["global"]["rmse_aligned_m"], ci[rid]["global"]["rmse_aligned_m"], rid)
            self.assertLessEqual(a["gap_to_central"], 2.0, rid)
            j = json.loads((self.out / f"agent_{rid}" / "stats.json").read_text())["joining"]
            self.assertTrue(j["solved"] and j["converged"], j)
            self.assertEqual(j["chains_joined"], j["chains"], j)
            # The own chain, each aligned peer's, and those placed from relayed submaps alone.
            self.assertEqual(j["chains"], len(a["peers_aligned"]) + 1 + j["relayed_placed"], j)
            self.assertGreater(j["solves"], 10, j)
            # The first pass ran when a chain entered, not at every solve; no solve judged on
            # the last solve's frames was refused by its residuals.
            self.assertGreaterEqual(j["first_passes"], 1, j)
            self.assertLessEqual(j["first_passes"], j["solves"] // 4, j)
            self.assertEqual(j["rechecks"], 0, j)

    def test_joining_holds_a_robot_two_hops_away(self):
        # line3 (seed 1): robot 1 never hears robot 3, but holds its submaps (relayed by robot
        # 2). The joining back-end rebuilds robot 3's map from them and places it where robot
        # 2's join put it (robot 2's local map carries the placement), composed with where it
        # put robot 2, once its maps verify it there; it then joins it. When robot 3 falls
        # silent (out of robot 2's range at 86 s), robot 2 relays robot 3's open submap as it
        # last took it, and robot 1 joins it after robot 3's closed ones: robot 1's global map
        # has robot 3's landmarks up to 86 s, at the optimum of what reached it (measured: 70 of
        # robot 3's landmarks, 1.03 times the reached optimum's RMSE; 59 and 1.08 without the
        # open submap).
        joined = self.run_ok(SCENARIOS / "line3.yaml", "--set", "agent.slam=cekf_submaps", "--set",
                             "agent.fusion=joining")
        stats = json.loads((self.out / "agent_1" / "stats.json").read_text())
        self.assertNotIn("3", stats["maps_received_from"])
        j = stats["joining"]
        self.assertEqual((j["relayed_placed"], j["chains"], j["chains_joined"]), (1, 3, 3), j)
        self.assertEqual(j["relayed_disagreements"], 0, j)
        self.assertEqual((j["relayed_by_placement"], j["placements_refused"]), (1, 0), j)
        relayer = json.loads((self.out / "agent_2" / "stats.json").read_text())
        self.assertGreaterEqual(relayer["submaps"]["open_relayed"], 1, relayer["submaps"])
        self.assertEqual(stats["data_until"]["3"], relayer["data_until"]["3"])  # robot 3's data to 86 s
        final = json.loads((self.out / "agent_1" / "global_map.json").read_text())
        self.assertGreaterEqual(len(origins(final, 3)), 65)
        self.assertLessEqual(joined[1]["gap_to_reached"], 1.25)
        self.assertGreaterEqual(joined[1]["global"]["coverage"], 0.92)
        # Robot 3's landmarks (and robot 2's) are scored against the trees their robots'
        # sensors measured (mapmesh-eval: by their origins), and none fuses two trees.
        self.assertGreaterEqual(joined[1]["global"]["signed_by_origins"], 65)
        self.assertEqual(joined[1]["global"]["identities_mixed"], 0)
        # Robot 3 is out of robot 2's range at the end: its last data never reached agents 1 and
        # 2, whose limit is the optimum of what did (reference_reached.json), with fewer
        # observations than the whole run's.
        whole = json.loads((self.out / "reference.json").read_text())
        for rid in (1, 2):
            until = joined[rid]["reached_until"]
            self.assertEqual(set(until), {"3"}, until)
            self.assertLess(until["3"], 120.0, until)
            reached = json.loads((self.out / f"agent_{rid}" / "reference_reached.json").read_text())
            self.assertEqual(reached["until"], until)
            self.assertLess(reached["central"]["observations"], whole["central"]["observations"])
            self.assertIsNotNone(joined[rid]["gap_to_reached"])
            # ... and every landmark of that optimum is in its global map (issue J2's figure,
            # measured 1.0 for both; agent 3, whose robot 1 data reached only to 24 s, 0.81).
            self.assertGreaterEqual(joined[rid]["global"]["coverage_reached"], 0.97)
        self.assertEqual(joined[3]["reached_until"], {"1": 24.0, "2": 86.0})  # its peers' maps carry their own data

    def test_joining_the_park_seeds_whose_wrong_pairings_were_traced_fuses_no_two_trees(self):
        # Issue J2 traced two wrong pairings of park4 joined (268adcd): seed 10's agent 3
        # merged tree 181 with trees 16 and 79, seed 2's agent 4 trees 65 and 119 (12-22 % of
        # the pairings across chains dropped in those runs). A pairing is kept only where the
        # submaps agree with it, and the global map is made from the join: no landmark of any
        # agent's global map names two trees (its origins, scored by the robots' identities),
        # every chain is joined, and the pairings the join kept apart are counted.
        for seed, traced in ((10, 3), (2, 4)):
            with self.subTest(seed=seed):
                agents = self.run_ok(SCENARIOS / "park4.yaml", "--set", f"seed={seed}", "--set",
                                     "agent.slam=cekf_submaps", "--set", "agent.fusion=joining",
                                     "--no-reference")
                for rid, a in agents.items():
                    self.assertEqual(a["global"]["identities_mixed"], 0, (rid, a["global"]))
                j = json.loads((self.out / f"agent_{traced}" / "stats.json").read_text())["joining"]
                self.assertEqual((j["chains"], j["chains_joined"]), (4, 4), j)
                self.assertLessEqual(j["ties_dropped"], j["ties"], j)
                self.assertGreaterEqual(agents[traced]["global"]["coverage"], 0.85)

    def test_joining_a_restarted_agent_keeps_its_earlier_chain_and_joins_it_once(self):
        # park4 with every robot out of range of the others (1 m): agent 3's first incarnation
        # closes a submap no peer ever hears. Killed at 60 s and restarted at 80 s, it holds
        # that chain again from its checkpoint (before, it was lost). In lockstep the restart
        # replays robot 3's stream from the start, so the new chain maps the same scans again:
        # the earlier one is left out of the join rather than counted twice.
        agents = self.run_ok(SCENARIOS / "park4.yaml", "--set", "radio.range_m=1", "--set", "duration_s=150",
                             "--set", "agent.slam=cekf_submaps", "--set", "agent.fusion=joining",
                             "--kill", "3@60", "--restart", "3@80")
        self.assertEqual((agents[3]["restarts"], agents[3]["alive_at_end"]), (1, True))
        stats = json.loads((self.out / "agent_3" / "stats.json").read_text())
        submaps = stats["submaps"]
        chains = {(c["robot"], c["incarnation"]): c["count"] for c in submaps["chains"]}
        self.assertGreaterEqual(chains.get((3, 1), 0), 1, chains)
        self.assertGreaterEqual(chains.get((3, 2), 0), 1, chains)
        self.assertEqual((submaps["restored"], submaps["received_new"]), (chains[(3, 1)], 0), submaps)
        j = stats["joining"]
        self.assertEqual((j["superseded_chains"], j["chains"], j["chains_joined"]), (1, 1, 1), j)
        # The second incarnation's checkpoint holds both chains, each submap as it travels
        # (header: "MS", version, flags, robot, incarnation, index).
        saved = json.loads((self.out / "agent_3" / "checkpoint.json").read_text())
        ids = sorted(struct.unpack_from("<2sBBIII", base64.b64decode(b, validate=True))[3:] for b in saved["submaps"])
        expected = sorted((3, inc, i) for (_, inc), n in chains.items() for i in range(n))
        self.assertEqual(ids, expected)

    def test_eight_agents_four_killed_keep_what_the_dead_sent(self):
        kills = {2: 40.0, 4: 75.0, 5: 110.0, 7: 150.0}
        agents = self.run_eight_killing(kills)
        survivors = [rid for rid in agents if rid not in kills]
        self.assertEqual(len(survivors), 4)
        checked = 0
        for rid in survivors:
            a = agents[rid]
            self.assertTrue(a["alive_at_end"])
            self.assertEqual(a["exit_code"], 0)
            final = json.loads((self.out / f"agent_{rid}" / "global_map.json").read_text())
            lines = history(self.out, rid)
            for dead, t in kills.items():
                before = [h for h in lines if h["t"] <= t]
                if not before:
                    continue
                snap = json.loads((self.out / f"agent_{rid}" / "snapshots" /
                                   f"t{before[-1]['t']:010.3f}_i{before[-1]['incarnation']}_global.json").read_text())
                had = origins(snap, dead)
                checked += len(had)
                self.assertLessEqual(had, origins(final, dead), f"agent {rid} lost landmarks of killed {dead}")
        self.assertGreater(checked, 0)  # some survivor had received landmarks from the killed ones

    def test_eight_agents_four_killed_later_hold_every_overlapping_dead_map(self):
        # Other robots and kill times than above, most before any alignment in the park (about
        # 100 s; survivors' coverage was 0.35-0.58 when a dead robot's map was tried only while
        # it spoke): a dead robot's last map keeps being tried against the survivor's growing
        # map. Every one that the exchange's alignment places on the survivor's final local map
        # (eval's dead_peers: the true transform found on most seeded tries) must be held whole.
        kills = {1: 40.0, 3: 70.0, 5: 100.0, 7: 130.0}
        agents = self.run_eight_killing(kills)
        alignable = 0
        for rid, a in agents.items():
            if rid in kills:
                continue
            self.assertEqual(a["exit_code"], 0)
            for d in a["dead_peers"]:
                self.assertIn(d["robot"], kills)
                if d["alignable"]:
                    alignable += 1
                    self.assertEqual(d["held"], d["landmarks"], f"agent {rid} lost landmarks of dead robot {d}")
        self.assertGreaterEqual(alignable, 4)  # the survivors could place the dead

    def test_restarted_agent_ends_with_at_least_its_coverage_before_the_kill(self):
        agents = self.run_ok(SCENARIOS / "park4.yaml", "--kill", "3@60", "--restart", "3@80")
        a = agents[3]
        self.assertTrue(a["alive_at_end"])
        self.assertEqual(a["restarts"], 1)
        timeline = json.loads((self.out / "timeline.json").read_text())["agents"]["3"]
        before = [h for h in timeline if h["t"] <= 60.0 and h["incarnation"] == 1]
        self.assertTrue(before)
        self.assertGreaterEqual(a["global"]["coverage"], before[-1]["global"]["coverage"])
        self.assertGreater(timeline[-1]["incarnation"], 1)

    def test_a_killed_peer_is_reported_stale_within_two_seconds(self):
        agents = self.run_ok(SCENARIOS / "thesis_circle_pair.yaml", "--kill", "2@100", "--pace", "realtime",
                             "--rate", "40")
        kill = self.summary()["kills"][0]
        self.assertIsNotNone(kill["wall"])
        self.assertEqual(agents[1]["peers_stale"], [2])
        stats = json.loads((self.out / "agent_1" / "stats.json").read_text())
        lost = stats["peers_lost_wall"]["2"] - kill["wall"]
        self.assertGreaterEqual(lost, 0.0)
        self.assertLessEqual(lost, 2.0)
        # Its landmarks stay in the global map.
        self.assertEqual(agents[1]["global"]["coverage"], 1.0)

    def test_bad_input_is_counted_and_refused_and_the_global_map_is_unaffected(self):
        # mapmesh-inject publishes every malformed payload, stale versions, maps from a robot
        # not in the run and a faulty peer (honest, then shuffled maps) while the pair maps.
        # Paced so that the run lasts long enough (about 13 s) for every case to go out often.
        agents = self.run_ok(SCENARIOS / "thesis_circle_pair.yaml", "--pace", "realtime", "--rate", "20",
                             "--inject", "all", "--inject-period", "0.05")
        summary = self.summary()
        self.assertEqual(summary["injector_exit_code"], 0)
        injected = summary["injected"]
        cases = injected["cases"]
        reasons = {"truncated": "truncated", "oversized": "oversized", "count_above_limit": "oversized",
                   "bad_magic": "bad_magic", "unknown_version": "unknown_version", "non_finite": "non_finite",
                   "bad_covariance": "bad_covariance", "duplicate_id": "duplicate_id", "bad_header": "bad_header",
                   "out_of_bounds": "out_of_bounds"}
        for rid, other in ((1, 2), (2, 1)):
            a = agents[rid]
            with self.subTest(agent=rid):
                self.assertTrue(a["alive_at_end"])
                self.assertEqual(a["exit_code"], 0)
                stats = json.loads((self.out / f"agent_{rid}" / "stats.json").read_text())
                # Each malformed payload from the other robot was refused for its own reason.
                sent_by_other = {}
                for case, reason in reasons.items():
                    n = cases[case]["by_sender"].get(str(other), 0)
                    self.assertGreater(n, 0, case)
                    sent_by_other[reason] = sent_by_other.get(reason, 0) + n
                for reason, n in sent_by_other.items():
                    self.assertGreaterEqual(stats["maps_rejected"][reason], 1, reason)
                    self.assertLessEqual(stats["maps_rejected"][reason], n, reason)
                self.assertGreaterEqual(stats["maps_unknown_sender"], 1)
                # (the tick flood's maps from the unknown robot too: in real time no inbox refuses them first)
                unknown = str(injected["unknown_id"])
                self.assertLessEqual(stats["maps_unknown_sender"], cases["unknown_sender"]["sent"]
                                     + cases["tick_flood"]["by_sender"].get(unknown, 0))
                # stale_version's copies claim the robot's own incarnation from the injector's
                # writer: refused unread (other_writer, issue R3) once a map of the robot was taken,
                # else stale (the gate itself: MapExchange's unit tests).
                self.assertGreaterEqual(stats["maps_stale_version"] + stats["maps_refused"]["other_writer"], 1)
                # The faulty peer was aligned on its honest maps, and its shuffled maps failed
                # verification and dropped it.
                self.assertGreater(cases["shuffled"]["by_sender"].get(str(other), 0), 0)
                faulty = [p for p in stats["peers"]
                          if p["robot"] == other and p["incarnation"] == injected["faulty_incarnation"]]
                self.assertEqual(len(faulty), 1, stats["peers"])
                self.assertTrue(faulty[0]["ever_aligned"], faulty[0])
                self.assertGreaterEqual(faulty[0]["rejected"], 1, faulty[0])
                self.assertGreaterEqual(faulty[0]["drops"], 1, faulty[0])
                # And the global map is what the pair alone makes: the union, every landmark on a
                # true one, no less consistent or accurate than the agent's own map.
                self.assertEqual(a["peers_aligned"], [other])
                g, loc = a["global"], a["local"]
                self.assertEqual(g["coverage"], 1.0)
                self.assertEqual(g["matched"], g["landmarks"])
                self.assertLessEqual(g["nees_mean"], loc["nees_mean"] + 1e-6)
                self.assertLessEqual(g["rmse_m"], loc["rmse_m"] + 0.01)

    def test_bad_inject_cases_are_one_line(self):
        r = self.swarm(SCENARIOS / "thesis_circle_pair.yaml", "--inject", "truncated,nonsense")
        self.assertEqual(r.returncode, 2)
        self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        self.assertIn("nonsense", r.stderr)
        self.assertFalse((self.out / "summary.json").exists())


class ExperimentOutputTest(SwarmCase):
    """M7: what a run and a sweep leave behind for the user."""

    def test_run_with_a_kill_and_a_restart_writes_a_consistent_report(self):
        r = self.swarm(SCENARIOS / "park4.yaml", "--set", "duration_s=80", "--kill", "2@30", "--restart", "2@50")
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn(f"report:  {self.out / 'report.html'}", r.stdout)
        # Not a terminal: a few plain progress lines, not one per event.
        progress = [line for line in r.stdout.splitlines() if line.startswith("t=") and "alive" in line]
        self.assertGreaterEqual(len(progress), 2)
        self.assertLessEqual(len(progress), 8)
        check_report(self, self.out, run=False)
        # `swarm report` redraws it from the run directory alone.
        r = subprocess.run(SWARM + ["report", str(self.out)], capture_output=True, text=True, timeout=120)
        self.assertEqual(r.returncode, 0, r.stderr)
        check_report(self, self.out, run=False)
        # X1: timeline.json has each map's RMSE after the rigid fit at every checkpoint, as the
        # summary has it at the end (the last checkpoint holds the final maps).
        timeline = json.loads((self.out / "timeline.json").read_text())
        summary = json.loads((self.out / "summary.json").read_text())
        for a in summary["agents"]:
            entries = timeline["agents"][str(a["id"])]
            fits = [e["local"]["rmse_aligned_m"] for e in entries if e.get("local")]
            self.assertGreater(len(fits), 3)
            self.assertTrue(all(isinstance(v, float) and 0 < v < 1 for v in fits), fits)
            self.assertAlmostEqual(entries[-1]["local"]["rmse_aligned_m"], a["local"]["rmse_aligned_m"], places=9)
        # X1: what a reader sees in a real browser.
        check_in_browser(self, self.out, self.out.parent / "report.png")

    def test_sweep_over_a_grid_with_a_kill(self):
        """X1: several --param (a grid) with seeds and a fault schedule from one command; a tidy
        CSV with a column per parameter; progress with what is left; a row of plots per parameter."""
        d = self.out.parent / "sweep"
        r = subprocess.run(SWARM + ["sweep", str(SCENARIOS / "park4.yaml"), "--param", "radio.range_m=0,40",
                                    "--param", "radio.loss_probability=0,0.5", "--seeds", "1,2",
                                    "--set", "duration_s=60", "--kill", "2@30", "--restart", "2@40",
                                    "--out", str(d)], capture_output=True, text=True, timeout=400)
        self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
        self.assertIn("8 runs, all checked", r.stdout)
        progress = [line for line in r.stdout.splitlines() if line.startswith("[")]
        self.assertEqual(len(progress), 8, r.stdout)
        self.assertTrue(all("to go)" in line for line in progress[:-1]), r.stdout)
        with open(d / "sweep.csv", newline="") as f:
            rows = list(csv.reader(f))
        self.assertEqual(rows[0], ["radio.range_m", "radio.loss_probability"] + SWEEP_HEADER)
        self.assertEqual(len(rows) - 1, 2 * 2 * 2 * 4)  # grid points x seeds x agents
        points = {(row[0], row[1], row[2]) for row in rows[1:]}
        self.assertEqual(points, {(a, b, s) for a in ("0", "40") for b in ("0", "0.5") for s in ("1", "2")})
        alive = rows[0].index("alive")
        restarted = [row for row in rows[1:] if row[rows[0].index("agent")] == "2"]
        self.assertTrue(all(row[alive] == "1" for row in restarted))  # each run's agent 2 came back
        for point in points:  # each run carried the fault schedule out
            run = d / "runs" / f"radio.range_m={point[0]}_radio.loss_probability={point[1]}_seed{point[2]}"
            summary = json.loads((run / "summary.json").read_text())
            self.assertEqual(next(a for a in summary["agents"] if a["id"] == 2)["restarts"], 1)
            options = json.loads((run / "run.json").read_text())["options"]
            self.assertEqual((options["kill"], options["restart"]), (["2@30"], ["2@40"]))
        cov = rows[0].index("coverage_global")
        at = {p: [float(row[cov]) for row in rows[1:] if row[0] == p and row[cov]] for p in ("0", "40")}
        self.assertGreater(sum(at["40"]) / len(at["40"]), sum(at["0"]) / len(at["0"]))  # range matters
        check_png(self, d / "sweep.png")
        check_sweep(self, d)


if __name__ == "__main__":
    unittest.main()
