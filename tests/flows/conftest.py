"""Fixtures of the flow tests: one Prefect test harness for the session (flows run in-process against it)."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest

HARNESS_STARTUP_TIMEOUT_S = 180
"""The harness starts a server subprocess: 10 to 20 s here, longer when other jobs share the 2 cores."""


@pytest.fixture(scope="session")
def prefect_harness() -> Iterator[None]:
    """A temporary Prefect server and database shared by every in-process flow test of the session.

    Its telemetry is off: offline, it only logs failures and contends for the SQLite file.
    """
    from prefect.testing.utilities import prefect_test_harness

    saved = os.environ.get("PREFECT_SERVER_ANALYTICS_ENABLED")
    os.environ["PREFECT_SERVER_ANALYTICS_ENABLED"] = "false"
    try:
        with prefect_test_harness(server_startup_timeout=HARNESS_STARTUP_TIMEOUT_S):
            yield
    finally:
        if saved is None:
            os.environ.pop("PREFECT_SERVER_ANALYTICS_ENABLED", None)
        else:
            os.environ["PREFECT_SERVER_ANALYTICS_ENABLED"] = saved
