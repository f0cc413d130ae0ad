"""A quantified safe set: the union of closed axis-aligned boxes centre +- half-width.

Each box has its own half-width (a set refined only near its boundary mixes sizes), and
may have one per axis (margin refinement splits a box only along some axes: an
*anisotropic* set); a set whose boxes share one half-width is *uniform*. The set's
identity is ``result_hash`` (order-independent); its file is ``safe_set.parquet`` (a
public interface: one row per box, one column per state variable holding the centre,
``half_width_<state>`` per state variable, and ``half_width``, the largest of them).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Iterator

import numpy as np

from coordinator.box_index import BoxIndex
from coordinator.spatial import TREE_DIMENSION, TREE_QUERIES, PointIndex, point_tree, tree_within
from coordinator.volume import corner_hull_volume, hull_volume, union_volume
from coordinator.volume_estimate import VolumeEstimate, disjoint_volume, hull_volume_estimate, union_volume_estimate
from scenarios.errors import DataError
from scenarios.version import __version__

HALF_WIDTH = "half_width"  # the column of each box's (largest) half-width in safe_set.parquet
AXIS_HALF_WIDTH = "half_width_{}"  # the columns of each box's half-width along a state variable
COVERING_MARGIN = "covering_margin"  # metadata: how far past its boxes the set's covering reaches
MIXED_HASH_TAG = b"scenario-farm safe set, per-box half-widths\n"
AXES_HASH_TAG = b"scenario-farm safe set, per-axis half-widths\n"
EXACT_MAX_DIM = 5  # above it an exact union or hull costs 2^n per box: estimated instead
CORNER_HULL_MAX_DIM = 3  # boxes with a half-width per axis: every corner to qhull up to here


class SafeSetError(DataError):
    """A safe-set file or array that cannot be read as a safe set (one-line message; a
    ``DataError``, so a ``UserError`` and still a ``ValueError``)."""


@dataclass(frozen=True, eq=False)
class SafeSet:
    """``centres`` (M, n), ``half_widths`` (M,), or (M, n) for a half-width per axis, and
    the scenario's ``state_names`` (n). ``disjoint``: the boxes meet only on faces (a
    partition's), so the union's volume is exact in any dimension. Arrays are read-only
    views; build a uniform set with ``SafeSet.uniform``."""

    centres: np.ndarray
    half_widths: np.ndarray
    state_names: tuple[str, ...]
    metadata: dict = field(default_factory=dict)  # the Parquet file's key-value metadata, when read from one
    disjoint: bool = False

    def __post_init__(self):
        names = tuple(str(s) for s in self.state_names)
        centres = np.asarray(self.centres, dtype=np.float64).reshape(-1, len(names)) if len(names) else \
            np.asarray(self.centres, dtype=np.float64)
        widths = np.asarray(self.half_widths, dtype=np.float64)
        if centres.ndim != 2 or centres.shape[1] != len(names):
            raise SafeSetError(f"safe set: centres of shape {centres.shape} for {len(names)} state variables")
        if widths.ndim == 2 and widths.shape == centres.shape and (widths == widths[:, :1]).all():
            widths = widths[:, 0].copy()  # the same on every axis: one per box, as every set before
        if widths.shape not in ((len(centres),), centres.shape):
            raise SafeSetError(f"safe set: {widths.shape} half-widths for {len(centres)} boxes; need one per box "
                               f"or one per box and axis")
        for name, value in (("centres", centres), ("half_widths", widths)):
            view = value.view()
            view.flags.writeable = False  # the caller's array stays writable; the set's view does not
            object.__setattr__(self, name, view)
        object.__setattr__(self, "state_names", names)

    @classmethod
    def uniform(cls, centres, half_width: float, state_names) -> "SafeSet":
        """Boxes that share one half-width."""
        centres = np.asarray(centres, dtype=np.float64).reshape(-1, len(tuple(state_names)))
        return cls(centres, np.full(len(centres), float(half_width)), tuple(state_names))

    # -- shape -------------------------------------------------------------------------------
    def __len__(self) -> int:
        return len(self.centres)

    @property
    def n(self) -> int:
        return len(self.state_names)

    @property
    def anisotropic(self) -> bool:
        """The boxes have a half-width per axis."""
        return self.half_widths.ndim == 2

    @cached_property
    def axis_half_widths(self) -> np.ndarray:
        """(M, n) each box's half-width along each axis."""
        if self.anisotropic:
            return self.half_widths
        return np.repeat(self.half_widths[:, None], self.n, axis=1)

    @property
    def largest_half_widths(self) -> np.ndarray:
        """(M,) each box's largest half-width (safe_set.parquet's ``half_width``)."""
        return self.half_widths.max(axis=1) if self.anisotropic else self.half_widths

    @property
    def lower(self) -> np.ndarray:
        return self.centres - self.axis_half_widths

    @property
    def upper(self) -> np.ndarray:
        return self.centres + self.axis_half_widths

    @cached_property
    def widths(self) -> np.ndarray:
        """The distinct half-widths, ascending (every axis's, for a set with one per axis)."""
        hw = self.half_widths.ravel()
        if len(hw) and (hw == hw[0]).all():  # the common case, without a sort
            return hw[:1].copy()
        return np.unique(hw)

    @property
    def is_uniform(self) -> bool:
        return len(self.widths) <= 1

    @property
    def half_width(self) -> float:
        """The half-width every box shares (0.0 for an empty set). A set of mixed sizes
        has none: ask ``finest`` / ``coarsest`` or ``half_widths``."""
        if not self.is_uniform:
            raise SafeSetError(f"safe set: its boxes have {len(self.widths)} different half-widths "
                               f"({self.finest:g} to {self.coarsest:g}), not one")
        return self.finest

    @property
    def finest(self) -> float:
        """The smallest half-width (the resolution where the set is finest); 0.0 if empty."""
        return float(self.widths[0]) if len(self.widths) else 0.0

    @property
    def coarsest(self) -> float:
        """The largest half-width; 0.0 if empty."""
        return float(self.widths[-1]) if len(self.widths) else 0.0

    def describe_widths(self) -> str:
        """"half-width 1" or "half-widths 0.25 to 2", for titles and messages."""
        if self.is_uniform:
            return f"half-width {self.finest:g}"
        return f"half-widths {self.finest:g} to {self.coarsest:g}"

    def by_width(self) -> Iterator[tuple[float, np.ndarray]]:
        """(half-width, (k, n) centres of the boxes of that half-width), ascending."""
        if self.is_uniform:
            if len(self):
                yield self.finest, self.centres
            return
        if self.anisotropic:
            raise SafeSetError("safe set: its boxes have a half-width per axis; ask axis_half_widths")
        for width in self.widths:
            yield float(width), self.centres[self.half_widths == width]

    def sorted(self) -> "SafeSet":
        """The same set, rows in lexicographic order of (centre, half-widths)."""
        widths = self.half_widths.T[::-1] if self.anisotropic else (self.half_widths,)
        order = np.lexsort((*widths, *self.centres.T[::-1])) if len(self) else np.zeros(0, np.int64)
        return SafeSet(self.centres[order], self.half_widths[order], self.state_names, dict(self.metadata),
                       self.disjoint)

    # -- membership and measures ---------------------------------------------------------------
    def contains(self, states) -> np.ndarray:
        """(B, n) states -> (B,) bool: inside some box (closed, to within the spatial
        index's tolerance)."""
        states = np.atleast_2d(np.asarray(states, dtype=float))
        if states.shape[1] != self.n:
            raise SafeSetError(f"contains: states need {self.n} columns ({', '.join(self.state_names)}), "
                               f"got {states.shape[1]}")
        if self.anisotropic:
            return self._box_index.contains(states)
        inside = np.zeros(len(states), dtype=bool)
        if self.n >= TREE_DIMENSION and len(states) >= TREE_QUERIES:
            # many queries in a high dimension (a volume estimate's points): one KD-tree per
            # half-width, built once for the set; the cell index's misses check 2^n cells
            for width, tree in self._trees:
                outside = np.flatnonzero(~inside)
                inside[outside] = tree_within(tree, states[outside], width, workers=-1)
            return inside
        for width, index in self._indexes:
            inside |= index.any_within(states, width)
        return inside

    @cached_property
    def _trees(self) -> list:
        """One KD-tree of the centres per half-width (``contains`` in a high dimension)."""
        return [(width, point_tree(centres)) for width, centres in self.by_width()]

    @cached_property
    def _box_index(self) -> BoxIndex:
        return BoxIndex(self.lower, self.upper)

    @cached_property
    def _indexes(self) -> list[tuple[float, PointIndex]]:
        """One spatial index per half-width (cells of the boxes' own size)."""
        indexes = []
        for width, centres in self.by_width():
            index = PointIndex(self.n, 2 * width, centres.min(axis=0), capacity=len(centres))
            index.insert(centres)
            indexes.append((width, index))
        return indexes

    def volume_union(self, bounds=None) -> float:
        """Volume of the union (clipped to ``bounds`` = (lo, hi) when given): exact where
        that is linear in the boxes, else estimated (``union_estimate`` says which)."""
        return self.union_estimate(bounds).value

    def volume_hull(self, bounds=None) -> float:
        """Volume of the convex hull of the union (the paper's "cardinality"): exact up to
        5 dimensions, an outer estimate above (``hull_estimate``)."""
        return self.hull_estimate(bounds).value

    def union_estimate(self, bounds=None) -> VolumeEstimate:
        if self.disjoint:
            return disjoint_volume(self.lower, self.upper, bounds)
        if not self.anisotropic and self.n <= EXACT_MAX_DIM:
            value = union_volume(self.centres, self.half_widths, bounds=bounds)
            return VolumeEstimate(value, value, value, True, "exact (the union of the boxes, cell by cell)")
        return union_volume_estimate(self.contains, self.lower, self.upper, bounds, seed=self._seed)

    def hull_estimate(self, bounds=None) -> VolumeEstimate:
        if not self.anisotropic and self.n <= EXACT_MAX_DIM:
            value = hull_volume(self.centres, self.half_widths, bounds=bounds)
            return VolumeEstimate(value, value, value, True, "exact (qhull over the hull boxes' corners)")
        if self.n <= CORNER_HULL_MAX_DIM:
            value = corner_hull_volume(self.lower, self.upper, bounds)
            return VolumeEstimate(value, value, value, True, "exact (qhull over every box's corners)")
        return hull_volume_estimate(self.lower, self.upper, bounds, seed=self._seed)

    @property
    def _seed(self) -> int:
        """The estimates' seed: the set's own hash, so its files are the same every time."""
        return int(self.result_hash[:12], 16)

    @cached_property
    def result_hash(self) -> str:
        """Order-independent hash of the boxes (exact float64 bytes), 16 hex digits. A
        uniform set hashes its half-width and its sorted centres, as every recorded
        result_hash did; a set of mixed sizes hashes its sorted (centre, half-width)
        rows after a tag of its own, so no mixed set shares a uniform set's hash."""
        digest = hashlib.sha256()
        if self.anisotropic:
            rows = np.column_stack([self.centres, self.half_widths])
            digest.update(AXES_HASH_TAG)
            digest.update(np.ascontiguousarray(rows[np.lexsort(rows.T[::-1])]).tobytes())
        elif self.is_uniform:
            centres = np.ascontiguousarray(self.centres)
            order = np.lexsort(centres.T[::-1]) if len(centres) else np.zeros(0, dtype=np.int64)
            digest.update(np.float64(self.finest).tobytes())
            digest.update(np.ascontiguousarray(centres[order]).tobytes())
        else:
            rows = np.column_stack([self.centres, self.half_widths])
            digest.update(MIXED_HASH_TAG)
            digest.update(np.ascontiguousarray(rows[np.lexsort(rows.T[::-1])]).tobytes())
        return digest.hexdigest()[:16]

    # -- safe_set.parquet -----------------------------------------------------------------------
    def to_table(self, metadata: dict | None = None):
        """The set as a pyarrow Table: the columns of safe_set.parquet, ``metadata``
        (values as strings) and the package version in its schema metadata."""
        import pyarrow as pa

        columns = {name: pa.array(self.centres[:, i], type=pa.float64()) for i, name in enumerate(self.state_names)}
        columns[HALF_WIDTH] = pa.array(self.largest_half_widths, type=pa.float64())
        for i, name in enumerate(self.state_names):
            columns[AXIS_HALF_WIDTH.format(name)] = pa.array(self.axis_half_widths[:, i], type=pa.float64())
        meta = {**self.metadata, **(metadata or {}), "scenario_farm_version": __version__}
        if self.disjoint:
            meta["disjoint"] = "true"
        return pa.table(columns).replace_schema_metadata({k: str(v) for k, v in meta.items()})

    def to_parquet(self, where, metadata: dict | None = None) -> None:
        """Write safe_set.parquet to ``where``: a path or an open binary file (farm
        writes through ``farm.directory.files.atomic_write``, so a reader never sees half a file)."""
        import pyarrow.parquet as pq

        pq.write_table(self.to_table(metadata), where)

    @classmethod
    def from_parquet(cls, path, state_names) -> "SafeSet":
        """Read a safe-set file, checking its columns against the scenario's state
        variables; boxes may differ in half-width. Bad files raise SafeSetError."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        path, names = Path(path), tuple(state_names)
        try:
            table = pq.read_table(path)
        except FileNotFoundError:
            raise SafeSetError(f"{path}: no such safe-set file") from None
        except (pa.ArrowInvalid, OSError) as exc:
            raise SafeSetError(f"{path}: not a readable Parquet safe set ({exc})") from None
        missing = [c for c in (*names, HALF_WIDTH) if c not in table.column_names]
        if missing:
            raise SafeSetError(f"{path}: safe set lacks column(s) {', '.join(missing)} for this scenario")
        axis_columns = [AXIS_HALF_WIDTH.format(name) for name in names]
        per_axis = [c for c in axis_columns if c in table.column_names]
        if per_axis and len(per_axis) != len(names):
            raise SafeSetError(f"{path}: safe set has {len(per_axis)} of the {len(names)} half_width_<state> "
                               f"columns; it needs all or none")
        extra = [c for c in table.column_names if c not in (*names, HALF_WIDTH, *axis_columns)]
        if extra:  # e.g. a fleet3 set handed to lead-follow: its v0, v1, p10 mean other things
            raise SafeSetError(f"{path}: safe set has column(s) {', '.join(extra)} that are not state variables of "
                               f"this scenario ({', '.join(names)}); it was written for another scenario")
        try:
            centres = np.stack([table.column(c).to_numpy().astype(float) for c in names], axis=1) \
                if table.num_rows else np.empty((0, len(names)))
            widths = table.column(HALF_WIDTH).to_numpy().astype(float)
            if per_axis:
                widths = np.stack([table.column(c).to_numpy().astype(float) for c in axis_columns], axis=1) \
                    if table.num_rows else np.empty((0, len(names)))
        except (TypeError, ValueError, pa.ArrowException) as exc:
            raise SafeSetError(f"{path}: safe-set columns must be numbers ({exc})") from None
        if not (np.isfinite(centres).all() and np.isfinite(widths).all() and (widths > 0).all()):
            raise SafeSetError(f"{path}: safe set holds a non-finite centre or a half_width <= 0; "
                               f"allowed half_width > 0")
        metadata = {k.decode(errors="replace"): v.decode(errors="replace")
                    for k, v in (table.schema.metadata or {}).items() if not k.startswith(b"ARROW:")}
        return cls(centres, widths, names, metadata, metadata.get("disjoint") == "true")
