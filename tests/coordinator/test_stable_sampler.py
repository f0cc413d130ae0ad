"""The stable sampler (coordinator/stable_sampler.py): each run's start is drawn from its
own stream, exactly by the law (uniform or weighted over the alive ids), and ``moved``
tells which draws a change since may have moved: with the law at hand, all those whose
stream now draws another id and hardly any other (a tracked draw is asked about the
slots it examined); never a moved one unflagged."""

import numpy as np
import pytest
from scipy import stats

from coordinator.stable_sampler import StableSampler, TableLaw, UniformLaw, WeightedLaw
from scenarios.streams import RunStreams

COUNT = 200


def uniform(alive: np.ndarray) -> UniformLaw:
    return UniformLaw(len(alive), lambda ids: alive[ids], lambda: np.flatnonzero(alive))


def weighted(alive: np.ndarray, w: np.ndarray) -> WeightedLaw:
    weights = np.where(alive, w, 0.0)
    cdf = np.cumsum(weights)

    def direct(u):
        return np.minimum(np.searchsorted(cdf, u * cdf[-1], side="right"), len(weights) - 1)

    return WeightedLaw(len(weights), weights.__getitem__, direct, float(weights.max()))


def streams(n: int, seed: int = 5) -> RunStreams:
    return RunStreams.of(seed, np.arange(n, dtype=np.uint64))


@pytest.mark.parametrize("kind", ["uniform", "weighted"])
def test_each_draw_follows_the_law_exactly(kind):
    rng = np.random.default_rng(0)  # test data only
    alive = rng.random(COUNT) < 0.6
    w = rng.uniform(0.1, 3.0, COUNT)
    law = uniform(alive) if kind == "uniform" else weighted(alive, w)
    sampler = StableSampler()
    sampler.restart(COUNT, 0)
    draws = sampler.draw(streams(60_000), law, 0)
    assert alive[draws.ids].all()
    p = np.where(alive, 1.0 if kind == "uniform" else w, 0.0)
    p = p[alive] / p[alive].sum()
    counts = np.bincount(draws.ids, minlength=COUNT)[alive]
    assert stats.chisquare(counts, p * counts.sum()).pvalue > 1e-3


@pytest.mark.parametrize("kind", ["uniform", "weighted"])
def test_moved_flags_exactly_the_draws_a_change_moved(kind):
    rng = np.random.default_rng(1)  # test data only
    count = COUNT
    alive = rng.random(count) < 0.6
    w = rng.uniform(0.1, 3.0, count)
    sampler = StableSampler()
    sampler.restart(count, 0)
    law = uniform(alive) if kind == "uniform" else weighted(alive, w)
    s = streams(20_000)
    draws = sampler.draw(s, law, 0)
    # version 1: some alive ids die, some ids are born (inserted past the count), and some
    # weights rise (a distance that fell) without changing the bound (a new bound is a new
    # law: it moves every draw, ``touch_all``)
    top = int(np.argmax(np.where(alive, w, 0)))
    killed = rng.choice(np.setdiff1d(np.flatnonzero(alive), [top]), 10, replace=False)
    alive = alive.copy()
    alive[killed] = False
    born = np.arange(count, count + 5)
    alive = np.concatenate([alive, np.ones(5, dtype=bool)])
    w = np.concatenate([w, rng.uniform(0.1, 1.0, 5)])
    raised = rng.choice(np.setdiff1d(np.flatnonzero(alive[:count]), [top]), 10, replace=False)
    w[raised] = np.minimum(w[raised] * 1.5, w[top])
    sampler.touch(np.concatenate([killed, born, raised]), 1)
    sampler.fit(count + 5, 1)  # the cap holds the new ids: no move of every draw
    law = uniform(alive) if kind == "uniform" else weighted(alive, w)
    if kind == "weighted":
        assert law.bound == pytest.approx(float(np.where(alive, w, 0).max()))
    fresh = sampler.draw(s, law, 1)
    really = fresh.ids != draws.ids
    flagged = sampler.moved(draws, law, 1)
    assert really.any() and not (really & ~flagged).any()  # no moved draw unflagged
    tracked = ~draws.untracked
    # exact where tracked, but for a draw whose accepted try fails now and a later try
    # finds the same id again (the same start: flagged, drawn again to know)
    assert (flagged & ~really)[tracked].mean() < 1e-3
    assert flagged.sum() < 3 * max(really.sum(), 1)  # far fewer than every touched draw
    # a draw found standing is renewed: nothing since moves it
    standing = tracked & ~flagged
    assert (draws.versions[standing & (draws.versions >= 0)] <= 1).all()
    assert not sampler.moved(draws, law, 1)[standing].any()


