"""Strata of Sigma from a quantified set S, with their masses under D, computed without
simulation.

A regular grid over Sigma (cells of the set's finest half-width, coarser if the grid
would exceed ``MAX_CELLS``) labels each cell by whether its centre lies in S and by its
Chebyshev distance, in cells, to the nearest cell of the other label (capped at
``band + 1``). The strata are: inside S deeper than ``band`` cells, inside S at distance
band..1, outside S at distance 1..band, and outside S farther out. Each stratum is a union
of cells, so under a product law its mass is a sum of products of per-axis CDF
differences (exact), and a draw from D restricted to it picks a cell by mass and draws
inside it (exact); for recorded starts (an empirical D) each row is classified by its
cell, and the masses are the rows' shares (exact for that D).

Any partition gives an unbiased stratified estimator; this one puts the boundary of S,
where failures and successes mix, into thin strata of their own, so that Neyman
allocation spends the runs there (docs/guarantee.md, "A failure rate beside the set").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.ndimage import maximum_filter

from coordinator.safe_set import SafeSet
from scenarios.distributions import EmpiricalLaw, ProductLaw

MAX_CELLS = 1 << 22  # grid cells at most (labels, masses: ~60 MB)
CONTAINS_CHUNK = 1 << 18  # cell centres per membership query


@dataclass(frozen=True, eq=False)
class Strata:
    """``names`` (H,) and ``masses`` (H,) of the strata under ``law``; ``edges``: the grid
    per axis; ``cell_stratum``: each grid cell's stratum (-1: no mass), flat in C order;
    ``members``: per stratum, its cells with mass (product law) or its rows (empirical);
    ``cumulative``: per stratum, its cells' cumulative masses normalised to 1 (product law)."""

    names: tuple[str, ...]
    masses: np.ndarray
    law: ProductLaw | EmpiricalLaw
    edges: tuple[np.ndarray, ...]
    cell_stratum: np.ndarray
    members: tuple[np.ndarray, ...]
    cumulative: tuple[np.ndarray, ...] | None

    def __len__(self) -> int:
        return len(self.names)

    @property
    def shape(self) -> tuple[int, ...]:
        return tuple(len(e) - 1 for e in self.edges)

    def stratum_of(self, points: np.ndarray) -> np.ndarray:
        """(B, n) states -> (B,) the stratum of each (-1 where D has no mass)."""
        cells = _cells_of(self.edges, np.atleast_2d(points))
        return self.cell_stratum[cells]

    def draw(self, strata: np.ndarray, u: np.ndarray) -> np.ndarray:
        """(B, n) starts drawn from D restricted to ``strata`` (B,), from ``u`` (B, n + 1)."""
        n = len(self.edges)
        out = np.empty((len(strata), n))
        for h in np.unique(strata):
            rows = np.flatnonzero(strata == h)
            members = self.members[h]
            if isinstance(self.law, EmpiricalLaw):
                pick = np.minimum((u[rows, 0] * len(members)).astype(np.int64), len(members) - 1)
                out[rows] = self.law.points[members[pick]]
                continue
            pick = np.minimum(np.searchsorted(self.cumulative[h], u[rows, 0], side="right"), len(members) - 1)
            index = np.unravel_index(members[pick], self.shape)
            lo = np.column_stack([self.edges[i][index[i]] for i in range(n)])
            hi = np.column_stack([self.edges[i][index[i] + 1] for i in range(n)])
            out[rows] = self.law.draw_in_boxes(u[rows, 1:], lo, hi)
        return out

    def describe(self) -> list[dict]:
        return [{"name": name, "mass": float(mass)} for name, mass in zip(self.names, self.masses)]


def _cells_of(edges, points) -> np.ndarray:
    """Flat grid cell of each point (points on Sigma's faces go to the cell inside)."""
    index = [np.clip(np.searchsorted(e, points[:, i], side="right") - 1, 0, len(e) - 2) for i, e in enumerate(edges)]
    return np.ravel_multi_index(index, tuple(len(e) - 1 for e in edges))


def grid_edges(lower, upper, width: float, max_cells: int = MAX_CELLS) -> tuple[np.ndarray, ...]:
    """Per axis, the edges of cells about ``width`` wide spanning [lower, upper] (coarser, by
    one factor on every axis, if the grid would hold more than ``max_cells`` cells)."""
    extent = np.asarray(upper, dtype=float) - np.asarray(lower, dtype=float)
    counts = np.maximum(1, np.ceil(extent / width - 1e-9)).astype(np.int64)
    while np.prod(counts.astype(float)) > max_cells:
        counts = np.maximum(1, np.floor(counts / 1.25)).astype(np.int64)
    return tuple(np.linspace(lo, hi, c + 1) for lo, hi, c in zip(lower, upper, counts))


