"""Reading object models for transfer (the IO edge): files open3d reads, Parquet models, recordings.

Point clouds (PLY, PCD, XYZ, PTS) are read as they are; meshes (OBJ, STL, OFF, GLTF, or a PLY with faces)
are surface-sampled. Every failure is a ``TransferError`` naming the input.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from tasks.arrays import Points
from tasks.errors import PbdError, TransferError
from tasks.ingest.api import ingest_recording
from tasks.recording.load import load_recording
from tasks.store import Store

MESH_SAMPLES = 8192
"""Points sampled uniformly over a mesh's surface."""
MAX_MODEL_POINTS = 10_000_000
"""Points a model file may declare: 10 million (240 MB as float64) keep reading within a few hundred MB."""
MAX_MODEL_COORDINATE_M = 1000.0
"""Model coordinates beyond this (m) are corrupt values or a wrong unit, not an object: those points are dropped."""
MAX_MODEL_FILE_BYTES = 512 << 20
"""Largest model file read: 10 million points as ASCII text take about 300 MB."""
REGISTRATION_POINTS = 100_000
"""Points kept for registration (a uniform random subset of denser models): about 2 mm spacing over the surface
of a half-metre object, finer than the registration's correspondence distance, with time and memory bounded."""
CLOUD_SUFFIXES = {".pcd", ".xyz", ".xyzn", ".xyzrgb", ".pts"}
MESH_SUFFIXES = {".obj", ".stl", ".off", ".gltf", ".glb"}
RECORDING_SUFFIXES = {".mcap", ".bag"}
_RECORDING_ID = re.compile(r"^[0-9a-f]{16}$")
_PLY_SIZES = {"char": 1, "uchar": 1, "int8": 1, "uint8": 1, "short": 2, "ushort": 2, "int16": 2, "uint16": 2}
_PLY_HEADER_BYTES = 1 << 16
"""A PLY header longer than this is not a model header (real ones are a few hundred bytes)."""


def _finite(points: Points, where: str, seed: int = 0) -> Points:
    """The finite rows of ``points`` (n, 3) within ``MAX_MODEL_COORDINATE_M``; a uniform random subset of
    ``REGISTRATION_POINTS`` when denser."""
    with np.errstate(invalid="ignore"):
        usable = (np.abs(points) <= MAX_MODEL_COORDINATE_M).all(axis=1) if points.size else None
    pts = points[usable] if usable is not None else points.reshape(0, 3)
    if pts.shape[0] == 0:
        msg = f"{where}: empty point cloud (no finite points within {MAX_MODEL_COORDINATE_M:g} m)"
        raise TransferError(msg)
    if pts.shape[0] > REGISTRATION_POINTS:
        keep = np.sort(np.random.default_rng(seed).choice(pts.shape[0], REGISTRATION_POINTS, replace=False))
        pts = pts[keep]
    return pts


def _check_ply_header(path: Path, size: int) -> None:
    """A PLY's declared element counts within ``MAX_MODEL_POINTS`` and the file's size (before open3d reads)."""
    with path.open("rb") as fh:
        head = fh.read(_PLY_HEADER_BYTES)
    if not head.startswith(b"ply"):
        msg = f"{path}: not a PLY file (it does not start with 'ply')"
        raise TransferError(msg)
    end = head.find(b"end_header")
    if end < 0:
        msg = f"{path}: PLY header without end_header in its first {_PLY_HEADER_BYTES} bytes"
        raise TransferError(msg)
    body = size - end - len(b"end_header\n")
    binary = b"format binary" in head[:end]
    elements: list[tuple[str, int, int]] = []  # (name, count, bytes per element at least)
    for line in head[:end].decode("ascii", "replace").splitlines():
        words = line.split()
        if len(words) == 3 and words[0] == "element":
            try:
                count = int(words[2])
            except ValueError:
                msg = f"{path}: PLY element {words[1]!r} has count {words[2][:20]!r}, not a number"
                raise TransferError(msg) from None
            elements.append((words[1], count, 0))
        elif len(words) >= 3 and words[0] == "property" and elements:
            name, count, width = elements[-1]
            per = (1 if words[1] == "list" else _PLY_SIZES.get(words[1], 4)) if binary else 2
            elements[-1] = (name, count, width + per)
    for name, count, _ in elements:
        if count < 0 or (name == "vertex" and count > MAX_MODEL_POINTS):
            msg = f"{path}: PLY header declares {count} {name} elements (limit {MAX_MODEL_POINTS} vertices)"
            raise TransferError(msg)
    need = sum(count * max(width, 1) for _, count, width in elements)
    if need > body:
        msg = f"{path}: PLY header declares {need} bytes of elements but the file holds {max(body, 0)}"
        raise TransferError(msg)