@pytest.mark.parametrize("change", ["kill", "insert", "reweigh"])
def test_the_coupling_moves_about_the_share_no_exact_sampler_can_keep(change):
    # TV(old law, new law) bounds from below the share of draws any exact sampler moves;
    # the stream-keyed sampler should move about that share, not a multiple of it
    # (experiments/coupling_bound.py measures the same over a whole campaign)
    from coordinator.stable_sampler import probabilities, total_variation

    rng = np.random.default_rng(3)  # test data only
    count = 4096
    alive = rng.random(count) < 0.5
    w = rng.uniform(0.5, 2.0, count)
    before = weighted(alive, w) if change == "reweigh" else uniform(alive)
    alive2, w2 = alive.copy(), w.copy()
    if change == "kill":
        alive2[rng.choice(np.flatnonzero(alive), 100, replace=False)] = False
    elif change == "insert":
        alive2[rng.choice(np.flatnonzero(~alive), 100, replace=False)] = True
    else:
        w2[rng.choice(np.flatnonzero(alive), 100, replace=False)] *= 0.3
    after = weighted(alive2, w2) if change == "reweigh" else uniform(alive2)
    sampler = StableSampler()
    sampler.restart(count, 0)
    s = streams(40_000)
    moved = np.mean(sampler.draw(s, before, 0).ids != sampler.draw(s, after, 0).ids)
    tv = total_variation(probabilities(before), probabilities(after))
    assert 0.01 < tv < 0.06
    assert tv - 0.004 <= moved <= 1.25 * tv + 0.004, (moved, tv)


def test_after_a_fork_a_draw_moves_where_the_state_left_behind_differed():
    # the state went back to a copy (coordinator/driver/speculation.py): draws made on the state
    # left behind stand only if no slot they examined differs between the two, and a draw
    # of an id born there is drawn again (the id names another centre here)
    import copy

    count = COUNT
    alive = np.ones(count, dtype=bool)
    sampler = StableSampler()
    sampler.restart(count, 0)
    copied = copy.deepcopy(sampler)  # the copy, at version 0
    # the state left behind: 20 ids die, 5 are born (version 1), then draws are made there
    rng = np.random.default_rng(3)  # test data only
    killed = rng.choice(count, 20, replace=False)
    left_alive = np.concatenate([alive, np.ones(5, dtype=bool)])
    left_alive[killed] = False
    sampler.touch(np.concatenate([killed, np.arange(count, count + 5)]), 1)
    sampler.fit(count + 5, 1)
    s = streams(20_000)
    made_there = sampler.draw(s, uniform(left_alive), 1)
    # back to the copy: nothing died, nothing was born
    copied.forked(sampler, 0, 2, count)
    here = copied.draw(s, uniform(alive), 2)
    flagged = copied.moved(made_there, uniform(alive), 2)
    differs = here.ids != made_there.ids
    assert differs.any() and not (differs & ~flagged).any()  # every draw that differs is flagged
    born = made_there.ids >= count
    assert born.any() and flagged[born].all()  # an id born on the other side is never taken as is
    assert flagged.mean() < 0.5  # not every draw: only those that examined a slot that differs


def _edge_table(rng, count: int, members: int):
    """A sparse law's table (a closing round's edge): ``members`` ids scattered over
    ``count``, listed in id order, and a membership mask over the ids."""
    table = np.sort(rng.choice(count, members, replace=False))
    mask = np.zeros(count, dtype=bool)
    mask[table] = True
    return table, mask


def test_a_table_law_draws_its_candidates_uniformly_within_a_few_tries():
    # 100 candidates among 20,000 ids: over the ids, most draws would exhaust their tries
    # and draw directly (which every change moves); over the table's slots none does
    rng = np.random.default_rng(4)  # test data only
    table, mask = _edge_table(rng, 20_000, 100)
    mask[table[::10]] = False  # listed, no longer candidates
    sampler = StableSampler()
    sampler.restart(len(table), 0)
    draws = sampler.draw(streams(40_000), TableLaw(table, mask.__getitem__), 0)
    assert mask[draws.ids].all() and not draws.untracked.any()
    assert (draws.slots >= 0).sum(axis=1).mean() < 3  # slots examined per draw
    counts = np.bincount(draws.ids, minlength=len(mask))[mask]
    assert stats.chisquare(counts).pvalue > 1e-3


