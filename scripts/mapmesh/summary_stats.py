"""The spread of a figure over agents and seeds as the tables of docs/EXPERIMENTS.md give it
(scripts/limit-table, scripts/reach-floor): the median, the 90th percentile and the worst."""

import statistics


def percentile(values, q):
    """The nearest-rank q-quantile of values (0 <= q <= 1)."""
    values = sorted(values)
    return values[min(len(values) - 1, int(round(q * (len(values) - 1))))]


def triple(values):
    """median / p90 / worst, two decimals; dashes when there are none."""
    values = list(values)
    if not values:
        return "– / – / –"
    return f"{statistics.median(values):.2f} / {percentile(values, 0.9):.2f} / {max(values):.2f}"
