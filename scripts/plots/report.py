#!/usr/bin/python3
"""One HTML page on a swarm run written by `scripts/swarm run SCENARIO --out DIR`.

Usage: /usr/bin/python3 scripts/plots/report.py DIR

Writes DIR/report.html and its figures in DIR/report/*.png (the page refers to them by
relative paths, so the run directory can be copied or served as it is; the page has no
script and no external URL). Prints the page's path on stdout.

The page shows:
  - the run: scenario, simulated duration, wall time, real-time factor, kills, restarts and pauses;
  - the limit (table#reference-table): the centralized batch optimum of the run's data, the
    known-pose map and each robot's own batch optimum (summary.json `reference`), or why there
    is none; the summary table's gap columns divide each map's RMSE by its limit's;
  - the summary table (table#summary: one row per agent, cells data-key="<summary path>" with
    the exact JSON value in data-value) and a table of peers and events. A map's accuracy figure
    is its RMSE after a least-squares rigid fit of the map to the landmark truth
    (rmse_aligned_m); its RMSE in the robot's true map frame (rmse_m), which adds the map's
    heading drift, is shown beside it (the table, each map figure's title and caption);
  - under it, the maps whose mean NEES is outside the consistency band [1, 3] (their cells red);
  - per agent, its maps in two panels: true landmarks (grey, darker when some robot saw them),
    true trajectory, the estimated local and global maps with their 95 % ellipses and the
    estimated trajectory. Left, placed by the agent's frame_in_world from summary.json (the
    heading drift shows); when a summary has no frame_in_world (older runs) the frame is taken
    from the truth, as mapmesh-eval does: the robot's true pose at the map frame's origin
    stamp; a frame_in_world of null means the pose is unknown: the maps are drawn in the agent's
    own frame. Right, each map placed by its own rigid fit to the truth (local.fit_in_world,
    global.fit_in_world): what the accuracy figures measure;
  - from timeline.json (when the run has one): the RMSE after the rigid fit over time; per pair
    of agents, when they were in radio range (truth and run.json's radio.range_m), when the
    receiver got maps from the sender and when it aligned it; mean NEES (each map kind on its own
    axis, the band [1, 3] drawn), coverage and bytes over time; no line across the time an agent
    was dead. Without it the page says so;
  - in the limit section, from timeline.json too, the gap over time: each global map over the
    centralized optimum of the data up to each time swarm run solved it for (--gap-samples).

Reads summary.json (required), truth.json, timeline.json, run.json and agent_<id>/{local_map,
global_map,trajectory,stats}.json and history.jsonl (each optional; whatever is missing is
skipped with a note).
Needs Debian's python3-matplotlib and python3-numpy (scripts/install-deps installs them)."""

import html
import json
import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1]))
from plotlib import directory_argument, ellipse95, plt  # noqa: E402
from mapmesh.columns import HTML_COLUMNS, lookup  # noqa: E402
from mapmesh.rundir import (GLOBAL_MAP, HISTORY, LOCAL_MAP, REPORT, STATS, SUMMARY, TIMELINE,  # noqa: E402
                            TRAJECTORY, TRUTH, RunDir, alignment_changes, pose_at, published_spans, radio_links,
                            radio_spans, read_history, truth_robots)

import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection, PatchCollection  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

DPI = 100
# Expected NEES of a consistent 2-D estimate (its degrees of freedom), and the band a map's mean
# NEES is counted consistent in (flagged in the summary outside it).
NEES_EXPECTED = 2.0
NEES_BAND = (1.0, 3.0)
DASH = "\u2013"  # what a cell shows for a null value

LOCAL_COLOUR = "tab:blue"
GLOBAL_COLOUR = "tab:orange"


# ----- values and text ----------------------------------------------------------------------
def format_number(v):
    """A number for a table cell: integers as they are, floats to 3 significant digits (never
    dropping integer digits: 1234.5 shows as 1235)."""
    if v is None:
        return DASH
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, int):
        return str(v)
    if not math.isfinite(v):
        return str(v)
    if v == 0:
        return "0"
    magnitude = math.floor(math.log10(abs(v)))
    if magnitude < -4:
        return f"{v:.2e}"
    return f"{v:.{max(0, 2 - magnitude)}f}"


def cell_text(value, count=False):
    """The text of a summary-table cell (data-value keeps the exact value); count: a list shows
    its number of items."""
    if value is None:
        return DASH
    if count and isinstance(value, list):
        return str(len(value))
    if isinstance(value, (int, float)):
        return format_number(value)
    if isinstance(value, list):
        return ", ".join(str(x) for x in value) or DASH
    return str(value)


def seconds(v):
    return DASH if v is None else f"{v:.1f} s"


def rmse_text(agent):
    """An agent's map accuracy in words: the RMSE after a rigid fit of each map to the truth
    first, the RMSE in the robot's true map frame beside it."""
    loc, glo = agent.get("local") or {}, agent.get("global") or {}
    return (f"RMSE after rigid fit local {cell_text(loc.get('rmse_aligned_m'))} m / global "
            f"{cell_text(glo.get('rmse_aligned_m'))} m (true frame {cell_text(loc.get('rmse_m'))} m / "
            f"{cell_text(glo.get('rmse_m'))} m)")


# ----- geometry -----------------------------------------------------------------------------
def to_world(frame, xy):
    """Points (N x 2, in a frame whose pose in the world is frame = [x0, y0, theta]) in the world."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    if frame is None:
        return xy
    c, s = math.cos(frame[2]), math.sin(frame[2])
    return np.column_stack([frame[0] + c * xy[:, 0] - s * xy[:, 1], frame[1] + s * xy[:, 0] + c * xy[:, 1]])


def ellipse_patches(xy, covs, theta):
    """95 % ellipses (matplotlib Ellipse patches) of landmarks at world points xy with their
    [sxx, sxy, syy] covariances, given in a frame rotated by theta from the world."""
    c, s = math.cos(theta), math.sin(theta)
    rot = np.array([[c, -s], [s, c]])
    patches = []
    for (x, y), cov in zip(xy, covs):
        if cov is None or len(cov) != 3 or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in cov):
            continue
        patches.append(ellipse95((x, y), rot @ np.array([[cov[0], cov[1]], [cov[1], cov[2]]]) @ rot.T))
    return patches


# ----- loading ------------------------------------------------------------------------------
class Run(RunDir):
    """The files of one run directory; `notes` collects what is missing or unreadable."""

    def __init__(self, d):
        super().__init__(d)
        self.summary = self.load(SUMMARY, required=True)
        self.truth = self.load(TRUTH)
        self.timeline = self.load(TIMELINE, quiet=True)
        self.agents = [a for a in self.summary.get("agents", []) if isinstance(a, dict)]
        self.ids = [a.get("id") for a in self.agents]
        self.colours, self.groups = agent_colours(self.ids)
        self.truth_robots = truth_robots(self.truth)
        # Kills and restarts as the summary and the timeline list them (the same, normally).
        self.kills = events(self.summary.get("kills"), (self.timeline or {}).get("kills"))
        self.restarts = events(self.summary.get("restarts"), (self.timeline or {}).get("restarts"))
        self.pauses = events(self.summary.get("pauses"), (self.timeline or {}).get("pauses"))
        self.duration = self.summary.get("sim_duration_s") or (self.truth or {}).get("duration_s")
        resolved = (self.load("run.json", quiet=True) or {}).get("resolved") or {}
        self.range_m = resolved.get("radio.range_m")  # None for a run without run.json
        self.links_period = resolved.get("radio.links_period_s") or 0.5

    def radio_spans(self):
        """{(a, b): [(start, end)]} in which robots a < b heard each other: the link tables the
        feeder published (feeder.json, whatever radio.model decided); for a run written before
        the feeder recorded them, from the truth and radio.range_m of run.json (the disc), or {}
        when the run does not say its range."""
        published = published_spans(self.load("feeder.json", quiet=True))
        if published is not None:
            return published
        if not isinstance(self.range_m, (int, float)) or not self.duration or not self.truth_robots:
            return {}
        return radio_spans(radio_links(self.truth_robots, self.range_m, self.links_period, self.duration),
                           self.links_period)

    def alignments(self, rid):
        """[(t, peer, aligned?)] of agent rid's history.jsonl."""
        return alignment_changes(read_history(self.path(HISTORY, rid)))

    def agent_file(self, rid, name):
        return self.load(name, rid, quiet=True)

    def dead_intervals(self, rid):
        """[(killed at, restarted at or the end of the run)] of one agent."""
        out = []
        for kid, t in sorted(self.kills, key=lambda k: k[1]):
            if kid != rid:
                continue
            back = [r for i, r in self.restarts if i == rid and r >= t]
            out.append((t, min(back) if back else (self.duration or t)))
        return out


