"""The hostile-input sweep: every ``pbd`` command fed a seeded corpus of corrupt, absurd and hostile inputs.

Cases come from ``tests/hostile/corpus.py`` (byte flips, truncations, random bytes, NaN and infinite values,
absurd extents and axes, huge counts, deep nesting, wrong encodings, folders and FIFOs, store faults: no space,
read-only, no permission). A case passes when the command exits as it documents (0, 1 for a diff that differs,
2 for bad input) with every stderr line ``pbd COMMAND: ...`` of bounded length: no traceback, no internal error;
within ``--timeout`` seconds and without the worker's peak RSS passing ``--max-rss-mb``.

Each group runs in a worker process (``flows.cli.main`` in-process, case after case); a worker that hangs is
killed and the case counted as a hang. ``--baseline DIR`` runs the same cases with the code of another checkout
(e.g. the main branch) beside ours. Development part: seed 1; held-out part: seed 1001. Usage::

    .venv/bin/python bench/hostile.py                 # 520 + 260 cases
    .venv/bin/python bench/hostile.py --quick         # 60 + 30 cases
    .venv/bin/python bench/hostile.py --baseline ../main
Exits 1 when any case of ours fails.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import resource
import selectors
import signal
import subprocess
import sys
import tempfile
from pathlib import Path
from types import ModuleType
from typing import Any

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))  # the corpus writes its originals with the tests' own writers
CORPUS_FILE = REPO / "tests" / "hostile" / "corpus.py"
DEVELOPMENT_SEEDS = (1,)
HELD_OUT_SEEDS = (1001,)
FULL_COUNTS = {"diff": 160, "simulate": 80, "transfer": 70, "ingest": 110, "learn": 40, "store": 60}
"""Cases per group in the development part (520); the held-out part runs half as many."""
QUICK_COUNTS = {"diff": 16, "simulate": 10, "transfer": 8, "ingest": 12, "learn": 6, "store": 8}


def _corpus() -> ModuleType:
    """``tests/hostile/corpus.py`` loaded by path, so a baseline checkout's ``tasks`` can run our cases."""
    spec = importlib.util.spec_from_file_location("hostile_corpus", CORPUS_FILE)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["hostile_corpus"] = module
    spec.loader.exec_module(module)
    return module


class _Hang(BaseException):
    """Raised by the alarm in a worker: the case ran past the timeout (not an ``Exception``, so no handler eats it)."""


def _alarm(signum: int, frame: Any) -> None:
    del signum, frame
    raise _Hang


def worker(inputs_json: str, group: str, seed: int, *, count: int, start: int, timeout: float) -> None:
    """Run cases ``start..count`` of ``group``; one JSON line per case on stdout."""
    corpus = _corpus()
    raw = json.loads(inputs_json)
    inputs = corpus.Inputs(
        Path(raw["folder"]),
        Path(raw["store"]),
        Path(raw["descriptor"]),
        tuple(Path(p) for p in raw["recordings"]),
        tuple(Path(p) for p in raw["models"]),
    )
    cases = corpus.make_cases(inputs, seed, {group: count})
    signal.signal(signal.SIGALRM, _alarm)
    out = sys.__stdout__
    assert out is not None
    for index in range(start, len(cases)):
        case = cases[index]
        store = inputs.store
        if case.fresh_store:
            store = Path(tempfile.mkdtemp(dir=inputs.folder, prefix="fresh-")) / "store"
        signal.alarm(int(timeout))
        try:
            outcome = corpus.run_case(case, store)
            failure = corpus.judge(case, outcome)
            seconds = outcome.seconds
        except _Hang:
            failure, seconds = f"hang: over {timeout:.0f} s", timeout
        finally:
            signal.alarm(0)
        rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
        row = {"index": index, "label": case.label, "argv": list(case.argv), "failure": failure}
        row |= {"seconds": seconds, "rss_mb": rss_mb}
        out.write(json.dumps(row) + "\n")
        out.flush()


