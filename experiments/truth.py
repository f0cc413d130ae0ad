"""Monte-Carlo truth labels for accuracy measurements: which start states are safe under
Gamma*, computed by a second, independent copy of the dynamics.

Written again from shared/spec/scenarios.md alone (kinematics, the SV's brake and IDM,
the traffic IDM, the parameters example); it imports nothing of scenarios/, coordinator/
or farm/, so a bug there cannot hide in the labels. It also simulates differently: cars
are front positions and speeds on a lane [m, m/s], and the state is read off them after
every step. Under the single adversarial action the system is deterministic, so one run
per point, to its end, decides its label: a failure (unsafe), a truncation or the
standstill of every car (its state stops changing: nothing can happen later) (safe).

    python experiments/truth.py platoon5/idm 1000000 0 [--out truth.npz]

Cases: ``lead-follow/{brake,idm}``, ``fleet3/{brake,idm}[/lead|/rear]`` (the side: only
that failure facet counts, the other truncates), ``platoon<k>[r<r>]/{brake,idm}[/lead|
/rear]`` (k cars, r followers, default 1), ``lead-follow-params/{brake,idm}``.
"""

from __future__ import annotations

import re
import sys
import time
from dataclasses import dataclass, replace
from typing import Callable

import numpy as np

DT = 0.1  # [s]
CAR_LENGTH = 5.0  # [m]
TOLERANCE = 1e-9  # [m or m/s] a facet counts as crossed only beyond this
MAX_STEPS = 5000
CHUNK = 1 << 16  # points simulated at once: ~10 arrays of (CHUNK, k) floats, a few MB
FAILURE, TRUNCATED, STANDSTILL = 2, 1, 0
SV_BRAKE = -10.0  # [m/s^2]
LEAD_BRAKE, REAR_BRAKE = -5.0, -3.0  # [m/s^2] Gamma*: front lead brakes hardest, rear follower least


@dataclass(frozen=True)
class Driver:
    """An IDM: a, b [m/s^2], v_des [m/s], T [s], s0 [m], clip [lo, hi] [m/s^2]."""

    a: float
    b: float
    v_des: float
    T: float
    s0: float
    lo: float
    hi: float


SV_IDM = Driver(a=0.73, b=1.67, v_des=30.0, T=1.5, s0=2.0, lo=-4.67, hi=0.73)
TRAFFIC_IDM = Driver(a=1.0, b=2.0, v_des=30.0, T=1.0, s0=2.0, lo=-6.0, hi=1.0)


def idm(driver: Driver, v, v_ahead, s, T=None, lo=None):
    """The spec's IDM on the bumper gap s [m]; T [s] and lo [m/s^2] may be per row."""
    T = driver.T if T is None else T
    lo = driver.lo if lo is None else lo
    desired = driver.s0 + np.maximum(0.0, v * T + v * (v - v_ahead) / (2.0 * np.sqrt(driver.a * driver.b)))
    open_gap = np.where(s > 0.0, s, 1.0)  # s <= 0 brakes fully below: never divide by it
    accel = driver.a * (1.0 - (v / driver.v_des) ** 4 - (desired / open_gap) ** 2)
    return np.where(s > 0.0, np.clip(accel, lo, driver.hi), lo)


def advance(v, a):
    """One step at constant acceleration; a car that would reverse stops inside the step.
    -> (new speed [m/s], distance [m])."""
    v_end = v + a * DT
    stops = v_end < 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        stop_distance = v * v / (2.0 * np.abs(a))
    return np.where(stops, 0.0, v_end), np.where(stops, stop_distance, v * DT + a * DT * DT / 2.0)


@dataclass(frozen=True)
class Case:
    """A system under Gamma*: Sigma, its failure facets (axis, upper?), the lane layout of
    a state, and the cars' accelerations on the lane."""

    name: str
    lower: np.ndarray
    upper: np.ndarray
    failure: tuple[tuple[int, bool], ...]
    to_lane: Callable  # states (B, n) -> fronts (B, c) [m], speeds (B, c) [m/s], extra (B, e)
    to_state: Callable  # fronts, speeds, extra -> states (B, n)
    accelerations: Callable  # fronts, speeds, extra -> (B, c) [m/s^2]


