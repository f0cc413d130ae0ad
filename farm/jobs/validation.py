"""A validation (`scenario-farm validate`): certify a claimed domain Phi, or find the
first counterexample (coordinator/validation.py runs Algs. 2-4), and write its
certificate.json (and counterexample.mcap) into a directory of its own."""

from __future__ import annotations

from pathlib import Path

from coordinator.domain import Domain
from coordinator.guarantee import validated
from coordinator.safe_set import SafeSet
from coordinator.validation import validate as run_validation, validation_plan
from farm import lazy
from farm.config import Config
from farm.directory.files import write_json
from farm.directory.storage import CampaignDir, CampaignError
from farm.execution.factory import make_executor
from farm.execution.process import build_simulator
from farm.jobs.resources import check_validate
from farm.openscenario.ranges import validate_section
from farm.reports.certificate import Certificate, certificate_of
from scenarios.simulator import SimSpec


def run(cfg: Config, out: Path | None = None, *, force: bool = False, progress=None) -> Certificate:
    """Validate the domain of ``cfg``'s [validate] section; with ``out``, write
    certificate.json there (refused before any run if ``out`` is not ours or, without
    ``force``, already holds one). ``progress(done, total)`` is told the runs committed."""
    v, farm_cfg = cfg.validate, cfg.farm
    spec = SimSpec(cfg.scenario.model_dump(), cfg.actions.model_dump(), v.horizon, farm_cfg.seed)
    simulator = build_simulator(spec)
    scenario, policy = simulator.scenario, simulator.policy
    safe_set = SafeSet.from_parquet(v.domain_set, scenario.state_names) if v.domain_set else None
    domain = Domain.from_config(scenario, validate_section(v, scenario), safe_set)
    check_validate(cfg, domain.lo, domain.hi, domain.is_set)
    plan = validation_plan(domain, v.algorithm, v.epsilon, v.beta, v.delta, v.boundary, simulator.deterministic)
    directory = CampaignDir(out) if out is not None else None
    if directory is not None:  # before the runs: a bad --out must not cost a validation
        _check_out(directory, force)
    executor = make_executor(farm_cfg, spec, check_step_bound=v.boundary)
    try:
        result = run_validation(domain, plan, executor, seed=farm_cfg.seed, delta=v.delta,
                                batch_size=farm_cfg.batch_size, pipeline_depth=farm_cfg.pipeline_depth,
                                progress=progress)
    finally:
        executor.close()
    guarantee = validated(scenario, policy, result, algorithm=plan.algorithm, plan_description=plan.description,
                          epsilon=v.epsilon, beta=v.beta, delta=v.delta, horizon=v.horizon, seed=farm_cfg.seed,
                          adversarial=cfg.actions.mode == "adversarial", mixed=domain.covering(v.delta) is not None,
                          covering=domain.covering_words(v.delta, named=True))
    cert = certificate_of(cfg, plan, result, guarantee, scenario, policy, domain)
    if directory is not None:
        _write(directory, cfg, cert, scenario, force)
    return cert


def _check_out(directory: CampaignDir, force: bool) -> None:
    directory.check_writable()
    marker = directory.marker()
    out = directory.path
    if marker is None and out.is_dir() and any(out.iterdir()):
        raise CampaignError(f"{out}: not empty and not a directory this tool wrote; choose another --out")
    if marker is not None and marker.get("kind") != "validate":
        raise CampaignError(f"{out}: a {marker.get('kind')} directory; choose another --out")
    if (out / "certificate.json").exists() and not force:
        raise CampaignError(f"{out}/certificate.json exists; pass --force to replace it")


def _write(directory: CampaignDir, cfg: Config, cert: Certificate, scenario, force: bool) -> None:
    if directory.path.exists() and directory.marker() is not None:
        directory.open("validate")
        directory.lock()
    else:
        directory.create("validate", force=force)
    try:
        write_json(directory.path / "config.json", {"config": cfg.model_dump(mode="json"),
                                                    "config_hash": cert.config_hash})
        cert.write(directory.path)
        if cert.counterexample and cfg.record.counterexamples:
            lazy.rerun.record_counterexample(directory.path / "counterexample.mcap", scenario, cert)
    finally:
        directory.unlock()
