"""The adversary search of ``actions.mode = "search"`` (scenarios/search.py has the
families): the mixture's weights move toward the families that make runs fail.

The update is a cross-entropy step on the committed runs of the round that just ended.
Every family saw starts drawn from the same distribution (a run's family is independent
of its start), so failure rates compare families fairly:

    r_f   = (failures_f + 1/2) / (runs_f + 1)                (smoothed failure rate)
    t_f   = r_f^SHARPNESS / sum_g r_g^SHARPNESS              (the elite's share)
    w_f  <- max(FLOOR, (1 - STEP) w_f + STEP t_f), normalized

FLOOR keeps every family sampled (the search never stops looking, and the uniform family
keeps all of Gamma in the support). Weights change only at round ends, so every round,
the last one included, samples one fixed mixture, and the N_eps rule's epsilon-almost
statement holds for that mixture. The update reads nothing but committed runs (their
keys and outcomes), so the schedule, and with it every result, is the same for any
number of workers and after a resume.

The proposed Gamma* is read from the *evidence* weights: those of the latest update, and
for a campaign that ended in its first round (no round end, so no update: delta0 =
delta_min without certification) the update that round's runs imply. The first round is
a fair comparison (every family meets the same unpruned set); a later round is not (the
set was already pruned against the leading family, so it fails less there), which is why
the final round's runs are not folded in once there was an update. Reading the evidence
weights changes nothing that was sampled.
"""

from __future__ import annotations

import numpy as np

from scenarios.base import FAILURE
from scenarios.search import SearchActions
from scenarios.streams import RunStreams

SHARPNESS = 3.0  # exponent on the failure rates: how strongly the elite is preferred
STEP = 0.8  # how far one round moves the weights toward the elite's shares
FLOOR = 0.04  # every family keeps at least this weight
DOMINANT = 0.5  # a vertex family at or above this weight is proposed as Gamma*


def updated_weights(weights, runs: np.ndarray, failures: np.ndarray) -> np.ndarray:
    """One cross-entropy step from ``weights`` given a round's ``runs`` and ``failures`` per
    family (the module docstring's formula); the result sums to 1."""
    rate = (failures + 0.5) / (runs + 1.0)
    elite = rate**SHARPNESS
    new = np.maximum((1 - STEP) * np.asarray(weights, dtype=float) + STEP * elite / elite.sum(), FLOOR)
    return new / new.sum()


def one_sided_z(failures_a: int, runs_a: int, failures_b: int, runs_b: int) -> float:
    """Two-proportion z statistic (pooled) that family a fails more often than family b."""
    pooled = (failures_a + failures_b) / max(runs_a + runs_b, 1)
    se = np.sqrt(pooled * (1 - pooled) * (1 / max(runs_a, 1) + 1 / max(runs_b, 1)))
    return float((failures_a / max(runs_a, 1) - failures_b / max(runs_b, 1)) / se) if se > 0 else 0.0


def schedule_state(arrays: dict) -> dict | None:
    """The search policy's state (``SearchActions.load``) from checkpoint arrays."""
    if "adv.firsts" not in arrays:
        return None
    return {"schedule": [[int(a), list(w)] for a, w in zip(arrays["adv.firsts"], arrays["adv.weights"])]}