# Up to this many agents each has a colour of its own; beyond, the agents are cut into at most
# COLOUR_GROUPS groups of consecutive ids, a hue each (shades within it), and legends name groups.
DISTINCT_COLOURS = 16
COLOUR_GROUPS = 8


def agent_colours(ids):
    """({id: RGBA}, [(label, RGBA, [ids])]): a colour per agent, distinct up to DISTINCT_COLOURS
    (tab10, then tab20 with its dark shades first), grouped beyond (groups empty when not)."""
    n = len(ids)
    if n <= 10:
        return {rid: plt.get_cmap("tab10")(i) for i, rid in enumerate(ids)}, []
    if n <= DISTINCT_COLOURS:
        order = list(range(0, 20, 2)) + list(range(1, 20, 2))  # the dark shade of each hue, then the light
        return {rid: plt.get_cmap("tab20")(order[i]) for i, rid in enumerate(ids)}, []
    size = -(-n // COLOUR_GROUPS)
    colours, groups = {}, []
    for g in range(0, n, size):
        members = ids[g:g + size]
        base = np.array(plt.get_cmap("tab10")(len(groups)))
        for j, rid in enumerate(members):  # shades from the hue to a lighter one
            mix = 0.45 * j / max(1, len(members) - 1)
            colours[rid] = tuple(base[:3] * (1 - mix) + mix) + (1.0,)
        groups.append((f"agents {members[0]}-{members[-1]}" if len(members) > 1 else f"agent {members[0]}",
                       tuple(base), members))
    return colours, groups


def agent_label(run, rid):
    """The legend label of agent rid's line: its own, or its group's on the group's first agent
    (None on the others: one legend entry per group)."""
    if not run.groups:
        return f"agent {rid}"
    for label, _, members in run.groups:
        if rid == members[0]:
            return label
    return None


def pauses_text(pauses):
    """'agent 2 at 30 s for 10 s (wall)' for each pause of summary.json."""
    return "; ".join(f"agent {p.get('id')} at {format_number(p.get('t'))} s "
                     f"for {format_number(p.get('seconds'))} s (wall)"
                     for p in pauses if isinstance(p, dict)) or DASH


def events(*lists):
    """[(agent id, t)] in time order of kill or restart lists ([{"id", "t"}, ...]), merged."""
    out = {(e.get("id"), float(e["t"])) for items in lists for e in items or []
           if isinstance(e, dict) and isinstance(e.get("t"), (int, float))}
    return sorted(out, key=lambda e: (e[1], str(e[0])))


def agent_frame(run, agent, trajectory, stats):
    """(pose of the agent's map frame in the world or None, how it is known)."""
    if "frame_in_world" in agent:
        frame = agent["frame_in_world"]
        if not (isinstance(frame, list) and len(frame) == 3
                and all(isinstance(v, (int, float)) and math.isfinite(v) for v in frame)):
            return None, "own frame (pose unknown)"
        return [float(v) for v in frame], "world frame"
    # Older summaries: the robot's true pose at the frame's origin stamp, as mapmesh-eval takes it.
    robot = run.truth_robots.get(agent.get("id"))
    if robot is None or not (run.truth or {}).get("headings_known", False):
        return None, "own frame (pose unknown)"
    stamp = (trajectory or {}).get("frame_origin_stamp")
    if stamp is None:
        stamp = (stats or {}).get("frame_origin_stamp")
    if stamp is None:
        frame = robot.get("start")
    else:
        frame = pose_at(robot.get("trajectory") or [], stamp) or robot.get("start")
    if frame is None:
        return None, "own frame (pose unknown)"
    return frame, "world frame (true pose at frame origin)"


# ----- map figures --------------------------------------------------------------------------
def landmark_arrays(m):
    lms = [lm for lm in (m or {}).get("landmarks", []) if isinstance(lm.get("x"), (int, float))
           and isinstance(lm.get("y"), (int, float))]
    return np.array([[lm["x"], lm["y"]] for lm in lms], dtype=float).reshape(-1, 2), [lm.get("cov") for lm in lms]


def nice_scale(x):
    """The largest of 1, 2, 5, 10, 20, 50, ... not above x (at least 1)."""
    best = 1
    for k in range(0, 7):
        for m in (1, 2, 5):
            if m * 10 ** k <= x:
                best = m * 10 ** k
    return best


def draw_errors(ax, run, maps, handles):
    """The error vectors after the rigid fit: from each true landmark to where the map (placed by
    its fit) puts it, by signature, scaled up by one factor for all (said in the legend) so that
    centimetres show on a map of tens of metres. maps: [(map, frame, colour, label)]."""
    truth = {lm.get("id"): (lm["x"], lm["y"]) for lm in (run.truth or {}).get("landmarks", [])
             if isinstance(lm.get("x"), (int, float)) and isinstance(lm.get("y"), (int, float))}
    pairs = []
    for m, frame, colour, label in maps:
        lms = [lm for lm in (m or {}).get("landmarks", []) if isinstance(lm.get("signature"), int)
               and lm["signature"] in truth and isinstance(lm.get("x"), (int, float))
               and isinstance(lm.get("y"), (int, float))]
        if lms:
            est = to_world(frame, [[lm["x"], lm["y"]] for lm in lms])
            true = np.array([truth[lm["signature"]] for lm in lms], dtype=float)
            pairs.append((true, est - true, colour, label))
    if not pairs:
        return
    errors = np.concatenate([np.hypot(d[:, 0], d[:, 1]) for _, d, _, _ in pairs])
    span = np.ptp(np.vstack([t for t, _, _, _ in pairs]), axis=0).max() if len(errors) > 1 else 1.0
    median = float(np.median(errors))
    scale = nice_scale(0.03 * span / median) if median > 0 else 1
    for true, d, colour, label in pairs:
        segments = np.stack([true, true + scale * d], axis=1)
        ax.add_collection(LineCollection(segments, colors=[colour], linewidths=0.9, alpha=0.9, zorder=5))
        handles.append(Line2D([], [], color=colour, lw=0.9, label=f"{label} error \u00d7{scale:g} (from the truth)"))


def valid_frame(frame):
    """frame as [x, y, theta] floats when it is one, else None."""
    if isinstance(frame, list) and len(frame) == 3 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in frame):
        return [float(v) for v in frame]
    return None


