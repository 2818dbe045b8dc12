"""The run report (scripts/plots/report.py) and the sweep plot (scripts/plots/sweep.py) on
synthetic inputs: every figure the page shows exists and is a real PNG of non-trivial size,
the summary table says what summary.json says, --help and a missing directory behave.

Run: cd tests/integration && /usr/bin/python3 -m unittest report_test
(Debian's /usr/bin/python3 has matplotlib and numpy.)

Reusable from other tests:
  make_fake_run(dir)             writes a synthetic run directory (3 agents, agent 3 killed and
                                 restarted, agent 2 with an unknown frame and no global map)
  check_report(testcase, dir)    runs report.py on a run directory and checks its page, images
                                 and summary table; returns what it parsed
  make_fake_sweep(dir)           writes a synthetic sweep.csv
  check_sweep(testcase, dir)     runs sweep.py on it and checks sweep.png
"""

import csv
import json
import math
import random
import re
import struct
import subprocess
import sys
import tempfile
import unittest
from html.parser import HTMLParser
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PYTHON = "/usr/bin/python3"
REPORT = REPO / "scripts" / "plots" / "report.py"
SWEEP = REPO / "scripts" / "plots" / "sweep.py"
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
sys.path.insert(0, str(REPO / "scripts"))
from mapmesh import columns  # noqa: E402
TIMELINE_IMAGES = ["report/rmse.png", "report/exchanges.png", "report/nees.png", "report/coverage.png",
                   "report/bytes.png"]
# The summary table's columns (data-key = path in a summary.json agent) and their headers: a
# map's RMSE after a rigid fit to the truth first, its RMSE in the true frame beside it.
SUMMARY_KEYS = ["id", "alive_at_end", "exit_code", "restarts", "local.landmarks", "local.rmse_aligned_m",
                "local.rmse_m", "local.nees_mean", "global.landmarks", "global.rmse_aligned_m", "global.rmse_m",
                "global.nees_mean", "global.coverage", "global.central_rmse_aligned_m", "gap_to_central",
                "global.central_known_starts_rmse_aligned_m", "gap_to_central_known_starts", "gap_to_reached",
                "gap_to_own_batch", "local.trajectory_ate_aligned_m", "local.trajectory_rpe.translation_rmse_m",
                "peers_aligned", "maps_received", "bytes_sent", "bytes_per_landmark", "cpu_s", "max_rss_mb"]
SUMMARY_HEADERS = ["agent", "alive", "exit", "restarts", "local landmarks", "local RMSE after rigid fit (m)",
                   "local RMSE, true frame (m)", "local NEES", "global landmarks", "global RMSE after rigid fit (m)",
                   "global RMSE, true frame (m)", "global NEES", "global coverage",
                   "centralized optimum on the same landmarks (m)", "global RMSE / centralized optimum",
                   "optimum with the true starts on the same landmarks (m)",
                   "global RMSE / optimum with the true starts", "global RMSE / optimum of what reached it",
                   "local RMSE / own batch optimum",
                   "trajectory ATE after rigid fit (m)", "trajectory RPE over 1 s (m)", "peers aligned",
                   "maps received", "bytes sent", "bytes / landmark", "CPU (s)", "max RSS (MB)"]
# sweep.csv as `swarm sweep` writes it, after the swept parameter.
SWEEP_HEADER = ["seed", "agent", "alive", "lm_local", "lm_global", "coverage_global", "coverage_reached",
                "nees_global", "rmse_global_aligned_m", "rmse_global_m", "rmse_local_aligned_m", "rmse_local_m",
                "nees_local",
                "rmse_central_same_m", "gap_to_central", "rmse_central_known_starts_same_m",
                "gap_to_central_known_starts", "gap_to_own_batch", "peers_aligned", "bytes_sent", "wall_s"]
DASH = "\u2013"


# ----- a synthetic run ----------------------------------------------------------------------
def _compose_inverse(frame, x, y):
    """World point (x, y) in the frame whose world pose is frame = [x0, y0, theta]."""
    dx, dy = x - frame[0], y - frame[1]
    c, s = math.cos(frame[2]), math.sin(frame[2])
    return c * dx + s * dy, -s * dx + c * dy


def _circle(cx, cy, r, phase, t, speed=0.05):
    a = phase + speed * t
    return [cx + r * math.cos(a), cy + r * math.sin(a), a + math.pi / 2]


def _write(path, value):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(value, indent=1) + "\n")


