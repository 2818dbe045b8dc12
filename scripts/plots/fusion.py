#!/usr/bin/python3
"""Plots the thesis fusion experiments written by `mapmesh-lab thesis-fusion --out DIR`.

Usage: /usr/bin/python3 scripts/plots/fusion.py DIR      (writes DIR/*.png)
Needs Debian's python3-matplotlib (scripts/install-deps installs it).

For each sweep (bearing noise, velocity noise, sensor range): the consistent-landmark ratio of
the merged overlap landmarks by estimator, beside each robot's own map (Figs. 61, 64, 72), and
the mean determinant of the merged covariances (Figs. 62, 65, 73). Maximum Likelihood's
covariance is rank-deficient for two inputs, so it has no determinant to plot. OGK and the CI-OGK
hybrid are drawn beside the thesis's estimators when the CSV has them (the CSVs also carry the mean
ellipse area pi sqrt(det), area_*_m2). The Victoria Park table (Table 7) becomes a bar chart of
mean NEES per robot pair.

The sweeps with the thesis's alignment figures (the 5 % overlap layout, Figs. 67-69, and the
simulated Victoria Park, Figs. 75-81) get a third panel: map similarity and RANSAC success as
the thesis counts them, and the share of runs aligned; their middle panel is the mean NEES of
the merged overlap. Table 7 on the simulated Victoria Park (ground truth) is a bar chart too.

Fig. 58 (fig58_ellipses.csv, one circle-pair run): six overlap landmarks, each with its 2.448-sigma
(95 %) ellipses: robot 1's and robot 2's own estimates (robot 2's placed by the alignment) and the
merged ones of ML, information fusion (the thesis's M-estimator counterpart), CI and OGK; the
truth is a cross. ML's covariance of two inputs is rank-deficient: its ellipse is a segment."""

import math
import sys
from pathlib import Path


sys.path.insert(0, str(Path(__file__).resolve().parent))
from plotlib import SIGMA_95, curves, directory_argument, ellipse95, number, panel, plt, rows, save  # noqa: E402

SWEEPS = [
    ("fig61_62_bearing", "robot 2 bearing sigma (deg)", "Figs. 61-62: bearing noise"),
    ("fig64_65_velocity", "robot 2 velocity sigma (m/s)", "Figs. 64-65: velocity noise"),
    ("fig72_73_range", "robot 2 sensor range (m)", "Figs. 72-73: sensor range, low overlap"),
]


# Sweeps that also carry the thesis's alignment figures: (CSV, x label, title).
ALIGNED_SWEEPS = [
    ("fig66_69_low_overlap", "robot 2 bearing sigma (deg)", "Figs. 67-69: bearing noise, 5 % overlap"),
    ("fig75_76_vp_bearing", "robot 2 bearing sigma (deg)", "Figs. 75-76: Victoria Park (sim.), bearing noise"),
    ("fig77_78_vp_velocity", "robot 2 velocity sigma (m/s)", "Figs. 77-78: Victoria Park (sim.), velocity noise"),
    ("fig80_81_vp_range", "robot 2 sensor range (m)", "Figs. 80-81: Victoria Park (sim.), sensor range"),
]

# Table 7's pairs in the thesis's order (robot a, robot b).
THESIS_PAIRS = [("2", "1"), ("2", "3"), ("2", "4"), ("3", "1"), ("3", "4"), ("4", "1")]

# One colour per estimator in every panel.
METHODS = ["ml", "information", "ci", "ci_det", "ci_trace", "ogk", "ci_ogk"]
METHOD_STYLE = {m: {"color": f"C{k}"} for k, m in enumerate(METHODS)}


# The robots' own maps beside the estimators: dashed.
DASHED = dict(METHOD_STYLE, **{"robot 1 map": {"linestyle": "--", "color": "black"},
                               "robot 2 map": {"linestyle": ":", "color": "grey"}})


