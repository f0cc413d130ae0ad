"""A campaign directory: what this tool writes, and nothing of anyone else's.

    DIR/.scenario-farm.json   the marker: this tool wrote DIR (kind, format version)
    DIR/.lock                 an advisory lock held by the process working in DIR (the
                              kernel releases it on exit, kill -9 included); it names
                              that process: its pid, and its host's name
    DIR/config.toml           the config as given (frozen copy)
    DIR/config.json           the normalized config with its hash
    DIR/checkpoint.npz, DIR/checkpoint/   the checkpoint (farm/directory/journal.py)
    DIR/ledger/segment-NNNNNN.parquet     committed runs, appended in segments
    DIR/status.json           live status (farm/reports/status.py)
    DIR/safe_set.parquet, summary.json, plots/, recordings/, report.html

``--force`` replaces only a directory with the marker; a second process is refused
with the lock holder's pid; temp files of dead writers are removed when a campaign is
opened again.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import re
import shutil
import socket
import time
import warnings
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from coordinator.driver.commit_log import CommitLog
from farm import config as config_mod, lazy
from farm.directory.files import TEMP_MARK, atomic_write, read_json, sha256_file, write_json
from scenarios.base import OUTCOME_NAMES
from scenarios.errors import CampaignError
from scenarios.version import __version__

MARKER = ".scenario-farm.json"
LOCK = ".lock"
DIRECTORY_FORMAT = 2
SEGMENT = re.compile(r"segment-(\d{6})\.parquet$")

__all__ = ["CampaignDir", "CampaignError", "Ledger", "read_ledger"]


class CampaignDir:
    """A directory this tool writes, locked while a process works in it."""

    def __init__(self, path):
        self.path = Path(path)
        self._lock_fd: int | None = None

    # -- opening ---------------------------------------------------------------------------
    def marker(self) -> dict | None:
        try:
            data = json.loads((self.path / MARKER).read_text())
            return data if isinstance(data, dict) else None
        except (OSError, ValueError):
            return None

    def check_writable(self) -> None:
        """Refuse, before any work, a path that cannot become a campaign directory."""
        p = self.path
        if p.is_symlink() and not p.exists():  # else mkdir says "File exists" of a name that leads nowhere
            try:
                os.stat(p)
                how = "dangles"
            except OSError as exc:
                how = "loops" if exc.errno == errno.ELOOP else "dangles"
            raise CampaignError(f"{p}: a symlink that {how} (to {os.readlink(p)}); choose another --out or fix "
                                f"the link")
        if p.exists() and not p.is_dir():
            raise CampaignError(f"{p}: exists and is not a directory")
        parent = p if p.exists() else next((a for a in p.parents if a.exists()), Path("."))
        if not os.access(parent, os.W_OK | os.X_OK):
            raise CampaignError(f"{parent}: not writable; choose another --out")

    def create(self, kind: str, *, force: bool) -> None:
        """A fresh campaign directory. A non-empty path is refused, unless ``force`` and
        this tool wrote it (marker present): then it is replaced."""
        self.check_writable()
        p = self.path
        if p.exists() and any(p.iterdir()):
            if not force:
                raise CampaignError(f"{p}: directory is not empty; pass --resume to continue the campaign in it "
                                    f"or --force to replace it")
            if self.marker() is None:
                raise CampaignError(f"{p}: not a directory this tool wrote (no {MARKER}); refusing to replace it "
                                    f"with --force")
            self.lock()  # not while another process works there
            for child in p.iterdir():
                if child.name != LOCK:
                    shutil.rmtree(child) if child.is_dir() and not child.is_symlink() else child.unlink()
        else:
            try:
                p.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise CampaignError(f"{p}: cannot create the directory ({exc.strerror})") from None
            self.lock()
        write_json(p / MARKER, {"tool": "scenario-farm", "kind": kind, "format": DIRECTORY_FORMAT,
                                "scenario_farm_version": __version__, "created": time.time()})

    def open(self, kind: str | None = None) -> dict:
        """An existing campaign directory, locked; returns its marker."""
        p = self.path
        if not p.is_dir():
            raise CampaignError(f"{p}: not a campaign directory ({'no such directory' if not p.exists() else 'a file'})")
        marker = self.marker()
        if marker is None:
            raise CampaignError(f"{p}: not a campaign directory (no {MARKER})")
        if marker.get("format") != DIRECTORY_FORMAT:
            raise CampaignError(f"{p}: written in directory format {marker.get('format')} by scenario-farm "
                                f"{marker.get('scenario_farm_version')}; this is format {DIRECTORY_FORMAT}")
        if kind is not None and marker.get("kind") != kind:
            raise CampaignError(f"{p}: a {marker.get('kind')} directory, not a {kind} campaign")
        return marker

    # -- the lock ---------------------------------------------------------------------------
    def lock(self, announce: bool = True) -> None:
        """Hold DIR/.lock for this process's lifetime; refuse if another holds it.
        ``announce``: write this pid into it now (else with ``announce()``, once the
        process is sure to work there: a refused resume leaves every file as it was)."""
        if self._lock_fd is not None:
            return
        fd = os.open(self.path / LOCK, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as exc:
            if exc.errno not in (errno.EAGAIN, errno.EACCES):
                raise
            pid, gone = _recorded_holder(fd)
            locker = _flock_locker(fd) if gone else None
            os.close(fd)
            if locker is not None:
                raise CampaignError(f"{self.path}: in use by pid {locker}, which has not written its pid there yet "
                                    "(starting, or reading its checkpoint); wait for it to finish or stop it "
                                    "first") from None
            if gone:
                raise CampaignError(f"{self.path}: locked, though pid {pid} that worked there has ended: a process "
                                    f"it started still holds {LOCK}; end that process, then try again") from None
            raise CampaignError(f"{self.path}: in use by pid {pid if pid is not None else '?'} (a campaign runs "
                                f"there); wait for it to finish or stop it first") from None
        self._lock_fd = fd
        if announce:
            self.announce()

    def announce(self) -> None:
        os.ftruncate(self._lock_fd, 0)
        os.pwrite(self._lock_fd, f"{os.getpid()}\n{socket.gethostname()}\n".encode(), 0)

    def unlock(self) -> None:
        if self._lock_fd is not None:
            os.close(self._lock_fd)  # closing releases the flock
            self._lock_fd = None

    def holder(self) -> int | None:
        """The pid working in DIR now, or None (for `status`): None too when the lock is
        held but the pid it names has ended on this machine (a process it started, which
        inherited the lock, outlived it: nobody works there)."""
        try:
            fd = os.open(self.path / LOCK, os.O_RDONLY)
        except OSError:
            return None
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
            return None  # nobody holds it
        except OSError:
            pid, gone = _recorded_holder(fd)
            if gone:
                return _flock_locker(fd)
            return pid if pid is not None else -1
        finally:
            os.close(fd)

    # -- what a campaign directory holds ----------------------------------------------------
    def frozen_config(self):
        """The campaign's config as frozen when it started (``config.json``)."""
        path = self.path / "config.json"
        raw = read_json(path, ("config",), missing=f"{self.path}: not a campaign directory (no config.json)")["config"]
        absent = [f"[{name}]" for name in config_mod.result_sections() if isinstance(raw, dict) and name not in raw]
        if absent:  # else filled with defaults, it would pass for another config (a hash mismatch)
            raise CampaignError(f"{path}: the frozen config lacks its {', '.join(absent)} section"
                                f"{'s' if len(absent) > 1 else ''} (damaged or edited?); nothing was changed")
        try:
            with warnings.catch_warnings():
                # the start of the campaign warned of a value it changed (a checkpoint
                # interval below the minimum); reading the config again is no news
                warnings.simplefilter("ignore", config_mod.ConfigWarning)
                return config_mod.normalize(raw)
        except config_mod.ConfigError as exc:
            raise CampaignError(f"{path}: not a valid frozen config ({exc})") from None

    def freeze_config(self, cfg, text: str | None = None) -> None:
        """Keep the config as given (``config.toml``: ``text``, or the normalized config as
        TOML) and normalized with its hash (``config.json``)."""
        (self.path / "config.toml").write_text(text if text is not None else config_mod.to_toml(cfg))
        write_json(self.path / "config.json", {"config": cfg.model_dump(mode="json"),
                                               "config_hash": config_mod.config_hash(cfg),
                                               "scenario_farm_version": __version__})

    def nothing_started(self) -> bool:
        """No directory, an empty one, or one of ours killed before its config was frozen."""
        p = self.path
        if not p.exists():
            return True
        if not p.is_dir():
            return False
        names = {c.name for c in p.iterdir()} - {LOCK}
        return not names or (self.marker() is not None and "config.json" not in names
                             and "checkpoint.npz" not in names and "ledger" not in names)

    # -- housekeeping -------------------------------------------------------------------------
    def remove_stale_temp_files(self) -> list[Path]:
        """Temp files (".<name>.tmp-<pid>") of writers that are gone: a kill -9 or a full
        disk in the middle of a write. Call with the lock held."""
        removed = []
        for tmp in self.path.rglob(f"*{TEMP_MARK}*"):
            pid = tmp.name.rsplit(TEMP_MARK, 1)[-1]
            if not pid.isdigit() or int(pid) != os.getpid():
                tmp.unlink(missing_ok=True)
                removed.append(tmp)
        return removed


