"""`scenario-farm compare DIR`: a quantified set against its reference safe set.

Prints IoU, precision, recall and the l-inf Hausdorff distance, writes compare.json and
plots/compare.png (2-D slices: claimed but unsafe in red, safe but not claimed in blue).
On a grid of k^n points, or (``points``, the default above MAX_GRID_N axes, where a grid
of ~1.5e6 points has 5 points per axis) on points uniform in Sigma: IoU, precision and
recall then carry exact 95 % intervals and there is no Hausdorff distance.

The reference is the scenario's model where it has one, else simulated under Gamma*
with the campaign's own back end: one run of up to ``adversary_settle_steps`` steps per
grid point and per figure pixel, then (uniform or searched actions) random action
sequences from reference-safe points. With a slow simulator that is the whole cost, so
compare says up front how many runs it will make, times a first batch (part of the
work: nothing is run twice) and prints the estimate before the rest; ``estimate_only``
(``--estimate``) stops there.
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from coordinator.reference import (compare_boxes, compare_sampled, falsified, grid as grid_points, reference_safe,
                                   uniform_points)
from coordinator.safe_set import SafeSet
from farm.directory.files import write_json
from farm import lazy
from farm.execution.process import build_simulator, spec_of
from farm.directory.storage import CampaignDir
from farm.reports.summary import Summary
from scenarios.errors import ConfigError

MAX_GRID_N = 5  # more axes: Monte-Carlo points by default
SAMPLE_POINTS, MAX_SAMPLE_POINTS = 200_000, 10**7
SIMULATED_GRID_POINTS = 24**3  # default grid of a simulated reference: 24 per axis in 3-D
MODEL_GRID_POINTS = 1.5e6
MAX_GRID_POINTS = 10**8  # (G, n) doubles and a KD-tree: ~10 GB at n = 5
FALSIFY_TRIES, FALSIFY_HORIZON, FALSIFY_POINTS = 4, 200, 20000
TIMED_MIN_S = 1.0  # a phase's first batches double from FIRST_BATCH until they took this long ...
TIMED_MAX_SHARE = 1 / 8  # ... or did this share of the phase; the last one's rate makes the estimate
FIRST_BATCH = 16  # (a vectorized back end's small batches cost mostly fixed overhead: the last is the largest)


def points_per_axis(n: int, grid: int | None = None, grid_total: int | None = None,
                    simulated: bool = False) -> int:
    """The reference grid's points per axis: ``grid`` as given, or the most whose n-th
    power fits in ``grid_total``; default ~1.5e6 points for a model reference and
    24^3 = 13,824 for a simulated one (24 per axis in 3-D, 6 in 5-D)."""
    if grid is not None and grid_total is not None:
        raise ConfigError("compare: give --grid (points per axis) or --grid-total (points in all), not both")
    if grid is not None:
        if not 2 <= grid <= 4096:
            raise ConfigError(f"--grid: {grid} is out of range; allowed [2, 4096] points per axis")
        return int(grid)
    if grid_total is not None:
        if not 2**n <= grid_total <= MAX_GRID_POINTS:
            raise ConfigError(f"--grid-total: {grid_total} is out of range; allowed [{2**n}, {MAX_GRID_POINTS}] "
                              f"(2 to the power n = {n} state variables at least)")
        return _root(int(grid_total), n)
    return _root(SIMULATED_GRID_POINTS, n) if simulated else int(round(MODEL_GRID_POINTS ** (1 / n)))


def _root(total: int, n: int) -> int:
    k = max(2, int(round(total ** (1 / n))))
    while k**n > total:
        k -= 1
    while (k + 1) ** n <= total:
        k += 1
    return k


def sample_count(n: int, grid: int | None, grid_total: int | None, points: int | None) -> int | None:
    """How many Monte-Carlo points to compare on; None: compare on a grid. ``points`` as
    given; by default SAMPLE_POINTS above MAX_GRID_N axes unless a grid was asked for."""
    if points is not None:
        if grid is not None or grid_total is not None:
            raise ConfigError("compare: give --points (uniform points) or a grid (--grid, --grid-total), not both")
        if not 1000 <= points <= MAX_SAMPLE_POINTS:
            raise ConfigError(f"--points: {points} is out of range; allowed [1000, {MAX_SAMPLE_POINTS}]")
        return int(points)
    return SAMPLE_POINTS if n > MAX_GRID_N and grid is None and grid_total is None else None


def compare(directory: Path, grid: int | None = None, progress=None, *, grid_total: int | None = None,
            estimate_only: bool = False, points: int | None = None) -> dict:
    """Metrics of a finished campaign against its reference (also written to
    compare.json, with plots/compare.png); ``notes`` says how the reference was made,
    ``runs`` how many runs each phase made and how long it took against the estimate.
    ``progress``: a farm.reports.progress.Progress told of the plan, the estimate and each
    phase. ``estimate_only``: time the first batch, return the plan with its estimate
    (``estimated_s``), write nothing. ``points``: compare on that many states uniform in
    Sigma (seeded: the same each time) instead of a grid; the default above
    MAX_GRID_N axes."""
    say = progress.line if progress is not None else (lambda text: None)
    directory = Path(directory)
    CampaignDir(directory).open("quantify")
    Summary.read(directory)  # a stopped campaign's safe set is not its result: "has not finished; see status"
    cfg = CampaignDir(directory).frozen_config()
    simulated = cfg.scenario.backend != "numpy"
    if simulated and cfg.actions.mode not in ("adversarial", "uniform", "search"):
        # constant or feedback actions quantify a different set than the worst case
        raise ConfigError(f"compare: a black-box SV has no model; its reference is simulated under Gamma*, which "
                          f"compares with actions.mode = 'adversarial', 'uniform' or 'search', not "
                          f"{cfg.actions.mode!r}")
    backend = build_simulator(spec_of(cfg)).backend
    scenario = backend.scenario
    sampled = sample_count(scenario.n, grid, grid_total, points)
    k = points_per_axis(scenario.n, grid, grid_total, simulated) if sampled is None else 0
    safe_set = SafeSet.from_parquet(directory / "safe_set.parquet", scenario.state_names)
    points = grid_points(scenario, k) if sampled is None else uniform_points(scenario, sampled)
    reference_safe(backend, points[:1])  # no reference at all: say so before any work
    model = not simulated and scenario.reference_safe(points[:1]) is not None
    how = "the scenario's model" if model else (f"simulated under Gamma* on the {cfg.scenario.backend} back end, "
                                                 f"up to {scenario.adversary_settle_steps} steps a run")
    res = _figure_resolution(simulated, k)
    pixels = _figure_pixels(scenario, res)
    falsifies = cfg.actions.mode != "adversarial" and scenario.name != "toy" and scenario.sv_policy_name != "brake"
    where = f"{len(points):,} grid points ({k} per axis)" if sampled is None else \
        f"{len(points):,} points uniform in Sigma"
    say(f"compare: reference safe set from {how}: {where} + "
        f"{len(pixels):,} for the figure = {len(points) + len(pixels):,} runs"
        + (f", then up to {FALSIFY_TRIES} random action sequences of {FALSIFY_HORIZON} steps from each of up to "
           f"{2 * FALSIFY_POINTS:,} reference-safe points" if falsifies else ""))
    everything = np.concatenate([points, pixels])
    t0 = time.monotonic()
    timed, timed_truth, rest_s = _timed_start(lambda rows: reference_safe(backend, everything[rows]), len(everything))
    say(f"compare: {len(timed):,} runs from random points of them took {time.monotonic() - t0:.2g} s: about "
        f"{_duration(rest_s)} for the rest (a shared machine's load changes this)")
    runs = {"reference_runs": int(len(points)), "figure_runs": int(len(pixels)),
            "estimated_s": round(time.monotonic() - t0 + rest_s, 3)}
    if estimate_only:
        return {**runs, "points_per_axis": k, "sample_points": sampled or 0, "reference": how,
                "falsification": falsifies}
    truth = np.empty(len(everything), dtype=bool)
    truth[timed] = timed_truth
    rest = _rest(len(everything), timed)
    truth[rest] = reference_safe(backend, everything[rest])
    truth, pixel_truth = truth[: len(points)], truth[len(points) :]
    runs["elapsed_s"] = round(time.monotonic() - t0, 3)
    say(f"compare: reference done in {runs['elapsed_s']:.1f} s; measuring the claimed set")
    metrics = (compare_boxes(backend, safe_set, truth=truth, grid_points_per_axis=k) if sampled is None
               else compare_sampled(safe_set, points, truth))
    notes = []
    if falsifies:
        sample = points[truth][:: max(1, int(truth.sum()) // FALSIFY_POINTS)]
        broken, seconds = _falsify(backend, sample, say)
        metrics["falsified_reference_points"] = [broken, int(len(sample))]
        runs.update(falsification_runs=FALSIFY_TRIES * int(len(sample)), falsification_s=round(seconds, 3))
        notes.append(f"reference = worst case under Gamma*; random action sequences broke {broken} of "
                     f"{len(sample)} sampled reference-safe points")
    metrics["reference"] = ("simulated under Gamma* (black-box SV)" if simulated else "model-based")
    metrics["boxes"], metrics["half_width"] = int(len(safe_set)), safe_set.finest
    if not safe_set.is_uniform:  # boundary refinement: coarser boxes inside
        metrics["half_width_max"] = safe_set.coarsest
    metrics["notes"] = notes
    metrics["runs"] = runs
    x, y, varied, levels = _figure_slices(scenario)
    lazy.plots.draw_reference(directory / "plots" / "compare.png", scenario, safe_set, x, y, varied, levels,
                              _figure_pixels(scenario, res), pixel_truth, res)
    write_json(directory / "compare.json", metrics)
    return metrics


def _timed_start(run, total: int) -> tuple[np.ndarray, np.ndarray, float]:
    """Call ``run(rows)`` on random items (a grid's first rows are one corner of Sigma,
    whose runs last unlike the others') in batches doubling from FIRST_BATCH until
    they took TIMED_MIN_S or covered TIMED_MAX_SHARE; -> (the rows done, their results,
    the seconds the rest should take in one call). The last two batches give a fixed
    cost per call and one per item (a vectorized back end's small batches are mostly
    fixed cost). Every item's result is its own (runs never depend on their
    batch-mates), so the rest can follow in any batches."""
    order = np.random.default_rng(0).permutation(total)
    rows, parts, times, done, size = [], [], [], 0, FIRST_BATCH
    start = time.monotonic()
    while done < total:
        size = min(size, total - done)
        rows.append(np.sort(order[done : done + size]))
        t = time.monotonic()
        parts.append(np.asarray(run(rows[-1]), dtype=bool))
        times.append(time.monotonic() - t)
        done += size
        if time.monotonic() - start >= TIMED_MIN_S or done >= total * TIMED_MAX_SHARE:
            break
        size *= 2
    if not rows:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=bool), 0.0
    per_item, fixed = times[-1] / len(rows[-1]), 0.0
    if len(times) >= 2 and len(rows[-1]) > len(rows[-2]):
        marginal = (times[-1] - times[-2]) / (len(rows[-1]) - len(rows[-2]))
        if 0 < marginal < per_item:
            per_item, fixed = marginal, times[-1] - marginal * len(rows[-1])
    left = total - done
    return np.concatenate(rows), np.concatenate(parts), (fixed + per_item * left) if left else 0.0


def _rest(total: int, done: np.ndarray) -> np.ndarray:
    keep = np.ones(total, dtype=bool)
    keep[done] = False
    return np.flatnonzero(keep)


def _duration(seconds: float) -> str:
    if seconds < 90:
        return f"{seconds:.0f} s"
    if seconds < 5400:
        return f"{seconds / 60:.0f} min"
    return f"{seconds / 3600:.1f} h"


def _falsify(backend, sample: np.ndarray, say) -> tuple[int, float]:
    """Random sequences from reference-safe points, a first part timed for an estimate
    of the rest (same stream keys as one call: the count does not change)."""
    say(f"compare: random action sequences from {len(sample):,} reference-safe points (falsification): "
        f"{FALSIFY_TRIES} x {len(sample):,} = {FALSIFY_TRIES * len(sample):,} runs")
    t0 = time.monotonic()
    timed, broken, rest_s = _timed_start(
        lambda rows: falsified(backend, sample, rows, FALSIFY_TRIES, FALSIFY_HORIZON), len(sample))
    count = int(broken.sum())
    if len(timed) < len(sample):
        say(f"compare: {FALSIFY_TRIES * len(timed):,} of them took {time.monotonic() - t0:.2g} s: about "
            f"{_duration(rest_s)} for the rest")
        count += int(falsified(backend, sample, _rest(len(sample), timed), FALSIFY_TRIES, FALSIFY_HORIZON).sum())
    return count, time.monotonic() - t0


def describe(directory: Path, metrics: dict) -> str:
    """The CLI's lines for ``compare``'s metrics."""
    widths = (f"half-width {metrics['half_width']:g}" if "half_width_max" not in metrics
              else f"half-widths {metrics['half_width']:g} to {metrics['half_width_max']:g}")
    if "sample_points" in metrics:
        lines = _describe_sampled(directory, metrics, widths)
    else:
        lines = [f"{directory}: {metrics['boxes']} boxes ({widths}) against the "
                 f"{metrics['reference']} reference on {metrics['grid_points']:,} grid points",
                 f"  IoU {metrics['iou']:.4f}  precision {metrics['precision']:.4f}  recall {metrics['recall']:.4f}  "
                 f"Hausdorff (l-inf) {metrics['hausdorff']:.3g}",
                 f"  claimed volume {metrics['claimed_volume']:.6g}, reference volume "
                 f"{metrics['reference_volume']:.6g}",
                 f"  errors reach {metrics['missed_depth_boxes']:.3g} box widths into the reference's safe region "
                 f"(missed) and {metrics['overclaimed_depth_boxes']:.3g} into its unsafe region (claimed); the "
                 f"boxes' boundary layer is 1 box width plus a grid cell ({metrics['grid_cell_boxes']:.3g} box "
                 f"widths)"]
    lines += [f"  {n}" for n in metrics["notes"]]
    runs = metrics.get("runs")
    if runs:
        lines.append(f"  runs: {runs['reference_runs']:,} for the reference and {runs['figure_runs']:,} for the "
                     f"figure in {runs['elapsed_s']:.3g} s (estimated {runs['estimated_s']:.3g} s)"
                     + (f", {runs['falsification_runs']:,} to falsify it in {runs['falsification_s']:.3g} s"
                        if "falsification_runs" in runs else ""))
    lines.append(f"  wrote {directory / 'compare.json'} and {directory / 'plots' / 'compare.png'}")
    return "\n".join(lines)


def _describe_sampled(directory: Path, metrics: dict, widths: str) -> list[str]:
    level = f"{100 * metrics['interval_level']:g} %"

    def share(name):
        low, high = metrics[f"{name}_interval"]
        return f"{metrics[name]:.4f} ({low:.4f} to {high:.4f})"

    return [f"{directory}: {metrics['boxes']} boxes ({widths}) against the {metrics['reference']} reference on "
            f"{metrics['sample_points']:,} points uniform in Sigma (exact {level} intervals)",
            f"  IoU {share('iou')}  precision {share('precision')}  recall {share('recall')}",
            f"  claimed {100 * metrics['claimed_share']:.3g} % of Sigma, reference {100 * metrics['reference_share']:.3g} %"]


def describe_estimate(directory: Path, plan: dict) -> str:
    """The CLI's lines for ``compare --estimate``."""
    where = (f"{plan['points_per_axis']} grid points per axis" if not plan.get("sample_points") else
             f"{plan['sample_points']:,} points uniform in Sigma")
    text = (f"{directory}: the reference would take {plan['reference_runs']:,} runs ({where}) and the figure {plan['figure_runs']:,}, from {plan['reference']}: about "
            f"{_duration(plan['estimated_s'])} at the rate of the first batch")
    if plan["falsification"]:
        text += (f"; then up to {FALSIFY_TRIES} x {2 * FALSIFY_POINTS:,} falsification runs of {FALSIFY_HORIZON} "
                 f"steps (estimated when the reference is known)")
    return text + "; choose the grid with --grid (per axis) or --grid-total, or --points"


