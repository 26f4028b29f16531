"""The run summary as Markdown (the Prefect markdown artifact): descriptors, what changed, simulation results."""

from __future__ import annotations

import json
import re
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

from tasks.report.refs import EntryResult

_MD_SPECIAL = re.compile(r"([\\`*_\[\]<>!|~&])")
"""Marks that change inline Markdown anywhere in a line (emphasis, code, links, images, HTML, table cells)."""


def md_text(text: str) -> str:
    """``text`` as literal Markdown inline text: control characters and line breaks become spaces, every Markdown
    punctuation mark is backslash-escaped (a recording's file name cannot open a link, an image or a new row)."""
    flat = "".join(ch if ch.isprintable() else " " for ch in text)
    return _MD_SPECIAL.sub(r"\\\1", flat)


def _fence(text: str) -> str:
    """A code fence longer than any run of backticks in ``text``, so ``text`` cannot close it."""
    longest = max((len(run) for run in re.findall(r"`+", text)), default=0)
    return "`" * max(3, longest + 1)


def _sim_cell(entry: EntryResult) -> str:
    sim = entry.simulation
    if sim is None:
        return "-"
    if sim.skipped is not None:
        return "not simulated"
    pairs = ", ".join(f"{a:.3f}/{t:.3f}" for a, t in zip(sim.achieved, sim.target, strict=False))
    return f"{'success' if sim.success else 'FAILED'} ({pairs})" if pairs else ("success" if sim.success else "FAILED")


def summary_rows(entries: Sequence[EntryResult]) -> list[dict[str, str]]:
    """One row per recording (the Prefect table artifact): recording, status, descriptor, id, chain, simulation,
    error."""
    return [
        {
            "recording": Path(e.source).name,
            "status": e.status,
            "descriptor": e.descriptor.ref if e.descriptor else "-",
            "id": e.descriptor.id[:12] if e.descriptor else "-",
            "chain": str(e.extra.get("chain", "-")),
            "simulation": _sim_cell(e),
            "error": e.error or "",
        }
        for e in entries
    ]


def summary_markdown(title: str, entries: Sequence[EntryResult], report_html: Path | None) -> str:
    """Markdown: counts by status, a table of descriptors and simulation results, and the diffs."""
    counts = Counter(e.status for e in entries)
    lines = [f"# {title}", ""]
    lines.append(
        f"{len(entries)} recordings: {counts['new']} new, {counts['changed']} changed, "
        f"{counts['unchanged']} unchanged, {counts['failed']} failed."
    )
    if report_html is not None:
        lines += ["", f"Report: {md_text(str(report_html))}"]
    lines += ["", "| recording | descriptor | id | status | chain | simulation (achieved/target) |"]
    lines.append("| --- | --- | --- | --- | --- | --- |")
    for e in entries:
        d = e.descriptor
        chain = e.extra.get("chain", "-")
        rec = md_text(Path(e.source).name)
        if d is None:
            lines.append(f"| {rec} | - | - | failed: {md_text(e.error or '?')} | - | - |")
            continue
        lines.append(
            f"| {rec} | {md_text(d.ref)} | `{d.id[:12]}` | {e.status} | {md_text(str(chain))} | {_sim_cell(e)} |"
        )
    failed = [e for e in entries if e.status == "failed"]
    if failed:
        lines += ["", "## Failed", ""]
        lines += [f"- {md_text(e.source)}: {md_text(e.error or '?')}" for e in failed]
    changed = [e for e in entries if e.status == "changed"]
    if changed:
        lines += ["", "## What changed", ""]
        for e in changed:
            if e.descriptor is None:
                continue
            lines.append(f"### {md_text(str(e.descriptor.previous))} → {md_text(e.descriptor.ref)}")
            words = (e.diff or {}).get("lines")
            text = "\n".join(str(x) for x in words) if isinstance(words, list) else json.dumps(e.diff, indent=1)
            fence = _fence(text)
            lines += ["", fence, text, fence, ""]
    return "\n".join(lines) + "\n"
