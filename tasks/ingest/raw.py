"""What a container reader gives: every topic with its type, definition and count, and the kept raw payloads."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from tasks.ingest.batch import Batch


@dataclass
class RawTopic:
    """One topic's raw messages.

    ``encoding``: message encoding (``cdr``, ``ros1``, ``json``, or what the file says);
    ``schema_encoding``/``schema``: the message definition carried by the recording (``ros2msg``,
    ``ros2idl``, ``ros1msg``, ``jsonschema``; empty when the recording has none).
    """

    name: str
    msgtype: str
    encoding: str
    schema_encoding: str
    schema: str
    batches: list[Batch] = field(default_factory=list)
    expected: int | None = None
    """Message count promised by the container's metadata (rosbag2 ``metadata.yaml``), if any."""
    seen: int = 0
    """Messages the reader counted, their payloads kept or not (0: only the kept ones are known)."""

    @property
    def kept(self) -> int:
        """Messages whose payloads were kept."""
        return sum(len(b) for b in self.batches)

    @property
    def count(self) -> int:
        """Messages in the recording (read or counted)."""
        return max(self.seen, self.kept)


@dataclass
class RawRecording:
    """A recording's topics and raw messages, plus what was lost to damage (``--recover``)."""

    path: Path
    container: str
    topics: dict[str, RawTopic]
    lost_messages: int = 0
    warnings: list[str] = field(default_factory=list)
    log_range: tuple[int, int] | None = None
    """Earliest and latest log time (ns) over every message, kept or not (None: take them from the batches)."""

    @property
    def message_count(self) -> int:
        """Messages read over all topics."""
        return sum(t.count for t in self.topics.values())
