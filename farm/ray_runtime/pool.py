"""The Ray actors of an executor and what each is running: a worker that overruns its
chunk's time limit is replaced, a lost worker is left until Ray brings it back, their
chunks go to the others, and every wait for a result wakes for a stop.

An actor runs its calls one after the other, in the order they were sent. The pool keeps
them in that order per actor (``Slot.queue``), and when the driver last saw the one at the
head start (``Slot.started``: when the one before it was seen finished). With ``depth``
set (long chunks), an actor is sent at most that many calls; the others wait in the pool,
urgent ones (replacements) first, and go to the next actor that has room: a replacement
then waits for no queued chunk (the actor is not idle for long: the driver looks for
finished calls whenever it waits or asks whether a chunk is back). A wait looks
every ``POLL_S`` at the stop flag and at the head calls: the one that has run longer than
its limit (farm/execution/chunking.py) has its actor killed (``ray.kill``; Ray restarts it from its
constructor) and every call queued there is launched again on another actor; the call
that overran is charged a try. A call whose actor died is handled the same way, the
running call charged. After ``max_retries`` tries more than the first a call stops the
campaign with a ``WorkerError`` naming its runs.

An actor that died or was killed is down until it answers a ping: Ray restarts it on a
node with room (at once, on a machine that lost a process; never, on a cluster that lost
the node and has no room left: the others carry on). Ray gives up on an actor whose node
or cluster is gone for good (``ActorDiedError``); with no actor left, or none up for
``NO_WORKER_S``, the campaign stops with a ``WorkerError``.
"""

from __future__ import annotations

import dataclasses
import threading
import time
from collections import deque
from typing import Callable

from farm.execution.waiting import POLL_S, WorkerError, stop_asked
from farm.ray_runtime import where

PING_S = 2.0  # [s] between asks whether a down actor is back
POLL_QUIET_S = 0.005  # [s] between looks for finished calls outside a wait
STARTUP_LIMIT_S = 600.0  # [s] for an actor to start (import, build its simulator) before it is replaced
NO_WORKER_S = 120.0  # [s] with every actor down before the campaign stops


def check_started(exc: Exception) -> None:
    """A Ray actor error because the actor's constructor raised (a simulator that cannot be
    built on the workers: a module missing there) is not a lost worker: raise it as one line."""
    if getattr(exc, "actor_init_failed", False):
        lines = [line.strip() for line in str(exc).splitlines() if line.strip()]
        raise WorkerError(f"a Ray worker could not build the simulator: {lines[-1] if lines else exc}") from None


@dataclasses.dataclass(eq=False)
class Call:
    """Work sent to an actor; ``launch(actor)`` (re)sends it there and sets ``ref``."""

    runs: int  # runs simulated or screened: what its time limit is reckoned from
    what: str  # names it in messages: "runs from sample index 1024 (64 runs)"
    launch: Callable[[int], None]
    ref: object = None  # the object whose readiness ends the call
    actor: int = -1
    tries: int = 0  # launches that failed (overran or lost their actor)
    timeouts: int = 0
    dropped: bool = False  # nobody waits for it any more (a cancelled chunk): not launched again
    limit: float | None = None  # [s] its own time limit (else the pool's, by its runs)
    call_s: float = 0.0  # [s] the driver's time on sending it and reading its result
    urgent: bool = False  # the commit head waits for it (replacements): the fast lane may take it


@dataclasses.dataclass
class Slot:
    """One actor, as the driver knows it."""

    handle: object
    where_key: str = ""  # the name it reports where it hangs under (farm/ray_runtime/where.py)
    lane: bool = False  # the fast lane: only urgent calls, unless no other actor is up
    queue: deque = dataclasses.field(default_factory=deque)  # Calls in the order the actor runs them
    started: float = 0.0  # when the head call started, as far as the driver knows
    synced: tuple | None = None  # the coverage (id, epoch, seq) its mirror was sent ...
    confirmed: tuple | None = None  # ... and known to have applied
    down: bool = False
    dead: bool = False  # Ray gave up on it
    ping: object = None
    pinged: float = 0.0

    runs_queued: int = 0  # the runs of the calls in ``queue``

    def push(self, call: Call) -> None:
        self.queue.append(call)
        self.runs_queued += call.runs

    def pop(self) -> Call:
        call = self.queue.popleft()
        self.runs_queued -= call.runs
        return call

    def clear(self) -> list[Call]:
        calls = list(self.queue)
        self.queue.clear()
        self.runs_queued = 0
        return calls


