#!/usr/bin/python3
"""Plots a parameter sweep written by `scripts/swarm sweep ... --out DIR`.

Usage: /usr/bin/python3 scripts/plots/sweep.py DIR      (reads DIR/sweep.csv, writes DIR/sweep.png)

sweep.csv has one row per run and agent (or per run): its columns before `seed` (or its first
column, without one) are the swept parameters, each named by its scenario path (e.g.
radio.range_m), and it has the columns coverage_global,
nees_global and rmse_global_aligned_m (as `swarm sweep` writes them; the summary.json paths
global.coverage, global.nees_mean and global.rmse_aligned_m are accepted too, with '.' or '_').
The RMSE panel draws the global map's RMSE after a least-squares rigid fit to the landmark truth,
the primary accuracy figure (issue 19); a sweep.csv written before it, which has only the RMSE
in the robot's true frame (rmse_global_m), gets that one, titled so, and a note on stderr. The seed
column groups the rows into runs and the alive column (1/0) says which agents were alive at the
end; other columns (agent, the true-frame RMSE, ...) are ignored, apart from counting agents.
Empty, null, None and nan cells are skipped. The figure has a row of panels per
parameter, one panel per metric: against the parameter's value, one line per combination of the
other parameters' values, drawn from the runs (scripts/mapmesh/sweep_stats.py, as `swarm sweep`
writes sweep_summary.csv): per run the median over its agents alive at the end; over the seeds
their median (the line), the distribution-free interval for the median (the band; its coverage in
the title: 95 %, or the whole range where the seeds are too few) and each seed's figure (dots).
Agents dead at the end (killed: their figures froze when they died) are drawn apart, grey, and
counted in the title; a sweep.csv without the alive column counts every agent alive. A parameter
whose values are not all numbers is plotted as categories in order of appearance.
Prints the figure's path on stdout.
Needs Debian's python3-matplotlib and python3-numpy (scripts/install-deps installs them)."""

import math
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(1, str(Path(__file__).resolve().parents[1]))
from plotlib import directory_argument, plt, rows  # noqa: E402
from mapmesh import sweep_stats  # noqa: E402
from mapmesh.columns import BY_KEY, PLOT_COLUMNS  # noqa: E402

# (column names, first preferred: sweep.csv's, then the summary.json path; panel title; y label)
METRICS = [((c.name, c.key), *c.plot) for c in PLOT_COLUMNS]
# Per metric, what an older sweep.csv without it offers instead: (column names, panel title).
FALLBACKS = {c.name: ((BY_KEY[c.plot_fallback].name, c.plot_fallback), BY_KEY[c.plot_fallback].html.replace(" (m)", ""))
             for c in PLOT_COLUMNS if c.plot_fallback}
NEES_EXPECTED = 2.0
MISSING = {"", "null", "none", "nan", "-", "\u2013"}


def normalised(name):
    return re.sub(r"[^0-9a-z]+", "_", name.strip().lower()).strip("_")


def find_column(header, *names):
    """The header column that is one of `names` (the first found) up to case and separators,
    or None."""
    for name in names:
        want = normalised(name)
        found = next((h for h in header if normalised(h) == want), None)
        if found:
            return found
    return None


def value(cell):
    """A CSV cell as a finite float, or None when it is empty, null or not finite."""
    if cell is None or cell.strip().lower() in MISSING:
        return None
    try:
        v = float(cell)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def aggregate(data, column, numeric):
    """{group: [(parameter value, median, lo, hi, coverage, [(seed, figure)])]} of a column over the
    runs (seeds) of each parameter value, in the order of the values (floats ascending, or category
    names in order of appearance); sweep_stats has the statistics (each run's median over the
    group's agents, then the median and interval over the seeds)."""
    runs = {}  # (value, seed) -> rows
    for r in data:
        runs.setdefault((r["_x"], r["_seed"]), []).append(r)
    ordered = [(x, seed, rows) for (x, seed), rows in runs.items()]
    if numeric:
        ordered.sort(key=lambda run: run[0])
    out = {}
    for x, group, per_seed, (med, lo, hi, cover) in sweep_stats.summarise(ordered, column):
        out.setdefault(group, []).append((x, med, lo, hi, cover, per_seed))
    return out


def distinct(data, header, name):
    col = find_column(header, name)
    return len({r[col] for r in data if r.get(col, "").strip()}) if col else None


