"""Write a run's report: ``<store>/reports/<run id>/report.html`` with its PNG plots and the axes MCAPs.

The folder is staged under ``<store>/tmp`` and renamed into place, so a report is either complete or absent.
"""

from __future__ import annotations

import dataclasses
import hashlib
import html
import json
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib.pyplot as plt
import numpy as np

from schemas.descriptor import Descriptor, canonical_json
from tasks.code_version import code_version
from tasks.errors import StoreError
from tasks.hand import barrett
from tasks.recording.load import load_recording
from tasks.report import plots
from tasks.report.markdown import summary_markdown
from tasks.report.plots import quat_to_matrix
from tasks.report.refs import EntryResult
from tasks.report.scene_mcap import axes_mcap_bytes, scene_update
from tasks.store import Store, write_bytes_atomic

FIGURES_DIRNAME = "figures"
"""Folder under ``reports/`` of the parts shared by every run's report, one per content (``cached_part``)."""
PART_FILE = "part.html"
"""A shared part's HTML fragment, beside its figures."""
SRC_MARK = "@part@/"
"""Stands for a part's folder in its fragment's links until the part is published."""

MAX_MARKERS_DRAWN = 16
"""Marker trajectories drawn per recording at most (the chain's markers first)."""

_CSS = """
body{font-family:system-ui,sans-serif;margin:2em;max-width:1100px;color:#222}
table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;font-size:14px}
th{background:#f3f3f3}.new{color:#1a7f37}.changed{color:#b35900}.failed{color:#c00}.unchanged{color:#666}
img{max-width:100%;border:1px solid #eee;margin:4px 0}pre{background:#f7f7f7;padding:8px;overflow-x:auto}
section{border-top:2px solid #ddd;margin-top:2em}
"""


@dataclass(frozen=True)
class ReportPaths:
    """Where a run's report landed: the HTML file, its folder and the axes MCAPs (one per descriptor)."""

    html: Path
    folder: Path
    mcaps: tuple[Path, ...]
    markdown: str


def _save(fig: Any, path: Path) -> str:
    """Save a matplotlib figure as PNG and close it; returns the file name for the HTML."""

    fig.savefig(path, dpi=90)
    plt.close(fig)
    return f"{SRC_MARK}{path.name}"


def _finger_dofs(a1: float, a2: float) -> list[float] | None:
    """Barrett [spread, f1, f2, f3] in rad of the eigengrasp amplitudes ``a1``, ``a2``."""
    return [float(v) for v in np.asarray(barrett.dofs_from_eigengrasps(a1, a2)).ravel()]


def _hand_lines(grasp: Any) -> list[Any] | None:
    """The Barrett hand's three fingers as world polylines (knuckle → joints → tip, metres) at the grasp."""
    tfs = barrett.link_transforms(barrett.joint_positions(barrett.dofs_from_eigengrasps(*grasp.eigengrasps)))
    rot = quat_to_matrix(grasp.wrist_orientation)
    pos = np.asarray(grasp.wrist_position)
    lines = []
    for k in range(3):
        knuckle, prox, dist = tfs[3 * k + 1], tfs[3 * k + 2], tfs[3 * k + 3]
        tip = dist @ np.array([0.0, 0.0, float(barrett.DISTAL_LENGTH), 1.0])
        pts_palm = np.stack([np.zeros(3), knuckle[:3, 3], prox[:3, 3], dist[:3, 3], tip[:3]])
        lines.append(pts_palm @ rot.T + pos)
    return lines


