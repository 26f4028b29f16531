"""Prefect wrapper of the diff (``tasks.diff.core.diff_descriptors``) against the previous stored version.

Only a descriptor stored as a new version on top of an older one has something to compare; for new and
unchanged ones the task returns None. Cached on the two versions (a stored version never changes) and the
code version of the diff.
"""

from __future__ import annotations

from typing import Any

from prefect import task
from prefect.context import TaskRunContext

from flows.caching import RETRIED, stage_key
from tasks.diff.core import diff_descriptors, format_diff
from tasks.report.refs import DescriptorRef
from tasks.store import Store

DIFF_MODULES = ("tasks.diff", "schemas")
"""Modules whose source is the diff's code version."""


def nothing_to_compare(descriptor: DescriptorRef) -> bool:
    """True for a new or unchanged version: there is no previous version to compare, the diff is None."""
    return descriptor.previous is None


def diff_cache_key(context: TaskRunContext, parameters: dict[str, Any]) -> str:
    """Cache key of a diff: this descriptor's id and ``name@vN`` of the version before it."""
    del context
    descriptor: DescriptorRef = parameters["descriptor"]
    refs = {"descriptor": descriptor.id, "previous": descriptor.previous}
    return stage_key("diff", DIFF_MODULES, refs, {})


@task(
    name="diff",
    cache_key_fn=diff_cache_key,
    persist_result=True,
    **RETRIED,
)
def diff_task(store_root: str, descriptor: DescriptorRef) -> dict[str, Any] | None:
    """What changed from the previous version (``DescriptorDiff.to_dict()`` plus ``lines`` in words), or None."""
    if nothing_to_compare(descriptor):
        return None
    store = Store(store_root)
    diff = diff_descriptors(store.load(str(descriptor.previous)), store.load(descriptor.path))
    return {**diff.to_dict(), "lines": format_diff(diff)}
