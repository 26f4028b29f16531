"""A real Prefect server on loopback with a temporary PREFECT_HOME, and processes talking to it.

Every process is started in its own session and stopped by its id (SIGINT, then SIGKILL after a grace
period), never by name.
"""

from __future__ import annotations

import contextlib
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import httpx

REPO = Path(__file__).resolve().parents[2]
BIN = Path(sys.executable).parent


def free_port() -> int:
    """A free TCP port on 127.0.0.1."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


@dataclass
class LocalServer:
    """A running server: its API URL and the environment for clients of it."""

    api_url: str
    env: dict[str, str]
    process: subprocess.Popen[bytes]
    log: Path


def prefect_env(home: Path, api_url: str | None = None, extra: Mapping[str, str] | None = None) -> dict[str, str]:
    """Environment for a Prefect process: temporary home, SQLite, no analytics, no UI, fast services."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("PREFECT_")}
    env.update(
        {
            "PREFECT_HOME": str(home),
            "PREFECT_SERVER_ANALYTICS_ENABLED": "false",
            "PREFECT_UI_ENABLED": "false",
            "PREFECT_SERVER_SERVICES_SCHEDULER_LOOP_SECONDS": "2",
            "PREFECT_RUNNER_POLL_FREQUENCY": "1",
            "PREFECT_LOGGING_LEVEL": "WARNING",
        }
    )
    if api_url is not None:
        env["PREFECT_API_URL"] = api_url
    env.update(extra or {})
    return env


def start(argv: Sequence[str], env: Mapping[str, str], log: Path, cwd: Path = REPO) -> subprocess.Popen[bytes]:
    """Start a process in its own session with output to ``log``."""
    with log.open("wb") as fh:
        return subprocess.Popen(
            list(argv), env=dict(env), cwd=cwd, stdout=fh, stderr=subprocess.STDOUT, start_new_session=True
        )


def stop(process: subprocess.Popen[bytes], grace_s: float = 15.0) -> None:
    """Stop a process this test started: SIGINT to its group, SIGKILL if it is still alive after ``grace_s``."""
    if process.poll() is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        os.killpg(process.pid, signal.SIGINT)
    try:
        process.wait(timeout=grace_s)
    except subprocess.TimeoutExpired:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait(timeout=10)


def wait_healthy(api_url: str, process: subprocess.Popen[bytes], log: Path, timeout_s: float = 120.0) -> None:
    """Wait until ``GET /health`` answers; fail with the server's log if it exits or times out."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if process.poll() is not None:
            msg = f"prefect server exited ({process.returncode}):\n{log.read_text()[-3000:]}"
            raise RuntimeError(msg)
        with contextlib.suppress(httpx.HTTPError):
            if httpx.get(f"{api_url}/health", timeout=2).status_code == 200:
                return
        time.sleep(0.5)
    msg = f"prefect server not healthy after {timeout_s} s:\n{log.read_text()[-3000:]}"
    raise RuntimeError(msg)


@contextlib.contextmanager
def local_server(home: Path) -> Iterator[LocalServer]:
    """``prefect server start`` on 127.0.0.1 with SQLite under ``home``; stopped on exit."""
    port = free_port()
    api_url = f"http://127.0.0.1:{port}/api"
    env = prefect_env(home)
    log = home / "server.log"
    home.mkdir(parents=True, exist_ok=True)
    argv = [str(BIN / "prefect"), "server", "start", "--host", "127.0.0.1", "--port", str(port)]
    process = start(argv, env, log)
    try:
        wait_healthy(api_url, process, log)
        yield LocalServer(api_url, prefect_env(home, api_url), process, log)
    finally:
        stop(process)


def deployment_id(api_url: str, flow_name: str, deployment: str, timeout_s: float = 90.0) -> str:
    """Id of ``flow_name/deployment`` once it is registered (``pbd serve`` registers it on start-up)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        r = httpx.get(f"{api_url}/deployments/name/{flow_name}/{deployment}", timeout=5)
        if r.status_code == 200:
            dep_id: str = r.json()["id"]
            return dep_id
        time.sleep(0.5)
    msg = f"deployment {flow_name}/{deployment} not registered after {timeout_s} s"
    raise RuntimeError(msg)


def flow_runs(api_url: str, dep_id: str) -> list[dict[str, object]]:
    """Every flow run of a deployment (JSON objects from the REST API)."""
    body = {"flow_runs": {"deployment_id": {"any_": [dep_id]}}}
    r = httpx.post(f"{api_url}/flow_runs/filter", json=body, timeout=10)
    r.raise_for_status()
    runs: list[dict[str, object]] = r.json()
    return runs
