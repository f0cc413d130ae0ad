"""What every quantification algorithm promises when its campaign is done: ``stop_committing``
leaves the state whole (the last checkpoint gathers it after), and ``release`` leaves the
answers (``result``, ``counts``, ``failure_points``) as they were. Real campaigns, every
algorithm (SPE also with deterministic certification, whose certificates it drops)."""


import numpy as np
import pytest

from farm import config as config_mod
from farm.execution.local import LocalExecutor
from farm.execution.process import build_simulator, spec_of
from farm.jobs.campaign_setup import build_algorithm, build_campaign


@pytest.mark.parametrize("algorithm,mode,refine", [("spe", "uniform", "auto"), ("spe", "adversarial", "all"),
                                                   ("spe", "adversarial", "margin"), ("ae", "uniform", "auto"),
                                                   ("delta-pruning", "uniform", "auto"), ("vs", "uniform", "auto")])
def test_a_done_algorithm_keeps_its_state_until_released_and_its_answers_after(algorithm, mode, refine):
    cfg = config_mod.normalize({
        "scenario": {"name": "lead-follow", "sv_policy": "idm"}, "actions": {"mode": mode},
        "quantify": {"algorithm": algorithm, "delta0": 4.0, "delta_min": 2.0, "epsilon": 0.01, "beta": 0.1,
                     "horizon": 30, "budget": 3_000, "refine": refine},  # vs may draw box after box: done by the budget
        "farm": {"executor": "local", "batch_size": 256, "seed": 1}})
    sim = build_simulator(spec_of(cfg))
    algo = build_algorithm(cfg, sim)
    counters = build_campaign(cfg, algo, sim, LocalExecutor(spec_of(cfg))).run()
    assert counters.done
    state = {k: np.array(v, copy=True) for k, v in algo.state().items()}
    answers = (algo.result(), algo.counts(), algo.failure_points())
    algo.stop_committing()
    after = algo.state()
    assert after.keys() == state.keys()
    assert all(np.array_equal(after[k], v) for k, v in state.items())
    algo.release()
    safe_set, counts, failures = algo.result(), algo.counts(), algo.failure_points()
    assert np.array_equal(safe_set.centres, answers[0].centres) and safe_set.result_hash == answers[0].result_hash
    assert counts == answers[1]
    assert np.array_equal(failures, answers[2])
    if mode == "adversarial":  # certification ran: the certified count survives the release
        assert (algo.enumerates or refine == "margin") and counts["certified"] == counts["boxes"] > 0