def with_robot_maps(data, series, figure):
    """series plus robot 1's and robot 2's own maps' `figure` (columns figure_a, figure_b), which
    every method's rows repeat: taken from the first method's."""
    first = data[0]["method"] if data else None
    if first:
        series["robot 1 map"] = curves(data, "method", "value", f"{figure}_a")[first]
        series["robot 2 map"] = curves(data, "method", "value", f"{figure}_b")[first]
    return series


def bar_chart(path, groups, bars, xlabel, ylabel, title):
    """Grouped bars: groups are the x tick labels, bars (label, values, one per group)."""
    fig, ax = plt.subplots(figsize=(9, 4))
    width = 0.8 / len(bars)
    for k, (label, values) in enumerate(bars):
        ax.bar([i + k * width for i in range(len(groups))], values, width, label=label)
    ax.set_xticks([i + 0.4 - width / 2 for i in range(len(groups))])
    ax.set_xticklabels(groups)
    if xlabel:
        ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3, axis="y")
    ax.legend(fontsize=8)
    save(fig, path)


def sweep_figure(d, name, xlabel, title):
    data = rows(d / f"{name}.csv")
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    series = with_robot_maps(data, curves(data, "method", "value", "consistent_merged"), "consistent")
    panel(axes[0], series, f"{title}: consistent landmarks (NEES < 5.99)", xlabel, "ratio", style=DASHED)
    axes[0].set_ylim(0, 1.05)
    dets = curves(data, "method", "value", "det_merged", lambda r: r["method"] != "ml")
    dets = {k: [(x, y) for x, y in v if y > 0 and math.isfinite(y)] for k, v in dets.items()}
    panel(axes[1], dets, f"{title}: determinant", xlabel, "mean det of merged covariance (m^4)", style=METHOD_STYLE)
    axes[1].set_yscale("log")
    save(fig, d / f"{name}.png")


def aligned_sweep_figure(d, name, xlabel, title):
    data = rows(d / f"{name}.csv")
    first = data[0]["method"] if data else None
    one = [r for r in data if r["method"] == first]
    fig, axes = plt.subplots(1, 3, figsize=(16, 4))

    def column(col):
        return [(number(r["value"]), number(r[col])) for r in one]

    align = {
        "map similarity (thesis metric)": column("thesis_similarity_true_ratio"),
        "map similarity (sorted sides)": column("similarity_true_ratio"),
        "RANSAC success (true pairs found)": column("ransac_true_recall"),
        "runs aligned": [(number(r["value"]), number(r["fused_runs"]) / number(r["runs"])) for r in one],
    }
    panel(axes[0], align, f"{title}: alignment", xlabel, "ratio")
    axes[0].set_ylim(0, 1.05)
    nees = with_robot_maps(data, curves(data, "method", "value", "nees_merged", lambda r: r["method"] != "ml"),
                           "nees")
    panel(axes[1], nees, f"{title}: NEES of the overlap", xlabel, "mean NEES (2 dof)", style=DASHED)
    series = curves(data, "method", "value", "consistent_merged")
    panel(axes[2], series, f"{title}: consistent landmarks", xlabel, "ratio (NEES < 5.99)", style=METHOD_STYLE)
    axes[2].set_ylim(0, 1.05)
    save(fig, d / f"{name}.png")


def sim_table_figure(d):
    data = rows(d / "table7_vp_sim.csv")
    present = {(r["robot_a"], r["robot_b"]) for r in data}
    pairs = [p for p in THESIS_PAIRS if p in present] + sorted(present - set(THESIS_PAIRS))
    by = {(r["robot_a"], r["robot_b"], r["method"]): r for r in data}
    bars = [("robot a", "ci", "nees_a"), ("robot b", "ci", "nees_b"),
            ("merged, information", "information", "nees_merged"), ("merged, CI", "ci", "nees_merged"),
            ("merged, CI det", "ci_det", "nees_merged")]
    values = [(label, [number(by[(a, b, m)][col]) if (a, b, m) in by else float("nan") for a, b in pairs])
              for label, m, col in bars]
    bar_chart(d / "table7_vp_sim.png", [f"traj. {a} & {b}" for a, b in pairs], values, None,
              "mean NEES on the overlap (ground truth)",
              "Table 7 on the simulated Victoria Park: single maps and merged map")


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
    bar_chart(d / "table7_victoria.png", labels, [(name, [number(r[col]) for r in data]) for name, col in bars],
              "Victoria Park robot pair", "mean NEES on the overlap",
              "Table 7: single maps and merged map (against the whole-run reference)")


