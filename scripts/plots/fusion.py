#!/usr/bin/python3
"""Plots the thesis fusion experiments written by `mapmesh-lab thesis-fusion --out DIR`.

Usage: /usr/bin/python3 scripts/plots/fusion.py DIR      (writes DIR/*.png)
Needs Debian's python3-matplotlib (scripts/install-deps installs it).

For each sweep (bearing noise, velocity noise, sensor range): the consistent-landmark ratio of
the merged overlap landmarks by estimator, beside each robot's own map (Figs. 61, 64, 72), and
the mean determinant of the merged covariances (Figs. 62, 65, 73). Maximum Likelihood's
covariance is rank-deficient for two inputs, so it has no determinant to plot. OGK and the CI-OGK
hybrid are drawn beside the thesis's estimators when the CSV has them (the CSVs also carry the mean
ellipse area pi sqrt(det), area_*_m2). The Victoria
Park table (Table 7) becomes a bar chart of mean NEES per robot pair."""

import math
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from plotlib import curves, directory_argument, number, panel, plt, rows  # noqa: E402

SWEEPS = [
    ("fig61_62_bearing", "robot 2 bearing sigma (deg)", "Figs. 61-62: bearing noise"),
    ("fig64_65_velocity", "robot 2 velocity sigma (m/s)", "Figs. 64-65: velocity noise"),
    ("fig72_73_range", "robot 2 sensor range (m)", "Figs. 72-73: sensor range, low overlap"),
]


# One colour per estimator in every panel.
METHODS = ["ml", "information", "ci", "ci_det", "ci_trace", "ogk", "ci_ogk"]
METHOD_STYLE = {m: {"color": f"C{k}"} for k, m in enumerate(METHODS)}


def sweep_figure(d, name, xlabel, title):
    data = rows(d / f"{name}.csv")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    series = curves(data, "method", "value", "consistent_merged")
    first = next(iter(series)) if series else None
    if first:
        series["robot 1 map"] = sorted(curves(data, "method", "value", "consistent_a")[first])
        series["robot 2 map"] = sorted(curves(data, "method", "value", "consistent_b")[first])
    dashed = dict(METHOD_STYLE)
    dashed.update({"robot 1 map": {"linestyle": "--", "color": "black"},
                   "robot 2 map": {"linestyle": ":", "color": "grey"}})
    panel(axes[0], series, f"{title}: consistent landmarks (NEES < 5.99)", xlabel, "ratio", style=dashed)
    axes[0].set_ylim(0, 1.05)
    dets = curves(data, "method", "value", "det_merged", lambda r: r["method"] != "ml")
    dets = {k: [(x, y) for x, y in v if y > 0 and math.isfinite(y)] for k, v in dets.items()}
    panel(axes[1], dets, f"{title}: determinant", xlabel, "mean det of merged covariance (m^4)", style=METHOD_STYLE)
    axes[1].set_yscale("log")
    fig.tight_layout()
    fig.savefig(d / f"{name}.png", dpi=110)
    plt.close(fig)


def table_figure(d):
    data = rows(d / "table7_victoria.csv")
    data = [r for r in data if r["verdict"] == "accepted"]
    if not data:
        return
    labels = [f"{r['robot_a']}&{r['robot_b']}" for r in data]
    bars = [("robot a", "nees_a"), ("robot b", "nees_b"), ("merged, information", "nees_merged_information"),
            ("merged, CI", "nees_merged_ci"), ("merged, CI det", "nees_merged_ci_det"),
            ("merged, OGK", "nees_merged_ogk"), ("merged, CI-OGK", "nees_merged_ci_ogk")]
    bars = [(n, c) for n, c in bars if c in data[0]]
    fig, ax = plt.subplots(figsize=(9, 4))
    width = 0.8 / len(bars)
    for k, (name, col) in enumerate(bars):
        ax.bar([i + k * width for i in range(len(data))], [number(r[col]) for r in data], width, label=name)
    ax.set_xticks([i + 0.4 - width / 2 for i in range(len(data))])
    ax.set_xticklabels(labels)
    ax.set_xlabel("Victoria Park robot pair")
    ax.set_ylabel("mean NEES on the overlap")
    ax.set_title("Table 7: single maps and merged map (against the whole-run reference)", fontsize=10)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(d / "table7_victoria.png", dpi=110)
    plt.close(fig)


def main(argv):
    doc = __doc__
    d, code = None, None
    for name, _, _ in SWEEPS + [("table7_victoria", None, None)]:
        if len(argv) == 2 and (Path(argv[1]) / f"{name}.csv").exists():
            d, code = directory_argument(argv, doc, "fusion.py", f"{name}.csv", "mapmesh-lab thesis-fusion --out")
            break
    if d is None:
        d, code = directory_argument(argv, doc, "fusion.py", "fig61_62_bearing.csv", "mapmesh-lab thesis-fusion --out")
        if d is None:
            return code
    for name, xlabel, title in SWEEPS:
        if (d / f"{name}.csv").exists():
            sweep_figure(d, name, xlabel, title)
    if (d / "table7_victoria.csv").exists():
        table_figure(d)
    print(f"fusion.py: wrote {len(list(d.glob('*.png')))} figures in {d}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
