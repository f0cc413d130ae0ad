"""The scenario interface: state box Sigma, facets, action space, vectorized step.

A scenario is the system ``sigma(t+1) = f(sigma(t), u(t); w(t))`` of the paper (eq. 3),
with the SV policy (the black box under test) folded into ``f``. Batches are rows:
states ``(B, n)``, actions ``(B, m)``.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from scenarios.errors import ConfigError, ScenarioError

# A facet counts as crossed only when crossed by more than this, so that a state landing
# exactly on a facet (as grid states do) is decided as exact arithmetic would decide it.
FACET_TOLERANCE = 1e-9

CONTINUE, TRUNCATED, FAILURE, HORIZON = 0, 1, 2, 3
NO_SV = "none"  # the sv_policy of a scenario without an SV policy (e.g. the toy)
EXTERNAL_SV = "external"  # the SV is simulated by the back end (e.g. SUMO's car following)
OUTCOME_NAMES = {TRUNCATED: "truncated", FAILURE: "failure", HORIZON: "horizon"}


@dataclass(frozen=True)
class View:
    """A 3-D picture of a safe set: over the plane (x, y), the boundary value of z.

    ``safe_above``: the safe set lies above the surface (the smallest safe z is drawn,
    e.g. a gap that must be large enough) or below it (the largest safe z). The other
    coordinates are held at ``fixed`` (state name -> value), by default mid-range."""

    name: str  # file-safe, e.g. "lead_side"
    title: str  # e.g. "lead side"
    axes: tuple[str, str, str]  # state names x, y, z
    safe_above: bool = True
    fixed: tuple[tuple[str, float], ...] = ()


@dataclass(frozen=True)
class Slices:
    """2-D cuts of a safe set: the plane (x, y) at a few values of ``varied``."""

    x: str
    y: str
    varied: str | None = None


@dataclass(frozen=True)
class Facet:
    """One facet of the box Sigma: ``state[axis] < bound`` (lower) or ``> bound`` (upper)."""

    name: str  # the state variable, e.g. "p10"
    axis: int
    upper: bool
    bound: float

    @property
    def label(self) -> str:
        return f"{self.name} {'>' if self.upper else '<'} {self.bound:g}"


class Scenario(ABC):
    """A scenario system. Subclasses set the class attributes and implement ``step``.

    Class attributes:
      name            registry name, e.g. "lead-follow"
      state_names     tuple of n state variable names
      lower, upper    (n,) bounds of the box Sigma
      failure_sides   failure facets: state name -> True for its upper bound, False for
                      its lower (e.g. {"p10": False}: the gap below its lower bound)
      action_names    tuple of m action names
      action_lower, action_upper  (m,) bounds of Gamma
      adversarial_actions  (k, m) the finite adversarial set Gamma*
      dt              time step [s]
      sv_policies     SV policy name -> function (v0, v1, gap) -> SV acceleration;
                      empty for a scenario without an SV (or whose SV is the back end's)
      noise_width     U[0,1) draws per step for the disturbance (0: none supported)
      units           state name -> unit, for labels (e.g. {"v0": "m/s"})
      action_words    action name -> what it is, in words (e.g. {"u1": "the lead
                      vehicle's acceleration"}) and ``action_units``: for the plain
                      guarantee ("with the lead vehicle's acceleration held at -5 m/s^2")
      failure_words   what a failure is, as a verb (e.g. "collide")
      sides           named sub-studies: side name -> the failure facets that count
                      (e.g. fleet3's {"lead": ("p10",), "rear": ("p20",)}); each side is a
                      campaign of its own after the total (more runs: runs_committed sums
                      them), reported as volume_<side>_side; in a side's study another
                      side's failure facet ends a run without a failure (side_failures)
      parameter_names state variables that are parameters of the domain (a friction
                      coefficient, a controller's time headway): constant during a run.
                      ``step`` keeps them (the generic ``step_into`` copies them through;
                      a scenario writing its own calls ``hold_parameters``), their step
                      bound is 0 and they cannot be failure facets: a run never leaves
                      Sigma through a parameter's facet.
      margin_through_contact  the dynamics stay defined past a failure facet (a
                      negative gap): a failed run is stepped on to its horizon, without
                      being classified again, so that its margin says how deep it went
      config_options  keyword options of the constructor that a config may set as
                      ``scenario.<option>`` (e.g. platoon's "vehicles", "followers")
      traffic_roles   of a scenario laid out as vehicles on one lane (``vehicle_roles``,
                      farm/openscenario/layout.py): the vehicles no action column
                      commands, driven by the scenario's own traffic model (platoon's
                      cars between the SV and the commanded ones); the SUMO back end and
                      an OpenSCENARIO logical scenario cannot say how they drive
    """

    name: str = ""
    state_names: tuple[str, ...] = ()
    lower: np.ndarray
    upper: np.ndarray
    failure_sides: dict[str, bool] = {}  # facet name -> True for an upper facet
    action_names: tuple[str, ...] = ()
    action_lower: np.ndarray
    action_upper: np.ndarray
    adversarial_actions: np.ndarray
    dt: float = 0.1
    sv_policies: dict = {}  # name -> SV policy function; empty: the scenario has none
    noise_width: int = 0  # how many U[0,1) draws per step the disturbance needs
    adversary_settle_steps: int | None = None  # see reference_safe
    units: dict[str, str] = {}
    state_words: dict[str, str] = {}  # state name -> what it is, for the figures' key
    action_words: dict[str, str] = {}
    action_units: dict[str, str] = {}
    failure_words: str = "fail"
    sides: dict[str, tuple[str, ...]] = {}
    # the rollout may step a failed run on past the facet (its dynamics stay defined there:
    # a negative gap), so that its margin says how deep it went (``failure_distance``)
    margin_through_contact: bool = False
    parameter_names: tuple[str, ...] = ()
    config_options: tuple[str, ...] = ()
    traffic_roles: tuple[str, ...] = ()

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        # The farm simulates with step_into. A subclass that rewrites step() alone, over a
        # parent's vectorized step_into that never calls step (LeadFollow's), would be
        # simulated by the parent's dynamics under the user's name: it gets the generic
        # step_into, which calls its step. The parent's step keeps the parent's dynamics
        # (``_step_via_into``), so the user's step may call super().step().
        if "step_into" in cls.__dict__:
            cls._own_step_into = cls.__dict__["step_into"]
        elif "step" in cls.__dict__:
            cls.step_into = Scenario.step_into

    def __init__(self, sv_policy: str | None = None, failure_facets: tuple[str, ...] | None = None,
                 disturbance: float = 0.0):
        """``sv_policy`` names one of ``sv_policies`` (default: the first), or
        ``EXTERNAL_SV`` when a simulator back end drives the SV itself. ``failure_facets``
        selects which failure facets count (default: all); the others act as truncating
        facets. ``disturbance`` is the bound w [m/s^2]."""
        if sv_policy is None:
            sv_policy = next(iter(self.sv_policies), NO_SV)
        if sv_policy == EXTERNAL_SV or (sv_policy == NO_SV and not self.sv_policies):
            self._policy = None
        elif sv_policy in self.sv_policies:
            self._policy = self.sv_policies[sv_policy]
        else:
            allowed = ", ".join(self.sv_policies) or NO_SV
            raise ConfigError(f"scenario.sv_policy: {sv_policy!r} is not an SV policy of {self.name!r}; "
                              f"allowed: {allowed}")
        self.sv_policy_name = sv_policy
        names = tuple(self.failure_sides) if failure_facets is None else tuple(failure_facets)
        unknown = [f for f in names if f not in self.failure_sides]
        if unknown:
            raise ConfigError(
                f"scenario.failure_facets: unknown facet {unknown[0]!r}; "
                f"allowed: {sorted(self.failure_sides)}"
            )
        if not names:
            raise ConfigError("scenario.failure_facets: at least one failure facet must count")
        if not (isinstance(disturbance, (int, float)) and disturbance >= 0 and np.isfinite(disturbance)):
            raise ConfigError(f"scenario.disturbance: {disturbance!r} is out of range; allowed [0, inf)")
        if disturbance and not self.noise_width:
            raise ConfigError(f"scenario.disturbance: scenario {self.error_name!r} has no disturbance input; allowed: 0")
        self.failure_facets = names
        self.disturbance = float(disturbance)
        self.lower = np.asarray(self.lower, dtype=float)
        self.upper = np.asarray(self.upper, dtype=float)
        self.action_lower = np.asarray(self.action_lower, dtype=float)
        self.action_upper = np.asarray(self.action_upper, dtype=float)
        self.action_span = self.action_upper - self.action_lower
        self.adversarial_actions = np.atleast_2d(np.asarray(self.adversarial_actions, dtype=float))
        self._check_boxes()
        self.parameter_axes = self._parameter_axes()
        self._below = (self.lower - FACET_TOLERANCE).tolist()  # crossing thresholds
        self._above = (self.upper + FACET_TOLERANCE).tolist()
        self._failure_mask_lower = np.zeros(self.n, dtype=bool)
        self._failure_mask_upper = np.zeros(self.n, dtype=bool)
        for f in names:
            axis = self.state_names.index(f)
            if self.failure_sides[f]:
                self._failure_mask_upper[axis] = True
            else:
                self._failure_mask_lower[axis] = True

    def _check_boxes(self) -> None:
        """Sigma and Gamma are finite boxes of the declared sizes (a user scenario's class
        attributes: an infinite bound is named here, not later as a resolution too fine)."""
        for what, names, lo, hi in (("Sigma", self.state_names, self.lower, self.upper),
                                    ("Gamma", self.action_names, self.action_lower, self.action_upper)):
            if lo.shape != (len(names),) or hi.shape != (len(names),):
                raise ScenarioError(f"scenario {self.error_name!r}: {what}'s bounds have shapes {lo.shape} and {hi.shape}, "
                                    f"expected ({len(names)},): one per name in {tuple(names)}")
            bad = [i for i in range(len(names)) if not (np.isfinite(lo[i]) and np.isfinite(hi[i]) and lo[i] < hi[i])]
            if bad:
                i = bad[0]
                raise ScenarioError(f"scenario {self.error_name!r}: {what} must be a finite box; {names[i]} has bounds "
                                    f"[{lo[i]:g}, {hi[i]:g}], allowed finite lower < upper")

    def _parameter_axes(self) -> tuple[int, ...]:
        """The axes of ``parameter_names``: state variables, none of them a failure facet."""
        wrong = [p for p in self.parameter_names if p not in self.state_names or p in self.failure_sides]
        if wrong:
            raise ScenarioError(f"scenario {self.error_name!r}: parameter {wrong[0]!r} must be a state variable and no "
                                f"failure facet (a parameter never changes, so it never crosses a facet)")
        return tuple(self.state_names.index(p) for p in self.parameter_names)

    @property
    def error_name(self) -> str:
        """The scenario as errors name it: a class of this package by its ``name``
        ('lead-follow'), a user's by ``module:Class`` (as its config names it), never by
        a ``name`` it may have taken from the class it extends."""
        cls = type(self)
        if cls.__module__.split(".")[0] == "scenarios":
            return self.name
        return f"{cls.__module__}:{cls.__qualname__}"

    @property
    def external_sv(self) -> bool:
        """The SV is simulated by the back end (no model of it here)."""
        return bool(self.sv_policies) and self._policy is None

    @property
    def sv_policy(self):
        """The SV policy function (v0, v1, gap) -> acceleration, or None for an
        external SV (simulated by the back end)."""
        return self._policy

    # -- declared geometry -------------------------------------------------------------
    @property
    def n(self) -> int:
        return len(self.state_names)

    @property
    def m(self) -> int:
        return len(self.action_names)

    @property
    def volume(self) -> float:
        return float(np.prod(self.upper - self.lower))

    def facets(self) -> list[tuple[Facet, bool]]:
        """All 2n facets of Sigma with a flag: True if crossing it is a failure."""
        out = []
        for i, name in enumerate(self.state_names):
            out.append((Facet(name, i, False, self.lower[i]), bool(self._failure_mask_lower[i])))
            out.append((Facet(name, i, True, self.upper[i]), bool(self._failure_mask_upper[i])))
        return out

    def label(self, name: str) -> str:
        """Axis label of a state variable: its name, what it is and its unit where the
        scenario says (``state_words``, ``units``): "v0 (the SV's speed, m/s)"; "p10 [m]"
        with a unit only, "x" with neither."""
        unit, words = self.units.get(name), self.state_words.get(name)
        if words:
            return f"{name} ({words}, {unit})" if unit else f"{name} ({words})"
        return f"{name} [{unit}]" if unit else name

    def views(self) -> list[View]:
        """3-D views for figures. Default: the last coordinate over the first two (safe
        above), if there are at least three; scenarios override to say what matters."""
        if self.n < 3:
            return []
        names = self.state_names
        return [View("boundary", "boundary of the safe set", (names[0], names[1], names[-1]))]

    def slices(self) -> list[Slices]:
        """2-D cuts for figures. Default: (first, last) at a few values of the second
        coordinate; two coordinates: the plane itself."""
        names = self.state_names
        if self.n == 2:
            return [Slices(names[0], names[1])]
        return [Slices(names[0], names[-1], names[1])]

    def step_bound(self) -> float:
        """sigma-bar of Assumption 1: an upper bound on ||sigma(t+1) - sigma(t)||_inf.
        The default is Sigma's widest extent (always true, never useful); scenarios with
        known dynamics override it."""
        return float(np.max(self.upper - self.lower))

    def step_bounds(self) -> np.ndarray:
        """sigma-bar per axis: (n,) upper bounds on |sigma_a(t+1) - sigma_a(t)| (speeds
        move at most a_max dt, positions at most v_max dt). Boundary refinement's band is
        that thin along each axis. The default is ``step_bound()`` on every axis but the
        parameters' (0: they never change)."""
        bounds = np.full(self.n, self.step_bound())
        bounds[list(self.parameter_axes)] = 0.0
        return bounds

    # -- dynamics ------------------------------------------------------------------------
    @abstractmethod
    def step(self, states: np.ndarray, actions: np.ndarray, noise: np.ndarray | None) -> np.ndarray:
        """One step for a batch: states (B, n), actions (B, m) -> next states (B, n).

        ``noise`` is ``None`` (no disturbance) or a (B, noise_width) array of U[0,1)
        draws from each run's own stream, to be mapped onto the disturbance bound."""

    def step_into(self, states: np.ndarray, actions: np.ndarray, noise: np.ndarray | None,
                  out: np.ndarray) -> None:
        """``step`` written into ``out`` (n, B), the next states as rows: the run loop
        hands in a slab of its trajectory store. Scenarios of this package override it
        (and define ``step`` through it) to skip a copy of every state."""
        nxt = np.asarray(self.step(states, actions, noise))
        if nxt.shape != states.shape:
            raise ScenarioError(f"scenario {self.error_name!r} step returned shape {nxt.shape}, expected {states.shape}")
        out[...] = nxt.T
        self.hold_parameters(states, out)

    _own_step_into = step_into  # the dynamics ``_step_via_into`` runs (set per class)

    def hold_parameters(self, states: np.ndarray, out: np.ndarray) -> None:
        """Copy the parameters of ``states`` (B, n) into the next states ``out`` (n, B):
        a parameter of the domain never changes during a run."""
        for axis in self.parameter_axes:
            out[axis] = states[:, axis]

    def _require_sv_policy(self) -> None:
        """A functional step needs the SV's policy; a simulator back end brings its own."""
        if self._policy is None:
            raise ScenarioError(f"scenario {self.error_name!r}: the SV is simulated by the back end; a functional step "
                                f"needs an SV policy ({', '.join(self.sv_policies)})")

    def _step_via_into(self, states, actions, noise) -> np.ndarray:
        """``step`` of a scenario that writes its dynamics as ``step_into``: the nearest
        class's own step_into (a subclass's generic one would call step again)."""
        out = np.empty((self.n, len(states)))
        self._own_step_into(states, actions, noise, out)
        return out.T

    # -- classification --------------------------------------------------------------------
    def classify(self, states: np.ndarray) -> np.ndarray:
        """(B, n) -> (B,) int8: CONTINUE, TRUNCATED or FAILURE (failure wins ties).

        One axis at a time: with few columns, 1-D comparisons are much faster than
        (B, n) boolean masks reduced with ``any(axis=1)``. One state (a per-run simulator's
        step) in Python floats: the same comparisons, without numpy's per-call overhead."""
        if len(states) == 1:
            return np.array([self._classify_one(states[0].tolist())], dtype=np.int8)
        left = np.zeros(len(states), dtype=bool)
        failed = np.zeros(len(states), dtype=bool)
        for axis in range(states.shape[1]):
            column = states[:, axis]
            below = column < self._below[axis]
            above = column > self._above[axis]
            left |= below
            left |= above
            if self._failure_mask_lower[axis]:
                failed |= below
            if self._failure_mask_upper[axis]:
                failed |= above
        # a failure also left Sigma, so left + failed is 0, 1 (TRUNCATED) or 2 (FAILURE)
        return np.add(left, failed, dtype=np.int8)

    def _classify_one(self, state: list) -> int:
        verdict = CONTINUE
        for axis, x in enumerate(state):
            if x < self._below[axis]:
                if self._failure_mask_lower[axis]:
                    return FAILURE
                verdict = TRUNCATED
            elif x > self._above[axis]:
                if self._failure_mask_upper[axis]:
                    return FAILURE
                verdict = TRUNCATED
        return verdict

    def failure_distance(self, states: np.ndarray) -> np.ndarray:
        """(..., n) -> (...) the signed distance of each state to the counted failure
        facets, in the facet's own units: positive inside, negative past one (the smallest
        over the facets). A run's *margin* is its smallest value over the run. A scenario
        may override it with a better measure of how close a state is to failing."""
        out = np.full(states.shape[:-1], np.inf)
        for axis in np.flatnonzero(self._failure_mask_lower):
            np.minimum(out, states[..., axis] - self.lower[axis], out=out)
        for axis in np.flatnonzero(self._failure_mask_upper):
            np.minimum(out, self.upper[axis] - states[..., axis], out=out)
        return out

    def exits(self, states: np.ndarray) -> np.ndarray:
        """(B, n) states outside Sigma -> (B,) int8: the facet each left through, as an
        index into ``facets()`` (2 * axis, + 1 for the upper facet); -1 for a state inside.
        The facet that decides ``classify``: the first failure facet crossed, else the
        first facet crossed. Called once per batch, on its runs' last states."""
        crossed = np.empty((len(states), 2 * self.n), dtype=bool)
        crossed[:, 0::2] = states < np.asarray(self._below)
        crossed[:, 1::2] = states > np.asarray(self._above)
        failing = crossed & np.column_stack([self._failure_mask_lower, self._failure_mask_upper]).reshape(-1)
        first = np.where(failing.any(axis=1), failing.argmax(axis=1), crossed.argmax(axis=1))
        return np.where(crossed.any(axis=1), first, -1).astype(np.int8)

    # -- model-based reference (for `compare`) ------------------------------------------
    def reference_safe(self, points: np.ndarray) -> np.ndarray | None:
        """Membership of the maximal safe set from the model, (G, n) -> (G,) bool, or
        None when the scenario has no model (the default). ``compare`` then simulates
        each point under the single adversarial action for ``adversary_settle_steps``
        steps, if the scenario declares that an adversarial run has settled by then (no
        failure can come later), and refuses otherwise."""
        return None

    def describe(self) -> dict:
        return {
            "name": self.name,
            "state_names": list(self.state_names),
            "lower": self.lower.tolist(),
            "upper": self.upper.tolist(),
            "failure_facets": list(self.failure_facets),
            "action_names": list(self.action_names),
            "action_lower": self.action_lower.tolist(),
            "action_upper": self.action_upper.tolist(),
            "adversarial_actions": self.adversarial_actions.tolist(),
            "dt": self.dt,
            "disturbance": self.disturbance,
            "sv_policy": self.sv_policy_name,
        }
