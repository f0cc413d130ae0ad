"""Per-run random streams keyed by (campaign seed, global sample index).

The parallel contract needs every run's randomness to depend on nothing but
(seed, sample index): not on the worker, the batch it travelled in, or the time.
Creating one ``numpy.random.Generator`` per run costs ~15 us, which would dominate a
vectorized batch of 1e5 runs, so the streams are *counter-based* and evaluated for a
whole batch at once with numpy integer arithmetic:

    base(seed, index, purpose) = mix(mix(seed + G) ^ mix(index * G2 + purpose * G3 + G))
    draw(counter, lane)        = mix(base + (counter * LANES + lane + 1) * G)

``mix`` is the SplitMix64 finalizer (Steele, Lea and Flood, OOPSLA 2014; the generator
behind Java's SplittableRandom): each (seed, index, purpose) is one SplitMix64 sequence
started from a hashed state. A run's key is printed as ``(seed, index)``; re-running from
that key reproduces the run.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

_G_INT = 0x9E3779B97F4A7C15  # golden-ratio increment of SplitMix64
_G = np.uint64(_G_INT)
_G2 = np.uint64(0xD1B54A32D192ED03)
_G3 = np.uint64(0xAEF17502108EF2D9)
_C1 = np.uint64(0xBF58476D1CE4E5B9)
_C2 = np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = (np.uint64(s) for s in (30, 27, 31, 11))
LANES = 64  # at most this many draws per (counter, purpose)

# Purposes separate the sub-streams of one run so that they never share a counter.
PURPOSE_START = 0  # which start state the run gets
PURPOSE_ACTION = 1  # the scenario action sequence
PURPOSE_DISTURBANCE = 2  # the bounded disturbance w
PURPOSE_USER = 3  # free for user scenarios


def mix64(z: np.ndarray) -> np.ndarray:
    """SplitMix64 finalizer on a uint64 array (wrapping arithmetic)."""
    z = z ^ (z >> _S30)
    z *= _C1
    z ^= z >> _S27
    z *= _C2
    z ^= z >> _S31
    return z


@lru_cache(maxsize=64)
def _seed_part(seed: int) -> np.ndarray:
    part = mix64(np.array([(seed + _G_INT) % 2**64], dtype=np.uint64))
    part.flags.writeable = False  # shared by every batch of the seed
    return part


@lru_cache(maxsize=16)
def _purpose_offset(purpose: int) -> np.uint64:
    return np.uint64((purpose * int(_G3) + _G_INT) % 2**64)


@lru_cache(maxsize=64)
def _grid_steps(start: int, stop: int, width: int) -> np.ndarray:
    """(stop - start, width) the increments of draws (counter, lane) (read-only: shared)."""
    steps = np.array([[(c * LANES + lane + 1) * _G_INT % 2**64 for lane in range(width)] for c in range(start, stop)],
                     dtype=np.uint64)
    steps.flags.writeable = False
    return steps


_UNIT = 1.0 / 9007199254740992.0  # 2**-53: a draw is its top 53 bits times this


def _mix64_inplace(z: np.ndarray, scratch: np.ndarray) -> None:
    """``mix64`` in place, with one scratch array: the same values, without the five
    temporaries a 1e5-row action draw would otherwise allocate every step."""
    np.right_shift(z, _S30, out=scratch)
    z ^= scratch
    z *= _C1
    np.right_shift(z, _S27, out=scratch)
    z ^= scratch
    z *= _C2
    np.right_shift(z, _S31, out=scratch)
    z ^= scratch


@dataclass(frozen=True)
class RunStreams:
    """The random streams of a batch of runs: one per sample index.

    ``uniform(counter, purpose, width)`` returns a ``(B, width)`` array of independent
    U[0, 1) doubles: draw ``counter`` of each run's ``purpose`` sub-stream.
    """

    seed: int
    indices: np.ndarray  # (B,) uint64 global sample indices
    _bases: dict = field(default_factory=dict, compare=False, repr=False)

    @staticmethod
    def of(seed: int, indices) -> "RunStreams":
        if not 0 <= int(seed) < 2**63:
            raise ValueError(f"seed: must be in [0, 2**63), got {seed}")
        return RunStreams(int(seed), np.ascontiguousarray(indices, dtype=np.uint64))

    def __len__(self) -> int:
        return len(self.indices)

    def subset(self, rows) -> "RunStreams":
        sub = RunStreams(self.seed, self.indices[rows])
        for purpose, base in self._bases.items():
            sub._bases[purpose] = base[rows]
        return sub

    def _base(self, purpose: int) -> np.ndarray:
        base = self._bases.get(purpose)
        if base is None:
            # array arithmetic wraps silently; the scalar terms are folded in Python integers
            idx_part = mix64(self.indices * _G2 + _purpose_offset(purpose))
            base = mix64(_seed_part(self.seed) ^ idx_part)
            self._bases[purpose] = base
        return base

    def uniform(self, counter: int, purpose: int, width: int = 1) -> np.ndarray:
        if not 0 < width <= LANES:
            raise ValueError(f"width must be in [1, {LANES}]")
        base = self._base(purpose)
        out = np.empty((len(base), width))
        z, scratch = np.empty_like(base), np.empty_like(base)
        for lane in range(width):
            # the increment in Python integers (array uint64 arithmetic wraps silently; a
            # numpy scalar product would warn on overflow)
            step = np.uint64((counter * LANES + lane + 1) * _G_INT % 2**64)
            np.add(base, step, out=z)
            _mix64_inplace(z, scratch)
            z >>= _S11
            np.multiply(z, _UNIT, out=out[:, lane])  # uint64 -> double: exact below 2**53
        return out

    def uniform_at(self, counters: np.ndarray, purpose: int, lane: int = 0, rows: np.ndarray | None = None) -> np.ndarray:
        """(B,) U[0, 1) doubles: draw ``counters[r]`` (one counter per run) of lane
        ``lane`` of each run's ``purpose`` sub-stream; equals ``uniform(c, purpose,
        lane + 1)[r, lane]`` for ``c = counters[r]``. For policies whose runs are at
        different counters of their own schedule (bang-bang switching). ``rows``: the
        runs asked, one per counter (repeats allowed), as ``subset(rows).uniform_at``
        but without deriving their sub-streams again."""
        if not 0 <= lane < LANES:
            raise ValueError(f"lane must be in [0, {LANES})")
        base = self._base(purpose)
        if rows is not None:
            base = base[rows]
        counters = np.asarray(counters, dtype=np.uint64)
        with np.errstate(over="ignore"):  # uint64 arithmetic wraps, as SplitMix64 wants
            z = base + (counters * np.uint64(LANES) + np.uint64(lane + 1)) * _G
        z = mix64(z)
        return (z >> _S11) * _UNIT

    def uniform_grid(self, counters: range, purpose: int, width: int, rows: np.ndarray) -> np.ndarray:
        """(len(rows), len(counters), width) U[0, 1) doubles: entry [r, c, lane] equals
        ``uniform(counters[c], purpose, width)[rows[r], lane]``. Every run asked at the
        same counters (a sampler's block of tries): one gather of the runs' sub-streams and
        the increments of (counter, lane) computed once, not per run."""
        if not 0 < width <= LANES:
            raise ValueError(f"width must be in [1, {LANES}]")
        base = self._base(purpose)[rows]
        steps = _grid_steps(counters.start, counters.stop, width)
        z = base[:, None, None] + steps[None, :, :]  # uint64 arithmetic wraps, as SplitMix64 wants
        z = mix64(z)
        return (z >> _S11) * _UNIT

