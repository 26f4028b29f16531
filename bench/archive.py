"""Benchmark of ``pbd archive`` as whole processes against a local Prefect server (SQLite, 127.0.0.1).

Builds an archive of simulated demonstrations (``pbd synth``, the four scenes in turn, MCAP, bag and rosbag2 in
turn, one seed each, so every recording's content is its own), then times three whole ``pbd archive DIR --json``
processes on one store, report included:

1. the first run (the baseline every figure is a share of),
2. an unchanged re-run (target: under 10 % of the first at 20 recordings, under 5 % at 200: every stage a cache
   hit, no figure drawn again),
3. a re-run with a grasp planner parameter changed (``--grasp-param steps=300``): segment and fit must be cache
   hits, the grasp and what follows it re-run.

Beside them, the floor every whole process pays whatever the archive holds: a process that imports what ``pbd
archive`` imports and runs one empty flow against the same server. Each run prints wall seconds and CPU
seconds: of the ``pbd archive`` process (with its children) and of the server (the machine is shared, so CPU
time is the steadier figure). Stage executions are counted from the server's task runs (``Completed`` =
executed, ``Cached`` = hit, absent = not submitted because the run already knew its result).

The development archive uses seeds 0..N-1; the held-out archive (printed after it) seeds 1000.. and a tenth as
many recordings (at least 4). Uses ``PREFECT_API_URL`` when set; otherwise starts ``prefect server start`` on
loopback and stops it at the end. With ``--workdir`` the archives, stores, server database and measured runs are
kept there, and a later call with the same folder measures only what is missing (``--redo``: the unchanged
re-run again, on the store's last parameters), so a long first run is paid once.

    .venv/bin/python bench/archive.py              # 20 recordings (held out: 4)
    .venv/bin/python bench/archive.py --quick      # 4 recordings (held out: 4)
    .venv/bin/python bench/archive.py --count 200 --workdir /var/tmp/pbd-archive-200   # the archive-scale run
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import os
import resource
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
BIN = Path(sys.executable).parent


@contextlib.contextmanager
def local_server(home: Path) -> Iterator[tuple[str, int | None]]:
    """The API URL of a running server and its process id: ``$PREFECT_API_URL`` (no id) or a new one on
    loopback (stopped on exit)."""
    if os.environ.get("PREFECT_API_URL"):
        yield os.environ["PREFECT_API_URL"], None
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
        yield url, proc.pid
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
    simulation included. A recording already there with its truth file (written last) is kept."""
    from tasks.scenes.catalog import SCENE_NAMES
    from tasks.synth.paths import truth_path
    from tasks.synth.record import synthesize

    formats = ("mcap", "bag", "rosbag2")
    paths = []
    for i in range(count):
        fmt = formats[i % len(formats)]
        scene = SCENE_NAMES[i % len(SCENE_NAMES)]
        out = folder / (f"{scene}-{first_seed + i:04d}" + ("" if fmt == "rosbag2" else f".{fmt}"))
        if not truth_path(out).is_file():
            shutil.rmtree(out, ignore_errors=True) if out.is_dir() else out.unlink(missing_ok=True)
            synthesize(scene, first_seed + i, out, fmt)
        paths.append(out)
    return paths


def stage_counts(flow_run_id: str) -> dict[str, Counter[str]]:
    """Per stage task name: how many of its task runs in a flow run ended Completed (executed) or Cached.

    Task run states reach the server as events, a moment after the flow returns: read until the count of final
    task runs has not moved for three reads in a row.
    """
    from prefect.client.orchestration import get_client
    from prefect.client.schemas.filters import FlowRunFilter, FlowRunFilterId

    deadline = time.monotonic() + 60
    seen, steady = -1, 0
    with get_client(sync_client=True) as client:
        while True:
            runs: list[Any] = []
            while page := client.read_task_runs(
                flow_run_filter=FlowRunFilter(id=FlowRunFilterId(any_=[flow_run_id])), limit=200, offset=len(runs)
            ):
                runs += page
            final = [r for r in runs if r.state is not None and r.state.is_final()]
            steady = steady + 1 if len(final) == seen and len(final) == len(runs) else 0
            seen = len(final)
            if steady >= 3 or time.monotonic() > deadline:
                break
            time.sleep(1.0)
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


@dataclass
class Measure:
    """One whole process: wall seconds, CPU seconds of the process (with its children) and of the server."""

    wall_s: float
    cpu_s: float
    server_cpu_s: float
    status: str = ""
    stages: dict[str, dict[str, int]] = field(default_factory=dict)
    extra: list[str] = field(default_factory=list)


