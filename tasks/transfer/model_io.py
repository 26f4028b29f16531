"""Reading object models for transfer (the IO edge): files open3d reads, Parquet models, recordings.

Point clouds (PLY, PCD, XYZ, PTS) are read as they are; meshes (OBJ, STL, OFF, GLTF, or a PLY with faces)
are surface-sampled. Every failure is a ``TransferError`` naming the input.
"""

from __future__ import annotations

import re
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
CLOUD_SUFFIXES = {".pcd", ".xyz", ".xyzn", ".xyzrgb", ".pts"}
MESH_SUFFIXES = {".obj", ".stl", ".off", ".gltf", ".glb"}
RECORDING_SUFFIXES = {".mcap", ".bag"}
_RECORDING_ID = re.compile(r"^[0-9a-f]{16}$")


def _finite(points: Points, where: str) -> Points:
    pts = points[np.isfinite(points).all(axis=1)] if points.size else points.reshape(0, 3)
    if pts.shape[0] == 0:
        msg = f"{where}: empty point cloud (no finite points)"
        raise TransferError(msg)
    return pts


def read_model_file(path: Path, *, seed: int = 0) -> Points:
    """An (n, 3) float64 cloud (metres) from a point-cloud or mesh file, or a Parquet object model."""
    import open3d as o3d  # noqa: PLC0415 - heavy; only when a model is read

    if not path.exists():
        msg = f"{path}: no such model file"
        raise TransferError(msg)
    if not path.is_file():
        msg = f"{path}: not a file"
        raise TransferError(msg)
    suffix = path.suffix.lower()
    if suffix == ".parquet":
        return _finite(_read_parquet(path), str(path))
    if suffix == ".npy":
        try:
            arr = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as err:
            msg = f"{path}: unreadable .npy ({err})"
            raise TransferError(msg) from err
        if arr.ndim != 2 or arr.shape[1] != 3:
            msg = f"{path}: expected an (n, 3) array, got shape {arr.shape}"
            raise TransferError(msg)
        return _finite(np.asarray(arr, dtype=np.float64), str(path))
    if suffix not in CLOUD_SUFFIXES | MESH_SUFFIXES | {".ply"}:
        msg = f"{path}: unknown model format {suffix or '(no suffix)'} (PLY, PCD, XYZ, OBJ, STL, OFF, Parquet, npy)"
        raise TransferError(msg)
    o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)
    if suffix in MESH_SUFFIXES | {".ply"}:
        mesh = o3d.io.read_triangle_mesh(path)
        if len(mesh.triangles) > 0:
            o3d.utility.random.seed(seed)
            cloud = mesh.sample_points_uniformly(number_of_points=MESH_SAMPLES)
            return _finite(np.asarray(cloud.points, dtype=np.float64), str(path))
        if suffix != ".ply" and len(mesh.vertices) == 0:
            msg = f"{path}: unreadable or empty mesh"
            raise TransferError(msg)
        if suffix != ".ply":
            return _finite(np.asarray(mesh.vertices, dtype=np.float64), str(path))
    cloud = o3d.io.read_point_cloud(path)
    return _finite(np.asarray(cloud.points, dtype=np.float64).reshape(-1, 3), str(path))


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
