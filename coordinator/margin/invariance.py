"""The largest set of boxes whose centre runs stay in it: margin refinement's
certification (VAL^delta on its own boxes, paper Alg. 2 and Lemma 1).

Given the boxes whose centre runs did not fail (``candidates``) and, per such run, the
boxes its visited states lie in, drop every candidate whose run visits a box outside
the set, and repeat until nothing changes: what is left is the greatest fixpoint, and
every centre of it is certified by its own run (deterministic system: the run is the
run). Each drop looks only at the runs that visited the dropped box (a reverse index),
so the whole is linear in the visits.
"""

from __future__ import annotations

import numpy as np


def largest_invariant(candidates: np.ndarray, visited: np.ndarray, offsets: np.ndarray,
                      size: int) -> tuple[np.ndarray, int]:
    """``candidates`` (C,) box ids; run c's visited boxes are ``visited[offsets[c]:
    offsets[c+1]]`` (ids below ``size``). -> (the kept candidates, as a (C,) bool mask;
    the rounds of drops it took)."""
    inside = np.zeros(size, dtype=bool)
    inside[candidates] = True
    run = np.repeat(np.arange(len(candidates)), np.diff(offsets))
    # reverse index: visited box -> the candidate runs that visit it
    order = np.argsort(visited, kind="stable")
    by_box, runs_by_box = visited[order], run[order]
    kept = np.ones(len(candidates), dtype=bool)
    bad = np.zeros(len(candidates), dtype=bool)
    np.logical_or.at(bad, run, ~inside[visited])
    rounds = 0
    while bad.any():
        rounds += 1
        gone = candidates[bad & kept]
        kept &= ~bad
        inside[gone] = False
        lo = np.searchsorted(by_box, gone, side="left")
        hi = np.searchsorted(by_box, gone, side="right")
        hit = np.concatenate([runs_by_box[a:b] for a, b in zip(lo, hi)]) if len(gone) else np.zeros(0, np.int64)
        bad = np.zeros(len(candidates), dtype=bool)
        bad[hit] = True
        bad &= kept
    return kept, rounds
