"""Progress of a running flow for the command line: the flow reports each finished recording here.

A listener is a plain callable set by the CLI in the same process (``pbd archive`` draws a rich progress bar);
flows started by a deployment have none, and reporting costs nothing.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager

Listener = Callable[[int, int, str], None]
"""Called as ``listener(done, total, label)`` after each recording; ``done == 0`` announces the total."""

_lock = threading.Lock()
_listeners: list[Listener] = []


@contextmanager
def listening(listener: Listener) -> Iterator[None]:
    """Register ``listener`` for the duration of the block."""
    with _lock:
        _listeners.append(listener)
    try:
        yield
    finally:
        with _lock:
            _listeners.remove(listener)


def notify(done: int, total: int, label: str) -> None:
    """Tell every listener that ``done`` of ``total`` recordings are finished (``label``: the last one)."""
    with _lock:
        current = list(_listeners)
    for listener in current:
        listener(done, total, label)