def draw_truth(ax, run, rid, handles, extent):
    """The true landmarks, the robot's true trajectory and its kills and restarts (world frame)."""
    lms = run.truth.get("landmarks", [])
    seen = set(run.truth.get("seen", []))
    pts = np.array([[lm["x"], lm["y"]] for lm in lms], dtype=float).reshape(-1, 2)
    mask = np.array([lm.get("id") in seen for lm in lms], dtype=bool)
    ax.scatter(pts[~mask, 0], pts[~mask, 1], s=6, c="#cfcfcf", zorder=1, linewidths=0)
    ax.scatter(pts[mask, 0], pts[mask, 1], s=8, c="#8a8a8a", zorder=1, linewidths=0)
    handles += [Line2D([], [], ls="", marker="o", ms=3, color="#cfcfcf", label="true landmark (unseen)"),
                Line2D([], [], ls="", marker="o", ms=3, color="#8a8a8a", label="true landmark (seen)")]
    extent.append(pts)
    robot = run.truth_robots.get(rid)
    true_traj = np.array([p[1:3] for p in (robot or {}).get("trajectory", [])], dtype=float).reshape(-1, 2)
    if not len(true_traj):
        return
    ax.plot(true_traj[:, 0], true_traj[:, 1], color="black", lw=0.8, zorder=2)
    ax.plot(true_traj[0, 0], true_traj[0, 1], "k>", ms=7, zorder=6)
    handles.append(Line2D([], [], color="black", lw=0.8, marker=">", ms=5, label="true trajectory (start)"))
    extent.append(true_traj)
    full = robot.get("trajectory")
    for kid, t in run.kills:
        if kid == rid and (p := pose_at(full, t)):
            ax.plot(p[0], p[1], "x", color="red", ms=12, mew=2.5, zorder=7)
    for kid, t in run.restarts:
        if kid == rid and (p := pose_at(full, t)):
            ax.plot(p[0], p[1], "^", color="green", ms=10, zorder=7)
    if any(k == rid for k, _ in run.kills):
        handles.append(Line2D([], [], ls="", marker="x", color="red", ms=8, mew=2, label="killed"))
    if any(k == rid for k, _ in run.restarts):
        handles.append(Line2D([], [], ls="", marker="^", color="green", ms=7, label="restarted"))


def draw_estimates(ax, local, glob, traj, local_frame, global_frame, handles, extent):
    """The local and global maps with their 95 % ellipses, each placed by its frame (None: as
    they are), and the estimated trajectory, placed as the local map."""
    for m, frame, colour, marker, label, z in ((glob, global_frame, GLOBAL_COLOUR, "+", "global map", 3),
                                               (local, local_frame, LOCAL_COLOUR, "o", "local map", 4)):
        xy, covs = landmark_arrays(m)
        if not len(xy):
            continue
        xy = to_world(frame, xy)
        is_local = marker == "o"
        # The global map's ellipses (most of them the peers' landmarks) light and thin, so that the
        # local map drawn over them shows.
        ax.add_collection(PatchCollection(ellipse_patches(xy, covs, frame[2] if frame else 0.0), facecolor="none",
                                          edgecolor=colour, linewidth=1.0 if is_local else 0.6,
                                          alpha=1.0 if is_local else 0.4, zorder=z))
        ax.scatter(xy[:, 0], xy[:, 1], s=9 if is_local else 16, marker=marker, c=[colour], zorder=z,
                   linewidths=0 if is_local else 0.9)
        handles.append(Line2D([], [], ls="-", lw=0.8, marker=marker, ms=5, color=colour,
                              label=f"{label} ({len(xy)}) + 95 % ellipse"))
        extent.append(xy)
    poses = np.array([p[1:3] for p in (traj or {}).get("poses", []) if len(p) >= 3], dtype=float).reshape(-1, 2)
    if len(poses):
        est = to_world(local_frame, poses)
        ax.plot(est[:, 0], est[:, 1], color="tab:purple", lw=1.0, ls="--", zorder=5)
        ax.plot(est[-1, 0], est[-1, 1], "o", color="tab:purple", ms=5, zorder=6)
        handles.append(Line2D([], [], color="tab:purple", lw=1.0, ls="--", marker="o", ms=4,
                              label="estimated trajectory (end)"))
        extent.append(est)


def finish_panel(ax, extent, title):
    if extent:
        allpts = np.vstack(extent)
        allpts = allpts[np.all(np.isfinite(allpts), axis=1)]
        if len(allpts):
            lo, hi = allpts.min(axis=0), allpts.max(axis=0)
            pad = max(1.0, 0.04 * float(np.max(hi - lo)))
            ax.set_xlim(lo[0] - pad, hi[0] + pad)
            ax.set_ylim(lo[1] - pad, hi[1] + pad)
    else:
        ax.text(0.5, 0.5, "no map, trajectory or truth to draw", transform=ax.transAxes, ha="center", va="center")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.25)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title, fontsize=10)


def map_figure(run, agent, path):
    """The maps of one agent in two panels: as placed in the world by the agent's map frame (the
    heading drift shows), and each map after its own least-squares rigid fit to the truth (what
    the accuracy figures measure). Returns the frame description."""
    rid = agent.get("id")
    local = run.agent_file(rid, LOCAL_MAP)
    glob = run.agent_file(rid, GLOBAL_MAP)
    traj = run.agent_file(rid, TRAJECTORY)
    stats = run.agent_file(rid, STATS)
    for name, value in ((LOCAL_MAP, local), (GLOBAL_MAP, glob), (TRAJECTORY, traj)):
        if value is None:
            run.notes.append(f"agent {rid}: no {name}")
    frame, frame_text = agent_frame(run, agent, traj, stats)
    loc, glo = agent.get("local") or {}, agent.get("global") or {}
    local_fit, global_fit = valid_frame(loc.get("fit_in_world")), valid_frame(glo.get("fit_in_world"))

    fig, axes = plt.subplots(1, 2, figsize=(16, 8.6))
    fig.subplots_adjust(left=0.05, right=0.985, top=0.86, bottom=0.17, wspace=0.16)
    handles = []
    for i, ax in enumerate(axes):
        extent, panel = [], []
        if run.truth and (frame is not None or i == 1):
            draw_truth(ax, run, rid, panel, extent)
        if i == 0:
            draw_estimates(ax, local, glob, traj, frame, frame, panel, extent)
            title = (f"as placed by the agent's map frame ({frame_text}):\nthe heading drift shows; RMSE true "
                     f"frame local {cell_text(loc.get('rmse_m'))} m / global {cell_text(glo.get('rmse_m'))} m")
        elif local_fit or global_fit:
            draw_estimates(ax, local if local_fit else None, glob if global_fit else None, traj if local_fit else None,
                           local_fit, global_fit, panel, extent)
            draw_errors(ax, run, [(glob if global_fit else None, global_fit, GLOBAL_COLOUR, "global map"),
                                  (local if local_fit else None, local_fit, LOCAL_COLOUR, "local map")], panel)
            title = (f"each map after its least-squares rigid fit to the truth:\nRMSE after rigid fit local "
                     f"{cell_text(loc.get('rmse_aligned_m'))} m / global {cell_text(glo.get('rmse_aligned_m'))} m")
        else:
            ax.text(0.5, 0.5, "no rigid fit in summary.json (fit_in_world)", transform=ax.transAxes,
                    ha="center", va="center", color="grey")
            title = "each map after its rigid fit to the truth"
        finish_panel(ax, extent, title)
        handles += [h for h in panel if h.get_label() not in {x.get_label() for x in handles}]
    fig.suptitle(f"agent {rid}: landmarks local {cell_text(loc.get('landmarks'))} / global "
                 f"{cell_text(glo.get('landmarks'))}\n{rmse_text(agent)}", fontsize=12)
    if handles:
        fig.legend(handles=handles, loc="lower center", ncol=min(4, len(handles)), fontsize=9, frameon=False)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return frame_text


