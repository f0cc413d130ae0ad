"""A closing round's edge kept change by change (coordinator/closing_edge.py) is, at
every change, the edge computed whole: the same closing law, so the same draws."""

from __future__ import annotations

import numpy as np
import pytest

from coordinator.closing_edge import EdgeMembership
from coordinator.spe_certification import SPECertification
from farm import config as config_mod
from farm.execution.local import LocalExecutor
from farm.execution.process import spec_of
from farm.jobs.campaign_setup import build_algorithm, build_campaign


def _certified(seed: int):
    cfg = config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": "uniform"},
        "quantify": {"delta0": 4.0, "delta_min": 1.0, "epsilon": 0.001, "beta": 0.1, "horizon": 30},
        "farm": {"executor": "local", "seed": seed, "batch_size": 256}})
    executor = LocalExecutor(spec_of(cfg))
    algo = build_algorithm(cfg, executor.simulator)
    build_campaign(cfg, algo, executor.simulator, executor).run()
    return algo


@pytest.mark.parametrize("seed", [0, 1])
def test_the_edge_kept_by_change_is_the_edge_computed_whole_at_every_change(monkeypatch, seed):
    kept = SPECertification._edge_mask
    seen = {"by_change": 0, "moved": 0}

    def checked(self):
        fresh = self._edge is None or self._edge[0] != self.version
        by_change = fresh and self._edge_track is not None
        before = None if self._edge is None else self._edge[1].copy()  # (the mask is a view the change writes into)
        mask = kept(self)
        if by_change:
            assert np.array_equal(mask, self.edge_whole()), f"version {self.version}"
            seen["by_change"] += 1
            seen["moved"] += before is not None and (len(before) != len(mask) or not np.array_equal(before, mask))
        return mask

    monkeypatch.setattr(SPECertification, "_edge_mask", checked)
    algo = _certified(seed)
    assert algo.certifying
    # closing rounds ran, and their changes moved the edge (ids joined or left it)
    assert seen["by_change"] >= 20 and seen["moved"] >= 10, seen


def test_an_update_names_exactly_the_ids_whose_membership_changed_and_counts_the_members():
    rng = np.random.default_rng(3)
    core = rng.random(1000) < 0.2
    track = EdgeMembership(1.0, 2.0, core)
    truth = core.copy()
    for _ in range(20):
        count = len(truth) + int(rng.integers(0, 30))
        truth = np.concatenate([truth, np.zeros(count - len(truth), dtype=bool)])
        track.touched.append(rng.integers(0, count, 5))
        ids = track.candidates(count, rng.integers(0, count, 7))
        assert np.array_equal(ids, np.unique(ids))  # sorted, once each
        if count > track.count:  # the ids new since are candidates
            assert ids[-1] == count - 1
        member = rng.random(len(ids)) < 0.5
        moved = track.update(ids, member, count)
        assert np.array_equal(moved, ids[truth[ids] != member])
        truth[ids] = member
        assert np.array_equal(track.core(), truth) and track.size == np.count_nonzero(truth)