def _distance(mask: np.ndarray, cap: int) -> np.ndarray:
    """For the cells of ``mask``: Chebyshev distance in cells to the nearest cell outside
    it (``cap`` where none is within cap - 1)."""
    dist = np.full(mask.shape, cap, dtype=np.int16)
    reach = ~mask
    for d in range(1, cap):
        if not reach.any():
            break
        reach = maximum_filter(reach, size=3, mode="nearest")  # separable: cheap on millions of cells
        dist[(dist == cap) & reach & mask] = d
    return dist


def _labels(inside: np.ndarray, band: int) -> tuple[np.ndarray, list[str]]:
    """Codes 0 (inside, deep) .. band (inside, next to S's boundary), band + 1 (outside,
    next to it) .. 2 band + 1 (outside, far), and their names."""
    cap = band + 1
    code = np.where(inside, cap - _distance(inside, cap), band + _distance(~inside, cap))
    names = [f"inside S, deeper than {band} cells"] + [f"inside S, {d} cell{'s' * (d > 1)} from its boundary"
                                                       for d in range(band, 0, -1)]
    names += [f"outside S, {d} cell{'s' * (d > 1)} from it" for d in range(1, band + 1)]
    names += [f"outside S, farther than {band} cells"]
    return code.astype(np.int16), names


def _inside(safe_set: SafeSet, edges) -> np.ndarray:
    centres = [0.5 * (e[:-1] + e[1:]) for e in edges]
    shape = tuple(len(c) for c in centres)
    flat = np.empty(int(np.prod(shape)), dtype=bool)
    for lo in range(0, len(flat), CONTAINS_CHUNK):
        index = np.unravel_index(np.arange(lo, min(lo + CONTAINS_CHUNK, len(flat))), shape)
        flat[lo : lo + len(index[0])] = safe_set.contains(np.column_stack([c[i] for c, i in zip(centres, index)]))
    return flat.reshape(shape)


def set_strata(law, lower, upper, safe_set: SafeSet, band: int, max_cells: int = MAX_CELLS) -> Strata:
    """The strata of S (module docstring) with their masses under ``law``."""
    width = safe_set.finest if len(safe_set) else float(np.max(np.asarray(upper) - np.asarray(lower))) / 64
    edges = grid_edges(lower, upper, width, max_cells)
    code, names = _labels(_inside(safe_set, edges), band)
    return _build(law, edges, code.ravel(), names)


def whole_strata(law, lower, upper) -> Strata:
    """One stratum, all of Sigma: plain Monte Carlo."""
    edges = tuple(np.array([lo, hi], dtype=float) for lo, hi in zip(lower, upper))
    return _build(law, edges, np.zeros(1, dtype=np.int16), ["all of Sigma"])


def _build(law, edges, code: np.ndarray, names: list[str]) -> Strata:
    if isinstance(law, EmpiricalLaw):
        rows_code = code[_cells_of(edges, law.points)]
        counts = np.bincount(rows_code, minlength=len(names))
        kept = np.flatnonzero(counts > 0)
        members = tuple(np.flatnonzero(rows_code == h) for h in kept)
        masses, cumulative = counts[kept] / len(law.points), None
    else:
        cell_mass = law.axes[0].masses(edges[0])
        for axis, e in zip(law.axes[1:], edges[1:]):
            cell_mass = np.multiply.outer(cell_mass, axis.masses(e))
        cell_mass = cell_mass.ravel()
        weights = np.bincount(code, weights=cell_mass, minlength=len(names))
        kept = np.flatnonzero(weights > 0)
        members, cumulative = [], []
        for h in kept:
            cells = np.flatnonzero((code == h) & (cell_mass > 0))
            running = np.cumsum(cell_mass[cells])
            members.append(cells)
            cumulative.append(running / running[-1])
        masses = weights[kept] / weights[kept].sum()  # the grid's masses sum to 1 up to rounding
        members, cumulative = tuple(members), tuple(cumulative)
    remap = np.full(len(names), -1, dtype=np.int16)
    remap[kept] = np.arange(len(kept))
    if not isinstance(law, EmpiricalLaw):
        code = np.where(cell_mass > 0, code, len(names))  # cells without mass belong to no stratum
        remap = np.append(remap, -1)
    return Strata(tuple(names[h] for h in kept), np.asarray(masses, dtype=float), law, edges, remap[code], members,
                  cumulative)