class AdversarySearch:
    def __init__(self, policy: SearchActions, seed: int):
        self.policy = policy
        self.seed = seed
        f = len(policy.families)
        self.runs = np.zeros(f, dtype=np.int64)  # this round, per family
        self.failures = np.zeros(f, dtype=np.int64)
        self.total_runs = np.zeros(f, dtype=np.int64)
        self.total_failures = np.zeros(f, dtype=np.int64)
        self.history: list[dict] = []  # one entry per update: what the round saw and decided

    def observe(self, indices: np.ndarray, outcomes: np.ndarray) -> None:
        """Count committed runs ``indices`` (sample indices) with ``outcomes`` by family."""
        if len(indices) == 0:
            return
        fam = self.policy.family_of(RunStreams.of(self.seed, np.asarray(indices, dtype=np.uint64))).astype(np.intp)
        f = len(self.policy.families)
        self.runs += np.bincount(fam, minlength=f)
        self.failures += np.bincount(fam[np.asarray(outcomes) == FAILURE], minlength=f)

    def end_round(self, next_index: int) -> tuple[float, ...]:
        """The weights for runs from ``next_index`` on (appended to the policy's schedule)."""
        new = updated_weights(self.policy.weights, self.runs, self.failures)
        self.history.append({"first_index": int(next_index), "runs": self.runs.tolist(),
                             "failures": self.failures.tolist(), "weights": new.tolist()})
        self.total_runs += self.runs
        self.total_failures += self.failures
        self.runs[:] = 0
        self.failures[:] = 0
        self.policy.append(next_index, new)
        return tuple(new)

    # -- persistence (checkpoint arrays: plain numbers, no pickle) -----------------------------
    def state(self) -> dict[str, np.ndarray]:
        firsts = np.array([first for first, _ in self.policy.schedule], dtype=np.int64)
        weights = np.array([w for _, w in self.policy.schedule], dtype=float)
        hist = np.array([[h["first_index"], *h["runs"], *h["failures"]] for h in self.history],
                        dtype=np.int64).reshape(len(self.history), 1 + 2 * len(self.runs))
        return {"adv.firsts": firsts, "adv.weights": weights, "adv.runs": self.runs.copy(),
                "adv.failures": self.failures.copy(), "adv.total_runs": self.total_runs.copy(),
                "adv.total_failures": self.total_failures.copy(), "adv.history": hist,
                "adv.history_weights": np.array([h["weights"] for h in self.history], dtype=float).reshape(
                    len(self.history), len(self.runs))}

    def load_state(self, arrays: dict) -> None:
        schedule = schedule_state(arrays)
        if schedule is None:
            return  # a checkpoint from before the search mode existed
        self.policy.load(schedule)
        for name in ("runs", "failures", "total_runs", "total_failures"):
            getattr(self, name)[:] = arrays[f"adv.{name}"]
        f = len(self.runs)
        self.history = [{"first_index": int(row[0]), "runs": row[1 : 1 + f].tolist(),
                         "failures": row[1 + f :].tolist(), "weights": list(w)}
                        for row, w in zip(arrays["adv.history"], arrays["adv.history_weights"])]

    # -- what was found -----------------------------------------------------------------------
    def decisive_round(self) -> tuple[np.ndarray, np.ndarray]:
        """Runs and failures per family of the round the evidence weights come from: the
        last round that ended, or the first while none has."""
        if self.history:
            last = self.history[-1]
            return np.asarray(last["runs"]), np.asarray(last["failures"])
        return self.runs, self.failures

    def evidence_weights(self) -> np.ndarray:
        """The weights the proposal reads (module docstring). Changes nothing."""
        if self.history or self.runs.sum() == 0:
            return np.asarray(self.policy.weights, dtype=float)
        return updated_weights(self.policy.weights, self.runs, self.failures)

    def report(self, scenario) -> dict:
        """adversary.json: the final round's sampled weights, the evidence weights, each
        family's share of the failures, and a proposed Gamma* when one vertex family
        holds at least DOMINANT of the evidence weights."""
        runs = self.total_runs + self.runs
        failures = self.total_failures + self.failures
        evidence = self.evidence_weights()
        families = []
        for k, fam in enumerate(self.policy.families):
            families.append({"family": fam.label(), "kind": fam.kind,
                             "vertex": list(fam.vertex) if fam.vertex is not None else None,
                             "weight": float(self.policy.weights[k]), "evidence_weight": float(evidence[k]),
                             "runs": int(runs[k]), "failures": int(failures[k]),
                             "failure_share": float(failures[k] / max(failures.sum(), 1)),
                             "failure_rate": float(failures[k] / max(runs[k], 1))})
        top = int(np.argmax(evidence))
        best = self.policy.families[top]
        proposed = None
        if best.kind == "vertex" and evidence[top] >= DOMINANT:
            # how strong the evidence is (falsify is the test, this a hint), on the decisive
            # round's runs alone: within a round every family met the same starts
            round_runs, round_failures = self.decisive_round()
            rates = round_failures / np.maximum(round_runs, 1)
            runner_up = int(np.argmax(np.where(np.arange(len(rates)) == top, -np.inf, rates)))
            proposed = {"actions": [list(best.vertex)], "family": best.label(),
                        "weight": float(evidence[top]), "words": best.words(scenario),
                        "runner_up": self.policy.families[runner_up].label(),
                        "z_over_runner_up": one_sided_z(int(round_failures[top]), int(round_runs[top]),
                                                        int(round_failures[runner_up]), int(round_runs[runner_up]))}
        return {"families": families, "proposed_gamma_star": proposed,
                "known_gamma_star": scenario.adversarial_actions.tolist(),
                "update": {"sharpness": SHARPNESS, "step": STEP, "floor": FLOOR, "dominant": DOMINANT},
                "schedule": self.policy.state()["schedule"], "rounds": self.history}