@pytest.mark.parametrize("alone", [False, True])
def test_a_table_slot_that_names_another_vertex_after_a_fork_moves_its_draws(alone):
    # the state left behind appended vertices to the table; the state restored appends
    # others to the same slots: a draw that accepted such a slot is accepted there too,
    # but names another vertex, so it must be drawn again (alone: a replacement's one draw)
    import copy

    rng = np.random.default_rng(6)  # test data only
    table, mask = _edge_table(rng, 5_000, 60)
    sampler = StableSampler()
    sampler.restart(len(table), 0)
    copied, copied_table, copied_mask = copy.deepcopy(sampler), table.copy(), mask.copy()
    joined = rng.choice(np.flatnonzero(~mask), 20, replace=False)
    left_table, left_mask = np.concatenate([table, joined]), mask.copy()
    left_mask[joined] = True
    sampler.touch(np.arange(len(table), len(left_table)), 1)
    s = streams(20_000)
    made_there = sampler.draw(s, TableLaw(left_table, left_mask.__getitem__), 1)
    copied.forked(sampler, 0, 2, len(mask))
    others = rng.choice(np.flatnonzero(~left_mask), 20, replace=False)
    here_table, here_mask = np.concatenate([copied_table, others]), copied_mask
    here_mask[others] = True
    copied.touch(np.arange(len(table), len(here_table)), 3)
    law = TableLaw(here_table, here_mask.__getitem__)
    if alone:
        flagged = np.array([copied.moved(made_there.rows([i]), law, 3)[0] for i in range(len(made_there))])
    else:
        flagged = copied.moved(made_there, law, 3)
    differs = copied.draw(s, law, 3).ids != made_there.ids
    renamed = np.isin(made_there.ids, joined)  # accepted a slot the restored state gave another vertex
    assert renamed.any() and flagged[renamed].all()
    assert differs.any() and not (differs & ~flagged).any()


def test_a_draw_is_the_same_drawn_alone_or_in_a_large_batch():
    """A few runs (a replacement, a redraw) try all their candidates in one block, a large
    batch in growing blocks (coordinator/stable_sampler.py, SMALL_BATCH): the same starts,
    examined slots and numbers either way, under a sparse law where most runs need more
    than the first block of tries and some draw directly."""
    from coordinator.stable_sampler import SMALL_BATCH, TRY_BLOCKS

    rng = np.random.default_rng(3)  # test data only
    alive = rng.random(4 * COUNT) < 0.02
    law = uniform(alive)
    sampler = StableSampler()
    sampler.restart(len(alive), 0)
    many = sampler.draw(streams(5000), law, 0)
    tries = (many.slots >= 0).sum(axis=1)
    assert (tries > TRY_BLOCKS[0]).mean() > 0.5 and many.untracked.any()  # the blocks matter here
    for rows in (np.arange(SMALL_BATCH), np.flatnonzero(many.untracked)[:3], np.flatnonzero(tries > 30)[:1]):
        few = sampler.draw(streams(5000).subset(rows), law, 0)
        assert np.array_equal(few.ids, many.ids[rows])
        assert np.array_equal(few.slots, many.slots[rows]) and np.array_equal(few.untracked, many.untracked[rows])
        examined = few.slots >= 0
        assert np.array_equal(few.vs[examined], many.vs[rows][examined])


@pytest.mark.parametrize("change", ["touch", "touch_all", "fork"])
@pytest.mark.parametrize("with_law", [True, False])
def test_a_draw_asked_alone_moves_as_it_does_in_a_batch(change, with_law):
    """A replacement's draw is asked alone, on scalars (``StableSampler._moved_one``): the
    same flag and the same renewal as the batch path gives it, after slots are touched,
    after the law changed as a whole, and after a fork, for tracked, untracked and direct
    draws alike."""
    import copy

    rng = np.random.default_rng(4)  # test data only
    alive = rng.random(4 * COUNT) < 0.05  # sparse: some draws examine many slots, some draw directly
    sampler = StableSampler()
    sampler.restart(len(alive), 0)
    copied = copy.deepcopy(sampler)
    draws = sampler.draw(streams(3000), uniform(alive), 0)
    killed = rng.choice(np.flatnonzero(alive), 8, replace=False)
    alive = alive.copy()
    alive[killed] = False
    still_dead = rng.choice(np.flatnonzero(~alive), 400, replace=False)  # touched, unchanged: draws stand
    sampler.touch(np.concatenate([killed, still_dead]), 1)
    if change == "touch_all":
        sampler.touch_all(2)
    if change == "fork":
        copied.forked(sampler, 0, 2, len(alive) - 50)
        sampler = copied
    law = uniform(alive) if with_law else None
    batch = draws.rows(np.arange(len(draws)))
    flagged = sampler.moved(batch, law, 3 if with_law else None)
    assert flagged.any() and (flagged.all() if change == "touch_all" else not flagged.all())
    for row in range(len(draws)):
        one = draws.rows([row])
        assert sampler.moved(one, law, 3 if with_law else None)[0] == flagged[row], row
        assert one.versions[0] == batch.versions[row], row
    if with_law and change == "touch":
        assert (batch.versions == 3).any()  # some asked again and found standing: renewed