def _sv_accel(policy: str, v, v_ahead, bumper_gap, T=None, mu=1.0):
    if policy == "brake":
        return np.full_like(v, SV_BRAKE) * mu
    return idm(SV_IDM, v, v_ahead, bumper_gap, T=T, lo=SV_IDM.lo * mu)


def lead_follow(policy: str, parameters: bool = False) -> Case:
    """(v0, v1, p10[, T, mu]): the SV (car 0) behind the lead (car 1); p10 a bumper gap."""
    lower, upper = [0.0, 0.0, 0.0], [20.0, 20.0, 70.0]
    if parameters:  # the SV's IDM headway T [s] and the friction mu scaling every braking limit
        lower, upper = lower + [0.8, 0.4], upper + [2.0, 1.0]

    def to_lane(s):
        fronts = np.column_stack([np.zeros(len(s)), s[:, 2] + CAR_LENGTH])
        return fronts, s[:, :2].copy(), s[:, 3:].copy()

    def to_state(x, v, extra):
        return np.column_stack([v, x[:, 1] - x[:, 0] - CAR_LENGTH, extra])

    def accelerations(x, v, extra):
        T, mu = (extra[:, 0], extra[:, 1]) if parameters else (None, 1.0)
        a0 = _sv_accel(policy, v[:, 0], v[:, 1], x[:, 1] - x[:, 0] - CAR_LENGTH, T, mu)
        return np.column_stack([a0, np.full(len(x), LEAD_BRAKE) * mu])

    name = f"lead-follow{'-params' if parameters else ''}/{policy}"
    return Case(name, np.array(lower), np.array(upper), ((2, False),), to_lane, to_state, accelerations)


def platoon(vehicles: int, policy: str, followers: int = 1, side: str | None = None) -> Case:
    """k cars of 5 m: the SV (0), leads 1..m ahead (1 nearest), followers m+1..k-1 behind
    (m+1 nearest). State: speeds, then the lead gaps p10, p21, ... (car ahead minus car
    behind) and the rear gaps p(m+1)0, p(m+2)(m+1), ... (car behind minus car ahead), front
    to front. Cars between the SV and the front lead / rear follower drive the traffic IDM."""
    k, m = vehicles, vehicles - 1 - followers
    if m < 1 or followers < 1:
        raise ValueError(f"platoon: {k} vehicles with {followers} followers leave no lead")
    behind = list(range(0, m)) + [0] + list(range(m + 1, k - 1))  # behind[j - 1]: the car gap j is taken from
    order = list(range(k - 1, m, -1)) + [0] + list(range(1, m + 1))  # cars from the rear to the front
    ahead = {car: order[i + 1] for i, car in enumerate(order[:-1])}
    rear = m  # the column of p(m+1)0 among the gaps
    facets = {"lead": ((k, False),), "rear": ((k + rear, True),)}
    failure = facets[side] if side else facets["lead"] + facets["rear"]
    gaps_lower = [5.0] * m + [-25.0] * followers
    gaps_upper = [25.0] * m + [-5.0] * followers

    def to_lane(s):
        fronts = np.zeros((len(s), k))
        for j in range(1, k):  # the partner of car j has a smaller index: already placed
            fronts[:, j] = fronts[:, behind[j - 1]] + s[:, k - 1 + j]
        return fronts, s[:, :k].copy(), np.zeros((len(s), 0))

    def to_state(x, v, extra):
        return np.column_stack([v] + [x[:, j] - x[:, behind[j - 1]] for j in range(1, k)])

    def accelerations(x, v, extra):
        a = np.empty_like(v)
        for car in range(k):
            if car == 0:
                a[:, 0] = _sv_accel(policy, v[:, 0], v[:, 1], x[:, 1] - x[:, 0] - CAR_LENGTH)
            elif car == m:
                a[:, car] = LEAD_BRAKE
            elif car == k - 1:
                a[:, car] = REAR_BRAKE
            else:
                front = ahead[car]
                a[:, car] = idm(TRAFFIC_IDM, v[:, car], v[:, front], x[:, front] - x[:, car] - CAR_LENGTH)
        return a

    lower = np.array([0.0] * k + gaps_lower)
    upper = np.array([6.0] * k + gaps_upper)
    name = f"platoon{k}r{followers}/{policy}" + (f"/{side}" if side else "")
    return Case(name, lower, upper, failure, to_lane, to_state, accelerations)


