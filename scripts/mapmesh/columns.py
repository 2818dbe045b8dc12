"""The per-agent summary columns, in one place: what `swarm run` prints, what the report's
summary table shows (scripts/plots/report.py), what `swarm sweep` writes to sweep.csv and what
its plot draws (scripts/plots/sweep.py) are all taken from COLUMNS. Standard library only."""

from __future__ import annotations

from dataclasses import dataclass

DASH = "-"  # what the printed table shows for a null value


@dataclass(frozen=True)
class Column:
    key: str                    # dotted path of the value in a summary.json agent ("global.rmse_m")
    # Its one name outside summary.json: the header in the table `swarm run` prints and the column
    # of sweep.csv (and sweep_summary.csv), the key itself where that has no dot (None: neither).
    name: str | None = None
    table: bool = False         # in the table `swarm run` prints
    table_format: str = "d"     # format spec of its cells there
    html: str | None = None     # header in the report's summary table (None: not there)
    boolean: bool = False       # a flag: yes/no in the printed table, 1/0 in sweep.csv
    count: bool = False         # a list: the printed table and sweep.csv show its length, so does the report
    plot: tuple[str, str] | None = None  # (panel title, y label) in the sweep plot (None: not drawn)
    plot_fallback: str | None = None    # key of the column the plot draws instead where a sweep.csv lacks this one

    def __post_init__(self):
        if self.name is None and "." not in self.key:
            object.__setattr__(self, "name", self.key)
        if self.table and self.name is None:
            raise ValueError(f"column {self.key}: a column of the printed table needs a name")

    def value(self, agent):
        return lookup(agent, self.key)

    def table_cell(self, agent):
        v = self.value(agent)
        if self.boolean:
            return "yes" if v else "no"
        if self.count and isinstance(v, list):
            return str(len(v))
        if v is None:
            return DASH
        return format(v, self.table_format)

    def csv_cell(self, agent):
        v = self.value(agent)
        if self.count:
            return len(v or [])
        if self.boolean:
            return int(bool(v))
        return v


# In the order of the printed table and of the report's table (each shows the columns it names).
COLUMNS = [
    Column("id", name="agent", table=True, html="agent"),
    Column("alive_at_end", name="alive", table=True, boolean=True, html="alive"),
    Column("exit_code", table=True, html="exit"),
    Column("restarts", table=True, html="restarts"),
    Column("local.landmarks", name="lm_local", table=True, html="local landmarks"),
    # A map's accuracy (issue 19): first its RMSE after a least-squares rigid fit of the map to the
    # landmark truth (mapmesh-eval's rmse_aligned_m), then beside it the RMSE in the robot's true
    # map frame, which adds the map's heading drift.
    Column("local.rmse_aligned_m", name="rmse_local_aligned_m", table=True, table_format=".3f",
           html="local RMSE after rigid fit (m)"),
    Column("local.rmse_m", name="rmse_local_m", table=True, table_format=".3f", html="local RMSE, true frame (m)"),
    Column("local.nees_mean", name="nees_local", html="local NEES"),
    Column("global.landmarks", name="lm_global", table=True, html="global landmarks"),
    Column("global.rmse_aligned_m", name="rmse_global_aligned_m", table=True, table_format=".3f",
           html="global RMSE after rigid fit (m)",
           plot=("global RMSE after rigid fit", "RMSE (m)"), plot_fallback="global.rmse_m"),
    Column("global.rmse_m", name="rmse_global_m", table=True, table_format=".3f", html="global RMSE, true frame (m)"),
    Column("global.nees_mean", name="nees_global", html="global NEES",
           plot=("global mean NEES", "mean NEES (2 expected)")),
    Column("global.coverage", name="coverage_global", table=True, table_format=".2f", html="global coverage",
           plot=("global coverage", "share of the seen true landmarks")),
    # ... and of what reached the agent: the landmarks of the optimum of the data that reached it
    # (every one a robot whose data reached it saw by then; with the reference only).
    Column("global.coverage_reached", name="coverage_reached"),
    # Each map against its limit on the same landmarks (docs/EXPERIMENTS.md "The limit"): the RMSE
    # after a rigid fit over that of the centralized batch optimum with what the agents know of
    # the starts, none (global map), or of the robot's own batch optimum (local map); 1 is the limit.
    Column("global.central_rmse_aligned_m", name="rmse_central_same_m",
           html="centralized optimum on the same landmarks (m)"),
    Column("gap_to_central", table=True, table_format=".2f", html="global RMSE / centralized optimum",
           plot=("global RMSE over the centralized optimum", "ratio (1: the limit)")),
    # ... and over the optimum that knows every robot's true start, which no agent does (below 1 is
    # out of reach by more than what the starts tell).
    Column("global.central_known_starts_rmse_aligned_m", name="rmse_central_known_starts_same_m",
           html="optimum with the true starts on the same landmarks (m)"),
    Column("gap_to_central_known_starts", html="global RMSE / optimum with the true starts"),
    # ... and over the optimum of the data that reached the agent by the end (the same where all of
    # it did: scripts/mapmesh/reached.py).
    Column("gap_to_reached", html="global RMSE / optimum of what reached it"),
    Column("gap_to_own_batch", table=True, table_format=".2f", html="local RMSE / own batch optimum"),
    # The agent's own path (evo's figures): the absolute trajectory error after a rigid fit, and the
    # relative pose error over 1 s.
    Column("local.trajectory_ate_aligned_m", html="trajectory ATE after rigid fit (m)"),
    Column("local.trajectory_rpe.translation_rmse_m", html="trajectory RPE over 1 s (m)"),
    Column("peers_aligned", table=True, html="peers aligned", count=True),
    Column("maps_received", table=True, html="maps received"),
    Column("bytes_sent", table=True, html="bytes sent"),
    Column("bytes_received", table=True),
    Column("bytes_per_landmark", html="bytes / landmark"),
    Column("cpu_s", table=True, table_format=".2f", html="CPU (s)"),
    Column("max_rss_mb", table=True, table_format=".1f", html="max RSS (MB)"),
]
BY_KEY = {c.key: c for c in COLUMNS}

