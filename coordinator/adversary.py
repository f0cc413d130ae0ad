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
        w = np.asarray(self.policy.weights)
        rate = (self.failures + 0.5) / (self.runs + 1.0)
        elite = rate**SHARPNESS
        target = elite / elite.sum()
        new = np.maximum((1 - STEP) * w + STEP * target, FLOOR)
        new /= new.sum()
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
    def report(self, scenario) -> dict:
        """adversary.json: final weights, each family's share of the failures, and a
        proposed Gamma* when one vertex family dominates."""
        runs = self.total_runs + self.runs
        failures = self.total_failures + self.failures
        families = []
        for k, fam in enumerate(self.policy.families):
            families.append({"family": fam.label(), "kind": fam.kind,
                             "vertex": list(fam.vertex) if fam.vertex is not None else None,
                             "weight": float(self.policy.weights[k]), "runs": int(runs[k]),
                             "failures": int(failures[k]),
                             "failure_share": float(failures[k] / max(failures.sum(), 1)),
                             "failure_rate": float(failures[k] / max(runs[k], 1))})
        top = int(np.argmax(self.policy.weights))
        best = self.policy.families[top]
        proposed = None
        if best.kind == "vertex" and self.policy.weights[top] >= DOMINANT:
            proposed = {"actions": [list(best.vertex)], "family": best.label(),
                        "weight": float(self.policy.weights[top]),
                        "words": best.words(scenario)}
        return {"families": families, "proposed_gamma_star": proposed,
                "known_gamma_star": scenario.adversarial_actions.tolist(),
                "update": {"sharpness": SHARPNESS, "step": STEP, "floor": FLOOR, "dominant": DOMINANT},
                "schedule": self.policy.state()["schedule"], "rounds": self.history}
