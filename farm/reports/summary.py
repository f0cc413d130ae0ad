"""summary.json: what a finished quantification found, built, written and read here only.

Its keys are a public interface (README, "What a campaign writes"): scripts outside read
them, so a key is never renamed or dropped. A scenario with sides (fleet3: lead, rear)
adds, per side, ``volume_<side>_side``, ``volume_hull_<side>_side``,
``result_hash_<side>_side``, ``guarantee_<side>_side`` and ``guarantee_formal_<side>_side``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from coordinator.safe_set import SafeSet
from farm import config as config_mod
from farm.config import Config
from farm.directory.json_record import JsonFile, record_from_json, record_to_json
from scenarios.errors import CampaignError
from scenarios.version import __version__

FILE = "summary.json"
# written by every version of this tool; without them a file is no campaign's summary
REQUIRED = ("scenario", "algorithm", "boxes", "result_hash", "guarantee")
SIDE_KEYS = ("volume", "volume_hull", "result_hash", "guarantee", "guarantee_formal")
# a virtual farm's only
VIRTUAL_KEYS = ("virtual_elapsed_s", "utilisation", "virtual_waiting_s", "virtual_coordinator_s")
# written only where they apply: an estimated volume's interval, margin refinement, a holdout
OPTIONAL_KEYS = VIRTUAL_KEYS + ("refine", "volume_union_exact", "volume_union_interval", "volume_hull_exact",
                                "volume_hull_interval", "volume_method", "half_widths_finest", "holdout",
                                "side_failures")


@dataclass(frozen=True)
class SideSummary:
    """A side campaign's figures (its keys in summary.json end in ``_<side>_side``)."""

    volume: float
    volume_hull: float
    result_hash: str
    guarantee: str
    guarantee_formal: str = ""

    @staticmethod
    def key(name: str, label: str) -> str:
        """summary.json's key of field ``name`` for side ``label``."""
        return f"{name}_{label}_side"


