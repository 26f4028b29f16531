"""The artefact store (``../shared/DESCRIPTOR.md``, "Artefact store").

Layout under the store root::

    recordings/<recording id>/        Parquet, see RECORDING.md
    descriptors/<name>/v<N>.json      versions 1, 2, ... in order; a version is never rewritten
    descriptors/<name>/index.json     [{version, id, created, recording, parameters, code_version}]
    reports/<run id>/report.html      and the plots it shows
    models/<sha256>.parquet           object model point clouds referenced by descriptors (x, y, z float32)
    tmp/                              staging area; everything is written here first, then renamed

Writes are atomic (temporary file or folder, then rename) and safe with several processes writing at once
(an ``fcntl`` lock per descriptor name). Nothing is ever overwritten.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import fcntl
import hashlib
import json
import os
import re
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from schemas.descriptor import Descriptor
from schemas.tables import OBJECT_MODEL_SCHEMA
from tasks.errors import DescriptorError, StoreError

DEFAULT_STORE = Path("data/store")
_REF_VERSION = re.compile(r"^(?P<name>[A-Za-z0-9][A-Za-z0-9._-]*)@(?P<ver>v\d+|latest)$")
_HEX_PREFIX = re.compile(r"^[0-9a-f]{8,64}$")


def resolve_store_root(arg: str | os.PathLike[str] | None) -> Path:
    """The store folder: ``--store DIR``, else ``$PBD_STORE``, else ``data/store``."""
    if arg:
        return Path(arg)
    env = os.environ.get("PBD_STORE")
    return Path(env) if env else DEFAULT_STORE


def _modes() -> tuple[int, int]:
    """(file mode, folder mode) the process's umask allows (read once, at import, while one thread runs)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask, 0o777 & ~mask


FILE_MODE, DIR_MODE = _modes()
"""Permissions of the store's files and folders: what the umask allows (temporary files start as 0600 and
staging folders as 0700, which would make a shared store unreadable by the team)."""


def write_bytes_atomic(path: Path, data: bytes, *, overwrite: bool = False) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder, then rename.

    Refuses to replace an existing file unless ``overwrite`` (only indexes are rewritten).
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        os.fchmod(fd, FILE_MODE)
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        if overwrite:
            Path(tmp).replace(path)
        else:
            try:
                os.link(tmp, path)  # fails if path exists: no overwrite, even under a race
            except FileExistsError as err:
                msg = "refusing to overwrite an existing artefact"
                raise StoreError(path, msg) from err
            Path(tmp).unlink()
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            Path(tmp).unlink()
        raise


