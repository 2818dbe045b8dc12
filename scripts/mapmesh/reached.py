"""What of the run's data reached each agent by its end (issue J1's gap): each other robot's data
up to the last moment any of it reached the agent, through the robot's own maps and open
submaps, its open submap relayed once it fell silent (both in stats.json's data_until), the
closed submaps the agent holds of it (any number of hops), or a peer's maps that fused it (two
hops).
Where that is less than the whole run for some robot (a robot out of range at the end, a chain
whose last submaps never came), the optimum of what reached the agent is its limit: no merging
can recover what never arrived. Each moment is an upper bound of what reached the agent (a map
holds its sender's data up to its stamp at most; a peer's map fused its peers' data up to when
it last took theirs), so the limit is never made easier than it is. Pure: reads the agent files
given, no processes."""

import base64
import binascii

from . import submap_codec


def submap_closed(encoded):
    """(robot, closed_s) of a base64 submap as checkpoint.json holds it (its header: the submap
    codec's); None when it is not one."""
    try:
        robot, _, _, _, closed, _ = submap_codec.header(base64.b64decode(encoded, validate=True))
    except (binascii.Error, TypeError, ValueError):
        return None
    return robot, closed


def last_heard(stats):
    """{robot: the time up to which the maps the agent took of it hold its data} from its
    stats.json: `data_until` (each map's stamp, the sender's data up to then), else the peers'
    `last_heard` (when the last map arrived: later still)."""
    stats = stats or {}
    if isinstance(stats.get("data_until"), dict):
        return {int(r): float(t) for r, t in stats["data_until"].items() if isinstance(t, (int, float))}
    heard = {}
    for p in stats.get("peers", []):
        if "robot" in p and isinstance(p.get("last_heard"), (int, float)):
            heard[p["robot"]] = max(heard.get(p["robot"], 0.0), float(p["last_heard"]))
    return heard


def closed_until(stats, checkpoint):
    """{robot: the latest closing time of its submaps the agent holds}: stats.json's chains
    (`closed_until`), else the submaps of its checkpoint.json."""
    latest = {}
    chains = ((stats or {}).get("submaps") or {}).get("chains")
    if chains and all("closed_until" in c for c in chains):
        for c in chains:
            latest[c["robot"]] = max(latest.get(c["robot"], 0.0), float(c["closed_until"]))
        return latest
    for encoded in (checkpoint or {}).get("submaps", []):
        s = submap_closed(encoded)
        if s:
            latest[s[0]] = max(latest.get(s[0], 0.0), s[1])
    return latest


def reached_until(agents, end_s, slack_s, restarted=(), maps_relay=True):
    """agents: {id: (stats, checkpoint)} (either may be None). Per agent, {robot: t} for every
    other robot of the run whose data reached it only up to t < end_s - slack_s (the rest reached
    it whole); an empty dict when everything did. A `restarted` peer's maps also carry what its
    earlier incarnations held, which its last process's stats do not count: all that reached it
    by the time of its map is taken to have reached us with it. maps_relay: whether a peer's maps
    carry other robots' data (its global map, with agent.fusion ci); a joining agent publishes
    its local map only, and what it relays of others are their submaps, which the holder counts
    itself (closed ones held, open ones in data_until)."""
    heard = {a: last_heard(stats) for a, (stats, _) in agents.items()}
    closed = {a: closed_until(stats, checkpoint) for a, (stats, checkpoint) in agents.items()}
    until = {}
    for a in agents:
        mine = {}
        for r in agents:
            if r == a:
                continue
            t = max(heard[a].get(r, 0.0), closed[a].get(r, 0.0))
            for p, at in heard[a].items() if maps_relay else ():  # r's data in p's maps, as p last had it
                if p != r:
                    t = max(t, at if p in restarted else min(at, heard.get(p, {}).get(r, 0.0)))
            if t < end_s - slack_s:
                mine[r] = t
        until[a] = mine
    return until


def could_reach_until(trajectories, range_m, agent):
    """What of the run's data could have reached `agent` by the run's end at best, over the radio
    disc of `range_m` metres: per other robot, the latest time t such that a time-respecting path
    of links (robots within range of each other at a common time step, any number of hops within
    one step, data held while a robot carries it) leads from that robot at t to the agent by the
    last step. `trajectories` is {robot: [(t, x, y), ...]} sampled at common times (truth.json's
    robots). Returns {robot: t} for the robots whose data could not all reach it (a robot never
    linked to the agent at all is at the first step's time, a lower bound); the others are left
    out, as reached_until leaves them out. Instant delivery, no loss: a floor below which no
    exchange can bring an agent's data, whatever it relays."""
    positions = {r: {round(t, 6): (x, y) for t, x, y in samples} for r, samples in trajectories.items()}
    times = sorted(set().union(*(p.keys() for p in positions.values())), reverse=True)
    if agent not in positions or not times:
        return {}
    holders = {agent}  # robots that can still bring data to the agent by the end, going back in time
    latest = {}
    for t in times:
        grown = True
        while grown:
            grown = False
            for r, p in positions.items():
                if r in holders or t not in p:
                    continue
                if any(t in positions[h] and _within(p[t], positions[h][t], range_m) for h in holders):
                    holders.add(r)
                    latest[r] = t
                    grown = True
    end = times[0]
    return {r: latest.get(r, times[-1]) for r in positions if r != agent and latest.get(r) != end}


def _within(a, b, range_m):
    return (a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 <= range_m * range_m
