"""A run as an MCAP file (mapmesh/mcap.py) with Foxglove's message types in JSON, so that Foxglove
(or any MCAP reader) plays it back over scenario time (docs/EXPORTS.md):

  /tf                       foxglove.FrameTransforms  where each agent's map frame agent_N lies in
                                                      the world (as the report draws it), at the start
  /truth/landmarks          foxglove.SceneUpdate      the true landmarks, at the start
  /truth/agent_N/pose       foxglove.PoseInFrame      robot N's true pose (frame world), per truth sample
  /agent_N/pose             foxglove.PoseInFrame      agent N's estimated pose (frame agent_N), per sample
  /agent_N/local_map        foxglove.SceneUpdate      its local map at each snapshot: a flat cylinder per
  /agent_N/global_map                                 landmark, its 95 % covariance ellipse
  /radio/links              foxglove.SceneUpdate      a line between each pair of robots in radio range,
                                                      every radio.links_period_s (true positions)
  /alignments               foxglove.Log              an agent aligning a peer, or dropping it
  /events                   foxglove.Log              kills, restarts and pauses

Log time is scenario time. The JSON schemas are written here from Foxglove's published message
definitions, for the fields these messages use. Standard library only."""

import math
import sys

from .mcap import Writer
from .rundir import (HISTORY, TRAJECTORY, TRUTH, alignment_changes, links_from_spans, pose_at, published_spans,
                     radio_links, read_history, read_json,
                     truth_robots)

CHI2_95_2DOF = 5.991464547107979  # the 95 % quantile of chi-square with 2 degrees of freedom
ELLIPSE_HEIGHT_M = 0.02
LOG_INFO, LOG_WARNING, LOG_ERROR = 2, 3, 4

