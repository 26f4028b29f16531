"""Argument helpers of the commands that run flows (``pbd archive``, ``pbd demo``)."""

from __future__ import annotations

import argparse
import json
from typing import Any

from tasks.errors import PbdError


class ParameterError(PbdError):
    """A ``--param KEY=VALUE`` argument is malformed."""


def add_param_argument(parser: argparse.ArgumentParser) -> None:
    """``--param KEY=VALUE`` (repeatable): a learning parameter, the value read as JSON when it parses."""
    parser.add_argument(
        "--param",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="learning parameter for tasks.learn.api.LearnParams (repeatable), e.g. --param t0=0.1",
    )


def parse_params(items: list[str]) -> dict[str, Any]:
    """``["k=3", "t0=0.1"]`` → ``{"k": 3, "t0": 0.1}``; values that are not JSON stay strings."""
    out: dict[str, Any] = {}
    for item in items:
        key, sep, raw = item.partition("=")
        if not sep or not key:
            msg = f"--param {item!r}: expected KEY=VALUE"
            raise ParameterError(msg)
        try:
            out[key] = json.loads(raw)
        except json.JSONDecodeError:
            out[key] = raw
    return out
