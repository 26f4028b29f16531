"""Reusable pybullet DIRECT clients: a per-process pool, each client emptied by ``resetSimulation`` when it is
given back.

Connecting and disconnecting a DIRECT client costs about 12 ms of CPU (pybullet starts its plugins each time),
resetting one 0.2 ms; an execution needs two clients, so a process that runs many executions (a flow, the
benchmark) saves some 25 ms per execution. ``resetSimulation`` deletes every body and constraint and rebuilds
the dynamics world, so a reused client behaves as a fresh one (the tests compare joint traces bit for bit); the
caller sets gravity, time step and engine parameters after acquiring, as on a fresh client.

The pool is guarded by a lock: threads (Prefect's thread task runner) each get clients of their own.
"""

from __future__ import annotations

import threading

import pybullet as pb

_FREE: list[int] = []
_LOCK = threading.Lock()


def acquire() -> int:
    """An empty pybullet DIRECT client id: a pooled one (emptied on release), or a new connection."""

    with _LOCK:
        client = _FREE.pop() if _FREE else None
    return int(pb.connect(pb.DIRECT)) if client is None else client


def release(client: int) -> None:
    """Empty ``client`` (``resetSimulation``: its bodies' memory is freed now) and give it back to the pool."""

    if not pb.isConnected(physicsClientId=client):
        return
    pb.resetSimulation(physicsClientId=client)
    with _LOCK:
        if client not in _FREE:
            _FREE.append(client)
