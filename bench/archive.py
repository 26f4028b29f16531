"""Benchmark of ``pbd archive`` as whole processes against a local Prefect server (SQLite, 127.0.0.1).

Builds an archive of simulated demonstrations (``pbd synth``, the four scenes in turn, MCAP, bag and rosbag2 in
turn), then times three whole ``pbd archive DIR --json`` processes on one store, report included:

1. the first run (the baseline every figure is a share of),
2. an unchanged re-run (target: under 10 % of the first at 20 recordings, under 5 % at 200: every stage a cache
   hit, no figure drawn again),
3. a re-run with a grasp planner parameter changed (``--grasp-param steps=300``): segment and fit must be cache
   hits, the grasp and what follows it re-run.

Stage executions are counted from the server's task runs (``Completed`` = executed, ``Cached`` = hit). The
development archive uses seeds 0..N-1; the held-out archive (printed after it) seeds 1000.. and a quarter as many
recordings (at least 4). Uses ``PREFECT_API_URL`` when set; otherwise starts ``prefect server start`` on
loopback with a temporary PREFECT_HOME and stops it at the end.

    .venv/bin/python bench/archive.py              # 20 recordings (held out: 5)
    .venv/bin/python bench/archive.py --quick      # 4 recordings (held out: 4)
    .venv/bin/python bench/archive.py --count 200  # the archive-scale run (long)
"""

from __future__ import annotations

import argparse
import contextlib
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
BIN = Path(sys.executable).parent


@contextlib.contextmanager
def local_server(home: Path) -> Iterator[str]:
    """The API URL of a running server: ``$PREFECT_API_URL`` or a new one on loopback (stopped on exit)."""
    if os.environ.get("PREFECT_API_URL"):
        yield os.environ["PREFECT_API_URL"]
        return
    import httpx

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    env = {k: v for k, v in os.environ.items() if not k.startswith("PREFECT_")}
    env |= {"PREFECT_HOME": str(home), "PREFECT_SERVER_ANALYTICS_ENABLED": "false", "PREFECT_UI_ENABLED": "false"}
    log = (home / "server.log").open("wb")
    argv = [str(BIN / "prefect"), "server", "start", "--host", "127.0.0.1", "--port", str(port)]
    proc = subprocess.Popen(argv, env=env, stdout=log, stderr=subprocess.STDOUT, start_new_session=True)
    url = f"http://127.0.0.1:{port}/api"
    try:
        deadline = time.monotonic() + 180
        while time.monotonic() < deadline:
            with contextlib.suppress(httpx.HTTPError):
                if httpx.get(f"{url}/health", timeout=2).status_code == 200:
                    break
            if proc.poll() is not None:
                raise RuntimeError("prefect server exited; see " + str(home / "server.log"))
            time.sleep(0.5)
        yield url
    finally:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        log.close()


def make_archive(folder: Path, count: int, first_seed: int = 0) -> list[Path]:
    """``count`` simulated demonstrations (``pbd synth``): the four built-in scenes in turn, seeds from
    ``first_seed``, MCAP, ROS 1 bag and rosbag2 in turn; each names its scene instance, so every stage runs,
    simulation included."""
    from tasks.scenes.catalog import SCENE_NAMES
    from tasks.synth.record import synthesize

    formats = ("mcap", "bag", "rosbag2")
    paths = []
    for i in range(count):
        fmt = formats[i % len(formats)]
        scene = SCENE_NAMES[i % len(SCENE_NAMES)]
        name = f"{scene}-{first_seed + i:04d}" + ("" if fmt == "rosbag2" else f".{fmt}")
        paths.append(synthesize(scene, first_seed + i, folder / name, fmt))
    return paths


def stage_counts(flow_run_id: str, expected: int) -> dict[str, Counter[str]]:
    """Per stage task name: how many of its task runs in a flow run ended Completed (executed) or Cached.

    Task run states reach the server as events, a moment after the flow returns: wait for ``expected`` runs.
    """
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import FlowRunFilter, FlowRunFilterId

    deadline = time.monotonic() + 30
    with get_client(sync_client=True) as client:
        while True:
            runs = client.read_task_runs(
                flow_run_filter=FlowRunFilter(id=FlowRunFilterId(any_=[flow_run_id])), limit=200
            )
            final = [r for r in runs if r.state is not None and r.state.is_final()]
            if len(final) >= expected or time.monotonic() > deadline:
                break
            time.sleep(0.5)
    out: dict[str, Counter[str]] = {}
    for run in final:
        stage = run.name.rsplit("-", 1)[0]
        state = run.state.name if run.state else "?"
        out.setdefault(stage, Counter())[state] += 1
    return out


