"""Where a Ray worker hangs: the user call it is stuck in, told to the coordinator.

A worker that overran its chunk's time limit cannot be asked (its only thread is in the
user's code; a second concurrency group would make the actor threaded, and Ray does not
keep a threaded actor's calls in order). So the worker tells before it is asked: a daemon
thread looks at the back end's ``where()`` (a per-run simulator's reset/step/close and
sample index) every ``POLL_S`` and, once the same call has lasted a whole poll, writes it
to Ray's key-value store under the actor's id. When the pool gives up on the chunk, it
reads the key before it kills the worker (``told``). A fast simulator's calls never last
a poll: nothing is written while it runs well. A hang in C code that holds the GIL
writes nothing; the error then names the runs, as before.
"""

from __future__ import annotations

import threading
import uuid
import time

NAMESPACE = "scenario_farm.where"
POLL_S = 0.5


def new_key() -> str:
    """A fresh name for one actor's reports (the driver's own: not Ray's actor id, which
    only a private attribute of the handle gives)."""
    return uuid.uuid4().hex


def watch(backend, actor_id: str) -> threading.Thread | None:
    """Start telling where ``backend`` hangs (None if it cannot say: not a per-run back end)."""
    where = getattr(backend, "where", None)
    if where is None:
        return None
    from ray.experimental import internal_kv

    key = actor_id.encode()
    internal_kv._internal_kv_del(key, namespace=NAMESPACE)  # a restarted actor: what its last life said is stale

    def loop():
        seen, told = None, None
        while True:
            time.sleep(POLL_S)
            now = where()
            try:
                if now is not None and now == seen and now != told:
                    internal_kv._internal_kv_put(key, now.encode(), namespace=NAMESPACE)
                    told = now
                elif now is None and told is not None:  # that call ended: not where it hangs
                    internal_kv._internal_kv_del(key, namespace=NAMESPACE)
                    told = None
            except Exception:  # noqa: BLE001 - Ray going away: the worker ends with it
                return
            seen = now

    thread = threading.Thread(target=loop, name="scenario-farm-where", daemon=True)
    thread.start()
    return thread


def told(actor_id: str) -> str | None:
    """What the worker ``actor_id`` last said it hangs in (and forget it), or None."""
    from ray.experimental import internal_kv

    try:
        value = internal_kv._internal_kv_get(actor_id.encode(), namespace=NAMESPACE)
        if value is not None:
            internal_kv._internal_kv_del(actor_id.encode(), namespace=NAMESPACE)
    except Exception:  # noqa: BLE001 - the store is unreachable: the error names the runs instead
        return None
    return value.decode() if value else None
