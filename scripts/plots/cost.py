#!/usr/bin/python3
"""The thesis's cost figures (chapter 5.1: Figs. 43, 47, 54 and Table 6) from mapmesh-bench,
drawn beside the thesis's numbers, with the ratios printed.

Usage: /usr/bin/python3 scripts/plots/cost.py [--bench PATH] [--repetitions N] [--json FILE] OUT
  Runs `nice -n 10 PATH --benchmark_filter=Thesis --benchmark_format=json
  --benchmark_repetitions=N --benchmark_enable_random_interleaving=true
  --benchmark_report_aggregates_only=true` (PATH: build/bin/mapmesh-bench, N: 5; the repetitions
  of all the benchmarks interleaved in random order, so that load from others spreads over
  all of them alike), keeps its output as OUT/thesis_cost.json, and writes OUT/fig43_delaunay.png,
  OUT/fig47_ransac_steps.png, OUT/fig54_fusion.png and OUT/table6_ci.png.
  With --json FILE it reads FILE (a mapmesh-bench JSON report) instead of running anything.
Prints markdown tables of our figures beside the thesis's and the ratios. Times are CPU times,
medians over the repetitions where there are several (others share the machine's cores).
Needs Debian's python3-matplotlib and python3-numpy.

The thesis's figures are images: only the values its text states are drawn (Fig. 43: about
0.04 ms at 400 landmarks, "almost linear"; Fig. 47: a flat hypothesis step at about 0.038 ms,
the test step crossing it near 100 samples; Fig. 54: about 10 ms for 1000 landmarks, Maximum
Likelihood about half of the others; Table 6 whole)."""

import json
import math
import statistics
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from plotlib import plt, save  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
FILTER = "Thesis"
TO_MS = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}

# What the thesis's text says (ms). Table 6 is a table; the figures are read from the text only.
THESIS = {
    "delaunay": {400: 0.04},
    "hypothesis_ms": 0.038,
    "crossover_samples": 100,
    "fusion_1000_ms": 10.0,
    "ml_share": 0.5,
    "table6": {"ci": {2: 0.018, 10: 0.09, 100: 1.0}, "ci_det": {2: 4.3, 10: 21.5, 100: 21.5}},
}
FUSION_METHODS = ["ml", "information", "ci", "ci_det", "ci_det_search"]
LABELS = {"ml": "Maximum Likelihood", "information": "information (modified M-estimator)", "ci": "CI, w = 0.5",
          "ci_det": "CI, det-optimal (closed form)", "ci_det_search": "CI, det-optimal (golden section)"}


class ReportError(Exception):
    pass


def parse_name(run_name):
    """'BM_ThesisFuse/ci/100' -> ('BM_ThesisFuse', 'ci', 100); 'BM_ThesisDelaunay/50' -> (.., '', 50)."""
    parts = run_name.split("/")
    if len(parts) < 2 or not parts[-1].isdigit():
        raise ReportError(f"unexpected benchmark name {run_name!r}")
    return parts[0], "/".join(parts[1:-1]), int(parts[-1])


def medians(report):
    """{(family, variant, n): CPU ms}: the 'median' aggregate where the report has one, else the
    median of the iteration runs (one run: its own time). Only BM_Thesis* benchmarks count."""
    runs, aggregated = defaultdict(list), {}
    for b in report.get("benchmarks", []):
        name = b.get("run_name", b.get("name", ""))
        if not name.startswith("BM_Thesis"):
            continue
        if "cpu_time" not in b or b.get("time_unit") not in TO_MS:
            raise ReportError(f"{name}: no cpu_time in a known time_unit")
        ms = b["cpu_time"] * TO_MS[b["time_unit"]]
        key = parse_name(name)
        if b.get("run_type") == "aggregate":
            if b.get("aggregate_name") == "median":
                aggregated[key] = ms
        else:
            runs[key].append(ms)
    out = {k: statistics.median(v) for k, v in runs.items()}
    out.update(aggregated)
    if not out:
        raise ReportError("no BM_Thesis benchmark in the report")
    return out


def series(med, family, variant=""):
    return sorted((n, t) for (f, v, n), t in med.items() if f == family and v == variant)


