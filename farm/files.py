"""Every file this package writes goes through ``atomic_write``: written aside, fsynced,
then renamed over the target, so a reader (or a resume after kill -9) sees the old
file or the new one, never half of one. Also the safe-set Parquet format (a public
interface: keep the names).

- ``safe_set.parquet``: one row per surviving box; one column per state variable (the
  box centre, named as in the scenario) and ``half_width``.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
from pathlib import Path
from typing import Callable

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from scenarios.errors import CampaignError, DataError
from scenarios.version import __version__

TEMP_PREFIX = "."
TEMP_MARK = ".tmp-"  # temp files are ".<name>.tmp-<pid>": the pid tells a dead writer's


def temp_path(path: Path) -> Path:
    return path.with_name(f"{TEMP_PREFIX}{path.name}{TEMP_MARK}{os.getpid()}")


def atomic_write(path: Path, write: Callable[[io.BufferedWriter], None]) -> None:
    """Call ``write(fh)`` on a temp file beside ``path``, fsync, rename over ``path``.
    On any error the temp file is removed and ``path`` is untouched."""
    path = Path(path)
    tmp = temp_path(path)
    try:
        with open(tmp, "wb") as fh:
            write(fh)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def atomic_write_bytes(path: Path, data: bytes) -> None:
    atomic_write(path, lambda fh: fh.write(data))


def write_json(path: Path, obj: dict) -> None:
    atomic_write_bytes(Path(path), (json.dumps(obj, indent=2, sort_keys=False) + "\n").encode())


def read_json(path: Path, required=()) -> dict:
    """A JSON object this tool wrote, holding at least the keys ``required``; a missing,
    damaged or foreign file is a one-line CampaignError naming it."""
    path = Path(path)
    try:
        data = json.loads(path.read_bytes().decode("utf-8"))  # what this tool writes
    except FileNotFoundError:
        raise CampaignError(f"{path}: missing") from None
    except IsADirectoryError:
        raise CampaignError(f"{path}: a directory, not a file of this tool") from None
    except (ValueError, RecursionError) as exc:  # UnicodeDecodeError and JSONDecodeError are ValueErrors
        raise CampaignError(f"{path}: not valid JSON (damaged? {type(exc).__name__}: {exc})") from None
    except OSError as exc:
        raise CampaignError(f"{path}: cannot be read ({exc.strerror or type(exc).__name__})") from None
    if not isinstance(data, dict):
        raise CampaignError(f"{path}: holds a JSON {type(data).__name__}, not the object this tool wrote (damaged?)")
    missing = [key for key in required if key not in data]
    if missing:
        raise CampaignError(f"{path}: lacks {', '.join(map(repr, missing))} (damaged?)")
    return data


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_table(path: Path, table: pa.Table) -> None:
    atomic_write(path, lambda fh: pq.write_table(table, fh))


def write_safe_set(path: Path, centres: np.ndarray, half_width: float, state_names, metadata: dict) -> None:
    columns = {name: pa.array(centres[:, i], type=pa.float64()) for i, name in enumerate(state_names)}
    columns["half_width"] = pa.array(np.full(len(centres), half_width), type=pa.float64())
    table = pa.table(columns).replace_schema_metadata(
        {k: str(v) for k, v in {**metadata, "scenario_farm_version": __version__}.items()})
    write_table(path, table)


def read_safe_set(path, state_names) -> tuple[np.ndarray, float]:
    """(M, n) centres and the half-width, checking the columns against the scenario."""
    path = Path(path)
    try:
        table = pq.read_table(path)
    except FileNotFoundError:
        raise DataError(f"{path}: no such safe-set file") from None
    except (pa.ArrowInvalid, OSError) as exc:
        raise DataError(f"{path}: not a readable Parquet safe set ({exc})") from None
    missing = [c for c in (*state_names, "half_width") if c not in table.column_names]
    if missing:
        raise DataError(f"{path}: safe set lacks column(s) {', '.join(missing)} for this scenario")
    extra = [c for c in table.column_names if c not in (*state_names, "half_width")]
    if extra:  # e.g. a fleet3 set handed to lead-follow: its v0, v1, p10 mean other things
        raise DataError(f"{path}: safe set has column(s) {', '.join(extra)} that are not state variables of "
                         f"this scenario ({', '.join(state_names)}); it was written for another scenario")
    try:
        centres = np.stack([table.column(c).to_numpy().astype(float) for c in state_names], axis=1) \
            if table.num_rows else np.empty((0, len(state_names)))
        widths = table.column("half_width").to_numpy().astype(float)
    except (TypeError, ValueError, pa.ArrowException) as exc:
        raise DataError(f"{path}: safe-set columns must be numbers ({exc})") from None
    if not (np.isfinite(centres).all() and np.isfinite(widths).all() and (widths > 0).all()):
        raise DataError(f"{path}: safe set holds a non-finite centre or a half_width <= 0; allowed half_width > 0")
    if len(widths) and not np.all(widths == widths[0]):
        raise DataError(f"{path}: boxes of different half-widths are not supported")
    return centres.astype(float), float(widths[0]) if len(widths) else 0.0
