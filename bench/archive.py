"""Benchmark of the reprocessing flow against a local Prefect server (SQLite, 127.0.0.1).

Builds an archive of simulated demonstrations (``pbd synth``, the four scenes), then measures in one run:

1. first run of ``reprocess-archive`` on an empty store,
2. an unchanged re-run (target: under 10% of the first; every stage a cache hit),
3. a re-run after one learning parameter changed (ingest cached, learning re-runs),
4. the same work done by calling the stage functions directly, one recording after another, against a
   cold flow run with one worker (target: orchestration overhead under 20%). The machine is shared, so
   direct and flow runs alternate, twice each on fresh stores, and the best of each pair is compared.

Stage executions are counted from the server's task runs (``Completed`` = executed, ``Cached`` = hit).
Uses ``PREFECT_API_URL`` when it is set; otherwise starts ``prefect server start`` on loopback with a temporary
PREFECT_HOME and stops it at the end.

    .venv/bin/python bench/archive.py            # 20 recordings
    .venv/bin/python bench/archive.py --quick    # 4 recordings
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


def make_archive(folder: Path, count: int) -> list[Path]:
    """``count`` simulated demonstrations (``pbd synth``): the four built-in scenes in turn, seed ``i``, MCAP, ROS 1
    bag and rosbag2 in turn; each names its scene instance, so every stage runs, simulation included."""
    from tasks.scenes.catalog import SCENE_NAMES
    from tasks.synth.record import synthesize

    formats = ("mcap", "bag", "rosbag2")
    paths = []
    for i in range(count):
        fmt = formats[i % len(formats)]
        scene = SCENE_NAMES[i % len(SCENE_NAMES)]
        name = f"{scene}-{i:02d}" + ("" if fmt == "rosbag2" else f".{fmt}")
        paths.append(synthesize(scene, i, folder / name, fmt))
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


def timed_flow(archive: Path, store: Path, params: dict[str, Any], workers: int) -> tuple[float, str, Any]:
    """Seconds of one in-process ``reprocess-archive`` run, its flow run id and its summary."""
    from flows.reprocess_archive import reprocess_archive
    from flows.runtime import cli_settings

    t0 = time.perf_counter()
    with cli_settings():
        state = reprocess_archive(
            archive=str(archive), store=str(store), params=params, workers=workers, report=False, return_state=True
        )
    elapsed = time.perf_counter() - t0
    return elapsed, str(state.state_details.flow_run_id), state.result()


CHANGED_PARAM = {"min_rotation_rad": 0.3}
"""The one learning parameter changed for the third run (default 0.25 rad)."""


def process_directly(source: Path, store_root: Path, name: str, params: dict[str, Any]) -> None:
    """The flow's stage work for one recording without Prefect: ingest, learn, store, simulate, diff."""
    import numpy as np

    from tasks.diff.core import diff_descriptors
    from tasks.errors import SceneError, SimulationError
    from tasks.ingest.api import ingest_recording
    from tasks.learn.api import learn_descriptor
    from tasks.learn.params import LearnParams
    from tasks.recording.load import load_recording
    from tasks.simulate.api import simulate_descriptor
    from tasks.simulate.instance import instance_from_meta
    from tasks.store import Store

    store = Store(store_root)
    rec_id = ingest_recording(source, store).recording_id
    rec = load_recording(store, rec_id)
    desc = learn_descriptor(rec, LearnParams(**params), name=name, rng=np.random.default_rng(0))
    if rec.object_model is not None:
        store.put_model(rec.object_model)
    put = store.put_descriptor(desc)
    scene, seed = instance_from_meta(rec.meta)  # the instance the recording names, as in the flow
    if scene is not None:
        with contextlib.suppress(SceneError, SimulationError):  # a misfit is a failed simulation, as in the flow
            simulate_descriptor(desc, scene=scene, rng=np.random.default_rng(seed) if seed is not None else None)
    if put.created and put.version > 1:
        diff_descriptors(store.load(f"{put.name}@v{put.version - 1}"), desc)


def find_first(archive: Path) -> Path:
    """The first recording of the archive."""
    from flows.discover import find_recordings

    return find_recordings(archive)[0]


