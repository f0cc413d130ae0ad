"""The shared rollout core: ``run_scenario`` (paper Alg. 1) for a batch of runs on any
back end, with every piece of bookkeeping done here once.

Every step's new states are classified continue / truncated / failure (failure wins);
a run ends at its first non-continue state or after K states (the start counts as the
first), and a run that ended is never stepped again. The returned trajectories hold
every state of every run, the terminal one included, so a run can be checked and
replayed state by state.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from scenarios.base import CONTINUE, FAILURE, HORIZON, TRUNCATED, Scenario, ScenarioError
from scenarios.streams import PURPOSE_DISTURBANCE, RunStreams

START_TOLERANCE = 1e-9  # a back end must start a run within this of the requested state
STEP_BOUND_SLACK = 1e-9  # rounding room when checking sigma-bar against observed steps


@dataclass
class RunBatch:
    """Results of a batch of runs.

    indices       (B,) uint64 global sample indices (the runs' stream keys with the seed)
    trajectories  (K, B, n) states; entries past a run's length are meaningless
    lengths       (B,) int32 number of states in each run (start included, >= 1)
    outcomes      (B,) int8 FAILURE / TRUNCATED / HORIZON
    exits         (B,) int8 the facet a failed or truncated run left Sigma through, as an
                  index into ``Scenario.facets()``; -1 for a run that ran its horizon
    margins       (B,) float64 each run's margin: the smallest ``Scenario.failure_distance``
                  over its states (negative for a failed run; how deep, when the scenario
                  is stepped on past the facet: ``margin_through_contact``)
    """

    indices: np.ndarray
    trajectories: np.ndarray
    lengths: np.ndarray
    outcomes: np.ndarray
    exits: np.ndarray
    margins: np.ndarray

    @property
    def starts(self) -> np.ndarray:
        return self.trajectories[0]

    @property
    def steps(self) -> int:
        return int(self.lengths.sum() - len(self.lengths))

    def __len__(self) -> int:
        return len(self.indices)

    @classmethod
    def joined(cls, parts: list["RunBatch"]) -> "RunBatch":
        """The runs of ``parts`` one after another as one batch: the same batch as if they
        had been simulated together (a run depends on its key only)."""
        steps = max(len(part.trajectories) for part in parts)
        trajectories = np.empty((steps, sum(len(part) for part in parts), parts[0].trajectories.shape[2]))
        at = 0
        for part in parts:  # the steps past a part's longest run are past all of its runs' lengths
            trajectories[: len(part.trajectories), at : at + len(part)] = part.trajectories
            at += len(part)
        return cls(np.concatenate([part.indices for part in parts]), trajectories,
                   *(np.concatenate([getattr(part, name) for part in parts])
                     for name in ("lengths", "outcomes", "exits", "margins")))

    def trajectory(self, row: int) -> np.ndarray:
        """(length, n) states of one run."""
        return self.trajectories[: self.lengths[row], row]

    def last_states(self) -> np.ndarray:
        """(B, n) the terminal state of every run."""
        return self.trajectories[self.lengths - 1, np.arange(len(self))]

    def visited(self) -> tuple[np.ndarray, np.ndarray]:
        """The states after the start that lie inside Sigma, run by run in time order:
        (S, n) states and (B + 1,) offsets (run r's states are ``states[off[r]:off[r+1]]``).
        A failed or truncated run's terminal state is left out: it is outside Sigma."""
        ends = self.lengths.astype(np.int64) - np.isin(self.outcomes, (FAILURE, TRUNCATED))
        counts = np.maximum(ends - 1, 0)
        offsets = np.zeros(len(self) + 1, dtype=np.int64)
        np.cumsum(counts, out=offsets[1:])
        total = int(offsets[-1])
        run = np.repeat(np.arange(len(self)), counts)
        t = np.arange(total) - np.repeat(offsets[:-1], counts) + 1
        return self.trajectories[t, run], offsets


def run_scenario(backend, starts: np.ndarray, horizon: int, policy, streams: RunStreams, *,
                 check_step_bound: bool = False, deep_margins: bool = False) -> RunBatch:
    """Run a batch from ``starts`` (B, n) for up to ``horizon`` states each on ``backend``
    (a ``scenarios.backend.Backend``). ``check_step_bound``: verify that no step moves
    farther (l-inf) than the scenario's ``step_bound()`` (Assumption 1), which the
    boundary-band options rely on; an error names the run that breaks it.
    ``deep_margins``: a failed run's margin goes as deep as the run would past the facet,
    where the scenario allows it (``margin_through_contact``; margin refinement asks for
    it). A bare
    ``Scenario`` runs on its own vectorized dynamics (the numpy back end)."""
    if isinstance(backend, Scenario):
        from scenarios.backend import NumpyBackend

        backend = NumpyBackend(backend)
    scenario: Scenario = backend.scenario
    if horizon < 2:
        raise ValueError(f"horizon: K must be >= 2, got {horizon}")
    starts = np.asarray(starts, dtype=float)
    if starts.ndim != 2 or starts.shape[1] != scenario.n:
        raise ScenarioError(f"start states have shape {starts.shape}, scenario {scenario.error_name!r} needs (B, {scenario.n})")
    if len(streams) != len(starts):
        raise ScenarioError(f"{len(starts)} start states but {len(streams)} run streams")
    batch, n = starts.shape
    # Stored as (K, n, B) so that each step writes n contiguous rows; exposed as (K, B, n).
    # Zeroed, not left as it comes: a run's entries past its end are never written, and the
    # margins are worked out over the whole store at once, where leftover bytes (a NaN that
    # signals) made numpy warn "invalid value" on a user's terminal now and then.
    store = np.zeros((horizon, n, batch))
    store[0] = starts.T
    lengths = np.full(batch, horizon, dtype=np.int32)
    outcomes = np.full(batch, HORIZON, dtype=np.int8)
    exits = np.full(batch, -1, dtype=np.int8)
    piece = getattr(backend, "max_batch", None) or max(batch, 1)
    for lo in range(0, batch, piece):
        hi = min(batch, lo + piece)
        part = streams if (lo, hi) == (0, batch) else streams.subset(np.arange(lo, hi))
        _run_piece(backend, starts[lo:hi], horizon, policy, part, check_step_bound,
                   store[:, :, lo:hi] if (lo, hi) != (0, batch) else store, lengths[lo:hi], outcomes[lo:hi])
    ended = np.flatnonzero(outcomes != HORIZON)  # the facet each left through, from its last state
    exits[ended] = scenario.exits(store[lengths[ended] - 1, :, ended])
    margins = _margins(scenario, store, lengths)
    if deep_margins and scenario.margin_through_contact and getattr(backend, "name", None) == "numpy":
        _through_contact(scenario, store, lengths, outcomes, margins, horizon, policy, streams)
    return RunBatch(streams.indices, store.transpose(0, 2, 1), lengths, outcomes, exits, margins)


def _run_piece(backend, starts, horizon, policy, streams, check_step_bound, store, lengths, outcomes) -> None:
    """One simulation of the runs ``starts``; fills ``store`` (K, n, b), lengths and
    outcomes. A run that ended is never stepped again: the back end forgets it (``keep``)
    in the step it ended, so a simulator never sees a state past a facet."""
    scenario = backend.scenario
    batch, n = starts.shape
    disturbed = scenario.disturbance > 0.0 and scenario.noise_width > 0
    bound = scenario.step_bounds() + STEP_BOUND_SLACK if check_step_bound else None  # per axis
    try:
        states = backend.insert(starts, horizon, streams)
        if states is not starts:
            _check_start(scenario, states, starts, streams)
        rows = np.arange(batch)  # the batch rows of the runs still running: the back end holds these
        alive = np.ones(batch, dtype=bool)  # the same rows as flags (rows is increasing)
        row_streams = streams
        for t in range(1, horizon):
            actions = policy(scenario, states, t, row_streams)
            noise = row_streams.uniform(t, PURPOSE_DISTURBANCE, scenario.noise_width) if disturbed else None
            # every run still running: straight into the store; after the first end: scattered there
            full = len(rows) == batch
            slab = store[t] if full else np.empty((n, len(rows)))
            backend.step(states, actions, noise, slab)
            nxt = slab.T
            if not full:  # by flags, one state variable at a time: cheaper than by row numbers
                for i in range(n):
                    store[t][i][alive] = slab[i]
            # one pass: a sum is finite iff every term is (or it overflowed, which the exact
            # per-row check below then clears); the per-row search only on error
            if not np.isfinite(np.add.reduce(slab, axis=None)):
                bad = ~np.isfinite(nxt).all(axis=1)
                if bad.any():
                    _raise_bad_state(scenario, nxt, rows, bad, streams, starts, t)
            if bound is not None:
                _check_step(scenario, bound, states, nxt, rows, streams, t)
            status = scenario.classify(nxt)
            ended = status != CONTINUE
            if ended.any():
                done = rows[ended]
                outcomes[done] = status[ended]
                lengths[done] = t + 1
                going = ~ended
                if not going.any():
                    break
                backend.keep(going)
                alive[done] = False
                rows = rows[going]
                nxt = np.compress(going, slab, axis=1).T
                row_streams = row_streams.subset(going)
            states = nxt
    finally:
        backend.clear()  # also after an error: the next batch must find an empty simulator


def _margins(scenario, store, lengths) -> np.ndarray:
    """(B,) each run's smallest failure distance over its states (the store's entries past
    a run's length are not its), in one pass over the store."""
    distance = scenario.failure_distance(store.transpose(0, 2, 1))  # (K, B)
    distance[np.arange(len(store))[:, None] >= lengths[None, :]] = np.inf
    return distance.min(axis=0) if len(store) else np.zeros(store.shape[2])


def _through_contact(scenario, store, lengths, outcomes, margins, horizon, policy, streams) -> None:
    """Failed runs stepped on past the facet to their horizon (their states are not kept:
    the run ended at the facet), so that each margin goes as deep as the run would: a
    margin then varies smoothly across the boundary instead of stopping at the first
    state past it. Actions and disturbance come from each run's stream at each step, as
    if it had gone on."""
    rows = np.flatnonzero((outcomes == FAILURE) & (lengths < horizon))
    if len(rows) == 0:
        return
    disturbed = scenario.disturbance > 0.0 and scenario.noise_width > 0
    states = store[lengths[rows] - 1, :, rows]  # (r, n): each run's state past the facet
    from_step = lengths[rows]
    out = np.empty((scenario.n, len(rows)))
    for t in range(int(from_step.min()), horizon):
        go = np.flatnonzero(from_step <= t)
        part = streams.subset(rows[go])
        actions = policy(scenario, states[go], t, part)
        noise = part.uniform(t, PURPOSE_DISTURBANCE, scenario.noise_width) if disturbed else None
        scenario.step_into(states[go], actions, noise, out[:, : len(go)])
        nxt = out[:, : len(go)].T
        finite = np.isfinite(nxt).all(axis=1)
        states[go[finite]] = nxt[finite]
        depth = scenario.failure_distance(nxt[finite])
        margins[rows[go[finite]]] = np.minimum(margins[rows[go[finite]]], depth)


def _check_start(scenario, states, starts, streams) -> None:
    states = np.asarray(states, dtype=float)
    bad = ~(np.abs(states - starts) <= START_TOLERANCE).all(axis=1)
    if bad.any():
        row = int(np.nonzero(bad)[0][0])
        raise ScenarioError(f"the back end did not start sample index {int(streams.indices[row])} at its start "
                            f"state {starts[row].tolist()}: read back {states[row].tolist()}")


def _check_step(scenario, bound, states, nxt, rows, streams, t) -> None:
    """``bound`` (n,): sigma-bar per axis (``step_bounds()``, whose largest is ``step_bound()``)."""
    moved = np.abs(nxt - states)
    over = moved - bound
    if len(moved) and over.max() > 0:
        k, axis = np.unravel_index(int(np.argmax(over)), over.shape)
        run = int(rows[k])
        name = scenario.state_names[axis]
        raise ScenarioError(f"scenario {scenario.error_name!r}: step_bound() = {scenario.step_bound():g} but sample index "
                            f"{int(streams.indices[run])} moved {moved[k, axis]:g} along {name} in step {t}, more than "
                            f"step_bounds() allows there ({scenario.step_bounds()[axis]:g}); they must bound every "
                            f"step (Assumption 1)")


def _raise_bad_state(scenario, nxt, rows, bad, streams, starts, t):
    row = int(np.nonzero(bad)[0][0])
    run = int(rows[row])
    raise ScenarioError(
        f"scenario {scenario.error_name!r} produced a non-finite state at step {t} of sample index "
        f"{int(streams.indices[run])} (start state {starts[run].tolist()}): {nxt[row].tolist()}"
    )
