"""The Dask scheduler address a flow may run its tasks on (``pbd archive --address``, the deployments'
``address`` parameter): checked once, in one line, before any work starts."""

from __future__ import annotations

import socket
from typing import Any
from urllib.parse import urlsplit

from flows.cli_args import ParameterError

CONNECT_TIMEOUT_S = 5.0
"""Seconds to wait for the scheduler's TCP port to accept: a scheduler on the network answers in milliseconds."""


def check_address(address: str) -> tuple[str, int]:
    """``(host, port)`` of ``tcp://HOST:PORT`` when a scheduler listens there; ``ParameterError`` otherwise."""
    parts = urlsplit(address)
    try:
        port = parts.port
    except ValueError:
        port = None
    if parts.scheme not in {"tcp", "tls"} or not parts.hostname or port is None:
        msg = f"--address {address!r}: expected tcp://HOST:PORT of a Dask scheduler"
        raise ParameterError(msg)
    try:
        with socket.create_connection((parts.hostname, port), timeout=CONNECT_TIMEOUT_S):
            pass
    except OSError as err:
        msg = f"--address {address}: no Dask scheduler answers there ({err.strerror or err})"
        raise ParameterError(msg) from err
    return parts.hostname, port


def dask_runner(address: str) -> Any:
    """prefect-dask's ``DaskTaskRunner`` on the scheduler at ``address``."""
    from prefect_dask.task_runners import DaskTaskRunner  # noqa: PLC0415 - dask.distributed only with an address

    return DaskTaskRunner(address=address)
