"""Waiting for a worker: a stop (SIGINT / SIGTERM) wakes the wait within ``POLL_S``,
whatever the simulator is doing, and a time limit ends it.

The Ray executor waits on its actors (farm/ray_runtime/pool.py); the in-process executor runs its
simulator in one thread (``InThread``) so that its own wait can end as well. A thread
cannot be cancelled: a chunk abandoned on a stop finishes (or hangs) in the background
until the process ends, and a chunk that overran its limit leaves the thread stuck, so
the executor gives up (``WorkerError``) rather than retrying; Ray replaces the worker.
"""

from __future__ import annotations

import queue
import threading
import time
from typing import Any, Callable

import numpy as np

from scenarios.errors import InfrastructureError

POLL_S = 0.2  # [s] how often a wait looks at the stop flag and the time limits


class WorkerError(InfrastructureError):
    """The workers failed on a chunk (it overran its time limit, or lost its worker) more
    often than ``farm.max_retries`` allows, or no worker is left."""


class Interrupted(KeyboardInterrupt):
    """A wait for a chunk was ended by a stop: nothing was committed since the last chunk,
    so the campaign can be checkpointed as it is."""


def culprit(scenario: dict) -> str:
    """Whose code simulates a ``[scenario]`` section's runs, as errors name it: the back
    end a config names (a user's per-run simulator), else the scenario."""
    backend = scenario.get("backend")
    if backend and backend != "numpy":
        return f"back end {str(backend)!r}"
    return f"scenario {str(scenario.get('name', '?'))!r}"


def name_runs(culprit: str, first: int, starts: np.ndarray, indices: np.ndarray | None = None) -> str:
    """A chunk's runs as an error names them (``culprit``: whose code ran them): the
    sample index and start state of a single run, the index range of several."""
    k = len(starts)
    if k == 1:
        index = first if indices is None else int(indices[0])
        where = f"sample index {index} (start state {np.round(starts[0], 6).tolist()})"
    elif indices is None:
        where = f"the {k} runs at sample indices {first}-{first + k - 1}"
    else:
        where = f"the {k} runs at sample indices {int(indices[0])}, ..., {int(indices[-1])}"
    return f"{culprit}: {where}"


def stop_asked(stop: threading.Event | None) -> None:
    """Raise Interrupted if ``stop`` is set."""
    if stop is not None and stop.is_set():
        raise Interrupted


class InThread:
    """Runs work in one daemon thread while the caller waits, stop-aware and time-limited."""

    def __init__(self, stop: threading.Event | None = None):
        self.stop = stop
        self._work: queue.SimpleQueue = queue.SimpleQueue()
        self._thread: threading.Thread | None = None
        self._stuck = ""  # what the thread is stuck in, once something overran

    def run(self, work: Callable[[], Any], limit: float, what: str | Callable[[], str],
            interruptible: bool = True) -> Any:
        """``work()``'s value (or its exception). Raises Interrupted on a stop
        (``interruptible``), WorkerError when it runs longer than ``limit`` seconds, naming
        ``what`` (a function: asked then, e.g. which user call the work is stuck in)."""
        if self._stuck:
            raise WorkerError(f"the in-process simulator is still stuck in {self._stuck}")
        if self._thread is None:
            self._thread = threading.Thread(target=self._serve, name="farm-simulator", daemon=True)
            self._thread.start()
        done, box = threading.Event(), {}
        self._work.put((work, done, box))
        t0 = time.monotonic()
        while not done.wait(POLL_S):
            if interruptible:
                stop_asked(self.stop)
            if time.monotonic() - t0 > limit:
                self._stuck = what = what() if callable(what) else what
                raise WorkerError(f"{what} did not finish within {limit:.3g} s (farm.chunk_timeout): the simulator "
                                  f"hangs there, or is far slower than on the runs before; the in-process executor "
                                  f"cannot stop it (the Ray executor replaces a hung worker and retries)")
        if "error" in box:
            raise box["error"]
        return box["value"]

    @property
    def stuck(self) -> bool:
        """Some work overran its limit: the thread is stuck in it."""
        return bool(self._stuck)

    def _serve(self) -> None:
        while True:
            work, done, box = self._work.get()
            try:
                box["value"] = work()
            except BaseException as exc:  # noqa: BLE001 - handed to the waiting caller
                box["error"] = exc
            done.set()