def test_a_row_s_current_draw_is_what_its_stream_draws_now():
    """``Draws.current``: once the moved rows of a batch are drawn again and tracked (as a
    commit's check does), a row's current draw is its stream's draw now, id and examined
    slots alike: a replacement is launched from it without drawing again."""
    rng = np.random.default_rng(6)  # test data only
    alive = rng.random(COUNT) < 0.5
    sampler = StableSampler()
    sampler.restart(COUNT, 0)
    s = streams(2000)
    draws = sampler.draw(s, uniform(alive), 0)
    killed = rng.choice(np.flatnonzero(alive), 20, replace=False)
    alive = alive.copy()
    alive[killed] = False
    sampler.touch(killed, 1)
    law = uniform(alive)
    moved = np.flatnonzero(sampler.moved(draws, law, 1))
    draws.track(moved, sampler.draw(s.subset(moved), law, 1))
    now = sampler.draw(s, law, 1)
    changed = np.flatnonzero(draws.now != draws.ids)
    assert len(changed) > 10
    for row in changed:
        one = draws.current(int(row))
        assert one.ids[0] == now.ids[row] and np.array_equal(one.slots[0], now.slots[row])
        assert not sampler.moved(one, law, 1)[0]
    draws.now[changed[0]] = -1  # its id names another start (after a fork): not known
    assert draws.current(int(changed[0])) is None


def test_the_edge_table_lists_each_edge_id_once_and_reuses_freed_slots():
    # coordinator/spe_certification.py: ids that leave the edge free their slots (never
    # accepted again, so an id that comes back does not hold two), ids that join take the
    # free slots lowest first, then new ones; every such slot is touched
    from coordinator.buffers import Appendable
    from coordinator.spe_certification import SPECertification

    class Edge(SPECertification):
        def __init__(self, mask):
            self._edge_table = Appendable(np.int64, np.flatnonzero(mask))
            self._edge_slot = np.full(len(mask), -1, dtype=np.int64)
            self._edge_slot[self._edge_table.view] = np.arange(self._edge_table.size)
            self._edge_free = []  # no free slot yet (the loader lists those of a table read back)
            self._stable, self.version = StableSampler(), 0

    rng = np.random.default_rng(8)  # test data only
    mask = rng.random(300) < 0.2
    edge = Edge(mask)
    edge._stable.restart(2 * edge._edge_table.size, 0)
    for version in range(1, 40):
        new_mask = mask.copy()
        new_mask[rng.choice(np.flatnonzero(mask), 3, replace=False)] = False
        new_mask[rng.choice(np.flatnonzero(~mask), 4 if version % 2 else 1, replace=False)] = True
        if version == 20:
            new_mask = np.concatenate([new_mask, [True, False, True]])  # ids born in the edge
        leaving = edge._edge_slot[np.flatnonzero(mask & ~new_mask[: len(mask)])]
        free_slots = np.flatnonzero(edge._edge_table.view < 0)
        free_before, size_before = np.union1d(free_slots, leaving), edge._edge_table.size
        edge.version = version
        changed = np.flatnonzero(new_mask[: len(mask)] != mask)
        edge._edge_slots_moved(np.concatenate([changed, len(mask) + np.flatnonzero(new_mask[len(mask):])]), new_mask)
        joined = np.flatnonzero(new_mask & ~np.concatenate([mask, np.zeros(len(new_mask) - len(mask), bool)]))
        mask = new_mask
        table = edge._edge_table.view
        listed = table[table >= 0]
        assert np.array_equal(np.sort(listed), np.flatnonzero(mask))  # each edge id in exactly one slot
        assert np.array_equal(edge._edge_slot[listed], np.flatnonzero(table >= 0))
        assert np.array_equal(np.setdiff1d(np.arange(len(table)), edge._edge_slot[listed]), np.flatnonzero(table < 0))
        took = edge._edge_slot[joined]  # in id order: the free slots (lowest first, those freed now too), then new ones
        k = min(len(joined), len(free_before))
        assert np.array_equal(took[:k], free_before[:k])
        assert np.array_equal(took[k:], np.arange(size_before, size_before + len(joined) - k))
        assert (edge._stable.stamp[np.concatenate([took, leaving])] == version).all()
    law = TableLaw(edge._edge_table.view, mask.__getitem__)
    draws = edge._stable.draw(streams(20_000), law, 40)
    assert mask[draws.ids].all()
    counts = np.bincount(draws.ids, minlength=len(mask))[mask]
    assert stats.chisquare(counts).pvalue > 1e-3  # uniform over the edge, free slots and all
