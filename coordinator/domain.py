"""The claimed domain Phi of a validation: a box inside Sigma, optionally cut by linear
constraints a . sigma <= b, or a set written by quantification (union of l-inf boxes).

Sampling is i.i.d. uniform in Phi (or in its boundary set, Theorem 3), drawn from each
run's own stream by rejection, so the sample of run i depends on (seed, i) alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from coordinator.lattice import Lattice
from coordinator.safe_set import COVERING_MARGIN, SafeSet
from scenarios.streams import PURPOSE_START, RunStreams
from scenarios.base import FACET_TOLERANCE, Scenario
from scenarios.errors import ConfigError, ScenarioError

MAX_REJECTION_ROUNDS = 256


class DomainError(ConfigError):
    """A [validate] domain that cannot be sampled as given (one line naming the key)."""


@dataclass
class Domain:
    scenario: Scenario
    lo: np.ndarray  # (n,) bounding box of Phi
    hi: np.ndarray
    cuts_a: np.ndarray  # (c, n): Phi = {lo <= sigma <= hi, cuts_a @ sigma <= cuts_b}
    cuts_b: np.ndarray  # (c,)
    safe_set: SafeSet | None = None  # or the union of a set's boxes
    predicate: object = None  # and, optionally, a membership function (B, n) -> (B,) bool
    predicate_name: str = ""

    # -- construction -------------------------------------------------------------------
    @staticmethod
    def of_set(scenario: Scenario, safe_set: SafeSet) -> "Domain":
        """Phi = the union of a set's boxes (e.g. a quantified safe set)."""
        if len(safe_set) == 0:
            raise DomainError("validate.domain_set: the set holds no boxes")
        if not safe_set.finest > 0:
            raise DomainError(f"validate.domain_set: half_width {safe_set.finest!r} is out of range; allowed (0, inf)")
        return Domain(scenario, np.maximum(safe_set.lower.min(0), scenario.lower),
                      np.minimum(safe_set.upper.max(0), scenario.upper),
                      np.zeros((0, scenario.n)), np.zeros(0), safe_set)

    @staticmethod
    def from_config(scenario: Scenario, section: dict, safe_set: SafeSet | None = None) -> "Domain":
        """The domain of a ``[validate]`` section; ``safe_set``: the set that
        ``validate.domain_set`` names, read by the caller."""
        names = scenario.state_names
        if section.get("domain_set"):
            if section.get("domain") or section.get("constraints"):
                raise DomainError("validate.domain_set: give either domain_set or domain/constraints, not both")
            return Domain.of_set(scenario, safe_set)
        lo, hi = scenario.lower.copy(), scenario.upper.copy()
        for name, bounds in (section.get("domain") or {}).items():
            if name not in names:
                raise DomainError(f"validate.domain.{name}: unknown state variable; allowed: {', '.join(names)}")
            i = names.index(name)
            if (not isinstance(bounds, list) or len(bounds) != 2
                    or not all(isinstance(b, (int, float)) and not isinstance(b, bool) for b in bounds)):
                raise DomainError(f"validate.domain.{name}: expected [low, high], got {bounds!r}")
            a, b = float(bounds[0]), float(bounds[1])
            if not (scenario.lower[i] <= a < b <= scenario.upper[i]):
                raise DomainError(f"validate.domain.{name}: [{a:g}, {b:g}] must be an interval inside Sigma; "
                                  f"allowed {scenario.lower[i]:g} <= low < high <= {scenario.upper[i]:g}")
            lo[i], hi[i] = a, b
        rows, rhs = [], []
        for k, cut in enumerate(section.get("constraints") or []):
            field = f"validate.constraints[{k}]"
            if not isinstance(cut, dict) or set(cut) != {"a", "b"} or not isinstance(cut["a"], dict):
                raise DomainError(f"{field}: expected {{ a = {{ <state> = coefficient, ... }}, b = number }}")
            row = np.zeros(scenario.n)
            for name, coef in cut["a"].items():
                if name not in names:
                    raise DomainError(f"{field}.a.{name}: unknown state variable; allowed: {', '.join(names)}")
                row[names.index(name)] = float(coef)
            if not np.any(row):
                raise DomainError(f"{field}.a: all coefficients are zero")
            rows.append(row)
            rhs.append(float(cut["b"]))
        dom = Domain(scenario, lo, hi, np.array(rows).reshape(-1, scenario.n), np.array(rhs))
        if section.get("domain_predicate"):
            from scenarios.actions import check_output, load_callable, probe_states

            target, signature = section["domain_predicate"], "states (B, n) -> (B,) bool"
            dom.predicate = load_callable(target, "validate.domain_predicate", signature)
            check_output(dom.predicate, target, "validate.domain_predicate", signature, probe_states(lo, hi), None)
            dom.predicate_name = target
        if not dom.contains(dom.midpoints(20)).any():
            raise DomainError("validate.constraints: the constraints leave an (almost) empty domain")
        return dom

    # -- geometry -------------------------------------------------------------------------
    @property
    def is_set(self) -> bool:
        return self.safe_set is not None

    def contains(self, points: np.ndarray) -> np.ndarray:
        if self.is_set:
            return self.safe_set.contains(points)
        tol = FACET_TOLERANCE
        inside = ((points >= self.lo - tol) & (points <= self.hi + tol)).all(axis=1)
        if len(self.cuts_b):
            inside &= (points @ self.cuts_a.T <= self.cuts_b + tol).all(axis=1)
        if self.predicate is not None and inside.any():
            try:
                inside[inside] = np.asarray(self.predicate(points[inside]), dtype=bool)
            except Exception as exc:  # noqa: BLE001 - the user's predicate: named as such
                raise ScenarioError(f"validate.domain_predicate: {self.predicate_name!r} raised "
                                    f"{type(exc).__name__} on {int(inside.sum())} states: {exc}") from None
        return inside

    def boundary_distance(self, points: np.ndarray) -> np.ndarray:
        """l-inf distance to the part of the boundary of Phi a trajectory can leave through
        without ending quietly: faces on a truncating facet of Sigma are left out, since
        leaving there is a truncation, not a violation."""
        if self.is_set or self.predicate is not None:
            raise DomainError("validate.boundary: needs a box domain (with linear constraints); not supported "
                              "with validate.domain_set or validate.domain_predicate")
        sc = self.scenario
        dist = np.full(len(points), np.inf)
        for (facet, failure) in sc.facets():
            i = facet.axis
            bound = self.hi[i] if facet.upper else self.lo[i]
            on_sigma = bound == (sc.upper[i] if facet.upper else sc.lower[i])
            if on_sigma and not failure:
                continue
            d = (bound - points[:, i]) if facet.upper else (points[:, i] - bound)
            dist = np.minimum(dist, d)
        if len(self.cuts_b):
            d = (self.cuts_b - points @ self.cuts_a.T) / np.abs(self.cuts_a).sum(axis=1)
            dist = np.minimum(dist, d.min(axis=1))
        return dist

    def volume(self) -> float:
        if self.is_set:
            return self.safe_set.volume_union()
        box = float(np.prod(self.hi - self.lo))
        if not len(self.cuts_b) and self.predicate is None:
            return box
        return box * float(np.mean(self.contains(self.midpoints(40))))

    def midpoints(self, per_short_side: int, max_points: int = 2**20) -> np.ndarray:
        """Cell midpoints of a grid over the bounding box: ``per_short_side`` cells along
        its shortest side, cubic cells, coarser when that would exceed ``max_points`` (a
        domain 1e-7 thin on one axis must not ask for 1e9 cells on the others)."""
        extent = self.hi - self.lo
        step = min(extent) / per_short_side
        counts = np.maximum(1, np.ceil(extent / step - 1e-9))
        while np.prod(counts) > max_points:
            step *= 2
            counts = np.maximum(1, np.ceil(extent / step - 1e-9))
        axes = [lo + (np.arange(k) + 0.5) * (e / k) for lo, e, k in zip(self.lo, extent, counts.astype(int))]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, len(axes))

    def lattice(self, delta: float, reach: float | None = None) -> np.ndarray:
        """delta-covering centres of Phi (Definition 1). A set domain's own box centres
        (its covering is the one it was built on: Definition 1 asks only that *some*
        delta-covering works, and delta at least every box's half-width makes them
        one); otherwise the tiling of the bounding box, kept where the centre lies in
        Phi (and in the boundary set within ``reach``, if given)."""
        if self.is_set:
            # a set of mixed sizes (boundary refinement) is its own covering: each box at
            # its own half-width or delta, whichever is larger (``covering``)
            least = self.safe_set.coarsest if self.safe_set.is_uniform else self.safe_set.finest
            if delta < least * (1 - 1e-12):
                raise DomainError(f"validate.delta: {delta:g} is below the set's "
                                  f"{'' if self.safe_set.is_uniform else 'smallest '}box half-width "
                                  f"{least:g}; allowed [{least:g}, inf)")
            return np.asarray(self.safe_set.centres)
        centres = Lattice.tiling(self.lo, self.hi, delta).box_centres(delta)
        keep = self.contains(centres)
        if reach is not None:
            keep &= self.boundary_distance(centres) <= reach
        return centres[keep]

    def covering(self, delta: float) -> SafeSet | None:
        """Phi_delta of a set of mixed box sizes: each box at max(its half-width, delta)
        (None for any other domain: the delta-boxes of ``lattice``'s centres). A set with
        a half-width per axis that says how far past its boxes its covering reaches
        (margin refinement's ``covering_margin``): each box widened by that, at least to
        delta, per axis."""
        if not self.is_set or self.safe_set.is_uniform:
            return None
        s = self.safe_set
        if s.anisotropic:
            margin = float(s.metadata.get(COVERING_MARGIN, 0.0))
            return SafeSet(s.centres, np.maximum(s.axis_half_widths + margin, delta), s.state_names)
        return SafeSet(s.centres, np.maximum(s.half_widths, delta), s.state_names)

    def covering_words(self, delta: float, named: bool = False) -> str:
        """``covering`` in words: "each box at max(its half-width, 1)", or for a set with a
        covering margin "each box at max(its half-widths + 0.5, 1) per axis"; ``named``:
        "delta = 1"."""
        value = f"delta = {delta:g}" if named else f"{delta:g}"
        s = self.safe_set
        if s is not None and s.anisotropic:
            margin = float(s.metadata.get(COVERING_MARGIN, 0.0))
            return f"each box at max(its half-widths + {margin:g}, {value}) per axis"
        return f"each box at max(its half-width, {value})"

    # -- sampling ---------------------------------------------------------------------------
    def sample(self, streams: RunStreams, reach: float | None = None) -> np.ndarray:
        """i.i.d. uniform in Phi (or its boundary set): rejection from the bounding box, attempt k
        of run i using draw k of its start stream. For a set domain a box is picked with
        probability proportional to its volume (uniformly, when the boxes share one size)
        and a point in it accepted with probability 1/(boxes covering it), which is
        exactly uniform on the union."""
        n = self.scenario.n
        out = np.full((len(streams), n), np.nan)
        todo = np.arange(len(streams))
        for attempt in range(MAX_REJECTION_ROUNDS):
            if len(todo) == 0:
                return out
            sub = streams.subset(todo)
            if self.is_set:
                u = sub.uniform(attempt, PURPOSE_START, n + 2)
                box = self._pick_box(u[:, 0])
                pts = self.safe_set.centres[box] + self.safe_set.axis_half_widths[box] * (2 * u[:, 1 : n + 1] - 1)
                pts = np.clip(pts, self.scenario.lower, self.scenario.upper)
                ok = u[:, n + 1] * self._cover_count(pts) <= 1.0
            else:
                u = sub.uniform(attempt, PURPOSE_START, n)
                pts = self.lo + (self.hi - self.lo) * u
                ok = self.contains(pts)
                if reach is not None:
                    ok &= self.boundary_distance(pts) <= reach
            out[todo[ok]] = pts[ok]
            todo = todo[~ok]
        raise DomainError("validate.domain: rejection sampling accepts too rarely (the domain or its boundary set is "
                          "a tiny part of its bounding box); enlarge it or drop validate.boundary")

    def _pick_box(self, u: np.ndarray) -> np.ndarray:
        """A box per uniform number u, with probability proportional to its volume."""
        boxes = len(self.safe_set)
        if self.safe_set.is_uniform:
            return np.minimum((u * boxes).astype(np.int64), boxes - 1)
        cdf = np.cumsum(np.prod(self.safe_set.axis_half_widths, axis=1))
        return np.minimum(np.searchsorted(cdf, u * cdf[-1], side="right"), boxes - 1)

    def _cover_count(self, pts: np.ndarray) -> np.ndarray:
        """How many of the set's boxes hold each point (at least 1)."""
        if self.safe_set.disjoint:  # a partition's boxes meet only on faces
            return np.ones(len(pts))
        from scipy.spatial import cKDTree

        trees = getattr(self, "_trees", None)
        if trees is None:
            trees = self._trees = [(width, cKDTree(centres)) for width, centres in self.safe_set.by_width()]
        hits = sum(tree.query_ball_point(pts, width + 1e-12, p=np.inf, return_length=True) for width, tree in trees)
        return np.maximum(hits, 1)

    def describe(self) -> str:
        if self.is_set:
            return f"a union of {len(self.safe_set)} boxes of {self.safe_set.describe_widths()}"
        names = self.scenario.state_names
        parts = [f"{nm} in [{a:g}, {b:g}]" for nm, a, b in zip(names, self.lo, self.hi)]
        for row, b in zip(self.cuts_a, self.cuts_b):
            terms = " + ".join(f"{c:g}*{nm}" for c, nm in zip(row, names) if c)
            parts.append(f"{terms} <= {b:g}")
        if self.predicate is not None:
            parts.append(f"{self.predicate_name}(sigma) true")
        return ", ".join(parts)
