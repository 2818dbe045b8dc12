#!/usr/bin/python3
"""Plots the thesis alignment experiments written by `mapmesh-lab thesis-align --out DIR`.

Usage: /usr/bin/python3 scripts/plots/alignment.py DIR      (writes DIR/*.png)
Needs Debian's python3-matplotlib (scripts/install-deps installs it).

Fig. 45 (how the overlap ratio is varied) is drawn from fig45_overlap.csv: one 200-landmark pair
per ratio, map B in A's frame, the landmarks both maps hold filled."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from plotlib import curves, directory_argument, panel, plt, rows, save  # noqa: E402


def overlap_figure(d):
    data = rows(d / "fig45_overlap.csv")
    ratios = sorted({float(r["overlap"]) for r in data}, reverse=True)
    fig, axes = plt.subplots(1, len(ratios), figsize=(3.2 * len(ratios), 3.6), sharex=True, sharey=True)
    for ax, ov in zip(axes, ratios):
        at = [r for r in data if float(r["overlap"]) == ov]
        for name, colour, marker in [("A", "black", "o"), ("B", "red", "s")]:
            for shared in ("1", "0"):
                pts = [(float(r["x"]), float(r["y"])) for r in at if r["map"] == name and r["shared"] == shared]
                if pts:
                    xs, ys = zip(*pts)
                    ax.scatter(xs, ys, s=10, marker=marker, edgecolors=colour,
                               facecolors=colour if shared == "1" else "none", linewidths=0.7,
                               label=f"map {name}" + (", in both" if shared == "1" else ""))
        both = sum(1 for r in at if r["map"] == "A" and r["shared"] == "1")
        na = sum(1 for r in at if r["map"] == "A")
        ax.set_title(f"overlap {ov:g}: {both} of {na} shared", fontsize=9)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
    axes[0].set_ylabel("y (m)")
    axes[-1].legend(fontsize=7, loc="lower right")
    fig.suptitle("Fig. 45: the overlap ratio (map B's square slides along A's diagonal)")
    save(fig, d / "fig45_overlap.png")


def main(argv):
    d, code = directory_argument(argv, __doc__, "alignment.py", "fig46_similarity.csv",
                                 "mapmesh-lab thesis-align --out")
    if d is None:
        return code
    if (d / "fig45_overlap.csv").exists():
        overlap_figure(d)
    sim = rows(d / "fig46_similarity.csv")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    panel(axes[0], curves(sim, "landmarks", "overlap", "candidate_precision", lambda r: r["matcher"] == "sorted_sides"),
          "Fig. 46: true share of candidate pairs (sorted sides)", "overlap ratio", "share", "{} landmarks")
    panel(axes[1], curves(sim, "landmarks", "overlap", "correct_rate", lambda r: r["matcher"] == "sorted_sides"),
          "alignment within 0.2 m and 1 deg", "overlap ratio", "success rate", "{} landmarks")
    save(fig, d / "fig46_similarity.png")

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, name, title in [(axes[0], "fig48_noise.csv", "Fig. 48: RANSAC vs landmark noise"),
                            (axes[1], "fig50_transforms.csv", "Fig. 50: with random transforms")]:
        panel(ax, curves(rows(d / name), "landmarks", "sigma_m", "thesis_success"), title,
              "landmark sigma (m)", "true pairs among inliers", "{} landmarks")
    save(fig, d / "fig48_50_noise.png")

    mr = rows(d / "fig49_51_match_ratio.csv")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    panel(axes[0], curves(mr, "landmarks", "match_ratio", "thesis_success"), "Fig. 49: RANSAC vs true-match ratio",
          "true-match ratio", "true pairs among inliers", "{} landmarks")
    panel(axes[1], curves(mr, "landmarks", "match_ratio", "median_ms"), "Fig. 51: RANSAC time", "true-match ratio",
          "median ms", "{} landmarks")
    save(fig, d / "fig49_51_match_ratio.png")

    dist = rows(d / "fig52_53_distance.csv")
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    panel(axes[0], curves(dist, "distance", "sigma_m", "thesis_success"), "Fig. 52: Euclidean vs Mahalanobis",
          "landmark sigma (m)", "true pairs among inliers")
    panel(axes[1], curves(dist, "distance", "sigma_m", "median_ms"), "Fig. 53: time", "landmark sigma (m)", "median ms")
    save(fig, d / "fig52_53_distance.png")
    print(f"alignment.py: wrote {len(list(d.glob('*.png')))} figures in {d}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
