"""A quantified safe set: the union of closed l-inf boxes centre +- half-width.

Each box has its own half-width (a set refined only near its boundary mixes sizes); a
set whose boxes share one half-width is *uniform*. The set's identity is ``result_hash``
(order-independent); its file is ``safe_set.parquet`` (a public interface: one row per
box, one column per state variable holding the centre, and ``half_width``).
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Iterator

import numpy as np

from coordinator.spatial import PointIndex
from coordinator.volume import hull_volume, union_volume
from scenarios.errors import DataError
from scenarios.version import __version__

HALF_WIDTH = "half_width"  # the column of each box's half-width in safe_set.parquet
MIXED_HASH_TAG = b"scenario-farm safe set, per-box half-widths\n"


class SafeSetError(DataError):
    """A safe-set file or array that cannot be read as a safe set (one-line message; a
    ``DataError``, so a ``UserError`` and still a ``ValueError``)."""


@dataclass(frozen=True, eq=False)
class SafeSet:
    """``centres`` (M, n), ``half_widths`` (M,) and the scenario's ``state_names`` (n).
    Arrays are read-only views; build a uniform set with ``SafeSet.uniform``."""

    centres: np.ndarray
    half_widths: np.ndarray
    state_names: tuple[str, ...]
    metadata: dict = field(default_factory=dict)  # the Parquet file's key-value metadata, when read from one

    def __post_init__(self):
        names = tuple(str(s) for s in self.state_names)
        centres = np.asarray(self.centres, dtype=np.float64).reshape(-1, len(names)) if len(names) else \
            np.asarray(self.centres, dtype=np.float64)
        widths = np.asarray(self.half_widths, dtype=np.float64)
        if centres.ndim != 2 or centres.shape[1] != len(names):
            raise SafeSetError(f"safe set: centres of shape {centres.shape} for {len(names)} state variables")
        if widths.shape != (len(centres),):
            raise SafeSetError(f"safe set: {widths.shape} half-widths for {len(centres)} boxes; need one per box")
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

    @cached_property
    def widths(self) -> np.ndarray:
        """The distinct half-widths, ascending."""
        hw = self.half_widths
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
        for width in self.widths:
            yield float(width), self.centres[self.half_widths == width]

    def sorted(self) -> "SafeSet":
        """The same set, rows in lexicographic order of (centre, half-width)."""
        order = np.lexsort((self.half_widths, *self.centres.T[::-1])) if len(self) else np.zeros(0, np.int64)
        return SafeSet(self.centres[order], self.half_widths[order], self.state_names, dict(self.metadata))

    # -- membership and measures ---------------------------------------------------------------
    def contains(self, states) -> np.ndarray:
        """(B, n) states -> (B,) bool: inside some box (closed, to within the spatial
        index's tolerance)."""
        states = np.atleast_2d(np.asarray(states, dtype=float))
        if states.shape[1] != self.n:
            raise SafeSetError(f"contains: states need {self.n} columns ({', '.join(self.state_names)}), "
                               f"got {states.shape[1]}")
        inside = np.zeros(len(states), dtype=bool)
        for width, index in self._indexes:
            inside |= index.any_within(states, width)
        return inside

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
        """Exact volume of the union (clipped to ``bounds`` = (lo, hi) when given)."""
        return union_volume(self.centres, self.half_widths, bounds=bounds)

    def volume_hull(self, bounds=None) -> float:
        """Volume of the convex hull of the union (the paper's "cardinality")."""
        return hull_volume(self.centres, self.half_widths, bounds=bounds)

    @cached_property
    def result_hash(self) -> str:
        """Order-independent hash of the boxes (exact float64 bytes), 16 hex digits. A
        uniform set hashes its half-width and its sorted centres, as every recorded
        result_hash did; a set of mixed sizes hashes its sorted (centre, half-width)
        rows after a tag of its own, so no mixed set shares a uniform set's hash."""
        digest = hashlib.sha256()
        if self.is_uniform:
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
        columns[HALF_WIDTH] = pa.array(self.half_widths, type=pa.float64())
        meta = {**(metadata or {}), "scenario_farm_version": __version__}
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
        extra = [c for c in table.column_names if c not in (*names, HALF_WIDTH)]
        if extra:  # e.g. a fleet3 set handed to lead-follow: its v0, v1, p10 mean other things
            raise SafeSetError(f"{path}: safe set has column(s) {', '.join(extra)} that are not state variables of "
                               f"this scenario ({', '.join(names)}); it was written for another scenario")
        try:
            centres = np.stack([table.column(c).to_numpy().astype(float) for c in names], axis=1) \
                if table.num_rows else np.empty((0, len(names)))
            widths = table.column(HALF_WIDTH).to_numpy().astype(float)
        except (TypeError, ValueError, pa.ArrowException) as exc:
            raise SafeSetError(f"{path}: safe-set columns must be numbers ({exc})") from None
        if not (np.isfinite(centres).all() and np.isfinite(widths).all() and (widths > 0).all()):
            raise SafeSetError(f"{path}: safe set holds a non-finite centre or a half_width <= 0; "
                               f"allowed half_width > 0")
        metadata = {k.decode(errors="replace"): v.decode(errors="replace")
                    for k, v in (table.schema.metadata or {}).items() if not k.startswith(b"ARROW:")}
        return cls(centres, widths, names, metadata)