@dataclass(frozen=True)
class VersionEntry:
    """One row of ``descriptors/<name>/index.json``."""

    version: int
    id: str
    created: str
    recording: str | None
    parameters: dict[str, Any]
    code_version: str

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready row."""
        return {
            "version": self.version,
            "id": self.id,
            "created": self.created,
            "recording": self.recording,
            "parameters": self.parameters,
            "code_version": self.code_version,
        }


@dataclass(frozen=True)
class PutResult:
    """Outcome of ``Store.put_descriptor``: the version holding this content and whether it is new."""

    name: str
    version: int
    id: str
    created: bool
    path: Path


class Store:
    """A pbd artefact store rooted at a folder."""

    def __init__(self, root: str | os.PathLike[str]) -> None:
        self.root = Path(root)

    # -- folders ------------------------------------------------------------------------------------
    @property
    def recordings_dir(self) -> Path:
        """``recordings/``: one Parquet folder per recording id."""
        return self.root / "recordings"

    @property
    def descriptors_dir(self) -> Path:
        """``descriptors/``: one folder of versions per descriptor name."""
        return self.root / "descriptors"

    @property
    def reports_dir(self) -> Path:
        """``reports/``: one folder per run id."""
        return self.root / "reports"

    @property
    def models_dir(self) -> Path:
        """``models/``: object model point clouds by sha256."""
        return self.root / "models"

    @property
    def tmp_dir(self) -> Path:
        """``tmp/``: staging for atomic renames (same file system as the artefacts)."""
        return self.root / "tmp"

    def recording_dir(self, recording_id: str) -> Path:
        """The Parquet folder of a recording (may not exist yet)."""
        return self.recordings_dir / recording_id

    def has_recording(self, recording_id: str) -> bool:
        """True when the recording has been ingested completely."""
        return (self.recording_dir(recording_id) / "recording.json").is_file()

    @contextlib.contextmanager
    def staging(self, prefix: str = "stage") -> Iterator[Path]:
        """A fresh temporary folder under ``tmp/``; removed on exit unless it was published."""
        self.tmp_dir.mkdir(parents=True, exist_ok=True)
        path = Path(tempfile.mkdtemp(dir=self.tmp_dir, prefix=f"{prefix}-"))
        path.chmod(DIR_MODE)
        try:
            yield path
        finally:
            shutil.rmtree(path, ignore_errors=True)

    def publish_dir(self, staged: Path, final: Path) -> bool:
        """Rename a staged folder into place; False (and nothing changed) when ``final`` already exists."""
        final.parent.mkdir(parents=True, exist_ok=True)
        try:
            staged.rename(final)
        except OSError as err:
            if final.exists():
                return False
            msg = f"cannot publish {staged.name}: {err.strerror}"
            raise StoreError(final, msg) from err
        return True

    # -- object models --------------------------------------------------------------------------------
    def put_model(self, points_xyz: Any) -> tuple[str, Path]:
        """Store an (n, 3) model point cloud (metres) as Parquet by its content sha256; returns (sha, path)."""

        pts = np.ascontiguousarray(np.asarray(points_xyz, dtype=np.float32).reshape(-1, 3))
        sha = hashlib.sha256(pts.tobytes()).hexdigest()
        path = self.models_dir / f"{sha}.parquet"
        if path.exists():
            return sha, path
        table = pa.Table.from_arrays([pa.array(pts[:, i]) for i in range(3)], schema=OBJECT_MODEL_SCHEMA)
        self.models_dir.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=self.models_dir, prefix=".model.", suffix=".tmp")
        os.fchmod(fd, FILE_MODE)
        os.close(fd)
        try:
            pq.write_table(table, tmp)
            with contextlib.suppress(FileExistsError):
                os.link(tmp, path)
        finally:
            Path(tmp).unlink(missing_ok=True)
        return sha, path

    def load_model(self, sha256: str) -> Any:
        """The (n, 3) float64 model point cloud stored under ``sha256``."""

        path = self.models_dir / f"{sha256}.parquet"
        if not path.is_file():
            msg = f"object model {sha256[:12]}... is not in the store"
            raise StoreError(path, msg)
        table = pq.read_table(path)
        return np.column_stack([table.column(c).to_numpy() for c in ("x", "y", "z")]).astype(np.float64)

    # -- descriptors --------------------------------------------------------------------------------
    def descriptor_dir(self, name: str) -> Path:
        """``descriptors/<name>/``."""
        return self.descriptors_dir / name

    @contextlib.contextmanager
    def _locked(self, name: str) -> Iterator[None]:
        folder = self.descriptor_dir(name)
        folder.mkdir(parents=True, exist_ok=True)
        with (folder / ".lock").open("a") as fh:
            fcntl.flock(fh.fileno(), fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(fh.fileno(), fcntl.LOCK_UN)

    def versions(self, name: str) -> list[VersionEntry]:
        """The index of a descriptor name, oldest first (empty when the name is unknown)."""
        path = self.descriptor_dir(name) / "index.json"
        if not path.is_file():
            return []
        try:
            rows = json.loads(path.read_text())
        except json.JSONDecodeError as err:
            msg = f"corrupt index ({err.msg})"
            raise StoreError(path, msg) from err
        return [VersionEntry(**row) for row in rows]

    def names(self) -> list[str]:
        """Every descriptor name in the store, sorted."""
        if not self.descriptors_dir.is_dir():
            return []
        return sorted(p.name for p in self.descriptors_dir.iterdir() if (p / "index.json").is_file())

    def put_descriptor(self, desc: Descriptor) -> PutResult:
        """Store ``desc`` as the next version of its name unless the latest version has the same id."""
        text = desc.to_json()
        with self._locked(desc.name):
            entries = self.versions(desc.name)
            folder = self.descriptor_dir(desc.name)
            if entries and entries[-1].id == desc.id:
                last = entries[-1]
                return PutResult(desc.name, last.version, last.id, False, folder / f"v{last.version}.json")
            version = entries[-1].version + 1 if entries else 1
            path = folder / f"v{version}.json"
            write_bytes_atomic(path, text.encode())
            entry = VersionEntry(
                version=version,
                id=desc.id,
                created=dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
                recording=desc.recording_id,
                parameters=desc.parameters,
                code_version=desc.code_version,
            )
            rows = [e.to_dict() for e in [*entries, entry]]
            write_bytes_atomic(folder / "index.json", (json.dumps(rows, indent=2) + "\n").encode(), overwrite=True)
        return PutResult(desc.name, version, desc.id, True, path)

    def descriptor_path(self, name: str, version: int) -> Path:
        """``descriptors/<name>/v<N>.json``."""
        return self.descriptor_dir(name) / f"v{version}.json"

    def resolve(self, ref: str) -> Path:
        """Path of a descriptor given as a file path, a content id (8+ hex digits) or ``name@vN|latest``."""
        path = Path(ref)
        if path.is_file():
            return path
        match = _REF_VERSION.match(ref)
        if match:
            name, ver = match["name"], match["ver"]
            entries = self.versions(name)
            if not entries:
                msg = f"no descriptor named {name!r} in store {self.root}"
                raise DescriptorError(ref, msg)
            if ver == "latest":
                return self.descriptor_path(name, entries[-1].version)
            number = int(ver[1:])
            if not any(e.version == number for e in entries):
                msg = f"{name} has versions 1..{entries[-1].version}, not {number}"
                raise DescriptorError(ref, msg)
            return self.descriptor_path(name, number)
        if _HEX_PREFIX.match(ref):
            hits = sorted({(n, e.version) for n in self.names() for e in self.versions(n) if e.id.startswith(ref)})
            if len(hits) == 1:
                return self.descriptor_path(*hits[0])
            if len(hits) > 1:
                ids = {e.id for n in self.names() for e in self.versions(n) if e.id.startswith(ref)}
                if len(ids) == 1:  # same content stored under several names: take the first
                    return self.descriptor_path(*hits[0])
                msg = f"ambiguous id prefix: {len(ids)} descriptors match"
                raise DescriptorError(ref, msg)
            msg = f"no descriptor with id starting {ref} in store {self.root}"
            raise DescriptorError(ref, msg)
        msg = "not a file, a content id, nor name@vN / name@latest"
        raise DescriptorError(ref, msg)

    def load(self, ref: str) -> Descriptor:
        """Load and validate a descriptor given as in ``resolve``."""
        path = self.resolve(ref)
        try:
            text = path.read_text()
        except OSError as err:
            msg = f"cannot read: {err.strerror}"
            raise DescriptorError(path, msg) from err
        return Descriptor.from_json(text, source=str(path))
