"""General message decoding from the definitions a recording carries (rosbags typestore), and JSON.

A typestore is built per topic from that topic's own definition (MCAP schema, ROS 1 connection header,
rosbag2 ``message_definitions``), so custom types decode without ROS and two topics cannot clash. When the
recording has no definition (old rosbag2 sqlite3 files), the built-in ROS 2 (``cdr``) or ROS 1 Noetic
(``ros1``) types are used.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

from tasks.errors import RecordingError
from tasks.ingest.raw import RawTopic

_IDL_SEP = "=" * 80


def typestore_for(topic: RawTopic, path: str) -> Any:
    """A rosbags typestore holding ``topic.msgtype`` and its dependencies; raises ``RecordingError``."""
    from rosbags.typesys import (  # noqa: PLC0415 (imported on first use: bulk-decoded types never need it)
        Stores,
        get_types_from_idl,
        get_types_from_msg,
        get_typestore,
    )

    if not topic.schema:
        store = get_typestore(Stores.ROS1_NOETIC if topic.encoding == "ros1" else Stores.LATEST)
        if topic.msgtype not in store.fielddefs:
            msg = f"no message definition for {topic.msgtype} in the recording, and it is not a standard type"
            raise RecordingError(path, msg, topic.name)
        return store
    try:
        if topic.schema_encoding == "ros2idl":
            typs: dict[str, Any] = {}
            if topic.schema.startswith(f"{_IDL_SEP}\nIDL: "):
                for part in topic.schema.split(f"{_IDL_SEP}\n")[1:]:
                    _hdr, idl = part.split("\n", 1)
                    typs.update(get_types_from_idl(idl))
            else:
                typs.update(get_types_from_idl(topic.schema))
        else:
            typs = dict(get_types_from_msg(topic.schema, topic.msgtype))
        store = get_typestore(Stores.EMPTY)
        store.register(typs)
    except Exception as err:  # the rosbags parsers raise several kinds on bad text
        first = str(err).splitlines()[0][:120] if str(err) else type(err).__name__
        msg = f"cannot parse the message definition of {topic.msgtype} ({first})"
        raise RecordingError(path, msg, topic.name) from err
    if topic.msgtype not in store.fielddefs:
        msg = f"the message definition does not define {topic.msgtype}"
        raise RecordingError(path, msg, topic.name)
    return store


def decode_topic(topic: RawTopic, path: str, indices: dict[int, Any] | None = None) -> Iterator[tuple[int, Any]]:
    """Decode every message of ``topic``: yields (log time ns, message object or parsed JSON).

    ``indices`` optionally maps a batch number to the message indices to decode in that batch.
    """
    if topic.encoding == "json":
        deser = None
    elif topic.encoding in ("cdr", "ros1"):
        store = typestore_for(topic, path)
        deser = store.deserialize_cdr if topic.encoding == "cdr" else store.deserialize_ros1
    else:
        msg = f"unknown message encoding {topic.encoding!r}"
        raise RecordingError(path, msg, topic.name)
    for b, batch in enumerate(topic.batches):
        which = range(len(batch)) if indices is None else indices.get(b, ())
        for i in which:
            raw = batch.payload(int(i))
            try:
                obj = json.loads(bytes(raw)) if deser is None else deser(raw, topic.msgtype)
            except Exception as err:
                msg = f"message {int(i)} does not decode as {topic.msgtype} ({type(err).__name__}: {err})"
                raise RecordingError(path, msg, topic.name) from err
            yield int(batch.log_ns[int(i)]), obj
