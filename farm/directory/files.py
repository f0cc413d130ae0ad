"""Every file this package writes goes through ``atomic_write``: written aside, fsynced,
then renamed over the target, so a reader (or a resume after kill -9) sees the old
file or the new one, never half of one. (The safe-set Parquet format is
``coordinator.safe_set.SafeSet``'s.)
"""

from __future__ import annotations

import hashlib
import io
import json
import os
from pathlib import Path
from typing import Callable

import pyarrow as pa
import pyarrow.parquet as pq

from scenarios.errors import CampaignError

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


def read_json(path: Path, required=(), missing: str | None = None) -> dict:
    """A JSON object this tool wrote, holding at least the keys ``required``; a missing,
    damaged or foreign file is a one-line CampaignError naming it (``missing``: the
    message when there is no file)."""
    path = Path(path)
    try:
        data = json.loads(path.read_bytes().decode("utf-8"))  # what this tool writes
    except FileNotFoundError:
        raise CampaignError(missing or f"{path}: missing") from None
    except IsADirectoryError:
        raise CampaignError(f"{path}: a directory, not a file of this tool") from None
    except (ValueError, RecursionError) as exc:  # UnicodeDecodeError and JSONDecodeError are ValueErrors
        raise CampaignError(f"{path}: not valid JSON (damaged? {type(exc).__name__}: {exc})") from None
    except OSError as exc:
        raise CampaignError(f"{path}: cannot be read ({exc.strerror or type(exc).__name__})") from None
    if not isinstance(data, dict):
        raise CampaignError(f"{path}: holds a JSON {type(data).__name__}, not the object this tool wrote (damaged?)")
    absent = [key for key in required if key not in data]
    if absent:
        raise CampaignError(f"{path}: lacks {', '.join(map(repr, absent))} (damaged?)")
    return data


def sha256_file(path: Path) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def write_table(path: Path, table: pa.Table) -> None:
    atomic_write(path, lambda fh: pq.write_table(table, fh))
