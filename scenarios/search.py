"""``actions.mode = "search"``: a mixture of action-sequence families over Gamma whose
weights the campaign adapts toward what makes runs fail (coordinator/adversary.py).

Families (``families``):
- ``uniform``: u ~ U(Gamma) i.i.d. at every step (what ``mode = "uniform"`` samples);
- ``vertex k``: u held at vertex k of the box Gamma for the whole run (one family per
  vertex while Gamma has at most ``MAX_VERTEX_FAMILIES`` vertices): for dynamics that are
  monotone in u, the worst case is one of these;
- ``bang-bang``: piecewise constant between random vertices of Gamma with random switch
  times (a per-run dwell of 1 to ``MAX_DWELL`` steps, log-uniform, and a random phase):
  for control-affine dynamics the worst case over a horizon is bang-bang.

Every run's family and actions come from its own stream (seed, sample index) and the
weights in force for its index. The weights are a *schedule*: ``[(first_index, weights),
...]``, entry e applying to the runs from ``first_index`` on; the campaign appends an
entry at each round end. The schedule only grows, so the newest one reproduces every
earlier run: replay and experience replay need nothing but the key and that schedule.

Draws: counter 0 of the action sub-stream picks the family (lane 0) and the bang-bang
dwell and phase (lanes 1, 2); a uniform run draws step t's action at counter t, a
bang-bang run draws segment j's vertex at counter j + 1 (one lane per action).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from scenarios.actions import ActionPolicy, describe_action
from scenarios.streams import PURPOSE_ACTION, RunStreams

MAX_VERTEX_FAMILIES = 16  # Gamma's vertices get a family each up to this many (m <= 4)
MAX_DWELL = 40  # steps: the longest bang-bang segment (log-uniform from 1)
_FAMILY_CACHE = "search.family"  # per-run cache keys in RunStreams (carried by subset())
_SWITCH_CACHE = "search.switching"


@dataclass(frozen=True)
class Family:
    kind: str  # "uniform" | "vertex" | "bang-bang"
    vertex: tuple[float, ...] | None = None

    def label(self) -> str:
        if self.kind == "vertex":
            return "vertex " + ", ".join(f"{v:g}" for v in self.vertex)
        return self.kind

    def words(self, scenario) -> str:
        if self.kind == "vertex":
            return describe_action(scenario, self.vertex) + " throughout"
        if self.kind == "bang-bang":
            return "switching between the extremes of Gamma at random times (bang-bang)"
        return "drawn uniformly from Gamma at every step"


def families(scenario) -> list[Family]:
    out = [Family("uniform")]
    if 2 ** scenario.m <= MAX_VERTEX_FAMILIES:
        for corner in itertools.product((0, 1), repeat=scenario.m):
            vertex = np.where(np.array(corner) == 1, scenario.action_upper, scenario.action_lower)
            out.append(Family("vertex", tuple(float(v) for v in vertex)))
    out.append(Family("bang-bang"))
    return out


@dataclass
class SearchActions(ActionPolicy):
    """The mixture; ``schedule`` holds the weights by first sample index."""

    scenario: object = None
    schedule: list = field(default_factory=list)  # [(first_index, (w_0, ..., w_F-1)), ...]
    deterministic: bool = False

    def __post_init__(self):
        self.families = families(self.scenario)
        if not self.schedule:
            f = len(self.families)
            self.schedule = [(0, tuple([1.0 / f] * f))]
        self._index()

    def _index(self) -> None:
        self._firsts = np.array([first for first, _ in self.schedule], dtype=np.uint64)
        cum = np.cumsum(np.array([w for _, w in self.schedule], dtype=float), axis=1)
        self._cum = cum / cum[:, -1:]

    # -- the schedule as plain data (what executors ship, checkpoints and adversary.json keep)
    def state(self) -> dict:
        return {"schedule": [[int(first), [float(w) for w in weights]] for first, weights in self.schedule]}

    def load(self, state: dict) -> None:
        schedule = [(int(first), tuple(float(w) for w in weights)) for first, weights in state["schedule"]]
        if schedule != self.schedule:
            self.schedule = schedule
            self._index()

    def append(self, first_index: int, weights) -> None:
        if first_index < self.schedule[-1][0]:
            raise ValueError(f"search schedule: entry at {first_index} before the last one at {self.schedule[-1][0]}")
        if first_index == self.schedule[-1][0]:
            self.schedule.pop()  # nothing was sampled with the last entry
        self.schedule.append((int(first_index), tuple(float(w) for w in weights)))
        self._index()

    @property
    def weights(self) -> tuple[float, ...]:
        """The weights in force now (for the newest runs)."""
        return self.schedule[-1][1]

    # -- sampling ------------------------------------------------------------------------
    def family_of(self, streams: RunStreams) -> np.ndarray:
        """(B,) each run's family index, from its key and the weights for its index."""
        cached = streams._bases.get(_FAMILY_CACHE)
        if cached is not None:
            return cached
        entry = np.searchsorted(self._firsts, streams.indices, side="right") - 1
        u = streams.uniform(0, PURPOSE_ACTION, 1)[:, 0]
        fam = (self._cum[entry] <= u[:, None]).sum(axis=1)
        fam = np.minimum(fam, len(self.families) - 1).astype(np.uint64)
        streams._bases[_FAMILY_CACHE] = fam  # subset() carries it with the rows
        return fam

    def __call__(self, scenario, states, t, streams):
        fam = self.family_of(streams).astype(np.intp)  # also caches the action stream's base
        out = np.empty((len(fam), scenario.m))
        for k, family in enumerate(self.families):
            rows = np.flatnonzero(fam == k)
            if len(rows) == 0:
                continue
            if family.kind == "vertex":
                out[rows] = family.vertex
            elif family.kind == "uniform":  # only these runs draw: late rounds hold few of them
                u = streams.subset(rows).uniform(t, PURPOSE_ACTION, scenario.m)
                out[rows] = scenario.action_lower + scenario.action_span * u
            else:
                out[rows] = self._bang_bang(scenario, streams, rows, t)
        return out

    def _bang_bang(self, scenario, streams, rows, t) -> np.ndarray:
        switching = streams._bases.get(_SWITCH_CACHE)
        if switching is None:  # per run: dwell (steps) and phase, drawn once
            head = streams.uniform(0, PURPOSE_ACTION, 3)
            dwell = np.maximum(np.floor(np.exp(head[:, 1] * np.log(MAX_DWELL + 1))), 1.0)
            switching = np.column_stack([dwell, np.floor(head[:, 2] * dwell)])
            streams._bases[_SWITCH_CACHE] = switching  # (B, 2): subset() carries it with the rows
        dwell, phase = switching[rows, 0], switching[rows, 1]
        segment = ((t - 1 + phase) // dwell).astype(np.uint64) + np.uint64(1)
        sub = streams.subset(rows)
        out = np.empty((len(rows), scenario.m))
        for lane in range(scenario.m):
            upper = sub.uniform_at(segment, PURPOSE_ACTION, lane) >= 0.5
            out[:, lane] = np.where(upper, scenario.action_upper[lane], scenario.action_lower[lane])
        return out

    # -- words -----------------------------------------------------------------------------
    @property
    def description(self) -> str:  # type: ignore[override]
        parts = [f"{f.label()} {w:.3f}" for f, w in zip(self.families, self.weights)]
        return "search mixture (" + ", ".join(parts) + ")"

    def words(self, scenario) -> str:
        order = np.argsort(self.weights)[::-1]
        parts = [f"{100 * self.weights[k]:.3g}% {self.families[k].words(scenario)}" for k in order]
        which = "the final round's search mixture" if len(self.schedule) > 1 else "the search mixture"
        return f"with each scenario's actions drawn from {which}: " + "; ".join(parts)
