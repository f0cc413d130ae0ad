"""A campaign directory: frozen config, checkpoint, run ledger, results.

    DIR/config.toml           the config as given (frozen copy)
    DIR/config.json           the normalized config with its hash
    DIR/checkpoint.npz        algorithm + driver state: numpy arrays only (no pickle),
                              written aside, fsynced, then os.replace'd
    DIR/ledger/segment-NNNNNN.parquet   committed runs, appended in segments
    DIR/status.json           live status (pid, heartbeat, counters) for `status`
    DIR/safe_set.parquet, summary.json, plots/, recordings/

The checkpoint names how many ledger segments belong to it; segments written after the
last checkpoint are the uncommitted tail of a killed process and are discarded on resume.
"""

from __future__ import annotations

import io
import json
import os
import re
import time
import zipfile
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from scenarios.version import __version__
from farm.files import atomic_write_bytes, write_json

CHECKPOINT_FORMAT = 1
SEGMENT = re.compile(r"segment-(\d{6})\.parquet$")


class CampaignError(RuntimeError):
    """A campaign directory that cannot be used as asked (printed as one line, exit 2)."""


def save_checkpoint(path: Path, arrays: dict[str, np.ndarray], meta: dict) -> None:
    meta = {**meta, "format": CHECKPOINT_FORMAT, "scenario_farm_version": __version__}
    payload = dict(arrays)
    payload["__meta__"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
    buf = io.BytesIO()
    np.savez(buf, **payload)
    atomic_write_bytes(Path(path), buf.getvalue())


def load_checkpoint(path: Path) -> tuple[dict[str, np.ndarray], dict]:
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {k: data[k] for k in data.files}
    except FileNotFoundError:
        raise CampaignError(f"{path}: no checkpoint") from None
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
        raise CampaignError(f"{path}: checkpoint is truncated or corrupt ({exc}); nothing was changed") from None
    try:
        meta = json.loads(arrays.pop("__meta__").tobytes().decode())
    except (KeyError, ValueError) as exc:
        raise CampaignError(f"{path}: checkpoint has no readable metadata ({exc}); nothing was changed") from None
    if meta.get("format") != CHECKPOINT_FORMAT:
        raise CampaignError(f"{path}: checkpoint format {meta.get('format')} is not {CHECKPOINT_FORMAT}")
    return arrays, meta


class Ledger:
    """Committed runs as Parquet segments: sample_index, round, delta, one column per
    state variable (the start state), outcome, steps, changed, counted."""

    def __init__(self, directory: Path, state_names):
        self.dir = Path(directory)
        self.state_names = list(state_names)
        self.segments = 0
        self.rows = 0

    def append(self, log: dict[str, np.ndarray] | None) -> None:
        if not log:
            return
        from scenarios.base import OUTCOME_NAMES

        self.dir.mkdir(parents=True, exist_ok=True)
        cols = {"sample_index": log["sample_index"], "round": log["round"], "delta": log["delta"]}
        for i, name in enumerate(self.state_names):
            cols[name] = log["start"][:, i]
        names = np.array([OUTCOME_NAMES[o] for o in range(1, 4)])
        cols["outcome"] = names[log["outcome"] - 1]
        cols.update(steps=log["steps"], changed=log["changed"], counted=log["counted"])
        table = pa.table(cols)
        path = self.dir / f"segment-{self.segments:06d}.parquet"
        tmp = path.with_name("." + path.name + ".tmp")
        pq.write_table(table, tmp)
        with open(tmp, "rb") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, path)
        self.segments += 1
        self.rows += len(log["sample_index"])

    def verify_and_trim(self, segments: int, rows: int) -> None:
        """On resume: the first ``segments`` must be intact and hold ``rows`` rows; later
        segments are an uncheckpointed tail and are removed."""
        found = 0
        for i in range(segments):
            path = self.dir / f"segment-{i:06d}.parquet"
            try:
                found += pq.ParquetFile(path).metadata.num_rows
            except FileNotFoundError:
                raise CampaignError(f"{path}: ledger segment missing; the checkpoint needs it") from None
            except (pa.ArrowInvalid, OSError) as exc:
                raise CampaignError(f"{path}: ledger segment is corrupt ({exc}); nothing was changed") from None
        if found != rows:
            raise CampaignError(f"{self.dir}: ledger holds {found} rows in its first {segments} segments, the "
                                f"checkpoint expects {rows}; nothing was changed")
        if self.dir.exists():
            for path in self.dir.iterdir():
                m = SEGMENT.search(path.name)
                if (m and int(m.group(1)) >= segments) or path.name.endswith(".tmp"):
                    path.unlink()
        recordings = self.dir.parent / "recordings"
        if recordings.exists():  # recordings flushed with a later, lost checkpoint
            for path in recordings.glob("runs-*.mcap"):
                if int(path.stem.split("-")[1]) >= segments:
                    path.unlink()
        self.segments, self.rows = segments, rows


def write_status(directory: Path, status: dict) -> None:
    write_json(Path(directory) / "status.json", {**status, "pid": os.getpid(), "heartbeat": time.time()})


def read_status(directory: Path) -> dict | None:
    path = Path(directory) / "status.json"
    try:
        return json.loads(path.read_text())
    except (FileNotFoundError, ValueError):
        return None


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True
