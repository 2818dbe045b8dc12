"""A sweep's statistics (U1), in one place: what `swarm sweep` writes to sweep_summary.csv and what
scripts/plots/sweep.py draws. Standard library only.

The unit is the run (a seed at a grid point): the agents of one run share its world, its noise and
each other's maps, so they are not independent draws. Each run gives one figure per group of
agents, the median over them (robust to one agent's outlier), where the groups are the agents
alive at the end and those killed (dead at the end: their figures froze when they died and are
kept apart). Over the seeds of a grid point: the median, and the distribution-free interval for the
median from order statistics, [x_(k), x_(n+1-k)] with the largest k whose coverage
P(k <= B <= n-k), B ~ Binomial(n, 1/2), is at least 95 %. With fewer than six seeds no such k
exists; the interval is then the whole range, and its coverage, 1 - 2^(1-n), is written beside it
(75 % at three seeds) rather than called 95 %."""

from __future__ import annotations

import math
from statistics import median

LEVEL = 0.95
GROUPS = ("alive", "killed")  # agents alive at the end; killed (dead at the end), apart


def interval_coverage(n, k):
    """The probability that [x_(k), x_(n+1-k)] of n draws holds their population median."""
    below = sum(math.comb(n, i) for i in range(k)) / 2 ** n  # P(B <= k-1)
    return 1.0 - 2.0 * below


def median_interval(values, level=LEVEL):
    """(median, lo, hi, coverage) of a list of numbers (None when it is empty)."""
    xs = sorted(values)
    n = len(xs)
    if n == 0:
        return None
    k = 1
    while 2 * (k + 1) <= n and interval_coverage(n, k + 1) >= level:
        k += 1
    return median(xs), xs[k - 1], xs[n - k], interval_coverage(n, k)


def number(cell):
    """A CSV cell or JSON value as a finite float, or None (empty, null, nan, not a number)."""
    if cell is None or isinstance(cell, bool):
        return None
    if isinstance(cell, str):
        if cell.strip().lower() in ("", "null", "none", "nan", "-"):
            return None
        try:
            cell = float(cell)
        except ValueError:
            return None
    v = float(cell)
    return v if math.isfinite(v) else None


def group_of(alive):
    """The group of an agent by its alive cell (1/0, True/False, yes/no)."""
    return GROUPS[0] if str(alive).strip().lower() in ("1", "true", "yes") else GROUPS[1]


def run_figures(rows, metric):
    """{group: (median over its agents, agents counted)} of one run's rows (dicts with `alive` and
    the metric); a group whose agents all lack the figure is left out."""
    by_group = {}
    for r in rows:
        v = number(r.get(metric))
        if v is not None:
            by_group.setdefault(group_of(r.get("alive")), []).append(v)
    return {g: (median(vs), len(vs)) for g, vs in by_group.items()}


def summarise(runs, metric):
    """Per grid point and group, over the seeds: [(point, group, per-seed figures, median_interval)],
    points in the order of `runs` ([(point, seed, rows)]), groups in GROUPS order; a point's
    group no run of it has is left out."""
    per = {}
    for point, seed, rows in runs:
        for group, (fig, _) in run_figures(rows, metric).items():
            per.setdefault(point, {}).setdefault(group, []).append((seed, fig))
    out = []
    for point, groups in per.items():
        for group in GROUPS:
            if group in groups:
                seeds = groups[group]
                out.append((point, group, seeds, median_interval([f for _, f in seeds])))
    return out