TABLE_COLUMNS = [c for c in COLUMNS if c.table]
HTML_COLUMNS = [c for c in COLUMNS if c.html]
# sweep.csv: the swept parameters (one column each), "seed", these agent columns in this order, then the run's "wall_s".
SWEEP_COLUMNS = [BY_KEY[k] for k in ("id", "alive_at_end", "local.landmarks", "global.landmarks", "global.coverage",
                                     "global.coverage_reached",
                                     "global.nees_mean", "global.rmse_aligned_m", "global.rmse_m",
                                     "local.rmse_aligned_m", "local.rmse_m", "local.nees_mean",
                                     "global.central_rmse_aligned_m", "gap_to_central",
                                     "global.central_known_starts_rmse_aligned_m", "gap_to_central_known_starts",
                                     "gap_to_own_batch",
                                     "peers_aligned", "bytes_sent")]
SWEEP_HEADER = ["seed"] + [c.name for c in SWEEP_COLUMNS] + ["wall_s"]
# The sweep plot's panels, left to right.
PLOT_COLUMNS = [c for c in SWEEP_COLUMNS if c.plot]


def lookup(record, path):
    """The value at a dotted path ("global.rmse_m") of a dict, or None where any step is missing."""
    value = record
    for part in path.split("."):
        if not isinstance(value, dict):
            return None
        value = value.get(part)
    return value


def sweep_row(seed, summary, agent):
    """One sweep.csv row after the parameters' values: the seed, SWEEP_COLUMNS of one agent and the run's wall time."""
    return [seed] + [c.csv_cell(agent) for c in SWEEP_COLUMNS] + [summary["wall_s"]]


# The printed table is cut into blocks, each led by the agent column, so that the full names fit
# a terminal: the local map, the global map and the limit, the traffic and the process; and
# wherever a block would grow wider than TABLE_WIDTH characters.
TABLE_BREAKS = ("global.landmarks", "peers_aligned")
TABLE_WIDTH = 120


def table_blocks(rows, breaks=(), width=TABLE_WIDTH):
    """rows (the header first, then a row per agent; the first cell each row's agent) as lines:
    the columns right-aligned two spaces apart, in blocks of consecutive columns, a new one at
    each index in `breaks` and wherever one would grow wider than `width` characters (one column
    at least each), each block led by the first column, a blank line between blocks."""
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    blocks, block = [], []
    used = widths[0]
    for i in range(1, len(widths)):
        if block and (i in breaks or used + 2 + widths[i] > width):
            blocks.append(block)
            block, used = [], widths[0]
        block.append(i)
        used += 2 + widths[i]
    if block:
        blocks.append(block)
    lines = []
    for n, block in enumerate(blocks):
        if n:
            lines.append("")
        cols = [0] + block
        lines += ["  ".join(r[i].rjust(widths[i]) for i in cols) for r in rows]
    return lines


def format_table(summary, width=TABLE_WIDTH):
    """The per-agent table `swarm run` prints, under a line on the run: its headers are the
    columns' names (sweep.csv's), in blocks that fit `width` characters."""
    rows = [tuple(c.name for c in TABLE_COLUMNS)]
    for a in summary["agents"]:
        rows.append(tuple(c.table_cell(a) for c in TABLE_COLUMNS))
    head = (f"{summary['scenario']}: {summary['sim_duration_s']:.1f} s simulated in {summary['wall_s']:.1f} s wall "
            f"(x{summary['real_time_factor']:.1f})")
    breaks = [i for i, c in enumerate(TABLE_COLUMNS) if c.key in TABLE_BREAKS]
    return "\n".join([head] + table_blocks(rows, breaks, width))
