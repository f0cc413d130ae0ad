"""What a campaign explored (its ledger and checkpoint), for the slices' three classes."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from farm.directory.journal import Journal
from farm.directory.storage import read_ledger


def explored_boxes(directory, state_names) -> tuple[np.ndarray, np.ndarray] | None:
    """The boxes a campaign explored, from its directory: ``(points (P, n), half_widths
    (P,))``, or None when the directory holds no record of it (no ledger, no checkpoint).

    - every committed run's start state (the ledger), at its round's delta: its box was
      in the covering when it was drawn;
    - the checkpoint's vertices, alive or pruned, at the final delta; SPE's first roots
      (the first block of graph roots: the tiling of Sigma it starts from) at delta0;
    - the checkpoint's failure points (PhiBar), at the final delta.

    Outside the safe set, these boxes are the states the campaign explored and pruned;
    the rest it never explored (for SPE, which starts from all of Sigma, nothing)."""
    directory = Path(directory)
    names = list(state_names)
    points, widths = [], []
    if any((directory / "ledger").glob("segment-*.parquet")):
        table = read_ledger(directory, columns=["delta", *names])
        if table.num_rows:
            points.append(np.column_stack([table.column(c).to_numpy() for c in names]).astype(float))
            widths.append(table.column("delta").to_numpy().astype(float))
    if (directory / "checkpoint.npz").exists():
        state, _ = Journal(directory).read(["algo.scalars", "algo.vertices.points", "algo.graph.parent",
                                            "algo.failures.points"])
        delta = float(state["algo.scalars"][0]) if "algo.scalars" in state else 0.0
        vertices = state.get("algo.vertices.points", np.zeros((0, len(names))))
        if delta > 0 and len(vertices):
            wide = np.full(len(vertices), delta)
            parent = state.get("algo.graph.parent")
            if parent is not None and len(parent) and parent[0] == -1:
                first = int(np.argmax(parent != -1)) if (parent != -1).any() else len(parent)
                wide[:first] = max(delta, _delta0(directory, delta))
            points.append(vertices.reshape(-1, len(names)))
            widths.append(wide)
        failures = state.get("algo.failures.points")
        if delta > 0 and failures is not None and len(failures):
            points.append(failures.reshape(-1, len(names)))
            widths.append(np.full(len(failures), delta))
    if not points:
        return None
    return np.concatenate(points), np.concatenate(widths)


def _delta0(directory: Path, default: float) -> float:
    """quantify.delta0 of the campaign's frozen config (a side campaign: its parent's)."""
    for folder in (directory, *directory.parents[:3]):
        try:
            return float(json.loads((folder / "config.json").read_text())["config"]["quantify"]["delta0"])
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return default


def _campaign_of(out_dir: Path) -> Path | None:
    """The campaign directory whose figures go to ``out_dir``: DIR for DIR/plots, a side
    campaign DIR/sides/<label> for DIR/plots/<label>_side; None for any other place."""
    out_dir = Path(out_dir)
    if out_dir.name == "plots":
        return out_dir.parent
    if out_dir.parent.name == "plots" and out_dir.name.endswith("_side"):
        return out_dir.parent.parent / "sides" / out_dir.name[: -len("_side")]
    return None
