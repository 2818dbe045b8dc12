"""Shared helpers of the plot scripts: CSV rows, curves grouped by a column, a panel, and the
command-line handling every plot script has (DIR argument, --help, one-line errors)."""

import csv
import math
import sys
from collections import defaultdict
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402,F401  (re-exported for the scripts)
import numpy as np  # noqa: E402
from matplotlib.patches import Ellipse  # noqa: E402

# Half-axes of the 95 % ellipse of a 2-D Gaussian, in standard deviations: sqrt(chi2_2(0.95)).
SIGMA_95 = 2.448


def rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def number(text):
    """A CSV cell as a float (inf and nan included)."""
    return float(text)


def curves(data, group, x, y, where=None):
    out = defaultdict(list)
    for r in data:
        if where and not where(r):
            continue
        out[r[group]].append((number(r[x]), number(r[y])))
    return {k: sorted(v) for k, v in out.items()}


def panel(ax, series, title, xlabel, ylabel, label_fmt="{}", style=None):
    for name, pts in series.items():
        kw = dict(marker="o", ms=3)
        if style:
            kw.update(style.get(name, {}))
        ax.plot([p[0] for p in pts], [p[1] for p in pts], label=label_fmt.format(name), **kw)
    ax.set_title(title, fontsize=10)
    ax.set_xlabel(xlabel)
    ax.set_ylabel(ylabel)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)


def ellipse95(centre, cov, **style):
    """The 95 % ellipse (a matplotlib Ellipse) of a 2-D Gaussian at centre with the 2x2
    covariance cov; a rank-deficient covariance gives a segment."""
    values, vectors = np.linalg.eigh(np.asarray(cov, dtype=float))
    values = np.clip(values, 0.0, None)
    major = vectors[:, 1]
    return Ellipse(centre, width=2 * SIGMA_95 * math.sqrt(values[1]), height=2 * SIGMA_95 * math.sqrt(values[0]),
                   angle=math.degrees(math.atan2(major[1], major[0])), **style)


def save(fig, path, dpi=110):
    """Lays out a figure, writes it as PNG and frees it."""
    fig.tight_layout()
    fig.savefig(path, dpi=dpi)
    plt.close(fig)


def directory_argument(argv, doc, script, first_csv, how_to_make):
    """The DIR argument of a plot script, or an exit code (help, usage, missing input)."""
    if len(argv) == 2 and argv[1] in ("-h", "--help"):
        print(doc.strip())
        return None, 0
    if len(argv) != 2:
        print(doc.strip(), file=sys.stderr)
        return None, 2
    d = Path(argv[1])
    if not (d / first_csv).exists():
        print(f"{script}: {d}: no {first_csv} (run {how_to_make} {d})", file=sys.stderr)
        return None, 1
    return d, None
