"""The root of pbd's exception family and the contract's own error (``tasks.errors`` adds the stages' errors)."""

from __future__ import annotations

from pathlib import Path


class PbdError(Exception):
    """Root of every error pbd raises on purpose (bad input, failed fit, store conflict)."""


class DescriptorError(PbdError):
    """A descriptor is malformed, fails its JSON Schema or a limit, or cannot be resolved."""

    def __init__(self, source: str | Path, what: str) -> None:
        self.source = str(source)
        super().__init__(f"{source}: {what}")
