"""scripts/mapmesh/reached.py: what of the run's data reached each agent by its end, from the
agents' stats.json and checkpoint.json (no processes).

Run: cd tests/integration && /usr/bin/python3 -m unittest reached_test
"""

import base64
import struct
import sys
import unittest
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "scripts"))
from mapmesh.reached import could_reach_until, reached_until, submap_closed  # noqa: E402


def submap(robot, index, closed_s):
    """A checkpoint's base64 submap: its header as common/map/submap_codec.h writes it, then filler."""
    header = struct.pack("<2sBBIIIdd", b"MS", 1, 0, robot, 1, index, closed_s - 30.0, closed_s)
    return base64.b64encode(header + bytes(8)).decode()


def stats(**last_heard):
    """stats.json's peers, {"r3": 88.0} for robot 3 last heard at 88 s."""
    return {"peers": [{"robot": int(k[1:]), "incarnation": 1, "last_heard": t} for k, t in last_heard.items()]}


class ReachedTest(unittest.TestCase):
    def test_the_maps_stamps_come_before_when_they_arrived(self):
        # stats.json's data_until (each map's stamp) where it is; the peers' last_heard (when the
        # last map arrived) in older runs.
        agents = {1: ({"data_until": {"2": 86.0}, "peers": [{"robot": 2, "last_heard": 88.0}]}, None),
                  2: ({"peers": [{"robot": 1, "last_heard": 88.0}]}, None)}
        self.assertEqual(reached_until(agents, 130.0, 4.0), {1: {2: 86.0}, 2: {1: 88.0}})

    def test_line_of_three_robot_three_out_of_range_at_the_end(self):
        # line3 seed 4 as it ran: robots 1 and 3 never meet; 2 last heard 3 at 88 s. Agent 1
        # holds robot 3's first two closed submaps (closed at 33.5 and 67.5 s), relayed by 2;
        # agent 3 holds none of robot 1's and heard 2 last at 88 s.
        agents = {
            1: (stats(r2=130.0), {"submaps": [submap(2, 0, 33.5), submap(3, 0, 33.5), submap(3, 1, 67.5)]}),
            2: (stats(r1=130.0, r3=88.0), {"submaps": [submap(1, 0, 33.5), submap(3, 1, 67.5)]}),
            3: (stats(r2=88.0), {"submaps": [submap(2, 1, 66.5)]}),
        }
        until = reached_until(agents, 130.0, 4.0)
        # Agent 1: robot 3's data through robot 2's maps (2 had it until 88 s, and we heard 2 to
        # the end) beats the submaps' 67.5 s.
        self.assertEqual(until[1], {3: 88.0})
        self.assertEqual(until[2], {3: 88.0})
        # Agent 3: robot 2 until 88 s; robot 1 through robot 2's maps, as 2 had it at 88 s.
        self.assertEqual(until[3], {1: 88.0, 2: 88.0})
        # With fusion joining a peer's maps carry its own data only: robot 3 reaches agent 1 through
        # the submaps it holds, robot 1 never reached agent 3.
        joining = reached_until(agents, 130.0, 4.0, maps_relay=False)
        self.assertEqual(joining[1], {3: 67.5})
        self.assertEqual(joining[2], {3: 88.0})
        self.assertEqual(joining[3], {1: 0.0, 2: 88.0})

    def test_everything_reached_and_closed_submaps_count(self):
        agents = {
            1: (stats(r2=129.0), None),
            2: (stats(r1=60.0), {"submaps": [submap(1, 3, 127.5)]}),  # out of range, but the chain arrived
        }
        self.assertEqual(reached_until(agents, 130.0, 4.0), {1: {}, 2: {}})
        # A robot never heard of at all: nothing of it reached the agent.
        self.assertEqual(reached_until({1: (None, None), 2: (stats(r1=130.0), None)}, 130.0, 4.0),
                         {1: {2: 0.0}, 2: {}})

    def test_a_restarted_peer_brings_what_its_earlier_incarnations_held(self):
        # Robot 2 restarted: its last process took nothing of robot 3, but its maps carry its
        # earlier incarnation's, robot 3's included: what reached us of 2 may hold 3's data.
        agents = {1: (stats(r2=120.0), None), 2: (stats(r1=120.0), None), 3: (stats(), None)}
        self.assertEqual(reached_until(agents, 130.0, 4.0)[1], {2: 120.0, 3: 0.0})
        self.assertEqual(reached_until(agents, 130.0, 4.0, restarted={2})[1], {2: 120.0, 3: 120.0})

    def test_the_chains_closing_times_in_stats_come_first(self):
        chains = {"submaps": {"chains": [{"robot": 3, "incarnation": 1, "count": 2, "closed_until": 67.5}]}}
        agents = {1: (chains, {"submaps": [submap(3, 0, 33.5)]}), 3: (stats(r1=130.0), None)}
        self.assertEqual(reached_until(agents, 130.0, 4.0)[1], {3: 67.5})

    def test_what_is_not_a_submap_is_left_out(self):
        self.assertEqual(submap_closed(submap(5, 2, 40.0)), (5, 40.0))
        for bad in ["", "not base64!", base64.b64encode(b"MS\x01").decode(),
                    base64.b64encode(b"XX" + bytes(40)).decode(), None]:
            self.assertIsNone(submap_closed(bad), bad)


def line(xs_at):
    """Trajectories along the x axis: {robot: [(t, x, 0), ...]} from {robot: {t: x}}."""
    return {r: [(t, x, 0.0) for t, x in sorted(at.items())] for r, at in xs_at.items()}


class CouldReachTest(unittest.TestCase):
    def test_a_relay_that_met_both_carries_the_data_it_holds(self):
        # Robot 2 meets 1 at t = 1 and 3 at t = 2; 1 and 3 never meet (25 m disc). Robot 1's
        # data up to t = 1 could reach agent 3 (through 2, which meets 3 after), nothing of it
        # later; robot 2's up to t = 2. Agent 1 gets robot 3's data up to nothing: 3 meets 2
        # only after 2 left 1, so its first step's time is the bound.
        traj = line({1: {0: 0.0, 1: 0.0, 2: 0.0, 3: 0.0},
                     2: {0: 100.0, 1: 20.0, 2: 80.0, 3: 200.0},
                     3: {0: 300.0, 1: 300.0, 2: 100.0, 3: 400.0}})
        self.assertEqual(could_reach_until(traj, 25.0, 3), {1: 1, 2: 2})
        self.assertEqual(could_reach_until(traj, 25.0, 1), {2: 1, 3: 0})

    def test_hops_within_one_step_and_everything_in_range_at_the_end(self):
        # At the last step 1-2-3 stand 20 m apart in a line: every robot's data reaches every
        # agent through the middle one (nothing is left out); before, they were apart.
        traj = line({1: {0: 0.0, 5: 0.0}, 2: {0: 500.0, 5: 20.0}, 3: {0: 1000.0, 5: 40.0}})
        for agent in (1, 2, 3):
            self.assertEqual(could_reach_until(traj, 25.0, agent), {}, agent)
        # With a 15 m disc nobody links: each other robot is bounded by the first step.
        self.assertEqual(could_reach_until(traj, 15.0, 1), {2: 0, 3: 0})

    def test_an_agent_not_in_the_trajectories_is_reached_by_nothing_to_say(self):
        self.assertEqual(could_reach_until(line({1: {0: 0.0}}), 25.0, 9), {})


if __name__ == "__main__":
    unittest.main()
