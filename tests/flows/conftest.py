"""Fixtures of the flow tests: one Prefect test harness for the session (flows run in-process against it)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

HARNESS_STARTUP_TIMEOUT_S = 180
"""The harness starts a server subprocess: 10 to 20 s here, longer when other jobs share the 2 cores."""


@pytest.fixture(scope="session")
def prefect_harness() -> Iterator[None]:
    """A temporary Prefect server and database shared by every in-process flow test of the session."""
    from prefect.testing.utilities import prefect_test_harness

    with prefect_test_harness(server_startup_timeout=HARNESS_STARTUP_TIMEOUT_S):
        yield
