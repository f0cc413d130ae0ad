"""Re-deciding a screened chunk after later changes (coordinator/coverage.py ``Rescreen``)
against a brute-force model: every run's visited states classified afresh at the
coverage as it is now."""

import numpy as np
import pytest

from coordinator.coverage import AddFailures, Coverage, Insert, Kill, Strict
from coordinator.rescreen import Rescreen
from scenarios.base import FAILURE

DELTA = 0.5
LOWER, UPPER = np.zeros(2), np.full(2, 8.0)


def _lattice(rng, k):
    """k distinct cell centres of the delta lattice (as SPE's centres are)."""
    cells = rng.choice(16 * 16, size=k, replace=False)
    return np.stack([cells // 16, cells % 16], axis=1) * 2 * DELTA + DELTA


def _chunk(rng, runs=120, steps=6):
    states = rng.uniform(0, 8, size=(runs * steps, 2))
    offsets = np.arange(0, runs * steps + 1, steps)
    outcomes = np.where(rng.random(runs) < 0.05, FAILURE, 0).astype(np.int8)
    return states, offsets, outcomes


def _brute(cov, states, offsets, outcomes, row):
    """Does run ``row`` change the coverage now, and its new states' mask."""
    s = states[offsets[row] : offsets[row + 1]]
    witness, near = cov.classify_states(s)
    return bool(outcomes[row] == FAILURE or ((witness < 0) & ~near).any())


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("strict", [False, True])
def test_rescreen_matches_a_fresh_classification(seed, strict):
    rng = np.random.default_rng(seed)
    cov = Coverage(2, DELTA, LOWER, bounds=(LOWER, UPPER))
    cov.apply(Insert(_lattice(rng, 150)), 1)
    cov.apply(AddFailures(rng.uniform(0, 8, size=(5, 2))), 2)
    if strict:
        cov.apply(Strict(True), 3)
    states, offsets, outcomes = _chunk(rng)
    screening = cov.screen(states, offsets, outcomes)
    rescreen = Rescreen(cov, screening, outcomes, lambda: (states, offsets))
    version, pos, checked = 10, 0, 0
    while pos < len(outcomes):
        row = rescreen.next_event(pos)
        expected = next((r for r in range(pos, len(outcomes)) if _brute(cov, states, offsets, outcomes, r)),
                        len(outcomes))
        assert row == expected
        if row == len(outcomes):
            break
        uncovered, near = rescreen.classification(row)
        candidates = rescreen.candidates(row)
        if uncovered is not None:  # what it claims to know is what a fresh query says
            witness = cov.vertices.cover(candidates, DELTA)
            assert np.array_equal(uncovered, witness < 0)
            if strict:
                assert near is None
            else:
                fresh_near = (witness < 0) & cov.failures.any_within(candidates, DELTA)
                assert np.array_equal(near, fresh_near)
            checked += 1
        # a change as SPE would make: a failure kills centres, an explore inserts
        version += 1
        if outcomes[row] == FAILURE:
            cov.apply(AddFailures(states[offsets[row]][None]), version)
            alive = cov.vertices.alive_ids()
            cov.apply(Kill(rng.choice(alive, size=min(4, len(alive)), replace=False)), version)
        else:
            cov.apply(Insert(_lattice(rng, 3) + rng.choice([0.0, 0.1], size=(3, 2))), version)
        pos = row + 1
    assert checked > 3  # the classification was known (and checked) for several events


def _rescreened_after_changes(rng, inserts: bool = True):
    """A chunk screened at one coverage, and a rescreen of it after 30 kills (and 5
    inserts): (coverage, rescreen, (states, offsets, outcomes))."""
    cov = Coverage(2, DELTA, LOWER, bounds=(LOWER, UPPER))
    cov.apply(Insert(_lattice(rng, 150)), 1)
    cov.apply(AddFailures(rng.uniform(0, 8, size=(5, 2))), 2)
    states, offsets, outcomes = _chunk(rng)
    screening = cov.screen(states, offsets, outcomes)
    cov.apply(Kill(rng.choice(cov.vertices.alive_ids(), size=30, replace=False)), 3)
    if inserts:
        cov.apply(Insert(_lattice(rng, 5) + 0.1), 4)
    return cov, Rescreen(cov, screening, outcomes, lambda: (states, offsets)), (states, offsets, outcomes)


@pytest.mark.parametrize("seed", range(3))
def test_a_run_asked_alone_is_decided_as_a_fresh_classification_decides_it(seed):
    """``Rescreen.changes(row)``, a replacement's question (that run alone, nothing after
    it classified), after kills and inserts since the chunk was screened, row by row in
    a random order on one rescreen: what a fresh classification of its states says."""
    rng = np.random.default_rng(seed)
    cov, rescreen, (states, offsets, outcomes) = _rescreened_after_changes(rng)
    answers = [(row, rescreen.changes(int(row))) for row in rng.permutation(len(outcomes))]
    assert all(changes == _brute(cov, states, offsets, outcomes, row) for row, changes in answers)
    assert 0 < sum(changes for _, changes in answers) < len(outcomes)


@pytest.mark.parametrize("seed", range(3))
def test_a_bounded_ask_finds_the_first_change_before_its_end_or_says_none(seed):
    """``next_event(lo, end=e)`` (the head asks no further than its next misprediction):
    the first run in [lo, e) that a fresh classification says changes the state, else
    the chunk's length; asked again from e on, the same rescreen still answers right."""
    rng = np.random.default_rng(10 + seed)
    cov, rescreen, (states, offsets, outcomes) = _rescreened_after_changes(rng, inserts=False)
    k = len(outcomes)
    changing = [r for r in range(k) if _brute(cov, states, offsets, outcomes, r)]
    lo = 0
    for end in sorted(rng.choice(np.arange(1, k), size=12, replace=False)) + [k]:
        expected = next((r for r in changing if lo <= r < end), k)
        assert rescreen.next_event(lo, end=int(end)) == expected
        lo = int(end)
    assert 0 < len(changing) < k


@pytest.mark.parametrize("mixed", [False, True])
def test_witnesses_after_an_insert_are_those_of_a_fresh_screening(mixed):
    """A state's witness is its newest covering centre: after an insert (boundary
    refinement splits boxes while it certifies) the witnesses must not depend on when
    the chunk was screened, or the certificates, and the runs they cost, depend on the
    executor (a Ray band campaign committed one run less than in-process)."""
    rng = np.random.default_rng(7)
    cov = Coverage(2, DELTA, LOWER, bounds=(LOWER, UPPER), mixed=mixed)
    cov.apply(Insert(_lattice(rng, 200)), 1)
    states, offsets, _ = _chunk(rng)
    outcomes = np.zeros(len(offsets) - 1, dtype=np.int8)
    rescreen = Rescreen(cov, cov.screen(states, offsets, outcomes), outcomes, lambda: (states, offsets))
    quiet = np.flatnonzero(cov.screen(states, offsets, outcomes).event == 0)
    before = rescreen.witnesses(quiet)
    # new centres on top of covered states: the newest covering centre changes
    covered = states[offsets[quiet[:20]]]
    cov.apply(Insert(np.floor(covered / (2 * DELTA)) * 2 * DELTA + DELTA), 2)
    fresh = cov.screen(states, offsets, outcomes)
    after = rescreen.witnesses(quiet)
    expected = Rescreen(cov, fresh, outcomes, lambda: (states, offsets)).witnesses(quiet)
    assert not np.array_equal(before[1], expected[1])  # the insert did change witnesses
    assert np.array_equal(after[0], expected[0]) and np.array_equal(after[1], expected[1])


def test_a_screening_is_judged_at_the_state_it_had_across_a_fork():
    # the algorithm went back to a copy of its coverage and went on (a fork,
    # coordinator/driver/speculation.py): a chunk screened before the copy still holds; one
    # screened on the state left behind, or at changes the copy has not had (a hold
    # judged at the state the head passed it), is screened again from its states
    import copy

    rng = np.random.default_rng(11)
    cov = Coverage(2, DELTA, LOWER, bounds=(LOWER, UPPER))
    cov.apply(Insert(_lattice(rng, 150)), 1)
    states, offsets, outcomes = _chunk(rng)
    before = cov.screen(states, offsets, outcomes)
    copied = copy.deepcopy(cov)
    for version in (2, 3):  # the state left behind goes on
        cov.apply(Insert(_lattice(rng, 6) + 0.1), version)
        cov.apply(Kill(rng.choice(cov.vertices.alive_ids(), 8, replace=False)), version)
    left_behind = cov.screen(states, offsets, outcomes)
    judged = Rescreen(copied, left_behind, outcomes, lambda: (states, offsets))  # newer than the copy
    restored = copy.deepcopy(copied)
    restored.fork(cov.epoch)
    restored.apply(Insert(_lattice(rng, 4) + 0.2), 4)  # the restored state goes on otherwise
    for coverage, screening in ((copied, left_behind), (restored, before), (restored, left_behind)):
        rescreen = Rescreen(coverage, screening, outcomes, lambda: (states, offsets))
        pos = 0
        while pos < len(outcomes):
            row = rescreen.next_event(pos)
            expected = next((r for r in range(pos, len(outcomes)) if _brute(coverage, states, offsets, outcomes, r)),
                            len(outcomes))
            assert row == expected
            pos = row + 1
    assert restored.descends(before.epoch, before.seq) and not restored.descends(left_behind.epoch, left_behind.seq)
    assert judged.next_event(0) == next(r for r in range(len(outcomes)) if _brute(copied, states, offsets, outcomes, r))
