"""The committed-run log keeps per chunk what its rows share and gives back, at a flush,
the same columns row by row as the ledger has them."""

from types import SimpleNamespace

import numpy as np

from coordinator.driver.commit_log import CommitLog


def test_a_flush_gives_every_committed_row_with_its_chunk_values_and_empties_the_log():
    rng = np.random.default_rng(2)
    log, expected = CommitLog(), []
    for first, k, committed, rnd, delta in [(0, 6, 6, 0, 2.0), (6, 5, 3, 0, 2.0), (9, 4, 0, 1, 1.0),
                                           (9, 7, 7, 1, 1.0)]:
        chunk = SimpleNamespace(outcomes=rng.integers(0, 3, k), lengths=rng.integers(1, 50, k), margins=rng.normal(size=k))
        starts = rng.random((k, 2))
        changed, counted = rng.random(committed) < 0.3, rng.random(committed) < 0.6
        log.add(first, starts[:committed], chunk, np.arange(committed), rnd, delta, changed, counted)
        expected += [(first + r, rnd, delta, *starts[r], chunk.outcomes[r], chunk.lengths[r] - 1, chunk.margins[r],
                      changed[r], counted[r], 0) for r in range(committed)]
    out = log.take()
    assert list(out) == list(CommitLog.COLUMNS)
    assert len(out["sample_index"]) == len(expected) == 16
    got = zip(out["sample_index"], out["round"], out["delta"], out["start"][:, 0], out["start"][:, 1],
              out["outcome"], out["steps"], out["margin"], out["changed"], out["counted"], out["kind"])
    assert [tuple(row) for row in got] == expected
    assert out["sample_index"].dtype == np.int64 and out["round"].dtype == np.int32
    assert log.take() is None