def _flock_locker(fd: int) -> int | None:
    """The live pid of this machine that took the flock on ``fd``'s file, where it is not
    the one the file names (a command locks before it writes its pid: a resume reading
    a large checkpoint holds the lock for minutes unnamed), from /proc/locks; None if
    unknown, or if that pid has ended (a process it started inherited the lock)."""
    st = os.fstat(fd)
    key = f"{os.major(st.st_dev):02x}:{os.minor(st.st_dev):02x}:{st.st_ino}"
    try:
        with open("/proc/locks") as f:
            lines = f.read().splitlines()
    except OSError:
        return None
    for line in lines:
        fields = line.split()
        if len(fields) > 5 and fields[1] == "FLOCK" and fields[5] == key and fields[4].isdigit():
            pid = int(fields[4])
            return pid if _running(pid) else None
    return None


def _running(pid: int) -> bool:
    """Is ``pid`` a process of this machine now (another user's counts)?"""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except OSError:  # another user's: alive
        pass
    return True


def _recorded_holder(fd: int) -> tuple[int | None, bool]:
    """(the pid a held lock names, whether that pid has ended). Only a pid of this
    machine (the host name beside it) is checked: another host's, or another PID
    namespace's, pid says nothing here."""
    pid, _, host = os.pread(fd, 320, 0).decode(errors="replace").partition("\n")
    if not pid.strip().isdigit():
        return None, False
    pid = int(pid)
    if host.strip() != socket.gethostname():
        return pid, False
    return pid, not _running(pid)