class ActorPool:
    def __init__(self, ray, handles: list, limit: Callable[[int], float], max_retries: int,
                 stop: threading.Event | None = None, notify: Callable[[str], None] | None = None):
        """``handles``: (actor handle, its where key) pairs; ``limit(runs)``: the seconds a call
        of ``runs`` runs may take once started."""
        self.ray = ray
        self.slots: list[Slot] = []
        self.limit = limit
        for handle, key in handles:
            self.add(handle, key)
        self.max_retries = max_retries
        self.stop = stop
        self.notify = notify
        self._all_down_since: float | None = None
        self._swept = 0.0  # when the calls queued were last looked at
        self.depth = 0  # calls an actor is sent at most (running and queued); 0: every call at once
        self._later: deque[Call] = deque()  # calls no actor had room for, in order
        self._later_urgent: deque[Call] = deque()
        self._polled = 0.0
        self.held_back = 0  # calls that waited in the pool for an actor with room (a statistic)

    def add(self, handle, where_key: str = "", lane: bool = False) -> None:
        """One more actor, ``where_key`` the name it reports under; ``lane``: kept for
        urgent calls (a fast lane)."""
        self.slots.append(Slot(handle, where_key, lane=lane))
        # its start-up is the first thing it runs: the chunks' limits count from its end
        up = Call(0, "the worker's start-up", None, handle.pid.remote(), dropped=True, limit=STARTUP_LIMIT_S)
        self.sent(up, len(self.slots) - 1)

    # -- sending -------------------------------------------------------------------------
    def pick(self, interruptible: bool = True, urgent: bool = False) -> int:
        """The up actor with the fewest runs queued (waits while every actor is down). An
        urgent call may go to a fast lane (first, on a tie), another call only where no
        worker is up: a replacement then never waits behind the chunks queued on a worker."""
        while True:
            actor = self._best(urgent)
            if actor is not None:
                return actor
            self._no_worker_left()
            self._pause(interruptible)

    def _best(self, urgent: bool, room: bool = False) -> int | None:
        """``pick``'s choice now, among the actors with room for another call if ``room``
        (``depth``); None if there is none."""
        self._revive()
        up = [i for i, s in enumerate(self.slots) if not s.down]
        if not urgent:
            up = [i for i in up if not self.slots[i].lane] or up
        if room and self.depth:
            up = [i for i in up if len(self.slots[i].queue) < self.depth]
        if not up:
            return None
        self._all_down_since = None
        return min(up, key=lambda i: (self.slots[i].runs_queued, not self.slots[i].lane))

    def sent(self, call: Call, actor: int) -> None:
        """``call`` was just sent to ``actor`` (its ``ref`` set)."""
        slot = self.slots[actor]
        if not slot.queue:
            slot.started = time.monotonic()
        call.actor = actor
        slot.push(call)

    def send(self, call: Call, interruptible: bool = True) -> None:
        """Launch ``call`` on the best actor (with ``depth``: the best with room, else when
        one has room)."""
        if not self.depth:
            call.launch(self.pick(interruptible, call.urgent))
            return
        later = self._later_urgent if call.urgent else self._later
        actor = None if later else self._best(call.urgent, room=True)
        if actor is None:
            call.ref = None  # not running anywhere: a wait for it waits until it is sent (again)
            later.append(call)
            self.held_back += 1
        else:
            call.launch(actor)

    def dispatch(self) -> None:
        """Send the waiting calls (urgent first) to the actors that have room."""
        for urgent, later in ((True, self._later_urgent), (False, self._later)):
            while later:
                if later[0].dropped:  # cancelled before it was sent: it never runs
                    later.popleft()
                    continue
                actor = self._best(urgent, room=True)
                if actor is None:
                    break
                later.popleft().launch(actor)

    def poll(self, also=None, timeout: float = 0.0) -> None:
        """Note the calls that finished (each actor's oldest) and send waiting calls where
        that made room; waits up to ``timeout`` for one of them or for ref ``also``."""
        self._polled = time.monotonic()
        heads = [s.queue[0].ref for s in self.slots if s.queue and not s.down]
        refs = heads + ([also] if also is not None and also not in set(heads) else [])
        if refs:
            ready, _ = self.ray.wait(refs, num_returns=1, timeout=timeout)
            if ready and len(refs) > 1:
                ready, _ = self.ray.wait(refs, num_returns=len(refs), timeout=0)
            done, now = set(ready), time.monotonic()
            for slot in self.slots:
                while slot.queue and slot.queue[0].ref in done:
                    slot.pop()
                    slot.started = now
        self.dispatch()

    def poll_now(self) -> None:
        """``poll`` unless it ran in the last few milliseconds (it asks Ray about every actor)."""
        if self.depth and time.monotonic() - self._polled >= POLL_QUIET_S:
            self.poll()

    def finished(self, call: Call) -> None:
        """``call``'s result was read: it and every call before it on its actor are over."""
        slot = self.slots[call.actor]
        if call in slot.queue:
            while slot.pop() is not call:
                pass
            slot.started = time.monotonic()
            if self.depth:
                self.dispatch()

    # -- waiting -------------------------------------------------------------------------
    def wait(self, call: Call, interruptible: bool = True) -> None:
        """Until ``call``'s result is ready (it may be launched again meanwhile, on another
        actor). Raises Interrupted on a stop (``interruptible``), WorkerError when it
        failed too often or no worker is left."""
        if self.depth:
            self._wait_lazily(call, interruptible)
            return
        ready, _ = self.ray.wait([call.ref], timeout=0)
        while not ready:
            if interruptible:
                stop_asked(self.stop)
            if time.monotonic() - self._swept >= POLL_S:  # a sweep asks Ray about every call queued
                self._sweep()
            self._revive()
            ready, _ = self.ray.wait([call.ref], timeout=POLL_S)

    def _wait_lazily(self, call: Call, interruptible: bool) -> None:
        """``wait`` where calls wait in the pool: every finished call makes room for the
        next, until ``call`` is sent and back."""
        while call.ref is None or not self.ray.wait([call.ref], timeout=0)[0]:
            if interruptible:
                stop_asked(self.stop)
            if time.monotonic() - self._swept >= POLL_S:
                self._sweep()
            if all(s.down for s in self.slots):
                self._revive()
                self._no_worker_left()
                self._pause(interruptible)
                continue
            self.poll(also=call.ref, timeout=POLL_S)

    def _pause(self, interruptible: bool) -> None:
        if interruptible:
            stop_asked(self.stop)
        time.sleep(POLL_S)

    def _sweep(self) -> None:
        """Note the calls that have finished; replace an actor whose running call overran."""
        self._swept = time.monotonic()
        refs = [c.ref for s in self.slots for c in s.queue]
        if not refs:
            return
        ready, _ = self.ray.wait(refs, num_returns=len(refs), timeout=0)
        done = set(ready)
        now = time.monotonic()
        for actor, slot in enumerate(self.slots):
            while slot.queue and slot.queue[0].ref in done:
                slot.pop()
                slot.started = now
            if slot.queue and not slot.down:
                head = slot.queue[0]
                limit = head.limit or self.limit(head.runs)
                if now - slot.started > limit:
                    self._overran(actor, head, now - slot.started, limit)
        if self.depth:
            self.dispatch()

    def _overran(self, actor: int, call: Call, seconds: float, limit: float) -> None:
        call.timeouts += 1
        handle = self.slots[actor].handle
        stuck = where.told(self.slots[actor].where_key) if self.slots[actor].where_key else None  # before the kill
        hung = f" (hung in {stuck})" if stuck else ""
        self._charge(call, f"did not finish within {limit:.3g} s{hung}")
        self.ray.kill(handle, no_restart=False)
        self._say(f"a Ray worker ran {call.what} for {seconds:.1f} s{hung}, over its limit of {limit:.3g} s "
                  f"(farm.chunk_timeout): it is replaced and the runs go to another worker")
        self.lost(actor, charged=call)

    # -- failures ------------------------------------------------------------------------
    def lost(self, actor: int, charged: Call | None = None, why: str = "", interruptible: bool = True) -> None:
        """``actor`` died (or was killed): it is down until it answers a ping, and the
        calls queued on it go to the others. The call it was running is charged a try
        (unless ``charged`` already was)."""
        slot = self.slots[actor]
        queue = slot.clear()
        slot.down, slot.ping, slot.pinged = True, None, time.monotonic()
        slot.synced = slot.confirmed = None  # Ray restarts it from its constructor: no mirror
        if charged is None and queue:
            self._charge(queue[0], f"lost its worker{f' ({why})' if why else ''}")
        if why:
            self._say(f"a Ray worker was lost ({why}); its chunks go to the others")
        for call in queue:
            if not call.dropped:
                self.send(call, interruptible)

    def failed(self, call: Call, why: str, interruptible: bool = True) -> None:
        """Reading ``call``'s result found its actor lost: the actor is lost (unless that
        is known), and the call is sent again. A poll may have taken the failed call off
        its actor's queue as done (a failed call is ready too); losing the actor then does
        not send it again, so it is sent here, charged a try."""
        ref, slot = call.ref, self.slots[call.actor]
        if call in slot.queue or not slot.down:
            self.lost(call.actor, why=why, interruptible=interruptible)
        if call.ref is ref and not call.dropped:
            self._charge(call, f"lost its worker ({why})")
            self.send(call, interruptible)

    def _charge(self, call: Call, what: str) -> None:
        call.tries += 1
        if not call.dropped and call.tries > self.max_retries:
            raise WorkerError(f"{call.what} {what} {call.tries} times, on a different worker each time "
                              f"(farm.max_retries = {self.max_retries}); "
                              + ("the simulator hangs there, or is far slower than on the runs before "
                                 "(set farm.chunk_timeout to allow more)" if call.timeouts == call.tries
                                 else "giving up"))

    def _revive(self) -> None:
        """Ping the down actors; one that answers is up again (with no mirror)."""
        ray = self.ray
        now = time.monotonic()
        for slot in self.slots:
            if not slot.down or slot.dead:
                continue
            if slot.ping is None:
                if now - slot.pinged >= PING_S:
                    slot.ping, slot.pinged = slot.handle.pid.remote(), now
                continue
            ready, _ = ray.wait([slot.ping], timeout=0)
            if not ready:
                continue
            try:
                ray.get(slot.ping)
                slot.down, slot.started = False, now
            except ray.exceptions.ActorUnavailableError:  # restarting, or no node with room for it
                pass
            except ray.exceptions.RayActorError as exc:  # Ray gave up on it (its cluster is gone)
                check_started(exc)
                slot.dead = True
            slot.ping = None

    def _no_worker_left(self) -> None:
        now = time.monotonic()
        if self._all_down_since is None:
            self._all_down_since = now
        n = sum(not s.lane for s in self.slots)
        if all(s.dead for s in self.slots):
            raise WorkerError(f"all {n} Ray workers are lost for good (the Ray cluster's head node, or this "
                              f"node's raylet, is gone?)")
        if now - self._all_down_since > NO_WORKER_S:
            raise WorkerError(f"none of the {n} Ray workers has been up for {NO_WORKER_S:.0f} s (lost nodes, "
                              f"or no room to restart them on the cluster)")

    def _say(self, text: str) -> None:
        if self.notify is not None:
            self.notify(text)