def run_group(
    inputs_json: str, group: str, seed: int, count: int, *, timeout: float, pythonpath: Path
) -> list[dict[str, Any]]:
    """All cases of one group in worker processes (restarted after a hang); their result rows."""
    rows: list[dict[str, Any]] = []
    start = 0
    env = {**os.environ, "PYTHONPATH": str(pythonpath)}
    env.pop("PBD_DEBUG", None)
    while start < count:
        argv = [sys.executable, __file__, "--worker", group, "--seed", str(seed), "--count", str(count)]
        argv += ["--start", str(start), "--timeout", str(timeout), "--inputs", inputs_json]
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env, cwd=pythonpath)
        assert proc.stdout is not None
        sel = selectors.DefaultSelector()
        sel.register(proc.stdout, selectors.EVENT_READ)
        while True:
            if not sel.select(timeout + 30):  # the alarm could not interrupt it (a C loop): kill the worker
                proc.kill()
                rows.append({"index": start, "label": "?", "failure": f"hang: over {timeout:.0f} s (killed)"})
                rows[-1] |= {"seconds": timeout, "rss_mb": 0.0, "argv": []}
                start += 1
                break
            line = proc.stdout.readline()
            if not line:
                proc.wait()
                if start < count:  # the worker died without a row: the case killed it
                    rows.append({"index": start, "label": "?", "argv": [], "seconds": 0.0, "rss_mb": 0.0})
                    rows[-1]["failure"] = f"worker died (exit {proc.returncode})"
                    start += 1
                break
            row = json.loads(line)
            rows.append(row)
            start = row["index"] + 1
        proc.stdout.close()
    return rows


def _summarise(rows: list[dict[str, Any]], max_rss_mb: float) -> tuple[int, float, float]:
    """(failures, slowest case s, peak RSS MB); an RSS over the limit fails the case that first passed it."""
    for row in rows:
        if row["failure"] is None and row["rss_mb"] > max_rss_mb:
            row["failure"] = f"peak RSS {row['rss_mb']:.0f} MB over {max_rss_mb:.0f} MB"
            break
    failures = sum(r["failure"] is not None for r in rows)
    return failures, max((r["seconds"] for r in rows), default=0.0), max((r["rss_mb"] for r in rows), default=0.0)


def main() -> int:
    """Run both parts (ours, and the baseline when given) and print a table per part; 1 on any failure of ours."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="a tenth of the cases")
    parser.add_argument("--timeout", type=float, default=60.0, help="seconds a case may take")
    parser.add_argument("--max-rss-mb", type=float, default=1024.0, help="peak resident memory a worker may reach")
    parser.add_argument("--baseline", type=Path, default=None, help="another checkout to run the same cases with")
    parser.add_argument("--groups", nargs="*", default=None, help="only these groups")
    parser.add_argument("--worker", default=None, help=argparse.SUPPRESS)
    parser.add_argument("--seed", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--count", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--start", type=int, default=0, help=argparse.SUPPRESS)
    parser.add_argument("--inputs", default="", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.worker:
        worker(args.inputs, args.worker, args.seed, count=args.count, start=args.start, timeout=args.timeout)
        return 0
    corpus = _corpus()
    counts = QUICK_COUNTS if args.quick else FULL_COUNTS
    groups = args.groups or list(corpus.COMMANDS)
    code = 0
    with tempfile.TemporaryDirectory(prefix="pbd-hostile-") as tmp:
        inputs = corpus.make_inputs(Path(tmp))
        inputs_json = json.dumps(
            {
                "folder": str(inputs.folder),
                "store": str(inputs.store),
                "descriptor": str(inputs.descriptor),
                "recordings": [str(p) for p in inputs.recordings],
                "models": [str(p) for p in inputs.models],
            }
        )
        runs = [("ours", REPO)] + ([("baseline", args.baseline.resolve())] if args.baseline else [])
        for part, seeds, scale in (("development", DEVELOPMENT_SEEDS, 1.0), ("held-out", HELD_OUT_SEEDS, 0.5)):
            print(f"\n{part} part (seeds {', '.join(map(str, seeds))})")
            print(
                f"{'command':<10} {'cases':>5}  "
                + "  ".join(f"{n + ' failed':>16} {'max s':>6} {'RSS MB':>6}" for n, _ in runs)
            )
            listed: list[str] = []
            total = dict.fromkeys((n for n, _ in runs), 0)
            n_cases = 0
            for group in groups:
                count = max(1, round(counts[group] * scale))
                cells = []
                for name, checkout in runs:
                    rows: list[dict[str, Any]] = []
                    for seed in seeds:
                        rows += run_group(inputs_json, group, seed, count, timeout=args.timeout, pythonpath=checkout)
                    failures, slowest, rss = _summarise(rows, args.max_rss_mb)
                    total[name] += failures
                    cells.append(f"{failures:>16} {slowest:>6.1f} {rss:>6.0f}")
                    if name == "ours":
                        listed += [
                            f"  {group} #{r['index']} {r['label']}: {r['failure']}  argv {r['argv']}"
                            for r in rows
                            if r["failure"]
                        ]
                n_cases += count * len(seeds)
                print(f"{group:<10} {count * len(seeds):>5}  " + "  ".join(cells), flush=True)
            print(f"{'all':<10} {n_cases:>5}  " + "  ".join(f"{total[n]:>16} {'':>6} {'':>6}" for n, _ in runs))
            for line in listed:
                print(line)
            code = code or int(total["ours"] > 0)
    return code


if __name__ == "__main__":
    sys.exit(main())
