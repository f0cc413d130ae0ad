"""What a campaign will need, estimated before it starts and refused past a limit.

Accepted values can still ask for the impossible: ``delta_min = 1e-300`` means more boxes
than atoms, a validation domain 1e-7 wide at ``delta = 1e-9`` a lattice of 10^18 centres.
Both used to run until the machine gave out. The estimates here are worst cases (every
cell of the finest covering alive), so a refusal is never wrong about what was asked;
the limit is ``farm.max_memory_gb`` (default: three quarters of this machine's memory).
Refinement that follows the boundary (SPE with band or margin) cannot be bounded before
its runs, short of the whole lattice at delta_min (a 5-D margin campaign that holds 40 k
boxes would be refused for 27 M): its first round is checked here, and the boxes it holds
as it runs (``MemoryGuard``).
The farm is checked too: a local Ray gets at most ``ACTORS_PER_CPU`` actors per CPU of
this machine, or, where the simulator waits on something else (``farm.waiting``: a remote
simulator server, a hardware-in-the-loop rig), as many as fit the memory limit at
``BYTES_PER_ACTOR`` each; a cluster is joined before any file is written.
"""

from __future__ import annotations

import math
import os

import numpy as np

from farm.config import Config, ConfigError
from farm.execution.chunking import fast_lanes
from farm.ray_runtime.session import connect

# Measured: lead-follow idm under Gamma* at delta_min 0.125 peaked at 1.66 GB with 1.83 M
# boxes alive (centres, graph, spatial index, failure distances, replay keys).
BYTES_PER_BOX = 1024
# A validation lattice holds centres, their index and per-centre verdicts.
BYTES_PER_CENTRE = 256
# Actors past the CPUs only share them (a local Ray gives each CPUs / workers of one), and
# each is a process that takes its memory and seconds to start; a few per CPU still hide
# a simulator that waits rather than computes (docs/benchmarks.md, branch errors).
ACTORS_PER_CPU = 4
# A waiting simulator's actors cost memory, not CPU: each is a Ray worker process holding
# the farm, numpy and the scenario. Measured (lead-follow numpy, after a 4,096-run chunk,
# /proc via psutil): 136 MB resident, 66 MB its own (USS); counted with room for a chunk.
BYTES_PER_ACTOR = 150e6


def memory_limit_bytes(cfg: Config) -> float:
    if cfg.farm.max_memory_gb is not None:
        return cfg.farm.max_memory_gb * 1e9
    try:
        return 0.75 * os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # not a POSIX sysconf: a laptop's worth
        return 8e9


def cells(lo, hi, delta: float) -> float:
    """Boxes of half-width ``delta`` tiling [lo, hi] (a float: it may exceed int64)."""
    extent = np.asarray(hi, dtype=float) - np.asarray(lo, dtype=float)
    with np.errstate(over="ignore"):  # inf boxes is a fine answer: it is refused
        return float(np.prod(np.maximum(1.0, np.ceil(extent / (2 * delta) - 1e-9))))


def _finest_allowed(lo, hi, max_cells: float) -> float:
    """About the smallest delta whose tiling has at most ``max_cells`` boxes."""
    extent = np.asarray(hi, dtype=float) - np.asarray(lo, dtype=float)
    return 0.5 * math.exp((np.log(extent).sum() - math.log(max(max_cells, 1.0))) / len(extent))


def _gb(b: float) -> str:
    return f"{b / 1e9:.3g} GB"


def _fits(cfg: Config, field: str, delta: float, lo, hi, per_cell: int, what: str) -> None:
    """Refuse a ``delta`` whose worst-case tiling of [lo, hi] would not fit the limit."""
    limit = memory_limit_bytes(cfg)
    count = cells(lo, hi, delta)
    if count * per_cell > limit:
        finest = _finest_allowed(lo, hi, limit / per_cell)
        raise ConfigError(f"{field}: {delta:g} {what.format(count)} (about {_gb(count * per_cell)}, over the limit "
                          f"farm.max_memory_gb = {_gb(limit)}); allowed {field.split('.')[1]} >= about "
                          f"{finest:.3g}, or raise farm.max_memory_gb")