# ----- timeline figures ---------------------------------------------------------------------
def timeline_entries(run):
    """{agent id: [checkpoint entries in time order]} of timeline.json (ids as in the summary)."""
    by_key = (run.timeline or {}).get("agents") or {}
    out = {}
    for key, entries in by_key.items():
        rid = next((i for i in run.ids if str(i) == str(key)), key)
        out[rid] = sorted((e for e in entries or [] if isinstance(e, dict) and e.get("t") is not None),
                          key=lambda e: e["t"])
    return out


def series(entries, value, cumulative=False, breaks=()):
    """(t, v) arrays of one agent's timeline; NaN breaks the line where the incarnation changes
    and at each time in breaks (the agent's kills: no line across the time it was dead).
    cumulative: v counts from 0 in each incarnation; add the previous incarnations' totals."""
    ts, vs = [], []
    offset, last, inc, prev_t = 0.0, None, None, None
    for e in entries:
        v = value(e)
        v = float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan
        changed = inc is not None and e.get("incarnation") != inc
        if changed or (prev_t is not None and any(prev_t < b <= e["t"] for b in breaks)):
            ts.append(math.nan)
            vs.append(math.nan)
        if changed:
            if cumulative and last is not None:
                offset += last
            last = None
        inc, prev_t = e.get("incarnation"), e["t"]
        if cumulative and math.isfinite(v):
            last = v
        ts.append(e["t"])
        vs.append(v + offset if cumulative else v)
    return np.array(ts, dtype=float), np.array(vs, dtype=float)


def mark_events(ax, run):
    """Kills (red), restarts (green) and pauses (orange) as vertical lines across a time axis."""
    for rid, t in run.pauses:
        ax.axvline(t, color="darkorange", lw=1.0, ls="--", alpha=0.8)
        ax.text(t, 1.0, f" \u2016{rid}", color="darkorange", fontsize=8, transform=ax.get_xaxis_transform(),
                va="bottom")
    for rid, t in run.kills:
        ax.axvline(t, color="red", lw=1.0, ls=":", alpha=0.8)
        ax.text(t, 1.0, f" \u00d7{rid}", color="red", fontsize=8, transform=ax.get_xaxis_transform(), va="bottom")
    for rid, t in run.restarts:
        ax.axvline(t, color="green", lw=1.0, ls=":", alpha=0.8)
        ax.text(t, 1.0, f" \u2191{rid}", color="green", fontsize=8, transform=ax.get_xaxis_transform(),
                va="bottom")


def time_axis(ax, run, ylabel, title):
    ax.set_xlabel("scenario time (s)")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10, pad=14)
    ax.grid(alpha=0.3)
    if run.duration:
        ax.set_xlim(0, run.duration)
    mark_events(ax, run)


def agent_lines(ax, run, tl, value, cumulative=False, ls="-", labels=True):
    drawn = False
    for rid, entries in tl.items():
        t, v = series(entries, value, cumulative, breaks=[k for i, k in run.kills if i == rid])
        if np.any(np.isfinite(v)):
            ax.plot(t, v, ls=ls, marker=".", ms=3, lw=1.2, color=run.colours.get(rid, "grey"),
                    label=agent_label(run, rid) if labels else None)
            drawn = True
    return drawn


def legend_below(fig, axes):
    """One legend for the figure's panels, below them, so that it never hides a value."""
    handles, labels = [], []
    for ax in axes:
        for h, label in zip(*ax.get_legend_handles_labels()):
            if label not in labels:
                handles.append(h)
                labels.append(label)
    if handles:
        fig.legend(handles, labels, loc="lower center", ncol=min(len(handles), 6), fontsize=8, frameon=False)


def no_data(ax, what):
    ax.text(0.5, 0.5, f"no {what} in timeline.json", transform=ax.transAxes, ha="center", va="center",
            color="grey")