def _figure_resolution(simulated: bool, k: int) -> int:
    """Pixels per side of each slice of plots/compare.png: a simulated reference runs
    one run per pixel, so its figure follows the grid the user chose (60 at the
    default 24 per axis)."""
    return 150 if not simulated else int(min(60, max(16, round(2.5 * k))))


def _figure_slices(scenario) -> tuple[int, int, int | None, np.ndarray]:
    """The axes of plots/compare.png: x, y, the varied one and its levels."""
    lo, hi = scenario.lower, scenario.upper
    x, y = 0, (3 if scenario.name == "fleet3" else scenario.n - 1)
    varied = 1 if scenario.n > 2 else None
    levels = np.linspace(lo[varied], hi[varied], 4) if varied is not None else np.array([np.nan])
    return x, y, varied, levels


def _figure_pixels(scenario, res: int) -> np.ndarray:
    """(levels * res^2, n) the states of the figure's pixels, level by level."""
    lo, hi = scenario.lower, scenario.upper
    x, y, varied, levels = _figure_slices(scenario)
    gx, gy = np.meshgrid(np.linspace(lo[x], hi[x], res), np.linspace(lo[y], hi[y], res), indexing="ij")
    out = []
    for level in levels:
        pts = np.tile((lo + hi) / 2, (gx.size, 1))
        pts[:, x], pts[:, y] = gx.ravel(), gy.ravel()
        if varied is not None:
            pts[:, varied] = level
        out.append(pts)
    return np.concatenate(out)