def machine_cpus() -> int:
    """The CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except (AttributeError, OSError):
        return os.cpu_count() or 1


def waiting_workers_most(limit_bytes: float) -> int:
    """The most workers of a waiting simulator whose actors, fast lanes included, fit
    ``limit_bytes`` at ``BYTES_PER_ACTOR`` each (at least 1)."""
    most = max(1, int(limit_bytes // BYTES_PER_ACTOR))
    while most > 1 and (most + fast_lanes(most)) * BYTES_PER_ACTOR > limit_bytes:
        most -= 1
    return most


def check_farm(cfg: Config) -> None:
    """Refuse a local Ray with more actors than ``ACTORS_PER_CPU`` per CPU, or, with
    ``farm.waiting``, than the memory limit holds (ConfigError). A cluster is joined now,
    before any file is written: an address that answers nothing, or answers but is no
    Ray cluster, is refused with nothing to clean up."""
    farm = cfg.farm
    if farm.executor != "ray":
        return
    if farm.address == "local":
        prefix = f"farm.workers: {farm.workers} actors on a local Ray of {machine_cpus()} CPUs; allowed"
        if farm.waiting:
            limit = memory_limit_bytes(cfg)
            most = waiting_workers_most(limit)
            if farm.workers > most:
                raise ConfigError(f"{prefix} [1, {most}] (farm.waiting: each a process of about "
                                  f"{_gb(BYTES_PER_ACTOR)}, within farm.max_memory_gb = {_gb(limit)}); for more, "
                                  f"join a cluster with farm.address")
            return
        most = ACTORS_PER_CPU * machine_cpus()
        if farm.workers > most:
            raise ConfigError(f"{prefix} [1, {most}] ({ACTORS_PER_CPU} per CPU: more only share the CPUs, each a "
                              f"process of its own; a simulator that waits on a remote server: farm.waiting = "
                              f"true); for more, join a cluster with farm.address")
        return
    connect(farm.address, farm.workers)


def check_quantify(cfg: Config, lower, upper) -> None:
    """Refuse, with the field named, a quantification that cannot fit (ConfigError)."""
    q = cfg.quantify
    half = float(np.max(np.asarray(upper) - np.asarray(lower))) / 2
    if q.delta0 > half * (1 + 1e-12):
        raise ConfigError(f"quantify.delta0: {q.delta0:g} is larger than Sigma (one box of half-width {half:g} "
                          f"covers it; every larger delta0 only adds rounds); allowed (0, {half:g}]")
    if follows_boundary(cfg):
        # only the first round covers all of Sigma; the finer ones follow the boundary, whose
        # size no one knows before the runs: MemoryGuard watches them as they grow
        _fits(cfg, "quantify.delta0", q.delta0, lower, upper, BYTES_PER_BOX, "needs {:.3g} boxes in the first round")
    else:
        _fits(cfg, "quantify.delta_min", q.delta_min, lower, upper, BYTES_PER_BOX, "may need {:.3g} boxes")
    check_farm(cfg)


def follows_boundary(cfg: Config) -> bool:
    """SPE refining only near the boundary (band, margin): its boxes past the first round
    are bounded by the boundary, not by the lattice at delta_min."""
    return cfg.quantify.algorithm == "spe" and cfg.refinement() in ("band", "margin")


def bytes_per_box(cfg: Config, n: int) -> float:
    """What a held box costs: ``BYTES_PER_BOX``, and under margin refinement twice that with
    the states of its run (K + 1 states of n floats, kept for the certificate's invariance
    check and gathered once more by it). Measured: lead-follow-params at delta_min 0.125,
    K = 120, peaked at 8.4 GB holding about 700 k boxes: 12 KB a box; this gives 11.7 KB."""
    if cfg.refinement() == "margin":
        return 2.0 * (BYTES_PER_BOX + 8.0 * n * (cfg.quantify.horizon + 1))
    return float(BYTES_PER_BOX)


class MemoryGuard:
    """Stops a campaign whose held boxes pass ``farm.max_memory_gb`` (checked after every
    committed chunk, so a stop lands at a checkpointable place): the campaign is then
    checkpointed and ``over`` says why in one line, resumable with a higher limit."""

    def __init__(self, cfg: Config, n: int):
        self.limit = memory_limit_bytes(cfg)
        self.per_box = bytes_per_box(cfg, n)
        self.held = 0

    def exceeded(self, held: int) -> bool:
        if held * self.per_box > self.limit:
            self.held = held
            return True
        return False

    def over(self, committed: int, directory) -> ConfigError:
        return ConfigError(
            f"farm.max_memory_gb: the campaign holds {self.held:,} boxes (about {_gb(self.held * self.per_box)}), "
            f"over the limit of {_gb(self.limit)}; stopped and checkpointed at {committed:,} committed runs: "
            f"continue with `scenario-farm resume {directory} --max-memory-gb G` where G GB fit, or start again "
            f"with a coarser quantify.delta_min")


def check_validate(cfg: Config, lo, hi, is_set: bool) -> None:
    """Refuse a validation whose delta-lattice cannot fit, or whose delta exceeds the
    domain (one box would cover it: a single start would 'certify' the whole domain)."""
    v = cfg.validate
    if v.algorithm != "eps" and not is_set:  # eps samples Phi itself; a set brings its own centres
        half = float(np.max(np.asarray(hi) - np.asarray(lo))) / 2
        if v.delta > half * (1 + 1e-12):
            raise ConfigError(f"validate.delta: {v.delta:g} is larger than the domain (half its widest side is "
                              f"{half:g}: one box would cover it, so a single start would stand for all of Phi); "
                              f"allowed (0, {half:g}]")
        _fits(cfg, "validate.delta", v.delta, lo, hi, BYTES_PER_CENTRE, "gives a lattice of {:.3g} centres")
    check_farm(cfg)
