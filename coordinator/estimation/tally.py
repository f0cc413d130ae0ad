"""What an estimate has counted: per stage (rows) and stratum (columns) the runs planned,
the runs committed and the failures, and with a second controller on the same runs its
failures and the discordant pairs. Arrays only: the checkpoint saves them as they are."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from coordinator.estimation.intervals import Interval, difference_interval, rate_interval


JEFFREYS = 0.5  # pseudo-failures (and pseudo-successes) per stratum when allocating


def _empty(strata: int) -> np.ndarray:
    return np.zeros((0, strata), dtype=np.int64)


@dataclass
class Tally:
    strata: int
    paired: bool = False
    planned: np.ndarray = field(default=None)  # (T, H) runs each stage allocated
    runs: np.ndarray = field(default=None)  # (T, H) runs committed
    failures: np.ndarray = field(default=None)  # (T, H) failures of the controller under test
    versus_failures: np.ndarray = field(default=None)  # (T, H) the second controller's (paired only)
    a_only: np.ndarray = field(default=None)  # (T, H) runs where only the controller under test failed
    b_only: np.ndarray = field(default=None)  # (T, H) runs where only the second controller failed

    ARRAYS = ("planned", "runs", "failures", "versus_failures", "a_only", "b_only")

    def __post_init__(self):
        for name in self.ARRAYS:
            if getattr(self, name) is None:
                setattr(self, name, _empty(self.strata))

    @property
    def stages(self) -> int:
        return len(self.planned)

    @property
    def committed(self) -> int:
        return int(self.runs.sum())

    @property
    def planned_total(self) -> int:
        return int(self.planned.sum())

    def stage_complete(self) -> bool:
        return self.committed == self.planned_total

    def begin(self, counts: np.ndarray) -> None:
        """A new stage with ``counts`` (H,) runs per stratum."""
        for name in self.ARRAYS:
            row = counts if name == "planned" else np.zeros(self.strata, dtype=np.int64)
            setattr(self, name, np.vstack([getattr(self, name), np.asarray(row, dtype=np.int64)[None, :]]))

    def add(self, strata: np.ndarray, failed: np.ndarray, versus_failed: np.ndarray | None = None) -> None:
        """Count committed runs of the current stage: their strata and outcomes."""
        t = self.stages - 1
        self.runs[t] += np.bincount(strata, minlength=self.strata)
        self.failures[t] += np.bincount(strata, weights=failed, minlength=self.strata).astype(np.int64)
        if self.paired:
            self.versus_failures[t] += np.bincount(strata, weights=versus_failed, minlength=self.strata).astype(np.int64)
            self.a_only[t] += np.bincount(strata, weights=failed & ~versus_failed, minlength=self.strata).astype(np.int64)
            self.b_only[t] += np.bincount(strata, weights=versus_failed & ~failed, minlength=self.strata).astype(np.int64)

    def sigmas(self) -> np.ndarray | None:
        """(H,) the strata's standard deviations for the next allocation, from the complete
        stages, at the posterior mean of each stratum's rate under Jeffreys' prior (x + 1/2)
        / (n + 1): a stratum without a failure yet keeps a share that shrinks as its runs
        grow, so that a rare failure mode is found before the runs go elsewhere (with a
        second controller: both rates together); None before any stage."""
        done = self.runs[:-1] if not self.stage_complete() else self.runs
        if len(done) == 0:
            return None
        n = done.sum(axis=0)
        p = (self.failures[: len(done)].sum(axis=0) + JEFFREYS) / (n + 2 * JEFFREYS)
        var = p * (1 - p)
        if self.paired:
            q = (self.versus_failures[: len(done)].sum(axis=0) + JEFFREYS) / (n + 2 * JEFFREYS)
            var = var + q * (1 - q)
        return np.sqrt(var)

    def _complete(self):
        """The stages with a run in every stratum (an unfinished stage may lack some)."""
        return self.runs.min(axis=1) > 0 if self.stages else np.zeros(0, dtype=bool)

    def rate(self, masses: np.ndarray, confidence: float, versus: bool = False) -> Interval:
        rows = self._complete()
        failures = self.versus_failures if versus else self.failures
        return rate_interval(masses, self.runs[rows], failures[rows], confidence)

    def difference(self, masses: np.ndarray, confidence: float) -> Interval:
        rows = self._complete()
        return difference_interval(masses, self.runs[rows], self.a_only[rows], self.b_only[rows], confidence)

    # -- the checkpoint ------------------------------------------------------------------------
    def arrays(self) -> dict[str, np.ndarray]:
        return {f"tally.{name}": getattr(self, name) for name in self.ARRAYS}

    @classmethod
    def from_arrays(cls, arrays: dict, strata: int, paired: bool) -> "Tally":
        values = {name: np.asarray(arrays[f"tally.{name}"], dtype=np.int64).reshape(-1, strata)
                  for name in cls.ARRAYS}
        return cls(strata, paired, **values)

