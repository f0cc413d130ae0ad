"""A worker's coverage mirror applies a stretch of logged inserts, kills and failures at
once (``Coverage.sync``); it must end exactly where applying them one by one ends: the
same witnesses for every query (they go into certificates), the same dense cell names,
counts, kill marker and per-change history."""

import numpy as np
import pytest

from coordinator.coverage import AddFailures, Coverage, Insert, Kill, Strict

DELTA = 0.5
LOWER, UPPER = np.zeros(2), np.full(2, 8.0)


def _points(rng, k):
    """Cell centres, many repeated (two centres at one cell exercise the renaming of a
    dense cell whose named centre dies), and some off-centre points."""
    cells = rng.integers(0, 40, size=k)  # 40 of the 256 cells: repeats are common
    pts = np.stack([cells // 16, cells % 16], axis=1) * 2 * DELTA + DELTA
    off = rng.random(k) < 0.3
    pts[off] = rng.uniform(0, 8, size=(int(off.sum()), 2))
    return pts


def _changes(rng, count):
    log, alive = [], 0
    for _ in range(count):
        kind = rng.choice(["insert", "kill", "fail", "strict"], p=[0.4, 0.35, 0.2, 0.05])
        if kind == "insert" or alive == 0:
            k = int(rng.integers(0, 6))
            log.append(Insert(_points(rng, k)))
            alive += k
        elif kind == "kill":
            log.append(Kill(rng.integers(0, alive, size=int(rng.integers(1, 4)))))
        elif kind == "fail":
            log.append(AddFailures(_points(rng, int(rng.integers(1, 3)))))
        else:
            log.append(Strict(bool(rng.integers(0, 2))))
    return log


def _same(a: Coverage, b: Coverage, rng) -> None:
    assert (a.seq, a.version, a.kill_seq, a.strict) == (b.seq, b.version, b.kill_seq, b.strict)
    va, vb = a.vertices, b.vertices
    assert va.count == vb.count and np.array_equal(va.alive[: va.count], vb.alive[: vb.count])
    assert np.array_equal(va._centre_point, vb._centre_point)
    assert np.array_equal(va._dense, vb._dense) and np.array_equal(va._others, vb._others)
    assert a.failures.count == b.failures.count
    queries = np.concatenate([rng.uniform(-0.5, 8.5, size=(400, 2)), _points(rng, 100)])
    assert np.array_equal(va.cover(queries, DELTA), vb.cover(queries, DELTA))
    assert np.array_equal(a.classify_states(queries)[1], b.classify_states(queries)[1])
    for seq in range(a.seq + 1):
        assert a.counts_at(seq) == b.counts_at(seq)


@pytest.mark.parametrize("seed", range(8))
def test_a_synced_stretch_ends_where_one_by_one_ends(seed):
    rng = np.random.default_rng(seed)
    coordinator = Coverage(2, DELTA, LOWER, bounds=(LOWER, UPPER))
    coordinator.start_log()
    mirror = Coverage.from_state(coordinator.state())
    stretches = 0
    for _ in range(12):  # the mirror catches up with a block of changes at a time
        for change in _changes(rng, int(rng.integers(1, 30))):
            coordinator.apply(change, coordinator.version + 1)
        block = coordinator.changes_since(mirror.seq)
        stretches += sum(1 for i in range(1, len(block))
                         if not isinstance(block[i][2], Strict) and not isinstance(block[i - 1][2], Strict))
        mirror.sync(block)
        _same(coordinator, mirror, rng)
    assert stretches > 50  # stretches of two and more were synced at once