def typical_period(tl):
    """The median time between an agent's checkpoints (when timeline.json has no period_s)."""
    steps = sorted(b["t"] - a["t"] for entries in tl.values() for a, b in zip(entries, entries[1:])
                   if b["t"] > a["t"])
    return steps[len(steps) // 2] if steps else 1.0


# Up to this many agents the exchanges are a timeline, a row per (receiver, sender); beyond, a
# matrix (the rows grow with the square of the swarm: 240 rows, 6,880 px at 16 agents).
EXCHANGE_ROWS_AGENTS = 8


def exchanges_figure(run, tl, period, path):
    """The map exchanges: a timeline up to EXCHANGE_ROWS_AGENTS agents, else a matrix; returns
    the kind drawn ("timeline" or "matrix")."""
    if len(tl) <= EXCHANGE_ROWS_AGENTS:
        exchanges_timeline(run, tl, period, path)
        return "timeline"
    exchanges_matrix(run, tl, path)
    return "matrix"


def exchanges_matrix(run, tl, path):
    """Receiver (row) by sender (column): the share of the run the two were linked by the radio
    (shade), the maps the receiver got from the sender (dot, its area by the count) and whether
    it held the sender aligned at the end (a black frame). Its size does not grow past 1,200 px."""
    ids = [r for r in run.ids if r in tl] or list(tl)
    n = len(ids)
    index = {rid: i for i, rid in enumerate(ids)}
    linked, received = np.zeros((n, n)), np.zeros((n, n))
    spans = run.radio_spans()
    for (a, b), runs in spans.items():
        if a in index and b in index and run.duration:
            share = sum(max(0.0, min(end, run.duration) - start) for start, end in runs) / run.duration
            linked[index[a], index[b]] = linked[index[b], index[a]] = min(1.0, share)
    for r in ids:
        last = {}
        for e in tl.get(r, []):  # each incarnation counts from 0: the most of each, summed
            inc = e.get("incarnation")
            for k, v in (e.get("maps_received_from") or {}).items():
                if isinstance(v, (int, float)):
                    last[(inc, k)] = max(last.get((inc, k), 0), v)
        for (_, k), v in last.items():
            s = int(k) if str(k).lstrip("-").isdigit() else None
            if s in index:
                received[index[r], index[s]] += v
    side = min(12.0, max(6.0, 0.17 * n + 3.0))
    fig, ax = plt.subplots(figsize=(side + 1.6, side))
    fig.subplots_adjust(left=0.1, right=0.9, top=0.92, bottom=0.11)
    image = ax.imshow(linked, cmap="Greens", vmin=0, vmax=1, origin="upper", aspect="equal")
    fig.colorbar(image, ax=ax, fraction=0.04, pad=0.02, label="share of the run linked by the radio")
    if received.max() > 0:
        ys, xs = np.nonzero(received)
        ax.scatter(xs, ys, s=4 + 60 * received[ys, xs] / received.max() * (16 / max(16, n)), c="tab:blue",
                   alpha=0.8, linewidths=0, label="maps received (area: count)")
    aligned = {a.get("id"): set(a.get("peers_aligned") or []) for a in run.agents}
    frames = [(index[r], index[p]) for r in ids for p in aligned.get(r, ()) if p in index]
    if frames:
        ax.scatter([x for _, x in frames], [y for y, _ in frames], s=30 * (16 / max(16, n)) + 8, marker="s",
                   facecolors="none", edgecolors="black", linewidths=0.8, label="aligned at the end")
    dead = [index[rid] for rid, _ in run.kills if rid in index and not next(
        (a.get("alive_at_end", True) for a in run.agents if a.get("id") == rid), True)]
    for y in dead:
        ax.axhline(y, color="red", lw=0.8, alpha=0.6)
    step = max(1, n // 16)
    ax.set_xticks(range(0, n, step))
    ax.set_xticklabels([str(ids[i]) for i in range(0, n, step)], fontsize=8)
    ax.set_yticks(range(0, n, step))
    ax.set_yticklabels([str(ids[i]) for i in range(0, n, step)], fontsize=8)
    ax.set_xlabel("sender")
    ax.set_ylabel("receiver")
    ax.set_title(f"who heard whom over the run ({n} agents); red line: an agent dead at the end", fontsize=10)
    if received.max() > 0 or frames:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.05), ncol=2, fontsize=8, frameon=False)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def exchanges_timeline(run, tl, period, path):
    """A row per (receiver, sender): a bar over each period (s) in which the receiver's count of
    maps from the sender grew. Kills and restarts marked on the receiver's rows."""
    receivers = list(tl)
    senders = set(run.ids)
    for entries in tl.values():
        for e in entries:
            senders.update(int(k) if str(k).lstrip("-").isdigit() else k for k in (e.get("maps_received_from") or {}))
    senders = sorted(senders, key=lambda x: (not isinstance(x, int), x if isinstance(x, int) else 0, str(x)))
    rows = [(r, s) for r in receivers for s in senders if str(s) != str(r)]
    height = max(4.0, 0.28 * len(rows) + 1.6)
    fig, ax = plt.subplots(figsize=(11, height))
    fig.subplots_adjust(left=0.12, right=0.97, top=1 - 0.8 / height, bottom=0.6 / height)
    restarts_at = {}
    for rid, t in run.restarts:
        restarts_at.setdefault(rid, []).append(t)
    in_range = run.radio_spans()
    aligned = {r: run.alignments(r) for r in receivers}
    for y, (r, s) in enumerate(rows):
        spans = in_range.get((min(r, s), max(r, s)), []) if isinstance(r, int) and isinstance(s, int) else []
        if spans:
            ax.broken_barh([(a, b - a) for a, b in spans], (y - 0.47, 0.94), facecolors="#d8efd8", zorder=0)
        for t, peer, now in aligned.get(r, []):
            if peer == s:
                ax.plot(t, y, "D", ms=6, mfc="black" if now else "white", mec="black", mew=1.2, zorder=4)
        bars = []
        prev_t, prev_n, inc = None, 0, None
        for e in tl[r]:
            n = (e.get("maps_received_from") or {}).get(str(s), 0) or 0
            if e.get("incarnation") != inc:  # a new incarnation counts from 0 since it began
                began = [t for t in restarts_at.get(r, []) if t <= e["t"]]
                prev_t = max(began) if inc is not None and began else (e["t"] - period if inc is not None else 0.0)
                prev_n = 0
                inc = e.get("incarnation")
            if n > prev_n:
                bars.append((prev_t, e["t"] - prev_t))
            prev_t, prev_n = e["t"], n
        ax.broken_barh(bars, (y - 0.3, 0.6), facecolors=[run.colours.get(s, "grey")], zorder=2)
    # Group the rows of each receiver, with its kills and dead time.
    y = 0
    for r in receivers:
        n = sum(1 for row in rows if row[0] == r)
        if n == 0:
            continue
        lo, hi = y - 0.5, y + n - 0.5
        for start, end in run.dead_intervals(r):
            ax.fill_between([start, end], lo, hi, color="red", alpha=0.08, lw=0)
        for kid, t in run.kills:
            if kid == r:
                ax.vlines(t, lo, hi, color="red", lw=1.5)
                ax.plot([t] * n, range(y, y + n), "x", color="red", ms=8, mew=2)
        for kid, t in run.restarts:
            if kid == r:
                ax.vlines(t, lo, hi, color="green", lw=1.5)
                ax.plot([t] * n, range(y, y + n), "^", color="green", ms=6)
        for kid, t in run.pauses:
            if kid == r:
                ax.vlines(t, lo, hi, color="darkorange", lw=1.5, ls="--")
                ax.plot([t] * n, range(y, y + n), "|", color="darkorange", ms=10, mew=2)
        ax.axhline(hi, color="grey", lw=0.6)
        y += n
    ax.set_yticks(range(len(rows)))
    ax.set_yticklabels([f"{r} \u2190 {s}" for r, s in rows], fontsize=8)
    ax.set_ylim(len(rows) - 0.5, -0.5)
    ax.set_xlabel("scenario time (s)")
    ax.set_ylabel("receiver \u2190 sender")
    if run.duration:
        ax.set_xlim(0, run.duration)
    ax.grid(axis="x", alpha=0.3)
    radio = (f"pale green: within radio range ({format_number(run.range_m)} m); " if in_range else "")
    ax.set_title(radio + "bar: a checkpoint period in which the receiver got maps from the sender;\n"
                 "\u25c6 the receiver aligned the sender, \u25c7 no longer held it; red \u00d7: killed, shaded until "
                 "restarted; green \u25b2: restarted; orange |: paused", fontsize=10)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def map_kinds_figure(run, tl, path, key, ylabel, title, before=None, after=None):
    """One panel per map kind (local, global), each on its own axis: the timeline's `kind.key`
    per agent over time; before(ax) and after(ax) draw what a panel adds under and over the lines."""
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8))
    fig.subplots_adjust(left=0.065, right=0.98, top=0.86, bottom=0.24, wspace=0.2)
    for ax, kind in zip(axes, ("local", "global")):
        if before:
            before(ax)
        drawn = agent_lines(ax, run, tl, lambda e, k=kind: lookup(e, f"{k}.{key}"))
        time_axis(ax, run, ylabel, f"{kind} map: {title}")
        if after:
            after(ax)
        if not drawn:
            no_data(ax, f"{kind} {title}")
    legend_below(fig, axes)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def nees_figure(run, tl, path):
    """Local and global NEES over time, each on its own axis (log when the values span more than
    30x, so that every value shows), with the consistency band [NEES_BAND] shaded."""
    def band(ax):
        ax.axhspan(*NEES_BAND, color="tab:green", alpha=0.12, lw=0,
                   label=f"consistency band [{NEES_BAND[0]:g}, {NEES_BAND[1]:g}]")
        ax.axhline(NEES_EXPECTED, color="black", ls="--", lw=1, label="expected (2 dof)")

    def scale(ax):
        values = [y for line in ax.get_lines()[1:] for y in np.asarray(line.get_ydata(), dtype=float)
                  if np.isfinite(y) and y > 0]
        if values and max(values + [NEES_BAND[1]]) / min(values + [NEES_BAND[0]]) > 30:
            ax.set_yscale("log")

    map_kinds_figure(run, tl, path, "nees_mean", "mean NEES", "mean NEES of matched landmarks", band, scale)


