"""Coupled counting's question at commit: is a run still what its own stream draws from
the algorithm's state as it is now (shared/spec/scaling.md)? An exact run is the run the
one-run-at-a-time campaign makes at that index; any other is discarded unseen and
replaced (coordinator/driver/replacements.py)."""

from __future__ import annotations

import numpy as np

from coordinator.stable_sampler import Draws


def verify(launcher, p, lo: int, hi: int) -> np.ndarray:
    """(hi - lo,) bool: which runs ``lo:hi`` of batch ``p`` are exact now: their streams
    draw their starts. A stream whose current draw a change may have moved is drawn
    again (and its current draw kept: a start the set moved away from is not drawn
    again until a change touches what its stream draws now)."""
    span = p.draws.span(lo, hi)
    moved = launcher.algorithm.moved(span)
    exact = span.now == span.ids
    if moved.any():
        exact[moved], _ = redraw(launcher, p, lo + np.flatnonzero(moved))
    return exact


def redraw(launcher, p, rows: np.ndarray) -> tuple[np.ndarray, Draws]:
    """Draw runs ``rows`` of batch ``p`` again: -> (still their starts, the fresh draws);
    the fresh draws become their current ones (later checks start from now)."""
    fresh = launcher.draw(p.first_index + rows)
    p.draws.track(rows, fresh)
    # the start too: after the algorithm went back to a copy (coordinator/driver/speculation.py)
    # an id may name another centre than the one the run was launched from
    same_id = fresh.ids == p.draws.ids[rows]
    same = same_id & (launcher.starts(fresh.ids) == p.starts[rows]).all(axis=1)
    p.draws.now[rows[same_id & ~same]] = -1  # its stream draws another start under that id
    return same, fresh


def drawn_now(launcher, r) -> Draws | None:
    """Is replacement (or run launched ahead) ``r``'s start what its stream draws now?
    None if it is (its draw renewed), else what its stream draws now (one draw)."""
    if not launcher.algorithm.moved(r.draws)[0]:
        return None
    fresh = launcher.draw([r.index])
    if fresh.ids[0] != r.draws.ids[0]:
        return fresh
    # (a run launched for a change not applied yet may name a centre that the change
    # would have inserted under that id: its start must be the centre's too)
    if not np.array_equal(r.start, launcher.starts(fresh.ids[0])):
        return fresh
    r.draws = fresh  # renewed: later checks start from now
    return None
