"""Which kind of round a campaign is in, what ends it, and what its end and its changes
lead to: the one place the driver reads the algorithm's round flags.

A campaign runs the algorithm's rounds (delta decays round by round) and, with
``certify``, ends with certification (coordinator/certification.py) as its last round:
every final centre once for a deterministic system (enumeration), otherwise closing
rounds (which change the set and spend no beta) alternating with checks (which change
nothing: they pass with at most quantify.certify_tolerance violations, or fail at the
next one, which is applied). A campaign of one round (delta0 = delta_min) certifies from
its first run.
"""

from __future__ import annotations

from enum import Enum

from coordinator.algorithm import Algorithm


class After(Enum):
    """What follows a round's end."""

    CHECK = "check"  # a closing round ended: check the set
    NEXT_ROUND = "next round"  # the algorithm decays delta and replays its runs
    CERTIFY = "certify"  # the last round ran by the algorithm's rule: certification takes over
    DONE = "done"  # the last round ended: the campaign is done


class Phase:
    def __init__(self, algorithm: Algorithm, settings):
        self.algorithm = algorithm
        self.settings = settings
        self.certify = settings.certify and algorithm.certifies
        self._quiet: tuple[int, int, int] | None = None  # (version, attempts, quiet runs needed)

    @property
    def enumerating(self) -> bool:
        """Certification runs every final centre once (a deterministic system)."""
        return self.algorithm.enumerates

    @property
    def closing(self) -> bool:
        return self.algorithm.closing

    @property
    def settled(self) -> bool:
        """The set is checked as it stands (a check, or the enumeration): a change there
        ends the check, so nothing is worked out or applied ahead of one."""
        return self.algorithm.certifying and not self.algorithm.closing

    @property
    def certified(self) -> bool:
        """The campaign certifies and has reached its certification."""
        return self.certify and self.algorithm.certifying

    def quiet_needed(self, attempts: int) -> int:
        """Indices in a row that must be resolved and quiet to end the current round
        (kept per state version: the head asks at every step of its walk, and a closing
        round's edge share is the edge's size)."""
        version = self.algorithm.version
        if self._quiet is None or self._quiet[:2] != (version, attempts):
            self._quiet = (version, attempts, self._quiet_needed(attempts))
        return self._quiet[2]

    def _quiet_needed(self, attempts: int) -> int:
        if self.algorithm.closing:
            return self.settings.closing_quiet(self.algorithm.closing_share())
        if self.algorithm.certifying:
            return self.settings.certification_quiet(max(attempts, 1))
        return self.settings.n_eps

    def begin_if_last(self, counters) -> None:
        """With ``certify``, the last round (at delta_min) is the certification itself.
        A deterministic system runs every final centre once (VAL^delta): exact, so the
        N_eps rule's epsilon-almost statement, and the runs spent on it, would add nothing.
        A sampled system starts with a closing round: it prunes and explores as the
        algorithm's last round would, but strictly and over the edge where the violations
        are, so the set is not first settled by the lenient rule and then settled again
        (the runs that saves: docs/certification.md). Only the checks certify
        (docs/guarantee.md). Called as the last round begins (for a campaign of one round:
        as it starts)."""
        algorithm = self.algorithm
        if self.certify and algorithm.final_round and not algorithm.certifying:
            algorithm.begin_certification()
            if algorithm.deterministic:
                counters.attempts = 1
            counters.certification_from = counters.committed

    def tolerates(self, counters) -> bool:
        """A check saw a violation: True if it is within quantify.certify_tolerance (counted,
        not applied: the set stays the one checked, and the check's runs go on)."""
        if not self.settled or self.algorithm.enumerates or \
                counters.check_violations >= self.settings.certify_tolerance:
            return False
        counters.check_violations += 1
        return True

    def changed(self, counters) -> bool:
        """A change was applied. True if it ended a check: a closing round follows, whose
        law moves every draw in flight (they are dropped as at a round end)."""
        if self.algorithm.enumerates:
            counters.attempts += 1
            return False
        if self.settled:  # the check failed: close again (spends no beta)
            self.algorithm.begin_closing()
            return True
        return False

    def round_ended(self, counters) -> After:
        """The N_eps rule ended a round: count it and say what follows."""
        algorithm = self.algorithm
        if algorithm.closing:
            counters.closing_ends.append(counters.committed)
            algorithm.begin_check()
            counters.attempts += 1
            counters.check_violations = 0
            return After.CHECK
        counters.round_ends.append(counters.committed)
        counters.rounds_completed += 1
        if algorithm.final_round and self.certify and not algorithm.certifying:
            # a last round run by the algorithm's rule: a checkpoint written before
            # certification took the last round's place, resumed
            return After.CERTIFY
        if algorithm.final_round:
            return After.DONE
        return After.NEXT_ROUND
