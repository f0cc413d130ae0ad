"""What each Ray actor's coverage mirror lacks, as the message a chunk carries to it.

A chunk's runs are screened on its actor against a mirror of the coverage
(coordinator/coverage.py). With each chunk goes what that mirror lacks: nothing (no
screen), a fixed screen's object ref (validation's domain check), a whole snapshot (a new
or restarted actor, or another coverage), or the changes since the version the actor was
last sent (small blocks inside the call, large ones put in the object store once and
shared by every actor that needs the same range). farm/ray_runtime/actor.py applies it.
"""

from __future__ import annotations

import numpy as np

from coordinator.coverage import Coverage, Reset
from farm.ray_runtime.packing import pack

INLINE_BYTES = 1 << 16  # change blocks up to this size travel inside the task call


def _nbytes(changes) -> int:
    """Array bytes of logged coverage changes (a whole-coverage Reset counts as large)."""
    total = 0
    for _, _, change in changes:
        if isinstance(change, Reset):
            return INLINE_BYTES + 1
        total += sum(v.nbytes for v in vars(change).values() if isinstance(v, np.ndarray))
    return total


class Mirrors:
    """Per actor slot of ``pool`` (farm/ray_runtime/pool.py: ``synced``, the version last sent;
    ``confirmed``, the version a returned chunk showed it had), the messages to send."""

    def __init__(self, ray, pool):
        self.ray = ray
        self.pool = pool
        self._blocks: dict[tuple, object] = {}  # (coverage id, from seq, to seq) -> ref
        self._static: dict[int, object] = {}  # id(screen) -> ref of a fixed screen
        self._snapshot: tuple = (None, None)  # (coverage id, epoch, seq), ref of its state
        self._since_trim = 0  # change messages since the coverage's log was last trimmed

    def message(self, actor: int, screen, fresh: bool = False):
        """What actor ``actor`` needs to screen a chunk against ``screen`` (``fresh``: it lost its mirror)."""
        if screen is None:
            return ("none", None, 0)
        if not isinstance(screen, Coverage):
            key = id(screen)
            if key not in self._static:
                self._static = {key: self.ray.put(screen)}
            return ("static", self._static[key], 0)
        screen.start_log()
        now = (id(screen), screen.epoch, screen.seq)
        slot = self.pool.slots[actor]
        sent = slot.synced
        slot.synced = now
        if fresh or sent is None or sent[:2] != now[:2]:
            if self._snapshot[0] != now:
                self._snapshot = (now, self.ray.put(screen.state()))
            return ("snapshot", self._snapshot[1], 0)
        if sent[2] == now[2]:
            return ("changes", [], sent[2])
        key = (id(screen), sent[2], now[2])
        if key not in self._blocks:
            self._blocks = {k: v for k, v in self._blocks.items() if k[2] == now[2]}  # older ranges are done
            changes = screen.changes_since(sent[2])
            # a small block goes inside the call, packed (Ray inlines it; a put costs the
            # driver ~1 ms), a large one once into the object store for every actor that needs it
            self._blocks[key] = pack(changes) if _nbytes(changes) <= INLINE_BYTES else self.ray.put(changes)
        self._since_trim += 1
        if self._since_trim >= len(self.pool.slots):  # a look at every actor: about once a wave
            self._trim(screen)
            self._since_trim = 0
        return ("changes", [self._blocks[key]], sent[2])

    def _trim(self, screen: Coverage) -> None:
        """Forget the changes every actor that was sent this coverage has applied. An
        actor never sent it gets a snapshot, not changes, so it holds nothing back: with
        fewer chunks in flight than workers the actors past the last are never used, and
        waiting for them kept every change of the campaign."""
        now = (id(screen), screen.epoch)
        slots = self.pool.slots
        holding = [s.confirmed for s in slots if s.synced is not None and s.synced[:2] == now]
        if holding and all(c is not None and c[:2] == now for c in holding):
            screen.trim_log(min(c[2] for c in holding))
