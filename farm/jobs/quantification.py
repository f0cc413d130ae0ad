"""A quantification campaign in a directory: check, start, checkpoint, stop, resume, finish.

``run`` reads top to bottom: check the directory and the config, build one campaign per
side (farm/jobs/side_campaign.py: the total, and fleet3's sides), run
each (checkpointing as it goes, farm/directory/checkpoint.py), then write the results. A resumed
campaign re-simulates exactly what it had drawn and reaches the very result an
uninterrupted run reaches. SIGINT and SIGTERM stop it at the next chunk boundary with a
checkpoint (farm/jobs/signals.py).
"""

from __future__ import annotations

from dataclasses import replace
from functools import partial
from pathlib import Path

from coordinator.guarantee import quantified, refined
from coordinator.margin.refinement import MarginRefinement
from coordinator.safe_set import SafeSet
from farm import config as config_mod
from farm import lazy
from farm.config import Config
from farm.directory.files import atomic_write, write_json
from farm.directory.storage import CampaignDir, CampaignError
from farm.execution.process import build_simulator, close_simulator, spec_of
from farm.jobs.campaign_setup import side_facets
from farm.jobs.resources import check_quantify
from farm.jobs.side_campaign import SideCampaign, Stopped
from farm.reports.progress import Progress
from farm.reports.status import StatusWriter, read_status
from farm.reports.summary import Summary, budget_used_up, summarize
from scenarios.errors import InfrastructureError

__all__ = ["Stopped", "run"]


def run(cfg: Config, out: Path, *, resume: bool = False, force: bool = False, progress: Progress | None = None,
        config_text: str | None = None) -> Summary:
    """Run (or continue) the campaign of ``cfg`` in directory ``out``; -> its summary.json.

    Everything is checked before anything is written: the config, the scenario, the back
    end, the actions, and when resuming the checkpoints. ``resume`` continues a stopped or
    killed campaign (a finished one is left untouched and its summary returned, but for
    the figures and final status a kill while finishing left unwritten); ``force``
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
    finished = None
    if resume:
        directory.open("quantify")
        _refuse_a_changed_config(directory, cfg)
        finished = Summary.finished(out)
        if finished is not None and not finishing_interrupted(out):
            return finished
    checked = build_simulator(spec_of(cfg))
    close_simulator(checked, cfg.farm.chunk_timeout)  # the config check's simulator: a close that hangs, named now
    scenario = checked.scenario
    check_quantify(cfg, scenario.lower, scenario.upper)
    sides = [SideCampaign(cfg, side, out if side == "total" else out / "sides" / side, failure_facets)
             for side, failure_facets in side_facets(cfg, scenario).items()]
    if len(sides) > 1:
        progress.line(sides_line(scenario.name, [side.side for side in sides[1:]]))
    status = StatusWriter(out)
    try:
        if finished is not None:
            # killed while finishing, after summary.json (the last result file before the
            # figures): the figures and the final status are all that is left to write
            directory.lock()
            directory.remove_stale_temp_files()
            draw({side.side: side.scenario for side in sides}, out, _saved_safe_sets(out, sides), finished)
            status.write({"state": "done", "result_hash": finished.result_hash})
            return finished
        if resume:
            directory.lock(announce=False)
            for side in sides:  # every checkpoint is checked before anything is written
                side.restore(progress.line)
            directory.announce()
            directory.remove_stale_temp_files()
        else:
            directory.create("quantify", force=force)
            directory.freeze_config(cfg, config_text)
        for side in sides:
            side.run(progress, status)
        progress.close(_ending(cfg, sides))
        status.write({"state": "finishing"})
        summary = finish(cfg, out, {side.side: side for side in sides})
        status.write({"state": "done", "result_hash": summary.result_hash})
        return summary
    finally:
        directory.unlock()


def _ending(cfg: Config, sides: list[SideCampaign]) -> str:
    """How the runs ended: all done, or the budget used up (then nothing is certified)."""
    spent = [side.campaign.counters for side in sides if not side.campaign.counters.converged]
    if not spent:
        return "all runs done"
    return budget_used_up(cfg.quantify.budget, sum(c.committed for c in spent), sum(c.runs_simulated for c in spent))


def sides_line(scenario: str, names: list[str]) -> str:
    """The start line of a campaign with sides: they are campaigns of their own, which a
    user who only named the scenario did not ask for by name."""
    return (f"sides: scenario {scenario!r} declares sides {', '.join(names)}: {1 + len(names)} campaigns, the total "
            f"then each side's, up to about {1 + len(names)}x the runs of the total alone (platoon with 4 vehicles, 7-D: "
            f"2.2x; runs_committed sums them); quantify.sides = false quantifies the total only")


def _refuse_a_changed_config(directory: CampaignDir, cfg: Config) -> None:
    changed = config_mod.changed_fields(directory.frozen_config(), cfg)
    if changed:
        raise CampaignError(f"{directory.path}: the config differs from the campaign's frozen config in "
                            f"{', '.join(changed)}; only settings that cannot change a result may change on "
                            f"resume (farm.workers, farm.executor, farm.address, and with sequential counting "
                            f"farm.batch_size and farm.pipeline_depth)")


def guarantee_of(cfg: Config, side: SideCampaign, delta: float):
    """The plain and formal guarantee of a finished side's campaign (coordinator/guarantee.py)."""
    q, campaign, algo = cfg.quantify, side.campaign, side.algorithm
    if isinstance(algo, MarginRefinement):
        result = algo.result()
        return refined(side.scenario, side.policy, horizon=q.horizon, boxes=len(result), covering=algo.covering,
                       finest=result.finest, coarsest=result.coarsest, converged=campaign.counters.converged,
                       budget=q.budget)
    certified = campaign.certify and algo.certifying
    return quantified(side.scenario, side.policy, epsilon=q.epsilon, beta=q.beta, delta=delta, horizon=q.horizon,
                      n_eps=campaign.n_eps, attempts=campaign.counters.attempts if certified else 0,
                      n_final=campaign.quiet_needed() if certified else campaign.n_eps,
                      converged=campaign.counters.converged, budget=q.budget,
                      enumerated=certified and algo.enumerates, boxes=algo.vertices.alive_count,
                      uniform=certified, distribution=campaign.final_distribution,
                      escaped=campaign.counters.escaped_in_streak, adversarial=cfg.actions.mode == "adversarial",
                      coarsest=algo.result().coarsest if q.refine == "band" else None,
                      tolerance=q.certify_tolerance if certified else 0,
                      seen=campaign.counters.check_violations if certified else 0)


