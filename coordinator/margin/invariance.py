"""The largest set of boxes whose centre runs stay in its covering: margin refinement's
certification (VAL^delta on its own boxes, paper Alg. 2 and Lemma 1).

The covering of a set of boxes (Definition 5, with a delta per box and axis: the paper's
vector-delta extension) is here each box widened by ``covering`` on every axis. Given
the boxes whose centre runs did not fail (``candidates``) and every state each run
visited, drop each candidate whose run visits a state outside the covering of the
candidates left, and repeat until nothing changes: what is left is the greatest
fixpoint, every centre of it certified by its own run (deterministic system: the run is
the run). A state near the set's boundary, where a run that just stops in time passes,
lies in a box whose centre failed more often than not: the covering's margin is what
keeps such runs, as the resolution of the claim.

A state in a kept box is inside; one that is not is looked for in the kept boxes a
probe reaches along each axis (at half and all of ``covering``, each way): a state found
so lies within ``covering`` of the set. Probes along the axes only (2n of them, not the
2^n corners) may miss a box reached diagonally: that drops a run, never keeps a wrong one.
"""

from __future__ import annotations

import numpy as np

PROBES = (0.5, 1.0)  # probe distances, as shares of the covering (a box is at least that wide)


def largest_invariant(candidates: np.ndarray, states: np.ndarray, offsets: np.ndarray, locate,
                      size: int, covering: float, lower: np.ndarray, upper: np.ndarray) -> tuple[np.ndarray, int]:
    """``candidates`` (C,) box ids below ``size``; run c visited
    ``states[offsets[c]:offsets[c+1]]``; ``locate(points)`` the box holding each point of
    Sigma = [lower, upper]. -> (the kept candidates, a (C,) bool mask; the rounds of drops)."""
    run = np.repeat(np.arange(len(candidates)), np.diff(offsets))
    home = locate(states) if len(states) else np.zeros(0, dtype=np.int64)
    kept_box = np.zeros(size + 1, dtype=bool)  # the last slot: "no box"
    kept_box[candidates] = True
    probed = np.full(len(states), -1, dtype=np.int64)  # a state's row in ``reach``, once probed
    reach = np.zeros((0, 4 * states.shape[1]), dtype=np.int64)
    kept = np.ones(len(candidates), dtype=bool)
    rounds = 0
    while True:
        homeless = np.flatnonzero(~kept_box[home] & kept[run])
        new = homeless[probed[homeless] < 0]
        if len(new):  # probed when first needed: most states lie in a kept box
            probed[new] = len(reach) + np.arange(len(new))
            reach = np.concatenate([reach, _probes(states[new], locate, covering, lower, upper, size)])
        outside = homeless[~kept_box[reach[probed[homeless]]].any(axis=1)]
        bad = np.zeros(len(candidates), dtype=bool)
        bad[run[outside]] = True
        if not bad.any():
            return kept, rounds
        kept &= ~bad
        kept_box[candidates[bad]] = False
        rounds += 1


def _probes(states: np.ndarray, locate, covering: float, lower, upper, none: int) -> np.ndarray:
    """(S, 4n) the boxes the probes from ``states`` reach (``none`` past Sigma)."""
    out = []
    for axis in range(states.shape[1]):
        for share in PROBES:
            for sign in (-1.0, 1.0):
                probe = states.copy()
                probe[:, axis] += sign * share * covering
                inside = (probe[:, axis] >= lower[axis]) & (probe[:, axis] <= upper[axis])
                box = np.full(len(states), none, dtype=np.int64)
                box[inside] = locate(probe[inside])
                out.append(box)
    return np.stack(out, axis=1)