def rmse_figure(run, tl, path):
    """Local and global RMSE after the rigid fit to the truth over time (timeline.json)."""
    map_kinds_figure(run, tl, path, "rmse_aligned_m", "RMSE after rigid fit (m)", "RMSE after a rigid fit to the truth",
                     after=lambda ax: ax.set_ylim(bottom=0))


def gap_entries(tl):
    """{agent: [its timeline entries that carry a gap to the optimum of the data up to then]}."""
    return {rid: [e for e in entries if isinstance(e.get("gap_to_central"), (int, float))]
            for rid, entries in tl.items()}


def gap_figure(run, tl, path):
    """The gap over time: each global map's RMSE after the rigid fit over the fair optimum's of the
    data up to then, on the same landmarks (timeline.json's gap_to_central, at the times
    reference_over_time.json was solved for and at the end); 1 is the limit. Log scale when the
    gaps span more than 10x. False (nothing written) when no entry has one."""
    gaps = gap_entries(tl)
    if not any(gaps.values()):
        return False
    fig, ax = plt.subplots(figsize=(13, 4.8))
    fig.subplots_adjust(left=0.065, right=0.98, top=0.86, bottom=0.24)
    ax.axhline(1.0, color="black", ls="--", lw=1, label="the limit (1)")
    agent_lines(ax, run, gaps, lambda e: e.get("gap_to_central"))
    values = [e["gap_to_central"] for entries in gaps.values() for e in entries if e["gap_to_central"] > 0]
    if values and max(values + [1.0]) / min(values + [1.0]) > 10:
        ax.set_yscale("log")
    else:
        ax.set_ylim(bottom=0)
    time_axis(ax, run, "global RMSE / optimum of the data up to then",
              "global map over the centralized optimum of the data up to then (same landmarks)")
    legend_below(fig, [ax])
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return True


# A global coverage that falls by this share between two checkpoints of one incarnation is an
# event the coverage figure's caption names, with the alignments the agent dropped meanwhile.
COVERAGE_DROP = 0.2


def coverage_drops(run, tl):
    """[(agent, t_before, before, t_after, after, [peers whose alignment it dropped by t_after])]:
    each fall of an agent's global coverage by COVERAGE_DROP or more between two checkpoints of
    one incarnation, in time order."""
    drops = []
    for rid, entries in tl.items():
        dropped = [(t, peer) for t, peer, now in run.alignments(rid) if not now]
        for a, b in zip(entries, entries[1:]):
            ca, cb = lookup(a, "global.coverage"), lookup(b, "global.coverage")
            if a.get("incarnation") != b.get("incarnation") or not all(
                    isinstance(c, (int, float)) for c in (ca, cb)) or ca - cb < COVERAGE_DROP:
                continue
            drops.append((rid, a["t"], ca, b["t"], cb, sorted({p for t, p in dropped if a["t"] < t <= b["t"]})))
    return sorted(drops, key=lambda d: (d[3], str(d[0])))


def drops_text(drops, most=6):
    """The caption's words on coverage_drops (at most `most` named, the rest counted)."""
    if not drops:
        return ""
    items = [f"agent {rid} {before:.2f} \u2192 {after:.2f} at {t0:g}-{t1:g} s"
             + (f" (dropped its alignment of {', '.join(map(str, peers))})" if peers else "")
             for rid, t0, before, t1, after, peers in drops[:most]]
    more = f"; {len(drops) - most} more" if len(drops) > most else ""
    return (f" Falls of a global coverage by {COVERAGE_DROP:.0%} or more between two checkpoints: "
            + "; ".join(items) + more + ". A dropped alignment takes that peer's landmarks out of the global map "
            "until the peer is aligned again.")


def coverage_figure(run, tl, path):
    fig, ax = plt.subplots(figsize=(11, 4.8))
    fig.subplots_adjust(left=0.07, right=0.98, top=0.86, bottom=0.24)
    drawn = agent_lines(ax, run, tl, lambda e: lookup(e, "global.coverage"))
    agent_lines(ax, run, tl, lambda e: lookup(e, "local.coverage"), ls=":", labels=False)
    time_axis(ax, run, "coverage", "coverage: share of the seen true landmarks in the map "
                                   "(solid: global map, dotted: local map)")
    ax.set_ylim(0, 1.02)
    if drawn:
        legend_below(fig, [ax])
    else:
        no_data(ax, "coverage")
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


def bytes_figure(run, tl, path):
    fig, axes = plt.subplots(1, 2, figsize=(13, 4.8))
    fig.subplots_adjust(left=0.07, right=0.98, top=0.86, bottom=0.24, wspace=0.2)
    for ax, key in zip(axes, ("bytes_sent", "bytes_received")):
        drawn = agent_lines(ax, run, tl, lambda e, k=key: None if e.get(k) is None else e[k] / 1000.0,
                            cumulative=True)
        time_axis(ax, run, "kB (cumulative over incarnations)", key.replace("_", " "))
        if not drawn:
            no_data(ax, key)
    legend_below(fig, axes)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)


# ----- page ---------------------------------------------------------------------------------
CSS = """
body { font-family: sans-serif; margin: 1.5em; color: #222; max-width: 1600px; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; border-bottom: 1px solid #ccc; }
table { border-collapse: collapse; font-size: 0.85em; margin: 0.6em 0; }
table.summary { font-size: 0.78em; }
table.summary th, table.summary td { padding: 0.15em 0.35em; }
table.summary th { max-width: 9em; }
h3 { font-size: 1em; margin: 1em 0 0.2em 0; }
div.side { display: flex; flex-wrap: wrap; column-gap: 2em; align-items: flex-start; }
div.wide { overflow-x: auto; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.5em; }
th { background: #f0f0f0; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
tr.dead td { background: #fdecec; }
td.flag { background: #f9c9c9; font-weight: bold; }
ul.flags { color: #8a1010; }
img { max-width: 100%; height: auto; border: 1px solid #eee; margin: 0.4em 0; }
.note { color: #7a4b00; }
figure { margin: 0 0 1.2em 0; } figcaption { font-size: 0.85em; color: #555; }
ul.terms { font-size: 0.85em; color: #444; }
details.maps summary { cursor: pointer; font-weight: bold; margin: 0.4em 0; }
"""


def esc(x):
    return html.escape(str(x), quote=True)


def events_text(events):
    return ", ".join(f"agent {rid} at {t:.1f} s" for rid, t in events) or "none"


NEES_KEYS = ("local.nees_mean", "global.nees_mean")


