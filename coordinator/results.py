"""Result files of a quantification (a public interface: keep the names).

- ``safe_set.parquet``: one row per surviving box; one column per state variable (the
  box centre, named as in the scenario) and ``half_width``.
- ``summary.json``: the campaign's figures and its guarantee sentence.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from farm import __version__


def result_hash(centres: np.ndarray, half_width: float) -> str:
    """Order-independent hash of a safe set (sorted rows, exact float64 bytes)."""
    centres = np.ascontiguousarray(centres, dtype=np.float64)
    order = np.lexsort(centres.T[::-1]) if len(centres) else np.zeros(0, dtype=np.int64)
    h = hashlib.sha256()
    h.update(np.float64(half_width).tobytes())
    h.update(np.ascontiguousarray(centres[order]).tobytes())
    return h.hexdigest()[:16]


def atomic_write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    with open(tmp, "wb") as fh:
        fh.write(data)
        fh.flush()
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def write_json(path: Path, obj: dict) -> None:
    atomic_write_bytes(Path(path), (json.dumps(obj, indent=2, sort_keys=False) + "\n").encode())


def write_safe_set(path: Path, centres: np.ndarray, half_width: float, state_names, metadata: dict) -> None:
    columns = {name: pa.array(centres[:, i], type=pa.float64()) for i, name in enumerate(state_names)}
    columns["half_width"] = pa.array(np.full(len(centres), half_width), type=pa.float64())
    table = pa.table(columns).replace_schema_metadata(
        {k: str(v) for k, v in {**metadata, "scenario_farm_version": __version__}.items()})
    path = Path(path)
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    pq.write_table(table, tmp)
    with open(tmp, "rb") as fh:
        os.fsync(fh.fileno())
    os.replace(tmp, path)


def read_safe_set(path, state_names) -> tuple[np.ndarray, float]:
    """(M, n) centres and the half-width, checking the columns against the scenario."""
    path = Path(path)
    try:
        table = pq.read_table(path)
    except FileNotFoundError:
        raise ValueError(f"{path}: no such safe-set file") from None
    except (pa.ArrowInvalid, OSError) as exc:
        raise ValueError(f"{path}: not a readable Parquet safe set ({exc})") from None
    missing = [c for c in (*state_names, "half_width") if c not in table.column_names]
    if missing:
        raise ValueError(f"{path}: safe set lacks column(s) {', '.join(missing)} for this scenario")
    centres = np.stack([table.column(c).to_numpy() for c in state_names], axis=1) if table.num_rows else \
        np.empty((0, len(state_names)))
    widths = table.column("half_width").to_numpy()
    if len(widths) and not np.all(widths == widths[0]):
        raise ValueError(f"{path}: boxes of different half-widths are not supported")
    return centres.astype(float), float(widths[0]) if len(widths) else 0.0