@contextlib.contextmanager
def _c_stderr() -> Iterator[list[str]]:
    """Collect what C libraries (open3d's RPly) print on file descriptor 2 meanwhile, instead of the terminal."""
    lines: list[str] = []
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as sink:
        os.dup2(sink.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            sink.seek(0)
            lines.extend(x for x in sink.read(4096).decode("utf-8", "replace").splitlines() if x.strip())


def _with_reason(path: Path, what: str, printed: list[str]) -> TransferError:
    """``what`` about ``path``, followed by the first thing the reader printed (folded into the same line)."""
    reason = f" ({printed[0].strip()[:120]})" if printed else ""
    return TransferError(f"{path}: {what}{reason}")


def read_model_file(path: Path, *, seed: int = 0) -> Points:
    """An (n, 3) float64 cloud (metres) from a point-cloud or mesh file, or a Parquet object model.

    Checked before reading: the file's size and a PLY's declared counts (``MAX_MODEL_POINTS``); denser clouds are
    thinned to ``REGISTRATION_POINTS`` (seeded). What open3d prints while reading joins the one-line error.
    """
    if not path.exists():
        msg = f"{path}: no such model file"
        raise TransferError(msg)
    if not path.is_file():
        msg = f"{path}: not a regular file"
        raise TransferError(msg)
    try:
        size = path.stat().st_size
        if size > MAX_MODEL_FILE_BYTES:
            msg = f"{path}: {size} bytes, larger than a model file may be ({MAX_MODEL_FILE_BYTES} bytes)"
            raise TransferError(msg)
        return _read_checked(path, size, seed)
    except OSError as err:
        msg = f"{path}: cannot read ({err.strerror or type(err).__name__})"
        raise TransferError(msg) from err


def _read_checked(path: Path, size: int, seed: int) -> Points:
    """``read_model_file`` once the file is known to exist and to be of a readable size."""
    import open3d as o3d  # noqa: PLC0415 - heavy; only when a model is read

    suffix = path.suffix.lower()
    if suffix == ".parquet":
        return _finite(_read_parquet(path), str(path), seed)
    if suffix == ".npy":
        try:
            arr = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as err:
            msg = f"{path}: unreadable .npy ({err})"
            raise TransferError(msg) from err
        if arr.ndim != 2 or arr.shape[1] != 3 or arr.dtype.kind not in "fiu":
            msg = f"{path}: expected an (n, 3) array of numbers, got shape {arr.shape} of {arr.dtype}"
            raise TransferError(msg)
        return _finite(np.asarray(arr, dtype=np.float64), str(path), seed)
    if suffix not in CLOUD_SUFFIXES | MESH_SUFFIXES | {".ply"}:
        msg = f"{path}: unknown model format {suffix or '(no suffix)'} (PLY, PCD, XYZ, OBJ, STL, OFF, Parquet, npy)"
        raise TransferError(msg)
    if suffix == ".ply":
        _check_ply_header(path, size)
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    with _c_stderr() as printed:
        if suffix in MESH_SUFFIXES | {".ply"}:
            mesh = o3d.io.read_triangle_mesh(path)
            if len(mesh.triangles) > 0:
                o3d.utility.random.seed(seed)
                cloud = mesh.sample_points_uniformly(number_of_points=MESH_SAMPLES)
                return _finite(np.asarray(cloud.points, dtype=np.float64), str(path), seed)
            if suffix != ".ply" and len(mesh.vertices) > 0:
                return _finite(np.asarray(mesh.vertices, dtype=np.float64), str(path), seed)
        if suffix in MESH_SUFFIXES:
            raise _with_reason(path, "unreadable or empty mesh", printed)
        cloud = o3d.io.read_point_cloud(path)
        points = np.asarray(cloud.points, dtype=np.float64).reshape(-1, 3)
    if any(line.startswith("RPly:") for line in printed):  # RPly fills what it cannot parse with zeros
        raise _with_reason(path, "corrupt PLY", [x for x in printed if x.startswith("RPly:")])
    if not np.isfinite(points).all(axis=1).any():
        raise _with_reason(path, "empty point cloud (no finite points)", printed)
    return _finite(points, str(path), seed)


def _read_parquet(path: Path) -> Points:
    try:
        table = pq.read_table(path)
        cols = [table.column(c).to_numpy() for c in ("x", "y", "z")]
    except (OSError, KeyError, pa.ArrowException) as err:
        msg = f"{path}: not an object model Parquet with x, y, z columns ({err})"
        raise TransferError(msg) from err
    return np.column_stack(cols).astype(np.float64)


def read_recording_model(store: Store, ref: str) -> tuple[Points, str, str]:
    """The object model of a recording given as an ingested id or a recording file/folder (ingested first).

    Returns (points (n, 3) metres, recording id, object name from the recording's meta or the id).
    """

    path = Path(ref)
    if _RECORDING_ID.match(ref) and store.has_recording(ref):
        rec_id = ref
    elif path.exists():
        rec_id = ingest_recording(path, store).recording_id
    else:
        msg = f"{ref}: no such model file or recording"
        raise TransferError(msg)
    try:
        rec = load_recording(store, rec_id)
    except PbdError as err:
        msg = f"{ref}: {err}"
        raise TransferError(msg) from err
    if rec.object_model is None or len(rec.object_model) == 0:
        msg = f"{ref}: recording {rec_id} has no object model"
        raise TransferError(msg)
    name = str(rec.meta.get("object") or rec_id)
    return _finite(np.asarray(rec.object_model, dtype=np.float64), ref), rec_id, name


def is_recording_ref(store: Store, ref: str) -> bool:
    """True when ``ref`` names a recording (ingested id, .mcap/.bag file, rosbag2 folder), not a model file."""
    path = Path(ref)
    if _RECORDING_ID.match(ref) and store.has_recording(ref) and not path.is_file():
        return True
    return path.suffix.lower() in RECORDING_SUFFIXES or (path.is_dir() and (path / "metadata.yaml").is_file())


def source_model_of(store: Store, model_sha256: str | None, model_uri: str | None, source: str) -> Points:
    """The source descriptor's object model: from the store by sha256, else from its uri."""
    if model_sha256 is None:
        msg = f"{source}: descriptor has no object model to register"
        raise TransferError(msg)
    if (store.models_dir / f"{model_sha256}.parquet").is_file():
        return _finite(np.asarray(store.load_model(model_sha256), dtype=np.float64), source)
    if model_uri:
        uri = model_uri.removeprefix("file://")
        if Path(uri).is_file():
            return read_model_file(Path(uri))
    msg = f"{source}: object model {model_sha256[:12]}... is neither in the store nor at its uri {model_uri}"
    raise TransferError(msg)