def direct(archive: Path, store: Path, params: dict[str, Any]) -> float:
    """Seconds to do the flow's stage work by calling the stage functions directly, one recording at a time."""
    from flows.chain import archive_names
    from flows.discover import find_recordings

    sources = find_recordings(archive)
    names = archive_names(archive, sources)
    t0 = time.perf_counter()
    for source in sources:
        process_directly(source, store, names[source], params)
    return time.perf_counter() - t0


def main() -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="4 recordings instead of 20")
    parser.add_argument("--count", type=int, default=None, help="number of recordings (default 20, quick 4)")
    parser.add_argument("--workers", type=int, default=2, help="recordings in flight in the concurrent run")
    args = parser.parse_args()
    count = args.count or (4 if args.quick else 20)
    tmp = Path(tempfile.mkdtemp(prefix="pbd-bench-archive-"))
    home = tmp / "prefect-home"
    home.mkdir()
    try:
        archive = tmp / "archive"
        archive.mkdir()
        t0 = time.perf_counter()
        make_archive(archive, count)
        print(f"archive: {count} recordings in {time.perf_counter() - t0:.1f} s ({archive})")
        with local_server(home) as url:
            os.environ["PREFECT_API_URL"] = url
            print(f"server: {url}")
            rows = []
            store = tmp / "store"
            # warm-up: both timed paths below run with every stage module imported and initialised
            import flows.reprocess_archive  # noqa: F401

            warm = find_first(archive)
            process_directly(warm, tmp / "store-warm-up", "warm-up", {})

            # The machine is shared: flow and direct runs alternate, each twice on a cold store, best of two.
            plain_runs = [direct(archive, tmp / "store-direct-1", {})]
            first, run1, _ = timed_flow(archive, store, {}, workers=1)
            rows.append(("first run (1 worker)", first, stage_counts(run1, 5 * count)))
            plain_runs.append(direct(archive, tmp / "store-direct-2", {}))
            cold2, _, _ = timed_flow(archive, tmp / "store-cold-2", {}, workers=1)
            again, run2, _ = timed_flow(archive, store, {}, workers=args.workers)
            rows.append(("unchanged re-run", again, stage_counts(run2, 5 * count)))
            changed, run3, _ = timed_flow(archive, store, CHANGED_PARAM, workers=args.workers)
            rows.append((f"re-run with {CHANGED_PARAM}", changed, stage_counts(run3, 5 * count)))
            concurrent, run4, _ = timed_flow(archive, tmp / "store-concurrent", {}, workers=args.workers)
            rows.append((f"first run ({args.workers} workers)", concurrent, stage_counts(run4, 5 * count)))
            plain = min(plain_runs)
            flow_best = min(first, cold2)
            from prefect.logging.handlers import APILogHandler

            APILogHandler().flush()  # send the queued run logs before the server stops
        print()
        print(f"{'run':<34} {'seconds':>8} {'% of first':>10}  stage runs (executed/cached)")
        for label, secs, counts in rows:
            stages = ", ".join(f"{k} {c.get('Completed', 0)}/{c.get('Cached', 0)}" for k, c in sorted(counts.items()))
            print(f"{label:<34} {secs:8.2f} {100 * secs / first:9.1f}%  {stages}")
        print(f"{'second cold run (1 worker)':<34} {cold2:8.2f} {100 * cold2 / first:9.1f}%")
        for i, secs in enumerate(plain_runs, 1):
            print(f"{f'stage functions called directly #{i}':<34} {secs:8.2f} {100 * secs / first:9.1f}%")
        print()
        overhead = 100 * (flow_best - plain) / plain
        ratio = 100 * again / first
        print(f"{'figure':<44} {'ours':>8} {'target':>8}")
        print(f"{'unchanged re-run, % of first run':<44} {ratio:7.1f}% {'< 10%':>8}")
        print(f"{'orchestration overhead vs direct calls (best of 2)':<44} {overhead:7.1f}% {'< 20%':>8}")
        print(f"{'per recording, direct / flow, best of 2 (s)':<44} {plain / count:8.2f} {flow_best / count:8.2f}")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
