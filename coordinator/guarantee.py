"""The guarantee in two forms: a plain sentence a safety case can quote, built from the
config's own values and units, and the formal statement in the paper's terms.

Plain: "With 90% confidence, at most 0.1% of scenarios started at a box centre of this
set (drawn uniformly), with the lead vehicle's acceleration held at -5 m/s^2, collide or
leave the set within 5 s." Formal: "Phi is (0.001, 1)-almost robustly controlled forward
invariant w.r.t. Gamma* with confidence 0.9 (...)".
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Guarantee:
    plain: str
    formal: str


def _percent(x: float) -> str:
    return f"{100 * x:.4g}%"


def _horizon_s(scenario, horizon: int) -> str:
    return f"{horizon * scenario.dt:g} s"


def _conditions(scenario, policy) -> str:
    words = policy.words(scenario)
    w = getattr(scenario, "disturbance", 0.0)
    if w:
        words += f", under a random disturbance of up to {w:g} m/s^2"
    return words


def _leave(delta: float, coarsest: float | None = None) -> str:
    if coarsest is not None and coarsest > delta * (1 + 1e-12):
        return (f"leave it (by more than its resolution: delta = {delta:g} within sigma-bar + delta of its boundary "
                f"toward failure, where it was refined, and its boxes' own half-widths, up to {coarsest:g}, inside)")
    return f"leave it (by more than its resolution delta = {delta:g})"


def _resolution(delta: float, coarsest: float | None) -> str:
    """Where the set's resolution holds: one delta, or (boundary refinement) delta near
    the boundary toward failure and the interior boxes' own half-widths."""
    if coarsest is not None and coarsest > delta * (1 + 1e-12):
        return (f"to within its resolution: delta = {delta:g} near its boundary toward failure, where it was "
                f"refined, and its boxes' own half-widths, up to {coarsest:g}, inside")
    return f"to within its resolution delta = {delta:g}"


def _covering(delta: float, coarsest: float | None) -> str:
    if coarsest is not None and coarsest > delta * (1 + 1e-12):
        return (f"its covering of mixed half-widths {delta:g} to {coarsest:g} (Phi_delta: each box at its own "
                f"half-width; {delta:g} within sigma-bar + delta of the boundary toward failure, Theorem 3)")
    return f"its {delta:g}-covering"


# -- quantification -------------------------------------------------------------------------
def refined(scenario, policy, *, horizon: int, boxes: int, covering: float, finest: float, coarsest: float,
            converged: bool, budget: int) -> Guarantee:
    """The guarantee of a set found by margin refinement (coordinator/margin): every box
    centre was run once, and each run stays within ``covering`` of the set (the set's
    own boxes, each widened by ``covering`` on every axis: its delta-covering) without
    failing. Deterministic: each run is the run."""
    cond, fail, t = _conditions(scenario, policy), scenario.failure_words, _horizon_s(scenario, horizon)
    if not converged:
        text = f"No guarantee: the budget of {budget} runs was used up before the refinement's last round."
        return Guarantee(text, text)
    plain = (f"Every scenario started at one of the {boxes} box centres of this set, {cond}, does not {fail} and "
             f"stays within {covering:g} of the set for {t}: each centre was simulated (the system is "
             f"deterministic). The boxes have a half-width per state variable, from {finest:g} near the set's "
             f"boundary to {coarsest:g} inside it; a state of a box is claimed safe to within them.")
    formal = (f"Phi is delta-almost robustly controlled forward invariant w.r.t. Gamma* (Definition 5 with a delta "
              f"per box and axis: the box's half-widths + {covering:g}, the paper's vector-delta covering) by "
              f"VAL^delta (Lemma 1) on its own {boxes} box centres: each one's run of K = {horizon} steps stays in "
              f"Phi_delta without failure ({policy.description}).")
    return Guarantee(plain, formal)