def growth_exponent(points):
    """Least-squares slope of log t against log n."""
    if len(points) < 2:
        return float("nan")
    x = np.log([p[0] for p in points])
    y = np.log([p[1] for p in points])
    return float(np.polyfit(x, y, 1)[0])


def break_even(hyp, test):
    """The candidate count at which one consensus test costs as much as one hypothesis: the
    hypothesis's median time over the counts over the test's time per candidate at the largest
    count (where the fixed cost of a test weighs least)."""
    if not hyp or not test:
        return None
    n, t = test[-1]
    return statistics.median(t for _, t in hyp) / (t / n)


def ratios(med):
    """Every ratio the docs quote, as {name: value}."""
    r = {}
    dl = series(med, "BM_ThesisDelaunay")
    if dl:
        r["delaunay_exponent"] = growth_exponent(dl)
        r["nlogn_exponent"] = growth_exponent([(n, n * math.log(n)) for n, _ in dl])
        r["delaunay_ns_per_nlogn"] = {n: t * 1e6 / (n * math.log2(n)) for n, t in dl}
        r["delaunay_over_thesis"] = {n: t / THESIS["delaunay"][n] for n, t in dl if n in THESIS["delaunay"]}
    hyp = series(med, "BM_ThesisRansacHypothesis")
    if hyp:
        r["hypothesis_spread"] = max(t for _, t in hyp) / min(t for _, t in hyp)
        for dist in ("mahalanobis", "euclidean"):
            test = series(med, "BM_ThesisRansacConsensus", dist)
            if test:
                r[f"consensus_exponent_{dist}"] = growth_exponent(test)
                r[f"break_even_{dist}"] = break_even(hyp, test)
                r[f"per_candidate_ms_{dist}"] = test[-1][1] / test[-1][0]
                r[f"consensus_over_hypothesis_{dist}"] = {n: t / dict(hyp)[n] for n, t in test if n in dict(hyp)}
    fuse = {m: dict(series(med, "BM_ThesisFuse", m)) for m in FUSION_METHODS}
    for num, den in (("ml", "ci"), ("ml", "information"), ("information", "ci"), ("ci_det", "ci"),
                     ("ci_det_search", "ci"), ("ci_det_search", "ci_det")):
        common = sorted(set(fuse[num]) & set(fuse[den]))
        if common:
            r[f"{num}/{den}"] = {n: fuse[num][n] / fuse[den][n] for n in common}
    return r


def fmt_ms(t):
    if t is None or not math.isfinite(t):
        return "—"
    if t >= 1.0:
        return f"{t:.3g} ms"
    if t >= 1e-3:
        return f"{t * 1e3:.3g} µs"
    return f"{t * 1e6:.3g} ns"


def fmt_ratio(x):
    return "—" if x is None else f"{x:.3g}"