# Fig. 58's sources in the thesis's colours (robots black and red; ML, M-estimator, CI blue,
# green, cyan), OGK beside them.
ELLIPSES = [("robot_a", "robot 1", "black", "-"), ("robot_b", "robot 2 (aligned)", "red", "-"),
            ("ml", "ML", "blue", "-"), ("information", "information (M-estimator)", "green", "-"),
            ("ci", "CI", "c", "-"), ("ogk", "OGK", "C1", "--")]


def ellipse_figure(d):
    data = rows(d / "fig58_ellipses.csv")
    by = {(r["signature"], r["source"]): r for r in data}
    landmarks = sorted({r["signature"] for r in data}, key=int)
    landmarks = [s for s in landmarks if all((s, src) in by for src, _, _, _ in ELLIPSES)]
    if not landmarks:
        return
    chosen = [landmarks[round(k * (len(landmarks) - 1) / 5)] for k in range(6)] if len(landmarks) >= 6 else landmarks
    fig, axes = plt.subplots(2, 3, figsize=(11, 7))
    for ax, sig in zip(axes.flat, dict.fromkeys(chosen)):
        truth = by[(sig, "robot_a")]
        tx, ty = number(truth["truth_x"]), number(truth["truth_y"])
        reach = 0.0
        for src, label, colour, style in ELLIPSES:
            r = by[(sig, src)]
            cov = [[number(r["cxx"]), number(r["cxy"])], [number(r["cxy"]), number(r["cyy"])]]
            x, y = number(r["x"]) - tx, number(r["y"]) - ty
            ax.add_patch(ellipse95((x, y), cov, fill=False, edgecolor=colour, linestyle=style, linewidth=1.2,
                                   label=label))
            ax.plot(x, y, ".", color=colour, ms=4)
            # The ellipse reaches SIGMA_95 standard deviations along each axis.
            reach = max(reach, abs(x) + SIGMA_95 * math.sqrt(cov[0][0]), abs(y) + SIGMA_95 * math.sqrt(cov[1][1]))
        ax.plot(0, 0, "x", color="grey", ms=8, label="truth")
        lim = 1.1 * reach if reach > 0 else 1.0
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
        ax.set_aspect("equal")
        ax.set_title(f"landmark {sig}", fontsize=9)
        ax.set_xlabel("x - truth (m)")
        ax.set_ylabel("y - truth (m)")
        ax.grid(alpha=0.3)
    for ax in list(axes.flat)[len(dict.fromkeys(chosen)):]:
        ax.axis("off")
    axes.flat[0].legend(fontsize=7, loc="upper left")
    fig.suptitle("Fig. 58: covariance ellipses (95 %) of the robots' estimates and the merged ones, one run")
    save(fig, d / "fig58_ellipses.png")


def main(argv):
    doc = __doc__
    d, code = None, None
    for name, _, _ in SWEEPS + ALIGNED_SWEEPS + [("table7_victoria", None, None), ("table7_vp_sim", None, None),
                                                 ("fig58_ellipses", None, None)]:
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
    for name, xlabel, title in ALIGNED_SWEEPS:
        if (d / f"{name}.csv").exists():
            aligned_sweep_figure(d, name, xlabel, title)
    if (d / "table7_victoria.csv").exists():
        table_figure(d)
    if (d / "table7_vp_sim.csv").exists():
        sim_table_figure(d)
    if (d / "fig58_ellipses.csv").exists():
        ellipse_figure(d)
    print(f"fusion.py: wrote {len(list(d.glob('*.png')))} figures in {d}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