def _entry_section(store: Store, entry: EntryResult, mcaps: list[Path]) -> str:
    """One recording's section: its status (this run's) and the descriptor's and simulation's figures, each
    rendered once per content (``cached_part``) and shared by every run's report."""
    title = html.escape(Path(entry.source).name)
    if entry.descriptor is None:
        return f"<section><h2>{title}</h2><p class=failed>failed: {html.escape(entry.error or '?')}</p></section>"
    ref = entry.descriptor
    desc = Descriptor.from_json(Path(ref.path).read_text(), source=ref.path)
    stem = f"{desc.name}-v{ref.version}"
    parts = [f"<section><h2 id='{html.escape(stem)}'>{html.escape(ref.ref)} <small>from {title}</small></h2>"]
    parts.append(f"<p>status <b class={entry.status}>{entry.status}</b></p>")
    rec_id = entry.recording.recording_id if entry.recording is not None else None
    body, files = cached_part(
        store, {"descriptor": desc.id, "recording": rec_id}, lambda folder: _descriptor_html(store, entry, desc, folder)
    )
    parts.append(body)
    mcaps += [f for f in files if f.suffix == ".mcap"]
    sim = entry.simulation
    if sim is not None and sim.skipped is None:
        key = {"simulation": dataclasses.asdict(sim)}
        parts.append(cached_part(store, key, lambda folder: (_simulation_html(entry, folder), []))[0])
    else:
        parts.append(_simulation_html(entry, store.reports_dir))  # draws nothing when not simulated
    if entry.status == "changed":
        diff_key = {"diff": desc.id, "previous": ref.previous}
        parts.append(cached_part(store, diff_key, lambda folder: (_diff_html(entry, folder), []))[0])
    else:
        parts.append(_diff_html(entry, store.reports_dir))  # draws nothing for a new or unchanged version
    parts.append("</section>")
    return "\n".join(parts)


def cached_part(
    store: Store, key: dict[str, Any], render: Callable[[Path], tuple[str, list[Path]]]
) -> tuple[str, list[Path]]:
    """An HTML fragment and its files, rendered by ``render(folder)`` once per ``key`` (content ids) and report
    code version into ``<store>/reports/figures/<hash>/``; its links point there from a run's report folder."""
    digest = hashlib.sha256(canonical_json({**key, "code": code_version("tasks.report")}).encode()).hexdigest()[:24]
    final = store.reports_dir / FIGURES_DIRNAME / digest
    if not (final / PART_FILE).is_file():
        with store.staging("figures") as staged:
            fragment, _ = render(staged)
            link = f"../{FIGURES_DIRNAME}/{digest}/"
            fragment = fragment.replace(SRC_MARK, link)
            write_bytes_atomic(staged / PART_FILE, fragment.encode())
            store.publish_dir(staged, final)  # False: a concurrent run published the same part first
    files = sorted(p for p in final.iterdir() if p.name != PART_FILE)
    return (final / PART_FILE).read_text(), files


def _descriptor_html(store: Store, entry: EntryResult, desc: Descriptor, folder: Path) -> tuple[str, list[Path]]:
    """The descriptor's table and figures (trajectories, timeline, axes MCAP, model selection, grasp) in ``folder``."""
    mcaps: list[Path] = []
    stem = "descriptor"
    parts = [
        f"<p>id <code>{desc.id[:16]}</code> · action "
        f"<b>{html.escape(desc.action)}</b> · object <b>{html.escape(desc.object.name)}</b> · parameters "
        f"<code>{html.escape(json.dumps(desc.parameters, sort_keys=True))}</code></p>"
    ]
    rows = "".join(
        f"<tr><td>{i}</td><td>{p.kind}</td><td>{_fmt(p.pos)}</td><td>{_fmt(p.dir)}</td><td>{p.extent:.4f}</td>"
        f"<td>{_fmt_t(p.t_start)}..{_fmt_t(p.t_end)}</td><td>{_rms_mm(p.fit)}</td></tr>"
        for i, p in enumerate(desc.chain)
    )
    parts.append(
        "<table><tr><th>#</th><th>kind</th><th>pos (m)</th><th>dir</th><th>extent (rad | m)</th><th>t (s)</th>"
        f"<th>fit RMS (mm)</th></tr>{rows}</table>"
    )
    rec = None
    if entry.recording is not None and store.has_recording(entry.recording.recording_id):
        rec = load_recording(store, entry.recording.recording_id)
    if rec is not None:
        chain_markers = {m for p in desc.chain for m in p.markers}
        names = sorted(rec.markers, key=lambda n: (n not in chain_markers, n))[:MAX_MARKERS_DRAWN]
        tracks = [plots.Track(n, rec.markers[n].stamps_ns, rec.markers[n].points) for n in names]
        img = _save(plots.trajectories_figure(tracks, rec.start_ns, desc), folder / f"{stem}-trajectories.png")
        parts.append(f"<h3>trajectories and fitted axes</h3><img src='{img}'>")
        duration = (int(rec.info.get("end_ns", rec.start_ns)) - rec.start_ns) / 1e9
        img = _save(plots.timeline_figure(desc, duration), folder / f"{stem}-timeline.png")
        parts.append(f"<h3>segment timeline</h3><img src='{img}'>")
        starts = _segment_starts(desc, tracks, rec.start_ns)
        frame = str(rec.info.get("frame_id", "world"))
        mcap_path = folder / f"{stem}-axes.mcap"
        write_bytes_atomic(
            mcap_path, axes_mcap_bytes([(rec.start_ns, scene_update(desc, rec.start_ns, frame, starts))])
        )
        mcaps.append(mcap_path)
        source = html.escape(str(rec.info.get("source", entry.source)))
        parts.append(
            f"<p>Axes as foxglove.SceneUpdate on <code>/pbd/axes</code>: "
            f"<a href='{SRC_MARK}{mcap_path.name}'>{mcap_path.name}</a> (open it together with <code>{source}</code> "
            "in Foxglove or Lichtblick).</p>"
        )
    img = _save(plots.model_selection_figure(desc), folder / f"{stem}-models.png")
    parts.append(f"<h3>model selection per segment</h3><img src='{img}'>")
    if desc.grasp is not None:
        model = rec.object_model if rec is not None else None
        dofs = _finger_dofs(*desc.grasp.eigengrasps)
        fig = plots.grasp_figure(desc.grasp, model, dofs, _hand_lines(desc.grasp))
        img = _save(fig, folder / f"{stem}-grasp.png")
        parts.append(f"<h3>planned grasp</h3><img src='{img}'>")
    else:
        parts.append("<h3>planned grasp</h3><p>none (no object model or no grasp planned)</p>")
    return "\n".join(parts), mcaps


