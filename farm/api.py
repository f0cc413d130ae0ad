"""The Python API: everything the CLI does, as documented functions.

    from farm import quantify, validate, compare, open_campaign

    result = quantify("examples/lead_follow_idm.toml", out="runs/lf-idm")
    result.volume_union, result.guarantee           # figures and the guarantee
    result.contains([[10.0, 10.0, 40.0]])           # is this state in the safe set?
    cert = validate({"scenario": {"name": "lead-follow", "sv_policy": "brake"},
                     "validate": {"domain_set": "runs/lf-idm/safe_set.parquet"}})
    cert.certified, cert.guarantee, cert.statement  # plain words, the paper's terms

A config is a path to a TOML file, a TOML string, a dict or a ``farm.config.Config``.
What these functions write is a normal campaign directory: every CLI command accepts it.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from farm import config as config_mod, lazy
from farm.config import Config
from farm.directory.storage import CampaignError
from farm.reports.certificate import Certificate
from farm.reports.estimate_report import EstimateReport
from farm.reports.progress import Progress
from farm.reports.result import QuantifyResult
from farm.reports.summary import Summary
from coordinator.safe_set import SafeSet

__all__ = ["Certificate", "EstimateReport", "QuantifyResult", "SafeSet", "Summary", "compare", "estimate",
           "export_openscenario", "falsify",
           "load_config", "open_campaign", "overlay", "plan", "quantify", "validate"]


def load_config(source, **overrides) -> Config:
    """A checked config from a TOML path or string, a dict or a Config; keyword
    overrides name fields as ``section__key`` (``farm__workers=4``)."""
    cfg = config_mod.load(source)
    if overrides:
        cfg = cfg.with_overrides({k.replace("__", "."): v for k, v in overrides.items()})
    return cfg


# -- quantification -----------------------------------------------------------------------
def quantify(config, out=None, *, resume: bool = False, force: bool = False, progress: bool = False,
             **overrides) -> QuantifyResult:
    """Find the maximal safe set of ``config`` (a quantification campaign) in directory
    ``out`` (default: a new temporary directory). ``resume`` continues a stopped
    campaign in ``out``; ``force`` replaces a campaign directory there. Keyword
    overrides as in ``load_config`` (``farm__executor="ray"``)."""
    text = config_mod.read_text(config) if isinstance(config, (str, Path)) and _is_file(config) else None
    cfg = load_config(config_mod.parse(text, str(config)) if text is not None else config, **overrides)
    out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="scenario-farm-")) / "campaign"
    lazy.quantification.run(cfg, out, resume=resume, force=force, progress=Progress(enabled=progress),
                            config_text=text)
    return QuantifyResult.load(out)


def plan(config, out=None, *, workers=(1, 32, 256), force: bool = False, run_time: float | None = None,
         call_cost: float | None = None, jitter: float | None = None, progress: bool = False, **overrides) -> dict:
    """Plan a cluster: run ``config`` on the virtual farm (the real coordinator on a
    simulated clock) at each count of ``workers``, in directory ``out`` (default: a new
    temporary directory; ``force`` replaces a plan directory there), each count a normal
    quantify campaign in ``out/workers-<W>``. ``run_time``, ``call_cost`` and ``jitter``
    override ``[farm.virtual]``. Returns the plan (``plan.json``): per count the simulated
    time to the result, the speed-up over the fewest workers, the workers' utilisation,
    the runs and the result hash; and ``recommended_workers``, the fewest within 10 % of
    the fastest. ``plan.png`` draws the time against the workers."""
    cfg = load_config(config, **overrides)
    out = Path(out) if out is not None else Path(tempfile.mkdtemp(prefix="scenario-farm-")) / "plan"
    return lazy.planning.plan(cfg, out, workers, force=force, run_time=run_time, call_cost=call_cost,
                              jitter=jitter, progress=Progress(enabled=progress))


def open_campaign(directory) -> QuantifyResult:
    """The result of a finished campaign directory."""
    return QuantifyResult.load(directory)


def _is_file(source) -> bool:
    try:
        return Path(source).is_file()
    except (OSError, ValueError):
        return False


# -- validation ------------------------------------------------------------------------------
def validate(config, *, out=None, force: bool = False, progress=None, **overrides) -> Certificate:
    """Certify the domain of ``config``'s [validate] section or find the first
    counterexample; with ``out``, write certificate.json (and counterexample.mcap);
    ``progress(done, total)`` is told the runs committed (farm/jobs/validation.py)."""
    return lazy.validation.run(load_config(config, **overrides), out, force=force, progress=progress)


# -- a failure rate beside the set ------------------------------------------------------------
def estimate(target, config=None, *, name: str | None = None, resume: bool = False, force: bool = False,
             progress=False, **overrides) -> EstimateReport:
    """P(failure) of runs started from a scenario distribution D, with an interval, beside
    the finished campaign ``target`` (directory or QuantifyResult), on its executors
    (farm/jobs/estimation.py). D, the strata and the stopping rule are the campaign's
    [estimate] section, or ``config``'s (a TOML path or string, or a dict, holding an
    [estimate] table only); keyword overrides as in ``load_config`` (``estimate__runs=20000``,
    ``estimate__strata="none"`` for plain Monte Carlo, ``estimate__versus={"sv_policy":
    "brake"}`` for a paired comparison, ``farm__executor="ray"``). Writes
    ``DIR/estimates/<name>/`` (estimate.json, the runs' ledger, failures.png; ``name``
    default: "stratified", "plain", with "-vs-<controller>" for a comparison); ``resume``
    continues a stopped or killed one, ``force`` replaces one. ``progress``: True or a
    farm.reports.progress.Progress. Returns estimate.json as an ``EstimateReport``."""
    directory = target.directory if isinstance(target, QuantifyResult) else Path(target)
    cfg = lazy.estimation.estimate_config(directory, config, {k.replace("__", "."): v for k, v in overrides.items()})
    shown = progress if isinstance(progress, Progress) else Progress(enabled=bool(progress))
    return lazy.estimation.run(cfg, directory, name=name, resume=resume, force=force, progress=shown)


# -- comparison -------------------------------------------------------------------------------
def overlay(results, path) -> Path:
    """Two or more campaigns of one scenario on the same slices (like the paper's Fig. 2:
    brake against idm); ``results``: directories or QuantifyResults."""
    results = [r if isinstance(r, QuantifyResult) else open_campaign(r) for r in results]
    names = {r.summary.scenario for r in results}
    if len(names) != 1:
        raise CampaignError(f"overlay: the campaigns quantify different scenarios ({', '.join(sorted(names))})")
    labels = [f"{r.summary.sv_policy} / {r.summary.actions} ({r.directory.name})" for r in results]
    return lazy.plots.draw_overlay(Path(path), results[0]._scenario(), [r.safe_set for r in results], labels)


def compare(target, *, grid: int | None = None, grid_total: int | None = None, estimate_only: bool = False,
            progress=None, points: int | None = None) -> dict:
    """A finished campaign (directory or QuantifyResult) against the reference safe set:
    IoU, precision, recall, Hausdorff; writes compare.json and plots/compare.png. The
    reference grid: ``grid`` points per axis or ``grid_total`` points in all (default
    ~1.5e6 for a model reference, 24^3 for one simulated with a black-box back end), or
    ``points`` states uniform in Sigma (the default, 200,000, above 5 axes): IoU,
    precision and recall then with exact 95 % intervals (``<name>_interval``).
    ``progress`` (a farm.reports.progress.Progress) is told the runs it will take and the time
    estimated from a first batch before the rest; ``estimate_only`` returns that plan
    ({"reference_runs", "figure_runs", "estimated_s", ...}) and writes nothing."""
    directory = target.directory if isinstance(target, QuantifyResult) else Path(target)
    return lazy.compare.compare(directory, grid=grid, grid_total=grid_total, estimate_only=estimate_only,
                                progress=progress, points=points)


def export_openscenario(target, *, force: bool = False) -> dict:
    """A campaign's failing runs and certified set as ASAM OpenSCENARIO files in
    DIR/openscenario/ (farm/openscenario/export.py): each recorded failing run or
    validation counterexample as a concrete scenario (``run-<index>.xosc``,
    ``counterexample-<index>.xosc``, OpenSCENARIO 1.0) on ``road.xodr`` (OpenDRIVE 1.5),
    and the certified set as a ParameterValueDistribution (``safe_set.xosc`` or
    ``certified_domain.xosc``, 1.2) over ``logical_scenario.xosc``. Returns
    {"directory", "files", "runs", "notes"}; ``force`` replaces an earlier export."""
    directory = target.directory if isinstance(target, QuantifyResult) else Path(target)
    return lazy.openscenario.export_openscenario(directory, force=force)


def falsify(target, *, gamma_star=None, points: int = 10_000, tries: int = 4, seed: int | None = None,
            progress=None) -> dict:
    """Try a worst case Gamma* on the black box (farm/jobs/falsify.py): ``gamma_star`` (m
    numbers; default: the proposal in the campaign's adversary.json) held from uniform
    start states; random sequences from Gamma from every start that survives it. Returns
    the report written to falsify.json (``refuted``, ``counterexamples`` with stream keys)."""
    directory = target.directory if isinstance(target, QuantifyResult) else Path(target)
    return lazy.falsify.falsify(directory, gamma_star=gamma_star, points=points, tries=tries, seed=seed,
                                progress=progress)