def make_fake_run(d):
    """Writes a small synthetic run directory at d (summary.json, truth.json, timeline.json,
    agent_<id>/{local_map,global_map,trajectory,stats}.json) and returns its summary.

    Three robots on circles in a 40 x 30 m park with 60 landmarks. Agent 1: everything known.
    Agent 2: frame_in_world null (own frame), global metrics null and no global_map.json.
    Agent 3: killed at 20 s and restarted at 30 s (its map frame begins there), local NEES null."""
    d = Path(d)
    rng = random.Random(7)
    duration, period = 60.0, 5.0
    landmarks = []
    for i in range(60):
        landmarks.append({"id": i, "x": 2 + (i % 10) * 4 + rng.uniform(-1, 1),
                          "y": 2 + (i // 10) * 5 + rng.uniform(-1, 1)})
    circles = {1: (12, 10, 7, 0.0), 2: (28, 12, 8, 1.5), 3: (20, 22, 6, 3.0)}
    times = [i * 0.5 for i in range(int(duration / 0.5) + 1)]
    robots = []
    for rid, c in circles.items():
        traj = [[t] + _circle(*c, t) for t in times]
        robots.append({"id": rid, "start": traj[0][1:], "trajectory": traj})
    origin_stamp = {1: 0.0, 2: 0.0, 3: 30.0}
    sensed = {}  # robot -> landmark ids it saw (within 9 m of its path while its agent ran)
    for r in robots:
        rid = r["id"]
        sensed[rid] = sorted({lm["id"] for p in r["trajectory"] if p[0] >= origin_stamp[rid] for lm in landmarks
                              if math.hypot(lm["x"] - p[1], lm["y"] - p[2]) < 9})
    seen = sorted(set().union(*sensed.values()))
    _write(d / "truth.json", {"scenario": "fake3", "duration_s": duration, "headings_known": True,
                              "landmarks": landmarks, "seen": seen, "robots": robots})

    frames = {r["id"]: next(p[1:] for p in r["trajectory"] if p[0] >= origin_stamp[r["id"]]) for r in robots}

    def estimate(lid, frame, sigma):
        lm = landmarks[lid]
        x, y = _compose_inverse(frame, lm["x"], lm["y"])
        a = rng.uniform(0, math.pi)
        s1, s2 = sigma * rng.uniform(1.0, 2.5), sigma * rng.uniform(0.3, 1.0)
        c, s = math.cos(a), math.sin(a)
        cov = [c * c * s1 * s1 + s * s * s2 * s2, c * s * (s1 * s1 - s2 * s2), s * s * s1 * s1 + c * c * s2 * s2]
        return {"id": lid, "x": x + rng.gauss(0, s2), "y": y + rng.gauss(0, s2), "cov": cov, "signature": lid}

    agents = []
    for r in robots:
        rid, frame = r["id"], frames[r["id"]]
        adir = d / f"agent_{rid}"
        local = [estimate(lid, frame, 0.15) for lid in sensed[rid]]
        _write(adir / "local_map.json", {"landmarks": local, "shape_sigma_m": 0.03})
        if rid != 2:
            glob = []
            for other in robots:
                for lid in sensed[other["id"]]:
                    if lid not in {g["id"] for g in glob}:
                        e = estimate(lid, frame, 0.15 if other["id"] == rid else 0.4)
                        e.update(signature=-1, origins=[[other["id"], 2 if other["id"] == 3 else 1, lid]])
                        glob.append(e)
            _write(adir / "global_map.json", {"landmarks": glob, "shape_sigma_m": 0.0, "stats": {}})
        poses = []
        for p in r["trajectory"]:
            if p[0] < origin_stamp[rid]:
                continue
            x, y = _compose_inverse(frame, p[1], p[2])
            drift = 0.01 * (p[0] - origin_stamp[rid])
            poses.append([p[0], x + drift, y - drift, p[3] - frame[2]])
        _write(adir / "trajectory.json", {"frame_origin_stamp": origin_stamp[rid], "poses": poses})
        _write(adir / "stats.json", {"id": rid, "incarnation": 2 if rid == 3 else 1,
                                     "frame_origin_stamp": origin_stamp[rid], "final": True})
        glob_metrics = {"landmarks": 0 if rid == 2 else len(glob), "rmse_m": 0.21 + 0.1 * rid,
                        "rmse_aligned_m": 0.0715 * rid,
                        "nees_mean": 0.2 if rid == 3 else 1.7 + rid / 3,  # 0.2: outside [1, 3], flagged
                        "coverage": round(len(seen) * 0.9 / len(seen), 3),
                        "consistent_ratio": 0.95, "rmse_own_landmarks_m": 0.2}
        if rid == 2:
            glob_metrics = None
        agents.append({
            "id": rid, "alive_at_end": True, "exit_code": 0, "restarts": 1 if rid == 3 else 0,
            "killed_at": [20.0] if rid == 3 else [], "restarted_at": [30.0] if rid == 3 else [],
            "paused_at": [40.0] if rid == 1 else [],
            "final_state": True,
            "frame_in_world": None if rid == 2 else frame,
            "local": {"landmarks": len(local), "matched": len(local), "rmse_m": 0.123456789 * rid,
                      "rmse_aligned_m": None if rid == 2 else 0.0456 * rid,
                      "nees_mean": {1: 848.0, 2: 2.0 + 2 / 7, 3: None}[rid],  # 848: flagged
                      "consistent_ratio": 0.97, "coverage": len(sensed[rid]) / len(seen),
                      "trajectory_rmse_m": 0.3, "frame": "true_origin"},
            "global": glob_metrics,
            "peers_aligned": [p for p in (1, 2, 3) if p != rid][: 1 if rid == 2 else 2],
            "peers_stale": [3] if rid == 2 else [],
            "alignment_errors": {},
            "maps_received": 40 + rid, "maps_dropped": 3, "maps_rejected": {},
            "bytes_sent": 12000 * rid, "bytes_received": 23000 + rid, "bytes_per_landmark": 16.25 + rid / 100,
            "odom_processed": 600, "scans_processed": 120, "odom_sent": 600, "scans_sent": 120,
            "cpu_s": 0.5 + rid / 10, "max_rss_mb": 11.9 + rid,
        })
    summary = {"scenario": "fake3", "scenario_file": "scenarios/fake3.yaml", "sim_duration_s": duration,
               "wall_s": 2.5, "real_time_factor": 24.0, "pace": "lockstep", "interrupted": False,
               "kills": [{"id": 3, "t": 20.0}], "restarts": [{"id": 3, "t": 30.0}],
               "pauses": [{"id": 1, "t": 40.0, "seconds": 3.0, "wall_start": 1.0e9, "wall_end": 1.0e9 + 3.0}],
               "feeder": {"exit_code": 0, "cpu_s": 0.1, "max_rss_mb": 10.0}, "agents": agents}

    def limit(rmse, nees, world):
        return {"landmarks": 60, "matched": 60, "rmse_aligned_m": rmse, "rmse_m": rmse * 1.2 if world else None,
                "nees_mean": nees, "frame": "world" if world else "aligned", "solve_s": 0.05, "converged": True}

    summary["reference"] = {"available": True, "loss": "none", "total_s": 0.4, "wall_s": 0.45,
                            "central": limit(0.0321, 1.97, True), "central_known_starts": limit(0.0280, 2.01, True),
                            "known_pose": limit(0.0187, 2.05, True),
                            "own_batch": {str(r): limit(0.04 + r / 100, 2.1, True) for r in (1, 2, 3)}}
    _write(d / "summary.json", summary)

    # timeline.json: a checkpoint every period while each agent runs; maps flow between robots
    # closer than 14 m; agent 3's second incarnation counts from 0 again.
    truth_at = {r["id"]: {p[0]: p for p in r["trajectory"]} for r in robots}
    timeline = {}
    for rid in circles:
        entries, received, sent, inc = [], {}, 0, 1
        t = period
        while t <= duration + 1e-9:
            if rid == 3 and 20.0 <= t < 35.0:
                if t == 30.0:
                    received, sent, inc = {}, 0, 2
                t += period
                continue
            for other in circles:
                alive = other != 3 or not 20.0 <= t < 30.0
                if other != rid and alive:
                    a, b = truth_at[rid][t], truth_at[other][t]
                    if math.hypot(a[1] - b[1], a[2] - b[2]) < 14:
                        received[str(other)] = received.get(str(other), 0) + 5
            sent += 1000 + 100 * rid
            k = len(entries) + 1
            metrics = {"landmarks": 5 * k, "nees_mean": 1.5 + 0.3 * rid + 0.05 * k,
                       "coverage": min(1.0, 0.05 * k * rid), "rmse_m": 0.1 + 0.01 * k}
            entries.append({"t": t, "incarnation": inc, "local": dict(metrics),
                            "global": None if rid == 2 and k < 3 else dict(metrics, coverage=min(1.0, 0.08 * k)),
                            "bytes_sent": sent, "bytes_received": sum(received.values()) * 300,
                            "maps_received_from": dict(received), "peers_aligned": [], "peers_stale": []})
            t += period
        timeline[str(rid)] = entries
    _write(d / "timeline.json", {"agents": timeline, "kills": summary["kills"], "restarts": summary["restarts"],
                                 "pauses": summary["pauses"], "period_s": period})
    return summary


# ----- checks -------------------------------------------------------------------------------
class _Page(HTMLParser):
    """The parts of report.html the checks read: images, links, scripts, the summary table."""

    def __init__(self):
        super().__init__(convert_charrefs=True)
        self.images = []  # attribute dicts of <img>
        self.urls = []  # href and src values
        self.scripts = 0
        self.ids = set()
        self.table_rows = {}  # data-agent -> [(data-key, data-value, text)]
        self.header_keys = []
        self.header_texts = []
        self.captions = {}  # data-agent of a figure's image -> its caption
        self.flagged = set()  # (data-agent, data-key) of the summary cells of class flag
        self.flag_items = []  # the texts of ul#flags's items
        self._in_flags = False
        self._flag_item = None
        self._in_summary = False
        self._header = None
        self._caption = None
        self._figure_agent = None
        self._row = None
        self._cell = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        if "id" in a:
            self.ids.add(a["id"])
        for k in ("href", "src"):
            if k in a:
                self.urls.append(a[k])
        if tag == "script":
            self.scripts += 1
        if tag == "img":
            self.images.append(a)
            self._figure_agent = a.get("data-agent")
        if tag == "figcaption":
            self._caption = ""
        if tag == "table" and a.get("id", "").startswith("summary"):  # the summary's tables, in order
            self._in_summary = True
        if tag == "ul" and a.get("id") == "flags":
            self._in_flags = True
        if tag == "li" and self._in_flags:
            self._flag_item = ""
        if not self._in_summary:
            return
        if tag == "tr" and "data-agent" in a:
            self._row = self.table_rows.setdefault(a["data-agent"], [])
            self._row_agent = a["data-agent"]
        elif tag == "th" and "data-key" in a:
            self.header_keys.append(a["data-key"])
            self._header = ""
        elif tag == "td" and self._row is not None and "data-key" in a:  # not a later table's agent column
            self._cell = [a.get("data-key"), a.get("data-value"), ""]
            if "flag" in (a.get("class") or "").split():
                self.flagged.add((self._row_agent, a.get("data-key")))

    def handle_endtag(self, tag):
        if tag == "li" and self._flag_item is not None:
            self.flag_items.append(self._flag_item)
            self._flag_item = None
        if tag == "ul":
            self._in_flags = False
        if tag == "figcaption" and self._caption is not None:
            if self._figure_agent is not None:
                self.captions[self._figure_agent] = self._caption
            self._caption = self._figure_agent = None
        if tag == "th" and self._header is not None:
            self.header_texts.append(self._header)
            self._header = None
        if tag == "table" and self._in_summary:
            self._in_summary = False
        elif tag == "td" and self._cell is not None:
            self._row.append(tuple(self._cell))
            self._cell = None
        elif tag == "tr":
            self._row = None

    def handle_data(self, data):
        if self._flag_item is not None:
            self._flag_item += data
        if self._cell is not None:
            self._cell[2] += data
        if self._header is not None:
            self._header += data
        if self._caption is not None:
            self._caption += data


def png_size(path):
    """(width, height) from a PNG's IHDR; raises ValueError if the file is not a PNG."""
    data = Path(path).read_bytes()[:24]
    if len(data) < 24 or not data.startswith(PNG_SIGNATURE) or data[12:16] != b"IHDR":
        raise ValueError(f"{path}: not a PNG")
    return struct.unpack(">II", data[16:24])


def check_png(testcase, path, min_bytes=5000, min_px=300):
    testcase.assertTrue(Path(path).is_file(), f"{path} missing")
    width, height = png_size(path)
    testcase.assertGreater(Path(path).stat().st_size, min_bytes, path)
    testcase.assertGreaterEqual(width, min_px, path)
    testcase.assertGreaterEqual(height, min_px, path)
    return width, height


def _lookup(record, path):
    for part in path.split("."):
        if not isinstance(record, dict):
            return None
        record = record.get(part)
    return record


def _check_cell_text(testcase, value, text, where):
    text = text.strip()
    if value is None:
        testcase.assertEqual(text, DASH, where)
    elif isinstance(value, bool):
        testcase.assertEqual(text, "yes" if value else "no", where)
    elif isinstance(value, list):
        testcase.assertEqual(text, str(len(value)), where)
    elif isinstance(value, int):
        testcase.assertEqual(text, str(value), where)
    elif isinstance(value, float):
        testcase.assertTrue(math.isclose(float(text), value, rel_tol=6e-3, abs_tol=1e-12), f"{where}: {text}")


def check_report(testcase, run_dir, run=True):
    """Runs report.py on run_dir (unless run=False) and checks report.html: it exists; every
    <img> it shows is a PNG under run_dir of more than 5 kB and at least 300 x 300 px; each
    agent has a map figure; the page has no script and no external URL; table#summary has one
    row per agent of summary.json, each cell's data-value equal to the summary's value at its
    data-key and its text agreeing; with a timeline.json the time figures are there, without
    one the page says so. Returns the parsed page (_Page)."""
    run_dir = Path(run_dir)
    if run:
        r = subprocess.run([PYTHON, str(REPORT), str(run_dir)], capture_output=True, text=True, timeout=120)
        testcase.assertEqual(r.returncode, 0, r.stderr)
        testcase.assertEqual(r.stdout.strip().splitlines()[-1], str(run_dir / "report.html"))
    page_path = run_dir / "report.html"
    testcase.assertTrue(page_path.is_file())
    page = _Page()
    page.feed(page_path.read_text())
    summary = json.loads((run_dir / "summary.json").read_text())

    testcase.assertEqual(page.scripts, 0)
    for url in page.urls:
        testcase.assertNotRegex(url, r"^[a-z]+:|^//|^/", f"not a relative path: {url}")
    testcase.assertTrue(page.images)
    for img in page.images:
        src = img.get("src", "")
        testcase.assertTrue(src.startswith("report/") and src.endswith(".png"), src)
        check_png(testcase, run_dir / src)
    mapped = {img.get("data-agent") for img in page.images}
    for a in summary["agents"]:
        testcase.assertIn(str(a["id"]), mapped, f"no map figure of agent {a['id']}")
    srcs = {img["src"] for img in page.images}
    if (run_dir / "timeline.json").exists():
        for name in TIMELINE_IMAGES:
            testcase.assertIn(name, srcs)
    else:
        testcase.assertIn("no-timeline", page.ids)

    testcase.assertEqual(page.header_keys, SUMMARY_KEYS)
    testcase.assertEqual(page.header_texts, SUMMARY_HEADERS)
    testcase.assertEqual(sorted(page.table_rows), sorted(str(a["id"]) for a in summary["agents"]))
    for a in summary["agents"]:
        cells = page.table_rows[str(a["id"])]
        testcase.assertEqual([c[0] for c in cells], SUMMARY_KEYS)
        for key, data_value, text in cells:
            where = f"agent {a['id']} {key}"
            expected = _lookup(a, key)
            testcase.assertEqual(json.loads(data_value), expected, where)
            _check_cell_text(testcase, expected, text, where)
        # A map whose mean NEES is outside the consistency band [1, 3] is flagged: its cell and a
        # line in the list under the table; no other is.
        for key in ("local.nees_mean", "global.nees_mean"):
            v = _lookup(a, key)
            outside = isinstance(v, (int, float)) and not 1.0 <= v <= 3.0
            testcase.assertEqual((str(a["id"]), key) in page.flagged, outside, f"agent {a['id']} {key} = {v}")
            item = f"agent {a['id']}: {key.split('.')[0]} map mean NEES"
            testcase.assertEqual(any(i.startswith(item) for i in page.flag_items), outside, page.flag_items)
        # Each map figure's caption quotes the RMSE after a rigid fit first, the true-frame one beside.
        m = re.search(r"RMSE after rigid fit local (\S+) m / global (\S+) m \(true frame (\S+) m / (\S+) m\)",
                      page.captions.get(str(a["id"]), ""))
        testcase.assertIsNotNone(m, f"agent {a['id']}: {page.captions.get(str(a['id']))}")
        for key, text in zip(("local.rmse_aligned_m", "global.rmse_aligned_m", "local.rmse_m", "global.rmse_m"),
                             m.groups()):
            _check_cell_text(testcase, _lookup(a, key), text, f"agent {a['id']} caption {key}")
    return page


def check_in_browser(testcase, run_dir, shot, width=1600):
    """Opens run_dir/report.html in headless Chromium (tests/js/report_shot.mjs, npm
    playwright-core driving Debian's chromium) and checks what a reader sees: every image loaded
    with a size, none wider than the page shows it, the page no wider than the window, no error
    in the console, the summary table there. Writes a full-page screenshot to shot; returns the
    browser's facts."""
    r = subprocess.run(["node", str(REPO / "tests" / "js" / "report_shot.mjs"), str(Path(run_dir) / "report.html"),
                        str(shot), str(width)], capture_output=True, text=True, timeout=180)
    testcase.assertEqual(r.returncode, 0, r.stderr)
    facts = json.loads(r.stdout)
    page = _Page()
    page.feed((Path(run_dir) / "report.html").read_text())
    testcase.assertEqual(facts["images"], len(page.images))
    testcase.assertEqual(facts["broken"], [])
    testcase.assertEqual(facts["too_wide"], [])
    testcase.assertLessEqual(facts["page_width"], facts["view_width"], "the page scrolls sideways")
    testcase.assertEqual(facts["console_errors"], [])
    testcase.assertIn("summary", facts["tables"])
    testcase.assertGreater(Path(shot).stat().st_size, 50_000)
    return facts


def make_fake_sweep(d, param="radio.range_m"):
    """Writes d/sweep.csv as `swarm sweep` does (scripts/mapmesh/sweep.py: the parameter, then
    SWEEP_HEADER): param in {0, 10, 20, 40, 80} x 3 seeds x 3 agents, with a few empty cells;
    returns the rows written."""
    d = Path(d)
    d.mkdir(parents=True, exist_ok=True)
    rng = random.Random(3)
    out = []
    for value in (0, 10, 20, 40, 80):
        for seed in (1, 2, 3):
            for agent in (1, 2, 3):
                share = min(1.0, value / 60)
                nees = "" if value == 0 and agent == 2 else round(rng.uniform(1, 3 + 5 * share), 4)  # an empty cell
                out.append({param: value, "seed": seed, "agent": agent, "alive": 1, "lm_local": 40,
                            "lm_global": 90,
                            "coverage_global": round(0.3 + 0.6 * share + rng.uniform(-0.05, 0.05), 4),
                            "coverage_reached": 1.0, "nees_global": nees,
                            "rmse_global_aligned_m": round(rng.uniform(0.03, 0.1 + share), 4),
                            "rmse_global_m": round(rng.uniform(0.1, 0.3 + share), 4), "rmse_local_aligned_m": 0.05,
                            "rmse_local_m": 0.2, "nees_local": 1.9, "rmse_central_same_m": 0.03,
                            "gap_to_central": round(rng.uniform(1.0, 2 + 3 * share), 4),
                            "rmse_central_known_starts_same_m": 0.027, "gap_to_central_known_starts": 1.2,
                            "gap_to_own_batch": 1.05,
                            "peers_aligned": 2, "bytes_sent": 1000, "wall_s": 3.2})
    assert list(out[0]) == [param] + SWEEP_HEADER
    with open(d / "sweep.csv", "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(out[0]))
        w.writeheader()
        w.writerows(out)
    return out


def check_sweep(testcase, d, old_rmse=False):
    """Runs sweep.py on d and checks d/sweep.png; old_rmse: sweep.csv has only the true-frame
    RMSE (written before the rigid-fit one), which sweep.py says on stderr it draws instead."""
    r = subprocess.run([PYTHON, str(SWEEP), str(d)], capture_output=True, text=True, timeout=120)
    testcase.assertEqual(r.returncode, 0, r.stderr)
    if old_rmse:
        testcase.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)
        testcase.assertIn("no column rmse_global_aligned_m", r.stderr)
        testcase.assertIn("the global RMSE, true frame", r.stderr)
    else:
        testcase.assertNotIn("no column", r.stderr)
    testcase.assertEqual(r.stdout.strip().splitlines()[-1], str(Path(d) / "sweep.png"))
    width, _ = check_png(testcase, Path(d) / "sweep.png", min_bytes=10_000)
    testcase.assertGreaterEqual(width, 800)


def _check_help_and_missing(testcase, script, needed, how):
    h = subprocess.run([PYTHON, str(script), "--help"], capture_output=True, text=True, timeout=60)
    testcase.assertEqual(h.returncode, 0, h.stderr)
    testcase.assertIn("Usage", h.stdout)
    with tempfile.TemporaryDirectory(prefix="mapmesh_report_") as tmp:
        for d in (Path(tmp) / "nonexistent", Path(tmp)):
            r = subprocess.run([PYTHON, str(script), str(d)], capture_output=True, text=True, timeout=60)
            testcase.assertEqual(r.returncode, 1)
            testcase.assertEqual(r.stderr.strip().splitlines(),
                                 [f"{script.name}: {d}: no {needed} (run {how} --out {d})"])
            testcase.assertEqual(r.stdout, "")


# ----- tests --------------------------------------------------------------------------------
class ReportTest(unittest.TestCase):
    def test_report_of_a_synthetic_run(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_report_") as tmp:
            summary = make_fake_run(tmp)
            page = check_report(self, tmp)
            maps = [i for i in page.images if i.get("data-agent")]
            self.assertEqual(len(maps), len(summary["agents"]))
            for img in maps:
                width, _ = png_size(Path(tmp) / img["src"])
                self.assertGreaterEqual(width, 800)
            text = (Path(tmp) / "report.html").read_text()
            self.assertIn("agent 3 at 20.0 s", text)  # the kill
            self.assertIn("agent 3 at 30.0 s", text)  # the restart
            self.assertIn("Pauses: agent 1 at 40.0 s for 3.00 s (wall)", text)  # the pause
            self.assertIn("paused at (s)", text)
            self.assertIn("own frame (pose unknown)", text)  # agent 2's frame_in_world is null
            # The limit: the centralized optimum with no start known, with the true starts, the
            # known-pose map and each robot's own optimum.
            self.assertIn("reference-table", page.ids)
            self.assertIn("<td>centralized batch optimum (all robots&#x27; data, no start known)</td><td>60</td>"
                          "<td>0.0321</td><td>0.0385</td><td>1.97</td><td>yes</td>", text)
            self.assertIn("<td>the same with every robot&#x27;s true start</td><td>60</td><td>0.0280</td>", text)
            self.assertIn("<td>robot 3&#x27;s own batch optimum</td>", text)

    def test_report_in_a_real_browser(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_report_") as tmp:
            make_fake_run(tmp)
            check_report(self, tmp)
            facts = check_in_browser(self, tmp, Path(tmp) / "shot.png")
            self.assertEqual(facts["title"], "mapmesh run: fake3")
            self.assertEqual(png_size(Path(tmp) / "shot.png")[0], 1600)
            self.assertGreater(facts["height"], 3000)  # a map per agent, the figures over time

    def test_report_without_timeline_or_agent_files(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_report_") as tmp:
            make_fake_run(tmp)
            check_report(self, tmp)  # with a timeline first: its figures must not outlive it
            (Path(tmp) / "timeline.json").unlink()
            for name in ("local_map.json", "global_map.json", "trajectory.json"):
                (Path(tmp) / "agent_3" / name).unlink()  # an agent killed before writing anything
            summary = json.loads((Path(tmp) / "summary.json").read_text())
            del summary["reference"]  # a run of an older build
            (Path(tmp) / "summary.json").write_text(json.dumps(summary))
            page = check_report(self, tmp)
            self.assertIn("no-timeline", page.ids)
            self.assertIn("reference", page.ids)  # summary.json without a reference: the page says so
            self.assertNotIn("reference-table", page.ids)
            self.assertFalse((Path(tmp) / "report" / "nees.png").exists())
            self.assertIn("agent 3: no local_map.json", (Path(tmp) / "report.html").read_text())

    def test_help_and_missing_directory(self):
        _check_help_and_missing(self, REPORT, "summary.json", "scripts/swarm run ...")


class SweepTest(unittest.TestCase):
    def test_sweep_figure(self):
        # What `swarm sweep` writes: the rigid-fit RMSE before the true-frame one, global then local.
        self.assertEqual(columns.SWEEP_HEADER, SWEEP_HEADER)
        self.assertEqual([c.name for c in columns.PLOT_COLUMNS],
                         ["coverage_global", "nees_global", "rmse_global_aligned_m", "gap_to_central"])
        with tempfile.TemporaryDirectory(prefix="mapmesh_sweep_") as tmp:
            make_fake_sweep(tmp)
            check_sweep(self, tmp)

    def test_a_grid_draws_a_row_of_panels_per_parameter(self):
        # X1: the columns before `seed` are the swept parameters; each gets a row of panels.
        with tempfile.TemporaryDirectory(prefix="mapmesh_sweep_") as tmp:
            make_fake_sweep(tmp)
            check_sweep(self, tmp)
            _, one_row = check_png(self, Path(tmp) / "sweep.png", min_bytes=10_000)
            with open(Path(tmp) / "sweep.csv", newline="") as f:
                rows = list(csv.DictReader(f))
            with open(Path(tmp) / "sweep.csv", "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=["radio.range_m", "radio.loss_probability"] + list(rows[0])[1:])
                w.writeheader()
                for i, r in enumerate(rows):
                    w.writerow({**r, "radio.loss_probability": (0, 0.5)[i % 2]})
            r = subprocess.run([PYTHON, str(SWEEP), tmp], capture_output=True, text=True, timeout=120)
            self.assertEqual(r.returncode, 0, r.stderr)
            _, two_rows = check_png(self, Path(tmp) / "sweep.png", min_bytes=10_000)
            self.assertGreater(two_rows, 1.7 * one_row)

    def test_categorical_parameter_and_missing_column(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_sweep_") as tmp:
            rows = make_fake_sweep(tmp, param="fusion.method")
            # Names as summary paths, no NEES column, a parameter that is not a number.
            with open(Path(tmp) / "sweep.csv", "w", newline="") as f:
                w = csv.DictWriter(f, fieldnames=["fusion.method", "seed", "global_coverage", "global_rmse_m"])
                w.writeheader()
                for r in rows:
                    w.writerow({"fusion.method": ["ci", "ml", "info", "ci", "ml"][r["fusion.method"] // 20],
                                "seed": r["seed"], "global_coverage": r["coverage_global"],
                                "global_rmse_m": r["rmse_global_m"]})
            check_sweep(self, tmp, old_rmse=True)

    def test_no_metric_columns_is_one_line(self):
        with tempfile.TemporaryDirectory(prefix="mapmesh_sweep_") as tmp:
            (Path(tmp) / "sweep.csv").write_text("radio.range_m,seed\n10,1\n")
            r = subprocess.run([PYTHON, str(SWEEP), tmp], capture_output=True, text=True, timeout=60)
            self.assertEqual(r.returncode, 1)
            self.assertEqual(len(r.stderr.strip().splitlines()), 1, r.stderr)

    def test_help_and_missing_directory(self):
        _check_help_and_missing(self, SWEEP, "sweep.csv", "scripts/swarm sweep ...")


class ReportLayoutTest(unittest.TestCase):
    """U1 (looked at in headless Chromium at 1400 px): the 24-column table needed a horizontal
    scrollbar, past 10 agents the colours repeated, and the exchange chart was 6,880 px tall at 16
    agents. Real runs of park4 at 4, 16 and 64 agents (64: label slow)."""

    def check_layout(self, agents, duration_s):
        sys.path.insert(0, str(REPORT.parent))
        import report as report_module  # noqa: E402 (scripts/plots/report.py: needs matplotlib)
        with tempfile.TemporaryDirectory(prefix="mapmesh_layout_") as tmp:
            out = Path(tmp) / "run"
            r = subprocess.run([sys.executable, str(REPO / "scripts" / "swarm"), "run", str(REPO / "scenarios" /
                                "park4.yaml"), "--agents", str(agents), "--set", f"duration_s={duration_s}",
                                "--kill", "2@10", "--quiet", "--out", str(out)],
                               capture_output=True, text=True, timeout=1200)
            self.assertEqual(r.returncode, 0, r.stdout + r.stderr)
            self.assertTrue((out / "report.html").is_file(), r.stderr)
            facts = check_in_browser(self, out, Path(tmp) / "shot.jpg", width=1400)
            self.assertEqual(facts["sideways"], [], "an element scrolls sideways")
            self.assertLessEqual(facts["tallest_image"], 2000)
            for tid in ("summary", "summary-limit", "summary-traffic"):
                self.assertIn(tid, facts["tables"])
            run = report_module.Run(out)
            colours = [run.colours[rid] for rid in run.ids]
            if agents <= report_module.DISTINCT_COLOURS:
                self.assertEqual(len(set(colours)), agents)  # every agent a colour of its own
                self.assertEqual(run.groups, [])
            else:  # grouped: a hue per group of consecutive agents, each named once in the legends
                self.assertLessEqual(len(run.groups), report_module.COLOUR_GROUPS)
                self.assertEqual([rid for _, _, members in run.groups for rid in members], run.ids)
                labels = [report_module.agent_label(run, rid) for rid in run.ids]
                self.assertEqual([x for x in labels if x], [label for label, _, _ in run.groups])
            page = (out / "report.html").read_text()
            if agents > report_module.EXCHANGE_ROWS_AGENTS:
                self.assertIn("Who heard whom", page)
            # Beyond 16 agents the maps are folded by colour group (a closed <details> each).
            self.assertEqual(page.count('<details class="maps">'), len(run.groups))
            return facts

    def test_a_fall_of_coverage_is_captioned_with_the_alignment_dropped(self):
        # U1: a coverage drop (0.80 -> 0.30 -> 0.80 at 130-150 s, an alignment dropped) had no caption.
        sys.path.insert(0, str(REPORT.parent))
        import report as report_module  # noqa: E402

        class FakeRun:
            def alignments(self, rid):
                return [(100.0, 2, True), (135.0, 2, False), (150.0, 2, True)] if rid == 1 else []

        def entry(t, c, inc=1):
            return {"t": t, "incarnation": inc, "global": {"coverage": c}}
        tl = {1: [entry(120, 0.8), entry(140, 0.3), entry(160, 0.8)],
              3: [entry(120, 0.9), entry(140, 0.85), entry(160, 0.1, inc=2)]}  # a restart is not a fall
        drops = report_module.coverage_drops(FakeRun(), tl)
        self.assertEqual(drops, [(1, 120, 0.8, 140, 0.3, [2])])
        self.assertIn("agent 1 0.80 \u2192 0.30 at 120-140 s (dropped its alignment of 2)",
                      report_module.drops_text(drops))
        self.assertEqual(report_module.drops_text([]), "")

    def test_the_fit_panel_draws_each_landmarks_error_scaled_up(self):
        # U1: the "map frame" and "rigid fit" panels looked the same although their RMSEs differed tenfold.
        sys.path.insert(0, str(REPORT.parent))
        import report as report_module  # noqa: E402
        self.assertEqual([report_module.nice_scale(x) for x in (0.3, 1, 3.9, 19, 20, 75, 1e9)],
                         [1, 1, 2, 10, 20, 50, 5_000_000])

        class FakeRun:
            truth = {"landmarks": [{"id": i, "x": 10.0 * i, "y": 0.0} for i in range(5)]}
        local = {"landmarks": [{"signature": i, "x": 10.0 * i + 0.01, "y": -0.02} for i in range(5)]
                 + [{"signature": -1, "x": 3.0, "y": 3.0}]}  # no identity: no vector
        fig, ax = report_module.plt.subplots()
        handles = []
        report_module.draw_errors(ax, FakeRun(), [(local, [0.0, 0.0, 0.0], "tab:blue", "local map")], handles)
        (lines,) = ax.collections
        segments = lines.get_segments()
        self.assertEqual(len(segments), 5)
        scale = report_module.nice_scale(0.03 * 40 / math.hypot(0.01, 0.02))  # 3 % of the span per median error
        self.assertEqual(handles[0].get_label(), f"local map error \u00d7{scale:g} (from the truth)")
        for i, seg in enumerate(segments):
            self.assertAlmostEqual(seg[0][0], 10.0 * i)
            self.assertAlmostEqual(seg[1][0] - seg[0][0], 0.01 * scale)
            self.assertAlmostEqual(seg[1][1] - seg[0][1], -0.02 * scale)
        report_module.plt.close(fig)

    def test_the_report_reads_at_a_glance_at_4_and_16_agents(self):
        self.check_layout(4, 40)
        self.check_layout(16, 30)

    def test_the_report_reads_at_a_glance_at_64_agents(self):
        self.check_layout(64, 20)


if __name__ == "__main__":
    unittest.main()
