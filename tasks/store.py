"""The artefact store (``../shared/DESCRIPTOR.md``, "Artefact store").

Layout under the store root::

    recordings/<recording id>/        Parquet, see RECORDING.md
    descriptors/<name>/v<N>.json      versions 1, 2, ... in order; a version is never rewritten
    descriptors/<name>/index.json     [{version, id, created, recording, parameters, code_version}]
    reports/<run id>/report.html      and the plots it shows
    models/<sha256>.parquet           object model point clouds referenced by descriptors (x, y, z float32)
    tmp/                              staging area; everything is written here first, then renamed
    quarantine/                       what a repair took out of the way (never read again; inspect or delete)

Writes are atomic (temporary file or folder, then rename or link) and safe with several processes writing at
once (an ``fcntl`` lock per descriptor name, and a shared lock on ``.staging.lock`` while a folder is staged).
Nothing is ever overwritten. Each protocol is ordered so that a kill or a full disk at any step leaves a store
the next write repairs (``docs/store.md``): staged folders of dead writers are removed, a version file the
index does not list yet is adopted when it is whole and valid and quarantined otherwise, so a name is never
blocked. A write that fails is one ``StoreError`` line naming the path and the cause.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import fcntl
import hashlib
import os
import re
import shutil
import tempfile
import uuid
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq

from schemas.descriptor import Descriptor
from schemas.limits import MAX_DESCRIPTOR_BYTES
from schemas.tables import OBJECT_MODEL_SCHEMA
from tasks.atomic import DIR_MODE, FILE_MODE, checkpoint, fsync_dir, write_bytes_atomic, write_errors
from tasks.errors import DescriptorError, StoreError
from tasks.store_index import VersionEntry, adoptable, lists, read_index, write_index

__all__ = [
    "DEFAULT_STORE",
    "DIR_MODE",
    "FILE_MODE",
    "PutResult",
    "Store",
    "VersionEntry",
    "model_sha256",
    "resolve_store_root",
    "write_bytes_atomic",
]

DEFAULT_STORE = Path("data/store")
_REF_VERSION = re.compile(r"^(?P<name>[A-Za-z0-9][A-Za-z0-9._-]*)@(?P<ver>v\d+|latest)$")
_HEX_PREFIX = re.compile(r"^[0-9a-f]{8,64}$")
_VERSION_FILE = re.compile(r"^v(?P<n>[1-9][0-9]{0,8})\.json$")

STAGE_STEPS = ("stage.created", "stage.publishing", "stage.published")
"""Steps of staging a folder (ingest, report) and renaming it into place."""
MODEL_STEPS = ("model.written", "model.linked")
"""Steps of storing an object model (a staged Parquet file hard-linked under its sha256)."""
DESCRIPTOR_STEPS = (
    "descriptor.locked",
    "descriptor.version.written",
    "descriptor.version.linked",
    "descriptor.index.written",
    "descriptor.index.linked",
)
"""Steps of storing a descriptor version: the version file first, then the index that lists it."""


def resolve_store_root(arg: str | os.PathLike[str] | None) -> Path:
    """The store folder: ``--store DIR``, else ``$PBD_STORE``, else ``data/store``."""
    if arg:
        return Path(arg)
    env = os.environ.get("PBD_STORE")
    return Path(env) if env else DEFAULT_STORE


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

    @property
    def quarantine_dir(self) -> Path:
        """``quarantine/``: files a repair moved out of the way (never read by pbd)."""
        return self.root / "quarantine"

    def recording_dir(self, recording_id: str) -> Path:
        """The Parquet folder of a recording (may not exist yet)."""
        return self.recordings_dir / recording_id

    def has_recording(self, recording_id: str) -> bool:
        """True when the recording has been ingested completely."""
        return (self.recording_dir(recording_id) / "recording.json").is_file()

    # -- staging ------------------------------------------------------------------------------------
    def _sweep_tmp(self) -> None:
        """Remove everything under ``tmp/``: called only while no other process stages (exclusive lock held)."""
        for entry in self.tmp_dir.iterdir():
            if entry.is_dir() and not entry.is_symlink():
                shutil.rmtree(entry, ignore_errors=True)
            else:
                entry.unlink(missing_ok=True)

    @contextlib.contextmanager
    def staging(self, prefix: str = "stage") -> Iterator[Path]:
        """A fresh temporary folder under ``tmp/``; removed on exit unless it was published.

        While it exists this process holds a shared lock on ``.staging.lock``; a process that gets the lock
        exclusively first knows nobody is staging and removes what dead writers left in ``tmp/``. An
        ``OSError`` inside (no space, read-only) becomes a one-line ``StoreError`` and the folder is removed.
        """
        with write_errors(self.tmp_dir):
            self.tmp_dir.mkdir(parents=True, exist_ok=True)
            lock = (self.root / ".staging.lock").open("a")
        try:
            try:
                fcntl.flock(lock.fileno(), fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                fcntl.flock(lock.fileno(), fcntl.LOCK_SH)
            else:
                self._sweep_tmp()
                fcntl.flock(lock.fileno(), fcntl.LOCK_SH)
            with write_errors(self.tmp_dir):
                path = Path(tempfile.mkdtemp(dir=self.tmp_dir, prefix=f"{prefix}-"))
                path.chmod(DIR_MODE)  # mkdtemp's 0700 would make a published folder unreadable by the team
            try:
                with write_errors(path, doing=""):
                    checkpoint("stage.created", path)
                    yield path
            finally:
                shutil.rmtree(path, ignore_errors=True)
        finally:
            lock.close()

    def publish_dir(self, staged: Path, final: Path) -> bool:
        """Rename a staged folder into place; False (and nothing changed) when ``final`` already exists."""
        with write_errors(final):
            final.parent.mkdir(parents=True, exist_ok=True)
            checkpoint("stage.publishing", final)
        try:
            staged.rename(final)
        except OSError as err:
            if final.exists():
                return False
            msg = f"cannot publish {staged.name}: {err.strerror}"
            raise StoreError(final, msg) from err
        fsync_dir(final.parent)
        with write_errors(final):
            checkpoint("stage.published", final)
        return True

    # -- object models --------------------------------------------------------------------------------
    def model_path(self, sha256: str) -> Path:
        """``models/<sha256>.parquet``."""
        return self.models_dir / f"{sha256}.parquet"

    def put_model(self, points_xyz: Any) -> tuple[str, Path]:
        """Store an (n, 3) model point cloud (metres) as Parquet by its content sha256; returns (sha, path).

        The Parquet file is written in a staging folder and hard-linked into ``models/`` (a link never replaces
        a file), so a kill leaves either no model or a whole one.
        """
        pts = np.ascontiguousarray(np.asarray(points_xyz, dtype=np.float32).reshape(-1, 3))
        sha = model_sha256(pts)
        path = self.model_path(sha)
        if path.exists():
            return sha, path
        table = pa.Table.from_arrays([pa.array(pts[:, i]) for i in range(3)], schema=OBJECT_MODEL_SCHEMA)
        with self.staging("model") as staged, write_errors(path):
            tmp = staged / path.name
            pq.write_table(table, tmp)
            checkpoint("model.written", path)
            self.models_dir.mkdir(parents=True, exist_ok=True)
            with contextlib.suppress(FileExistsError):
                os.link(tmp, path)
            fsync_dir(self.models_dir)
            checkpoint("model.linked", path)
        return sha, path

    def load_model(self, sha256: str) -> Any:
        """The (n, 3) float64 model point cloud stored under ``sha256``."""
        path = self.model_path(sha256)
        if not path.is_file():
            msg = f"object model {sha256[:12]}... is not in the store"
            raise StoreError(path, msg)
        try:
            table = pq.read_table(path)
            cols = [table.column(c).to_numpy() for c in ("x", "y", "z")]
        except (OSError, KeyError, pa.ArrowException) as err:
            msg = f"unreadable object model ({type(err).__name__})"
            raise StoreError(path, msg) from err
        return np.column_stack(cols).astype(np.float64)

    # -- descriptors --------------------------------------------------------------------------------
    def descriptor_dir(self, name: str) -> Path:
        """``descriptors/<name>/``."""
        return self.descriptors_dir / name

    @contextlib.contextmanager
    def _locked(self, name: str) -> Iterator[None]:
        folder = self.descriptor_dir(name)
        with write_errors(folder):
            folder.mkdir(parents=True, exist_ok=True)
            fh = (folder / ".lock").open("a")
        with fh:
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
        return read_index(path)

    def names(self) -> list[str]:
        """Every descriptor name in the store, sorted."""
        if not self.descriptors_dir.is_dir():
            return []
        return sorted(p.name for p in self.descriptors_dir.iterdir() if (p / "index.json").is_file())

    def _quarantine(self, path: Path, why: str) -> None:
        """Move ``path`` to ``quarantine/<folder>/<name>.<why>.<unique>`` (never replacing anything)."""
        folder = self.quarantine_dir / path.parent.relative_to(self.root)
        folder.mkdir(parents=True, exist_ok=True)
        path.rename(folder / f"{path.name}.{why}.{uuid.uuid4().hex[:12]}")

    def _repaired_index(self, name: str) -> list[VersionEntry]:
        """The index of ``name`` after repair (lock held): stale temporary files removed, version files the index
        does not list adopted when whole, valid and next in line, quarantined otherwise; rewritten if changed."""
        folder = self.descriptor_dir(name)
        for tmp in folder.glob(".*.tmp"):  # a writer holding this lock would have removed its own
            tmp.unlink(missing_ok=True)
        index = folder / "index.json"
        try:
            entries = read_index(index) if index.is_file() else []
        except StoreError:
            self._quarantine(index, "corrupt")
            entries = []
        listed = {e.version for e in entries}
        orphans = sorted(
            int(m["n"]) for p in folder.iterdir() if (m := _VERSION_FILE.match(p.name)) and int(m["n"]) not in listed
        )
        adopted = list(entries)
        for number in orphans:
            path = folder / f"v{number}.json"
            entry = adoptable(path, name, number, adopted)
            if entry is None:
                self._quarantine(path, "orphan")
            else:
                adopted.append(entry)
        if len(adopted) != len(entries) or (adopted and not index.is_file()):
            write_index(index, adopted)
        return adopted

    def put_descriptor(self, desc: Descriptor) -> PutResult:
        """Store ``desc`` as the next version of its name unless the latest version has the same id.

        Under the name's lock: repair (see ``_repaired_index``), write ``v<N>.json``, then rewrite
        ``index.json`` to list it. A kill between the two leaves a whole version file that the next write
        adopts; a failed index write removes the version file again. A failed write is a ``StoreError`` naming
        the path and the cause.
        """
        text = desc.to_json()
        folder = self.descriptor_dir(desc.name)
        with self._locked(desc.name), write_errors(folder):
            checkpoint("descriptor.locked", folder)
            entries = self._repaired_index(desc.name)
            if entries and entries[-1].id == desc.id:
                last = entries[-1]
                return PutResult(desc.name, last.version, last.id, False, folder / f"v{last.version}.json")
            version = entries[-1].version + 1 if entries else 1
            path = folder / f"v{version}.json"  # absent: the repair adopted or quarantined any orphan
            entry = VersionEntry(
                version=version,
                id=desc.id,
                created=dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
                recording=desc.recording_id,
                parameters=desc.parameters,
                code_version=desc.code_version,
            )
            try:
                write_bytes_atomic(path, text.encode(), step="descriptor.version")
                write_index(folder / "index.json", [*entries, entry])
            except BaseException:  # nothing left behind: the version file is ours while the lock is held
                if not lists(folder / "index.json", version):
                    path.unlink(missing_ok=True)
                raise
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
        if path.exists():
            msg = "not a regular file (a folder, a FIFO or a device)"
            raise DescriptorError(ref, msg)
        msg = "not a file, a content id, nor name@vN / name@latest"
        raise DescriptorError(ref, msg)

    def load(self, ref: str) -> Descriptor:
        """Load and validate a descriptor given as in ``resolve`` (at most ``MAX_DESCRIPTOR_BYTES``)."""
        path = self.resolve(ref)
        try:
            with path.open("rb") as fh:
                data = fh.read(MAX_DESCRIPTOR_BYTES + 1)
        except OSError as err:
            msg = f"cannot read: {err.strerror}"
            raise DescriptorError(path, msg) from err
        return Descriptor.from_bytes(data, source=str(path))


def model_sha256(points_xyz: Any) -> str:
    """The key of an (n, 3) model point cloud in ``models/``: sha256 of its float32 x, y, z bytes."""
    pts = np.ascontiguousarray(np.asarray(points_xyz, dtype=np.float32).reshape(-1, 3))
    return hashlib.sha256(pts.tobytes()).hexdigest()