# ----- Foxglove's message types as JSON schemas -----------------------------------------------
_NUM = {"type": "number"}
_TIME = {"type": "object", "properties": {"sec": {"type": "integer", "minimum": 0},
                                          "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}}
_VEC3 = {"type": "object", "properties": {"x": _NUM, "y": _NUM, "z": _NUM}}
_QUAT = {"type": "object", "properties": {"x": _NUM, "y": _NUM, "z": _NUM, "w": _NUM}}
_POSE = {"type": "object", "properties": {"position": _VEC3, "orientation": _QUAT}}
_COLOR = {"type": "object", "properties": {"r": _NUM, "g": _NUM, "b": _NUM, "a": _NUM}}
_STR = {"type": "string"}


def _object(title, **properties):
    return {"title": title, "type": "object", "properties": properties}


POSE_IN_FRAME = _object("foxglove.PoseInFrame", timestamp=_TIME, frame_id=_STR, pose=_POSE)
FRAME_TRANSFORMS = _object("foxglove.FrameTransforms", transforms={"type": "array", "items": _object(
    "foxglove.FrameTransform", timestamp=_TIME, parent_frame_id=_STR, child_frame_id=_STR, translation=_VEC3,
    rotation=_QUAT)})
LOG = _object("foxglove.Log", timestamp=_TIME, level={"type": "integer", "minimum": 0, "maximum": 5}, message=_STR,
              name=_STR, file=_STR, line={"type": "integer", "minimum": 0})
_PRIMITIVE = {"type": "array", "items": _object("primitive", pose=_POSE, size=_VEC3, bottom_scale=_NUM,
                                                top_scale=_NUM, color=_COLOR)}
_LINE_TYPE = {"type": "integer", "minimum": 0, "maximum": 2}  # LINE_STRIP, LINE_LOOP, LINE_LIST
_LINES = {"type": "array", "items": _object(
    "foxglove.LinePrimitive", type=_LINE_TYPE, pose=_POSE, thickness=_NUM, scale_invariant={"type": "boolean"},
    points={"type": "array", "items": _VEC3}, color=_COLOR, colors={"type": "array", "items": _COLOR},
    indices={"type": "array", "items": {"type": "integer"}})}
_KEY_VALUE = {"type": "array", "items": _object("foxglove.KeyValuePair", key=_STR, value=_STR)}
SCENE_UPDATE = _object("foxglove.SceneUpdate", deletions={"type": "array", "items": _object(
    "foxglove.SceneEntityDeletion", timestamp=_TIME, type={"type": "integer", "minimum": 0, "maximum": 1}, id=_STR)},
    entities={"type": "array", "items": _object(
        "foxglove.SceneEntity", timestamp=_TIME, frame_id=_STR, id=_STR, lifetime=_TIME,
        frame_locked={"type": "boolean"}, metadata=_KEY_VALUE, arrows={"type": "array"}, cubes={"type": "array"},
        spheres=_PRIMITIVE, cylinders=_PRIMITIVE, lines=_LINES, triangles={"type": "array"},
        texts={"type": "array"}, models={"type": "array"})})


# ----- values ---------------------------------------------------------------------------------
def stamp(t):
    ns = max(0, int(round(t * 1e9)))
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def ns(t):
    return max(0, int(round(t * 1e9)))


def pose(x, y, theta=0.0, z=0.0):
    return {"position": {"x": x, "y": y, "z": z},
            "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(theta / 2), "w": math.cos(theta / 2)}}


def colour(i, a=1.0):
    """tab10's colour i (the report's agent colours)."""
    table = ["1f77b4", "ff7f0e", "2ca02c", "d62728", "9467bd", "8c564b", "e377c2", "7f7f7f", "bcbd22", "17becf"]
    h = table[i % len(table)]
    return {"r": int(h[0:2], 16) / 255, "g": int(h[2:4], 16) / 255, "b": int(h[4:6], 16) / 255, "a": a}


def ellipse(cov):
    """(length, width, angle) of the 95 % ellipse of a 2 x 2 covariance [xx, xy, yy], or None."""
    if not (isinstance(cov, list) and len(cov) == 3 and all(isinstance(v, (int, float)) for v in cov)):
        return None
    a, b, c = cov
    mean, diff = (a + c) / 2, math.hypot((a - c) / 2, b)
    l1, l2 = mean + diff, max(mean - diff, 0.0)
    if not (math.isfinite(l1) and l1 >= 0):
        return None
    return 2 * math.sqrt(CHI2_95_2DOF * l1), 2 * math.sqrt(CHI2_95_2DOF * l2), 0.5 * math.atan2(2 * b, a - c)


def map_update(m, frame, entity, t, col):
    cylinders = []
    for lm in (m or {}).get("landmarks", []):
        e = ellipse(lm.get("cov"))
        if e is None or not all(isinstance(lm.get(k), (int, float)) for k in ("x", "y")):
            continue
        cylinders.append({"pose": pose(lm["x"], lm["y"], e[2]), "size": {"x": e[0], "y": e[1], "z": ELLIPSE_HEIGHT_M},
                          "bottom_scale": 1.0, "top_scale": 1.0, "color": col})
    return {"deletions": [], "entities": [{
        "timestamp": stamp(t), "frame_id": frame, "id": entity, "lifetime": stamp(0), "frame_locked": True,
        "metadata": [{"key": "landmarks", "value": str(len(cylinders))}], "arrows": [], "cubes": [], "spheres": [],
        "cylinders": cylinders, "lines": [], "triangles": [], "texts": [], "models": []}]}


def log(t, level, name, message):
    return {"timestamp": stamp(t), "level": level, "message": message, "name": name, "file": "", "line": 0}


def snapshots(run, rid):
    """[(t, snapshot path prefix)] of an agent's history.jsonl, once each, in time order."""
    out, seen = [], set()
    for e in read_history(run.path(HISTORY, rid)):
        snap = e.get("snapshot")
        if isinstance(snap, str) and snap not in seen and isinstance(e.get("t"), (int, float)):
            seen.add(snap)
            out.append((float(e["t"]), snap))
    return out


def run_duration(summary, truth):
    return summary.get("sim_duration_s") or (truth or {}).get("duration_s") or 0.0


def export_mcap(run, summary, path):
    """Writes the run to path; returns {topic: messages written}."""
    path.parent.mkdir(parents=True, exist_ok=True)
    w = Writer(profile="", library="mapmesh swarm export")
    truth = run.read_if_present(TRUTH) or {}
    robots = truth_robots(truth)
    agents = [a for a in summary.get("agents", []) if isinstance(a, dict)]
    colours = {a["id"]: colour(i) for i, a in enumerate(agents)}
    write_frames(w, agents)
    write_truth_landmarks(w, truth)
    for a in agents:
        write_agent(w, run, a["id"], robots.get(a["id"]) or {}, colours[a["id"]])
    write_radio_links(w, run, robots, run_duration(summary, truth))
    write_logs(w, run, summary, agents)
    counts = w.finish(path)
    for c in w.channels:  # a channel with no message is counted as such
        counts.setdefault(c[2], 0)
    return path, counts


def write_frames(w, agents):
    """/tf: each agent's map frame in the world (at the world's origin where it is not known)."""
    tf = w.channel("/tf", "foxglove.FrameTransforms", FRAME_TRANSFORMS)
    transforms = []
    for a in agents:
        frame = a.get("frame_in_world")
        if not (isinstance(frame, list) and len(frame) == 3):
            print(f"swarm export: agent {a['id']}: where its map frame lies is not known; drawn at the world's "
                  "origin", file=sys.stderr)
            frame = [0.0, 0.0, 0.0]
        transforms.append({"timestamp": stamp(0), "parent_frame_id": "world", "child_frame_id": f"agent_{a['id']}",
                           "translation": {"x": frame[0], "y": frame[1], "z": 0.0},
                           "rotation": pose(0, 0, frame[2])["orientation"]})
    w.message(tf, 0, {"transforms": transforms})


def write_truth_landmarks(w, truth):
    """/truth/landmarks, where the run knows them."""
    if not truth.get("landmarks"):
        return
    spheres = [{"pose": pose(lm[1], lm[2]) if isinstance(lm, list) else pose(lm["x"], lm["y"]),
                "size": {"x": 0.3, "y": 0.3, "z": 0.3}, "bottom_scale": 1.0, "top_scale": 1.0,
                "color": {"r": 0.1, "g": 0.1, "b": 0.1, "a": 0.8}} for lm in truth["landmarks"]]
    update = map_update(None, "world", "truth/landmarks", 0.0, None)
    update["entities"][0]["spheres"] = spheres
    update["entities"][0]["metadata"] = [{"key": "landmarks", "value": str(len(spheres))}]
    w.message(w.channel("/truth/landmarks", "foxglove.SceneUpdate", SCENE_UPDATE), 0, update)


def write_agent(w, run, rid, robot, rgb):
    """One agent's channels: its true poses, its estimated ones, and its local and global maps at
    every snapshot."""
    if robot.get("trajectory"):
        ch = w.channel(f"/truth/agent_{rid}/pose", "foxglove.PoseInFrame", POSE_IN_FRAME)
        for t, x, y, theta in (p[:4] for p in robot["trajectory"]):
            w.message(ch, ns(t), {"timestamp": stamp(t), "frame_id": "world", "pose": pose(x, y, theta)})
    traj = run.read_if_present(TRAJECTORY, rid) or {}
    if traj.get("poses"):
        ch = w.channel(f"/agent_{rid}/pose", "foxglove.PoseInFrame", POSE_IN_FRAME)
        for t, x, y, theta in (p[:4] for p in traj["poses"]):
            w.message(ch, ns(t), {"timestamp": stamp(t), "frame_id": f"agent_{rid}", "pose": pose(x, y, theta)})
    for kind in ("local", "global"):
        ch = None
        for t, snap in snapshots(run, rid):
            f = run.path(f"{snap}_{kind}.json", rid)
            if not f.exists():
                continue
            try:
                m = read_json(f)
            except (OSError, ValueError):
                continue
            ch = ch or w.channel(f"/agent_{rid}/{kind}_map", "foxglove.SceneUpdate", SCENE_UPDATE)
            w.message(ch, ns(t), map_update(m, f"agent_{rid}", f"agent_{rid}/{kind}_map", t,
                                            dict(rgb, a=0.5 if kind == "local" else 0.8)))


def write_radio_links(w, run, robots, duration):
    """/radio/links: as the feeder published them (feeder.json), or for a run written before it
    recorded them, from the true positions and radio.range_m (the disc)."""
    resolved = (run.read_if_present("run.json") or {}).get("resolved") or {}
    range_m, period = resolved.get("radio.range_m"), resolved.get("radio.links_period_s") or 0.5
    published = published_spans(run.read_if_present("feeder.json"))
    if not ((published is not None or isinstance(range_m, (int, float))) and duration and len(robots) > 1):
        return
    ch = w.channel("/radio/links", "foxglove.SceneUpdate", SCENE_UPDATE)
    tables = links_from_spans(published, period, duration) if published is not None else \
        radio_links(robots, range_m, period, duration)
    for t, pairs in tables:
        points = []
        for ra, rb in pairs:
            pa, pb = pose_at(robots[ra]["trajectory"], t), pose_at(robots[rb]["trajectory"], t)
            points += [{"x": pa[0], "y": pa[1], "z": 0.0}, {"x": pb[0], "y": pb[1], "z": 0.0}]
        update = map_update(None, "world", "radio/links", t, None)
        update["entities"][0]["lines"] = [{
            "type": 2, "pose": pose(0, 0), "thickness": 2.0, "scale_invariant": True, "points": points,
            "color": {"r": 0.2, "g": 0.6, "b": 0.2, "a": 0.7}, "colors": [], "indices": []}]
        update["entities"][0]["metadata"] = [{"key": "links", "value": str(len(pairs))}]
        w.message(ch, ns(t), update)


def write_logs(w, run, summary, agents):
    """/alignments (each agent's peers aligned and lost, from its history) and /events (kills,
    restarts and pauses)."""
    alignments = w.channel("/alignments", "foxglove.Log", LOG)
    for a in agents:
        for t, peer, aligned in alignment_changes(read_history(run.path(HISTORY, a["id"]))):
            w.message(alignments, ns(t), log(t, LOG_INFO if aligned else LOG_WARNING, f"agent_{a['id']}",
                                             f"agent {a['id']} {'aligned' if aligned else 'no longer holds'} "
                                             f"peer {peer}"))
    events = w.channel("/events", "foxglove.Log", LOG)
    for key, level, what in (("kills", LOG_ERROR, "killed"), ("restarts", LOG_INFO, "restarted"),
                             ("pauses", LOG_WARNING, "paused")):
        for e in summary.get(key) or []:
            if isinstance(e, dict) and isinstance(e.get("t"), (int, float)):
                extra = f" for {e['seconds']} s" if key == "pauses" and "seconds" in e else ""
                w.message(events, ns(e["t"]), log(e["t"], level, "swarm", f"agent {e.get('id')} {what}{extra}"))