def tables(med, r):
    lines = ["### Fig. 43: Delaunay triangulation", "",
             "| landmarks | ours | ns per n log2 n | thesis (text) |", "|---|---|---|---|"]
    for n, t in series(med, "BM_ThesisDelaunay"):
        th = THESIS["delaunay"].get(n)
        lines.append(f"| {n} | {fmt_ms(t)} | {r['delaunay_ns_per_nlogn'][n]:.3g} | {fmt_ms(th) if th else ''} |")
    if "delaunay_exponent" in r:
        lines += ["", f"growth exponent of our time over n: {r['delaunay_exponent']:.2f} "
                      f"(n log n over the same range: {r['nlogn_exponent']:.2f}; linear: 1)"]
        for n, x in r["delaunay_over_thesis"].items():
            lines.append(f"ours / thesis at {n} landmarks: {x:.3g}")
    hyp = dict(series(med, "BM_ThesisRansacHypothesis"))
    maha = dict(series(med, "BM_ThesisRansacConsensus", "mahalanobis"))
    eucl = dict(series(med, "BM_ThesisRansacConsensus", "euclidean"))
    lines += ["", "### Fig. 47: RANSAC's steps", "",
              "| candidates | hypothesis | consensus, Mahalanobis | consensus, Euclidean |", "|---|---|---|---|"]
    for n in sorted(set(hyp) | set(maha) | set(eucl)):
        lines.append(f"| {n} | {fmt_ms(hyp.get(n))} | {fmt_ms(maha.get(n))} | {fmt_ms(eucl.get(n))} |")
    if "hypothesis_spread" in r:
        lines += ["", f"hypothesis max/min over the counts: {r['hypothesis_spread']:.2f} (thesis: flat at "
                      f"{fmt_ms(THESIS['hypothesis_ms'])})"]
        for dist in ("mahalanobis", "euclidean"):
            if f"break_even_{dist}" in r:
                lines.append(f"consensus ({dist}): {fmt_ms(r[f'per_candidate_ms_{dist}'])} per candidate, growth "
                             f"exponent {r[f'consensus_exponent_{dist}']:.2f}; as dear as a hypothesis at "
                             f"{r[f'break_even_{dist}']:.3g} candidates (thesis: about {THESIS['crossover_samples']})")
    fuse = {m: dict(series(med, "BM_ThesisFuse", m)) for m in FUSION_METHODS}
    ns = sorted(set().union(*[set(v) for v in fuse.values()]))
    lines += ["", "### Fig. 54 and Table 6: fusing n landmarks' two estimates", "",
              "| landmarks | " + " | ".join(LABELS[m] for m in FUSION_METHODS) + " | thesis CI const | thesis CI opt |",
              "|---" * (len(FUSION_METHODS) + 3) + "|"]
    for n in ns:
        cells = [fmt_ms(fuse[m].get(n)) for m in FUSION_METHODS]
        tc, to = THESIS["table6"]["ci"].get(n), THESIS["table6"]["ci_det"].get(n)
        if n == 1000:
            tc = THESIS["fusion_1000_ms"]
        lines.append(f"| {n} | " + " | ".join(cells) + f" | {fmt_ms(tc) if tc else ''} | {fmt_ms(to) if to else ''} |")
    lines += ["", "| ratio | " + " | ".join(str(n) for n in ns) + " | thesis |", "|---" * (len(ns) + 2) + "|"]
    thesis_ratio = {"ml/ci": "about 0.5", "ml/information": "about 0.5", "information/ci": "below 1",
                    "ci_det/ci": " / ".join(f"{THESIS['table6']['ci_det'][n] / THESIS['table6']['ci'][n]:.3g}"
                                            for n in (2, 10, 100)) + " (2/10/100)",
                    "ci_det_search/ci": "(the thesis's search: see ci_det/ci)", "ci_det_search/ci_det": ""}
    for key, th in thesis_ratio.items():
        if key in r:
            lines.append(f"| {key} | " + " | ".join(fmt_ratio(r[key].get(n)) for n in ns) + f" | {th} |")
    return "\n".join(lines)


