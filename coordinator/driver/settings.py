"""What the campaign driver needs besides the algorithm and the executor."""

from __future__ import annotations

from dataclasses import dataclass

from coordinator import certification
from coordinator.sample_size import n_eps
from scenarios.errors import ConfigError

COUNTING = ("sequential", "deferred")


@dataclass(frozen=True)
class CampaignSettings:
    """The config's quantify.epsilon, beta, budget, certify, certify_margin,
    certify_tolerance, farm.batch_size, pipeline_depth, counting, seed and record.quantify_runs; and two
    switches no config sets, for tests that show a part never changes a result:
    ``look_ahead`` (runs launched before the head needs them, coordinator/driver/lookahead.py)
    and ``speculate`` (changes applied past holds, coordinator/driver/speculation.py)."""

    epsilon: float = 0.001
    beta: float = 0.1
    budget: int = 2_000_000
    batch_size: int = 1024
    pipeline_depth: int = 2
    seed: int = 0
    certify: bool = False
    record_limit: int = 0  # state-changing failures kept for the MCAP recording
    counting: str = "sequential"
    certify_margin: float = certification.MARGIN  # closing rounds aim at eps / margin
    certify_tolerance: int = 0  # violations a check may see and pass (the config's default: certification.TOLERANCE)
    look_ahead: bool = True
    speculate: bool = True

    def __post_init__(self):
        if self.counting not in COUNTING:
            raise ConfigError(f"farm.counting: {self.counting!r} is not allowed; allowed: {', '.join(COUNTING)}")

    @property
    def n_eps(self) -> int:
        """Quiet runs in a row that end a round (Lemma 2)."""
        return n_eps(self.epsilon, self.beta)

    @property
    def lag(self) -> int:
        """Indices after which a mispredicted run's replacement is applied."""
        return 0 if self.counting == "sequential" else self.batch_size * self.pipeline_depth

    def certification_quiet(self, attempt: int) -> int:
        """Runs that pass check ``attempt`` (1, 2, ...) with at most ``certify_tolerance``
        violations: beta split over the checks, so that the set finally exported keeps it."""
        return certification.check_quiet(self.epsilon, self.beta, attempt, self.certify_tolerance)

    def closing_quiet(self, share: float) -> int:
        """Quiet runs in a row that end a closing round over an edge of ``share`` of the centres."""
        return certification.closing_quiet(self.epsilon, self.beta, self.certify_margin, share)
