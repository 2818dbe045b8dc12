"""The per-agent summary columns, in one place: what `swarm run` prints, what the report's
summary table shows (scripts/plots/report.py), what `swarm sweep` writes to sweep.csv and what
its plot draws (scripts/plots/sweep.py) are all taken from COLUMNS. Standard library only."""

from __future__ import annotations

from dataclasses import dataclass

DASH = "-"  # what the printed table shows for a null value


@dataclass(frozen=True)
class Column:
    key: str                    # dotted path of the value in a summary.json agent ("global.rmse_m")
    table: str | None = None    # header in the table `swarm run` prints (None: not there)
    table_format: str = "d"     # format spec of its cells there
    table_scale: int = 1        # the table shows the value divided by this
    html: str | None = None     # header in the report's summary table (None: not there)
    csv: str | None = None      # column of sweep.csv (None: not there)
    boolean: bool = False       # a flag: yes/no in the printed table, 1/0 in sweep.csv
    count: bool = False         # a list: the printed table and sweep.csv show its length, so does the report
    plot: tuple[str, str] | None = None  # (panel title, y label) in the sweep plot (None: not drawn)
    plot_fallback: str | None = None    # key of the column the plot draws instead where a sweep.csv lacks this one

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
        return format(v / self.table_scale if self.table_scale != 1 else v, self.table_format)

    def csv_cell(self, agent):
        v = self.value(agent)
        if self.count:
            return len(v or [])
        if self.boolean:
            return int(bool(v))
        return v


# In the order of the printed table and of the report's table (each shows the columns it names).
COLUMNS = [
    Column("id", table="id", html="agent", csv="agent"),
    Column("alive_at_end", table="alive", boolean=True, html="alive", csv="alive"),
    Column("exit_code", table="exit", html="exit"),
    Column("restarts", table="restarts", html="restarts"),
    Column("local.landmarks", table="lm_local", html="local landmarks", csv="lm_local"),
    # A map's accuracy (issue 19): first its RMSE after a least-squares rigid fit of the map to the
    # landmark truth (mapmesh-eval's rmse_aligned_m), then beside it the RMSE in the robot's true
    # map frame, which adds the map's heading drift.
    Column("local.rmse_aligned_m", table="rmse_local_fit", table_format=".3f",
           html="local RMSE after rigid fit (m)", csv="rmse_local_aligned_m"),
    Column("local.rmse_m", table="rmse_local", table_format=".3f", html="local RMSE, true frame (m)",
           csv="rmse_local_m"),
    Column("local.nees_mean", html="local NEES", csv="nees_local"),
    Column("global.landmarks", table="lm_global", html="global landmarks", csv="lm_global"),
    Column("global.rmse_aligned_m", table="rmse_global_fit", table_format=".3f",
           html="global RMSE after rigid fit (m)", csv="rmse_global_aligned_m",
           plot=("global RMSE after rigid fit", "RMSE (m)"), plot_fallback="global.rmse_m"),
    Column("global.rmse_m", table="rmse_global", table_format=".3f", html="global RMSE, true frame (m)",
           csv="rmse_global_m"),
    Column("global.nees_mean", html="global NEES", csv="nees_global",
           plot=("global mean NEES", "mean NEES (2 expected)")),
    Column("global.coverage", table="cov_global", table_format=".2f", html="global coverage", csv="coverage_global",
           plot=("global coverage", "share of the seen true landmarks")),
    # ... and of what reached the agent: the landmarks of the optimum of the data that reached it
    # (every one a robot whose data reached it saw by then; with the reference only).
    Column("global.coverage_reached", csv="coverage_reached"),
    # Each map against its limit on the same landmarks (docs/EXPERIMENTS.md "The limit"): the RMSE
    # after a rigid fit over that of the centralized batch optimum with what the agents know of
    # the starts, none (global map), or of the robot's own batch optimum (local map); 1 is the limit.
    Column("global.central_rmse_aligned_m", html="centralized optimum on the same landmarks (m)",
           csv="rmse_central_same_m"),
    Column("gap_to_central", table="gap_central", table_format=".2f",
           html="global RMSE / centralized optimum", csv="gap_to_central",
           plot=("global RMSE over the centralized optimum", "ratio (1: the limit)")),
    # ... and over the optimum that knows every robot's true start, which no agent does (below 1 is
    # out of reach by more than what the starts tell).
    Column("global.central_known_starts_rmse_aligned_m", html="optimum with the true starts on the same landmarks (m)",
           csv="rmse_central_known_starts_same_m"),
    Column("gap_to_central_known_starts", html="global RMSE / optimum with the true starts",
           csv="gap_to_central_known_starts"),
    # ... and over the optimum of the data that reached the agent by the end (the same where all of
    # it did: scripts/mapmesh/reached.py).
    Column("gap_to_reached", html="global RMSE / optimum of what reached it", csv="gap_to_reached"),
    Column("gap_to_own_batch", table="gap_own", table_format=".2f", html="local RMSE / own batch optimum",
           csv="gap_to_own_batch"),
    # The agent's own path (evo's figures): the absolute trajectory error after a rigid fit, and the
    # relative pose error over 1 s.
    Column("local.trajectory_ate_aligned_m", html="trajectory ATE after rigid fit (m)"),
    Column("local.trajectory_rpe.translation_rmse_m", html="trajectory RPE over 1 s (m)"),
    Column("peers_aligned", table="peers", html="peers aligned", csv="peers_aligned", count=True),
    Column("maps_received", table="maps_rx", html="maps received"),
    Column("bytes_sent", table="kB_tx", table_format=".1f", table_scale=1000, html="bytes sent", csv="bytes_sent"),
    Column("bytes_received", table="kB_rx", table_format=".1f", table_scale=1000),
    Column("bytes_per_landmark", html="bytes / landmark"),
    Column("cpu_s", table="cpu_s", table_format=".2f", html="CPU (s)"),
    Column("max_rss_mb", table="rss_MB", table_format=".1f", html="max RSS (MB)"),
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
SWEEP_HEADER = ["seed"] + [c.csv for c in SWEEP_COLUMNS] + ["wall_s"]
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


def format_table(summary):
    """The per-agent table `swarm run` prints, under a line on the run."""
    rows = [tuple(c.table for c in TABLE_COLUMNS)]
    for a in summary["agents"]:
        rows.append(tuple(c.table_cell(a) for c in TABLE_COLUMNS))
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    lines = ["  ".join(c.rjust(w) for c, w in zip(r, widths)) for r in rows]
    head = (f"{summary['scenario']}: {summary['sim_duration_s']:.1f} s simulated in {summary['wall_s']:.1f} s wall "
            f"(x{summary['real_time_factor']:.1f})")
    return "\n".join([head] + lines)
