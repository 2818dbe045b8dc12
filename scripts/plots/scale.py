#!/usr/bin/python3
"""Plots a scale benchmark written by `scripts/swarm bench-scale ... --out DIR`.

Usage: /usr/bin/python3 scripts/plots/scale.py DIR      (reads DIR/scale.csv, writes DIR/scale.png)

Six panels against the number of agents (log 2 axis): wall time and real-time factor, CPU per
agent (mean and max), CPU per agent divided by the mean number of peers it aligned, RSS per
agent (mean and max), bytes per landmark sent, and mean global coverage with the count of false
alignments. Prints the figure's path on stdout.
Needs Debian's python3-matplotlib (scripts/install-deps installs it)."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from plotlib import directory_argument, number, plt, rows  # noqa: E402


def series(data, column):
    return [number(r[column]) if r[column] not in ("", None) else float("nan") for r in data]


def main(argv):
    d, code = directory_argument(argv, __doc__, "scale.py", "scale.csv", "scripts/swarm bench-scale SCENARIO --out")
    if d is None:
        return code
    data = sorted(rows(d / "scale.csv"), key=lambda r: number(r["agents"]))
    n = series(data, "agents")
    fig, axes = plt.subplots(2, 3, figsize=(14, 7.5))

    def draw(ax, columns, title, ylabel):
        for column, label in columns:
            ax.plot(n, series(data, column), marker="o", ms=4, label=label)
        ax.set_xscale("log", base=2)
        ax.set_xticks(n)
        ax.set_xticklabels([str(int(x)) for x in n])
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("agents")
        ax.set_ylabel(ylabel)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)

    draw(axes[0][0], [("wall_s", "wall time (s)")], "Wall time of the run", "s")
    rtf = axes[0][0].twinx()
    rtf.plot(n, series(data, "rtf"), color="tab:red", marker="s", ms=4, label="real-time factor")
    rtf.set_ylabel("real-time factor", color="tab:red")
    draw(axes[0][1], [("cpu_per_agent_mean_s", "mean"), ("cpu_per_agent_max_s", "max")], "CPU per agent", "CPU s")
    draw(axes[0][2], [("cpu_per_agent_per_peer_s", "CPU s per agent / mean peers aligned")],
         "CPU per agent per aligned peer", "CPU s")
    draw(axes[1][0], [("rss_per_agent_mean_mb", "mean"), ("rss_per_agent_max_mb", "max")], "Peak RSS per agent", "MB")
    draw(axes[1][1], [("bytes_per_landmark", "mean over agents")], "Bytes per landmark sent", "bytes")
    draw(axes[1][2], [("coverage_global_mean", "mean global coverage")], "Global maps", "coverage")
    false = axes[1][2].twinx()
    false.bar(n, series(data, "false_alignments"), width=[x * 0.15 for x in n], alpha=0.3, color="tab:red")
    false.set_ylabel("false alignments (all agents)", color="tab:red")
    fig.tight_layout()
    out = d / "scale.png"
    fig.savefig(out, dpi=110)
    print(out)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
