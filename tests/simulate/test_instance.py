"""The scene instance a recording's meta names (``pbd synth`` writes scene and seed into ``/demo/meta``)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from tasks.errors import RecordingError
from tasks.simulate.instance import instance_from_meta, recording_meta


@pytest.mark.parametrize(
    ("meta", "expected"),
    [
        ({"action": "open", "object": "door", "scene": "door", "seed": 4}, ("door", 4)),
        ({"scene": "bottle", "seed": None}, ("bottle", None)),
        ({"action": "open", "object": "microwave"}, (None, None)),
        ({"scene": "", "seed": True}, (None, None)),
        ({"scene": 3, "seed": "7"}, (None, None)),
    ],
)
def test_instance_from_meta(meta: dict[str, object], expected: tuple[str | None, int | None]) -> None:
    assert instance_from_meta(meta) == expected


def test_recording_meta_reads_recording_json(tmp_path: Path) -> None:
    (tmp_path / "recording.json").write_text(json.dumps({"id": "x", "meta": {"scene": "door", "seed": 2}}))
    assert recording_meta(tmp_path) == {"scene": "door", "seed": 2}
    (tmp_path / "recording.json").write_text(json.dumps({"id": "x"}))
    assert recording_meta(tmp_path) == {}


def test_recording_meta_names_an_unreadable_file(tmp_path: Path) -> None:
    (tmp_path / "recording.json").write_text("{not json")
    with pytest.raises(RecordingError, match=r"recording\.json: cannot read ingested recording"):
        recording_meta(tmp_path)
    with pytest.raises(RecordingError, match=r"missing/recording\.json: cannot read ingested recording"):
        recording_meta(tmp_path / "missing")
    (tmp_path / "recording.json").write_text(json.dumps({"schema_version": 99, "meta": {"scene": "door"}}))
    with pytest.raises(RecordingError, match="schema_version 99, this pbd reads"):
        recording_meta(tmp_path)
