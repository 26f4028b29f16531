"""Prefect settings for flows run in-process by the command line (``pbd demo``, ``pbd archive``).

Without ``PREFECT_API_URL`` Prefect starts an ephemeral server per process: 10 to 20 s on this machine, so
the start-up timeout is raised from Prefect's 20 s. The per-run heartbeat thread costs about 1 s at the end
of every synchronous flow run; CLI runs are watched by the person who started them, so it is switched off.
The ephemeral server's telemetry is off too (offline it only logs failures).
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

from prefect.settings import temporary_settings

EPHEMERAL_STARTUP_TIMEOUT_S = 180
"""Seconds to wait for the ephemeral server (measured 10 to 20 s here; slower under load on 2 cores)."""


@contextmanager
def cli_settings() -> Iterator[None]:
    """Prefect settings for an in-process CLI run: longer ephemeral start-up, no per-run heartbeat."""

    updates = {
        "server.ephemeral.startup_timeout_seconds": EPHEMERAL_STARTUP_TIMEOUT_S,
        "flows.heartbeat_frequency": None,
        "server.analytics_enabled": False,
    }
    with temporary_settings(updates=updates):
        yield
