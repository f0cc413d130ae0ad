"""certificate.json: the answer of a validation, built, written and read here only.

Its keys are a public interface: ``verdict`` (certified | counterexample), the guarantee
in plain words and in the paper's terms (``guarantee_formal``, also as ``statement``),
the parameters the algorithm used (VAL^eps has no ``delta``, VAL^delta no ``epsilon`` /
``beta``), the runs, what was validated, and the first ``counterexample`` or null.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from farm import config as config_mod
from farm.config import Config
from farm.directory.json_record import JsonFile, record_from_json, record_to_json
from scenarios.version import __version__

FILE = "certificate.json"
REQUIRED = ("verdict", "guarantee", "algorithm", "n_run", "seed", "config_hash")
PARAMETERS = {"delta": ("delta",), "eps": ("epsilon", "beta"), "eps-delta": ("epsilon", "beta", "delta")}


@dataclass(frozen=True, kw_only=True)
class Certificate(JsonFile):
    """The answer of a validation: certified, or the first counterexample; one field
    per key of certificate.json, in the file's order (``statement`` is
    ``guarantee_formal``). Keys this reader does not know are kept in ``extra``."""

    FILE: ClassVar[str] = FILE
    MISSING: ClassVar[str] = "{directory}: no {file} (not a validation directory)"

    verdict: str
    guarantee: str
    guarantee_formal: str = ""
    algorithm: str
    epsilon: float | None = None  # only the parameters the algorithm used (None: not written)
    beta: float | None = None
    delta: float | None = None
    horizon: int = 0
    n_required: int = 0
    n_run: int
    runs_simulated: int = 0
    steps_simulated: int = 0
    seed: int
    config_hash: str
    scenario: str = ""
    sv_policy: str = ""
    domain: str = ""
    sampling: str = ""
    actions: str = ""
    boundary: bool = False
    # the first violating run: sample index, stream key, start state, violating step,
    # reason, outcome, trajectory up to that step (coordinator.validation.counterexample)
    counterexample: dict | None = None
    scenario_farm_version: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def certified(self) -> bool:
        return self.verdict == "certified"

    @property
    def statement(self) -> str:
        """The verdict in the paper's terms (certificate.json ``statement``, the same as
        ``guarantee_formal``)."""
        return self.guarantee_formal

    # -- certificate.json -----------------------------------------------------------------------
    def to_json(self) -> dict:
        out = record_to_json(self, omit_none=("epsilon", "beta", "delta"))
        # ``statement`` stands right after ``guarantee_formal``, as it always has
        keys = list(out)
        keys.insert(keys.index("guarantee_formal") + 1, "statement")
        return {k: self.statement if k == "statement" else out[k] for k in keys}

    @property
    def data(self) -> dict:
        """certificate.json's object."""
        return self.to_json()

    @classmethod
    def from_json(cls, data, source: str = FILE) -> "Certificate":
        if isinstance(data, dict):
            data = dict(data)
            statement = data.pop("statement", "")
            data.setdefault("guarantee_formal", statement)  # the older name of the same words
        return record_from_json(cls, data, source, REQUIRED)



def certificate_of(cfg: Config, plan, result, guarantee, scenario, policy, domain) -> Certificate:
    """The certificate of a finished validation of ``cfg`` (its [validate] section):
    ``plan`` (coordinator.validation.ValidationPlan), ``result``
    (coordinator.validation.ValidationResult), ``guarantee``
    (coordinator.guarantee.validated), the scenario, action policy and Domain."""
    v = cfg.validate
    used = PARAMETERS[plan.algorithm]
    return Certificate(
        verdict=result.verdict, guarantee=guarantee.plain, guarantee_formal=guarantee.formal,
        algorithm=plan.algorithm, **{name: getattr(v, name) for name in used}, horizon=v.horizon,
        n_required=plan.n_required, n_run=result.n_run, runs_simulated=result.runs_simulated,
        steps_simulated=result.steps_simulated, seed=cfg.farm.seed, config_hash=config_mod.config_hash(cfg),
        scenario=cfg.scenario.name, sv_policy=scenario.sv_policy_name, domain=domain.describe(),
        sampling=plan.description, actions=policy.description, boundary=v.boundary,
        counterexample=result.counterexample, scenario_farm_version=__version__)
