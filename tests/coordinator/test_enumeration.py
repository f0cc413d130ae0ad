"""Deterministic certification's passes (coordinator/enumeration.py) against the plain
computation they replace: scan every centre at each batch, count every uncertified
centre at each chunk. Same centres drawn, same end, through inserts, prunes (lost
checked centres), short batches, new passes and a checkpoint round trip."""

import numpy as np
import pytest

from coordinator.algorithm import EmptySetError
from coordinator.checked_centres import CheckedCentres
from coordinator.enumeration import Enumeration
from coordinator.spatial import PointIndex


class Plain:
    """The computation as it was (one scan of every centre per call)."""

    def __init__(self):
        self.drawn = np.zeros(0, dtype=bool)

    def next(self, vertices, checked, k):
        alive = vertices.alive_ids()
        if len(alive) == 0:
            raise EmptySetError("empty")
        if len(self.drawn) < vertices.count:
            self.drawn = np.concatenate([self.drawn, np.zeros(vertices.count - len(self.drawn), bool)])
        open_ = ~checked.certified(vertices.count)[alive]
        pending = alive[open_ & ~self.drawn[alive]]
        if len(pending) == 0:
            self.drawn[:] = False
            pending = alive[open_] if open_.any() else alive
        chosen = pending[:k]
        self.drawn[chosen] = True
        return chosen

    def record(self, vertices, checked, starts, offsets, witnesses):
        before = checked.certified(vertices.count)
        checked.add(starts, offsets, witnesses)
        missing = int((vertices.alive[: vertices.count] & ~before).sum())
        fresh = np.zeros(len(starts), dtype=bool)
        first = np.unique(starts, return_index=True)[1]
        fresh[first] = ~before[starts[first]]
        reached = np.flatnonzero(np.cumsum(fresh) >= missing) if missing else np.array([0])
        return int(reached[0]) if len(reached) else -1


def _world(rng, n):
    vertices = PointIndex(2, 1.0, np.zeros(2))
    vertices.insert(rng.uniform(0, 50, size=(n, 2)))
    return vertices, CheckedCentres()


@pytest.mark.parametrize("seed", range(5))
def test_passes_draw_and_end_as_the_plain_scan(seed, monkeypatch):
    from coordinator import enumeration

    monkeypatch.setattr(enumeration, "SCAN_WINDOW", 64)  # many cursor steps on a small set
    rng = np.random.default_rng(seed)
    worlds = [_world(np.random.default_rng(seed), 600) for _ in range(2)]
    fast, plain = Enumeration(), Plain()
    ends = draws = 0
    last = np.zeros(0, dtype=np.int64)
    for step in range(300):
        op = rng.random()
        if op < 0.45:  # a batch
            k = int(rng.integers(1, 120))
            got = fast.next(*worlds[0], k)
            assert np.array_equal(got, plain.next(*worlds[1], k))
            draws += len(got)
            last = got
        elif op < 0.8:  # a chunk's quiet runs certify their (alive) start centres
            vertices = worlds[0][0]
            alive = vertices.alive_ids()
            drawn_alive = last[vertices.alive[last]]  # mostly the centres of the last batch, as runs are
            starts = np.concatenate([drawn_alive, rng.choice(alive, size=int(rng.integers(0, 20)))])
            if len(starts) == 0:
                continue
            counts = rng.integers(0, 8, len(starts))
            witnesses = rng.choice(alive, size=int(counts.sum()))
            offsets = np.concatenate([[0], np.cumsum(counts)])
            a = fast.record(*worlds[0], starts, offsets, witnesses)
            assert a == plain.record(*worlds[1], starts, offsets, witnesses)
            ends += a >= 0
        elif op < 0.95:  # a prune: centres die, checks naming them are lost
            alive = worlds[0][0].alive_ids()
            if rng.random() < 0.5:  # the last uncertified ones, sometimes: the end comes by a prune
                open_ = alive[~worlds[0][1].certified_at(alive)]
                alive = open_ if len(open_) else alive
            killed = rng.choice(alive, size=max(1, min(len(alive) - 50, int(rng.integers(1, 15)))), replace=False)
            fast.before_prune(*worlds[0], killed)
            for w, e in zip(worlds, (fast, plain)):
                w[0].kill(killed)
                reopened = w[1].invalidate(killed)
                if e is fast:
                    fast.reopened(reopened)
        else:  # new centres (an explore during certification)
            pts = rng.uniform(0, 50, size=(int(rng.integers(1, 30)), 2))
            for w in worlds:
                w[0].insert(pts)
        if step % 97 == 96:  # checkpoint and resume: the pass's drawn set survives
            fast = Enumeration(fast.drawn.copy())
    assert draws > 2000 and ends > 3  # passes restarted and the end was reached several times
