"""A quantification campaign in a directory: check, start, checkpoint, stop, resume, finish.

``run`` reads top to bottom: check the directory and the config, build one facet campaign
per set of failure facets (farm/facet_campaign.py: the total, and fleet3's sides), run
each (checkpointing as it goes, farm/checkpoint.py), then write the results. A resumed
campaign re-simulates exactly what it had drawn and reaches the very result an
uninterrupted run reaches. SIGINT and SIGTERM stop it at the next chunk boundary with a
checkpoint (farm/signals.py).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from coordinator.results import result_hash
from coordinator.volume import hull_volume, union_volume
from farm import config as config_mod
from farm.campaign_setup import side_facets, spec_of
from farm.config import Config
from farm.facet_campaign import FacetCampaign, Stopped
from farm.files import write_json, write_safe_set
from farm.progress import Progress
from farm.resources import check_quantify
from farm.simulators import build_simulator
from farm.status import StatusWriter
from farm.storage import CampaignDir, CampaignError
from scenarios.version import __version__

__all__ = ["Stopped", "run"]


def run(cfg: Config, out: Path, *, resume: bool = False, force: bool = False, progress: Progress | None = None,
        config_text: str | None = None) -> dict:
    """Run (or continue) the campaign of ``cfg`` in directory ``out``; -> summary.

    Everything is checked before anything is written: the config, the scenario, the back
    end, the actions, and when resuming the checkpoints. ``resume`` continues a stopped or
    killed campaign (a finished one is left untouched and its summary returned); ``force``
    replaces a campaign directory. ``config_text``: the config as the user gave it (kept
    as ``config.toml``)."""
    out = Path(out)
    progress = progress or Progress(enabled=False)
    directory = CampaignDir(out)
    directory.check_writable()
    if resume and directory.nothing_started():
        # killed before its first file: "continue" means start (a plain `resume DIR` has no
        # config to start from and still says "not a campaign directory")
        resume, force = False, True
    if resume:
        directory.open("quantify")
        _refuse_a_changed_config(directory, cfg)
        finished = directory.finished_summary()
        if finished is not None:
            return finished
    scenario = build_simulator(spec_of(cfg)).scenario
    check_quantify(cfg, scenario.lower, scenario.upper)
    facets = [FacetCampaign(cfg, label, out if label == "total" else out / "sides" / label, failure_facets)
              for label, failure_facets in side_facets(cfg, scenario).items()]
    status = StatusWriter(out)
    try:
        if resume:
            directory.lock(announce=False)
            for facet in facets:  # every checkpoint is checked before anything is written
                facet.restore()
            directory.announce()
            directory.remove_stale_temp_files()
        else:
            directory.create("quantify", force=force)
            directory.freeze_config(cfg, config_text)
        for facet in facets:
            facet.run(progress, status)
        progress.close()
        status.write({"state": "finishing"})
        summary = finish(cfg, out, {facet.label: facet for facet in facets})
        status.write({"state": "done", "result_hash": summary["result_hash"]})
        return summary
    finally:
        directory.unlock()


def _refuse_a_changed_config(directory: CampaignDir, cfg: Config) -> None:
    changed = config_mod.changed_fields(directory.frozen_config(), cfg)
    if changed:
        raise CampaignError(f"{directory.path}: the config differs from the campaign's frozen config in "
                            f"{', '.join(changed)}; only settings that cannot change a result may change on "
                            f"resume (farm.workers, farm.executor, farm.address, and with sequential counting "
                            f"farm.batch_size and farm.pipeline_depth)")


def guarantee_of(cfg: Config, part: FacetCampaign, delta: float):
    """The plain and formal guarantee of a finished campaign part (coordinator/guarantee.py)."""
    from coordinator.guarantee import quantified

    q, campaign, algo = cfg.quantify, part.campaign, part.algorithm
    certified = campaign.certify and algo.certifying
    return quantified(part.scenario, part.policy, epsilon=q.epsilon, beta=q.beta, delta=delta, horizon=q.horizon,
                      n_eps=campaign.n_eps, attempts=campaign.counters.attempts if certified else 0,
                      n_final=campaign.quiet_needed() if certified else campaign.n_eps,
                      converged=campaign.counters.converged, budget=q.budget,
                      enumerated=certified and algo.enumerates, boxes=algo.vertices.alive_count,
                      uniform=certified, distribution=campaign.final_distribution,
                      escaped=campaign.counters.escaped_in_streak, adversarial=cfg.actions.mode == "adversarial")


def finish(cfg: Config, out: Path, parts: dict[str, FacetCampaign]) -> dict:
    part = parts["total"]
    campaign, scenario = part.campaign, part.scenario
    centres, h = part.algorithm.result()
    centres = centres[np.lexsort(centres.T[::-1])]
    c = campaign.counters
    chash = config_mod.config_hash(cfg)
    rhash = result_hash(centres, h)
    bounds = (scenario.lower, scenario.upper)
    counters = [p.campaign.counters for p in parts.values()]
    summary = {
        "scenario": cfg.scenario.name,
        "sv_policy": scenario.sv_policy_name,
        "backend": cfg.scenario.backend,
        "algorithm": cfg.quantify.algorithm,
        "epsilon": cfg.quantify.epsilon,
        "beta": cfg.quantify.beta,
        "n_eps": campaign.n_eps,
        # a sampled certification's attempts, and the quiet runs its last one needed
        # (beta split over attempts); 0 and n_eps without certification
        "certification_attempts": c.attempts,
        "n_eps_final": campaign.quiet_needed() if c.attempts and not part.algorithm.enumerates else campaign.n_eps,
        "delta_final": h,
        "rounds": c.rounds_completed,
        "converged": c.converged,
        "runs_committed": sum(k.committed for k in counters),
        "runs_simulated": sum(k.runs_simulated for k in counters),
        "runs_dropped": sum(k.runs_dropped for k in counters),
        "runs_replaced": sum(k.runs_replaced for k in counters),
        "runs_discarded": sum(k.runs_discarded for k in counters),
        "steps_simulated": sum(k.steps_simulated for k in counters),
        "boxes": int(len(centres)),
        "volume_union": union_volume(centres, h, bounds=bounds),
        "volume_hull": hull_volume(centres, h, bounds=bounds),
        "volume_sigma": scenario.volume,
        "seed": cfg.farm.seed,
        "config_hash": chash,
        "result_hash": rhash,
        "elapsed_s": round(sum(k.elapsed_s for k in counters), 3),
        "startup_s": round(sum(p.startup_s for p in parts.values()), 3),
        "guarantee": (g := guarantee_of(cfg, part, h)).plain,
        "guarantee_formal": g.formal,
        "actions": part.policy.description,
        "failure_facets": list(scenario.failure_facets),
        "round_ends": list(c.round_ends),
        "scenario_farm_version": __version__,
    }
    for label, side in parts.items():
        if label == "total":
            continue
        sc, sh = side.algorithm.result()
        summary[f"volume_{label}_side"] = union_volume(sc, sh, bounds=bounds)
        summary[f"volume_hull_{label}_side"] = hull_volume(sc, sh, bounds=bounds)
        summary[f"result_hash_{label}_side"] = result_hash(sc, sh)
        gs = guarantee_of(cfg, side, sh)
        summary[f"guarantee_{label}_side"], summary[f"guarantee_formal_{label}_side"] = gs.plain, gs.formal
        write_safe_set(out / f"safe_set_{label}_side.parquet", sc, sh, side.scenario.state_names,
                       {"config_hash": chash, "side": label})
    write_safe_set(out / "safe_set.parquet", centres, h, scenario.state_names,
                   {"config_hash": chash, "result_hash": rhash})
    for label, p in parts.items():
        if p.campaign.adversary is not None:
            name = "adversary.json" if label == "total" else f"adversary_{label}_side.json"
            write_json(out / name, p.campaign.adversary.report(p.scenario))
    write_json(out / "summary.json", summary)
    from farm.plots import draw

    draw(out / "plots", scenario, centres, h, summary)
    for label, side in parts.items():
        if label != "total":
            sc, sh = side.algorithm.result()
            draw(out / "plots" / f"{label}_side", side.scenario, sc, sh, {**summary, "algorithm": f"{label} side"})
    return summary