def _simulation_html(entry: EntryResult, folder: Path) -> str:
    """The simulation's verdict and figures (extent reached, joint trace), drawn into ``folder``."""
    stem = "simulation"
    sim = entry.simulation
    if sim is None:
        return "<h3>simulation</h3><p>not simulated</p>"
    if sim.skipped is not None:
        return f"<h3>simulation</h3><p>not simulated: {html.escape(sim.skipped)}</p>"
    verdict = "<b class=new>success</b>" if sim.success else "<b class=failed>failed</b>"
    out = [f"<h3>simulation in scene {html.escape(sim.scene)}: {verdict}</h3>"]
    if sim.detail:
        out.append(f"<p>{html.escape(sim.detail)}</p>")
    if sim.target:
        fig = plots.simulation_extent_figure(sim.joints, sim.achieved, sim.target)
        out.append(f"<img src='{_save(fig, folder / f'{stem}-extent.png')}'>")
    if sim.trace_path and Path(sim.trace_path).is_file():
        with np.load(sim.trace_path, allow_pickle=False) as npz:
            times = np.asarray(npz["times_s"], dtype=np.float64)
            values = np.atleast_2d(np.asarray(npz["values"], dtype=np.float64))
            targets = np.asarray(npz["targets"], dtype=np.float64).ravel()
            names = [str(n) for n in npz["names"]]
            units = [str(u) for u in npz["units"]] if "units" in npz else ["rad"] * len(names)
        traces = [plots.JointTrace(n, times, values[i], float(targets[i]), units[i]) for i, n in enumerate(names)]
        fig = plots.joint_motion_figure(traces, "simulated joint motion over time vs demonstrated extent")
        out.append(f"<img src='{_save(fig, folder / f'{stem}-joint-trace.png')}'>")
    return "\n".join(out)


def _diff_html(entry: EntryResult, folder: Path) -> str:
    """What changed from the previous version, with its figure drawn into ``folder`` (changed versions only)."""
    stem = "diff"
    if entry.descriptor is None or entry.status != "changed":
        prev = "first version" if entry.status == "new" else "same content as the previous version"
        return f"<h3>against the previous version</h3><p>{prev}</p>"
    out = [f"<h3>against the previous version ({html.escape(entry.descriptor.previous or '')})</h3>"]
    changes = _numeric_changes(entry.diff or {})
    if changes:
        img = _save(plots.diff_figure(changes), folder / f"{stem}-diff.png")
        out.append(f"<img src='{img}'>")
    lines = (entry.diff or {}).get("lines")
    if isinstance(lines, list):
        out.append(f"<pre>{html.escape(chr(10).join(str(x) for x in lines))}</pre>")
    raw = html.escape(json.dumps(entry.diff, indent=1, sort_keys=True))
    out.append(f"<details><summary>diff as JSON</summary><pre>{raw}</pre></details>")
    return "\n".join(out)