def children_cpu_s() -> float:
    """CPU seconds (user + system) of this process's waited-for children so far."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def server_cpu_s(pid: int | None) -> float:
    """CPU seconds so far (user + system, with its waited-for children) of the processes of the server's session
    (``pid`` leads it; 0 for a server not started here). Reads ``/proc``."""
    if pid is None:
        return 0.0
    ticks = os.sysconf("SC_CLK_TCK")
    total = 0
    for stat in Path("/proc").glob("[0-9]*/stat"):
        with contextlib.suppress(OSError):
            fields = stat.read_text().rsplit(")", 1)[1].split()
            if int(fields[3]) == pid:  # the process group (field 5 of stat; fields here start at 3)
                total += sum(int(f) for f in fields[11:15])  # utime, stime, cutime, cstime
    return total / ticks


def timed(argv: list[str], server_pid: int | None) -> tuple[Measure, str]:
    """Run ``argv`` as a whole process; its measure and stdout (a non-zero exit is an error)."""
    cpu0, srv0, t0 = children_cpu_s(), server_cpu_s(server_pid), time.perf_counter()
    out = subprocess.run(argv, capture_output=True, text=True, check=False, cwd=REPO)
    wall = time.perf_counter() - t0
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(argv[:4])} exited {out.returncode}: {out.stderr[-2000:]}")
    return Measure(wall, children_cpu_s() - cpu0, server_cpu_s(server_pid) - srv0), out.stdout


FLOOR = """
import sys
sys.argv = ["pbd", "archive", "."]
from flows.cli import set_log_levels, build_parser
set_log_levels(build_parser().parse_args(sys.argv[1:]))
from tasks.quiet_import import quiet_import
quiet_import("pybullet")
import flows.commands.archive
from prefect import flow
from flows.runtime import cli_settings

@flow(name="bench-floor", persist_result=False)
def floor() -> int:
    return 0

with cli_settings():
    floor()
"""
"""The floor: a process importing what ``pbd archive`` imports, running one empty flow on the same server."""


def timed_archive(archive: Path, store: Path, workers: int, server_pid: int | None, *extra: str) -> Measure:
    """One whole ``pbd archive`` process (report included): its measure, statuses and stage counts."""
    import json

    since = time.time()
    argv = [sys.executable, "-m", "flows.cli", "archive", str(archive), "--store", str(store), "--json"]
    argv += ["--workers", str(workers), *extra]
    measure, stdout = timed(argv, server_pid)
    counts = json.loads(stdout)["counts"]
    measure.status = f"{counts['new']}n {counts['changed']}c {counts['unchanged']}u {counts['failed']}f"
    measure.stages = {k: dict(v) for k, v in stage_counts(archive_run_id(since)).items()}
    return measure


RUNS = (("first run", ()), ("unchanged re-run", ()), ("grasp parameter changed", GRASP_CHANGE))
"""The three measured runs of a part, in order, and their extra ``pbd archive`` arguments."""


def bench_part(
    label: str,
    archive: Path,
    store: Path,
    *,
    workers: int,
    server_pid: int | None,
    done: dict[str, Any],
    redo: bool,
    runs: int = len(RUNS),
) -> list[tuple[str, Measure]]:
    """The three runs on one archive (measured unless ``done`` holds them); ``done`` is updated in place."""
    rows = []
    for what, arguments in RUNS[:runs]:
        key = f"{label}: {what}"
        extra = arguments
        if key in done and not (redo and what == "unchanged re-run"):
            rows.append((key, Measure(**done[key])))
            continue
        if redo and what == "unchanged re-run":  # on the parameters of the store's last run: nothing changes
            extra = tuple(done.get(f"{label}: last arguments", ()))
        measure = timed_archive(archive, store, workers, server_pid, *extra)
        done[key] = dataclasses.asdict(measure)
        done[f"{label}: last arguments"] = list(extra)
        rows.append((key, measure))
        save_done(done)
    return rows


def save_done(done: dict[str, Any]) -> None:
    """Write the measured runs to the work folder's ``results.json`` (when there is one)."""
    import json

    if (where := done.get("_file")) is not None:
        Path(where).write_text(json.dumps(done, indent=1) + "\n")


def load_done(workdir: Path) -> dict[str, Any]:
    """The measured runs kept in ``workdir/results.json``."""
    import json

    path = workdir / "results.json"
    done = json.loads(path.read_text()) if path.is_file() else {}
    done["_file"] = str(path)
    return done


