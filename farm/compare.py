"""`scenario-farm compare DIR`: a quantified set against the model-based reference.

Prints IoU, precision, recall and the l-inf Hausdorff distance, writes compare.json and
plots/compare.png (2-D slices: claimed but unsafe in red, safe but not claimed in blue).
"""

from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from coordinator.reference import claimed, compare_boxes, falsify, grid, reference_safe
from farm.files import read_safe_set, write_json
from farm.executors import build_simulator
from scenarios.errors import ConfigError


def compare(directory: Path, grid: int | None = None, progress=None) -> dict:
    """Metrics of a finished campaign against its reference (also written to
    compare.json, with plots/compare.png); ``notes`` says how the reference was made.
    ``progress``: a farm.progress.Progress told of each phase (the reference can take
    a minute)."""
    say = progress.line if progress is not None else (lambda text: None)
    from farm.quantification import load_frozen_config, spec_of
    from farm.storage import CampaignDir

    directory = Path(directory)
    CampaignDir(directory).open("quantify")
    cfg = load_frozen_config(directory)
    if grid is not None and not (2 <= grid <= 4096):
        raise ConfigError(f"--grid: {grid} is out of range; allowed [2, 4096] points per axis")
    simulated = cfg.scenario.backend != "numpy"
    if simulated and cfg.actions.mode not in ("adversarial", "uniform", "search"):
        # constant or feedback actions quantify a different set than the worst case
        raise ConfigError(f"compare: a black-box SV has no model; its reference is simulated under Gamma*, which "
                          f"compares with actions.mode = 'adversarial', 'uniform' or 'search', not "
                          f"{cfg.actions.mode!r}")
    if simulated and grid is None:
        grid = 24  # every grid point is a 40 s simulation
    backend = build_simulator(spec_of(cfg)).backend
    scenario = backend.scenario
    centres, h = read_safe_set(directory / "safe_set.parquet", scenario.state_names)
    points = _grid(scenario, grid)
    reference_safe(backend, points[:1])  # no reference at all: say so before any work
    t0 = time.monotonic()
    say(f"compare: reference safe set on {len(points):,} grid points "
        f"({'simulated under Gamma*' if simulated or scenario.reference_safe(points[:1]) is None else 'model'})")
    truth = reference_safe(backend, points)
    say(f"compare: reference done in {time.monotonic() - t0:.1f} s; measuring the claimed set")
    metrics = compare_boxes(backend, centres, h, truth=truth, grid_points_per_axis=_k(scenario, grid))
    notes = []
    if cfg.actions.mode != "adversarial" and scenario.name != "toy" and scenario.sv_policy_name != "brake":
        sample = points[truth][:: max(1, int(truth.sum()) // 20000)]
        say(f"compare: random action sequences from {len(sample):,} reference-safe points (falsification)")
        broken = falsify(backend, sample)
        metrics["falsified_reference_points"] = [broken, int(len(sample))]
        notes.append(f"reference = worst case under Gamma*; random action sequences broke {broken} of "
                     f"{len(sample)} sampled reference-safe points")
    metrics["reference"] = ("simulated under Gamma* (black-box SV)" if simulated else "model-based")
    metrics["boxes"], metrics["half_width"] = int(len(centres)), h
    metrics["notes"] = notes
    write_json(directory / "compare.json", metrics)
    _plot(directory / "plots" / "compare.png", backend, centres, h, cfg)
    return metrics


def describe(directory: Path, metrics: dict) -> str:
    """The CLI's lines for ``compare``'s metrics."""
    lines = [f"{directory}: {metrics['boxes']} boxes (half-width {metrics['half_width']:g}) against the "
             f"{metrics['reference']} reference on {metrics['grid_points']:,} grid points",
             f"  IoU {metrics['iou']:.4f}  precision {metrics['precision']:.4f}  recall {metrics['recall']:.4f}  "
             f"Hausdorff (l-inf) {metrics['hausdorff']:.3g}",
             f"  claimed volume {metrics['claimed_volume']:.6g}, reference volume {metrics['reference_volume']:.6g}",
             f"  errors reach {metrics['missed_depth_boxes']:.3g} box widths into the reference's safe region "
             f"(missed) and {metrics['overclaimed_depth_boxes']:.3g} into its unsafe region (claimed); the boxes' "
             f"boundary layer is 1 box width plus a grid cell ({metrics['grid_cell_boxes']:.3g} box widths)"]
    lines += [f"  {n}" for n in metrics["notes"]]
    lines.append(f"  wrote {directory / 'compare.json'} and {directory / 'plots' / 'compare.png'}")
    return "\n".join(lines)


def _k(scenario, k):
    return k or int(round(1.5e6 ** (1 / scenario.n)))


def _grid(scenario, k):
    return grid(scenario, _k(scenario, k))


def _plot(path: Path, backend, centres, h, cfg) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    path.parent.mkdir(parents=True, exist_ok=True)
    scenario = backend.scenario
    lo, hi = scenario.lower, scenario.upper
    x, y = 0, (3 if scenario.name == "fleet3" else scenario.n - 1)
    varied = 1 if scenario.n > 2 else None
    levels = np.linspace(lo[varied], hi[varied], 4) if varied is not None else [None]
    fig, axs = plt.subplots(1, len(levels), figsize=(4.2 * len(levels), 4), squeeze=False)
    for ax, level in zip(axs[0], levels):
        res = 150 if cfg.scenario.backend == "numpy" else 60
        xs, ys = np.linspace(lo[x], hi[x], res), np.linspace(lo[y], hi[y], res)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        pts = np.tile((lo + hi) / 2, (gx.size, 1))
        pts[:, x], pts[:, y] = gx.ravel(), gy.ravel()
        if varied is not None:
            pts[:, varied] = level
        truth = reference_safe(backend, pts).reshape(gx.shape)
        got = claimed(scenario, centres, h, pts).reshape(gx.shape)
        img = np.zeros(gx.shape + (3,)) + 1.0
        img[truth & got] = (0.75, 0.9, 0.75)
        img[got & ~truth] = (0.85, 0.1, 0.1)
        img[truth & ~got] = (0.2, 0.35, 0.9)
        ax.imshow(np.transpose(img, (1, 0, 2)), origin="lower", aspect="auto", extent=(lo[x], hi[x], lo[y], hi[y]))
        ax.set_xlabel(scenario.state_names[x])
        ax.set_ylabel(scenario.state_names[y])
        if varied is not None:
            ax.set_title(f"{scenario.state_names[varied]} = {level:.3g}", fontsize=9)
    fig.suptitle(f"{cfg.scenario.name} / {scenario.sv_policy_name}: green agree, red claimed but unsafe, "
                 f"blue safe but not claimed", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