def quantified(scenario, policy, *, epsilon: float, beta: float, delta: float, horizon: int, n_eps: int,
               attempts: int, n_final: int, converged: bool, budget: int, enumerated: bool, boxes: int, uniform: bool, distribution: str,
               escaped: int, adversarial: bool, coarsest: float | None = None, tolerance: int = 0,
               seen: int = 0) -> Guarantee:
    """The guarantee of a quantified set. ``enumerated``: a deterministic system's final
    centres were each run once (VAL^delta); ``uniform``: the last N_eps runs were drawn
    uniformly over the final centres (a certification round); ``escaped``: counted runs
    that left Phi_delta toward a known failure (possible only without certification);
    ``attempts``/``n_final``: the sampled certification's checks and the runs the last
    one needed (beta split over checks, coordinator/certification.py); ``tolerance``: the
    violations that check could see and pass (the binomial test), ``seen`` those it saw.
    ``coarsest``: the largest box half-width, when boundary refinement left boxes coarser
    than ``delta`` inside the set."""
    cond, fail, t = _conditions(scenario, policy), scenario.failure_words, _horizon_s(scenario, horizon)
    gamma = "Gamma*" if adversarial else "Gamma"
    if not converged:
        text = (f"No guarantee: the budget of {budget} runs was used up before the last round (delta = "
                f"{delta:g}) saw N_eps = {n_eps} runs in a row that changed nothing.")
        return Guarantee(text, text)
    if enumerated:
        plain = (f"Every scenario started at one of the {boxes} box centres of this set, {cond}, stays in the set "
                 f"({_resolution(delta, coarsest)}) and does not {fail} for {t}: each centre was "
                 f"simulated (the system is deterministic).")
        formal = (f"Phi is {delta:g}-almost robustly controlled forward invariant w.r.t. {gamma} on "
                  f"{_covering(delta, coarsest)} (VAL^delta, Lemma 1): the run from each of the {boxes} centres stays in "
                  f"Phi_delta without failure for K = {horizon} steps ({policy.description}).")
        return Guarantee(plain, formal)
    where = ("started at a box centre of this set (drawn uniformly)" if uniform
             else f"started in this set as the last round drew them ({distribution})")
    confidence = _percent(1 - beta)
    nn = f"N_eps = ceil(ln {beta:g} / ln(1 - {epsilon:g})) = {n_eps} runs"
    if uniform and attempts:
        nn = (f"N = {n_final} runs, the need of certification attempt i = {attempts} (check i, after closing "
              f"rounds that spend no beta) with beta_i = 6 beta / (pi^2 i^2), so that the exported set keeps "
              f"confidence {1 - beta:g} over all attempts,")
    tolerant = bool(uniform and attempts and tolerance)
    if escaped == 0 or tolerant:
        plain = (f"With {confidence} confidence, at most {_percent(epsilon)} of scenarios {where}, {cond}, {fail} or "
                 f"{_leave(delta, coarsest)} within {t}.")
        drawn = f"drawn i.i.d. from {distribution}, actions {policy.description}"
        if tolerant:
            runs = (f"{nn} {drawn}, of which at most {tolerance} may fail or leave Phi_delta, the binomial test "
                    f"P(Bin(N, {epsilon:g}) <= {tolerance}) <= beta_i: {seen} did, and the set was exported as checked")
        else:
            runs = f"{nn} in a row {drawn}, neither failed nor left Phi_delta"
        formal = (f"Phi is ({epsilon:g}, {delta:g})-almost robustly controlled forward invariant w.r.t. {gamma} "
                  f"with confidence {1 - beta:g} ({runs}).")
        return Guarantee(plain, formal)
    plain = (f"With {confidence} confidence, at most {_percent(epsilon)} of scenarios {where}, {cond}, {fail} or "
             f"reach a state never seen before within {t}; {escaped} of the last {n_eps} runs did leave the set "
             f"toward a known failure, so this does not say the set holds its scenarios (turn on "
             f"quantify.certify for that).")
    formal = (f"No failure and no new state (not invariance: {escaped} of the runs left Phi_delta within delta "
              f"of PhiBar) with probability >= 1 - {epsilon:g} and confidence {1 - beta:g} ({nn} in a row "
              f"drawn i.i.d. from {distribution}, actions {policy.description}).")
    return Guarantee(plain, formal)


# -- validation -----------------------------------------------------------------------------
def validated(scenario, policy, result, *, algorithm: str, plan_description: str, epsilon: float,
              beta: float, delta: float, horizon: int, seed: int, adversarial: bool, mixed: bool = False,
              covering: str = "") -> Guarantee:
    """The verdict of a validation in both forms. ``mixed``: the domain is a set of mixed
    box sizes (boundary refinement), its own covering: ``covering`` in words (default each
    box at max(its half-width, delta); ``Domain.covering_words``)."""
    cond, fail, t = _conditions(scenario, policy), scenario.failure_words, _horizon_s(scenario, horizon)
    gamma = "Gamma* (the adversarial set, Definition 7)" if adversarial else "Gamma"
    n = result.n_run  # result: a coordinator.validation.ValidationResult
    if not result.certified:
        ce = result.counterexample
        what = (f"did {fail}" if ce["outcome"] == "failure" else "left the domain")
        at = ce["violating_step"] * scenario.dt
        plain = (f"Not certified: the scenario started at {ce['start_state']}, {cond}, {what} after {at:g} s "
                 f"(sample {ce['sample_index']}; `scenario-farm replay` re-runs it).")
        formal = (f"Phi is NOT forward invariant: sample {ce['sample_index']} (stream key seed={seed}, "
                  f"index={ce['sample_index']}) from {ce['start_state']} {ce['reason']}.")
        return Guarantee(plain, formal)
    own = covering or f"each box at max(its half-width, delta = {delta:g})"
    if algorithm == "delta" and mixed:
        plain = (f"Every scenario started at one of the {n} box centres of this set, {cond}, stays in the set "
                 f"({own}) and does not {fail} for {t}.")
        formal = (f"Phi is {delta:g}-almost forward invariant on its own covering ({own}; Lemma 1) for "
                  f"{policy.description} with probability one (N = {n} runs, {plan_description}, seed {seed}).")
        return Guarantee(plain, formal)
    if algorithm == "delta":
        plain = (f"Every scenario started at one of the {n} centres covering this domain (spacing 2 x delta = "
                 f"{2 * delta:g}), {cond}, stays within delta of the domain and does not {fail} for {t}.")
        formal = (f"Phi is {delta:g}-almost forward invariant (resolution complete, Lemma 1) for "
                  f"{policy.description} with probability one (N = {n} runs, {plan_description}, seed {seed}).")
        return Guarantee(plain, formal)
    if algorithm == "eps":
        where, kind, leave = "started in this domain (uniformly)", f"{epsilon:g}-almost", "leave it"
    elif mixed:
        where = "started at this set's box centres (uniformly)"
        kind, leave = f"({epsilon:g}, {delta:g})-almost", f"leave its boxes ({own})"
    else:
        where = f"started at this domain's {delta:g}-covering centres (uniformly)"
        kind, leave = f"({epsilon:g}, {delta:g})-almost", f"leave it by more than delta = {delta:g}"
    plain = (f"With {_percent(1 - beta)} confidence, at most {_percent(epsilon)} of scenarios {where}, {cond}, "
             f"{fail} or {leave} within {t}.")
    formal = (f"Phi is {kind} robustly controlled forward invariant w.r.t. {gamma} with confidence {1 - beta:g} "
              f"(N = {n} runs, {plan_description}, actions {policy.description}, seed {seed}).")
    return Guarantee(plain, formal)
