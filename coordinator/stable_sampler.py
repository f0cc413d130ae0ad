"""Start states drawn from each run's own stream, so that a change of state moves only
the draws it touches (coupled counting: shared/spec/scaling.md, algorithms.md point 3).

Run i's start is the first acceptable candidate of its start stream: candidate k is slot
``floor(u_k * cap)`` of the law's slot space (the vertex ids, or a table of the few ids a
sparse law draws from: ``TableLaw``; ``cap`` a power of two above the slot count: twice
the round's first count, doubled when the count outgrows it), acceptable if the law
accepts that slot with ``v_k``: the vertex it names exists, is alive and a candidate of
the law, and, for a weighted law (prioritized sampling, rho = alpha(d* - d)),
``v_k * bound < rho(slot)`` with ``bound`` at least the largest rho. Each accepted
candidate is exactly distributed as the law (a slot is accepted with probability
rho(slot) / (cap * bound) at every try); after ``MAX_TRIES`` rejections the run draws
directly from the law with one more uniform, so the draw is exact whatever the
acceptance rate.

A draw depends on the state only through the slots it examined. Each slot carries the
version of the last change that may have moved its acceptance (``stamp``): a kill, an
insert, a distance that fell. A change of the law as a whole (d*, the bound, the cap, a
switch between uniform and weighted, a new round) moves every draw (``everything``). So
``moved`` answers "is this draw still what its stream draws now?" without looking at
runs whose examined slots nothing touched; for a run whose examined slots a change did
touch, it asks the law again about those slots with the numbers the run drew for them
(kept with the draw): the draw stands iff every slot before the accepted one is still
rejected and the accepted one still accepted, and names the same vertex (a table's slot
can name another on a state restored from a copy). Only runs that examined more slots than
are kept, or drew directly, are flagged without that answer (drawn again to know).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Protocol

import numpy as np

from scenarios.streams import PURPOSE_START, RunStreams

MAX_TRIES = 64  # candidates a run examines before it draws directly from the law
# tries drawn at once for the runs still searching, growing: a dense law accepts within the
# first few, while a sparse one (a closing round's band, ~1 slot in 16) would otherwise take
# eight passes of the same dozen array operations for a handful of runs (a replacement is
# one run); tries past a run's first accepted one are drawn and never looked at
TRY_BLOCKS = (8, 16, 40)
assert sum(TRY_BLOCKS) == MAX_TRIES
# up to this many runs (a replacement, a few draws asked again) every try is drawn in one
# block: the blocks' dozen array operations each cost more than the tries they skip
SMALL_BATCH = 32
# examined slots kept per run (a run that examined more may move with any change): all of
# them, so that a sparse law (a closing round's band: ~1 slot in 16 accepted) still moves
# only the draws a change touched; results never depend on it, only what is re-drawn
TRACKED = MAX_TRIES


class Law(Protocol):
    """A sampling law over vertex ids, as the sampler needs it: over slots [0, count), each
    naming a vertex id (the id itself, or a table's entry: ``TableLaw``)."""

    count: int  # slots [0, count) exist
    bound: float  # >= the largest weight (1.0 for a uniform law)

    def accept(self, slots: np.ndarray, v: np.ndarray) -> np.ndarray:
        """(k,) bool: slot exists and is a candidate, and v * bound < weight(slot)."""

    def direct(self, u: np.ndarray) -> np.ndarray:
        """Vertex ids for uniform numbers u in [0, 1), exactly by the law."""

    def vertex(self, slots: np.ndarray) -> np.ndarray:
        """The vertex ids that accepted slots name."""


def _same(slots: np.ndarray) -> np.ndarray:
    return slots


@dataclass(frozen=True)
class UniformLaw:
    """Uniform over the vertices ``candidate(ids)`` accepts among ids [0, count)."""

    count: int
    candidate: Callable[[np.ndarray], np.ndarray]
    ids: Callable[[], np.ndarray]  # the candidate ids, in id order (for the direct draw)
    bound: float = 1.0
    vertex = staticmethod(_same)  # slot i is vertex id i

    def accept(self, slots: np.ndarray, v: np.ndarray) -> np.ndarray:
        ok = slots < self.count
        ok[ok] = self.candidate(slots[ok])
        return ok

    def direct(self, u: np.ndarray) -> np.ndarray:
        ids = self.ids()
        return ids[np.minimum((u * len(ids)).astype(np.int64), len(ids) - 1)]


@dataclass(frozen=True)
class WeightedLaw:
    """rho(id) = ``weight(ids)`` (zero for a non-candidate) over ids [0, count)."""

    count: int
    weight: Callable[[np.ndarray], np.ndarray]
    direct: Callable[[np.ndarray], np.ndarray]
    bound: float
    vertex = staticmethod(_same)  # slot i is vertex id i

    def accept(self, slots: np.ndarray, v: np.ndarray) -> np.ndarray:
        ok = slots < self.count
        ok[ok] = v[ok] * self.bound < self.weight(slots[ok])
        return ok


@dataclass(frozen=True)
class TableLaw:
    """Uniform over the vertices ``candidate`` accepts among those a table names: slot s
    is vertex ``table[s]``, each vertex in at most one slot. For a law whose candidates
    are a small share of the vertex ids (a closing round's edge), a slot space of their
    own: draws accept within a few tries, examine few slots (so few changes move them)
    and do not fall back to the direct draw, which every change moves."""

    table: np.ndarray  # (count,) vertex ids, -1 at a free slot
    candidate: Callable[[np.ndarray], np.ndarray]  # vertex ids -> bool
    bound: float = 1.0

    @property
    def count(self) -> int:
        return len(self.table)

    def accept(self, slots: np.ndarray, v: np.ndarray) -> np.ndarray:
        ok = slots < len(self.table)
        ok[ok] = self._listed(self.table[slots[ok]])
        return ok

    def direct(self, u: np.ndarray) -> np.ndarray:
        ids = self.table[self._listed(self.table)]
        return ids[np.minimum((u * len(ids)).astype(np.int64), len(ids) - 1)]

    def _listed(self, ids: np.ndarray) -> np.ndarray:
        ok = ids >= 0
        ok[ok] = self.candidate(ids[ok])
        return ok

    def vertex(self, slots: np.ndarray) -> np.ndarray:
        return self.table[slots]


def probabilities(law: Law) -> np.ndarray:
    """The probability the law gives each vertex id (a measurement: O(count)), up to the
    largest id a slot names."""
    slots = np.arange(law.count)
    if isinstance(law, WeightedLaw):
        w = np.asarray(law.weight(slots), dtype=float)
    else:
        w = law.accept(slots, np.zeros(len(slots))).astype(float)
    ids = law.vertex(slots)
    out = np.zeros(int(ids.max()) + 1 if len(ids) else 0)
    np.add.at(out, ids, w)
    return out / out.sum()


def total_variation(p: np.ndarray, q: np.ndarray) -> float:
    """TV(p, q) of two laws over vertex ids (the shorter one padded with zeros: ids added
    since). No coupling of a draw from p and one from q agrees with probability above
    1 - TV: a lower bound on the share of draws in flight that any exact sampler moves."""
    m = max(len(p), len(q))
    return 0.5 * float(np.abs(np.pad(p, (0, m - len(p))) - np.pad(q, (0, m - len(q)))).sum())


@dataclass
class Draws:
    """A batch of stable draws: per run its vertex id (its start), and what its stream
    draws now as far as known: that draw's id, the version it was last known at, the
    slots it examined (up to ``TRACKED``; a run that examined more, or drew directly, may
    move with any change) and the numbers it drew for them."""

    ids: np.ndarray  # (B,) vertex ids: the runs' starts
    versions: np.ndarray  # (B,) int64: the state version the current draw is known at (-1: unknown)
    slots: np.ndarray  # (B, TRACKED) int64: the slots the current draw examined, -1 past the last
    untracked: np.ndarray  # (B,) bool: examined more slots than tracked, or drew directly
    fixed: bool = False  # no change moves them (an enumeration's centres)
    vs: np.ndarray | None = None  # (B, TRACKED) the acceptance number drawn for each examined slot
    now: np.ndarray | None = None  # (B,) the current draw's vertex id (a start the set moved away from differs)

    def __post_init__(self):
        if self.vs is None:
            self.vs = np.zeros(self.slots.shape)
        if self.now is None:
            self.now = self.ids.copy()

    def __len__(self) -> int:
        return len(self.ids)

    def rows(self, rows) -> "Draws":
        """The draws of ``rows`` (an index array or a slice: views), as a batch of their own."""
        return Draws(self.ids[rows], self.versions[rows], self.slots[rows], self.untracked[rows], self.fixed,
                     self.vs[rows], self.now[rows])

    def current(self, row: int) -> "Draws | None":
        """Row ``row``'s current draw as a batch of one (copies), if known: None when its
        id names another start than the one drawn (coordinator/driver/exact.py)."""
        if self.now[row] < 0:
            return None
        one = self.rows([row])
        one.ids = one.now.copy()
        return one

    def span(self, lo: int, hi: int) -> "Draws":
        """The draws of rows ``lo:hi`` (views, no copy)."""
        return self.rows(slice(lo, hi))

    def track(self, rows: np.ndarray, fresh: "Draws") -> None:
        """Rows ``rows``' streams drawn again (``fresh``, one per row, in order): their
        current draws, in place; their starts stay."""
        self.versions[rows], self.now[rows] = fresh.versions, fresh.ids
        self.slots[rows], self.untracked[rows], self.vs[rows] = fresh.slots, fresh.untracked, fresh.vs

    @classmethod
    def fixed_at(cls, ids: np.ndarray, version: int) -> "Draws":
        """Draws no change can move (e.g. an enumeration's next centres)."""
        return cls(ids, np.full(len(ids), version, dtype=np.int64), np.full((len(ids), TRACKED), -1, dtype=np.int64),
                   np.zeros(len(ids), dtype=bool), fixed=True)

    @classmethod
    def unknown(cls, ids: np.ndarray, fixed: bool = False) -> "Draws":
        """Draws whose examined slots are not known (read back from a checkpoint): each
        is drawn again before it is used."""
        return cls(ids, np.full(len(ids), -1, dtype=np.int64), np.full((len(ids), TRACKED), -1, dtype=np.int64),
                   np.ones(len(ids), dtype=bool), fixed)


class StableSampler:
    """Draws keyed on each run's stream, and which draws a change may have moved."""

    def __init__(self):
        self.base = 1  # vertex ids when the round started
        self.cap = 0
        self.stamp = np.zeros(0, dtype=np.int64)  # per slot: last version that may have moved it
        self.everything = 0  # last version that may have moved every draw
        self.last = 0  # last version that may have moved any draw
        self.reborn = (np.iinfo(np.int64).max, -1)  # (first id, version) of ``forked``: ids from there were drawn again

    # -- what changed ----------------------------------------------------------------------
    def touch(self, ids: np.ndarray, version: int) -> None:
        """Changes at ``version`` may have moved the acceptance of slots ``ids``."""
        ids = np.asarray(ids, dtype=np.int64)
        if len(ids):
            self._grow(int(ids.max()) + 1)
            self.stamp[ids] = version
            self.last = max(self.last, version)

    def touch_all(self, version: int) -> None:
        """The law as a whole changed at ``version``: every draw may have moved."""
        self.everything = version
        self.last = max(self.last, version)

    def forked(self, left: "StableSampler", since: int, version: int, count: int) -> None:
        """This sampler's state was restored from a copy taken at version ``since``, with
        ``count`` vertex ids; ``left``, the sampler of the state left, went on from there:
        the slots its changes touched may accept otherwise here (stamped ``version``), all
        of them if it changed the law as a whole. A draw made on either state moves only if
        it examined one, or if it drew an id from ``count`` on: such an id names another
        centre here than there, though its slot may be accepted on both."""
        self.touch(np.flatnonzero(left.stamp > since), version)
        if left.everything > since:
            self.touch_all(version)
        self.last = max(self.last, version)
        self.reborn = (min(self.reborn[0], count), version)

    def restart(self, base: int, version: int) -> None:
        """A new round (or a new law for good, e.g. certification) with ``base`` vertex
        ids: the cap starts at twice that, room for the ids the round adds."""
        self.base = max(int(base), 1)
        self.cap = 0
        self.reborn = (np.iinfo(np.int64).max, -1)
        self.fit(base, version)

    def fit(self, count: int, version: int) -> None:
        """The cap for ``count`` vertex ids: the smallest power of two of at least twice
        the round's base and at least ``count`` (a function of the state alone, whenever
        it is asked); a new cap moves every draw."""
        cap = 1 << int(np.ceil(np.log2(max(2 * self.base, count, 2))))
        if cap != self.cap:
            self.cap = cap
            self.touch_all(version)

    # -- drawing -----------------------------------------------------------------------------
    def draw(self, streams: RunStreams, law: Law, version: int) -> Draws:
        """Each run's first acceptable candidate (or its direct draw after MAX_TRIES)."""
        b = len(streams)
        ids = np.full(b, -1, dtype=np.int64)
        tries = np.zeros(b, dtype=np.int64)  # candidates examined, the accepted one included
        slots = np.zeros((b, MAX_TRIES), dtype=np.int64)
        vs = np.zeros((b, MAX_TRIES))
        searching = np.arange(b)
        first = 0
        for k in TRY_BLOCKS if b > SMALL_BATCH else (MAX_TRIES,):
            if len(searching) == 0:
                break
            uv = streams.uniform_grid(range(first + 1, first + k + 1), PURPOSE_START, 2, searching)
            u, v = uv[:, :, 0], uv[:, :, 1]
            cand = np.minimum((u * self.cap).astype(np.int64), self.cap - 1)
            ok = law.accept(cand.ravel(), v.ravel()).reshape(-1, k)
            slots[searching, first : first + k] = cand
            vs[searching, first : first + k] = v
            found = ok.any(axis=1)
            at = np.argmax(ok, axis=1)
            hit = searching[found]
            ids[hit] = law.vertex(cand[found, at[found]])
            tries[hit] = first + at[found] + 1
            tries[searching[~found]] = first + k
            searching = searching[~found]
            first += k
        untracked = tries > TRACKED
        if len(searching):
            untracked[searching] = True
            u = streams.subset(searching).uniform_at(np.full(len(searching), MAX_TRIES + 1, dtype=np.uint64),
                                                     PURPOSE_START, 0)
            ids[searching] = law.direct(u)
        examined = slots[:, :TRACKED]  # the batch's own arrays: views, no copies
        examined[np.arange(TRACKED)[None, :] >= tries[:, None]] = -1
        return Draws(ids, np.full(b, version, dtype=np.int64), examined, untracked, vs=vs[:, :TRACKED])

    def moved(self, draws: Draws, law: Law | None = None, version: int | None = None) -> np.ndarray:
        """(B,) bool: draws that a change since they were drawn may have moved (draw them
        again to know). With the current ``law`` (and its ``version``), a tracked draw whose
        examined slots a change touched is asked again (see the module docstring): flagged
        only if its accepted try changed (rarely, a later try finds the same id), and
        renewed (its version set to ``version``) if it stands. Without, or for an untracked
        draw, flagged."""
        if draws.fixed or len(draws) == 0 or int(draws.versions.min()) >= self.last:
            return np.zeros(len(draws), dtype=bool)  # nothing changed since any of them was drawn
        if len(draws) == 1:  # a replacement's draw: the same questions on scalars
            return np.array([self._moved_one(draws, law, version)])
        out = (draws.versions < self.everything) | (draws.untracked & (draws.versions < self.last))
        if self.reborn[1] >= 0:
            out |= (draws.versions < self.reborn[1]) & (draws.now >= self.reborn[0])
        # only the columns some draw examined: a dense law's draws examine a few of TRACKED
        column_max = draws.slots.max(axis=0)
        width = int(np.flatnonzero(column_max >= 0)[-1]) + 1 if column_max.max() >= 0 else 1
        slots = draws.slots[:, :width]
        self._grow(max(int(column_max.max()) + 1, 1))  # all -1 (drawn before a restore): one slot
        latest = np.where(slots >= 0, self.stamp[np.maximum(slots, 0)], -1).max(axis=1)
        touched = latest > draws.versions
        if law is not None:
            ask = np.flatnonzero(touched & ~out)
            if len(ask):
                stands = self._stands(draws, ask, law)
                touched[ask[stands]] = False
                if version is not None:
                    draws.versions[ask[stands]] = version
        return out | touched

    def _moved_one(self, draws: Draws, law: Law | None, version: int | None) -> bool:
        """``moved`` for a batch of one draw, known to be older than the last change."""
        drawn = int(draws.versions[0])
        if drawn < self.everything or draws.untracked[0]:
            return True
        if self.reborn[1] >= 0 and drawn < self.reborn[1] and draws.now[0] >= self.reborn[0]:
            return True
        slots = draws.slots[0]
        examined = int(np.count_nonzero(slots >= 0))  # a prefix of the tracked columns
        if examined == 0:
            return False
        slots = slots[:examined]
        self._grow(int(slots.max()) + 1)
        if int(self.stamp[slots].max()) <= drawn:
            return False
        if law is None:
            return True
        accepted = law.accept(slots, draws.vs[0, :examined])
        if not accepted[-1] or accepted[:-1].any() or not _names(law, slots[-1:], draws.now[:1])[0]:
            return True
        if version is not None:
            draws.versions[0] = version
        return False

    @staticmethod
    def _stands(draws: Draws, rows: np.ndarray, law: Law) -> np.ndarray:
        """(len(rows),) bool: tracked draws ``rows`` are still what their streams draw under
        ``law``: every examined slot before the last still rejected, the last still accepted."""
        slots, vs = draws.slots[rows], draws.vs[rows]
        examined = slots >= 0
        accepted = np.zeros(slots.shape, dtype=bool)
        accepted[examined] = law.accept(slots[examined], vs[examined])
        last = examined.sum(axis=1) - 1
        at = np.arange(len(rows))
        still = accepted[at, last]
        still[still] = _names(law, slots[at, last][still], draws.now[rows][still])
        accepted[at, last] = False
        return still & ~accepted.any(axis=1)

    # -- persistence ---------------------------------------------------------------------------
    def state(self) -> dict[str, np.ndarray]:
        return {"stable.base": np.array(self.base, dtype=np.int64)}

    def load_state(self, state: dict[str, np.ndarray], count: int, version: int) -> None:
        """The round's base as it was; every draw made before is unknown (stamps are not kept)."""
        self.base = int(state["stable.base"])
        self.stamp = np.zeros(0, dtype=np.int64)
        self.last = version
        self.cap = 0
        self.fit(count, version)

    def _grow(self, size: int) -> None:
        if size > len(self.stamp):
            grown = np.zeros(max(size, 2 * len(self.stamp), 1024), dtype=np.int64)
            grown[: len(self.stamp)] = self.stamp
            self.stamp = grown


def _names(law: Law, slots: np.ndarray, now: np.ndarray) -> np.ndarray:
    """Do accepted ``slots`` still name the vertices ``now`` their draws found there? A
    table's slot may name another vertex on the state a copy was restored to than on the
    state left (``forked``); a slot of the vertex ids always names itself. (A current draw
    known to name another start, ``now`` -1, is no run's start whatever it names.)"""
    return (law.vertex(slots) == now) | (now < 0)