def draw(med, out):
    def loglog(ax, title, xlabel):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("CPU time (ms)")
        ax.grid(alpha=0.3, which="both")

    dl = series(med, "BM_ThesisDelaunay")
    fig, ax = plt.subplots(figsize=(6, 4))
    if dl:
        ax.plot(*zip(*dl), "o-", label="mapmesh (CGAL, C++)")
        n0, t0 = dl[-1]
        ns = np.array([n for n, _ in dl], dtype=float)
        ax.plot(ns, t0 * ns * np.log(ns) / (n0 * math.log(n0)), ":", color="grey", label="n log n through the last")
    ax.plot(list(THESIS["delaunay"]), list(THESIS["delaunay"].values()), "s", color="C3",
            label="thesis text (MATLAB): 0.04 ms at 400")
    loglog(ax, "Fig. 43: Delaunay triangulation", "landmarks")
    ax.legend(fontsize=8)
    save(fig, out / "fig43_delaunay.png")

    fig, ax = plt.subplots(figsize=(6, 4))
    hyp = series(med, "BM_ThesisRansacHypothesis")
    if hyp:
        ax.plot(*zip(*hyp), "o-", label="hypothesis (2-pair sample, closed form)")
    for dist, style in (("mahalanobis", "s-"), ("euclidean", "^-")):
        test = series(med, "BM_ThesisRansacConsensus", dist)
        if test:
            ax.plot(*zip(*test), style, label=f"consensus test, {dist}")
    ax.axhline(THESIS["hypothesis_ms"], color="C3", linestyle="--", label="thesis: hypothesis about 0.038 ms")
    ax.plot([THESIS["crossover_samples"]], [THESIS["hypothesis_ms"]], "*", ms=12, color="C3",
            label="thesis: test reaches it near 100")
    loglog(ax, "Fig. 47: RANSAC's hypothesis and test steps", "candidate pairs (samples)")
    ax.legend(fontsize=7)
    save(fig, out / "fig47_ransac_steps.png")

    fig, ax = plt.subplots(figsize=(6, 4))
    for m in ("ml", "information", "ci"):
        s = series(med, "BM_ThesisFuse", m)
        if s:
            ax.plot(*zip(*s), "o-", label=LABELS[m])
    ax.plot([1000, 1000], [THESIS["fusion_1000_ms"], THESIS["fusion_1000_ms"] * THESIS["ml_share"]], "s",
            color="C3", label="thesis text: about 10 ms at 1000, ML about half")
    loglog(ax, "Fig. 54: fusion cost", "landmarks")
    ax.legend(fontsize=7)
    save(fig, out / "fig54_fusion.png")

    fig, ax = plt.subplots(figsize=(9.5, 4))
    counts = [2, 10, 100]
    bars = [("thesis: constant w", THESIS["table6"]["ci"]), ("thesis: optimal w", THESIS["table6"]["ci_det"])]
    bars += [(f"ours: {LABELS[m]}", dict(series(med, "BM_ThesisFuse", m))) for m in ("ci", "ci_det", "ci_det_search")]
    width = 0.8 / len(bars)
    for k, (label, vals) in enumerate(bars):
        xs = [i + (k - (len(bars) - 1) / 2) * width for i in range(len(counts))]
        ax.bar(xs, [vals.get(n, float("nan")) for n in counts], width, label=label,
               hatch="//" if label.startswith("thesis") else None)
    ax.set_yscale("log")
    ax.set_xticks(range(len(counts)), [f"{n} landmarks" for n in counts])
    ax.set_ylabel("time (ms)")
    ax.set_title("Table 6: CI with a constant against the optimal weight", fontsize=10)
    ax.grid(alpha=0.3, axis="y", which="both")
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    save(fig, out / "table6_ci.png")


def run_bench(bench, repetitions, path):
    cmd = ["nice", "-n", "10", str(bench), f"--benchmark_filter={FILTER}", "--benchmark_format=json",
           f"--benchmark_repetitions={repetitions}", "--benchmark_enable_random_interleaving=true",
           "--benchmark_report_aggregates_only=true"]
    print("$ " + " ".join(cmd), file=sys.stderr)
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise ReportError(f"{bench} exited with {r.returncode}: {r.stderr.strip().splitlines()[-1:]}")
    path.write_text(r.stdout)


def main(argv):
    args = argv[1:]
    if args in (["-h"], ["--help"]):
        print(__doc__.strip())
        return 0
    opts = {"--bench": str(REPO / "build" / "bin" / "mapmesh-bench"), "--repetitions": "5", "--json": None}
    rest = []
    while args:
        a = args.pop(0)
        if a in opts and args:
            opts[a] = args.pop(0)
        elif a.startswith("-"):
            print(f"cost.py: unknown or incomplete option {a} (see --help)", file=sys.stderr)
            return 2
        else:
            rest.append(a)
    if len(rest) != 1 or not opts["--repetitions"].isdigit() or int(opts["--repetitions"]) < 1:
        print(__doc__.strip(), file=sys.stderr)
        return 2
    out = Path(rest[0])
    try:
        out.mkdir(parents=True, exist_ok=True)
        if opts["--json"]:
            path = Path(opts["--json"])
        else:
            if not Path(opts["--bench"]).is_file():
                raise ReportError(f"{opts['--bench']}: no such benchmark executable (build mapmesh-bench)")
            path = out / "thesis_cost.json"
            run_bench(opts["--bench"], int(opts["--repetitions"]), path)
        try:
            report = json.loads(Path(path).read_text())
        except (OSError, ValueError) as e:
            raise ReportError(f"{path}: not a readable JSON report ({e.__class__.__name__})")
        med = medians(report)
        r = ratios(med)
        draw(med, out)
    except (ReportError, OSError) as e:
        print(f"cost.py: {e}", file=sys.stderr)
        return 1
    print(tables(med, r))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