def finish(cfg: Config, out: Path, sides: dict[str, SideCampaign]) -> Summary:
    """The result files of finished side campaigns: the safe sets, summary.json, the
    adversary's report and the figures."""
    safe_sets = {name: side.algorithm.result() for name, side in sides.items()}
    safe_sets["total"] = safe_sets["total"].sorted()
    summary = summarize(cfg, sides, safe_sets,
                        {name: guarantee_of(cfg, side, safe_sets[name].finest) for name, side in sides.items()})
    for name, safe_set in safe_sets.items():
        if name == "total":
            file, meta = "safe_set.parquet", {"config_hash": summary.config_hash, "result_hash": summary.result_hash}
        else:
            file, meta = f"safe_set_{name}_side.parquet", {"config_hash": summary.config_hash, "side": name}
        atomic_write(out / file, partial(safe_set.to_parquet, metadata=meta))
    for name, side in sides.items():
        if side.campaign.adversary is not None:
            file = "adversary.json" if name == "total" else f"adversary_{name}_side.json"
            write_json(out / file, side.campaign.adversary.report(side.scenario))
    summary.write(out)  # the last result file: once it is there, a resume only draws (finishing_interrupted)
    draw({name: side.scenario for name, side in sides.items()}, out, safe_sets, summary)
    return summary


def draw(scenarios: dict, out: Path, safe_sets: dict, summary: Summary) -> None:
    """The figures of a finished campaign: ``scenarios`` and ``safe_sets``, side -> its
    scenario and its set ("total" and fleet3's sides). Drawn last, after the set and
    summary.json: a drawing that runs out of memory (a large set under ``ulimit -v``)
    loses no result, and the status left at "finishing" lets ``resume`` draw again."""
    try:
        for name, scenario in scenarios.items():
            if name == "total":
                lazy.plots.draw(out / "plots", scenario, safe_sets[name], summary)
            else:
                lazy.plots.draw(out / "plots" / f"{name}_side", scenario, safe_sets[name],
                                replace(summary, algorithm=f"{name} side"))
    except MemoryError:
        raise InfrastructureError(
            f"out of memory while drawing {out / 'plots'}: the set ({len(safe_sets['total']):,} boxes) and "
            f"summary.json are written; resume draws the figures (with more memory)") from None


def finishing_interrupted(out: Path) -> bool:
    """Was the campaign in ``out`` stopped after its summary.json and before its figures
    and final status (a kill while finishing)? Then a resume finishes it."""
    return (read_status(out) or {}).get("state") == "finishing"


def _saved_safe_sets(out: Path, sides: list[SideCampaign]) -> dict:
    """The sets ``finish`` wrote, read back (side -> SafeSet)."""
    return {side.side: SafeSet.from_parquet(out / ("safe_set.parquet" if side.side == "total"
                                                    else f"safe_set_{side.side}_side.parquet"),
                                            side.scenario.state_names)
            for side in sides}
