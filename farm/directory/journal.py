"""Checkpoints that grow with what changed, not with the campaign.

The state to save is named numpy arrays. Arrays the algorithm declares append-only
(points, graph parents, the replay buffer: they only gain rows between resets) are
written as journal segments, ``checkpoint/segment-NNNNNN.npz``, each holding only the
rows added since the previous checkpoint; everything else (alive flags, scalars, the
draws in flight) goes whole into ``checkpoint.npz``, which also lists the segments with
their sha256. A checkpoint is: new segment (atomic), then checkpoint.npz (atomic), then
removal of segments it no longer lists. A kill -9 at any moment leaves the previous
checkpoint.npz and every segment it lists intact; unlisted segments are debris, removed
when the campaign is opened again. numpy arrays only, loaded with allow_pickle=False.
"""

from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path

import numpy as np

from farm.directory.files import atomic_write, sha256_file
from farm.directory.storage import CampaignError
from scenarios.version import __version__

CHECKPOINT_FORMAT = 3  # 3: coupled counting (replacements, the stable sampler)
SEGMENT = re.compile(r"segment-(\d{6})\.npz$")
META_KEYS = ("epoch", "journal", "append_only", "shapes", "dtypes")  # what reading a checkpoint needs


def _npz_bytes(arrays: dict[str, np.ndarray]):
    def write(fh):
        np.savez(fh, **arrays)

    return write


