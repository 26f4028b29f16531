"""Hostile inputs to every command end in one bounded line and exit 2, never a traceback (the full sweep is
``bench/hostile.py``; here the cases issue 30 measured, and a small seeded sample of the corpus)."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from flows.cli import MAX_ERROR_CHARS
from tests.hostile.corpus import Case, Inputs, judge, make_cases, make_inputs, run_case, with_id

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def inputs(tmp_path_factory: pytest.TempPathFactory) -> Inputs:
    """The well-formed originals (a descriptor with its model in a store, two recordings, three models)."""
    return make_inputs(tmp_path_factory.mktemp("hostile"))


def _descriptor(inputs: Inputs, name: str, where: tuple[str | int, ...], change: Callable[[Any], Any]) -> str:
    """The original descriptor with the value at ``where`` changed by ``change``, its id recomputed."""
    doc = json.loads(inputs.descriptor.read_text())
    parent = doc
    for key in where[:-1]:
        parent = parent[key]
    parent[where[-1]] = change(parent[where[-1]])
    path = inputs.folder / f"{name}.json"
    path.write_text(with_id(doc))
    return str(path)


def _one_line(inputs: Inputs, argv: tuple[str, ...], message: str, code: int = 2) -> None:
    outcome = run_case(Case("cli", "direct", argv), inputs.store)
    assert judge(Case("cli", "direct", argv), outcome) is None, outcome.stderr
    assert outcome.code == code, outcome.stderr
    (line,) = outcome.stderr.splitlines()
    assert message in line, line


def test_descriptors_that_broke_diff_and_simulate(inputs: Inputs) -> None:
    good = str(inputs.descriptor)
    binary = inputs.folder / "binary.json"
    binary.write_bytes(bytes(range(256)))
    utf16 = inputs.folder / "utf16.json"
    utf16.write_text(inputs.descriptor.read_text(), encoding="utf-16")
    nested = inputs.folder / "nested.json"
    nested.write_text(
        inputs.descriptor.read_text().replace('"action"', '"deep": ' + "[" * 5000 + "]" * 5000 + ', "action"')
    )
    _one_line(inputs, ("diff", str(binary), good), "not UTF-8 text (byte 128 is b'\\x80')")
    _one_line(inputs, ("diff", good, str(utf16)), "not UTF-8 text (byte 0 is b'\\xff')")
    _one_line(inputs, ("diff", str(nested), good), "JSON nested too deeply to parse")
    zero = _descriptor(inputs, "zero", ("chain", 0, "dir"), lambda _: [0.0, 0.0, 0.0])
    _one_line(inputs, ("diff", zero, zero), "chain/0/dir: must be a unit vector, norm is 0")
    _one_line(inputs, ("simulate", zero), "chain/0/dir: must be a unit vector, norm is 0")
    huge = _descriptor(inputs, "huge", ("chain", 0, "extent"), lambda _: 1e308)
    _one_line(inputs, ("simulate", huge), "chain/0/extent: 1e+308 rad beyond 31.42 rad")
    far = _descriptor(inputs, "far", ("chain", 1, "extent"), lambda _: 1e6)
    _one_line(inputs, ("simulate", far), "chain/1/extent: 1e+06 m beyond 5 m")
    many = _descriptor(inputs, "many", ("chain",), lambda chain: chain * 20000)
    _one_line(inputs, ("diff", many, good), "larger than a descriptor can be (1048576 bytes)")
    chain = _descriptor(inputs, "chain", ("chain",), lambda chain: chain * 150)
    _one_line(inputs, ("simulate", chain), "chain of 300 primitives (limit 256)")
    amplitudes = _descriptor(inputs, "amplitudes", ("grasp", "eigengrasps"), lambda _: [0.1] * 100000)
    _one_line(inputs, ("diff", amplitudes, good), "grasp/eigengrasps: array of 100000 items (limit 256)")
    nan = inputs.folder / "nan.json"
    nan.write_text(inputs.descriptor.read_text().replace('"extent": 3.0', '"extent": NaN'))
    _one_line(inputs, ("diff", str(nan), good), "non-finite number NaN")


def test_models_that_broke_transfer(inputs: Inputs) -> None:
    models = sorted(p.name for p in (inputs.store / "models").iterdir())
    head = b"ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\n"
    ply = inputs.folder / "claims.ply"
    ply.write_bytes(head + b"property float x\nproperty float y\nproperty float z\nend_header\n" + bytes(64))
    argv = ("transfer", str(inputs.descriptor), "--to", str(ply))
    _one_line(inputs, argv, "declares 2000000000 vertex elements (limit 10000000 vertices)")
    garbage = inputs.folder / "garbage.ply"
    garbage.write_bytes(b"\x00\xff" * 300)
    _one_line(inputs, ("transfer", str(inputs.descriptor), "--to", str(garbage)), "not a PLY file")
    coincident = inputs.folder / "coincident.xyz"
    coincident.write_text("0.1 0.2 0.3\n" * 40)
    _one_line(inputs, ("transfer", str(inputs.descriptor), "--to", str(coincident)), "all points coincide")
    assert sorted(p.name for p in (inputs.store / "models").iterdir()) == models  # a failed transfer stores none


def test_recordings_with_absurd_marker_values(inputs: Inputs) -> None:
    import numpy as np

    from tests.learn.synthetic import make_demo, write_recording

    demo = make_demo("drawer", np.random.default_rng(4), hz=30.0)
    for name, (t, pts) in list(demo.markers.items()):
        demo.markers[name] = (t, np.full_like(pts, 1e300))
    path = inputs.folder / "absurd.mcap"
    write_recording(demo, path)
    _one_line(inputs, ("learn", str(path)), "no marker has enough finite samples to fit (marker ")


@pytest.mark.parametrize(("mode", "cause"), [("ENOSPC", "No space left on device"), ("EROFS", "Read-only file system")])
def test_a_full_or_read_only_store_is_one_line(inputs: Inputs, tmp_path: Path, mode: str, cause: str) -> None:
    env = {"PBD_FAULT_STEP": "stage.publishing", "PBD_FAULT_MODE": mode}
    case = Case("store", mode, ("ingest", str(inputs.recordings[0])), env, fresh_store=True)
    outcome = run_case(case, tmp_path / "store")
    assert judge(case, outcome) is None, outcome.stderr
    (line,) = outcome.stderr.splitlines()
    assert line.startswith(f"pbd ingest: {tmp_path / 'store' / 'recordings'}/") and line.endswith(cause), line
    assert not (tmp_path / "store" / "recordings").exists() or not any((tmp_path / "store" / "recordings").iterdir())


def test_a_seeded_sample_of_the_corpus(inputs: Inputs) -> None:
    counts = {"diff": 24, "simulate": 12, "ingest": 10, "learn": 2, "store": 3}
    cases = make_cases(inputs, 7, counts)
    failures = []
    for case in cases:
        store = inputs.store if not case.fresh_store else inputs.folder / f"fresh-{len(failures)}-{case.label}"
        failure = judge(case, run_case(case, store))
        if failure:
            failures.append(f"{case.group} {case.label}: {failure}")
    assert failures == []
    assert len(cases) == sum(counts.values())


def test_the_exit_path_of_a_real_process(inputs: Inputs, tmp_path: Path) -> None:
    """What a C library prints and what the entry point does with a fault, seen from outside the process."""
    cut = tmp_path / "cut.ply"
    cut.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                    b"property float z\nend_header\nx y z\nq r s\nt u v\n")  # fmt: skip
    argv = [sys.executable, "-m", "flows.cli", "transfer", str(inputs.descriptor), "--to", str(cut)]
    env = {"PYTHONPATH": str(REPO), "PATH": "/usr/bin:/bin"}
    out = subprocess.run([*argv, "--store", str(inputs.store)], capture_output=True, text=True, env=env, cwd=REPO,
                         timeout=120, check=False)  # fmt: skip
    assert out.returncode == 2
    (line,) = out.stderr.splitlines()
    assert "corrupt PLY (RPly: Error reading 'x' of 'vertex' number 0)" in line and len(line) <= MAX_ERROR_CHARS, line
    env |= {"PBD_FAULT_STEP": "stage.created", "PBD_FAULT_MODE": "EACCES"}
    argv = [sys.executable, "-m", "flows.cli", "ingest", str(inputs.recordings[1]), "--store", str(tmp_path / "s")]
    out = subprocess.run(argv, capture_output=True, text=True, env=env, cwd=REPO, timeout=120, check=False)
    assert out.returncode == 2
    (line,) = out.stderr.splitlines()
    assert line.startswith(f"pbd ingest: {tmp_path / 's' / 'tmp'}/ingest-") and line.endswith("Permission denied")
