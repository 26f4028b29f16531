"""``pbd simulate NAME@latest`` runs a learned descriptor in the scene instance it was learned on."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from flows.cli import main
from tasks.store import Store
from tasks.synth.record import synthesize
from tasks.synth.samples import sample_seed


def test_a_demo_descriptor_simulates_by_name_alone(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    recording = synthesize("microwave", sample_seed("microwave"), tmp_path / "microwave.mcap")
    store = tmp_path / "store"
    assert main(["learn", str(recording), "--store", str(store)]) == 0
    desc = Store(store).load("open-microwave@latest")
    assert desc.extra_provenance["scene"] == {"name": "microwave", "seed": sample_seed("microwave")}
    assert desc.extra_provenance["seed"] == 0
    capsys.readouterr()
    assert main(["simulate", "open-microwave@latest", "--store", str(store), "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["scene"] == "microwave"
    assert result["success"] is True
