#!/usr/bin/python3
"""Plots the thesis alignment experiments written by `mapmesh-lab thesis-align --out DIR`.

Usage: /usr/bin/python3 scripts/plots/alignment.py DIR      (writes DIR/*.png)
Needs Debian's python3-matplotlib (scripts/install-deps installs it)."""

import csv
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def curves(data, group, x, y, where=None):
    out = defaultdict(list)
    for r in data:
        if where and not where(r):
            continue
        out[r[group]].append((float(r[x]), float(r[y])))
    return {k: sorted(v) for k, v in out.items()}


def panel(ax, series, title, xlabel, ylabel, label_fmt="{}"):
    for name, pts in series.items():
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", ms=3, label=label_fmt.format(name))
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def main(argv):
    if len(argv) == 2 and argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0
    if len(argv) != 2:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    d = Path(argv[1])
    if not (d / "fig46_similarity.csv").exists():
        print(f"alignment.py: {d}: no fig46_similarity.csv (run mapmesh-lab thesis-align --out {d})", file=sys.stderr)
        return 1
    sim = rows(d / "fig46_similarity.csv")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    panel(axes[0], curves(sim, "landmarks", "overlap", "candidate_precision", lambda r: r["matcher"] == "sorted_sides"),
          "Fig. 46: true share of candidate pairs (sorted sides)", "overlap ratio", "share", "{} landmarks")
    panel(axes[1], curves(sim, "landmarks", "overlap", "correct_rate", lambda r: r["matcher"] == "sorted_sides"),
          "alignment within 0.2 m and 1 deg", "overlap ratio", "success rate", "{} landmarks")
    fig.tight_layout()
    fig.savefig(d / "fig46_similarity.png", dpi=110)

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, name, title in [(axes[0], "fig48_noise.csv", "Fig. 48: RANSAC vs landmark noise"),
                            (axes[1], "fig50_transforms.csv", "Fig. 50: with random transforms")]:
        panel(ax, curves(rows(d / name), "landmarks", "sigma_m", "thesis_success"), title,
              "landmark sigma (m)", "true pairs among inliers", "{} landmarks")
    fig.tight_layout()
    fig.savefig(d / "fig48_50_noise.png", dpi=110)

    mr = rows(d / "fig49_51_match_ratio.csv")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    panel(axes[0], curves(mr, "landmarks", "match_ratio", "thesis_success"), "Fig. 49: RANSAC vs true-match ratio",
          "true-match ratio", "true pairs among inliers", "{} landmarks")
    panel(axes[1], curves(mr, "landmarks", "match_ratio", "median_ms"), "Fig. 51: RANSAC time", "true-match ratio",
          "median ms", "{} landmarks")
    fig.tight_layout()
    fig.savefig(d / "fig49_51_match_ratio.png", dpi=110)

    dist = rows(d / "fig52_53_distance.csv")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    panel(axes[0], curves(dist, "distance", "sigma_m", "thesis_success"), "Fig. 52: Euclidean vs Mahalanobis",
          "landmark sigma (m)", "true pairs among inliers")
    panel(axes[1], curves(dist, "distance", "sigma_m", "median_ms"), "Fig. 53: time", "landmark sigma (m)", "median ms")
    fig.tight_layout()
    fig.savefig(d / "fig52_53_distance.png", dpi=110)
    print(f"alignment.py: wrote {len(list(d.glob('*.png')))} figures in {d}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