GRASP_CHANGE = ("--grasp-param", "steps=300")
"""The grasp planner parameter changed for the third run (default 400 annealing steps)."""


def archive_run_id(since: float) -> str:
    """Id of the ``reprocess-archive-run`` flow run started after ``since`` (epoch seconds)."""
    from datetime import UTC, datetime

    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import FlowFilter, FlowFilterName, FlowRunFilter, FlowRunFilterStartTime

    after = datetime.fromtimestamp(since, tz=UTC)
    with get_client(sync_client=True) as client:
        runs = client.read_flow_runs(
            flow_filter=FlowFilter(name=FlowFilterName(any_=["reprocess-archive-run"])),
            flow_run_filter=FlowRunFilter(start_time=FlowRunFilterStartTime(after_=after)),
        )
    return str(runs[0].id)


def timed_archive(archive: Path, store: Path, workers: int, *extra: str) -> tuple[float, dict[str, Any], str]:
    """Seconds of one whole ``pbd archive`` process (report included), its summary and its flow run id."""
    import json

    since = time.time()
    argv = [sys.executable, "-m", "flows.cli", "archive", str(archive), "--store", str(store), "--json"]
    argv += ["--workers", str(workers), *extra]
    t0 = time.perf_counter()
    out = subprocess.run(argv, capture_output=True, text=True, check=False, cwd=REPO)
    elapsed = time.perf_counter() - t0
    if out.returncode != 0:
        raise RuntimeError(f"pbd archive exited {out.returncode}: {out.stderr[-2000:]}")
    return elapsed, json.loads(out.stdout), archive_run_id(since)


def bench_archive(label: str, archive: Path, store: Path, count: int, workers: int) -> list[tuple[str, float, Any]]:
    """The three runs on one archive: (label, seconds, stage counts) each."""
    rows = []
    for what, extra in (("first run", ()), ("unchanged re-run", ()), ("grasp parameter changed", GRASP_CHANGE)):
        secs, summary, run_id = timed_archive(archive, store, workers, *extra)
        counts = summary["counts"]
        status = f"{counts['new']}n {counts['changed']}c {counts['unchanged']}u {counts['failed']}f"
        rows.append((f"{label}: {what} ({status})", secs, stage_counts(run_id, 8 * count)))
    return rows


def main() -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="4 recordings instead of 20")
    parser.add_argument("--count", type=int, default=None, help="number of recordings (default 20, quick 4)")
    parser.add_argument("--workers", type=int, default=2, help="recordings in flight")
    args = parser.parse_args()
    count = args.count or (4 if args.quick else 20)
    held_out = max(4, count // 4)
    tmp = Path(tempfile.mkdtemp(prefix="pbd-bench-archive-"))
    home = tmp / "prefect-home"
    home.mkdir()
    try:
        t0 = time.perf_counter()
        make_archive(tmp / "development", count, first_seed=0)
        make_archive(tmp / "held-out", held_out, first_seed=1000)
        print(f"archives: {count} + {held_out} recordings in {time.perf_counter() - t0:.1f} s ({tmp})")
        with local_server(home) as url:
            os.environ["PREFECT_API_URL"] = url
            print(f"server: {url}")
            rows = bench_archive(f"development ({count})", tmp / "development", tmp / "store-dev", count, args.workers)
            rows += bench_archive(
                f"held out ({held_out})", tmp / "held-out", tmp / "store-held", held_out, args.workers
            )
        print()
        print(f"{'run':<58} {'seconds':>8} {'% of first':>10}  stage runs (executed/cached)")
        for i, (label, secs, counts) in enumerate(rows):
            first = rows[i - i % 3][1]
            stages = ", ".join(f"{k} {c.get('Completed', 0)}/{c.get('Cached', 0)}" for k, c in sorted(counts.items()))
            print(f"{label:<58} {secs:8.2f} {100 * secs / first:9.1f}%  {stages}")
        target = "< 5%" if count >= 200 else "< 10%"
        print()
        print(f"{'figure':<58} {'ours':>8} {'target':>8}")
        for part in (0, 3):
            ratio = 100 * rows[part + 1][1] / rows[part][1]
            print(f"{rows[part][0].split(':')[0] + ': unchanged re-run, % of first run':<58} {ratio:7.1f}% {target:>8}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