class Journal:
    """The checkpoint of one campaign part: ``DIR/checkpoint.npz`` + ``DIR/checkpoint/``."""

    def __init__(self, directory: Path):
        self.dir = Path(directory)
        self.main = self.dir / "checkpoint.npz"
        self.segment_dir = self.dir / "checkpoint"
        self.segments: list[dict] = []  # {"name", "sha256", "rows": {array: [start, stop]}}
        self.saved_rows: dict[str, int] = {}  # append-only array -> rows saved so far
        self.epoch: int | None = None

    # -- saving -----------------------------------------------------------------------------
    def save(self, arrays: dict[str, np.ndarray], append_only, epoch: int, meta: dict) -> None:
        if epoch != self.epoch:  # the append-only arrays were reset: start a new journal
            obsolete, self.segments, self.saved_rows = self.segments, [], {}
        else:
            obsolete = []
        tail = {}
        rows = {}
        for name in append_only:
            if name not in arrays:
                continue
            array = arrays[name]
            start = self.saved_rows.get(name, 0)
            if len(array) < start:
                raise ValueError(f"checkpoint: append-only array {name} shrank from {start} to {len(array)} rows")
            if len(array) > start:
                tail[name] = np.ascontiguousarray(array[start:])
                rows[name] = [start, len(array)]
        if tail:
            self.segment_dir.mkdir(parents=True, exist_ok=True)
            name = f"segment-{self._next_number():06d}.npz"
            path = self.segment_dir / name
            atomic_write(path, _npz_bytes(tail))
            self.segments.append({"name": name, "sha256": sha256_file(path), "rows": rows})
        whole = {k: v for k, v in arrays.items() if k not in append_only}
        meta = {**meta, "format": CHECKPOINT_FORMAT, "scenario_farm_version": __version__, "epoch": epoch,
                "journal": self.segments, "append_only": sorted(n for n in append_only if n in arrays),
                "shapes": {n: list(arrays[n].shape[1:]) for n in append_only if n in arrays},
                "dtypes": {n: arrays[n].dtype.str for n in append_only if n in arrays},
                # the whole arrays' shapes and dtypes, so that a damaged or replaced one is refused on
                # reading (a wrong-shaped alive flag or cell size was accepted, and made a resume crawl)
                "whole": {n: [list(v.shape), v.dtype.str] for n, v in whole.items()}}
        whole["__meta__"] = np.frombuffer(json.dumps(meta).encode(), dtype=np.uint8)
        atomic_write(self.main, _npz_bytes(whole))
        for name in append_only:
            if name in arrays:
                self.saved_rows[name] = len(arrays[name])
        self.epoch = epoch
        for segment in obsolete:
            (self.segment_dir / segment["name"]).unlink(missing_ok=True)

    def _next_number(self) -> int:
        used = [int(SEGMENT.search(s["name"]).group(1)) for s in self.segments]
        if self.segment_dir.exists():
            used += [int(m.group(1)) for p in self.segment_dir.iterdir() if (m := SEGMENT.search(p.name))]
        return max(used, default=-1) + 1

    # -- loading ------------------------------------------------------------------------------
    def exists(self) -> bool:
        return self.main.exists()

    def size_bytes(self) -> int:
        """Bytes on disk: checkpoint.npz and its segments (what a restore reads, about)."""
        files = [self.main, *(p for p in self.segment_dir.glob("*") if SEGMENT.search(p.name))] \
            if self.segment_dir.is_dir() else [self.main]
        return sum(f.stat().st_size for f in files if f.is_file())

    def load(self) -> tuple[dict[str, np.ndarray], dict]:
        """The saved arrays (append-only ones reassembled) and the metadata, for the
        campaign that owns the checkpoint and goes on writing it: checks every segment's
        sha256 and removes segments the checkpoint does not list."""
        arrays, meta = self.read()
        self.segments = list(meta["journal"])
        self.saved_rows = {name: len(arrays[name]) for name in meta["append_only"]}
        self.epoch = meta["epoch"]
        self._remove_unlisted()
        return arrays, meta

    def read(self, names=None) -> tuple[dict[str, np.ndarray], dict]:
        """The saved arrays (only ``names``, those saved, if given) and the metadata,
        changing nothing on disk: for readers (plots, exports, replay), which must not
        remove a segment a running campaign has just written and not listed yet, and
        need not load a certified campaign's certificates (the bulk of its state) to draw its boxes.
        Checks the sha256 of every segment it reads."""
        wanted = None if names is None else set(names)
        arrays = _read_npz(self.main, None if wanted is None else wanted | {"__meta__"})
        try:
            meta = json.loads(arrays.pop("__meta__").tobytes().decode())
        except (KeyError, ValueError) as exc:
            raise CampaignError(f"{self.main}: checkpoint has no readable metadata ({exc}); nothing was changed") \
                from None
        if not isinstance(meta, dict) or meta.get("format") != CHECKPOINT_FORMAT:
            raise CampaignError(f"{self.main}: checkpoint format {meta.get('format') if isinstance(meta, dict) else '?'}"
                                f" is not {CHECKPOINT_FORMAT}; nothing was changed")
        missing = [key for key in META_KEYS if key not in meta]
        if missing:
            raise CampaignError(f"{self.main}: checkpoint metadata lacks {', '.join(map(repr, missing))} (damaged?); "
                                f"nothing was changed")
        _check_whole(self.main, arrays, meta.get("whole"))  # absent: written before it was recorded
        try:
            return arrays | self._journalled(meta, wanted), meta
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise CampaignError(f"{self.main}: checkpoint metadata is damaged ({type(exc).__name__}: {exc}); nothing "
                                f"was changed") from None

    def _journalled(self, meta: dict, wanted: set | None) -> dict[str, np.ndarray]:
        """The append-only arrays the metadata lists, reassembled from their segments."""
        arrays = {}
        journalled = [n for n in meta["append_only"] if wanted is None or n in wanted]
        parts: dict[str, list[np.ndarray]] = {name: [] for name in journalled}
        for segment in meta["journal"]:
            rows = {n: r for n, r in segment["rows"].items() if n in parts}
            if not rows:
                continue
            path = self.segment_dir / segment["name"]
            if not path.exists():
                raise CampaignError(f"{path}: checkpoint segment missing; nothing was changed")
            if sha256_file(path) != segment["sha256"]:
                raise CampaignError(f"{path}: checkpoint segment differs from the one written (sha256 mismatch); "
                                    f"nothing was changed")
            data = _read_npz(path, set(rows))
            for name, (start, stop) in rows.items():
                if name not in data or len(data[name]) != stop - start:
                    raise CampaignError(f"{path}: checkpoint segment lacks rows {start}..{stop} of {name}")
                parts[name].append(data[name])
        for name in journalled:
            shape, dtype = meta["shapes"][name], np.dtype(meta["dtypes"][name])
            arrays[name] = np.concatenate(parts[name]) if parts[name] else np.empty((0, *shape), dtype=dtype)
        return arrays

    def _remove_unlisted(self) -> None:
        listed = {s["name"] for s in self.segments}
        if self.segment_dir.exists():
            for path in self.segment_dir.iterdir():
                if SEGMENT.search(path.name) and path.name not in listed:
                    path.unlink()


def _check_whole(path: Path, arrays: dict[str, np.ndarray], written: dict | None) -> None:
    """Every array of ``checkpoint.npz`` has the shape and dtype it was written with."""
    if written is None:
        return
    if not isinstance(written, dict):
        raise CampaignError(f"{path}: checkpoint metadata is damaged (whole is not a table); nothing was changed")
    for name, array in arrays.items():
        want = written.get(name)
        if want is None or [list(array.shape), array.dtype.str] != list(want):
            what = "was not written" if want is None else f"was written as shape {tuple(want[0])} {want[1]}"
            raise CampaignError(f"{path}: checkpoint array {name!r} has shape {array.shape} {array.dtype.str} but "
                                f"{what} (damaged?); nothing was changed")


def _read_npz(path: Path, names=None) -> dict[str, np.ndarray]:
    """The arrays of an .npz (only ``names``, those present, if given: the others are
    not read)."""
    try:
        with np.load(path, allow_pickle=False) as data:
            return {k: data[k] for k in data.files if names is None or k in names}
    except FileNotFoundError:
        raise CampaignError(f"{path}: no checkpoint") from None
    except (zipfile.BadZipFile, ValueError, OSError, EOFError) as exc:
        raise CampaignError(f"{path}: checkpoint is truncated or corrupt ({exc}); nothing was changed") from None