def print_table(rows: list[tuple[str, Measure]], floor: Measure, per_part: int) -> None:
    """The runs (seconds and share of each part's first run, wall and CPU) and the headline figures."""
    print()
    head = f"{'run':<48} {'wall s':>8} {'% first':>8} {'CPU s':>8} {'% first':>8} {'server CPU s':>12}"
    print(head + "  stage runs (executed/cached)")
    print(f"{'floor: empty flow, same imports and server':<48} {floor.wall_s:8.2f} {'':>8} {floor.cpu_s:8.2f}"
          f" {'':>8} {floor.server_cpu_s:12.2f}")  # fmt: skip
    for i, (label, m) in enumerate(rows):
        first = rows[i - i % per_part][1]
        stages = ", ".join(f"{k} {c.get('Completed', 0)}/{c.get('Cached', 0)}" for k, c in sorted(m.stages.items()))
        print(
            f"{label + f' ({m.status})':<48} {m.wall_s:8.2f} {100 * m.wall_s / first.wall_s:7.1f}% "
            f"{m.cpu_s:8.2f} {100 * m.cpu_s / first.cpu_s:7.1f}% {m.server_cpu_s:12.2f}  {stages}"
        )
    print()
    print(f"{'figure':<58} {'wall':>7} {'CPU':>7} {'target':>7}")
    for part in range(0, len(rows) - 1 if per_part > 1 else 0, per_part):
        first, again = rows[part][1], rows[part + 1][1]
        name = rows[part][0].split(":")[0] + ": unchanged re-run, % of first run"
        count = int(name.split("(")[1].split(")")[0])
        target = "< 5%" if count >= 200 else "< 10%"
        print(f"{name:<58} {100 * again.wall_s / first.wall_s:6.1f}% {100 * again.cpu_s / first.cpu_s:6.1f}% "
              f"{target:>7}")  # fmt: skip


def main() -> int:
    """Run the benchmark and print the table."""
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--quick", action="store_true", help="4 recordings instead of 20")
    parser.add_argument("--count", type=int, default=None, help="number of recordings (default 20, quick 4)")
    parser.add_argument("--held-out", type=int, default=None, help="held-out recordings (default: as many, <= 20)")
    parser.add_argument("--workers", type=int, default=2, help="recordings in flight")
    parser.add_argument("--workdir", type=Path, default=None, help="keep (and reuse) archives, stores, runs here")
    parser.add_argument("--redo", action="store_true", help="with --workdir: measure the unchanged re-run again")
    parser.add_argument("--part", choices=("both", "development", "held-out"), default="both", help="which part")
    parser.add_argument("--runs", type=int, choices=(1, 2, 3), default=3, help="the first N of the three runs")
    args = parser.parse_args()
    count = args.count or (4 if args.quick else 20)
    held_out = args.held_out or min(count, 20)
    tmp = args.workdir.resolve() if args.workdir else Path(tempfile.mkdtemp(prefix="pbd-bench-archive-"))
    home = tmp / "prefect-home"
    home.mkdir(parents=True, exist_ok=True)
    done = load_done(tmp) if args.workdir else {"_file": None}
    signal.signal(signal.SIGTERM, signal.default_int_handler)  # a TERM stops the server started here too
    try:
        t0 = time.perf_counter()
        # archive folder, recordings, first seed, store folder
        parts = [("development", count, 0, "store-dev"), ("held-out", held_out, 1000, "store-held")]
        parts = [p for p in parts if args.part in ("both", p[0])]
        for folder, n, first_seed, _ in parts:
            make_archive(tmp / folder, n, first_seed)
        print(f"archives: {', '.join(f'{p[0]} {p[1]}' for p in parts)} in {time.perf_counter() - t0:.1f} s ({tmp})")
        with local_server(home) as (url, pid):
            os.environ["PREFECT_API_URL"] = url
            print(f"server: {url}", flush=True)
            floor, _ = timed([sys.executable, "-c", FLOOR], pid)
            common = {"workers": args.workers, "server_pid": pid, "done": done, "redo": args.redo, "runs": args.runs}
            rows: list[tuple[str, Measure]] = []
            for folder, n, _, store in parts:
                label = f"{folder.replace('-', ' ')} ({n})"
                rows += bench_part(label, tmp / folder, tmp / store, **common)
        print_table(rows, floor, args.runs)
    finally:
        if not args.workdir:
            shutil.rmtree(tmp, ignore_errors=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
