"""One exception family for pbd (root ``PbdError`` in ``schemas.errors``). The CLI turns a ``PbdError`` into one
line on stderr and exit 2."""

from __future__ import annotations

from pathlib import Path

from schemas.errors import DescriptorError, PbdError

__all__ = [
    "DescriptorError",
    "FitError",
    "GraspError",
    "PbdError",
    "RecordingError",
    "SceneError",
    "SimulationError",
    "StoreError",
    "TopicMapError",
    "TransferError",
    "TruncatedRecordingError",
]


class RecordingError(PbdError):
    """A recording cannot be read: names the file, the topic (if any) and what was wrong."""

    def __init__(self, path: str | Path, what: str, topic: str | None = None) -> None:
        self.path = str(path)
        self.topic = topic
        self.what = one_line(what)
        where = f"{self.path}" + (f" topic {one_line(topic, NAME_CHARS)}" if topic else "")
        super().__init__(f"{where}: {self.what}")


class TruncatedRecordingError(RecordingError):
    """The recording ends early; ``offset`` is the byte where the damage starts."""

    def __init__(self, path: str | Path, offset: int, what: str = "", topic: str | None = None) -> None:
        self.offset = offset
        detail = f"truncated at byte {offset}" + (f" ({what})" if what else "")
        super().__init__(path, detail, topic)


class TopicMapError(PbdError):
    """A topic map (``--topics FILE``) is malformed or names topics that are not there."""

    def __init__(self, path: str | Path, what: str) -> None:
        self.path = str(path)
        super().__init__(f"{path}: {one_line(what)}")


class StoreError(PbdError):
    """The artefact store is inconsistent or a write would overwrite an artefact."""

    def __init__(self, path: str | Path, what: str) -> None:
        self.path = str(path)
        super().__init__(f"{path}: {what}")


class FitError(PbdError):
    """Segmentation or model fitting cannot proceed (no markers, too few samples, NaNs)."""

    def __init__(self, what: str, marker: str | None = None, span_s: tuple[float, float] | None = None) -> None:
        self.marker = marker
        self.span_s = span_s
        where = ""
        if marker:
            where += f"marker {marker}"
        if span_s is not None:
            where += f"{' ' if where else ''}t={span_s[0]:.3f}..{span_s[1]:.3f} s"
        super().__init__(f"{where}: {what}" if where else what)


class SceneError(PbdError):
    """A scene name, URDF or scene parameter is unknown or invalid."""


class GraspError(PbdError):
    """Grasp planning cannot proceed (no object model, no seed, nothing reachable)."""


class TransferError(PbdError):
    """Registration of two object models failed or is too poor under ``--strict``."""


class SimulationError(PbdError):
    """A descriptor does not fit the scene it is executed in."""


NAMES_SHOWN = 5
"""Names an error or warning lists before "and N more": enough to recognise them, and the line stays short."""
NAME_CHARS = 120
"""Characters of one name shown in an error or warning line (a topic or marker name is rarely longer)."""


LINE_CHARS = 400
"""Characters of the part of an error line that comes from the input (a message, a name): longer text is cut."""


def one_line(text: str, limit: int = LINE_CHARS) -> str:
    """``text`` on one line (line breaks become spaces), cut to ``limit`` characters."""
    flat = " ".join(text.split("\n")).replace("\r", " ")
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


def bounded(names: list[str] | tuple[str, ...], first: int = NAMES_SHOWN) -> str:
    """``a, b, c`` or ``a, b, c, d, e and 7 more``: at most ``first`` names, each cut to ``NAME_CHARS``."""
    shown = [n if len(n) <= NAME_CHARS else n[: NAME_CHARS - 3] + "..." for n in names[:first]]
    more = len(names) - len(shown)
    return ", ".join(shown) + (f" and {more} more" if more > 0 else "")
