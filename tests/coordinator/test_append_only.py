"""A checkpoint writes the arrays an algorithm declares append-only as journal segments
of their new rows (farm/directory/journal.py), so a declared array must only gain rows within a
state epoch: a saved row that changed would be restored wrong. Checked on real campaigns
(uniform actions; Gamma* with deterministic certification, whose certificates are
append-only too; Gamma* refined by margins, whose partition only gains boxes) by comparing every chunk's state with the previous one."""


import numpy as np
import pytest

from farm import config as config_mod
from farm.execution.local import LocalExecutor
from farm.execution.process import build_simulator, spec_of
from farm.jobs.campaign_setup import build_algorithm, build_campaign


@pytest.mark.parametrize("algorithm,mode,refine", [("spe", "uniform", "auto"), ("spe", "adversarial", "all"),
                                                   ("spe", "adversarial", "margin"), ("ae", "uniform", "auto")])
def test_declared_append_only_arrays_only_gain_rows(algorithm, mode, refine):
    cfg = config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": mode},
        "quantify": {"algorithm": algorithm, "delta0": 4.0, "delta_min": 1.0, "epsilon": 0.01, "beta": 0.1,
                     "horizon": 30, "refine": refine},
        "farm": {"executor": "local", "batch_size": 128, "seed": 1}})  # many chunks, so many comparisons
    sim = build_simulator(spec_of(cfg))
    algo = build_algorithm(cfg, sim)
    seen = {"previous": None, "compared": 0, "grown": set()}

    def check(_campaign) -> None:
        state = {k: np.array(v, copy=True) for k, v in algo.state().items()}
        previous, seen["previous"] = seen["previous"], (algo.state_epoch, state)
        if previous is None or previous[0] != algo.state_epoch:
            return
        for name in algo.append_only:
            before, after = previous[1][name], state[name]
            assert len(after) >= len(before), name
            assert np.array_equal(after[: len(before)], before), f"{name}: a saved row changed"
            if len(after) > len(before):
                seen["grown"].add(name)
        seen["compared"] += 1

    build_campaign(cfg, algo, sim, LocalExecutor(spec_of(cfg)), observers=[check]).run()
    assert seen["compared"] > 20
    assert seen["grown"]  # the check looked at arrays that did grow
    if refine == "margin":  # the partition's boxes were journalled
        assert {"part.lo", "part.hi"} <= seen["grown"]
    elif mode == "adversarial":  # certification ran and its entries were journalled
        assert {"cert.vertex", "cert.offsets", "cert.witness"} <= seen["grown"]
