"""One place that turns a config into a running campaign's parts: what a worker
simulates (``spec_of``), the driver's settings (``campaign_settings``), the algorithm
(``build_algorithm``) and the driver itself (``build_campaign``). The CLI, the Python API,
experiments, benchmarks and tests all build campaigns here, so that a setting means the
same everywhere.
"""

from __future__ import annotations

from typing import Iterable

from coordinator.adversary import AdversarySearch
from coordinator.algorithm import Algorithm
from coordinator.baselines import make_algorithm
from coordinator.driver import Campaign, CampaignSettings, Observer
from coordinator.executor import Executor
from coordinator.driver.refinement_campaign import RefinementCampaign
from coordinator.margin.refinement import MarginRefinement
from farm.config import Config, ConfigError
from farm.directory.checkpoint import Restored
from scenarios.search import SearchActions
from scenarios.simulator import Simulator


def campaign_settings(cfg: Config) -> CampaignSettings:
    q, farm_cfg = cfg.quantify, cfg.farm
    return CampaignSettings(epsilon=q.epsilon, beta=q.beta, budget=q.budget, batch_size=farm_cfg.batch_size,
                            pipeline_depth=farm_cfg.pipeline_depth, seed=farm_cfg.seed, certify=q.certify,
                            certify_margin=q.certify_margin,
                            certify_tolerance=q.certify_tolerance, record_limit=cfg.record.quantify_runs, counting=farm_cfg.counting)


def build_algorithm(cfg: Config, simulator: Simulator) -> Algorithm | MarginRefinement:
    """The configured quantification algorithm over the simulator's scenario (margin
    refinement where ``quantify.refine`` resolves to it)."""
    if cfg.refinement() == "margin":
        if not simulator.deterministic:
            raise ConfigError("quantify.refine: margin refinement needs a deterministic system (one adversarial "
                              "action, no disturbance, a deterministic back end); allowed here: all, band")
        return MarginRefinement(simulator.scenario, cfg.quantify.settings())
    return make_algorithm(cfg.quantify.algorithm, simulator.scenario, cfg.quantify.settings(), cfg.farm.seed,
                          simulator.deterministic)


def build_campaign(cfg: Config, algorithm: Algorithm | MarginRefinement, simulator: Simulator,
                   executor: Executor | None, observers: Iterable[Observer] = (),
                   restored: Restored | None = None) -> Campaign | RefinementCampaign:
    """The driver of ``algorithm`` on ``executor``; with actions.mode = "search", the
    adversary search over the simulator's action mixture. ``restored``: where a
    checkpoint left off (farm/directory/checkpoint.py)."""
    if isinstance(algorithm, MarginRefinement):
        return RefinementCampaign(algorithm, executor, campaign_settings(cfg), observers,
                                  restored.driver if restored is not None else None)
    if restored is not None:
        return Campaign(algorithm, executor, campaign_settings(cfg), observers, restored.adversary, restored.driver)
    policy = simulator.policy
    adversary = AdversarySearch(policy, cfg.farm.seed) if isinstance(policy, SearchActions) else None
    return Campaign(algorithm, executor, campaign_settings(cfg), observers, adversary)


def side_facets(cfg: Config, scenario) -> dict[str, list | None]:
    """The campaigns a quantification runs, by label: "total" (the configured failure
    facets) and, for a scenario that declares sides (fleet3: lead, rear), one per side."""
    facets = {"total": cfg.scenario.failure_facets}
    sides = cfg.quantify.sides
    if sides is None:
        sides = bool(scenario.sides) and cfg.scenario.failure_facets is None
    if sides:
        if not scenario.sides:
            raise ConfigError(f"quantify.sides: scenario {scenario.name!r} declares no sides; allowed: false")
        facets.update({label: list(side) for label, side in scenario.sides.items()})
    return facets