def main(argv):
    d, code = directory_argument(argv, __doc__, "sweep.py", "sweep.csv", "scripts/swarm sweep ... --out")
    if d is None:
        return code
    csv_path = d / "sweep.csv"
    try:
        data = rows(csv_path)
    except (OSError, UnicodeDecodeError) as e:
        print(f"sweep.py: {csv_path}: {e}", file=sys.stderr)
        return 1
    header = list(data[0].keys()) if data else []
    if not header:
        print(f"sweep.py: {csv_path}: no rows", file=sys.stderr)
        return 1
    seed_col = find_column(header, "seed")
    params = header[:header.index(seed_col)] if seed_col and header.index(seed_col) > 0 else header[:1]
    columns = {names[0]: find_column(header, *names) for names, _, _ in METRICS}
    titles = {names[0]: title for names, title, _ in METRICS}
    for metric, (names, title) in FALLBACKS.items():
        found = find_column(header, *names)
        if columns[metric] is None and found:
            columns[metric], titles[metric] = found, title
            print(f"sweep.py: {csv_path}: no column {metric} (a sweep.csv written before the rigid-fit RMSE): "
                  f"drawing {found}, the {title}", file=sys.stderr)
    if not any(columns.values()):
        print(f"sweep.py: {csv_path}: none of the columns {', '.join(columns)}", file=sys.stderr)
        return 1
    data = [r for r in data if all((r.get(k) or "").strip() for k in params)]
    alive_col, agent_col = find_column(header, "alive"), find_column(header, "agent")
    for r in data:  # a sweep.csv without the alive column: every agent counted alive
        r["alive"] = "1" if alive_col is None or sweep_stats.group_of(r.get(alive_col)) == "alive" else "0"
        r["_seed"] = (r.get(seed_col) or "").strip() if seed_col else ""
    covers = set()
    numeric = {k: all(value(r[k]) is not None for r in data) for k in params}
    categories = {k: list(dict.fromkeys(r[k].strip() for r in data)) for k in params}

    fig, axes = plt.subplots(len(params), len(METRICS), figsize=(15, 0.6 + 4.2 * len(params)), squeeze=False)
    fig.subplots_adjust(left=0.05, right=0.98, top=1 - 0.95 / (0.6 + 4.2 * len(params)),
                        bottom=0.5 / (0.6 + 4.2 * len(params)), wspace=0.25, hspace=0.45)
    for row, param in enumerate(params):
        others = [k for k in params if k != param]
        for r in data:
            r["_x"] = value(r[param]) if numeric[param] else r[param].strip()
        groups = {}  # the other parameters' values -> their rows
        for r in data:
            groups.setdefault(tuple(r[k].strip() for k in others), []).append(r)
        for ax, ((metric, _), _, ylabel) in zip(axes[row], METRICS):
            col, title = columns[metric], titles[metric]
            drawn = []
            for i, (rest, group) in enumerate(groups.items()):
                by_group = aggregate(group, col, numeric[param]) if col else {}
                if not by_group:
                    continue
                color = f"C{i % 10}"
                label = ", ".join(f"{k}={v}" for k, v in zip(others, rest))
                for kind, points in by_group.items():
                    xs = [p[0] if numeric[param] else categories[param].index(p[0]) for p in points]
                    alive = kind == "alive"
                    name = (label + ": " if label else "") + ("median" if alive else "killed agents (apart)")
                    if alive:
                        ax.fill_between(xs, [p[2] for p in points], [p[3] for p in points], color=color, alpha=0.15,
                                        lw=0)
                    ax.plot(xs, [p[1] for p in points], "o-" if alive else "x--", color=color if alive else "grey",
                            ms=4, lw=1.5 if alive else 1, label=name)
                    # Each seed's figure, a small shift apart so that equal ones stay visible.
                    for x, p in zip(xs, points):
                        seeds = p[5]
                        width = 0.012 * (max(xs) - min(xs) if numeric[param] and len(xs) > 1 else 1.0)
                        offs = [(j - (len(seeds) - 1) / 2) * width for j in range(len(seeds))]
                        ax.scatter([x + o for o in offs], [v for _, v in seeds], s=16, marker="." if alive else "x",
                                   color=color if alive else "grey", alpha=0.8, zorder=3, lw=0.8)
                    drawn += [(p[0], p[1], min(p[2], *(v for _, v in p[5])), max(p[3], *(v for _, v in p[5])),
                               p[4]) for p in points]
                    if alive:
                        covers.update(p[4] for p in points)
            if drawn:
                if not numeric[param]:
                    ax.set_xticks(range(len(categories[param])))
                    ax.set_xticklabels(categories[param], rotation=30, ha="right", fontsize=8)
                if metric.startswith("nees"):
                    ax.axhline(NEES_EXPECTED, color="black", ls="--", lw=1, label="expected (2 dof)")
                    lo = min(p[2] for p in drawn)
                    if lo > 0 and max(p[3] for p in drawn) / lo > 30:
                        ax.set_yscale("log")
                if metric.startswith("coverage"):
                    ax.set_ylim(0, 1.02)
                ax.legend(fontsize=7, title="line: median over seeds; band: interval; dots: seeds", title_fontsize=7)
            else:
                ax.text(0.5, 0.5, f"no {metric} values" if col else f"no column {metric}", transform=ax.transAxes,
                        ha="center", va="center", color="grey")
            ax.set_title(title, fontsize=10)
            ax.set_xlabel(param)
            ax.set_ylabel(ylabel)
            ax.grid(alpha=0.3)
    counts = [f"{len(categories[k])} values of {k}" for k in params]
    for name in ("seed", "agent"):
        n = distinct(data, header, name)
        if n:
            counts.append(f"{n} {name}s")
    killed = sorted({r["_seed"] + ":" + (r.get(agent_col) or "") for r in data if r["alive"] == "0"}) if agent_col \
        else [r for r in data if r["alive"] == "0"]
    cover = (f"interval for the median, coverage {min(covers):.0%}" if covers and min(covers) == max(covers)
             else f"interval for the median, coverage {min(covers):.0%}-{max(covers):.0%}" if covers else "")
    fig.suptitle(f"sweep of {' x '.join(params)} ({', '.join(counts)}, {len(data)} rows)\nper run the median over "
                 f"the agents alive at the end, then over the seeds the median (line) and the {cover} (band)"
                 + (f"; {len(killed)} agent-runs killed, dead at the end, drawn apart (grey x)" if killed else ""),
                 fontsize=10)
    out = d / "sweep.png"
    fig.savefig(out, dpi=100)
    plt.close(fig)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
