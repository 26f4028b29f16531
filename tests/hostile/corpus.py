"""A seeded corpus of corrupt, absurd and hostile inputs for every ``pbd`` command, and the judge of an outcome.

``make_inputs`` writes the well-formed originals with the real writers (a learned-style descriptor with its
object model in a store, an MCAP and a ROS 1 bag recording, PLY / XYZ / npy models); ``make_cases`` derives
cases from them with a ``numpy`` generator: byte flips, truncations, random bytes, non-finite and absurd values
(with the content id recomputed, so the limits and not the id check meet them), huge counts, deep nesting,
wrong encodings, folders and FIFOs where files belong, and store faults (``$PBD_FAULT_STEP``: no space,
read-only, no permission at a step of a write). ``run_case`` runs one through ``flows.cli.main`` in this
process; ``judge`` says what is wrong with the outcome (None when it is right): exit 0, 1 or 2 as the command
documents, a failure as one line ``pbd COMMAND: ...`` of bounded length, never a traceback or internal error.
"""

from __future__ import annotations

import contextlib
import hashlib
import io
import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from flows.cli import main
from schemas.descriptor import canonical_json

FAULT_STEP_ENV = "PBD_FAULT_STEP"
FAULT_MODE_ENV = "PBD_FAULT_MODE"
STAGE_STEPS = ("stage.created", "stage.publishing")
DESCRIPTOR_STEPS = ("descriptor.locked", "descriptor.version.written", "descriptor.version.linked")
"""Hook and steps of ``tasks.atomic`` / ``tasks.store``, spelled here so a baseline checkout without them can run
the same corpus (the hook is then inert there: the fault cases show what happens without it)."""
MAX_ERROR_CHARS = 400
"""Longest error line accepted (``flows.cli.MAX_ERROR_CHARS``)."""

COMMANDS = ("diff", "simulate", "transfer", "ingest", "learn", "store")
"""Groups of cases; ``store`` runs writing commands on a store that fails (no space, read-only, permission)."""
CODES = {"diff": {0, 1, 2}, "simulate": {0, 2}, "transfer": {0, 2}, "ingest": {0, 2}, "learn": {0, 2}}
"""Exit codes a command may give on a hostile input (diff: 0 same, 1 different; all: 2 bad input)."""
FAULT_MODES = ("ENOSPC", "EROFS", "EACCES")


@dataclass(frozen=True)
class Inputs:
    """The well-formed originals the cases are derived from."""

    folder: Path
    store: Path
    descriptor: Path
    recordings: tuple[Path, ...]
    models: tuple[Path, ...]


@dataclass(frozen=True)
class Case:
    """One hostile run: the command line (without ``--store``), its group, a label, and environment to set."""

    group: str
    label: str
    argv: tuple[str, ...]
    env: dict[str, str] = field(default_factory=dict)
    fresh_store: bool = False
    """Run against a new empty store (so a write actually happens), not the shared one."""


@dataclass(frozen=True)
class Outcome:
    """Exit code, stderr text and wall time (s) of one case."""

    code: int
    stderr: str
    seconds: float


def make_inputs(folder: Path) -> Inputs:
    """Write the originals into ``folder`` (a few seconds: one small bottle model, two short recordings)."""
    import open3d as o3d

    from tasks.store import Store
    from tests.learn.synthetic import make_demo, write_recording
    from tests.transfer import shapes
    from tests.transfer.conftest import make_descriptor

    folder.mkdir(parents=True, exist_ok=True)
    store = Store(folder / "store")
    bottle = shapes.bottle(np.random.default_rng(7), n=600)
    sha, model_path = store.put_model(bottle.points)
    desc = make_descriptor(bottle, sha, str(model_path))
    store.put_descriptor(desc)
    descriptor = folder / "twist-cap.json"
    descriptor.write_text(desc.to_json())
    demo = make_demo("drawer", np.random.default_rng(11), hz=30.0)
    recordings = (folder / "drawer.mcap", folder / "drawer.bag")
    write_recording(demo, recordings[0], "mcap")
    write_recording(demo, recordings[1], "bag")
    cloud = o3d.geometry.PointCloud()
    cloud.points = o3d.utility.Vector3dVector(bottle.points * 1.1)
    models = (folder / "bottle-ascii.ply", folder / "bottle-binary.ply", folder / "bottle.xyz")
    o3d.io.write_point_cloud(str(models[0]), cloud, write_ascii=True)
    o3d.io.write_point_cloud(str(models[1]), cloud)
    o3d.io.write_point_cloud(str(models[2]), cloud)
    return Inputs(folder, store.root, descriptor, recordings, models)


