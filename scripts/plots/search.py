#!/usr/bin/python3
"""Plots RANSAC vs the adaptive random walk vs the iterative translation search, written by
`mapmesh-lab search --csv DIR/search.csv` (docs/EXPERIMENTS.md, thesis Tables 3-4).

Usage: /usr/bin/python3 scripts/plots/search.py DIR      (writes DIR/search.png)
Needs Debian's python3-matplotlib (scripts/install-deps installs it)."""

import statistics
import sys
from collections import defaultdict
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from plotlib import directory_argument, number, panel, plt, rows, save  # noqa: E402


def main(argv):
    d, code = directory_argument(argv, __doc__, "search.py", "search.csv", "mapmesh-lab search --csv DIR/search.csv;")
    if d is None:
        return code
    groups = defaultdict(list)
    for r in rows(d / "search.csv"):
        groups[(r["search"], number(r["overlap"]))].append(r)
    correct, wrong, ms = defaultdict(list), defaultdict(list), defaultdict(list)
    for (search, overlap), rs in sorted(groups.items(), key=lambda kv: kv[0][1]):
        n = len(rs)
        correct[search].append((overlap, sum(int(r["correct"]) for r in rs) / n))
        wrong[search].append((overlap, sum(r["verdict"] == "accepted" and r["correct"] == "0" for r in rs) / n))
        ms[search].append((overlap, statistics.median(number(r["ms"]) for r in rs)))
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    panel(axes[0], correct, "accepted within 0.2 m and 1 deg", "overlap", "share of pairs")
    panel(axes[1], wrong, "accepted but wrong", "overlap", "share of pairs")
    panel(axes[2], ms, "time per alignment", "overlap", "median ms")
    axes[2].set_yscale("log")
    save(fig, d / "search.png")
    print(f"search.py: wrote {d / 'search.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