@dataclass(frozen=True, kw_only=True)
class Summary(JsonFile):
    """The content of summary.json, one field per key, in the file's order. Fields an
    older writer did not write keep their defaults; keys this reader does not know are
    kept in ``extra``."""

    FILE: ClassVar[str] = FILE
    MISSING: ClassVar[str] = "{directory}: the campaign has not finished (no {file}); see `scenario-farm status " \
                             "{directory}`"

    scenario: str
    sv_policy: str = ""
    backend: str = ""
    algorithm: str
    epsilon: float = 0.0
    beta: float = 0.0
    n_eps: int = 0
    # a sampled certification's checks, and the quiet runs its last one needed (beta
    # split over checks); 0 and n_eps without certification
    certification_attempts: int = 0
    n_eps_final: int = 0
    # violations the passing check saw, within quantify.certify_tolerance (the checked set is
    # exported unchanged), and such violations over all its checks
    certification_check_violations: int = 0
    certification_violations_tolerated: int = 0
    # committed runs certification took: its closing rounds and checks (a deterministic
    # system: its last round, every final centre once); 0 without certification
    runs_certification: int = 0
    delta_final: float = 0.0  # the boxes' half-width (for boxes of mixed sizes, the smallest)
    half_width_max: float = 0.0  # the largest (quantify.refine = "band" leaves coarser boxes inside)
    rounds: int = 0
    converged: bool = False
    runs_committed: int = 0
    runs_simulated: int = 0
    runs_dropped: int = 0
    # coupled counting: mispredicted runs discarded unseen, and the replacements applied
    runs_replaced: int = 0
    runs_discarded: int = 0
    counting: str = ""
    steps_simulated: int = 0
    boxes: int
    volume_union: float = 0.0
    volume_hull: float = 0.0
    volume_sigma: float = 0.0
    # where a volume is estimated (an exact one costs 2^n per box above 5 dimensions): False
    # and its 95 % interval [low, high]; how each was computed, in words
    volume_union_exact: bool | None = None
    volume_union_interval: list | None = None
    volume_hull_exact: bool | None = None
    volume_hull_interval: list | None = None
    volume_method: dict | None = None
    # the refinement quantify.refine resolved to ("margin": boxes with a half-width per
    # axis, whose finest per state variable is half_widths_finest)
    refine: str | None = None
    half_widths_finest: dict | None = None
    # fresh uniform runs against the set: disagreements with Clopper-Pearson intervals
    holdout: dict | None = None
    seed: int = 0
    config_hash: str = ""
    result_hash: str
    elapsed_s: float = 0.0
    startup_s: float = 0.0
    guarantee: str
    guarantee_formal: str = ""
    actions: str = ""
    failure_facets: list = field(default_factory=list)
    round_ends: list = field(default_factory=list)
    # committed runs that left Sigma through a truncating facet (counted safe), per facet
    truncations: dict = field(default_factory=dict)
    # a scenario with sides: committed runs of a side's study that reached another side's
    # failure facet (which that study leaves out: the run ends there, no failure), per
    # facet and side study: {"p20 > -5": {"lead": 412}}
    side_failures: dict | None = None
    scenario_farm_version: str = ""
    # the virtual farm (farm.executor = "virtual"): simulated time to the result, the
    # share of the workers' time spent on runs, and of the time to the result the head's
    # waits for runs and the coordinator's own CPU (the rest: its calls)
    virtual_elapsed_s: float | None = None
    utilisation: float | None = None
    virtual_waiting_s: float | None = None
    virtual_coordinator_s: float | None = None
    sides: dict[str, SideSummary] = field(default_factory=dict)
    extra: dict = field(default_factory=dict)

    # -- summary.json ----------------------------------------------------------------------------
    def to_json(self) -> dict:
        """summary.json's object: every key, in the file's order."""
        out = record_to_json(self, leave_out=("sides", "extra"), omit_none=OPTIONAL_KEYS)
        for label, side in self.sides.items():
            out.update({SideSummary.key(name, label): getattr(side, name) for name in SIDE_KEYS})
        out.update(self.extra)
        return out

    @classmethod
    def finished(cls, directory) -> "Summary | None":
        """``summary.json`` of a finished campaign in ``directory``, or None (not finished)."""
        try:
            return cls.read(directory)
        except (CampaignError, OSError, ValueError):
            return None

    @classmethod
    def from_json(cls, data, source: str = FILE) -> "Summary":
        if not isinstance(data, dict):
            return record_from_json(cls, data, source, REQUIRED)
        data, sides = dict(data), {}
        labels = [k[len("result_hash_") : -len("_side")] for k in data
                  if k.startswith("result_hash_") and k.endswith("_side")]
        for label in labels:
            present = {name: data.pop(SideSummary.key(name, label)) for name in SIDE_KEYS
                       if SideSummary.key(name, label) in data}
            sides[label] = record_from_json(SideSummary, present, f"{source} (side {label!r})", SIDE_KEYS[:4])
        return record_from_json(cls, data, source, REQUIRED, sides=sides)


def budget_used_up(budget: int, committed: int, simulated: int) -> str:
    """How a campaign stopped by ``quantify.budget`` ended, in one line (the CLI's end
    lines): the runs went on the budget, not on the last round's N_eps rule."""
    return (f"quantify.budget of {budget:,} runs used up ({committed:,} committed, {simulated:,} simulated) "
            f"before the last round ended: the set is NOT certified")


