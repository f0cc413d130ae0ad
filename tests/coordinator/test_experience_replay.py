"""Experience replay's pieces merged by source for the executor's call and split back
(coordinator/experience_replay.py): per piece, the same states and run positions as
screening each piece alone, whatever the order the pieces of several chunks come in."""

import numpy as np

from coordinator.experience_replay import Stored, merged_by_source, select, split_found


def _chunk(rng, runs: int, n: int = 3):
    """A chunk's visited states: (states, offsets), each run 0-6 states."""
    lengths = rng.integers(0, 7, size=runs)
    offsets = np.concatenate([[0], np.cumsum(lengths)])
    return rng.random((int(offsets[-1]), n)), offsets


def _piece(rng, source, rows):
    takes = rng.integers(0, 7, size=len(rows)).clip(max=np.diff(source[1])[rows])
    return Stored(source, rng.integers(0, 10**6, size=len(rows)), rows, takes, rng.integers(0, 99, size=len(rows)),
                  rng.random((len(rows), 3)))


def _screen(piece):
    """What a worker finds in a piece: its kept states, those past a threshold as new."""
    kept, run = select(*piece.source, piece.rows, piece.takes)
    new = kept[:, 0] > 0.4
    return kept[new], run[new]


def test_merged_pieces_find_per_piece_what_each_piece_finds_alone():
    rng = np.random.default_rng(7)
    chunks = [_chunk(rng, 40) for _ in range(3)]
    pieces = []
    for _ in range(4):  # the commits of three chunks, interleaved
        for source in rng.permutation(len(chunks)):
            rows = np.sort(rng.choice(40, size=int(rng.integers(1, 9)), replace=False))
            pieces.append(_piece(rng, chunks[source], rows))
    pieces.append(Stored(None, np.arange(3), np.arange(3), np.ones(3, dtype=np.int64), np.zeros(3, dtype=np.int64),
                         np.zeros((3, 3))))  # re-simulated from its keys: never merged
    merged, parts = merged_by_source(pieces)
    assert len(merged) == 4 and merged[-1] is pieces[-1]
    assert [m.source for m in merged[:3]] == [pieces[i].source for i in range(3)]  # in the order of their first
    found = [_screen(m) if m.source is not None else (np.zeros((0, 3)), np.zeros(0, dtype=np.int64)) for m in merged]
    back = split_found(found, parts)
    assert len(back) == len(pieces)
    for piece, (states, run) in zip(pieces[:-1], back):
        alone_states, alone_run = _screen(piece)
        np.testing.assert_array_equal(states, alone_states)
        np.testing.assert_array_equal(run, alone_run)
        assert len(alone_run) == 0 or run.max() < len(piece.indices)
    assert sum(len(s) for s, _ in back[:-1]) > 0  # something was found, and put back where it belongs