def _numeric_changes(diff: dict[str, Any]) -> list[tuple[str, float, float]]:
    """(label, axis angle change deg, axis offset mm) per changed primitive, read from a ``tasks.diff`` result."""
    out = []
    items = diff.get("primitives") or diff.get("changed") or []
    for i, item in enumerate(items if isinstance(items, list) else []):
        if not isinstance(item, dict):
            continue
        angle = item.get("axis_angle_deg", item.get("angle_deg"))
        offset = item.get("axis_offset_mm", item.get("offset_mm"))
        if angle is None and offset is None:
            continue
        label = f"{item.get('index_b', item.get('index', i))}: {item.get('kind', '')}"
        out.append((label, float(angle or 0.0), float(offset or 0.0)))
    return out


def _segment_starts(desc: Descriptor, tracks: Sequence[Any], start_ns: int) -> dict[int, list[float]]:
    """A world point per primitive where its motion starts: the first sample of its marker in the segment."""
    out: dict[int, list[float]] = {}
    for i, prim in enumerate(desc.chain):
        if prim.t_start is None:
            continue
        for track in tracks:
            if prim.markers and track.name not in prim.markers:
                continue
            t = (track.stamps_ns - start_ns) / 1e9
            sel = np.flatnonzero((t >= prim.t_start) & np.all(np.isfinite(track.points), axis=1))
            if len(sel):
                out[i] = [float(v) for v in track.points[sel[0]]]
                break
    return out


def _fmt(v: Any) -> str:
    return "-" if v is None else "[" + ", ".join(f"{float(x):.3f}" for x in v) + "]"


def _rms_mm(fit: dict[str, Any]) -> str:
    rms = fit.get("rms_m")
    return "-" if rms is None else f"{1000 * float(rms):.2f}"


def _fmt_t(v: float | None) -> str:
    return "?" if v is None else f"{v:.2f}"


def write_report(store: Store, run_id: str, title: str, entries: Sequence[EntryResult]) -> ReportPaths:
    """Write ``<store>/reports/<run_id>/report.html`` (plots, axes MCAPs) for ``entries``; refuses to overwrite."""
    final = store.reports_dir / run_id
    if final.exists():
        msg = "a report for this run already exists"
        raise StoreError(final, msg)
    mcaps: list[Path] = []
    with store.staging("report") as staged:
        sections = [_entry_section(store, e, mcaps) for e in entries]
        md = summary_markdown(title, entries, final / "report.html")
        rows = "".join(
            f"<tr><td>{html.escape(Path(e.source).name)}</td>"
            f"<td>{html.escape(e.descriptor.ref if e.descriptor else '-')}</td>"
            f"<td class={e.status}>{e.status}</td><td>{_sim_text(e)}</td></tr>"
            for e in entries
        )
        page = (
            f"<!doctype html><html><head><meta charset='utf-8'><title>{html.escape(title)}</title>"
            f"<style>{_CSS}</style></head><body><h1>{html.escape(title)}</h1><p>run <code>{html.escape(run_id)}</code>"
            f" · store <code>{html.escape(str(store.root.resolve()))}</code></p>"
            f"<table><tr><th>recording</th><th>descriptor</th><th>status</th><th>simulation</th></tr>{rows}</table>"
            + "\n".join(sections)
            + "</body></html>\n"
        )
        write_bytes_atomic(staged / "report.html", page.encode())
        write_bytes_atomic(staged / "summary.md", md.encode())
        if not store.publish_dir(staged, final):
            msg = "a report for this run already exists"
            raise StoreError(final, msg)
    return ReportPaths(final / "report.html", final, tuple(mcaps), md)


def _sim_text(entry: EntryResult) -> str:
    sim = entry.simulation
    if sim is None or sim.skipped is not None:
        return "-"
    return "<b class=new>success</b>" if sim.success else "<b class=failed>failed</b>"