def summarize(cfg: Config, sides: dict, safe_sets: dict[str, SafeSet], guarantees: dict) -> Summary:
    """The summary of a finished campaign. ``sides``: side -> its finished campaign
    (``farm.jobs.side_campaign.SideCampaign``: campaign, algorithm, scenario, policy;
    "total" first, then the scenario's sides); ``safe_sets`` and ``guarantees``
    (``coordinator.guarantee.Guarantee``): side -> its set and guarantee."""
    main, total = sides["total"], safe_sets["total"]
    campaign, scenario = main.campaign, main.scenario
    c = campaign.counters
    bounds = (scenario.lower, scenario.upper)
    counters = [side.campaign.counters for side in sides.values()]
    # the sampled certification's checks; a deterministic one runs every centre once and
    # checks nothing (its counter counts the changes it made: coordinator/driver/phase.py)
    checked = not main.algorithm.enumerates
    return Summary(
        scenario=cfg.scenario.name,
        sv_policy=scenario.sv_policy_name,
        backend=cfg.scenario.backend,
        algorithm=cfg.quantify.algorithm,
        epsilon=cfg.quantify.epsilon,
        beta=cfg.quantify.beta,
        n_eps=campaign.n_eps,
        certification_attempts=c.attempts if checked else 0,
        n_eps_final=campaign.quiet_needed() if c.attempts and checked else campaign.n_eps,
        certification_check_violations=c.check_violations if checked else 0,
        certification_violations_tolerated=sum(k.violations_tolerated(cfg.quantify.certify_tolerance)
                                               for k in counters) if checked else 0,
        runs_certification=sum(k.runs_certification for k in counters),
        delta_final=total.finest,
        half_width_max=total.coarsest,
        rounds=c.rounds_completed,
        converged=c.converged,
        runs_committed=sum(k.committed for k in counters),
        runs_simulated=sum(k.runs_simulated for k in counters),
        runs_dropped=sum(k.runs_dropped for k in counters),
        runs_replaced=sum(k.runs_replaced for k in counters),
        runs_discarded=sum(k.runs_discarded for k in counters),
        counting=cfg.farm.counting,
        steps_simulated=sum(k.steps_simulated for k in counters),
        boxes=len(total),
        **_volumes(total, bounds),
        volume_sigma=scenario.volume,
        seed=cfg.farm.seed,
        config_hash=config_mod.config_hash(cfg),
        result_hash=total.result_hash,
        elapsed_s=round(sum(k.elapsed_s for k in counters), 3),
        startup_s=round(sum(side.startup_s for side in sides.values()), 3),
        guarantee=guarantees["total"].plain,
        guarantee_formal=guarantees["total"].formal,
        actions=main.policy.description,
        failure_facets=list(scenario.failure_facets),
        refine=cfg.refinement() if cfg.quantify.algorithm == "spe" else None,
        holdout=main.holdout,
        half_widths_finest=dict(zip(total.state_names, total.axis_half_widths.min(axis=0).tolist()))
        if total.anisotropic and len(total) else None,
        round_ends=list(c.round_ends),
        truncations=_truncations(scenario, counters),
        side_failures=_side_failures(scenario, sides),
        scenario_farm_version=__version__,
        **_virtual(sides),
        sides={name: SideSummary(volume=safe_sets[name].volume_union(bounds),
                                 volume_hull=safe_sets[name].volume_hull(bounds),
                                 result_hash=safe_sets[name].result_hash, guarantee=guarantees[name].plain,
                                 guarantee_formal=guarantees[name].formal)
               for name in sides if name != "total"})


def _volumes(safe_set: SafeSet, bounds) -> dict:
    """The union's and the hull's volume; where one is estimated, its interval and how."""
    union, hull = safe_set.union_estimate(bounds), safe_set.hull_estimate(bounds)
    out = {"volume_union": union.value, "volume_hull": hull.value}
    if not (union.exact and hull.exact):
        out.update(volume_union_exact=union.exact, volume_hull_exact=hull.exact,
                   volume_union_interval=[union.low, union.high], volume_hull_interval=[hull.low, hull.high],
                   volume_method={"union": union.method, "hull": hull.method})
    return out


def _truncations(scenario, counters: list) -> dict[str, int]:
    """Committed truncated runs per facet label, over the sides' campaigns; a facet that
    is a failure of the scenario (another side's, in a side's study) is not a truncation
    (``_side_failures``)."""
    totals = {}
    for k in counters:
        for (facet, failure), n in zip(scenario.facets(), k.truncations):
            if n and not failure:
                totals[facet.label] = totals.get(facet.label, 0) + int(n)
    return totals


def _side_failures(scenario, sides: dict) -> dict | None:
    """Committed runs of each side's study that ended on a failure facet of the scenario
    that the side leaves out (another side's failure), per facet label and side; None
    without sides."""
    if len(sides) < 2:
        return None
    out: dict = {}
    for name, side in sides.items():
        for (facet, failure), n in zip(scenario.facets(), side.campaign.counters.truncations):
            if n and failure:
                out.setdefault(facet.label, {})[name] = int(n)
    return out


def _virtual(sides: dict) -> dict:
    """The virtual farm's clock over the sides' campaigns (they run one after the other)."""
    clocks = [side.virtual for side in sides.values() if side.virtual is not None]
    if not clocks:
        return {}
    elapsed = sum(c.elapsed_s for c in clocks)
    busy = sum(c.elapsed_s * c.utilisation for c in clocks)
    return {"virtual_elapsed_s": round(elapsed, 3), "utilisation": round(busy / elapsed, 4) if elapsed else 0.0,
            "virtual_waiting_s": round(sum(c.waiting_s for c in clocks), 3),
            "virtual_coordinator_s": round(sum(c.coordinator_s for c in clocks), 3)}
