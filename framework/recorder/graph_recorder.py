"""Recording a running graph: its topics from a Zenoh session, with the graph's provenance (docs/recording.md)."""

from __future__ import annotations

import json
import logging
import socket
import time
from collections.abc import Iterable, Iterator
from pathlib import Path
from typing import Any

from .. import keys, wire
from ..files.mcap_writer import McapWriter, RecordingError, TopicFilter
from ..messages import MessageError, Text
from ..registry import is_path_plugin

log = logging.getLogger("handflow.recording")
MAX_ATTACHED_FILE_BYTES = 64 * 2**20  # files named by params larger than this are listed, not attached


def graph_provenance(graph: Any) -> tuple[dict[str, dict[str, str]], dict[str, tuple[str, bytes]]]:
    """Metadata records and attachments that say how a recording of ``graph`` was made.

    Metadata: ``handflow.graph`` (name, file, host, start time), ``handflow.params`` (node id →
    resolved params as JSON), ``handflow.plugins`` (node id → plugin), ``handflow.files``
    (``node.param`` → attachment name, or a note why the file is not attached).
    Attachments: ``graph.yaml`` (the graph file) and every existing file a param names, and the source of
    a plugin given by path (``NODE.plugin``), resolved relative to the graph folder, as ``files/<path>``.
    """
    meta = {
        "handflow.graph": {
            "name": graph.name,
            "file": str(graph.path),
            "host": socket.gethostname(),
            "started_ns": str(time.time_ns()),
        },
        "handflow.params": {nid: json.dumps(rn.params.model_dump(mode="json")) for nid, rn in graph.nodes.items()},
        "handflow.plugins": {nid: rn.spec.plugin for nid, rn in graph.nodes.items()},
    }
    attachments: dict[str, tuple[str, bytes]] = {}
    try:
        attachments["graph.yaml"] = ("application/yaml", graph.path.read_bytes())
    except OSError as exc:
        log.warning("graph file %s not attached: %s", graph.path, exc.strerror)
    files: dict[str, str] = {}
    for nid, rn in graph.nodes.items():
        source = [("plugin", rn.spec.plugin.rpartition(":")[0])] if is_path_plugin(rn.spec.plugin) else []
        for name, value in [*source, *_string_leaves(rn.params.model_dump(mode="json"))]:
            path = _existing_file(graph.base_dir, value)
            if path is None:
                continue
            label = f"{nid}.{name}"
            size = path.stat().st_size
            if size > MAX_ATTACHED_FILE_BYTES:
                files[label] = f"not attached: {path} is {size} bytes (limit {MAX_ATTACHED_FILE_BYTES})"
                continue
            try:
                rel = path.relative_to(graph.base_dir)
            except ValueError:
                rel = Path(str(path).lstrip("/"))
            att = f"files/{rel.as_posix()}"
            attachments.setdefault(att, ("application/octet-stream", path.read_bytes()))
            files[label] = att
    meta["handflow.files"] = files
    return meta, attachments


def _string_leaves(value: Any, prefix: str = "") -> Iterator[tuple[str, str]]:
    if isinstance(value, str):
        yield prefix, value
    elif isinstance(value, dict):
        for k, v in value.items():
            yield from _string_leaves(v, f"{prefix}.{k}" if prefix else str(k))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield from _string_leaves(v, f"{prefix}[{i}]")


def _existing_file(base: Path, value: str) -> Path | None:
    if not value or "\n" in value or len(value) > 4096:
        return None
    p = Path(value).expanduser()
    p = p if p.is_absolute() else base / p
    try:
        return p.resolve() if p.is_file() else None
    except OSError:
        return None


class GraphRecorder:
    """Records a graph's topics from a Zenoh session into an :class:`McapWriter`.

    ``GraphRecorder.for_graph(graph, path)`` also stores the graph's provenance
    (:func:`graph_provenance`); ``attach(session)`` subscribes to ``handflow/<graph>/**`` and keeps
    the topics matching the ``record.topics`` globs, and the parameter changes
    (``handflow/<graph>/_params/changes``) whatever the globs; ``close()`` finalises the file.
    Payloads are validated by :func:`decode` and stored as received (never re-encoded); invalid
    payloads are counted in ``skipped`` and logged once per topic.  The first :class:`Text` document
    of each topic (e.g. a robot description) is also attached as a file named after the topic
    (``handflow/demo/sim/description.urdf`` for a URDF; docs/foxglove.md).
    """

    def __init__(self, writer: McapWriter, graph_name: str, topics: Iterable[str] | None = None) -> None:
        self.writer = writer
        self.graph_name = graph_name
        self.filter = TopicFilter(topics)
        self.skipped: dict[str, int] = {}
        self._subscriber = None
        self._documents: set[str] = set()
        self._params_key = keys.params_key(graph_name)

    @classmethod
    def for_graph(
        cls, graph: Any, path: str | Path, topics: Iterable[str] | None = None, **writer_kw: Any
    ) -> GraphRecorder:
        if topics is None:
            topics = graph.spec.record.topics if graph.spec.record else None
        writer = McapWriter(path, **writer_kw)
        meta, attachments = graph_provenance(graph)
        for name, data in meta.items():
            writer.add_metadata(name, data)
        for name, (media_type, data) in attachments.items():
            writer.add_attachment(name, data, media_type)
        return cls(writer, graph.name, topics)

    def attach(self, session: Any) -> None:
        self._subscriber = session.declare_subscriber(f"{keys.PREFIX}/{self.graph_name}/**", self._on_sample)

    def _on_sample(self, sample: Any) -> None:
        key = str(sample.key_expr)
        if not (self.filter(key) or key == self._params_key):  # parameter changes always (docs/tuning.md)
            return
        data, att = wire.sample_parts(sample)
        try:
            msg = wire.unpack(data, att)  # what replay and Foxglove read back must be valid (docs/robustness.md)
            if (att is not None) == (
                self.writer.encoding == "cdr"
            ):  # already in the file's encoding: stored as received
                self.writer.write_encoded(key, msg.TYPE, data, None, msg.header.stamp_ns, msg.header.seq)
            else:
                self.writer.write(key, msg)
            if isinstance(msg, Text) and key not in self._documents:
                self._documents.add(key)
                self._attach_document(key, msg.data)
        except (MessageError, RecordingError) as exc:
            if self.writer.failure:
                return  # reported once by the writer
            if key not in self.skipped:
                log.warning("not recording a payload on %s: %s", key, exc)
            self.skipped[key] = self.skipped.get(key, 0) + 1

    def _attach_document(self, key: str, text: str) -> None:
        urdf = "<robot" in text[:2000]
        name, media_type = (f"{key}.urdf", "application/xml") if urdf else (f"{key}.txt", "text/plain")
        self.writer.add_attachment(name, text.encode(), media_type)

    @property
    def summary(self) -> str:
        """``recorded N message(s) on T topic(s) to PATH``."""
        return f"recorded {self.writer.message_count} message(s) on {len(self.writer.counts)} topic(s) to {self.writer.path}"

    def close(self, log_summary: bool = True) -> None:
        """Stop recording and finish the file; log :attr:`summary` unless the caller prints it itself."""
        if self._subscriber is not None:
            self._subscriber.undeclare()
            self._subscriber = None
        self.writer.close()
        if log_summary:
            log.info("%s", self.summary)