def make_case(name: str) -> Case:
    """A case by name (module docstring)."""
    match = re.fullmatch(r"(lead-follow|lead-follow-params|fleet3|platoon(\d)(?:r(\d))?)/(brake|idm)(?:/(lead|rear))?",
                         name)
    if not match:
        raise ValueError(f"case: {name!r} is not a case; allowed e.g. lead-follow/idm, fleet3/brake/rear, "
                         f"platoon5r2/idm, lead-follow-params/idm")
    family, k, r, policy, side = match.groups()
    if family.startswith("lead-follow"):
        if side:
            raise ValueError(f"case: {name!r}: lead-follow has one failure facet; no side")
        return lead_follow(policy, parameters=family.endswith("params"))
    if family == "fleet3":  # the spec: fleet3 is the platoon of three
        return replace(platoon(3, policy, 1, side), name=name)
    return replace(platoon(int(k), policy, int(r or 1), side), name=name)


def outcomes(case: Case, points: np.ndarray) -> np.ndarray:
    """(N, n) start states -> (N,) int8: FAILURE, TRUNCATED or STANDSTILL, each run
    simulated under Gamma* to its end."""
    out = np.empty(len(points), dtype=np.int8)
    for lo in range(0, len(points), CHUNK):
        out[lo : lo + CHUNK] = _outcomes_chunk(case, np.asarray(points[lo : lo + CHUNK], dtype=float))
    return out


def _outcomes_chunk(case: Case, points: np.ndarray) -> np.ndarray:
    result = np.full(len(points), -1, dtype=np.int8)
    x, v, extra = case.to_lane(points)
    rows = np.arange(len(points))
    below, above = case.lower - TOLERANCE, case.upper + TOLERANCE
    failing_lower = np.zeros(len(case.lower), dtype=bool)
    failing_upper = np.zeros(len(case.lower), dtype=bool)
    for axis, upper in case.failure:
        (failing_upper if upper else failing_lower)[axis] = True
    for _ in range(MAX_STEPS):
        v_next, distance = advance(v, case.accelerations(x, v, extra))
        x = x + distance
        state = case.to_state(x, v_next, extra)
        under, over = state < below, state > above
        failed = (under & failing_lower).any(axis=1) | (over & failing_upper).any(axis=1)
        left = (under | over).any(axis=1)
        still = ~left & (distance == 0.0).all(axis=1) & (v_next == 0.0).all(axis=1)
        result[rows[failed]] = FAILURE
        result[rows[left & ~failed]] = TRUNCATED
        result[rows[still]] = STANDSTILL
        going = ~(left | still)
        rows, x, v, extra = rows[going], x[going], v_next[going], extra[going]
        if len(rows) == 0:
            return result
    raise RuntimeError(f"{case.name}: {len(rows)} runs neither ended nor stood still within {MAX_STEPS} steps")


def truth_points(case: str | Case, n_points: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """``n_points`` states uniform over Sigma (numpy's default_rng(seed)) and their labels:
    -> points (N, n), safe (N,) bool."""
    case = make_case(case) if isinstance(case, str) else case
    rng = np.random.default_rng(seed)
    points = rng.uniform(case.lower, case.upper, (n_points, len(case.lower)))
    return points, outcomes(case, points) != FAILURE


def main(argv: list[str]) -> None:
    if len(argv) not in (3, 5) or (len(argv) == 5 and argv[3] != "--out"):
        raise SystemExit("usage: python experiments/truth.py CASE N_POINTS SEED [--out FILE.npz]")
    case = make_case(argv[0])
    start = time.perf_counter()
    points, safe = truth_points(case, int(argv[1]), int(argv[2]))
    seconds = time.perf_counter() - start
    print(f"{case.name}: {int(safe.sum())} of {len(safe)} safe ({safe.mean():.4%}) in {seconds:.1f} s")
    if len(argv) == 5:
        np.savez_compressed(argv[4], points=points, safe=safe, case=np.array(case.name), seed=np.array(int(argv[2])))


if __name__ == "__main__":
    main(sys.argv[1:])