def outside_band(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and not NEES_BAND[0] <= v <= NEES_BAND[1]


def flags_html(run):
    """A list of the maps whose mean NEES is outside the consistency band (their cells are red)."""
    items = [f"agent {a.get('id')}: {key.split('.')[0]} map mean NEES {format_number(lookup(a, key))}"
             for a in run.agents for key in NEES_KEYS if outside_band(lookup(a, key))]
    if not items:
        return (f'<p id="flags">Every map\'s mean NEES is within the consistency band [{NEES_BAND[0]:g}, '
                f"{NEES_BAND[1]:g}].</p>")
    return (f'<p>Flagged: mean NEES outside the consistency band [{NEES_BAND[0]:g}, {NEES_BAND[1]:g}] (below: '
            "the map claims less certainty than it has; above: more, an overconfident map).</p>"
            '<ul id="flags" class="flags">' + "".join(f"<li>{esc(i)}</li>" for i in items) + "</ul>")


# The summary's columns (HTML_COLUMNS, in their order) cut into tables that each fit a 1400 px
# page: (id, heading, key of its first column); the later tables repeat the agent column.
SUMMARY_TABLES = [("summary", "The maps", "id"),
                  ("summary-limit", "Against the limit (1: the limit; docs/EXPERIMENTS.md \"The limit\")",
                   "global.central_rmse_aligned_m"),
                  ("summary-traffic", "The path and the traffic", "local.trajectory_ate_aligned_m")]


def summary_parts():
    """[(table id, heading, [columns])]: HTML_COLUMNS cut at each SUMMARY_TABLES first key."""
    starts = [next(i for i, c in enumerate(HTML_COLUMNS) if c.key == key) for _, _, key in SUMMARY_TABLES]
    ends = starts[1:] + [len(HTML_COLUMNS)]
    return [(tid, head, HTML_COLUMNS[a:b]) for (tid, head, _), a, b in zip(SUMMARY_TABLES, starts, ends)]


def summary_table(run):
    """The summary tables: each agent's figures, a row per agent, a table per SUMMARY_TABLES."""
    out = []
    for n, (tid, head, columns) in enumerate(summary_parts()):
        agent_th = '<th class="agent">agent</th>' if n else ""
        if n == 1:
            out.append('<div class="side">')  # the later tables side by side where the page has room
        out += ["<div>" if n else "", f'<h3>{esc(head)}</h3>', f'<table id="{tid}" class="summary">',
                "<tr>" + agent_th + "".join(f'<th data-key="{esc(c.key)}">{esc(c.html)}</th>' for c in columns)
                + "</tr>"]
        for a in run.agents:
            cls = "" if a.get("alive_at_end", True) else ' class="dead"'
            cells = [f'<td class="agent num">{esc(a.get("id"))}</td>'] if n else []
            for c in columns:
                v = c.value(a)
                num = isinstance(v, (int, float, list)) and not isinstance(v, bool)
                classes = (["num"] if num else []) + (["flag"] if c.key in NEES_KEYS and outside_band(v) else [])
                cls_num = f' class="{" ".join(classes)}"' if classes else ""
                cells.append(f'<td data-key="{esc(c.key)}" data-value="{esc(json.dumps(v))}"{cls_num}>'
                             f"{esc(cell_text(v, c.count))}</td>")
            out.append(f'<tr data-agent="{esc(a.get("id"))}"{cls}>' + "".join(cells) + "</tr>")
        out.append("</table>" + ("</div>" if n else ""))
    if len(SUMMARY_TABLES) > 1:
        out.append("</div>")
    return "\n".join(out)


def peers_table(run, frames):
    head = ["agent", "map frame", "killed at (s)", "restarted at (s)", "paused at (s)", "peers aligned", "peers stale",
            "maps dropped", "bytes received", "local trajectory RMSE (m)", "global RMSE own landmarks, true frame (m)",
            "worst alignment error (m)"]
    out = ['<table id="peers">', "<tr>" + "".join(f"<th>{esc(h)}</th>" for h in head) + "</tr>"]
    for a in run.agents:
        errs = [e.get("trans_m") for e in (a.get("alignment_errors") or {}).values()
                if isinstance(e, dict) and isinstance(e.get("trans_m"), (int, float))]
        cells = [a.get("id"), frames.get(a.get("id"), DASH),
                 ", ".join(format_number(t) for t in a.get("killed_at") or []) or DASH,
                 ", ".join(format_number(t) for t in a.get("restarted_at") or []) or DASH,
                 ", ".join(format_number(t) for t in a.get("paused_at") or []) or DASH,
                 ", ".join(str(p) for p in a.get("peers_aligned") or []) or DASH,
                 ", ".join(str(p) for p in a.get("peers_stale") or []) or DASH,
                 format_number(a.get("maps_dropped")), format_number(a.get("bytes_received")),
                 format_number(lookup(a, "local.trajectory_rmse_m")),
                 format_number(lookup(a, "global.rmse_own_landmarks_m")),
                 format_number(max(errs) if errs else None)]
        out.append("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in cells) + "</tr>")
    out.append("</table>")
    return "\n".join(out)


def figure_html(src, alt, caption, agent=None):
    data = f' data-agent="{esc(agent)}"' if agent is not None else ""
    return (f'<figure><img src="{esc(src)}" alt="{esc(alt)}"{data}>'
            f"<figcaption>{esc(caption)}</figcaption></figure>")


def reference_html(ref):
    """The run's reference (summary.json `reference`): the centralized batch optimum of all the
    robots' data, the known-pose map and each robot's own batch optimum, or why there is none."""
    if not ref:
        return '<p class="note" id="reference">No reference in this summary (a run of an older build).</p>'
    if not ref.get("available"):
        return (f'<p class="note" id="reference">No reference for this run: {esc(ref.get("why_none", "?"))}.</p>')

    def row(name, m):
        if not m:
            return ""
        cells = (name, cell_text(m.get("landmarks")), cell_text(m.get("rmse_aligned_m")), cell_text(m.get("rmse_m")),
                 cell_text(m.get("nees_mean")), "yes" if m.get("converged") else "NO", cell_text(m.get("solve_s")))
        return "<tr>" + "".join(f"<td>{esc(v)}</td>" for v in cells) + "</tr>"

    central = ref.get("central") or {}
    rows = [row("centralized batch optimum (all robots' data, no start known)", central),
            row("the same with every robot's true start", ref.get("central_known_starts")),
            row("known poses (every observation from the true pose)", ref.get("known_pose"))]
    rows += [row(f"robot {rid}'s own batch optimum", m) for rid, m in sorted(
        (ref.get("own_batch") or {}).items(), key=lambda kv: int(kv[0]))]
    apart = ""
    if central.get("unconnected"):
        robots = ", ".join(str(r) for r in central["unconnected"])
        apart = (f" Robots {esc(robots)} share too little with the others (fewer than two landmarks and sightings) "
                 "for their frames to be tied: each such group is solved and scored in a frame of its own.")
    return f"""<p id="reference">What the run's data allows, from the feeder's own streams: every odometry
and range-bearing reading, and the robots' sightings of each other that the agents use, in one sparse
least-squares problem with known association (loss {esc(ref.get('loss', 'none'))}), solved in
{esc(seconds(ref.get('wall_s', ref.get('total_s'))))}. Like the agents, it knows no robot's start: one robot's
start fixes the frame (the gauge), every other is found from the data. The summary's
<i>global RMSE / centralized optimum</i> divides each global map's RMSE after a rigid fit by the
optimum's on the same landmarks, and <i>local RMSE / own batch optimum</i> each local map's by its
robot's own optimum's: 1 is the limit. The optimum that also knows every robot's true start, which no
agent does, is beside it (<i>global RMSE / optimum with the true starts</i>).{apart}</p>
<table id="reference-table"><tr><th>map</th><th>landmarks</th><th>RMSE after rigid fit (m)</th>
<th>RMSE, world frame (m)</th><th>NEES</th><th>converged</th><th>solve (s)</th></tr>
{''.join(rows)}</table>
<ul id="reference-terms" class="terms">
<li><b>loss</b>: the robust loss on each reading's residual ({esc(ref.get('loss', 'none'))}; none: plain least
squares, the optimum for Gaussian noise, as in simulated worlds; real datasets use a Cauchy loss against
their heavy-tailed ranges).</li>
<li><b>converged</b>: the solver stopped because the step no longer lowered the cost, not at its iteration
cap; NO means the figures are of an unfinished solve.</li>
<li><b>RMSE after rigid fit</b>: after the least-squares rigid fit of the whole map to the true landmarks (the
accuracy figure); <b>world frame</b>: as the solve's gauge places it, with the frame's own error.</li>
<li><b>a ratio below 1</b>: a map better than the optimum on the same landmarks. The optimum is the best
estimate on average, not in every run: one robot's own map (gap to own batch optimum) or a map of few
landmarks can beat it in one realisation of the noise by some percent.</li>
</ul>"""


def maps_html(run, maps):
    """The agents' map figures: all of them up to DISTINCT_COLOURS agents; beyond, folded by the
    colour groups (a closed <details> each, opened by a click), so that the page stays short."""
    if not run.groups:
        return "".join(maps)
    by_id = dict(zip(run.ids, maps))
    return (f'<p>{len(run.ids)} agents: their maps are folded by groups of consecutive agents; open one to '
            "see its agents' maps.</p>" + "".join(
                f'<details class="maps"><summary>{esc(label)}</summary>'
                + "".join(by_id[rid] for rid in members if rid in by_id) + "</details>"
                for label, _, members in run.groups))


def write_report(d):
    run = Run(d)
    out = run.dir / "report"
    out.mkdir(exist_ok=True)
    for old in out.glob("*.png"):  # figures of an earlier report of this run
        old.unlink()
    s = run.summary

    frames, maps = {}, []
    for a in run.agents:
        rid = a.get("id")
        name = f"map_agent_{rid}.png"
        frames[rid] = map_figure(run, a, out / name)
        maps.append(figure_html(f"report/{name}", f"maps of agent {rid}",
                                f"Agent {rid} ({frames[rid]}): true landmarks (grey; darker: seen by some robot), "
                                "true trajectory (black), local map (blue dots) and global map (orange +) with 95 % "
                                "ellipses, estimated trajectory (purple, dashed); on the right, after each map's "
                                "rigid fit, each landmark's error from the truth as a line, scaled up by the legend's "
                                f"factor. {rmse_text(a)}.", agent=rid))

    if run.timeline is not None:
        tl = timeline_entries(run)
        period = run.timeline.get("period_s") or typical_period(tl)
        exchanges = exchanges_figure(run, tl, period, out / "exchanges.png")
        rmse_figure(run, tl, out / "rmse.png")
        nees_figure(run, tl, out / "nees.png")
        coverage_figure(run, tl, out / "coverage.png")
        bytes_figure(run, tl, out / "bytes.png")
        timeline = [
            figure_html("report/rmse.png", "RMSE after rigid fit over time",
                        "Each map's accuracy over time: its RMSE after a least-squares rigid fit of the whole map "
                        "to the landmark truth, at each checkpoint. No line across the time an agent was dead."),
            figure_html("report/exchanges.png", "radio, map exchanges and alignments over time",
                        "Per receiver \u2190 sender: when the radio linked the two (as the feeder published the "
                        f"links), the checkpoint periods ({seconds(period)}) in which maps arrived, and when the "
                        "receiver aligned the sender." if exchanges == "timeline" else
                        "Who heard whom: per receiver (row) and sender (column), the share of the run the radio "
                        "linked them (as the feeder published the links), the maps received, and the peers "
                        f"aligned at the end (over {EXCHANGE_ROWS_AGENTS} agents a matrix: a row per pair "
                        "would grow with the square of the swarm)."),
            figure_html("report/nees.png", "NEES over time",
                        "Mean NEES of the matched landmarks over time, each map kind on its own axis; 2 is the "
                        f"expected value of a consistent estimate, and a map outside [{NEES_BAND[0]:g}, "
                        f"{NEES_BAND[1]:g}] is flagged in the summary."),
            figure_html("report/coverage.png", "coverage over time",
                        "Coverage of the seen true landmarks." + drops_text(coverage_drops(run, tl))),
            figure_html("report/bytes.png", "bytes exchanged over time",
                        "Bytes sent and received, cumulative over an agent's incarnations."),
        ]
    else:
        timeline = ['<p class="note" id="no-timeline">This run has no timeline.json: the plots over time '
                    "(RMSE, exchanges, NEES, coverage, bytes) are skipped.</p>"]

    rtf = s.get("real_time_factor")
    intro = (f"Scenario <b>{esc(s.get('scenario', '?'))}</b>"
             + (f" ({esc(s['scenario_file'])})" if s.get("scenario_file") else "")
             + f": {esc(seconds(s.get('sim_duration_s')))} simulated in {esc(seconds(s.get('wall_s')))} wall time"
             + (f", real-time factor {esc(format_number(rtf))}" if rtf is not None else "")
             + (f", pace {esc(s['pace'])}" if s.get("pace") else "")
             + f"; {len(run.agents)} agents."
             + f" Kills: {esc(events_text(run.kills))}. Restarts: {esc(events_text(run.restarts))}."
             + (f" Pauses: {esc(pauses_text(s.get('pauses')))}." if s.get("pauses") else "")
             + (" <b>The run was interrupted.</b>" if s.get("interrupted") else ""))
    limit = reference_html(s.get("reference"))
    if run.timeline is not None and gap_figure(run, tl, out / "gap.png"):
        solved = ((s.get("reference") or {}).get("over_time") or {}).get("samples_t") or []
        limit += figure_html(
            "report/gap.png", "the gap over time",
            "The gap over time: each global map's RMSE after a rigid fit over the centralized optimum's (no start "
            "known) of every robot's data up to that time, on the same landmarks; 1 is the limit. Solved at "
            + (", ".join(f"{t:g}" for t in solved) + " s and " if solved else "")
            + "the end (swarm run --gap-samples), each against the agent's latest snapshot by then. Early on a "
            "global map holds mostly its own robot's landmarks, where its gap is its local map's; each merge "
            "adds landmarks placed by an imperfect transform.")
    notes = "".join(f"<li>{esc(n)}</li>" for n in dict.fromkeys(run.notes))
    page = f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>mapmesh run: {esc(s.get('scenario', '?'))}</title>
<style>{CSS}</style>
</head>
<body>
<h1>mapmesh run: {esc(s.get('scenario', '?'))}</h1>
<p id="intro">{intro}</p>
{f'<ul class="note" id="notes">{notes}</ul>' if notes else ''}
<h2>Summary</h2>
<p>Metrics against the truth (mapmesh-eval); {DASH} where there is none. RMSE and NEES over matched
landmarks; coverage is the share of the true landmarks some robot saw that the map holds. A map's
accuracy is its RMSE after a least-squares rigid fit of the map to the landmark truth; the RMSE
in the robot's true map frame beside it also holds the heading error the map built up (its
heading drift). Red rows: agents not alive at the end.</p>
<div class="wide">{summary_table(run)}</div>
{flags_html(run)}
<h2>The limit</h2>
{limit}
<h2>Peers and events</h2>
{peers_table(run, frames)}
<h2>Maps</h2>
{maps_html(run, maps)}
<h2>Over time</h2>
{''.join(timeline)}
</body>
</html>
"""
    path = run.path(REPORT)
    tmp = run.path(REPORT + ".tmp")
    tmp.write_text(page)
    tmp.replace(path)
    return path


def main(argv):
    d, code = directory_argument(argv, __doc__, "report.py", SUMMARY, "scripts/swarm run ... --out")
    if d is None:
        return code
    try:
        path = write_report(d)
    except (OSError, ValueError) as e:
        print(f"report.py: {d}: {e}", file=sys.stderr)
        return 1
    print(path)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