class Ledger:
    """Committed runs, and runs discarded unseen (``discarded``), as Parquet segments:
    sample_index, round, delta, one column per state variable (the start state), outcome,
    steps, margin (the run's smallest distance to a failure facet: negative for a failure),
    changed, counted, discarded, replacement. Each segment's
    sha256 goes into the checkpoint, so a changed or swapped segment is noticed."""

    def __init__(self, directory: Path, state_names):
        self.dir = Path(directory)
        self.state_names = list(state_names)
        self.digests: list[str] = []
        self.rows = 0

    @property
    def segments(self) -> int:
        return len(self.digests)

    def append(self, log: dict[str, np.ndarray] | None) -> None:
        if not log:
            return
        self.dir.mkdir(parents=True, exist_ok=True)
        cols = {"sample_index": log["sample_index"], "round": log["round"], "delta": log["delta"]}
        for i, name in enumerate(self.state_names):
            cols[name] = log["start"][:, i]
        # the names taken by code from a 3-entry dictionary: Arrow builds a string column
        # from a numpy array of Python-sized strings one element at a time
        names = pa.array([OUTCOME_NAMES[o] for o in range(1, 4)])
        codes = pa.array(np.asarray(log["outcome"], dtype=np.int8) - 1)
        cols["outcome"] = pa.DictionaryArray.from_arrays(codes, names).cast(pa.string())
        cols.update(steps=log["steps"], margin=log["margin"], changed=log["changed"], counted=log["counted"],
                    discarded=log["kind"] == CommitLog.DISCARDED, replacement=log["kind"] == CommitLog.REPLACEMENT)
        path = self.dir / f"segment-{self.segments:06d}.parquet"
        atomic_write(path, lambda fh: pq.write_table(pa.table(cols), fh))
        self.digests.append(sha256_file(path))
        self.rows += len(log["sample_index"])

    def verify_and_trim(self, digests: list[str], rows: int) -> None:
        """On resume: the segments the checkpoint names must be there, unchanged, and hold
        ``rows`` rows; later segments are an uncheckpointed tail and are removed."""
        found = 0
        for i, digest in enumerate(digests):
            path = self.dir / f"segment-{i:06d}.parquet"
            try:
                actual = sha256_file(path)
                found += pq.ParquetFile(path).metadata.num_rows
            except FileNotFoundError:
                raise CampaignError(f"{path}: ledger segment missing; the checkpoint needs it") from None
            except (pa.ArrowInvalid, OSError) as exc:
                raise CampaignError(f"{path}: ledger segment is corrupt ({exc}); nothing was changed") from None
            if actual != digest:
                raise CampaignError(f"{path}: ledger segment differs from the one checkpointed (sha256 "
                                    f"{actual[:12]}..., expected {digest[:12]}...); nothing was changed")
        if found != rows:
            raise CampaignError(f"{self.dir}: ledger holds {found} rows in its first {len(digests)} segments, the "
                                f"checkpoint expects {rows}; nothing was changed")
        if self.dir.exists():
            for path in self.dir.iterdir():
                m = SEGMENT.search(path.name)
                if m and int(m.group(1)) >= len(digests):
                    path.unlink()
        recordings = self.dir.parent / "recordings"
        if recordings.exists():  # recordings flushed with a later, lost checkpoint
            for path in recordings.glob("runs-*.mcap"):
                stem = path.stem.split("-")[-1]
                if stem.isdigit() and int(stem) >= len(digests):
                    path.unlink()
        self.digests, self.rows = list(digests), rows


def read_ledger(directory: Path, columns=None, filter=None) -> pa.Table:
    """The runs of DIR/ledger (committed, and discarded unseen), every segment, as one table (``columns`` and a
    pyarrow.dataset ``filter`` as ``Dataset.to_table`` takes them); a missing ledger or a
    damaged segment is a one-line CampaignError naming it."""
    ds = lazy.pyarrow_dataset
    ledger = Path(directory) / "ledger"
    paths = sorted(str(p) for p in ledger.glob("segment-*.parquet"))
    if not paths:
        raise CampaignError(f"{ledger}: no ledger segments (removed?); the campaign's committed runs are gone")
    try:
        return ds.dataset(paths, format="parquet").to_table(columns=columns, filter=filter)
    except (pa.ArrowException, OSError) as exc:
        for path in paths:  # name the segment at fault
            try:
                pq.ParquetFile(path).schema_arrow
            except (pa.ArrowException, OSError) as bad:
                raise CampaignError(f"{path}: ledger segment is damaged ({' '.join(str(bad).split())})") from None
        raise CampaignError(f"{ledger}: the ledger segments do not read as one table (damaged or mixed? "
                            f"{' '.join(str(exc).split())})") from None
