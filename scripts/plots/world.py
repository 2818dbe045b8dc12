#!/usr/bin/python3
"""Draws a simulated scenario's world: its landmarks (those any robot saw filled) and every
robot's true trajectory, as the thesis's map-and-trajectory illustrations (Figs. 59, 66, 70,
74, 79 and 82).

Usage: /usr/bin/python3 scripts/plots/world.py SCENARIO.yaml OUT.png [--set KEY=VALUE ...]
The world comes from `mapmesh-feeder --no-dds --record` (its truth.json), so generated
landmarks and paths are drawn exactly as a run sees them. Needs the feeder built
(MAPMESH_BIN, else build/bin) and Debian's python3-matplotlib."""

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from plotlib import plt, save  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


def truth_of(scenario, sets):
    feeder = Path(os.environ.get("MAPMESH_BIN", REPO / "build" / "bin")) / "mapmesh-feeder"
    if not feeder.exists():
        raise RuntimeError(f"{feeder}: not built (cmake --build build)")
    with tempfile.TemporaryDirectory(prefix="mapmesh_world_") as tmp:
        cmd = [str(feeder), "--scenario", str(scenario), "--no-dds", "--record", f"{tmp}/stream.rec", "--out", tmp]
        for s in sets:
            cmd += ["--set", s]
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        if r.returncode != 0:
            raise RuntimeError((r.stderr.strip().splitlines() or ["mapmesh-feeder failed"])[-1])
        return json.loads((Path(tmp) / "truth.json").read_text())


def draw(truth, out):
    seen = set(truth.get("seen", []))
    lm = truth["landmarks"]
    fig, ax = plt.subplots(figsize=(8, 7))
    ax.scatter([p["x"] for p in lm if p["id"] not in seen], [p["y"] for p in lm if p["id"] not in seen], s=6,
               facecolors="none", edgecolors="grey", linewidths=0.5, label="landmark, never seen")
    ax.scatter([p["x"] for p in lm if p["id"] in seen], [p["y"] for p in lm if p["id"] in seen], s=6, c="black",
               label="landmark, seen")
    for k, robot in enumerate(truth["robots"]):
        xs = [p[1] for p in robot["trajectory"]]
        ys = [p[2] for p in robot["trajectory"]]
        ax.plot(xs, ys, color=f"C{k}", lw=1.2, label=f"robot {robot['id']}")
        ax.plot(xs[:1], ys[:1], marker="o", color=f"C{k}")
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{truth.get('scenario', '')}: landmarks and true trajectories", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    save(fig, out)


def main(argv):
    p = argparse.ArgumentParser(prog="world.py", description=__doc__.strip().splitlines()[0])
    p.add_argument("scenario", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="a scenario override")
    a = p.parse_args(argv[1:])
    if not a.scenario.is_file():
        print(f"world.py: {a.scenario}: no such scenario file", file=sys.stderr)
        return 1
    try:
        draw(truth_of(a.scenario, a.set), a.out)
    except (RuntimeError, OSError, json.JSONDecodeError) as e:
        print(f"world.py: {e}", file=sys.stderr)
        return 1
    print(f"world.py: wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
