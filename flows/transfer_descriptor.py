"""Flow ``transfer-descriptor``: a stored descriptor onto another object model → store → simulate → report.

Its parameters are ``pbd transfer``'s options (``flows.transfer_inputs.TransferOptions``), checked before any
task runs: a bad value fails the run in one line."""

from __future__ import annotations

from prefect import flow

from flows.caching import on_store
from flows.stages.diff import diff_task
from flows.stages.learn import store_descriptor_task
from flows.stages.report import report_task
from flows.stages.simulate import simulate_task
from flows.stages.transfer import resolve_descriptor_task, target_model_task, transfer_task
from flows.summary import RunSummary, summarise
from flows.transfer_inputs import TransferOptions
from tasks.report.refs import EntryResult, RecordingRef
from tasks.store import resolve_store_root


@flow(name="transfer-descriptor", persist_result=False)
def transfer_descriptor_flow(
    descriptor: str,
    to: str,
    *,
    store: str | None = None,
    name: str | None = None,
    whole: bool = False,
    crop_radius_m: float | None = None,
    strict: bool = False,
    replan_grasp: bool = False,
    seed: int = 0,
    accept_ambiguous: bool = False,
    scale_range: tuple[float, float] | None = None,
    report: bool = True,
) -> RunSummary:
    """Carry ``descriptor`` (path, id or ``name@vN``) to the model ``to`` (model file, recording or its id) and
    simulate it: in the scene instance a recording's meta names, else on the built-in scene named like the object.

    ``accept_ambiguous``: store the best guess of a poor, ambiguous or loose registration (else the run fails
    naming why); ``scale_range`` (LO, HI): the target/source size ratios allowed."""
    options = TransferOptions(
        name=name,
        whole=whole,
        crop_radius_m=crop_radius_m,
        strict=strict,
        replan_grasp=replan_grasp,
        seed=seed,
        accept_ambiguous=accept_ambiguous,
        scale_range=scale_range,
    )
    root = str(resolve_store_root(store).resolve())
    source = resolve_descriptor_task(root, descriptor)
    target = target_model_task(root, to, seed=seed)
    carried = on_store(transfer_task, root)(root, source, target, options)
    stored = store_descriptor_task(root, carried)
    # a recording's world frame is its own: the carried descriptor runs in the scene instance its meta names
    # (a pbd synth recording), and is not run on a nominal scene it was never placed in
    recording = RecordingRef(target.recording_id, to) if target.recording_id else None
    simulated = on_store(simulate_task, root)(root, stored, recording=recording)
    diff = on_store(diff_task, root)(root, stored)
    chain = " → ".join(p.kind for p in carried.chain) or "(empty)"
    entry = EntryResult(
        source=f"{descriptor} → {to}",
        descriptor=stored,
        simulation=simulated,
        diff=diff,
        extra={"chain": chain, "parent": source.ref if source.version else source.id},
    )
    html = report_task(root, f"transfer-descriptor {source.name} → {target.object_name}", [entry]) if report else None
    return summarise([entry], html)
