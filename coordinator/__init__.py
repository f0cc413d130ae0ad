"""The coordinator: algorithm state and the campaign driver (the middle layer; it imports
``scenarios`` and nothing of ``farm``).

- ``Algorithm`` (``algorithm.py``): the quantification contract, ask/tell over explicit
  state; ``SPE`` (``spe.py``, paper Alg. 8) and the baselines AE, delta-pruning and VS
  (``baselines.py``), by name from ``make_algorithm``; ``coordinator/testing.py`` is the
  conformance suite every algorithm passes.
- ``Campaign`` and ``CampaignSettings`` (the ``driver`` package): the batch driver that
  keeps the parallel contract (shared/spec/algorithms.md), one part per job
  (``driver/__init__.py`` lists them); it asks an ``Executor`` (``executor.py``: the
  contract of where runs are simulated) for ``Chunk``s.
- ``Coverage`` (``coverage.py``): what a run is screened against, on the coordinator
  and as mirrors on the workers; the spatial index under it (``spatial.py``); the
  lattice of delta-coverings (``lattice.py``); the exploration graph (``graph.py``);
  experience replay (``experience_replay.py``); prioritized sampling (``sampler.py``,
  ``priorities.py``); certification (``certification.py``: closing rounds and checks)
  and its bookkeeping (``checked_centres.py``, ``enumeration.py``); coupled counting's
  stable draws (``stable_sampler.py``); boxes of
  mixed sizes (``levels.py``, ``level_grid.py``, ``refinement.py``); a growable array
  (``buffers.py``).
- Validation of a claimed domain (``validation.py``, ``domain.py``), sample sizes
  (``sample_size.py``: Lemmas 1 and 2), the guarantee in words (``guarantee.py``),
  volumes (``volume.py``), reference sets and comparison (``reference.py``), the
  adversary search (``adversary.py``).
- A failure rate beside the set (the ``estimation`` package): strata of Sigma around a
  quantified set with their masses under a scenario distribution, Neyman stages on an
  executor, the stratified and paired estimators and their intervals.
"""

from coordinator.algorithm import Algorithm, EmptySetError, Event
from coordinator.baselines import AdaptiveExploration, DeltaPruning, VanillaSampling, make_algorithm
from coordinator.driver import Campaign, CampaignSettings, Counters, DriverState
from coordinator.coverage import Coverage, Screening
from coordinator.executor import Chunk, Executor
from coordinator.lattice import Lattice
from coordinator.sample_size import covering_size, n_eps, n_eps_attempt
from coordinator.spe import SPE, SPESettings

__all__ = ["AdaptiveExploration", "Algorithm", "Campaign", "CampaignSettings", "Chunk", "Counters", "Coverage",
           "DeltaPruning", "DriverState", "EmptySetError", "Event", "Executor", "Lattice", "SPE", "SPESettings",
           "Screening", "VanillaSampling", "covering_size", "make_algorithm", "n_eps", "n_eps_attempt"]
