"""Republishing a received message unchanged without encoding it again (docs/ros2.md, "Forwarding").

A node that forwards what it receives (a selector, a relay, a throttle) publishes the very message
object the runtime decoded for it.  The runtime then sends the received CDR body again with the
new stamp patched in, instead of validating and encoding the message anew — but only if nothing
in it can have changed:

* :func:`snapshot` is taken right after decoding, before the node sees the message.  It holds
  every field except the header: read-only numpy arrays (views of the received bytes, which cannot
  be made writeable) by identity, strings and numbers by value, lists of those as tuples (so an
  in-place edit shows).  A message with any other field value (a writeable array, a dict, a list
  of lists) gets no snapshot and is always encoded.
* :func:`unchanged` compares the message with its snapshot when it is published.

Only the header's stamp may differ: the source node and sequence number travel in the attachment,
not in the body (:mod:`handflow.framework.wire`).
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np

from ..messages import Message

_IMMUTABLE_TYPES = frozenset((str, int, float, bool, bytes, type(None)))


@functools.cache
def _body_fields(cls: type[Message]) -> tuple[str, ...]:
    return tuple(f.name for f in dataclasses.fields(cls) if f.name != "header")


def snapshot(msg: Message) -> tuple | None:
    """What :func:`unchanged` compares against, or ``None`` when a field could change unseen."""
    out = []
    for name in _body_fields(type(msg)):
        value = getattr(msg, name)
        if isinstance(value, np.ndarray):
            if value.flags.writeable:
                return None
        elif type(value) is list:
            value = tuple(value)
            if not _IMMUTABLE_TYPES.issuperset(map(type, value)):
                return None
        elif type(value) not in _IMMUTABLE_TYPES:
            return None
        out.append(value)
    return tuple(out)


def unchanged(msg: Message, snap: tuple) -> bool:
    """True when every field of ``msg`` still holds what :func:`snapshot` saw."""
    for name, seen in zip(_body_fields(type(msg)), snap):
        value = getattr(msg, name)
        if isinstance(seen, np.ndarray):
            if value is not seen:
                return False
        elif type(seen) is tuple:
            if type(value) is not list or tuple(value) != seen:
                return False
        elif type(value) is not type(seen) or value != seen:
            return False
    return True
