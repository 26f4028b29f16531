"""``prefect.yaml`` and ``pbd serve`` describe the same two deployments of real flows."""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import yaml
from prefect import Flow

from flows.deployments import NIGHTLY_CRON, build_deployments

REPO = Path(__file__).resolve().parents[2]


def _flow_of(entrypoint: str) -> Flow[Any, Any]:
    path, func = entrypoint.split(":")
    module = importlib.import_module(path.removesuffix(".py").replace("/", "."))
    flow = getattr(module, func)
    assert isinstance(flow, Flow)
    return flow


def test_prefect_yaml_matches_the_served_deployments(tmp_path: Path) -> None:
    spec = yaml.safe_load((REPO / "prefect.yaml").read_text())
    from_yaml = {}
    for dep in spec["deployments"]:
        flow = _flow_of(dep["entrypoint"])
        accepted = set(flow.parameters.properties)
        assert set(dep.get("parameters", {})) <= accepted, dep["name"]
        crons = [s["cron"] for s in dep.get("schedules", [])]
        from_yaml[f"{flow.name}/{dep['name']}"] = (crons, set(dep.get("parameters", {})))

    served = build_deployments(str(tmp_path / "archive"), str(tmp_path / "store"))
    from_serve = {}
    for dep in served:
        crons = [str(s.schedule.cron) for s in dep.schedules or []]  # type: ignore[union-attr]
        from_serve[f"{dep.flow_name}/{dep.name}"] = (crons, set(dep.parameters))
    assert from_yaml == from_serve
    assert from_serve["reprocess-archive/nightly"][0] == [NIGHTLY_CRON]
    assert {"archive", "store"} <= from_serve["reprocess-archive/nightly"][1]
