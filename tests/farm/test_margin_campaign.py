"""Margin refinement as a campaign: the default for one adversarial action, the same set on
any executor and after a stop and resume, a certificate that holds when checked from
outside, and an exported set that validate certifies."""

import json
import subprocess
import sys

import numpy as np
import pytest

from coordinator.box_index import BoxIndex
from coordinator.safe_set import SafeSet
from farm.config import parse
from farm.jobs.quantification import run
from farm.jobs.side_campaign import SideCampaign
from scenarios.base import FAILURE
from scenarios.errors import Stopped
from scenarios.simulator import SimSpec, Simulator

TOML = """
[scenario]
name = "lead-follow"
sv_policy = "idm"
[actions]
mode = "adversarial"
[quantify]
delta0 = 2.0
delta_min = 0.5
holdout_runs = 500
[farm]
executor = "{executor}"
workers = 2
"""
NAMES = ("v0", "v1", "p10")


def _summary(directory):
    return json.loads((directory / "summary.json").read_text())


def test_a_deterministic_campaign_refines_by_margins_and_its_certificate_holds(tmp_path):
    s = run(parse(TOML.format(executor="local")), tmp_path / "c")
    assert s.refine == "margin" and s.converged and s.holdout["runs"] == 500
    safe = SafeSet.from_parquet(tmp_path / "c" / "safe_set.parquet", NAMES)
    assert safe.anisotropic and safe.disjoint and safe.result_hash == s.result_hash
    # the certificate, checked from outside: each centre's run does not fail and stays
    # within the covering margin (delta_min) of the set's boxes
    margin = float(safe.metadata["covering_margin"])
    batch = Simulator(SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "adversarial"}, 50, 0)) \
        .simulate(0, safe.centres)
    assert not (batch.outcomes == FAILURE).any()
    states, _ = batch.visited()
    assert BoxIndex(safe.lower - margin, safe.upper + margin).contains(states).all()
    # the set is right where it counts: against the model's reference on random states
    x = np.random.default_rng(0).uniform([0, 0, 0], [20, 20, 70], (20_000, 3))
    reference = Simulator(SimSpec({"name": "lead-follow", "sv_policy": "idm"}, {"mode": "adversarial"}, 50, 0)) \
        .scenario.reference_safe(x)
    claimed = safe.contains(x)
    assert (claimed & reference).sum() / (claimed | reference).sum() > 0.985
    for algorithm in ("delta", "eps-delta"):  # and validate certifies it, as exported
        (tmp_path / "v.toml").write_text(
            f'[scenario]\nname = "lead-follow"\nsv_policy = "idm"\n[actions]\nmode = "adversarial"\n'
            f'[validate]\nalgorithm = "{algorithm}"\ndelta = 0.5\ndomain_set = "{tmp_path / "c" / "safe_set.parquet"}"\n'
            f'[farm]\nexecutor = "local"\nseed = 7\n')
        r = subprocess.run([sys.executable, "-m", "farm", "validate", str(tmp_path / "v.toml")], capture_output=True,
                           text=True, timeout=600)
        assert r.returncode == 0, r.stdout + r.stderr


def test_the_same_set_on_two_ray_workers(tmp_path, ray_local):
    local = run(parse(TOML.format(executor="local")), tmp_path / "local")
    ray = run(parse(TOML.format(executor="ray")), tmp_path / "ray")
    assert ray.result_hash == local.result_hash and ray.runs_committed == local.runs_committed


def test_a_campaign_stopped_in_a_wave_resumes_to_the_same_set(tmp_path, monkeypatch):
    whole = run(parse(TOML.format(executor="local")), tmp_path / "whole")
    observer = SideCampaign._observer

    def stop_in_the_third_wave(self, progress, status):
        observe = observer(self, progress, status)

        def then_stop(campaign):
            observe(campaign)
            if campaign.algorithm.round >= 2 and 0 < campaign.algorithm.wave_done < len(campaign.algorithm.wave):
                self.save()
                campaign.stop()

        return then_stop

    monkeypatch.setattr(SideCampaign, "_observer", stop_in_the_third_wave)
    with pytest.raises(Stopped):
        run(parse(TOML.format(executor="local") + "batch_size = 64\n"), tmp_path / "stopped")
    monkeypatch.setattr(SideCampaign, "_observer", observer)
    resumed = run(parse(TOML.format(executor="local") + "batch_size = 64\n"), tmp_path / "stopped", resume=True)
    assert resumed.result_hash == whole.result_hash and resumed.runs_committed == whole.runs_committed


def test_parameter_axes_narrower_than_delta0_are_refined_once_delta_allows(tmp_path):
    # T (range 1.2) and mu (0.6) fit in one box at delta0 = 2: no neighbour shows the margin's
    # change along them, so only the split rule's spans-Sigma clause refines them (before it,
    # the set claimed every T and mu from runs at their middle: half-widths 0.6 and 0.3)
    toml = TOML.format(executor="local").replace('name = "lead-follow"', 'name = "lead-follow-params"') \
        .replace("holdout_runs = 500", "horizon = 120\nholdout_runs = 0")
    s = run(parse(toml), tmp_path / "p")
    assert s.refine == "margin" and s.converged
    safe = SafeSet.from_parquet(tmp_path / "p" / "safe_set.parquet", ("v0", "v1", "p10", "T", "mu"))
    widths = safe.axis_half_widths
    assert widths[:, 3].max() <= 0.3 + 1e-9  # T split once: 0.6 -> 0.3
    assert np.allclose(widths[:, 4], 0.3)  # mu's whole range is narrower than delta_min: the user's resolution
