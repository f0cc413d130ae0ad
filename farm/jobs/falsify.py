"""`scenario-farm falsify DIR`: try a proposed worst case Gamma* on the black box.

A search campaign (actions.mode = "search") proposes Gamma* in adversary.json when one
vertex family dominates. Gamma* is the worst case if no admissible action sequence makes
a run fail from a state where holding Gamma* does not. So: draw start states uniformly
over Sigma, keep those that survive the horizon under Gamma* (the Gamma*-safe starts),
and run random action sequences from Gamma from each (i.i.d. uniform, bang-bang, and
every other vertex of Gamma held). One failure refutes Gamma*; every failure is written
to falsify.json with its stream key and recorded (falsify.mcap). Not finding one is
evidence, not proof: the report says how many sequences were tried.

Keys: start state i is drawn from stream (seed, i); the Gamma* run from i has sample
index i; try k from start i has index (k + 1) * points + i.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from farm.directory.files import read_json, write_json
from farm.directory.recording import write_recording
from farm.execution.process import build_simulator, spec_of
from farm.directory.storage import CampaignDir
from scenarios.actions import ConstantActions, check_action
from scenarios.base import FAILURE
from scenarios.errors import CampaignError, ConfigError
from scenarios.rollout import run_scenario
from scenarios.search import SearchActions
from scenarios.streams import PURPOSE_START, RunStreams

RECORD_LIMIT = 64  # failures written to falsify.mcap (all are listed in falsify.json)


def proposed_gamma_star(directory: Path) -> list[list[float]]:
    """The Gamma* that the campaign in ``directory`` proposed (adversary.json)."""
    path = Path(directory) / "adversary.json"
    if not path.exists():
        raise CampaignError(f"{directory}: no adversary.json (only a finished campaign with actions.mode = 'search' "
                            f"proposes Gamma*); give one with --gamma-star")
    proposal = read_json(path).get("proposed_gamma_star")
    if not proposal:
        raise CampaignError(f"{path}: no family dominated (no weight >= 0.5), so no Gamma* was proposed; "
                            f"give one with --gamma-star")
    return proposal["actions"]


def falsify(directory, *, gamma_star=None, points: int = 10_000, tries: int = 4, seed: int | None = None,
            progress=None) -> dict:
    """Try ``gamma_star`` (a list of m numbers; default: the campaign's proposal) from
    ``points`` uniform start states with ``tries`` random sequences each; writes
    falsify.json (and falsify.mcap when something failed) in ``directory``."""
    directory = Path(directory)
    CampaignDir(directory).open("quantify")
    if not 1 <= points <= 10_000_000:
        raise ConfigError(f"--points: {points} is out of range; allowed [1, 10000000]")
    if not 1 <= tries <= 1000:
        raise ConfigError(f"--tries: {tries} is out of range; allowed [1, 1000]")
    cfg = CampaignDir(directory).frozen_config()
    seed = cfg.farm.seed if seed is None else seed
    if not 0 <= seed < 2**63:
        raise ConfigError(f"--seed: {seed} is out of range; allowed [0, 2**63)")
    simulator = build_simulator(spec_of(cfg))
    backend, scenario, horizon = simulator.backend, simulator.scenario, cfg.quantify.horizon
    star = np.asarray(check_action(gamma_star if gamma_star is not None else proposed_gamma_star(directory)[0],
                                   scenario, "--gamma-star"))
    say = progress.line if progress is not None else (lambda text: None)

    streams = RunStreams.of(seed, np.arange(points, dtype=np.uint64))
    starts = scenario.lower + (scenario.upper - scenario.lower) * streams.uniform(0, PURPOSE_START, scenario.n)
    held = run_scenario(backend, starts, horizon, ConstantActions(tuple(star)), streams)
    safe = held.outcomes != FAILURE
    safe_starts, safe_rows = starts[safe], np.nonzero(safe)[0]
    say(f"falsify: {int(safe.sum()):,} of {points:,} uniform start states survive {horizon} steps holding "
        f"Gamma* = {star.tolist()}; trying {tries} random sequences from each")

    # every family but Gamma* itself: i.i.d. uniform, bang-bang, the other vertices held
    policy = SearchActions(scenario)
    weights = np.array([0.0 if f.kind == "vertex" and np.allclose(f.vertex, star) else 1.0 for f in policy.families])
    policy.append(0, weights / weights.sum())
    found = []
    runs = 0
    for k in range(tries):
        keys = ((k + 1) * points + safe_rows).astype(np.uint64)
        tried = RunStreams.of(seed, keys)
        batch = run_scenario(backend, safe_starts, horizon, policy, tried)
        runs += len(keys)
        families = policy.family_of(tried)
        for r in np.nonzero(batch.outcomes == FAILURE)[0]:
            found.append({"key": {"seed": int(seed), "index": int(keys[r])}, "start": safe_starts[r].tolist(),
                          "family": policy.families[int(families[r])].label(), "steps": int(batch.lengths[r] - 1),
                          "trajectory": batch.trajectory(r)})
        say(f"falsify: try {k + 1}/{tries}: {len(found):,} failures so far")
    report = {"gamma_star": star.tolist(), "points": points, "gamma_star_safe": int(safe.sum()), "tries": tries,
              "runs": runs, "horizon": horizon, "seed": int(seed), "failures": len(found),
              "refuted": bool(found), "actions": policy.description,
              "counterexamples": [{k: v for k, v in f.items() if k != "trajectory"} for f in found]}
    write_json(directory / "falsify.json", report)
    if found:
        write_recording(directory / "falsify.mcap", scenario_name=scenario.name,
                        state_names=list(scenario.state_names), dt=scenario.dt,
                        runs=[{"sample_index": f["key"]["index"], "trajectory": f["trajectory"], "outcome": "failure"}
                              for f in found[:RECORD_LIMIT]],
                        metadata={"kind": "falsify counterexamples", "seed": str(seed),
                                  "gamma_star": str(star.tolist())})
    return report


def describe(directory: Path, report: dict) -> str:
    head = (f"{directory}: Gamma* = {report['gamma_star']} held from {report['gamma_star_safe']:,} of "
            f"{report['points']:,} uniform start states without failure; {report['runs']:,} random sequences "
            f"from Gamma tried from them")
    if report["refuted"]:
        first = report["counterexamples"][0]
        return (f"{head}\n  REFUTED: {report['failures']:,} failed, e.g. stream key (seed={first['key']['seed']}, "
                f"index={first['key']['index']}) from {first['start']} ({first['family']}, {first['steps']} steps)\n"
                f"  wrote {directory / 'falsify.json'} and {directory / 'falsify.mcap'}")
    return f"{head}\n  not refuted: none failed\n  wrote {directory / 'falsify.json'}"