# -- mutations of bytes -------------------------------------------------------------------------------
def flip(data: bytes, rng: np.random.Generator, span: int | None = None) -> bytes:
    """``data`` with 1 to 8 bytes XOR-ed with random values (within its first ``span`` bytes when given)."""
    out = bytearray(data)
    end = min(len(out), span or len(out))
    for at in rng.integers(0, end, size=int(rng.integers(1, 9))):
        out[at] ^= int(rng.integers(1, 256))
    return bytes(out)


def truncate(data: bytes, rng: np.random.Generator) -> bytes:
    """``data`` cut at a random length."""
    return data[: int(rng.integers(0, len(data)))]


# -- mutations of a descriptor ----------------------------------------------------------------------
ABSURD = (0.0, -1.0, 1e6, 1e308, -1e308, 1e-320, 123456.0)
NON_FINITE = ("NaN", "Infinity", "-Infinity")
ID_CHARS = 100_000
"""Documents longer than this keep their old id (only the shape limits meet them)."""


def _leaves(doc: Any, path: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Paths of the numeric leaves of a JSON document."""
    if isinstance(doc, dict):
        return [p for k, v in doc.items() for p in _leaves(v, (*path, k))]
    if isinstance(doc, list):
        return [p for i, v in enumerate(doc) for p in _leaves(v, (*path, i))]
    return [path] if isinstance(doc, int | float) and not isinstance(doc, bool) else []


def _set(doc: Any, path: tuple[Any, ...], value: Any) -> None:
    for key in path[:-1]:
        doc = doc[key]
    doc[path[-1]] = value


def with_id(doc: dict[str, Any]) -> str:
    """The document as JSON text with its ``id`` recomputed from its content (so checks past the id run)."""
    text = json.dumps(doc, indent=1)
    if len(text) > ID_CHARS:  # the limits refuse it before its id is checked
        return text
    body = {k: doc.get(k) for k in ("action", "object", "grasp", "chain")}
    with contextlib.suppress(Exception):
        doc["id"] = hashlib.sha256(canonical_json(body).encode()).hexdigest()
    return json.dumps(doc, indent=1)


def _absurd_leaf(original: str, rng: np.random.Generator) -> bytes:
    d = json.loads(original)
    leaves = _leaves(d)
    _set(d, leaves[int(rng.integers(len(leaves)))], float(rng.choice(ABSURD)))
    return with_id(d).encode()


def _non_finite_leaf(original: str, rng: np.random.Generator) -> bytes:
    d = json.loads(original)
    leaves = _leaves(d)
    _set(d, leaves[int(rng.integers(len(leaves)))], 0.0)
    return with_id(d).replace("0.0", str(rng.choice(NON_FINITE)), 1).encode()


def _edited(original: str, edit: Callable[[dict[str, Any]], None]) -> bytes:
    d = json.loads(original)
    edit(d)
    return with_id(d).encode()


def _nested(original: str, rng: np.random.Generator) -> bytes:
    depth = int(rng.choice([40, 900, 5000]))
    text = with_id(json.loads(original)).replace('"action"', '"deep": ' + "[" * depth + "]" * depth + ', "action"', 1)
    return text.encode()


def _wrong_type(original: str, rng: np.random.Generator) -> bytes:
    key = str(rng.choice(["chain", "grasp", "object", "provenance", "name"]))
    value = [None, 7, "x", [], {}][int(rng.integers(5))] if key != "name" else "../../etc/x"
    return _edited(original, lambda d: d.__setitem__(key, value))


DESCRIPTOR_KINDS: tuple[tuple[str, Callable[[str, np.random.Generator], bytes]], ...] = (
    ("flip", lambda o, rng: flip(o.encode(), rng)),
    ("truncate", lambda o, rng: truncate(o.encode(), rng)),
    ("absurd value", _absurd_leaf),
    ("non-finite", _non_finite_leaf),
    ("zero axis", lambda o, _: _edited(o, lambda d: d["chain"][0].__setitem__("dir", [0.0, 0.0, 0.0]))),
    (
        "huge extent",
        lambda o, rng: _edited(o, lambda d: d["chain"][0].__setitem__("extent", float(rng.choice([1e308, 1e6, 40.0])))),
    ),
    (
        "many primitives",
        lambda o, rng: _edited(o, lambda d: d.__setitem__("chain", d["chain"] * int(rng.choice([33, 500, 20000])))),
    ),
    (
        "long array",
        lambda o, rng: _edited(
            o, lambda d: d["grasp"].__setitem__("eigengrasps", [0.1] * int(rng.choice([3, 1000, 200000])))
        ),
    ),
    ("deep nesting", _nested),
    (
        "encoding",
        lambda o, rng: o.replace("bottle", "bouteille é").encode(
            str(rng.choice(["utf-16", "utf-32", "utf-8-sig", "latin-1"]))
        ),
    ),
    ("random bytes", lambda _, rng: rng.bytes(int(rng.integers(0, 4096)))),
    ("wrong type", _wrong_type),
)
"""Kinds of hostile descriptor, each a function of the original text and the generator."""


# -- mutations of a model file and of a recording ---------------------------------------------------
def model_variants(models: tuple[Path, ...], rng: np.random.Generator) -> list[tuple[str, str, bytes]]:
    """(label, file suffix, bytes) of one hostile model of each kind."""
    ascii_ply, binary_ply, xyz = (m.read_bytes() for m in models)
    head_end = binary_ply.index(b"end_header") + 11
    count = int(rng.choice([2_000_000_000, -5, 0, 99_999_999, 10_000_001]))
    header = binary_ply[:head_end].replace(b"element vertex 600", f"element vertex {count}".encode())
    rows = np.tile([[0.1, 0.2, 0.3]], (int(rng.integers(1, 40)), 1))
    bad_values = rows.copy()
    bad_values[0, 0] = float(rng.choice([np.nan, np.inf, 1e308]))
    npy = io.BytesIO()
    np.save(npy, np.asarray(rng.choice([None, "x", 1]), dtype=object)[None].repeat(3), allow_pickle=True)
    return [
        ("header flip", ".ply", flip(binary_ply, rng, span=head_end)),
        ("ascii flip", ".ply", flip(ascii_ply, rng)),
        ("truncate", ".ply", truncate(binary_ply, rng)),
        ("vertex count", ".ply", header + binary_ply[head_end:]),
        ("garbage", ".ply", b"ply\nformat ascii 1.0\n" + rng.bytes(int(rng.integers(1, 2000)))),
        ("random bytes", str(rng.choice([".ply", ".pcd", ".stl", ".obj", ".parquet", ".npy"])), rng.bytes(500)),
        ("coincident", ".xyz", "\n".join(" ".join(map(str, r)) for r in rows).encode()),
        ("non-finite", ".xyz", "\n".join(" ".join(map(str, r)) for r in bad_values).encode()),
        ("xyz flip", ".xyz", flip(xyz, rng)),
        ("object npy", ".npy", npy.getvalue()),
    ]


def recording_variants(recordings: tuple[Path, ...], rng: np.random.Generator) -> list[tuple[str, str, bytes]]:
    """(label, suffix, bytes) of one hostile recording of each kind (the values cases are written separately)."""
    mcap, bag = (r.read_bytes() for r in recordings)
    return [
        ("mcap flip", ".mcap", flip(mcap, rng)),
        ("mcap truncate", ".mcap", truncate(mcap, rng)),
        ("bag flip", ".bag", flip(bag, rng)),
        ("bag truncate", ".bag", truncate(bag, rng)),
        ("random bytes", str(rng.choice([".mcap", ".bag"])), rng.bytes(int(rng.integers(0, 5000)))),
        ("json as mcap", ".mcap", b'{"not": "a recording"}'),
    ]


def value_recording(folder: Path, rng: np.random.Generator, stem: str) -> tuple[str, Path]:
    """A recording written by the real writer whose marker values are non-finite, absurd or out of order."""
    from tests.learn.synthetic import make_demo, write_recording

    demo = make_demo("drawer", np.random.default_rng(int(rng.integers(1 << 30))), hz=30.0)
    kind = str(rng.choice(["1e300", "inf", "nan", "backwards", "all 1e300"]))
    name, (t, pts) = next(iter(demo.markers.items()))
    pts = pts.copy()
    t = t.copy()
    rows = rng.integers(0, len(pts), size=5)
    if kind == "backwards":
        t[rows] = t[rows[::-1]]
    elif kind == "all 1e300":
        pts[:] = 1e300
    else:
        pts[rows] = {"1e300": 1e300, "inf": np.inf, "nan": np.nan}[kind]
    demo.markers[name] = (t, pts)
    path = folder / f"{stem}.mcap"
    path.unlink(missing_ok=True)  # a re-run of the same seed writes the same case again
    write_recording(demo, path)
    return f"values {kind}", path


# -- the corpus ---------------------------------------------------------------------------------------
def _file(folder: Path, stem: str, suffix: str, data: bytes) -> str:
    path = folder / f"{stem}{suffix}"
    path.write_bytes(data)
    return str(path)


def _special(folder: Path) -> dict[str, str]:
    """Paths that are not regular files: a folder, a FIFO, a dangling symlink, a symlink loop."""
    out = {"folder": folder / "a-folder.json", "fifo": folder / "a-fifo.json", "dangling": folder / "dangling.json"}
    out["folder"].mkdir(exist_ok=True)
    if not out["fifo"].exists():
        os.mkfifo(out["fifo"])
    with contextlib.suppress(FileExistsError):
        out["dangling"].symlink_to(folder / "nowhere")
    loop = folder / "loop.json"
    with contextlib.suppress(FileExistsError):
        loop.symlink_to(loop)
    out["loop"] = loop
    return {k: str(v) for k, v in out.items()}


def make_cases(inputs: Inputs, seed: int, counts: dict[str, int]) -> list[Case]:
    """``counts[group]`` cases per group drawn from ``seed`` (files written under ``inputs.folder/seed``)."""
    folder = inputs.folder / f"seed-{seed}"
    folder.mkdir(parents=True, exist_ok=True)
    original = inputs.descriptor.read_text()
    good = str(inputs.descriptor)
    special = _special(folder)
    cases: list[Case] = []
    rng = np.random.default_rng(seed)
    makers: dict[str, Callable[[int], Case]] = {}

    def descriptor_case(group: str, i: int) -> Case:
        label, kind = DESCRIPTOR_KINDS[i % len(DESCRIPTOR_KINDS)]
        data = kind(original, rng)
        path = _file(folder, f"{group}-{i}", ".json", data)
        if group == "diff":
            pair = (path, good) if rng.random() < 0.5 else (good, path)
            return Case(group, label, ("diff", *pair))
        if group == "simulate":
            return Case(group, label, ("simulate", path))
        return Case(group, label, ("transfer", path, "--to", str(inputs.models[1])))

    def special_case(group: str, i: int) -> Case:
        label, path = sorted(special.items())[i % len(special)]
        argv = {"diff": ("diff", path, good), "simulate": ("simulate", path)}.get(
            group, ("transfer", good, "--to", path)
        )
        return Case(group, label, argv)

    def transfer_case(i: int) -> Case:
        if i % 4 == 0:
            return descriptor_case("transfer", i // 4)
        if i % 4 == 1 and i % 8 == 1:
            return special_case("transfer", i // 8)
        variants = model_variants(inputs.models, rng)
        label, suffix, data = variants[i % len(variants)]
        return Case("transfer", label, ("transfer", good, "--to", _file(folder, f"model-{i}", suffix, data)))

    def recording_case(group: str, i: int) -> Case:
        if i % 5 == 4:
            label, path = value_recording(folder, rng, f"{group}-values-{i}")
            return Case(group, label, (group, str(path)))
        variants = recording_variants(inputs.recordings, rng)
        label, suffix, data = variants[i % len(variants)]
        return Case(group, label, (group, _file(folder, f"{group}-{i}", suffix, data)))

    def store_case(i: int) -> Case:
        mode = FAULT_MODES[i % len(FAULT_MODES)]
        if i % 3 == 2:
            step = str(rng.choice([*STAGE_STEPS, *DESCRIPTOR_STEPS]))
            argv: tuple[str, ...] = ("learn", str(inputs.recordings[i % 2]))
        else:
            step = str(rng.choice(STAGE_STEPS))
            argv = ("ingest", str(inputs.recordings[i % 2]))
        env = {FAULT_STEP_ENV: step, FAULT_MODE_ENV: mode}
        return Case("store", f"{mode} at {step}", argv, env, fresh_store=True)

    makers["diff"] = lambda i: special_case("diff", i) if i % 13 == 12 else descriptor_case("diff", i)
    makers["simulate"] = lambda i: special_case("simulate", i) if i % 13 == 12 else descriptor_case("simulate", i)
    makers["transfer"] = transfer_case
    makers["ingest"] = lambda i: recording_case("ingest", i)
    makers["learn"] = lambda i: recording_case("learn", i)
    makers["store"] = store_case
    for group in COMMANDS:
        rng = np.random.default_rng([seed, COMMANDS.index(group)])  # a group's cases do not depend on the others
        cases += [makers[group](i) for i in range(counts.get(group, 0))]
    return cases


def run_case(case: Case, store: Path) -> Outcome:
    """Run ``case`` through ``flows.cli.main`` in this process against ``store``; stdout is discarded."""
    err = io.StringIO()
    saved = {k: os.environ.get(k) for k in case.env}
    os.environ.update(case.env)
    start = time.perf_counter()
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            code = main([*case.argv, "--store", str(store)])
    except SystemExit as exc:  # argparse
        code = int(exc.code or 0)
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v
    return Outcome(code, err.getvalue(), time.perf_counter() - start)


def judge(case: Case, outcome: Outcome) -> str | None:
    """What is wrong with ``outcome`` (None when right): an exit code the command does not give, a traceback, an
    internal error, an error that is not one bounded ``pbd COMMAND:`` line."""
    command = case.argv[0]
    allowed = {2} if case.group == "store" else CODES[command]
    if case.group == "store" and outcome.code == 0:
        return "a write that was made to fail succeeded"
    lines = outcome.stderr.splitlines()
    if "Traceback" in outcome.stderr or "internal error" in outcome.stderr:
        return f"traceback: {' | '.join(lines[-3:])[:300]}"
    if outcome.code not in allowed:
        return f"exit {outcome.code}: {' | '.join(lines[-2:])[:300]}"
    bad = [x for x in lines if not x.startswith(f"pbd {command}: ") or len(x) > MAX_ERROR_CHARS]
    if bad:
        return f"stderr line not 'pbd {command}: ...' of at most {MAX_ERROR_CHARS} characters: {bad[0][:200]!r}"
    if outcome.code == 2 and len(lines) != 1 and command in {"diff", "simulate", "transfer"}:
        return f"{len(lines)} stderr lines for one error"
    causes = ("No space", "Read-only", "denied")
    if case.group == "store" and outcome.code == 2 and not any(m in lines[-1] for m in causes):
        return f"store fault not named: {lines[-1][:200]!r}"
    return None
