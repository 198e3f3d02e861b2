"""Compare two recordings message by message (``handflow compare``, docs/recording.md "Comparing").

Topics are matched by ``node/port`` (a replay into another graph records the same node's output
under another graph name), messages by their header's ``stamp_ns`` (which the recorder also writes
as the MCAP ``publish_time``; files written by other tools may set that differently), the k-th
message of a stamp with the k-th of the same stamp in the other file.  Two messages are equal when every decoded field and the header's stamp and seq
are equal (the header's source is the topic's node, which CDR does not store), whatever the encoding.
Without globs, the data topics are compared: those whose node and port names do not start with ``_``
(recordings also hold the runtime's ``_params/changes`` and ``_runtime/events``, which globs naming
them compare).  Truncated files are compared as far as they were recovered (:class:`ReadReport` says so).
"""

from __future__ import annotations

import hashlib
import json
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from pathlib import Path

from .. import keys
from ..messages import MessageError
from .mcap_reader import ReadReport, RecordedMessage, iter_recording


@dataclass
class TopicComparison:
    """Per ``node/port``: messages equal, differing, only in A, only in B; the first stamp that differs."""

    topic: str
    equal: int = 0
    differing: int = 0
    only_a: int = 0
    only_b: int = 0
    first_difference_ns: int | None = None

    @property
    def same(self) -> bool:
        return not (self.differing or self.only_a or self.only_b)


def _topic(key: str) -> str:
    parts = keys.split_key(key)
    return f"{parts[1]}/{parts[2]}" if parts else key


def _stamped_digest(rm: RecordedMessage) -> tuple[int, bytes]:
    """The header stamp and a fingerprint of the decoded message (encoding-independent); the ``publish_time``
    and a fingerprint of the raw bytes if it does not decode."""
    try:
        d = rm.decode().to_dict()
    except MessageError:
        return rm.publish_time_ns, hashlib.blake2b(b"undecodable:" + rm.data, digest_size=16).digest()
    del d["header"]["source"]  # the topic's node (CDR does not store it), matched with the topic
    return d["header"]["stamp_ns"], hashlib.blake2b(json.dumps(d, sort_keys=True).encode(), digest_size=16).digest()


def is_data_topic(topic: str) -> bool:
    """Whether ``node/port`` is a data topic: neither name starts with ``_`` (not ``_runtime/events``)."""
    return not any(name.startswith("_") for name in topic.split("/"))


def _index(path: str | Path, topics: Iterable[str] | None, report: ReadReport) -> dict[str, dict[int, list[bytes]]]:
    """topic → stamp → fingerprints in file order (without globs: of the data topics)."""
    out: dict[str, dict[int, list[bytes]]] = defaultdict(lambda: defaultdict(list))
    for rm in iter_recording(path, topics, report=report):
        topic = _topic(rm.topic)
        if topics is None and not is_data_topic(topic):
            continue
        stamp, digest = _stamped_digest(rm)
        out[topic][stamp].append(digest)
    return out


def compare_recordings(
    a: str | Path, b: str | Path, topics: Iterable[str] | None = None
) -> tuple[list[TopicComparison], ReadReport, ReadReport]:
    """Compare the topics (:class:`TopicFilter` globs, default every data topic, :func:`is_data_topic`) of two
    recordings.

    Raises :class:`handflow.framework.files.mcap_writer.RecordingError` for a missing or non-MCAP file.
    """
    reports = ReadReport(Path(a)), ReadReport(Path(b))
    index_a, index_b = _index(a, topics, reports[0]), _index(b, topics, reports[1])
    result = []
    for topic in sorted(set(index_a) | set(index_b)):
        c = TopicComparison(topic)
        by_a, by_b = index_a.get(topic, {}), index_b.get(topic, {})
        for stamp in sorted(set(by_a) | set(by_b)):
            xs, ys = by_a.get(stamp, []), by_b.get(stamp, [])
            same = sum(x == y for x, y in zip(xs, ys))
            c.equal += same
            c.differing += min(len(xs), len(ys)) - same
            c.only_a += max(0, len(xs) - len(ys))
            c.only_b += max(0, len(ys) - len(xs))
            if c.first_difference_ns is None and not c.same:
                c.first_difference_ns = stamp
        result.append(c)
    return result, *reports


def as_json(result: list[TopicComparison], report_a: ReadReport, report_b: ReadReport) -> dict:
    """The ``--json`` object of ``handflow compare`` (docs/recording.md)."""
    return {
        "equal": all(c.same for c in result),
        "topics": [asdict(c) for c in result],
        "files": [
            {"file": str(r.path), "messages": r.messages, "recovered": r.recovered, "error": r.error or None}
            for r in (report_a, report_b)
        ],
    }
